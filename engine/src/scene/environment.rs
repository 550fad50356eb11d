//! What lights the scene: point lights, and the environment at infinity (a constant colour or a
//! latitude-longitude HDR map) seen by rays that leave the scene.
//!
//! The lat-long (equirectangular) mapping, for a unit direction d = (x, y, z) in the right-handed,
//! y-up world:
//!
//! ```text
//! u = ½ + atan2(x, −z) / 2π      ∈ [0, 1)   (−z at u = ½, +x at u = ¾, +z at the seam u = 0 ≡ 1)
//! v = acos(y) / π                ∈ [0, 1]   (+y, the zenith, at v = 0: the top row)
//! d = (sin πv · sin φ, cos πv, −sin πv · cos φ)   with φ = 2π(u − ½)
//! ```
//!
//! Pixel (i, j) of a W×H map (row j = 0 at the top) covers u ∈ [i/W, (i+1)/W] and
//! v ∈ [j/H, (j+1)/H]; its centre is at ((i + ½)/W, (j + ½)/H). Sampling is bilinear between texel
//! centres, wrapping in u and clamping in v.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

/// An isotropic point light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// Position in metres.
    pub position: Vec3,
    /// Radiant intensity per channel (W/sr, linear rgb, ≥ 0): the irradiance at distance d
    /// facing the light is `intensity / d²`.
    pub intensity: Vec3,
}

/// The radiance arriving from infinitely far away along rays that leave the scene.
#[derive(Clone, Debug, PartialEq)]
pub enum Environment {
    /// The same radiance (linear rgb, ≥ 0) in every direction.
    Constant(Vec3),
    /// A latitude-longitude HDR map (see the module documentation for the mapping).
    LatLong(LatLongMap),
}

impl Environment {
    /// Radiance (linear rgb) arriving along `-direction`, i.e. seen looking along `direction`.
    /// `direction` need not be unit length; a zero or non-finite direction is treated as +y.
    pub fn radiance(&self, direction: Vec3) -> Vec3 {
        match self {
            Environment::Constant(colour) => *colour,
            Environment::LatLong(map) => map.radiance(direction),
        }
    }
}

/// A latitude-longitude (equirectangular) environment map in linear rgb.
#[derive(Clone, Debug, PartialEq)]
pub struct LatLongMap {
    /// Width in texels (longitude), ≥ 1.
    pub width: u32,
    /// Height in texels (latitude), ≥ 1.
    pub height: u32,
    /// `width × height` radiance texels (linear rgb, finite, ≥ 0), row-major, row 0 at the zenith.
    pub texels: Vec<Vec3>,
}

/// The lat-long coordinates (u, v) ∈ [0, 1)×[0, 1] of a direction (need not be unit; zero or
/// non-finite → the zenith).
pub fn direction_to_lat_long(direction: Vec3) -> Vec2 {
    let d = direction
        .try_normalize()
        .filter(|d| d.is_finite())
        .unwrap_or(Vec3::Y);
    let u = (0.5 + d.x.atan2(-d.z) / TAU).rem_euclid(1.0);
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    Vec2::new(u, v)
}

/// The unit direction of lat-long coordinates (u, v); the inverse of [`direction_to_lat_long`].
pub fn lat_long_to_direction(uv: Vec2) -> Vec3 {
    let phi = TAU * (uv.x - 0.5);
    let theta = PI * uv.y;
    Vec3::new(
        theta.sin() * phi.sin(),
        theta.cos(),
        -theta.sin() * phi.cos(),
    )
}

impl LatLongMap {
    /// The texel at integer coordinates, wrapping in x and clamping in y.
    pub fn texel(&self, x: i64, y: i64) -> Vec3 {
        let x = x.rem_euclid(i64::from(self.width.max(1))) as usize;
        let y = y.clamp(0, i64::from(self.height.max(1)) - 1) as usize;
        self.texels
            .get(y * self.width as usize + x)
            .copied()
            .unwrap_or(Vec3::ZERO)
    }

    /// Bilinear radiance seen looking along `direction`.
    pub fn radiance(&self, direction: Vec3) -> Vec3 {
        let uv = direction_to_lat_long(direction);
        super::image_file::bilinear(
            uv.x * self.width as f32,
            uv.y * self.height as f32,
            |x, y| self.texel(x, y),
        )
    }
}

/// The softboxes of [`studio`]: centre azimuth and elevation, half extents (all degrees), and
/// radiance.
const SOFTBOXES: [([f32; 4], [f32; 3]); 3] = [
    ([35.0, 30.0, 14.0, 8.0], [6.0, 5.6, 5.0]),
    ([160.0, 15.0, 7.0, 12.0], [1.5, 2.5, 5.0]),
    ([265.0, 55.0, 10.0, 10.0], [4.0, 4.0, 4.0]),
];

