//! Materials: glass and mirror (the "lens" materials that the ray tracer and the hybrid runtime
//! trace through), diffuse (the environment, shaded by point lights), with textures, and glossy
//! (the reflection-space IBR paper's objects).

use glam::{Vec2, Vec3};

/// How a surface scatters light.
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// A dielectric: refraction and reflection by the exact unpolarized Fresnel equations.
    Glass {
        /// Index of refraction relative to the surrounding air (> 0, typically 1.3–2.0).
        ior: f32,
        /// Transmittance per metre of glass, per channel in (0, 1]: light that travels a distance
        /// d inside is multiplied by the attenuation G = absorption^d (1 = clear).
        absorption: Vec3,
    },
    /// A reflector. The tracer applies Schlick's approximation
    /// F(θ) = R₀ + (1 − R₀)(1 − cos θ)⁵ per channel, with R₀ = `reflectance`.
    Mirror {
        /// Reflectance at normal incidence R₀, per channel in [0, 1].
        reflectance: Vec3,
    },
    /// A Lambertian surface: albedo = `colour` × texture(uv) (the texture term is 1 without one).
    Diffuse {
        /// Albedo, per channel in [0, 1].
        colour: Vec3,
        /// Optional texture multiplied into the albedo, sampled at the mesh's uvs.
        texture: Option<Texture>,
    },
    /// A glossy surface: a Lambertian base and a Phong lobe, optionally under a Fresnel clear
    /// coat (`crate::trace::glossy` gives its BRDF). Part of the environment's geometry; the
    /// reference ray tracer integrates its BRDF against everything it sees, while hybrid frames
    /// draw it with its light map, which holds its diffuse base under the point lights.
    Glossy(Glossy),
}

/// A glossy material's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Glossy {
    /// Lambertian albedo kd per channel, in [0, 1].
    pub diffuse: Vec3,
    /// The Phong lobe's reflectance ks per channel, in [0, 1], with kd + ks ≤ 1: the share of
    /// uniform light it reflects at normal incidence.
    pub specular: Vec3,
    /// The Phong exponent m, in [1, 10⁵].
    pub exponent: f32,
    /// A clear coat over the base, if any.
    pub coat: Option<Coat>,
}

/// A Fresnel clear coat: a Phong lobe of its own, weighted by the exact dielectric Fresnel
/// reflectance F at the viewing angle, over the base weighted by 1 − F.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coat {
    /// Index of refraction of the coat, in (1, 3].
    pub ior: f32,
    /// The coat lobe's Phong exponent, in [1, 10⁵].
    pub exponent: f32,
}

impl Material {
    /// The material's kind as a scene file names it (`glass`, `mirror`, `diffuse`, `glossy`),
    /// for messages.
    pub fn kind(&self) -> &'static str {
        match self {
            Material::Glass { .. } => "glass",
            Material::Mirror { .. } => "mirror",
            Material::Diffuse { .. } => "diffuse",
            Material::Glossy(_) => "glossy",
        }
    }

    /// Whether this material makes a lens object (glass or mirror), i.e. is ray traced rather
    /// than approximated by environment maps.
    pub fn is_lens(&self) -> bool {
        matches!(self, Material::Glass { .. } | Material::Mirror { .. })
    }

    /// The diffuse albedo at texture coordinate `uv` (a glossy material's base; zero for glass
    /// and mirror).
    pub fn albedo(&self, uv: Vec2) -> Vec3 {
        match self {
            Material::Diffuse { colour, texture } => {
                *colour * texture.as_ref().map_or(Vec3::ONE, |t| t.sample(uv))
            }
            Material::Glossy(glossy) => glossy.diffuse,
            _ => Vec3::ZERO,
        }
    }
}

/// A texture over uv space (u right, v up; `v = 0` is the bottom row of an image, as in OBJ).
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    /// A procedural checkerboard: `scale` squares per uv unit along u and v; the square with
    /// `floor(u·scale) + floor(v·scale)` even is `a`, odd is `b`.
    Checker {
        /// Colour of the even squares (the one containing uv = (0, 0)+), linear rgb.
        a: Vec3,
        /// Colour of the odd squares, linear rgb.
        b: Vec3,
        /// Squares per uv unit, > 0.
        scale: f32,
    },
    /// An image, repeated over uv space.
    Image(ImageTexture),
}

