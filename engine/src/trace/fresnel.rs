//! Fresnel coefficients and the reflection and refraction directions they weight.
//!
//! Exact unpolarized Fresnel for dielectrics (the average of the s- and p-polarized reflectances,
//! with total internal reflection), Schlick's approximation for mirrors, and the mirror-reflection
//! and Snell-refraction directions. Everything is total: cosines are clamped so grazing incidence
//! and incidence exactly at the critical angle give finite numbers, never NaN.
//!
//! The functions are generic over the float type ([`Real`]): lensmap runs them in f64; the f32
//! instances exist to measure what single precision in the per-vertex stages would cost
//! ([`crate::hybrid::paths::VertexPrecision`]). Called with f64 arguments they infer f64.

use std::ops::{Add, Div, Mul, Neg, Sub};

use glam::{DVec3, Vec3};

/// A float type ray-path arithmetic can run in: f64 (what lensmap ships) or f32 (to measure what
/// single precision costs). Values cross between precisions through f64 ([`DVec3`]), which holds
/// every f32 exactly, so an f32 result stored in an f64 field is still the f32 result.
pub trait Real:
    Copy
    + PartialOrd
    + std::fmt::Debug
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// The 3-vector of this precision (`Vec3`, `DVec3`).
    type Vec3: Vector3<Scalar = Self>;
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// The gap between 1 and the next value (2⁻²³ for f32, 2⁻⁵² for f64).
    const EPSILON: Self;
    /// The smallest positive normal value.
    const MIN_POSITIVE: Self;
    /// +∞.
    const INFINITY: Self;
    /// −∞.
    const NEG_INFINITY: Self;
    /// `x` rounded to this precision.
    fn of(x: f64) -> Self;
    /// The value in f64 (exact).
    fn to_f64(self) -> f64;
    /// √self.
    fn sqrt(self) -> Self;
    /// |self|.
    fn abs(self) -> Self;
    /// self^exponent.
    fn powf(self, exponent: Self) -> Self;
    /// self^exponent.
    fn powi(self, exponent: i32) -> Self;
    /// −1, 0 or 1 by sign (±1 for ±0, as the std method).
    fn signum(self) -> Self;
    /// Neither NaN nor infinite.
    fn is_finite(self) -> bool;
    /// NaN.
    fn is_nan(self) -> bool;
    /// The larger (the other one when either is NaN).
    fn max(self, other: Self) -> Self;
    /// The smaller (the other one when either is NaN).
    fn min(self, other: Self) -> Self;
    /// Clamped to `[low, high]`.
    fn clamp(self, low: Self, high: Self) -> Self;
}

/// The 3-vector of a [`Real`] (glam's `Vec3` or `DVec3`), with the operations the ray-path code
/// uses.
pub trait Vector3:
    Copy
    + PartialEq
    + std::fmt::Debug
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Neg<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Mul<Self::Scalar, Output = Self>
    + Div<Self::Scalar, Output = Self>
{
    /// The component type.
    type Scalar: Real<Vec3 = Self>;
    /// The zero vector.
    const ZERO: Self;
    /// `v` rounded to this precision.
    fn of(v: DVec3) -> Self;
    /// The vector in f64 (exact).
    fn to_dvec3(self) -> DVec3;
    /// All three components `s`.
    fn splat(s: Self::Scalar) -> Self;
    /// From components.
    fn new(x: Self::Scalar, y: Self::Scalar, z: Self::Scalar) -> Self;
    /// The components.
    fn components(self) -> [Self::Scalar; 3];
    /// Dot product.
    fn dot(self, other: Self) -> Self::Scalar;
    /// Cross product.
    fn cross(self, other: Self) -> Self;
    /// Euclidean length.
    fn length(self) -> Self::Scalar;
    /// Squared length.
    fn length_squared(self) -> Self::Scalar;
    /// Unit vector (NaN for zero, as glam's).
    fn normalize(self) -> Self;
    /// Unit vector, or `None` for a zero or non-finite length.
    fn try_normalize(self) -> Option<Self>;
    /// Per-component |·|.
    fn abs(self) -> Self;
    /// The largest component.
    fn max_element(self) -> Self::Scalar;
    /// Per-component minimum.
    fn min(self, other: Self) -> Self;
    /// Per-component maximum.
    fn max(self, other: Self) -> Self;
    /// Every component finite.
    fn is_finite(self) -> bool;
}

