//! Fresnel coefficients and the reflection and refraction directions they weight.
//!
//! Exact unpolarized Fresnel for dielectrics (the average of the s- and p-polarized reflectances,
//! with total internal reflection), Schlick's approximation for mirrors, and the mirror-reflection
//! and Snell-refraction directions. Everything is f64 and total: cosines are clamped so grazing
//! incidence and incidence exactly at the critical angle give finite numbers, never NaN.

use glam::DVec3;

/// The Fresnel split of light arriving at a smooth dielectric interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DielectricFresnel {
    /// Amplitude reflection coefficient squared for s-polarized light, in [0, 1].
    pub rs: f64,
    /// Amplitude reflection coefficient squared for p-polarized light, in [0, 1].
    pub rp: f64,
    /// Unpolarized reflectance `(rs + rp) / 2`, in [0, 1]; 1 under total internal reflection.
    pub reflectance: f64,
    /// Unpolarized transmittance `1 − reflectance`, in [0, 1] (energy, without the radiance
    /// scaling by the squared IOR ratio, as in the paper's `T̂F`).
    pub transmittance: f64,
    /// Cosine of the refraction angle, in [0, 1]; 0 under total internal reflection.
    pub cos_transmitted: f64,
    /// True when no light is transmitted (incidence at or past the critical angle).
    pub total_internal_reflection: bool,
}

