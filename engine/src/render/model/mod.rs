//! The CPU f64 model of one compositor frame: the same passes the Vulkan frame records, evaluated
//! pixel by pixel in f64, so that a GPU frame can be checked number for number.
//!
//! What is modelled, in the order the GPU does it (see [`render_model`]):
//! 1. colour cleared to (0,0,0,0), depth to 1;
//! 2. environment meshes, no culling, depth test LESS with write, output (colour, 1);
//! 3. per lens object: a prime pass (front faces, or both for [`super::LensFaces::Both`]; LESS,
//!    depth write, output (0,0,0,0)), then for each viewpoint with a non-zero weight and each
//!    term the object has (refraction before reflection) a group of n layer passes front to back
//!    (LESS_OR_EQUAL, no depth write, blend `src·(1 − dstα) + dst` on colour and alpha, the
//!    shader emitting `(texel.rgb · FG · w_v, texel.α)`), with an alpha clear between
//!    consecutive groups.
//!
//! Rasterization follows Vulkan: framebuffer coordinates with y down, pixel centres at
//! (x + ½, y + ½), depth `z_clip/w_clip` interpolated linearly in screen space, attributes
//! interpolated perspective-correctly, front faces counter-clockwise by the spec's signed area
//! `a = −½ Σ (x_i y_{i+1} − x_{i+1} y_i)` (a > 0 is front), the top-left rule for exact ties.
//! Texture LODs come from derivatives over the pixel's 2×2 quad (by default coarse: top-right −
//! top-left, bottom-left − top-left), with every quad pixel evaluated by the fragment's own
//! triangle extended beyond its edges, as helper invocations are; cube maps are sampled through
//! [`crate::cubemap::sampling`].
//!
//! The spec leaves the LOD's derivatives (coarse or fine) and its logarithm's precision to the
//! implementation. [`ModelOptions::default`] is the spec's arithmetic with coarse derivatives;
//! [`ModelOptions::lavapipe`] is what Mesa's lavapipe (22.3) does, as measured: fine
//! derivatives and a piecewise-linear log2 ([`LodLog2::PiecewiseLinearOfSquare`]). With it, a
//! random 128×128 sphere frame (n = 1…4, one and two viewpoints, random texels in every level)
//! matches lavapipe's RGBA32F multipass frame to < 9e-6 on every lens pixel not excluded, while
//! the default options differ by up to 5e-2 wherever λ is not clamped.
//!
//! Where a GPU may legitimately differ (coverage at an edge, a depth tie, a cube-face tie, a cube
//! corner), the pixel gets an [`Exclusion`] saying why, and comparisons leave it out.
//!
//! Where it may differ by rounding the spec allows, [`ModelOptions::precision`] asks for
//! [`ModelImage::bounds`]: per pixel and channel an interval every conformant implementation's
//! result lies in (up to f32 arithmetic), from the device's reported filtering precision and the
//! spec's freedom in the LOD ([`crate::cubemap::sampling::sample_cube_bounds`]), carried through
//! the blend passes with interval arithmetic. A comparison on any driver checks the GPU against
//! the interval; one on lavapipe can also check against the nominal value.

//!
//! The model lives in one file per job: `blend` (the blend arithmetic on values), `bounds`
//! (the same over intervals), `raster` (triangles to fragments) and `shading` (the passes at a
//! pixel).

mod blend;
mod bounds;
mod raster;
mod shading;

use std::fmt;

use rayon::prelude::*;

use super::frame_input::FrameInput;
use super::plan::BlendScheme;
pub use crate::cubemap::sampling::{FilterPrecision, LodLog2};
pub use crate::cubemap::sampling::{cube_lod, sample_cube_trilinear};
pub use blend::{
    CompositeGroup, alpha_clear, blend_back_to_front, blend_front_to_back, composite_by_blending,
    composite_closed_form, over,
};
use raster::FrameSetup;
use shading::PixelResult;

