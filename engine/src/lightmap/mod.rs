//! Light maps for the opaque environment: the PEM paper's parameterized texture maps. Diffuse
//! shading here is view independent (two-sided Lambert with shadows,
//! [`crate::trace::world::TraceScene::shade_diffuse`]), so one texture per environment object,
//! made once per scene, serves every viewpoint: each texel holds the ray-traced outgoing radiance of the surface it
//! covers (texture and shadows included), averaged over k×k sub-samples where the radiance
//! changes within it, and the GPU samples it with bilinear filtering.
//!
//! - [`atlas`]: the parameterization. Each triangle, or each pair of coplanar triangles forming a
//!   quad (a plane's grid cell, a cylinder side's quad), is one planar chart with its own
//!   rectangle in the object's atlas and a gutter; texel density is uniform within a chart.
//! - [`density`]: each chart's density from its distance to the nearest viewpoint, so texels are
//!   about as fine as the pixels that show them, and a texel budget over the whole scene.
//! - [`radiance`]: filling an atlas by ray tracing (rayon over texel rows), adaptive
//!   supersampling, and the gutter's dilation.
//!
//! The texture itself ([`LightMap`]) is plain data below `render/`, like a cube map: the
//! compositor uploads it as RGBA16F and its CPU model samples it the same way.

pub mod atlas;
pub mod density;
pub mod radiance;

use glam::DVec3;
use half::f16;

use crate::options::{Fix, OptionError, names};

pub use atlas::{Atlas, AtlasError, Chart, TexelRect};
pub use density::{PlanError, Viewers, plan_atlases};
pub use radiance::{LightMapStats, LightMappedMesh, build_light_mapped_mesh};

/// Least texel density of any chart by default, texels per metre: what charts far from every
/// viewpoint get, unless the budget lowers it.
pub const DEFAULT_MIN_TEXELS_PER_METRE: f64 = 16.0;

/// Greatest texel density of any chart by default, texels per metre: 4 mm texels, for surfaces
/// right in front of a viewpoint.
pub const DEFAULT_MAX_TEXELS_PER_METRE: f64 = 256.0;

/// Pixels of the scene camera's resolution per texel side by default, at each chart's nearest
/// viewpoint (P). Measured at 640×480 with the default budget, non-lens PSNR against the
/// reference (display sRGB) / build time on two cores / RGBA16F memory: mirror-teapot from
/// viewpoint 0, 49.9 dB, 0.66 s, 31 MiB (uniform 32/m: 39.4 dB, 0.34 s, 14.7 MiB);
/// teapot-room's camera 59.0 dB, 0.70 s, 30 MiB (uniform 32/m: 51.0 dB, 0.37 s, 15.8 MiB).
/// P = 3 gave 46.6 dB on mirror-teapot, too close to 45 dB.
pub const DEFAULT_PIXELS_PER_TEXEL: f64 = 2.0;

/// Largest light-map atlas side by default, texels: an object whose charts do not fit at the
/// requested densities gets them all lowered by one factor of its own.
pub const DEFAULT_MAX_ATLAS_SIZE: u32 = 4096;

/// Texels of all of a scene's light maps together by default: 4 Mi, 32 MiB of RGBA16F, about
/// 0.7 s to fill on two cores. Both measured scenes reach it at P = 2 (mirror-teapot's
/// densities are lowered to 0.78×, teapot-room's to 0.58×); at 8 Mi they took 50–62 MiB and
/// 1.1–1.3 s for +2.6 dB on teapot-room and −1.2 dB on mirror-teapot (texels finer than the
/// pixels alias without mip maps where a surface is seen at a slant).
pub const DEFAULT_MAX_TEXELS: u64 = 4 << 20;

/// Sub-samples per texel side, by default, where the radiance changes within a texel.
pub const DEFAULT_SUPERSAMPLING: u32 = 4;

/// How light maps are made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightMapOptions {
    /// Least texel density of a chart, texels per metre along each chart axis; in [1, 4096].
    /// Lowered only by the caps below.
    pub min_texels_per_metre: f64,
    /// Greatest texel density of a chart, texels per metre; in [`Self::min_texels_per_metre`],
    /// 4096]. Equal to the least, every chart gets that one density.
    pub max_texels_per_metre: f64,
    /// P: a chart's texel is to span about P pixels of the scene camera's resolution seen from
    /// the chart's nearest viewpoint (see [`density`]); in [0.25, 64].
    pub pixels_per_texel: f64,
    /// Largest atlas side, texels; in [16, 16384]. An object whose atlas would be larger has all
    /// its charts' densities lowered by one factor (see [`Atlas::density_scale`]).
    pub max_atlas_size: u32,
    /// Texels of all the scene's atlases together (unused atlas space included); in
    /// [2¹⁶, 2³²]. Over it, every chart's density is lowered by one factor.
    pub max_texels: u64,
    /// k: a texel where the radiance changes (its centre sample differs from a neighbour's)
    /// averages k×k stratified sub-samples; elsewhere its centre sample stands for it. In [1, 16].
    pub supersampling: u32,
}

impl Default for LightMapOptions {
    fn default() -> Self {
        LightMapOptions {
            min_texels_per_metre: DEFAULT_MIN_TEXELS_PER_METRE,
            max_texels_per_metre: DEFAULT_MAX_TEXELS_PER_METRE,
            pixels_per_texel: DEFAULT_PIXELS_PER_TEXEL,
            max_atlas_size: DEFAULT_MAX_ATLAS_SIZE,
            max_texels: DEFAULT_MAX_TEXELS,
            supersampling: DEFAULT_SUPERSAMPLING,
        }
    }
}