/// Exact unpolarized Fresnel reflectance of a dielectric interface.
///
/// `cos_incident` is the cosine between the incoming direction reversed and the surface normal on
/// the incident side (clamped to [0, 1]); `eta_incident` and `eta_transmitted` are the refractive
/// indices of the medium the light comes from and the one it enters (both > 0).
pub fn dielectric(cos_incident: f64, eta_incident: f64, eta_transmitted: f64) -> DielectricFresnel {
    let cos_i = if cos_incident.is_nan() {
        0.0
    } else {
        cos_incident.clamp(0.0, 1.0)
    };
    let eta = eta_incident / eta_transmitted;
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 || !sin2_t.is_finite() {
        return DielectricFresnel {
            rs: 1.0,
            rp: 1.0,
            reflectance: 1.0,
            transmittance: 0.0,
            cos_transmitted: 0.0,
            total_internal_reflection: true,
        };
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let (n1, n2) = (eta_incident, eta_transmitted);
    let rs = amplitude_squared(n1 * cos_i - n2 * cos_t, n1 * cos_i + n2 * cos_t);
    let rp = amplitude_squared(n2 * cos_i - n1 * cos_t, n2 * cos_i + n1 * cos_t);
    let reflectance = (0.5 * (rs + rp)).clamp(0.0, 1.0);
    DielectricFresnel {
        rs,
        rp,
        reflectance,
        transmittance: 1.0 - reflectance,
        cos_transmitted: cos_t,
        total_internal_reflection: false,
    }
}

/// `(numerator / denominator)²`, taken as 1 when the denominator vanishes (grazing incidence,
/// where every reflectance tends to 1).
fn amplitude_squared(numerator: f64, denominator: f64) -> f64 {
    if denominator.abs() <= f64::MIN_POSITIVE {
        1.0
    } else {
        let r = numerator / denominator;
        (r * r).min(1.0)
    }
}

/// Schlick's approximation `R0 + (1 − R0)(1 − cos θ)⁵` per colour channel, for mirrors.
///
/// `normal_incidence` is the reflectance at normal incidence per channel (each in [0, 1]);
/// `cos_incident` is clamped to [0, 1].
pub fn schlick(normal_incidence: DVec3, cos_incident: f64) -> DVec3 {
    let cos_i = if cos_incident.is_nan() {
        0.0
    } else {
        cos_incident.clamp(0.0, 1.0)
    };
    let m = (1.0 - cos_i).powi(5);
    normal_incidence + (DVec3::ONE - normal_incidence) * m
}

/// Mirror reflection of `direction` about `normal` (either side; both unit vectors).
pub fn reflect(direction: DVec3, normal: DVec3) -> DVec3 {
    (direction - 2.0 * direction.dot(normal) * normal).normalize()
}

/// Snell refraction of the unit `direction` through an interface whose unit `normal` faces the
/// incident side (`direction · normal ≤ 0`), with `eta = eta_incident / eta_transmitted` and the
/// transmitted cosine from [`dielectric`]. Only meaningful without total internal reflection.
pub fn refract(direction: DVec3, normal: DVec3, eta: f64, cos_transmitted: f64) -> DVec3 {
    let cos_i = (-direction.dot(normal)).clamp(0.0, 1.0);
    (eta * direction + (eta * cos_i - cos_transmitted) * normal).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    const IORS: [f64; 4] = [1.33, 1.5, 1.7, 2.4];

    #[test]
    fn normal_incidence_matches_closed_form() {
        for n in IORS {
            let expected = ((n - 1.0) / (n + 1.0)).powi(2);
            let from_outside = dielectric(1.0, 1.0, n);
            let from_inside = dielectric(1.0, n, 1.0);
            assert!(
                (from_outside.reflectance - expected).abs() < 1e-15,
                "n = {n}"
            );
            assert!(
                (from_inside.reflectance - expected).abs() < 1e-15,
                "n = {n}"
            );
        }
    }

    #[test]
    fn p_polarization_vanishes_at_brewster_angle() {
        for n in IORS {
            for (n1, n2) in [(1.0, n), (n, 1.0)] {
                let brewster = (n2 / n1).atan();
                let f = dielectric(brewster.cos(), n1, n2);
                assert!(f.rp < 1e-28, "rp = {} for {n1} → {n2}", f.rp);
                assert!(f.rs > 0.01);
                assert!((f.reflectance - 0.5 * f.rs).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn total_internal_reflection_past_the_critical_angle() {
        for n in IORS {
            let critical = (1.0 / n).asin();
            for k in 1..=50 {
                let angle = critical + (std::f64::consts::FRAC_PI_2 - critical) * k as f64 / 50.0;
                let f = dielectric(angle.cos(), n, 1.0);
                assert_eq!(f.reflectance, 1.0, "n = {n}, angle = {angle}");
                assert_eq!(f.transmittance, 0.0);
                assert!(f.total_internal_reflection);
            }
            // Just before the critical angle some light still leaves.
            let f = dielectric((critical - 1e-3).cos(), n, 1.0);
            assert!(f.reflectance < 1.0 && !f.total_internal_reflection);
        }
    }

    #[test]
    fn reflectance_plus_transmittance_is_one_and_matches_the_textbook_form() {
        for n in IORS {
            for k in 0..=1000 {
                let theta = std::f64::consts::FRAC_PI_2 * k as f64 / 1000.0;
                for (n1, n2) in [(1.0, n), (n, 1.0)] {
                    let f = dielectric(theta.cos(), n1, n2);
                    assert!((f.reflectance + f.transmittance - 1.0).abs() < 1e-15);
                    assert!((0.0..=1.0).contains(&f.reflectance));
                    // Independent form: Fresnel's sine/tangent equations.
                    let sin_t = n1 / n2 * theta.sin();
                    if sin_t < 1.0 && theta > 1e-6 && theta < std::f64::consts::FRAC_PI_2 - 1e-6 {
                        let theta_t = sin_t.asin();
                        let rs = ((theta - theta_t).sin() / (theta + theta_t).sin()).powi(2);
                        let rp = ((theta - theta_t).tan() / (theta + theta_t).tan()).powi(2);
                        assert!((f.rs - rs).abs() < 1e-12, "rs {} vs {rs}", f.rs);
                        assert!((f.rp - rp).abs() < 1e-12, "rp {} vs {rp}", f.rp);
                    }
                }
            }
        }
    }

    #[test]
    fn grazing_and_exactly_critical_incidence_are_finite() {
        for n in IORS {
            let grazing_out = dielectric(0.0, 1.0, n);
            assert_eq!(grazing_out.reflectance, 1.0);
            let grazing_in = dielectric(0.0, n, 1.0);
            assert_eq!(grazing_in.reflectance, 1.0);
            // Exactly critical: sin θt = 1, cos θt = 0.
            let cos_critical = (1.0 - 1.0 / (n * n)).sqrt();
            for cos_i in [
                cos_critical,
                cos_critical * (1.0 + 1e-16),
                cos_critical * (1.0 - 1e-16),
            ] {
                let f = dielectric(cos_i, n, 1.0);
                assert!(f.reflectance.is_finite() && f.cos_transmitted.is_finite());
                assert!(f.reflectance > 0.999, "R = {}", f.reflectance);
            }
            for weird in [-0.5, 1.5, f64::NAN, -0.0] {
                let f = dielectric(weird, 1.0, n);
                assert!(f.reflectance.is_finite() && (0.0..=1.0).contains(&f.reflectance));
            }
            // Equal indices: nothing reflects, even at grazing angles a hair off 90°.
            let f = dielectric(1e-12, n, n);
            assert!(f.reflectance.is_finite());
        }
    }

    #[test]
    fn schlick_endpoints() {
        let r0 = DVec3::new(0.9, 0.5, 0.04);
        assert_eq!(schlick(r0, 1.0), r0);
        assert_eq!(schlick(r0, 0.0), DVec3::ONE);
        assert!(schlick(r0, f64::NAN).is_finite());
    }

    #[test]
    fn refraction_obeys_snell() {
        let normal = DVec3::Z;
        for k in 0..90 {
            let theta = (k as f64).to_radians();
            let d = DVec3::new(theta.sin(), 0.0, -theta.cos());
            let f = dielectric(theta.cos(), 1.0, 1.5);
            let t = refract(d, normal, 1.0 / 1.5, f.cos_transmitted);
            let sin_t = t.x;
            assert!((theta.sin() - 1.5 * sin_t).abs() < 1e-14);
            assert!((t.length() - 1.0).abs() < 1e-14 && t.z <= 0.0);
            let r = reflect(d, normal);
            assert!((r - DVec3::new(d.x, 0.0, -d.z)).length() < 1e-14);
        }
    }
}