/// Why a model pixel is not a fair point of comparison with a GPU frame. A pixel carries the
/// first applicable reason in the order of [`Exclusion::ALL`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Exclusion {
    /// A triangle touching this pixel has a vertex with w ≤ 0 or a depth outside [0, 1]; the GPU
    /// clips it and the model does not, so every pixel of the clipped triangle's screen bounding
    /// box is left out.
    ClippedTriangle,
    /// The pixel centre lies within [`ModelOptions::edge_tolerance_px`] of an edge of a triangle
    /// that could be visible here (or that is visible here): whether the GPU covers the sample
    /// depends on its sub-pixel snapping and tie-break rule, not on the maths.
    NearTriangleEdge,
    /// Two different triangles that could be visible here are within
    /// [`ModelOptions::depth_tolerance`] in depth: the depth test's outcome is decided by
    /// rounding (z-fighting), or a lens object's layer passes blend twice.
    DepthTie,
    /// A quad neighbour's extrapolated attributes are undefined (the triangle's interpolated 1/w
    /// is ≤ 0 there, or a direction is zero or not finite), so the implicit LOD is undefined.
    UndefinedDerivative,
    /// The direction that decides a sample's LOD is within [`ModelOptions::face_tie_tolerance`]
    /// of a cube-face boundary and the competing faces give different LODs: a GPU computing in
    /// f32 may select the other face. (The filtered value itself is continuous across faces with
    /// seamless filtering, so only the LOD is at stake.)
    CubeFaceTie,
    /// A sample's bilinear footprint used a cube-corner texel with a non-zero weight, and the
    /// three texels it is made from differ; the spec leaves that texel to the implementation
    /// (the model averages the three, as the spec recommends). Where the three agree the spec
    /// fixes the result and the pixel is not excluded.
    CubeCorner,
    /// Only with [`ModelOptions::flag_quad_straddle`]: the lens pixel's 2×2 quad contains pixels
    /// whose visible surface is another triangle. Vulkan evaluates the quad with helper
    /// invocations of the pixel's own triangle, which the model reproduces exactly, so this is
    /// off by default; it exists for drivers suspected of doing otherwise.
    QuadStraddle,
}

impl Exclusion {
    /// Every reason, in order of precedence.
    pub const ALL: [Exclusion; 7] = [
        Exclusion::ClippedTriangle,
        Exclusion::NearTriangleEdge,
        Exclusion::DepthTie,
        Exclusion::UndefinedDerivative,
        Exclusion::CubeFaceTie,
        Exclusion::CubeCorner,
        Exclusion::QuadStraddle,
    ];

    /// A short lower-case description, for test reports.
    pub fn description(self) -> &'static str {
        match self {
            Exclusion::ClippedTriangle => "touched by a triangle the GPU clips (w ≤ 0 or depth)",
            Exclusion::NearTriangleEdge => "pixel centre on a triangle edge (coverage tie)",
            Exclusion::DepthTie => "two surfaces at equal depth (z-fight)",
            Exclusion::UndefinedDerivative => "quad derivatives undefined",
            Exclusion::CubeFaceTie => "LOD direction on a cube-face boundary",
            Exclusion::CubeCorner => "filter footprint uses a cube-corner texel",
            Exclusion::QuadStraddle => "2×2 quad straddles triangles",
        }
    }

    /// The reason's bit in a pixel's exclusion flags.
    fn bit(self) -> u8 {
        1 << (self as u8)
    }
}

impl fmt::Display for Exclusion {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.description())
    }
}

/// Which pixel's direction decides the implicit LOD of a quad.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LodMode {
    /// Every pixel computes its own λ from its own direction and the quad's coarse derivatives
    /// (the spec's per-fragment LOD).
    #[default]
    PerPixel,
    /// Every pixel of a quad uses the λ of the quad's top-left pixel (its direction, face and the
    /// quad's coarse derivatives), as llvmpipe's "quad LOD" does for 2D textures. Measured on
    /// lavapipe (Mesa 22.3) cube maps do NOT use it (their LOD is per pixel), so this is only
    /// for other implementations.
    PerQuadTopLeft,
}