impl Texture {
    /// The texture's linear rgb value at `uv` (black for a non-finite uv).
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        if !uv.is_finite() {
            return Vec3::ZERO;
        }
        match self {
            Texture::Checker { a, b, scale } => {
                let cell = (uv * *scale).floor();
                let parity = (cell.x as i64 + cell.y as i64).rem_euclid(2);
                if parity == 0 { *a } else { *b }
            }
            Texture::Image(image) => image.sample(uv),
        }
    }
}

/// An image texture in linear rgb, sampled bilinearly with repeat wrapping.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageTexture {
    /// Width in texels, ≥ 1.
    pub width: u32,
    /// Height in texels, ≥ 1.
    pub height: u32,
    /// `width × height` linear rgb texels, row-major, row 0 at the top of the image (v = 1).
    pub texels: Vec<Vec3>,
}

impl ImageTexture {
    /// The texel at integer coordinates, wrapped (repeat) into the image.
    pub fn texel(&self, x: i64, y: i64) -> Vec3 {
        let x = x.rem_euclid(i64::from(self.width.max(1))) as usize;
        let y = y.rem_euclid(i64::from(self.height.max(1))) as usize;
        self.texels
            .get(y * self.width as usize + x)
            .copied()
            .unwrap_or(Vec3::ZERO)
    }

    /// Bilinear sample at `uv` with repeat wrapping; texel (x, y) has its centre at
    /// u = (x + ½)/width, v = 1 − (y + ½)/height.
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        super::image_file::bilinear(
            uv.x * self.width as f32,
            (1.0 - uv.y) * self.height as f32,
            |x, y| self.texel(x, y),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checker_alternates_every_square() {
        let (a, b) = (Vec3::ONE, Vec3::ZERO);
        let checker = Texture::Checker { a, b, scale: 4.0 };
        assert_eq!(checker.sample(Vec2::new(0.1, 0.1)), a);
        assert_eq!(checker.sample(Vec2::new(0.3, 0.1)), b);
        assert_eq!(checker.sample(Vec2::new(0.3, 0.3)), a);
        assert_eq!(checker.sample(Vec2::new(-0.1, 0.1)), b);
        assert_eq!(checker.sample(Vec2::new(-0.1, -0.1)), a);
        assert_eq!(checker.sample(Vec2::new(f32::NAN, 0.0)), Vec3::ZERO);
    }

    #[test]
    fn image_is_bilinear_and_repeats() {
        // 2×1 image: left texel black, right texel white.
        let image = ImageTexture {
            width: 2,
            height: 1,
            texels: vec![Vec3::ZERO, Vec3::ONE],
        };
        // Texel centres: u = 0.25 (black) and 0.75 (white); halfway is grey.
        assert!(
            image
                .sample(Vec2::new(0.25, 0.5))
                .abs_diff_eq(Vec3::ZERO, 1e-6)
        );
        assert!(
            image
                .sample(Vec2::new(0.75, 0.5))
                .abs_diff_eq(Vec3::ONE, 1e-6)
        );
        assert!(
            image
                .sample(Vec2::new(0.5, 0.5))
                .abs_diff_eq(Vec3::splat(0.5), 1e-6)
        );
        // Wrapping: u = 0 is halfway between the right texel (wrapped) and the left one.
        assert!(
            image
                .sample(Vec2::new(0.0, 0.5))
                .abs_diff_eq(Vec3::splat(0.5), 1e-6)
        );
        assert!(
            image
                .sample(Vec2::new(1.75, 3.5))
                .abs_diff_eq(Vec3::ONE, 1e-6)
        );
    }

    #[test]
    fn lens_materials() {
        assert!(
            Material::Glass {
                ior: 1.5,
                absorption: Vec3::ONE
            }
            .is_lens()
        );
        assert!(
            Material::Mirror {
                reflectance: Vec3::ONE
            }
            .is_lens()
        );
        let diffuse = Material::Diffuse {
            colour: Vec3::splat(0.5),
            texture: None,
        };
        assert!(!diffuse.is_lens());
        assert_eq!(diffuse.albedo(Vec2::ZERO), Vec3::splat(0.5));
    }
}