/// lensmap's procedural studio, a lat-long map `width × width/2` (the pixel centres'
/// directions, no filtering): a sky graded from a pale horizon to a blue zenith, a dark ground
/// in a 12 × 6 checker of azimuth and elevation, and three bright softboxes (rectangles in
/// azimuth and elevation) at different heights and colours: distant lighting with sharp
/// features for the glossy objects' maps, made in code because the repository holds no HDR
/// image. Azimuth is `atan2(x, −z)` in degrees, [0, 360); elevation `asin(y)`.
pub fn studio(width: u32) -> LatLongMap {
    let width = width.max(2);
    let height = (width / 2).max(1);
    let mut texels = Vec::with_capacity((width * height) as usize);
    for j in 0..height {
        for i in 0..width {
            let uv = Vec2::new(
                (i as f32 + 0.5) / width as f32,
                (j as f32 + 0.5) / height as f32,
            );
            texels.push(studio_radiance(lat_long_to_direction(uv)));
        }
    }
    LatLongMap {
        width,
        height,
        texels,
    }
}

/// [`studio`]'s radiance along unit `direction`.
fn studio_radiance(direction: Vec3) -> Vec3 {
    let azimuth = direction
        .x
        .atan2(-direction.z)
        .to_degrees()
        .rem_euclid(360.0);
    let elevation = direction.y.clamp(-1.0, 1.0).asin().to_degrees();
    for ([az, el, half_az, half_el], radiance) in SOFTBOXES {
        let d_az = (azimuth - az + 180.0).rem_euclid(360.0) - 180.0;
        if d_az.abs() <= half_az && (elevation - el).abs() <= half_el {
            return Vec3::from(radiance);
        }
    }
    if elevation >= 0.0 {
        let t = (elevation / 90.0).sqrt();
        Vec3::new(0.55, 0.6, 0.7).lerp(Vec3::new(0.1, 0.2, 0.5), t)
    } else {
        let cell = (azimuth / 30.0).floor() as i32 + (-elevation / 15.0).floor() as i32;
        if cell % 2 == 0 {
            Vec3::new(0.12, 0.1, 0.08)
        } else {
            Vec3::new(0.05, 0.045, 0.04)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn lat_long_round_trips() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        for _ in 0..1000 {
            let d = Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            );
            let Some(d) = d.try_normalize() else { continue };
            let back = lat_long_to_direction(direction_to_lat_long(d));
            assert!(back.distance(d) < 1e-5, "{d} → {back}");
            let uv = Vec2::new(rng.gen_range(0.0..1.0), rng.gen_range(0.01..0.99));
            let again = direction_to_lat_long(lat_long_to_direction(uv));
            assert!(again.distance(uv) < 1e-4, "{uv} → {again}");
        }
    }

    #[test]
    fn lat_long_axes() {
        let close =
            |d: Vec3, u: f32, v: f32| direction_to_lat_long(d).distance(Vec2::new(u, v)) < 1e-6;
        assert!(close(Vec3::NEG_Z, 0.5, 0.5));
        assert!(close(Vec3::X, 0.75, 0.5));
        assert!(close(Vec3::NEG_X, 0.25, 0.5));
        // At the poles u is arbitrary.
        assert_eq!(direction_to_lat_long(Vec3::Y).y, 0.0);
        assert_eq!(direction_to_lat_long(Vec3::NEG_Y).y, 1.0);
        assert!(
            direction_to_lat_long(Vec3::Z)
                .x
                .min(1.0 - direction_to_lat_long(Vec3::Z).x)
                < 1e-6
        );
    }

    #[test]
    fn lat_long_map_samples_texel_centres() {
        // 4×2 map with a distinct value per texel; looking at a texel centre returns it exactly.
        let texels: Vec<Vec3> = (0..8).map(|i| Vec3::splat(i as f32)).collect();
        let map = LatLongMap {
            width: 4,
            height: 2,
            texels,
        };
        for j in 0..2 {
            for i in 0..4 {
                let uv = Vec2::new((i as f32 + 0.5) / 4.0, (j as f32 + 0.5) / 2.0);
                let value = map.radiance(lat_long_to_direction(uv));
                assert!(
                    (value.x - (j * 4 + i) as f32).abs() < 1e-4,
                    "({i}, {j}): {value}"
                );
            }
        }
        // Exactly at the seam (u = 0), halfway between the last and first texel of the row.
        let seam = map.radiance(lat_long_to_direction(Vec2::new(0.0, 0.25)));
        assert!((seam.x - 1.5).abs() < 1e-4, "{seam}");
        let env = Environment::LatLong(map);
        assert!(env.radiance(Vec3::ZERO).is_finite());
        assert_eq!(
            Environment::Constant(Vec3::ONE).radiance(Vec3::X),
            Vec3::ONE
        );
    }
}