impl LightMapOptions {
    /// One density, `texels_per_metre`, for every chart (the caps still apply).
    pub fn uniform(texels_per_metre: f64) -> LightMapOptions {
        LightMapOptions {
            min_texels_per_metre: texels_per_metre,
            max_texels_per_metre: texels_per_metre,
            ..LightMapOptions::default()
        }
    }

    /// Checks every option against its range.
    pub fn validate(&self) -> Result<(), OptionError> {
        let density = |d: f64| d.is_finite() && (1.0..=4096.0).contains(&d);
        OptionError::require(
            density(self.min_texels_per_metre),
            names::LIGHT_MAP_DENSITY,
            self.min_texels_per_metre,
            "give texels per metre in [1, 4096], e.g. 16",
        )?;
        OptionError::require(
            density(self.max_texels_per_metre)
                && self.max_texels_per_metre >= self.min_texels_per_metre,
            names::LIGHT_MAP_MAX_DENSITY,
            self.max_texels_per_metre,
            Fix::naming(
                "give texels per metre in [{0}, 4096], e.g. 256",
                &[names::LIGHT_MAP_DENSITY],
            ),
        )?;
        OptionError::require(
            self.pixels_per_texel.is_finite() && (0.25..=64.0).contains(&self.pixels_per_texel),
            names::LIGHT_MAP_PIXELS_PER_TEXEL,
            self.pixels_per_texel,
            "give pixels per texel in [0.25, 64], e.g. 2",
        )?;
        OptionError::require(
            (16..=16384).contains(&self.max_atlas_size),
            names::LIGHT_MAP_MAX_SIZE,
            self.max_atlas_size,
            "give an atlas side in [16, 16384] texels, e.g. 4096",
        )?;
        OptionError::require(
            (1 << 16..=1 << 32).contains(&self.max_texels),
            names::LIGHT_MAP_MAX_TEXELS,
            self.max_texels,
            "give a texel budget in [65536, 4294967296], e.g. 4194304 (32 MiB)",
        )?;
        OptionError::require(
            (1..=16).contains(&self.supersampling),
            names::LIGHT_MAP_SUPERSAMPLING,
            self.supersampling,
            "give k in [1, 16], e.g. 4",
        )
    }
}

/// One environment object's light map: linear outgoing radiance per texel, RGBA16F as the GPU
/// samples it (α = 1 where a chart is, 0 in unused atlas space), rows top to bottom. Texel
/// `(x, y)` covers texture coordinates `[x/width, (x+1)/width] × [y/height, (y+1)/height]`.
#[derive(Clone, Debug, PartialEq)]
pub struct LightMap {
    /// Width in texels, ≥ 1.
    pub width: u32,
    /// Height in texels, ≥ 1.
    pub height: u32,
    /// `width × height` texels, row-major.
    pub texels: Vec<[f16; 4]>,
}

impl LightMap {
    /// A `width × height` map of one value (a white 1×1 map multiplies vertex colours by 1).
    pub fn uniform(width: u32, height: u32, rgba: [f32; 4]) -> LightMap {
        LightMap {
            width,
            height,
            texels: vec![rgba.map(f16::from_f32); (width as usize) * (height as usize)],
        }
    }

    /// Texel `(x, y)` as f32.
    pub fn texel(&self, x: u32, y: u32) -> [f32; 4] {
        self.texels[(y as usize) * (self.width as usize) + x as usize].map(f16::to_f32)
    }

    /// Bytes on the GPU (RGBA16F, one level).
    pub fn gpu_bytes(&self) -> u64 {
        8 * u64::from(self.width) * u64::from(self.height)
    }

    /// The texels as the bytes of an RGBA16F upload.
    pub fn to_bytes(&self) -> Vec<u8> {
        self.texels
            .iter()
            .flat_map(|t| t.map(f16::to_le_bytes))
            .flatten()
            .collect()
    }

    /// What bilinear filtering with clamp-to-edge addressing returns at texture coordinates
    /// `uv`, in f64 (Vulkan's rule: `u·width − ½`, the four texels around it, weights from the
    /// fraction): the CPU model of the GPU's light-map sampling.
    pub fn sample_bilinear(&self, uv: glam::DVec2) -> DVec3 {
        let at = |coordinate: f64, size: u32| {
            let x = coordinate * f64::from(size) - 0.5;
            let base = x.floor();
            let clamp = |i: f64| i.clamp(0.0, f64::from(size - 1)) as u32;
            (clamp(base), clamp(base + 1.0), x - base)
        };
        let (x0, x1, fx) = at(uv.x, self.width);
        let (y0, y1, fy) = at(uv.y, self.height);
        let texel = |x: u32, y: u32| {
            let t = self.texel(x, y);
            DVec3::new(f64::from(t[0]), f64::from(t[1]), f64::from(t[2]))
        };
        (texel(x0, y0) * (1.0 - fx) + texel(x1, y0) * fx) * (1.0 - fy)
            + (texel(x0, y1) * (1.0 - fx) + texel(x1, y1) * fx) * fy
    }

    /// Checks sizes and values: a non-empty image, one texel per pixel, every value finite.
    pub fn validate(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!(
                "light map is {}×{}; both sides must be ≥ 1",
                self.width, self.height
            ));
        }
        if self.texels.len() != (self.width as usize) * (self.height as usize) {
            return Err(format!(
                "light map has {} texels for {}×{}; give one per texel",
                self.texels.len(),
                self.width,
                self.height
            ));
        }
        if self.texels.iter().flatten().any(|c| !c.is_finite()) {
            return Err("light map has NaN or infinite texels".into());
        }
        Ok(())
    }
}