/// How the implicit LOD's screen-space derivatives are taken over a 2×2 quad.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DerivativeMode {
    /// One pair per quad: ∂/∂x = top-right − top-left, ∂/∂y = bottom-left − top-left.
    #[default]
    Coarse,
    /// Per pixel: ∂/∂x along the pixel's own row, ∂/∂y along its own column.
    Fine,
}

/// Where the alpha clear between groups applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AlphaClearScope {
    /// A full-screen pass: α of every pixel becomes 0 (environment pixels included).
    FullScreen,
    /// The lens object's own pixels only: its mesh drawn with the layer passes' depth test
    /// (LESS_OR_EQUAL, back faces culled) and a colour write mask of A. This is what
    /// `render::plan` records, so it is the default.
    #[default]
    LensCoverage,
}

/// Tolerances and implementation choices of the model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelOptions {
    /// Distance in pixels from a triangle edge within which coverage counts as a tie
    /// ([`Exclusion::NearTriangleEdge`]). Default 1/64: lavapipe snaps vertices to 1/256 pixel.
    pub edge_tolerance_px: f64,
    /// Depth difference below which two surfaces count as tied ([`Exclusion::DepthTie`]).
    /// Default 1e-6 (f32 depth interpolation is good to a few 1e-8).
    pub depth_tolerance: f64,
    /// Relative difference of the two largest direction components below which face selection
    /// counts as a tie ([`Exclusion::CubeFaceTie`]). Default 1e-4.
    pub face_tie_tolerance: f64,
    /// LOD differences between competing faces below this do not count as a tie. Default 1e-6.
    pub lod_tie_tolerance: f64,
    /// Which pixel's direction decides a quad's LOD.
    pub lod_mode: LodMode,
    /// How λ = log2 ρ is evaluated.
    pub lod_log2: LodLog2,
    /// How the quad derivatives are taken.
    pub derivatives: DerivativeMode,
    /// Where alpha clears apply.
    pub alpha_clear: AlphaClearScope,
    /// Flag lens pixels whose quad straddles triangles ([`Exclusion::QuadStraddle`]).
    pub flag_quad_straddle: bool,
    /// The device's filtering precision, for [`ModelImage::bounds`]; `None` (the default) gives
    /// point intervals `[v, v]`. With it, [`Exclusion::CubeCorner`] also covers corner texels
    /// that any LOD in the allowed range would weigh, not only the nominal LOD's.
    pub precision: Option<FilterPrecision>,
    /// The blending scheme whose passes the model evaluates (each in its own arithmetic order;
    /// they agree to f64 rounding).
    pub blend: BlendScheme,
}

impl Default for ModelOptions {
    fn default() -> Self {
        ModelOptions {
            edge_tolerance_px: 1.0 / 64.0,
            depth_tolerance: 1e-6,
            face_tie_tolerance: 1e-4,
            lod_tie_tolerance: 1e-6,
            lod_mode: LodMode::PerPixel,
            lod_log2: LodLog2::Exact,
            derivatives: DerivativeMode::Coarse,
            alpha_clear: AlphaClearScope::LensCoverage,
            flag_quad_straddle: false,
            precision: None,
            blend: BlendScheme::FrontToBack,
        }
    }
}

impl ModelOptions {
    /// The options that match Mesa's lavapipe with default settings (no `GALLIVM_PERF`): the
    /// spec's per-pixel LOD but with llvmpipe's piecewise-linear logarithm
    /// ([`LodLog2::PiecewiseLinearOfSquare`]), otherwise the defaults.
    pub fn lavapipe() -> Self {
        ModelOptions {
            lod_log2: LodLog2::PiecewiseLinearOfSquare,
            derivatives: DerivativeMode::Fine,
            ..ModelOptions::default()
        }
    }
}