macro_rules! real_and_vector {
    ($real:ty, $vector:ty, $from_f64:expr, $from_dvec3:expr, $to_dvec3:expr) => {
        impl Real for $real {
            type Vec3 = $vector;
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const EPSILON: Self = <$real>::EPSILON;
            const MIN_POSITIVE: Self = <$real>::MIN_POSITIVE;
            const INFINITY: Self = <$real>::INFINITY;
            const NEG_INFINITY: Self = <$real>::NEG_INFINITY;
            #[inline]
            fn of(x: f64) -> Self {
                $from_f64(x)
            }
            #[inline]
            fn to_f64(self) -> f64 {
                f64::from(self)
            }
            #[inline]
            fn sqrt(self) -> Self {
                <$real>::sqrt(self)
            }
            #[inline]
            fn abs(self) -> Self {
                <$real>::abs(self)
            }
            #[inline]
            fn powf(self, exponent: Self) -> Self {
                <$real>::powf(self, exponent)
            }
            #[inline]
            fn powi(self, exponent: i32) -> Self {
                <$real>::powi(self, exponent)
            }
            #[inline]
            fn signum(self) -> Self {
                <$real>::signum(self)
            }
            #[inline]
            fn is_finite(self) -> bool {
                <$real>::is_finite(self)
            }
            #[inline]
            fn is_nan(self) -> bool {
                <$real>::is_nan(self)
            }
            #[inline]
            fn max(self, other: Self) -> Self {
                <$real>::max(self, other)
            }
            #[inline]
            fn min(self, other: Self) -> Self {
                <$real>::min(self, other)
            }
            #[inline]
            fn clamp(self, low: Self, high: Self) -> Self {
                <$real>::clamp(self, low, high)
            }
        }

        impl Vector3 for $vector {
            type Scalar = $real;
            const ZERO: Self = <$vector>::ZERO;
            #[inline]
            fn of(v: DVec3) -> Self {
                $from_dvec3(v)
            }
            #[inline]
            fn to_dvec3(self) -> DVec3 {
                $to_dvec3(self)
            }
            #[inline]
            fn splat(s: $real) -> Self {
                <$vector>::splat(s)
            }
            #[inline]
            fn new(x: $real, y: $real, z: $real) -> Self {
                <$vector>::new(x, y, z)
            }
            #[inline]
            fn components(self) -> [$real; 3] {
                self.to_array()
            }
            #[inline]
            fn dot(self, other: Self) -> $real {
                <$vector>::dot(self, other)
            }
            #[inline]
            fn cross(self, other: Self) -> Self {
                <$vector>::cross(self, other)
            }
            #[inline]
            fn length(self) -> $real {
                <$vector>::length(self)
            }
            #[inline]
            fn length_squared(self) -> $real {
                <$vector>::length_squared(self)
            }
            #[inline]
            fn normalize(self) -> Self {
                <$vector>::normalize(self)
            }
            #[inline]
            fn try_normalize(self) -> Option<Self> {
                <$vector>::try_normalize(self)
            }
            #[inline]
            fn abs(self) -> Self {
                <$vector>::abs(self)
            }
            #[inline]
            fn max_element(self) -> $real {
                <$vector>::max_element(self)
            }
            #[inline]
            fn min(self, other: Self) -> Self {
                <$vector>::min(self, other)
            }
            #[inline]
            fn max(self, other: Self) -> Self {
                <$vector>::max(self, other)
            }
            #[inline]
            fn is_finite(self) -> bool {
                <$vector>::is_finite(self)
            }
        }
    };
}

real_and_vector!(f64, DVec3, |x: f64| x, |v: DVec3| v, |v: DVec3| v);
real_and_vector!(
    f32,
    Vec3,
    |x: f64| x as f32,
    |v: DVec3| v.as_vec3(),
    |v: Vec3| v.as_dvec3()
);

/// The Fresnel split of light arriving at a smooth dielectric interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DielectricFresnel<R = f64> {
    /// Amplitude reflection coefficient squared for s-polarized light, in [0, 1].
    pub rs: R,
    /// Amplitude reflection coefficient squared for p-polarized light, in [0, 1].
    pub rp: R,
    /// Unpolarized reflectance `(rs + rp) / 2`, in [0, 1]; 1 under total internal reflection.
    pub reflectance: R,
    /// Unpolarized transmittance `1 − reflectance`, in [0, 1] (energy, without the radiance
    /// scaling by the squared IOR ratio, as in the paper's `T̂F`).
    pub transmittance: R,
    /// Cosine of the refraction angle, in [0, 1]; 0 under total internal reflection.
    pub cos_transmitted: R,
    /// True when no light is transmitted (incidence at or past the critical angle).
    pub total_internal_reflection: bool,
}