/// The model's frame: per pixel f64 RGBA (premultiplied, as the framebuffer holds it), why the
/// pixel is not comparable (if it is not), and whether a lens is its front-most surface.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major, row 0 at the top (framebuffer y = 0).
    pub rgba: Vec<[f64; 4]>,
    /// `Some(reason)` where the pixel is ill-defined for comparison.
    pub exclusion: Vec<Option<Exclusion>>,
    /// The pixel's front-most surface (after all depth tests) is a lens object.
    pub lens_mask: Vec<bool>,
    /// The final depth buffer (1.0 where nothing was drawn).
    pub depth: Vec<f64>,
    /// Per pixel and premultiplied RGBA channel, `[lo, hi]`: where any conformant
    /// implementation's result lies, in exact arithmetic, given [`ModelOptions::precision`]
    /// (`[v, v]` without it). Compare with a slack for f32 arithmetic.
    pub bounds: Vec<[[f64; 2]; 4]>,
}

impl ModelImage {
    /// Index of pixel (x, y) in the per-pixel vectors.
    pub fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }

    /// How many pixels carry each exclusion reason (reasons with no pixels omitted).
    pub fn exclusion_counts(&self) -> Vec<(Exclusion, usize)> {
        Exclusion::ALL
            .iter()
            .map(|&reason| {
                let count = self
                    .exclusion
                    .iter()
                    .filter(|e| **e == Some(reason))
                    .count();
                (reason, count)
            })
            .filter(|&(_, count)| count > 0)
            .collect()
    }

    /// How far `rgba` lies outside pixel `index`'s [`ModelImage::bounds`]: the largest distance
    /// over the channels, 0 when every channel is inside (NaN counts as infinitely far).
    pub fn distance_outside_bounds(&self, index: usize, rgba: [f64; 4]) -> f64 {
        self.bounds[index]
            .iter()
            .zip(rgba)
            .map(|(&[lo, hi], value)| {
                if value.is_nan() {
                    f64::INFINITY
                } else {
                    (lo - value).max(value - hi).max(0.0)
                }
            })
            .fold(0.0, f64::max)
    }

    /// Number of lens pixels with no exclusion: the pixels a lens comparison uses.
    pub fn comparable_lens_pixels(&self) -> usize {
        self.lens_mask
            .iter()
            .zip(&self.exclusion)
            .filter(|(lens, exclusion)| **lens && exclusion.is_none())
            .count()
    }
}

/// Renders `frame` in f64 exactly as the GPU frame's passes define it (module docs), marking
/// pixels that are ill-defined for comparison. Deterministic; parallel over quad rows.
pub fn render_model(frame: &FrameInput, options: &ModelOptions) -> ModelImage {
    let setup = FrameSetup::new(frame, options);
    let (width, height) = (frame.width as usize, frame.height as usize);
    let quad_rows = height.div_ceil(2);
    let rows: Vec<Vec<PixelResult>> = (0..quad_rows)
        .into_par_iter()
        .map(|quad_row| setup.render_quad_row(quad_row))
        .collect();
    let mut image = ModelImage {
        width: frame.width,
        height: frame.height,
        rgba: Vec::with_capacity(width * height),
        exclusion: Vec::with_capacity(width * height),
        lens_mask: Vec::with_capacity(width * height),
        depth: Vec::with_capacity(width * height),
        bounds: Vec::with_capacity(width * height),
    };
    for pixel in rows.into_iter().flatten() {
        image.rgba.push(pixel.rgba);
        image.bounds.push(pixel.bounds);
        image.lens_mask.push(pixel.lens);
        image.depth.push(pixel.depth);
        image.exclusion.push(
            Exclusion::ALL
                .into_iter()
                .find(|reason| pixel.flags & reason.bit() != 0),
        );
    }
    image
}

#[cfg(test)]
mod tests;