/// Exact unpolarized Fresnel reflectance of a dielectric interface.
///
/// `cos_incident` is the cosine between the incoming direction reversed and the surface normal on
/// the incident side (clamped to [0, 1]); `eta_incident` and `eta_transmitted` are the refractive
/// indices of the medium the light comes from and the one it enters (both > 0).
pub fn dielectric<R: Real>(
    cos_incident: R,
    eta_incident: R,
    eta_transmitted: R,
) -> DielectricFresnel<R> {
    let (zero, one) = (R::ZERO, R::ONE);
    let cos_i = if cos_incident.is_nan() {
        zero
    } else {
        cos_incident.clamp(zero, one)
    };
    let eta = eta_incident / eta_transmitted;
    let sin2_t = eta * eta * (one - cos_i * cos_i).max(zero);
    if sin2_t >= one || !sin2_t.is_finite() {
        return DielectricFresnel {
            rs: one,
            rp: one,
            reflectance: one,
            transmittance: zero,
            cos_transmitted: zero,
            total_internal_reflection: true,
        };
    }
    let cos_t = (one - sin2_t).sqrt();
    let (n1, n2) = (eta_incident, eta_transmitted);
    let rs = amplitude_squared(n1 * cos_i - n2 * cos_t, n1 * cos_i + n2 * cos_t);
    let rp = amplitude_squared(n2 * cos_i - n1 * cos_t, n2 * cos_i + n1 * cos_t);
    let reflectance = (R::of(0.5) * (rs + rp)).clamp(zero, one);
    DielectricFresnel {
        rs,
        rp,
        reflectance,
        transmittance: one - reflectance,
        cos_transmitted: cos_t,
        total_internal_reflection: false,
    }
}

/// `(numerator / denominator)²`, taken as 1 when the denominator vanishes (grazing incidence,
/// where every reflectance tends to 1).
fn amplitude_squared<R: Real>(numerator: R, denominator: R) -> R {
    if denominator.abs() <= R::MIN_POSITIVE {
        R::ONE
    } else {
        let r = numerator / denominator;
        (r * r).min(R::ONE)
    }
}

/// Schlick's approximation `R0 + (1 − R0)(1 − cos θ)⁵` per colour channel, for mirrors.
///
/// `normal_incidence` is the reflectance at normal incidence per channel (each in [0, 1]);
/// `cos_incident` is clamped to [0, 1].
pub fn schlick<V: Vector3>(normal_incidence: V, cos_incident: V::Scalar) -> V {
    schlick_by(normal_incidence, cos_incident, |c| {
        (<V::Scalar as Real>::ONE - c).powi(5)
    })
}

/// [`schlick`] with its fifth-order term given by `fifth_power(c) ≈ (1 − c)⁵` (evaluated, or
/// looked up in a [`SchlickTable`](super::schlick_table::SchlickTable)), called with the cosine
/// clamped to [0, 1].
pub fn schlick_by<V: Vector3>(
    normal_incidence: V,
    cos_incident: V::Scalar,
    fifth_power: impl Fn(V::Scalar) -> V::Scalar,
) -> V {
    let one = <V::Scalar as Real>::ONE;
    let cos_i = if cos_incident.is_nan() {
        <V::Scalar as Real>::ZERO
    } else {
        cos_incident.clamp(<V::Scalar as Real>::ZERO, one)
    };
    let m = fifth_power(cos_i);
    normal_incidence + (V::splat(one) - normal_incidence) * m
}

/// Schlick's approximation at a dielectric interface, with the fifth-order term given by
/// `fifth_power(c) ≈ (1 − c)⁵`: `R = R0 + (1 − R0)·fifth_power(c)`, `R0 = ((n1 − n2)/(n1 + n2))²`
/// (the same both ways), where `c` is the cosine on the optically thinner side, as the
/// approximation assumes: `cos θi` entering a denser medium, the transmitted `cos θt` (Snell's
/// law) leaving it. Past the critical angle there is no transmitted ray: total internal
/// reflection, `R = 1`, as [`dielectric`] says. Arguments as [`dielectric`]'s. Schlick does not
/// split the polarizations: `rs` and `rp` are both `R`.
pub fn dielectric_schlick<R: Real>(
    cos_incident: R,
    eta_incident: R,
    eta_transmitted: R,
    fifth_power: impl Fn(R) -> R,
) -> DielectricFresnel<R> {
    let (zero, one) = (R::ZERO, R::ONE);
    let exact = dielectric(cos_incident, eta_incident, eta_transmitted);
    if exact.total_internal_reflection {
        return exact;
    }
    let cos_i = if cos_incident.is_nan() {
        zero
    } else {
        cos_incident.clamp(zero, one)
    };
    let thinner_side = if eta_incident > eta_transmitted {
        exact.cos_transmitted
    } else {
        cos_i
    };
    let r0 = amplitude_squared(
        eta_incident - eta_transmitted,
        eta_incident + eta_transmitted,
    );
    let reflectance = (r0 + (one - r0) * fifth_power(thinner_side)).clamp(zero, one);
    DielectricFresnel {
        rs: reflectance,
        rp: reflectance,
        reflectance,
        transmittance: one - reflectance,
        cos_transmitted: exact.cos_transmitted,
        total_internal_reflection: false,
    }
}

/// Mirror reflection of `direction` about `normal` (either side; both unit vectors).
pub fn reflect<V: Vector3>(direction: V, normal: V) -> V {
    let two = <V::Scalar as Real>::of(2.0);
    (direction - normal * (two * direction.dot(normal))).normalize()
}

/// Snell refraction of the unit `direction` through an interface whose unit `normal` faces the
/// incident side (`direction · normal ≤ 0`), with `eta = eta_incident / eta_transmitted` and the
/// transmitted cosine from [`dielectric`]. Only meaningful without total internal reflection.
pub fn refract<V: Vector3>(
    direction: V,
    normal: V,
    eta: V::Scalar,
    cos_transmitted: V::Scalar,
) -> V {
    let cos_i = (-direction.dot(normal)).clamp(<V::Scalar as Real>::ZERO, <V::Scalar as Real>::ONE);
    (direction * eta + normal * (eta * cos_i - cos_transmitted)).normalize()
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

    /// Schlick at a dielectric against its closed form on both sides: `R0` at normal incidence,
    /// 1 at grazing entry and at the critical angle leaving, the light side's cosine leaving, and
    /// close to exact Fresnel throughout (Schlick's own error at n = 1.5 peaks at 0.0357, the same both ways).
    #[test]
    fn dielectric_schlick_uses_the_light_sides_cosine_and_total_internal_reflection() {
        let fifth = |c: f64| (1.0 - c).powi(5);
        for n in IORS {
            let r0 = ((n - 1.0) / (n + 1.0)).powi(2);
            for (n1, n2) in [(1.0, n), (n, 1.0)] {
                let at_normal = dielectric_schlick(1.0, n1, n2, fifth);
                assert!((at_normal.reflectance - r0).abs() < 1e-15);
            }
            assert_eq!(dielectric_schlick(0.0, 1.0, n, fifth).reflectance, 1.0);
            let critical = (1.0 / n).asin();
            for k in 0..=200 {
                let theta = std::f64::consts::FRAC_PI_2 * f64::from(k) / 200.0;
                let leaving = dielectric_schlick(theta.cos(), n, 1.0, fifth);
                if theta >= critical {
                    assert_eq!(leaving.reflectance, 1.0, "n = {n}, θ = {theta}");
                    assert!(leaving.total_internal_reflection);
                } else {
                    let theta_t = (n * theta.sin()).asin();
                    let expected = r0 + (1.0 - r0) * (1.0 - theta_t.cos()).powi(5);
                    assert!((leaving.reflectance - expected).abs() < 1e-12);
                    assert!((leaving.reflectance + leaving.transmittance - 1.0).abs() < 1e-15);
                }
                let entering = dielectric_schlick(theta.cos(), 1.0, n, fifth);
                let expected = r0 + (1.0 - r0) * (1.0 - theta.cos()).powi(5);
                assert!((entering.reflectance - expected).abs() < 1e-15);
                if n == 1.5 {
                    for (n1, n2) in [(1.0, n), (n, 1.0)] {
                        let exact = dielectric(theta.cos(), n1, n2).reflectance;
                        let schlick = dielectric_schlick(theta.cos(), n1, n2, fifth).reflectance;
                        assert!((schlick - exact).abs() < 0.036, "θ = {theta}");
                    }
                }
            }
        }
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
