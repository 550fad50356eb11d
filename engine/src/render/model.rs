//! The CPU f64 model of one compositor frame: the same passes the Vulkan frame records, evaluated
//! pixel by pixel in f64, so that a GPU frame can be checked number for number (issue 2, item 8).
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
//! [`ModelOptions::lavapipe`] is what Mesa's lavapipe (22.3) was measured to do: fine
//! derivatives and a piecewise-linear log2 ([`LodLog2::PiecewiseLinearOfSquare`]). With it, a
//! random 128×128 sphere frame (n = 1…4, one and two viewpoints, random texels in every level)
//! matched lavapipe's RGBA32F multipass frame to < 9e-6 on every lens pixel not excluded, while
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

use std::fmt;

use glam::{DMat4, DVec2, DVec3, DVec4};
use rayon::prelude::*;

use super::frame_input::{FrameInput, LensObject};
use super::plan::BlendScheme;
use crate::cubemap::CubeMap;
use crate::cubemap::face::{competing_faces, major_face};
pub use crate::cubemap::sampling::{FilterPrecision, LodLog2};
pub use crate::cubemap::sampling::{cube_lod, sample_cube_trilinear};
use crate::cubemap::sampling::{
    cube_lod_on_face, cube_lod_range_on_face, sample_cube, sample_cube_bounds,
};
use crate::lightmap::LightMap;
use crate::trace::Term;

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

/// Premultiplied "over": `front + (1 − front.α)·back` on all four channels.
pub fn over(front: [f64; 4], back: [f64; 4]) -> [f64; 4] {
    std::array::from_fn(|c| front[c] + (1.0 - front[3]) * back[c])
}

/// The layer passes' blend, front to back ("under"): `src·(1 − dst.α) + dst·1` on colour and
/// alpha, i.e. `dst over src`.
pub fn blend_front_to_back(dst: [f64; 4], src: [f64; 4]) -> [f64; 4] {
    std::array::from_fn(|c| src[c] * (1.0 - dst[3]) + dst[c])
}

/// The alpha clear between groups: rgb × 1, α × 0.
pub fn alpha_clear(dst: [f64; 4]) -> [f64; 4] {
    [dst[0], dst[1], dst[2], 0.0]
}

/// One (viewpoint, term) group at one pixel: its weight `w_v`, its F·G, and the filtered
/// premultiplied layer samples front to back.
#[derive(Clone, Debug, PartialEq)]
pub struct CompositeGroup {
    /// Viewpoint weight w_v.
    pub weight: f64,
    /// The term's interpolated F·G (rgb).
    pub fg: [f64; 3],
    /// Premultiplied layer samples L1 … Ln, nearest first.
    pub layers: Vec<[f64; 4]>,
}

/// The shader's output for one layer of a group: `(texel.rgb · FG · w, texel.α)`.
fn layer_source(group_weight: f64, fg: [f64; 3], texel: [f64; 4]) -> [f64; 4] {
    [
        texel[0] * fg[0] * group_weight,
        texel[1] * fg[1] * group_weight,
        texel[2] * fg[2] * group_weight,
        texel[3],
    ]
}

/// The GPU's pass sequence at one lens pixel, starting from the prime's (0,0,0,0): each group's
/// layers blended front to back, an alpha clear between consecutive groups.
pub fn composite_by_blending(groups: &[CompositeGroup]) -> [f64; 4] {
    let mut dst = [0.0; 4];
    for (index, group) in groups.iter().enumerate() {
        if index > 0 {
            dst = alpha_clear(dst);
        }
        for &layer in &group.layers {
            dst = blend_front_to_back(dst, layer_source(group.weight, group.fg, layer));
        }
    }
    dst
}

/// The paper's closed form at one lens pixel: rgb = Σ_groups w·FG ⊙ (L1 over … over Ln).rgb,
/// α = the last group's (L1 over … over Ln).α.
pub fn composite_closed_form(groups: &[CompositeGroup]) -> [f64; 4] {
    let mut result = [0.0; 4];
    for group in groups {
        let composite = group
            .layers
            .iter()
            .rev()
            .fold([0.0; 4], |back, &front| over(front, back));
        for c in 0..3 {
            result[c] += group.weight * group.fg[c] * composite[c];
        }
        result[3] = composite[3];
    }
    result
}

/// A closed interval `[lo, hi]`, one per premultiplied channel in [`ModelImage::bounds`].
type Interval = [f64; 2];

/// Point intervals `[v, v]`.
fn point_bounds(rgba: [f64; 4]) -> [Interval; 4] {
    rgba.map(|v| [v, v])
}

/// `{x·y : x ∈ a, y ∈ b}`, whatever the signs.
fn interval_product(a: Interval, b: Interval) -> Interval {
    let products = [a[0] * b[0], a[0] * b[1], a[1] * b[0], a[1] * b[1]];
    [
        products.into_iter().fold(f64::INFINITY, f64::min),
        products.into_iter().fold(f64::NEG_INFINITY, f64::max),
    ]
}

/// [`layer_source`] over a texel interval (weight and F·G exact).
fn layer_source_bounds(group_weight: f64, fg: [f64; 3], texel: [Interval; 4]) -> [Interval; 4] {
    let scale = |c: usize| {
        interval_product(
            interval_product(texel[c], [fg[c], fg[c]]),
            [group_weight, group_weight],
        )
    };
    [scale(0), scale(1), scale(2), texel[3]]
}

/// [`blend_front_to_back`] over intervals: contains the blend of every `dst`, `src` in them.
fn blend_front_to_back_bounds(dst: [Interval; 4], src: [Interval; 4]) -> [Interval; 4] {
    let transmittance = [1.0 - dst[3][1], 1.0 - dst[3][0]];
    let mut out: [Interval; 4] = std::array::from_fn(|c| {
        let scaled = interval_product(src[c], transmittance);
        [scaled[0] + dst[c][0], scaled[1] + dst[c][1]]
    });
    // α: src·(1 − dst) + dst rises in both src and dst when both lie in [0, 1], so its ends are
    // exact there (the general form above counts dst twice and is wider).
    let unit = |a: Interval| 0.0 <= a[0] && a[1] <= 1.0;
    if unit(src[3]) && unit(dst[3]) {
        let alpha = |s: f64, d: f64| s * (1.0 - d) + d;
        out[3] = [alpha(src[3][0], dst[3][0]), alpha(src[3][1], dst[3][1])];
    }
    out
}

/// The back-to-front blend `src + dst·(1 − srcα)` (classic "over") over intervals.
fn blend_back_to_front_bounds(dst: [Interval; 4], src: [Interval; 4]) -> [Interval; 4] {
    let transmittance = [1.0 - src[3][1], 1.0 - src[3][0]];
    let mut out: [Interval; 4] = std::array::from_fn(|c| {
        let scaled = interval_product(dst[c], transmittance);
        [src[c][0] + scaled[0], src[c][1] + scaled[1]]
    });
    // α: s + d·(1 − s) rises in both when both lie in [0, 1].
    let unit = |a: Interval| 0.0 <= a[0] && a[1] <= 1.0;
    if unit(src[3]) && unit(dst[3]) {
        let alpha = |s: f64, d: f64| s + d * (1.0 - s);
        out[3] = [alpha(src[3][0], dst[3][0]), alpha(src[3][1], dst[3][1])];
    }
    out
}

/// The back-to-front blend on values: `src + dst·(1 − srcα)` on colour and alpha.
pub fn blend_back_to_front(dst: [f64; 4], src: [f64; 4]) -> [f64; 4] {
    std::array::from_fn(|c| src[c] + dst[c] * (1.0 - src[3]))
}

/// Adds `src` to `dst` on the channels of `mask` (bit c: channel c), as an additive blend with
/// that colour write mask does.
fn add_masked(dst: [f64; 4], src: [f64; 4], mask: u8) -> [f64; 4] {
    std::array::from_fn(|c| {
        if mask & (1 << c) != 0 {
            dst[c] + src[c]
        } else {
            dst[c]
        }
    })
}

/// [`add_masked`] over intervals.
fn add_masked_bounds(dst: [Interval; 4], src: [Interval; 4], mask: u8) -> [Interval; 4] {
    std::array::from_fn(|c| {
        if mask & (1 << c) != 0 {
            [dst[c][0] + src[c][0], dst[c][1] + src[c][1]]
        } else {
            dst[c]
        }
    })
}

/// The alpha clear over intervals: α becomes exactly 0.
fn alpha_clear_bounds(dst: [Interval; 4]) -> [Interval; 4] {
    [dst[0], dst[1], dst[2], [0.0, 0.0]]
}

/// The range of a light map's bilinear rgb at `uv` over fractions snapped to the sub-texel grid
/// (the same rectangle-corner argument as the cube maps', same clamp-to-edge footprint as
/// [`LightMap::sample_bilinear`]).
fn light_map_bounds(map: &LightMap, uv: DVec2, precision: FilterPrecision) -> [Interval; 3] {
    let step = precision.sub_texel_step();
    let axis = |coordinate: f64, size: u32| {
        let x = coordinate * f64::from(size) - 0.5;
        let base = x.floor();
        let clamp = |i: f64| i.clamp(0.0, f64::from(size - 1)) as u32;
        let fraction = x - base;
        (
            [clamp(base), clamp(base + 1.0)],
            [(fraction - step).max(0.0), (fraction + step).min(1.0)],
        )
    };
    let (xs, fxs) = axis(uv.x, map.width);
    let (ys, fys) = axis(uv.y, map.height);
    let texel = |x: u32, y: u32| map.texel(x, y).map(f64::from);
    let mut bounds = [[f64::INFINITY, f64::NEG_INFINITY]; 3];
    for fx in fxs {
        for fy in fys {
            for (c, bound) in bounds.iter_mut().enumerate() {
                let value = (texel(xs[0], ys[0])[c] * (1.0 - fx) + texel(xs[1], ys[0])[c] * fx)
                    * (1.0 - fy)
                    + (texel(xs[0], ys[1])[c] * (1.0 - fx) + texel(xs[1], ys[1])[c] * fx) * fy;
                *bound = [bound[0].min(value), bound[1].max(value)];
            }
        }
    }
    bounds
}

/// Renders `frame` with [`ModelOptions::default`]. See [`render_model_with`].
pub fn render_model(frame: &FrameInput) -> ModelImage {
    render_model_with(frame, &ModelOptions::default())
}

/// Renders `frame` in f64 exactly as the GPU frame's passes define it (module docs), marking
/// pixels that are ill-defined for comparison. Deterministic; parallel over quad rows.
pub fn render_model_with(frame: &FrameInput, options: &ModelOptions) -> ModelImage {
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

/// Which draw a triangle belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Source {
    Environment { mesh: usize },
    Lens { object: usize },
}

/// A triangle after the vertex stage and viewport transform.
#[derive(Clone, Debug)]
struct ScreenTriangle {
    source: Source,
    vertices: [usize; 3],
    /// Framebuffer coordinates (y down).
    position: [DVec2; 3],
    /// z_clip / w_clip.
    depth: [f64; 3],
    inv_w: [f64; 3],
    /// cross(p1 − p0, p2 − p0); Vulkan's signed area is −cross/2.
    cross: f64,
    /// The passes draw it: environment triangles always, lens triangles when front-facing or
    /// when their lens draws both faces.
    drawn: bool,
    /// Drawn, or so thin that a GPU's facing decision could differ (then every pixel it could
    /// cover is near one of its edges anyway).
    possibly_drawn: bool,
    edge_length: [f64; 3],
    /// Whether an exact tie on edge i counts as covered (top-left rule).
    top_left: [bool; 3],
    /// Inclusive pixel bounds, already clamped to the framebuffer.
    x_range: (i64, i64),
    y_range: (i64, i64),
}

impl ScreenTriangle {
    /// Edge functions E_i(q) = cross(p_{i+2} − p_{i+1}, q − p_{i+1}); Σ E_i = cross.
    fn edge_values(&self, q: DVec2) -> [f64; 3] {
        std::array::from_fn(|i| {
            let a = self.position[(i + 1) % 3];
            let b = self.position[(i + 2) % 3];
            let e = b - a;
            let r = q - a;
            e.x * r.y - e.y * r.x
        })
    }

    /// Perspective-correct barycentric weights at `q` (inside or outside the triangle), or
    /// `None` where the interpolated 1/w is not positive.
    fn perspective_weights(&self, q: DVec2) -> Option<[f64; 3]> {
        let e = self.edge_values(q);
        let screen: [f64; 3] = std::array::from_fn(|i| e[i] / self.cross * self.inv_w[i]);
        let sum = screen[0] + screen[1] + screen[2];
        (sum > 0.0 && sum.is_finite()).then(|| screen.map(|w| w / sum))
    }
}

/// A triangle's sample at one pixel.
#[derive(Clone, Copy, Debug)]
struct Fragment {
    triangle: usize,
    covered: bool,
    near_edge: bool,
    depth: f64,
}

/// One pixel of the model's output before the exclusion bits become a reason.
#[derive(Clone, Copy, Debug)]
struct PixelResult {
    rgba: [f64; 4],
    bounds: [Interval; 4],
    depth: f64,
    lens: bool,
    flags: u8,
    visible: Option<usize>,
}

/// The per-frame data every quad row reads.
struct FrameSetup<'a> {
    frame: &'a FrameInput,
    options: ModelOptions,
    triangles: Vec<ScreenTriangle>,
    /// Pixels touched by a clipped triangle.
    clipped: Vec<bool>,
    /// Per lens object, its groups as (viewpoint, term index into `object.terms`) in pass order.
    groups: Vec<Vec<(usize, usize)>>,
}

impl<'a> FrameSetup<'a> {
    fn new(frame: &'a FrameInput, options: &ModelOptions) -> Self {
        let view_proj: DMat4 = frame.view_proj.as_dmat4();
        let (width, height) = (frame.width as usize, frame.height as usize);
        let mut setup = FrameSetup {
            frame,
            options: *options,
            triangles: Vec::new(),
            clipped: vec![false; width * height],
            groups: Vec::new(),
        };
        for (mesh, environment) in frame.environment.iter().enumerate() {
            let clip: Vec<DVec4> = environment
                .positions
                .iter()
                .map(|p| view_proj * p.as_dvec3().extend(1.0))
                .collect();
            for triangle in &environment.triangles {
                setup.add_triangle(Source::Environment { mesh }, &clip, *triangle);
            }
        }
        for (object, lens) in frame.lenses.iter().enumerate() {
            let clip: Vec<DVec4> = lens
                .positions
                .iter()
                .map(|p| view_proj * p.as_dvec3().extend(1.0))
                .collect();
            for triangle in &lens.triangles {
                setup.add_triangle(Source::Lens { object }, &clip, *triangle);
            }
            setup.groups.push(lens_groups(frame, lens));
        }
        setup
    }

    fn add_triangle(&mut self, source: Source, clip: &[DVec4], indices: [u32; 3]) {
        let vertices = indices.map(|i| i as usize);
        let Some(c) = vertices
            .iter()
            .map(|&v| clip.get(v).copied())
            .collect::<Option<Vec<DVec4>>>()
        else {
            return;
        };
        let (width, height) = (f64::from(self.frame.width), f64::from(self.frame.height));
        let inside = |v: &DVec4| v.w > 0.0 && v.z >= 0.0 && v.z <= v.w;
        if !c.iter().all(inside) {
            self.mark_clipped(&c);
            return;
        }
        let position: [DVec2; 3] = std::array::from_fn(|i| {
            let ndc = c[i].truncate() / c[i].w;
            DVec2::new((ndc.x + 1.0) * 0.5 * width, (ndc.y + 1.0) * 0.5 * height)
        });
        let depth: [f64; 3] = std::array::from_fn(|i| c[i].z / c[i].w);
        let inv_w: [f64; 3] = std::array::from_fn(|i| 1.0 / c[i].w);
        let cross = (position[1] - position[0]).perp_dot(position[2] - position[0]);
        if cross == 0.0 || !cross.is_finite() {
            // Zero area covers no sample.
            return;
        }
        let edge_length: [f64; 3] =
            std::array::from_fn(|i| (position[(i + 2) % 3] - position[(i + 1) % 3]).length());
        let top_left: [bool; 3] = std::array::from_fn(|i| {
            let e = position[(i + 2) % 3] - position[(i + 1) % 3];
            // ∇E_i = (−e.y, e.x); times sign(cross) it points into the triangle. Top-left rule
            // with y down: a left edge has the interior to its right (+x), a top edge is
            // horizontal with the interior below it (+y).
            let inward = DVec2::new(-e.y, e.x) * cross.signum();
            inward.x > 0.0 || (inward.x == 0.0 && inward.y > 0.0)
        });
        // Vulkan: a = −½ Σ (x_i y_{i+1} − x_{i+1} y_i) = −cross/2, front-facing (CCW) if a > 0.
        let front = cross < 0.0;
        let drawn = match source {
            Source::Environment { .. } => true,
            Source::Lens { object } => {
                front || self.frame.lenses[object].faces == super::LensFaces::Both
            }
        };
        let longest = edge_length.iter().copied().fold(0.0, f64::max);
        let thin = cross.abs() / longest < self.options.edge_tolerance_px;
        let margin = self.options.edge_tolerance_px;
        let pixel_range = |lo: f64, hi: f64, size: f64| -> (i64, i64) {
            // Pixel k's centre k + ½ must lie in [lo − margin, hi + margin].
            let first = (lo - margin - 0.5).ceil().max(0.0);
            let last = (hi + margin - 0.5).floor().min(size - 1.0);
            (first as i64, last as i64)
        };
        let xs = position.map(|p| p.x);
        let ys = position.map(|p| p.y);
        let x_range = pixel_range(
            xs.iter().copied().fold(f64::INFINITY, f64::min),
            xs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            width,
        );
        let y_range = pixel_range(
            ys.iter().copied().fold(f64::INFINITY, f64::min),
            ys.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            height,
        );
        self.triangles.push(ScreenTriangle {
            source,
            vertices,
            position,
            depth,
            inv_w,
            cross,
            drawn,
            possibly_drawn: drawn || thin,
            edge_length,
            top_left,
            x_range,
            y_range,
        });
    }

    /// Marks the screen bounding box (plus a pixel) of the visible part of a triangle the GPU
    /// would clip: the triangle clipped to 0 ≤ z ≤ w and w > 0, projected.
    fn mark_clipped(&mut self, clip: &[DVec4]) {
        let mut polygon: Vec<DVec4> = clip.to_vec();
        let planes: [fn(DVec4) -> f64; 3] = [|v| v.z, |v| v.w - v.z, |v| v.w - 1e-12 * v.w.abs()];
        for plane in planes {
            let mut next = Vec::with_capacity(polygon.len() + 1);
            for k in 0..polygon.len() {
                let (a, b) = (polygon[k], polygon[(k + 1) % polygon.len()]);
                let (da, db) = (plane(a), plane(b));
                if da >= 0.0 {
                    next.push(a);
                }
                if (da >= 0.0) != (db >= 0.0) {
                    next.push(a + (b - a) * (da / (da - db)));
                }
            }
            polygon = next;
            if polygon.is_empty() {
                return;
            }
        }
        let (width, height) = (f64::from(self.frame.width), f64::from(self.frame.height));
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for v in &polygon {
            if v.w <= 0.0 {
                continue;
            }
            let p = DVec2::new(
                (v.x / v.w + 1.0) * 0.5 * width,
                (v.y / v.w + 1.0) * 0.5 * height,
            );
            lo = lo.min(p);
            hi = hi.max(p);
        }
        if !(lo.x <= hi.x && lo.y <= hi.y) {
            return;
        }
        let x0 = (lo.x - 1.0).floor().clamp(0.0, width) as usize;
        let x1 = (hi.x + 1.0).ceil().clamp(0.0, width) as usize;
        let y0 = (lo.y - 1.0).floor().clamp(0.0, height) as usize;
        let y1 = (hi.y + 1.0).ceil().clamp(0.0, height) as usize;
        for y in y0..y1 {
            for x in x0..x1 {
                self.clipped[y * self.frame.width as usize + x] = true;
            }
        }
    }

    /// Renders framebuffer rows 2·quad_row and 2·quad_row + 1 (those that exist).
    fn render_quad_row(&self, quad_row: usize) -> Vec<PixelResult> {
        let width = self.frame.width as usize;
        let height = self.frame.height as usize;
        let rows: Vec<usize> = (2 * quad_row..(2 * quad_row + 2).min(height)).collect();
        let mut results = Vec::with_capacity(rows.len() * width);
        for &y in &rows {
            let fragments = self.rasterize_row(y);
            for (x, pixel_fragments) in fragments.iter().enumerate() {
                results.push(self.shade_pixel(x, y, pixel_fragments));
            }
        }
        if self.options.flag_quad_straddle {
            self.flag_quad_straddles(&mut results, rows.len());
        }
        results
    }

    /// All triangles' fragments on row y, per pixel in draw order (triangles are stored in draw
    /// order, and a pixel's fragments keep that order, as Vulkan's primitive order does).
    fn rasterize_row(&self, y: usize) -> Vec<Vec<Fragment>> {
        let width = self.frame.width as usize;
        let mut fragments = vec![Vec::new(); width];
        let yi = y as i64;
        let tolerance = self.options.edge_tolerance_px;
        for (index, triangle) in self.triangles.iter().enumerate() {
            if yi < triangle.y_range.0 || yi > triangle.y_range.1 {
                continue;
            }
            let sign = triangle.cross.signum();
            for x in triangle.x_range.0..=triangle.x_range.1 {
                let q = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                let e = triangle.edge_values(q).map(|v| v * sign);
                // Signed distances to the edges' lines, positive inside. For a convex polygon
                // the minimum is the distance to the boundary inside, and a lower bound of
                // minus the distance outside, so (−tol, tol) contains every near-edge point.
                let distance = (0..3)
                    .map(|i| e[i] / triangle.edge_length[i])
                    .fold(f64::INFINITY, f64::min);
                if distance <= -tolerance {
                    continue;
                }
                let covered = (0..3).all(|i| e[i] > 0.0 || (e[i] == 0.0 && triangle.top_left[i]));
                let near_edge = distance < tolerance;
                if !covered && !near_edge {
                    continue;
                }
                let b: [f64; 3] = std::array::from_fn(|i| e[i] * sign / triangle.cross);
                let depth =
                    b[0] * triangle.depth[0] + b[1] * triangle.depth[1] + b[2] * triangle.depth[2];
                fragments[x as usize].push(Fragment {
                    triangle: index,
                    covered,
                    near_edge,
                    depth,
                });
            }
        }
        fragments
    }

    /// The passes at one pixel.
    fn shade_pixel(&self, x: usize, y: usize, fragments: &[Fragment]) -> PixelResult {
        let mut flags = 0u8;
        if self.clipped[y * self.frame.width as usize + x] {
            flags |= Exclusion::ClippedTriangle.bit();
        }
        let mut colour = [0.0; 4];
        let mut bounds = point_bounds(colour);
        let mut depth = 1.0;
        let mut visible = None;
        let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);

        // Environment: LESS, write, (colour, 1).
        for fragment in fragments {
            let triangle = &self.triangles[fragment.triangle];
            let Source::Environment { mesh } = triangle.source else {
                continue;
            };
            if fragment.covered && fragment.depth < depth {
                let environment = &self.frame.environment[mesh];
                let colours = &environment.colours;
                let vertex_rgb = self.interpolate(triangle, centre, |v| colours[v].as_dvec3());
                let mut rgb = vertex_rgb;
                // Times the light map's bilinear sample at the perspective-correct uv.
                let mut light_bounds = None;
                if let Some(light_map) = &environment.light_map {
                    let uv = self.interpolate(triangle, centre, |v| {
                        light_map.uvs[v].as_dvec2().extend(0.0)
                    });
                    rgb *= light_map.map.sample_bilinear(uv.truncate());
                    light_bounds = self.options.precision.map(|precision| {
                        light_map_bounds(&light_map.map, uv.truncate(), precision)
                    });
                }
                colour = [rgb.x, rgb.y, rgb.z, 1.0];
                bounds = point_bounds(colour);
                if let Some(light) = light_bounds {
                    for c in 0..3 {
                        bounds[c] = interval_product([vertex_rgb[c]; 2], light[c]);
                    }
                }
                depth = fragment.depth;
                visible = Some(fragment.triangle);
            }
        }

        for (object_index, object) in self.frame.lenses.iter().enumerate() {
            let object_fragments: Vec<&Fragment> = fragments
                .iter()
                .filter(|f| {
                    let t = &self.triangles[f.triangle];
                    t.source
                        == (Source::Lens {
                            object: object_index,
                        })
                        && t.drawn
                        && f.covered
                })
                .collect();
            // Prime: LESS, write, (0,0,0,0).
            for fragment in &object_fragments {
                if fragment.depth < depth {
                    colour = [0.0; 4];
                    bounds = point_bounds(colour);
                    depth = fragment.depth;
                    visible = Some(fragment.triangle);
                }
            }
            // Layer passes: LESS_OR_EQUAL against the primed depth, which no longer changes.
            let passing: Vec<LensFragment> = object_fragments
                .iter()
                .filter(|f| f.depth <= depth)
                .map(|f| self.lens_fragment(object, &self.triangles[f.triangle], x, y))
                .collect();
            for lens_fragment in &passing {
                flags |= lens_fragment.flags;
            }
            let groups = &self.groups[object_index];
            // Scratch images of the back-to-front and group-targets schemes (cleared: zero).
            let mut scratch: Vec<([f64; 4], [Interval; 4])> = Vec::new();
            for (group_index, &(viewpoint, term)) in groups.iter().enumerate() {
                let blend = self.options.blend;
                let into_framebuffer =
                    matches!(blend, BlendScheme::FrontToBack | BlendScheme::Programmable);
                if into_framebuffer && group_index > 0 {
                    // The alpha clear (the programmable scheme's in-shader reset is the same
                    // arithmetic: α of the current value taken as 0).
                    let clears_here = match self.options.alpha_clear {
                        AlphaClearScope::FullScreen => true,
                        AlphaClearScope::LensCoverage => !passing.is_empty(),
                    };
                    if clears_here {
                        colour = alpha_clear(colour);
                        bounds = alpha_clear_bounds(bounds);
                    }
                }
                // Where this group's layers composite: the framebuffer, or a cleared scratch.
                let (mut target, mut target_bounds) = if into_framebuffer {
                    (colour, bounds)
                } else {
                    ([0.0; 4], point_bounds([0.0; 4]))
                };
                let weight = f64::from(self.frame.viewpoint_weights[viewpoint]);
                let n = object.layer_count();
                let order: Vec<usize> = if blend == BlendScheme::BackToFront {
                    (0..n).rev().collect()
                } else {
                    (0..n).collect()
                };
                for layer in order {
                    for lens_fragment in &passing {
                        let cube = &object.layers[viewpoint][layer];
                        let samples = &lens_fragment.directions[term][layer];
                        let sample = self.sample(cube, samples);
                        flags |= sample.flags;
                        let fg = lens_fragment.fg[term].to_array();
                        let source = layer_source(weight, fg, sample.rgba);
                        let source_bounds = layer_source_bounds(weight, fg, sample.bounds);
                        if blend == BlendScheme::BackToFront {
                            target = blend_back_to_front(target, source);
                            target_bounds =
                                blend_back_to_front_bounds(target_bounds, source_bounds);
                        } else {
                            target = blend_front_to_back(target, source);
                            target_bounds =
                                blend_front_to_back_bounds(target_bounds, source_bounds);
                        }
                    }
                }
                let last = group_index + 1 == groups.len();
                match blend {
                    BlendScheme::FrontToBack | BlendScheme::Programmable => {
                        (colour, bounds) = (target, target_bounds);
                    }
                    // Each group's scratch image added to the framebuffer: colour, and α for the
                    // last group.
                    BlendScheme::BackToFront => {
                        let mask = if last { 0b1111 } else { 0b0111 };
                        colour = add_masked(colour, target, mask);
                        bounds = add_masked_bounds(bounds, target_bounds, mask);
                    }
                    BlendScheme::GroupTargets => scratch.push((target, target_bounds)),
                }
            }
            // The group sum: the groups' colour summed in order from zero, α the last group's,
            // added to the framebuffer.
            if let Some(&(last, last_bounds)) = scratch.last() {
                let mut sum = [0.0; 4];
                let mut sum_bounds = point_bounds([0.0; 4]);
                for (value, value_bounds) in &scratch {
                    sum = add_masked(sum, *value, 0b0111);
                    sum_bounds = add_masked_bounds(sum_bounds, *value_bounds, 0b0111);
                }
                (sum[3], sum_bounds[3]) = (last[3], last_bounds[3]);
                colour = add_masked(colour, sum, 0b1111);
                bounds = add_masked_bounds(bounds, sum_bounds, 0b1111);
            }
        }

        flags |= self.geometry_flags(fragments, depth);
        let lens = visible.is_some_and(|t| matches!(self.triangles[t].source, Source::Lens { .. }));
        PixelResult {
            rgba: colour,
            bounds,
            depth,
            lens,
            flags,
            visible,
        }
    }

    /// Coverage and depth ties that could change what the pixel shows.
    fn geometry_flags(&self, fragments: &[Fragment], final_depth: f64) -> u8 {
        let tolerance = self.options.depth_tolerance;
        let mut flags = 0;
        // An edge tie matters when its triangle is drawn and could be in front: at or nearer
        // than what the pixel finally shows (give or take the depth tolerance).
        if fragments.iter().any(|f| {
            f.near_edge
                && self.triangles[f.triangle].possibly_drawn
                && f.depth <= final_depth + tolerance
        }) {
            flags |= Exclusion::NearTriangleEdge.bit();
        }
        // Among covered, drawn fragments, the front-most and any other triangle within the
        // tolerance make the depth test (or the layer passes' LESS_OR_EQUAL) a coin toss.
        let mut drawn_depths = fragments
            .iter()
            .filter(|f| f.covered && self.triangles[f.triangle].drawn)
            .map(|f| (f.depth, f.triangle));
        if let Some(front) = drawn_depths.clone().min_by(|a, b| a.0.total_cmp(&b.0))
            && drawn_depths.any(|(d, t)| t != front.1 && (d - front.0).abs() < tolerance)
        {
            flags |= Exclusion::DepthTie.bit();
        }
        flags
    }

    /// Perspective-correct interpolation of a per-vertex attribute at `q`.
    fn interpolate(
        &self,
        triangle: &ScreenTriangle,
        q: DVec2,
        attribute: impl Fn(usize) -> DVec3,
    ) -> DVec3 {
        let weights = triangle.perspective_weights(q).unwrap_or([f64::NAN; 3]);
        (0..3)
            .map(|i| weights[i] * attribute(triangle.vertices[i]))
            .sum()
    }

    /// A visible lens fragment's interpolated data: F·G per term and, per term and layer, the
    /// direction at the pixel with the quad's coarse derivatives.
    fn lens_fragment(
        &self,
        object: &LensObject,
        triangle: &ScreenTriangle,
        x: usize,
        y: usize,
    ) -> LensFragment {
        let mut flags = 0u8;
        let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
        let top_left = DVec2::new((x & !1) as f64 + 0.5, (y & !1) as f64 + 0.5);
        let points = [
            centre,
            top_left,
            top_left + DVec2::new(1.0, 0.0),
            top_left + DVec2::new(0.0, 1.0),
            top_left + DVec2::new(1.0, 1.0),
        ];
        let weights: Vec<Option<[f64; 3]>> = points
            .iter()
            .map(|&q| triangle.perspective_weights(q))
            .collect();
        if weights.iter().any(Option::is_none) {
            flags |= Exclusion::UndefinedDerivative.bit();
        }
        let at = |k: usize, value: &dyn Fn(usize) -> DVec3| -> DVec3 {
            let w = weights[k].unwrap_or([0.0; 3]);
            (0..3).map(|i| w[i] * value(triangle.vertices[i])).sum()
        };
        let fg = object
            .terms
            .iter()
            .map(|term| at(0, &|v| term.fg[v].as_dvec3()))
            .collect();
        let directions = object
            .terms
            .iter()
            .map(|term| {
                term.directions
                    .iter()
                    .map(|layer| {
                        let value = |v: usize| layer[v].as_dvec3();
                        // The quad's pixels: top-left, top-right, bottom-left, bottom-right.
                        let quad = [at(1, &value), at(2, &value), at(3, &value), at(4, &value)];
                        let quad_top_left = quad[0];
                        let (column, row) = (x & 1, y & 1);
                        let coarse = (quad[1] - quad[0], quad[2] - quad[0]);
                        let fine = (
                            quad[2 * row + 1] - quad[2 * row],
                            quad[2 + column] - quad[column],
                        );
                        let (ddx, ddy) = match self.options.derivatives {
                            DerivativeMode::Coarse => coarse,
                            DerivativeMode::Fine => fine,
                        };
                        let direction = at(0, &value);
                        let lod_direction = match self.options.lod_mode {
                            LodMode::PerPixel => direction,
                            LodMode::PerQuadTopLeft => quad_top_left,
                        };
                        let finite = [direction, lod_direction, ddx, ddy]
                            .iter()
                            .all(|v| v.is_finite());
                        if !finite || direction == DVec3::ZERO || lod_direction == DVec3::ZERO {
                            flags |= Exclusion::UndefinedDerivative.bit();
                        }
                        DirectionSample {
                            direction,
                            lod_direction,
                            ddx,
                            ddy,
                            either_derivatives: [coarse, fine],
                        }
                    })
                    .collect()
            })
            .collect();
        LensFragment {
            fg,
            directions,
            flags,
        }
    }

    /// A trilinear sample as the layer pass takes it, its bounds, and the exclusion bits it
    /// raises.
    fn sample(&self, cube: &CubeMap, at: &DirectionSample) -> FilteredSample {
        let levels = cube.levels.len() as u32;
        let lod_on = |face| {
            cube_lod_on_face(
                face,
                cube.size,
                levels,
                at.lod_direction,
                at.ddx,
                at.ddy,
                self.options.lod_log2,
            )
        };
        let lambda = lod_on(major_face(at.lod_direction));
        let mut flags = 0u8;
        let competing = competing_faces(at.lod_direction, self.options.face_tie_tolerance);
        if competing.len() > 1 {
            let lods: Vec<f64> = competing.iter().copied().map(lod_on).collect();
            let spread = lods.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                - lods.iter().copied().fold(f64::INFINITY, f64::min);
            if spread > self.options.lod_tie_tolerance {
                flags |= Exclusion::CubeFaceTie.bit();
            }
        }
        let sample = sample_cube(cube, at.direction, lambda);
        if sample.corner {
            flags |= Exclusion::CubeCorner.bit();
        }
        let bounds = match self.options.precision {
            None => point_bounds(sample.rgba),
            Some(precision) => {
                // Every LOD the spec allows, on whichever face f32 face selection may pick.
                let mut lod_range = [f64::INFINITY, f64::NEG_INFINITY];
                for face in competing
                    .iter()
                    .copied()
                    .chain([major_face(at.lod_direction)])
                {
                    let range = cube_lod_range_on_face(
                        face,
                        cube.size,
                        levels,
                        at.lod_direction,
                        &at.either_derivatives,
                        precision,
                    );
                    lod_range = [lod_range[0].min(range[0]), lod_range[1].max(range[1])];
                }
                let range = sample_cube_bounds(cube, at.direction, lod_range, precision);
                if range.corner {
                    flags |= Exclusion::CubeCorner.bit();
                }
                range.bounds
            }
        };
        FilteredSample {
            rgba: sample.rgba,
            bounds,
            flags,
        }
    }

    /// Marks lens pixels whose quad shows more than one triangle (or some non-lens pixel).
    fn flag_quad_straddles(&self, results: &mut [PixelResult], rows: usize) {
        let width = self.frame.width as usize;
        for qx in (0..width).step_by(2) {
            let members: Vec<usize> = (0..rows)
                .flat_map(|r| (qx..(qx + 2).min(width)).map(move |x| r * width + x))
                .collect();
            let first = results[members[0]].visible;
            let straddles =
                members.iter().any(|&m| results[m].visible != first) || members.len() < 4;
            if straddles {
                for &m in &members {
                    if results[m].lens {
                        results[m].flags |= Exclusion::QuadStraddle.bit();
                    }
                }
            }
        }
    }
}

/// The groups a lens object's layer passes run, in pass order: viewpoints with a non-zero
/// weight, and within each, the object's terms with refraction before reflection.
fn lens_groups(frame: &FrameInput, object: &LensObject) -> Vec<(usize, usize)> {
    let mut terms: Vec<(Term, usize)> = object
        .terms
        .iter()
        .enumerate()
        .map(|(index, t)| (t.term, index))
        .collect();
    terms.sort();
    let mut groups = Vec::new();
    for (viewpoint, &weight) in frame.viewpoint_weights.iter().enumerate() {
        if weight == 0.0 || viewpoint >= object.layers.len() {
            continue;
        }
        for &(_, term) in &terms {
            groups.push((viewpoint, term));
        }
    }
    groups
}

/// Where one layer of one term is sampled at a pixel.
#[derive(Clone, Copy, Debug)]
struct DirectionSample {
    /// The interpolated direction at the pixel centre (what is filtered).
    direction: DVec3,
    /// The direction whose face and position decide the LOD ([`LodMode`]).
    lod_direction: DVec3,
    /// Quad derivatives of the direction, coarse or fine as [`ModelOptions::derivatives`] says.
    ddx: DVec3,
    ddy: DVec3,
    /// `(ddx, ddy)` both ways, coarse then fine: an implementation may take either.
    either_derivatives: [(DVec3, DVec3); 2],
}

/// A layer sample at a pixel: the model's value, its bounds ([`ModelImage::bounds`]) and the
/// exclusion bits it raises.
#[derive(Clone, Copy, Debug)]
struct FilteredSample {
    rgba: [f64; 4],
    bounds: [Interval; 4],
    flags: u8,
}

/// A lens fragment that passes the layer passes' depth test.
#[derive(Clone, Debug)]
struct LensFragment {
    /// Per term (in `object.terms` order), interpolated F·G.
    fg: Vec<DVec3>,
    /// `directions[term][layer]`.
    directions: Vec<Vec<DirectionSample>>,
    flags: u8,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::frame_input::{EnvironmentMesh, LensFaces, TermVertices};
    use glam::{Mat4, Vec3};
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn random_rgba(rng: &mut Pcg64) -> [f64; 4] {
        let alpha = rng.gen_range(0.0..1.0);
        [
            alpha * rng.gen_range(0.0..1.0),
            alpha * rng.gen_range(0.0..1.0),
            alpha * rng.gen_range(0.0..1.0),
            alpha,
        ]
    }

    #[test]
    fn over_is_associative() {
        let mut rng = Pcg64::seed_from_u64(10);
        for _ in 0..1000 {
            let (a, b, c) = (
                random_rgba(&mut rng),
                random_rgba(&mut rng),
                random_rgba(&mut rng),
            );
            let left = over(over(a, b), c);
            let right = over(a, over(b, c));
            for k in 0..4 {
                assert!((left[k] - right[k]).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn blend_sequence_equals_the_closed_form() {
        let mut rng = Pcg64::seed_from_u64(11);
        for _ in 0..1000 {
            let groups: Vec<CompositeGroup> = (0..rng.gen_range(1..=4))
                .map(|_| CompositeGroup {
                    weight: rng.gen_range(0.0..1.0),
                    fg: std::array::from_fn(|_| rng.gen_range(0.0..1.0)),
                    layers: (0..rng.gen_range(1..=4))
                        .map(|_| random_rgba(&mut rng))
                        .collect(),
                })
                .collect();
            let blended = composite_by_blending(&groups);
            let closed = composite_closed_form(&groups);
            for k in 0..4 {
                assert!(
                    (blended[k] - closed[k]).abs() < 1e-14,
                    "{blended:?} {closed:?}"
                );
            }
        }
    }

    /// An 8×8 frame with identity view-projection (framebuffer x = 4(x + 1), y = 4(y + 1)): an
    /// environment triangle covering the screen at depth 0.9 whose colour is (x, y, 0.25), and a
    /// lens rectangle over pixels 2..6 × 2..6 at depth 0.25, with a back-facing triangle in front of
    /// part of it that culling must remove.
    fn small_frame(weights: Vec<f32>, layers: Vec<Vec<CubeMap>>) -> FrameInput {
        let environment = EnvironmentMesh {
            positions: vec![
                Vec3::new(-1.0, -1.0, 0.9),
                Vec3::new(3.0, -1.0, 0.9),
                Vec3::new(-1.0, 3.0, 0.9),
            ],
            colours: vec![
                Vec3::new(-1.0, -1.0, 0.25),
                Vec3::new(3.0, -1.0, 0.25),
                Vec3::new(-1.0, 3.0, 0.25),
            ],
            triangles: vec![[0, 1, 2]],
            light_map: None,
        };
        let n = layers[0].len();
        // Front-facing order in framebuffer coordinates: (2,2) → (2,6) → (6,6) → (6,2).
        // The rectangle's corners are off the pixel grid so that no pixel centre lies on its
        // diagonal: framebuffer x ∈ [1.8, 6.0], y ∈ [2.0, 6.2] covers pixels 2..6 × 2..6.
        let positions = vec![
            Vec3::new(-0.55, -0.5, 0.25),
            Vec3::new(-0.55, 0.55, 0.25),
            Vec3::new(0.5, 0.55, 0.25),
            Vec3::new(0.5, -0.5, 0.25),
            // Back-facing triangle nearer the camera.
            Vec3::new(-0.5, -0.5, 0.1),
            Vec3::new(0.5, -0.5, 0.1),
            Vec3::new(0.5, 0.5, 0.1),
        ];
        let directions: Vec<Vec<Vec3>> = (0..n)
            .map(|l| {
                (0..positions.len())
                    .map(|v| Vec3::new(0.1 * v as f32, 0.2 * l as f32 - 0.1, 1.0))
                    .collect()
            })
            .collect();
        let lens = LensObject {
            name: "square".into(),
            positions,
            triangles: vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]],
            faces: LensFaces::Front,
            terms: vec![TermVertices {
                term: Term::Reflection,
                fg: vec![Vec3::new(0.5, 0.75, 1.0); 7],
                directions,
            }],
            layers: layers
                .into_iter()
                .map(|v| v.into_iter().map(std::sync::Arc::new).collect())
                .collect(),
        };
        FrameInput {
            width: 8,
            height: 8,
            view_proj: Mat4::IDENTITY,
            environment: vec![std::sync::Arc::new(environment)],
            lenses: vec![lens],
            viewpoint_weights: weights,
        }
    }

    #[test]
    fn small_frame_matches_hand_computed_pixels() {
        let l1 = [0.1f32, 0.15, 0.05, 0.5];
        let l2 = [0.4f32, 0.6, 0.8, 1.0];
        let frame = small_frame(
            vec![1.0],
            vec![vec![CubeMap::uniform(4, l1), CubeMap::uniform(4, l2)]],
        );
        let image = render_model(&frame);
        let fg = [0.5, 0.75, 1.0];
        for y in 0..8u32 {
            for x in 0..8u32 {
                let i = image.index(x, y);
                assert_eq!(image.exclusion[i], None, "({x},{y})");
                let inside = (2..6).contains(&x) && (2..6).contains(&y);
                assert_eq!(image.lens_mask[i], inside);
                let expected = if inside {
                    // L1 over L2, times F·G; one group so no alpha clear.
                    let c: [f64; 4] =
                        std::array::from_fn(|k| f64::from(l1[k]) + 0.5 * f64::from(l2[k]));
                    [c[0] * fg[0], c[1] * fg[1], c[2] * fg[2], c[3]]
                } else {
                    // The environment's colour is the pixel centre's NDC position.
                    let nx = (f64::from(x) + 0.5) / 4.0 - 1.0;
                    let ny = (f64::from(y) + 0.5) / 4.0 - 1.0;
                    [nx, ny, 0.25, 1.0]
                };
                for k in 0..4 {
                    assert!(
                        (image.rgba[i][k] - expected[k]).abs() < 1e-7,
                        "({x},{y}) {:?} vs {expected:?}",
                        image.rgba[i]
                    );
                }
                let depth = if inside { 0.25 } else { 0.9 };
                assert!((image.depth[i] - depth).abs() < 1e-7);
            }
        }
    }

    #[test]
    fn two_viewpoints_sum_and_alpha_clear() {
        let a = [[0.1f32, 0.2, 0.3, 0.5], [0.2, 0.2, 0.2, 0.25]];
        let b = [[0.4f32, 0.1, 0.0, 0.5], [0.6, 0.3, 0.9, 1.0]];
        let cubes = |texels: [[f32; 4]; 2]| texels.map(|t| CubeMap::uniform(2, t)).to_vec();
        let weights = [0.25f32, 0.75];
        for scope in [AlphaClearScope::FullScreen, AlphaClearScope::LensCoverage] {
            let frame = small_frame(weights.to_vec(), vec![cubes(a), cubes(b)]);
            let options = ModelOptions {
                alpha_clear: scope,
                ..ModelOptions::default()
            };
            let image = render_model_with(&frame, &options);
            let composite =
                |t: [[f32; 4]; 2]| -> [f64; 4] { over(t[0].map(f64::from), t[1].map(f64::from)) };
            let (ca, cb) = (composite(a), composite(b));
            let fg = [0.5, 0.75, 1.0];
            let lens_pixel = image.rgba[image.index(3, 4)];
            for k in 0..3 {
                let expected = fg[k] * (0.25 * ca[k] + 0.75 * cb[k]);
                assert!((lens_pixel[k] - expected).abs() < 1e-7);
            }
            // α is the last group's composite α.
            assert!((lens_pixel[3] - cb[3]).abs() < 1e-7);
            let environment_alpha = image.rgba[image.index(0, 0)][3];
            let expected_alpha = match scope {
                AlphaClearScope::FullScreen => 0.0,
                AlphaClearScope::LensCoverage => 1.0,
            };
            assert_eq!(environment_alpha, expected_alpha);
        }
    }

    #[test]
    fn perspective_interpolation_matches_ray_plane_intersection() {
        // A tilted environment triangle seen in perspective; its colour is its world position,
        // so at every pixel the model's colour must be where the pixel's ray meets the plane.
        // Right-handed view space looking down −z, projected to Vulkan clip space (y down,
        // depth 0 at the near plane, 1 at the far plane), written out by hand.
        let (near, far, focal) = (0.1f32, 100.0f32, 1.5f32);
        let projection = Mat4::from_cols_array(&[
            focal,
            0.0,
            0.0,
            0.0, //
            0.0,
            -focal,
            0.0,
            0.0, //
            0.0,
            0.0,
            far / (near - far),
            -1.0, //
            0.0,
            0.0,
            near * far / (near - far),
            0.0,
        ]);
        let view = Mat4::from_rotation_y(0.15)
            * Mat4::from_rotation_x(-0.1)
            * Mat4::from_translation(Vec3::new(-0.3, -0.2, -3.0));
        let view_proj = projection * view;
        let corners = vec![
            Vec3::new(-2.0, -2.0, -1.0),
            Vec3::new(2.0, -1.5, 0.5),
            Vec3::new(-1.0, 2.5, 0.0),
        ];
        let frame = FrameInput {
            width: 32,
            height: 32,
            view_proj,
            environment: vec![std::sync::Arc::new(EnvironmentMesh {
                positions: corners.clone(),
                colours: corners.clone(),
                triangles: vec![[0, 1, 2]],
                light_map: None,
            })],
            lenses: vec![],
            viewpoint_weights: vec![1.0],
        };
        let image = render_model(&frame);
        let inverse = view_proj.as_dmat4().inverse();
        let p: Vec<DVec3> = corners.iter().map(|c| c.as_dvec3()).collect();
        let normal = (p[1] - p[0]).cross(p[2] - p[0]);
        let mut drawn = 0;
        for y in 0..32u32 {
            for x in 0..32u32 {
                let i = image.index(x, y);
                if image.depth[i] == 1.0 || image.exclusion[i].is_some() {
                    continue;
                }
                drawn += 1;
                let ndc = DVec2::new(
                    (f64::from(x) + 0.5) / 16.0 - 1.0,
                    (f64::from(y) + 0.5) / 16.0 - 1.0,
                );
                let near = inverse.project_point3(ndc.extend(0.0));
                let far = inverse.project_point3(ndc.extend(1.0));
                let t = normal.dot(p[0] - near) / normal.dot(far - near);
                let hit = near + t * (far - near);
                let rgb = image.rgba[i];
                let got = DVec3::new(rgb[0], rgb[1], rgb[2]);
                assert!((got - hit).length() < 1e-9, "({x},{y}) {got} vs {hit}");
            }
        }
        assert!(drawn > 100);
    }

    #[test]
    fn lod_uses_the_quads_coarse_derivatives() {
        // Directions on the +Z face varying linearly in screen space (w = 1): s grows by
        // 2^k/size per pixel along x, so every lens pixel samples at λ = k. A cube map whose
        // levels hold different uniform values reveals the level mix.
        let size = 64u32;
        let levels = CubeMap::full_chain_levels(size) as usize;
        let mut cube = CubeMap::uniform(size, [0.0; 4]);
        for (l, level) in cube.levels.iter_mut().enumerate() {
            for face in level.iter_mut() {
                face.fill([l as f32 / 8.0, 0.0, 0.0, 1.0]);
            }
        }
        for k in [0.0f64, 1.0, 1.5, 2.25] {
            let mut frame = small_frame(vec![1.0], vec![vec![cube.clone()]]);
            // Framebuffer x = 4(x_ndc + 1); s = ½(rx + 1) on +Z with rz = 1, so ∂s/∂x_fb =
            // ½·∂rx/∂x_fb = 2^k/size needs rx = 2·2^k/size·x_fb + c = 8·2^k/size·x_ndc + c.
            let slope = 8.0 * 2f64.powf(k) / f64::from(size);
            let lens = &mut frame.lenses[0];
            lens.terms[0].directions[0] = lens
                .positions
                .iter()
                .map(|p| Vec3::new((slope * f64::from(p.x)) as f32, 0.0, 1.0))
                .collect();
            let image = render_model(&frame);
            let expected = k / 8.0;
            assert!(expected <= (levels - 1) as f64 / 8.0);
            for y in 2..6 {
                for x in 2..6 {
                    let i = image.index(x, y);
                    assert!(image.lens_mask[i]);
                    // F·G red = 0.5.
                    let got = image.rgba[i][0] / 0.5;
                    assert!((got - expected).abs() < 1e-6, "λ={k} ({x},{y}) {got}");
                }
            }
        }
    }

    #[test]
    fn edge_pixels_and_ties_are_excluded() {
        // Move the lens square so its left edge passes exactly through pixel centres x = 2.5.
        let mut frame = small_frame(vec![1.0], vec![vec![CubeMap::uniform(1, [0.5; 4])]]);
        for p in frame.lenses[0].positions.iter_mut().take(4) {
            if p.x < 0.0 {
                // Framebuffer x = 2.5: through the centres of column 2.
                p.x = -0.375;
            }
        }
        let image = render_model(&frame);
        for y in 2..6 {
            assert_eq!(
                image.exclusion[image.index(2, y)],
                Some(Exclusion::NearTriangleEdge)
            );
            assert_eq!(image.exclusion[image.index(4, y)], None);
        }
        // A lens at the environment's depth is a z-fight.
        let mut frame = small_frame(vec![1.0], vec![vec![CubeMap::uniform(1, [0.5; 4])]]);
        for p in frame.lenses[0].positions.iter_mut().take(4) {
            p.z = 0.9;
        }
        let image = render_model(&frame);
        assert_eq!(
            image.exclusion[image.index(3, 3)],
            Some(Exclusion::DepthTie)
        );
        // A lens vertex behind the camera: its triangles are clipped and their pixels excluded.
        let mut frame = small_frame(vec![1.0], vec![vec![CubeMap::uniform(1, [0.5; 4])]]);
        frame.lenses[0].positions[0].z = -0.5;
        let image = render_model(&frame);
        assert_eq!(
            image.exclusion[image.index(3, 3)],
            Some(Exclusion::ClippedTriangle)
        );
        let counts = image.exclusion_counts();
        assert!(
            counts
                .iter()
                .any(|&(r, n)| r == Exclusion::ClippedTriangle && n > 0)
        );
    }

    /// A perspective frame like the GPU comparison uses: a tessellated sphere lens with both
    /// terms, random F·G, smooth directions, random texels in every level of every cube map,
    /// two viewpoints, in front of a coloured environment quad.
    fn random_sphere_frame(
        rng: &mut Pcg64,
        size: u32,
        cube_size: u32,
        layer_count: usize,
        viewpoints: usize,
    ) -> FrameInput {
        let (near, far, focal) = (0.1f32, 100.0f32, 1.5f32);
        let projection = Mat4::from_cols_array(&[
            focal,
            0.0,
            0.0,
            0.0, //
            0.0,
            -focal,
            0.0,
            0.0, //
            0.0,
            0.0,
            far / (near - far),
            -1.0, //
            0.0,
            0.0,
            near * far / (near - far),
            0.0,
        ]);
        let view_proj = projection * Mat4::from_translation(Vec3::new(0.05, -0.03, -3.0));
        let environment = EnvironmentMesh {
            positions: vec![
                Vec3::new(-6.0, -6.0, -4.0),
                Vec3::new(6.0, -6.0, -4.0),
                Vec3::new(6.0, 6.0, -4.0),
                Vec3::new(-6.0, 6.0, -4.0),
            ],
            colours: (0..4)
                .map(|_| Vec3::new(rng.r#gen(), rng.r#gen(), rng.r#gen()))
                .collect(),
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            light_map: None,
        };
        let (rings, segments) = (12usize, 24usize);
        let mut positions = Vec::new();
        for i in 0..=rings {
            let theta = std::f32::consts::PI * i as f32 / rings as f32;
            for j in 0..segments {
                let phi = std::f32::consts::TAU * j as f32 / segments as f32;
                positions.push(
                    0.8 * Vec3::new(
                        theta.sin() * phi.cos(),
                        theta.cos(),
                        theta.sin() * phi.sin(),
                    ),
                );
            }
        }
        let index = |i: usize, j: usize| (i * segments + j % segments) as u32;
        let mut triangles = Vec::new();
        for i in 0..rings {
            for j in 0..segments {
                let quad = [
                    index(i, j),
                    index(i + 1, j),
                    index(i + 1, j + 1),
                    index(i, j + 1),
                ];
                for mut t in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                    let p = t.map(|v| positions[v as usize]);
                    let normal = (p[1] - p[0]).cross(p[2] - p[0]);
                    if normal.length_squared() < 1e-12 {
                        continue; // the poles' degenerate triangles
                    }
                    // Counter-clockwise seen from outside.
                    if normal.dot(p[0] + p[1] + p[2]) < 0.0 {
                        t.swap(1, 2);
                    }
                    triangles.push(t);
                }
            }
        }
        let eye = Vec3::new(-0.05, 0.03, 3.0);
        let terms = [Term::Refraction, Term::Reflection]
            .into_iter()
            .map(|term| TermVertices {
                term,
                fg: positions
                    .iter()
                    .map(|_| Vec3::new(rng.r#gen(), rng.r#gen(), rng.r#gen()))
                    .collect(),
                directions: (0..layer_count)
                    .map(|layer| {
                        positions
                            .iter()
                            .map(|&p| {
                                let normal = p.normalize();
                                let view = (p - eye).normalize();
                                let outgoing = match term {
                                    Term::Reflection => view - 2.0 * view.dot(normal) * normal,
                                    Term::Refraction => (view - 0.3 * normal).normalize(),
                                };
                                p + (1.5 + layer as f32) * outgoing
                            })
                            .collect()
                    })
                    .collect(),
            })
            .collect();
        let layers = (0..viewpoints)
            .map(|_| {
                (0..layer_count)
                    .map(|_| {
                        let levels = (0..CubeMap::full_chain_levels(cube_size))
                            .map(|l| {
                                let n = ((cube_size >> l).max(1) as usize).pow(2);
                                std::array::from_fn(|_| {
                                    (0..n)
                                        .map(|_| {
                                            let alpha: f32 = rng.gen_range(0.0..1.0);
                                            [
                                                alpha * rng.r#gen::<f32>(),
                                                alpha * rng.r#gen::<f32>(),
                                                alpha * rng.r#gen::<f32>(),
                                                alpha,
                                            ]
                                        })
                                        .collect()
                                })
                            })
                            .collect();
                        std::sync::Arc::new(CubeMap {
                            size: cube_size,
                            levels,
                        })
                    })
                    .collect()
            })
            .collect();
        let first: f32 = if viewpoints == 2 {
            rng.gen_range(0.05..0.95)
        } else {
            1.0
        };
        let viewpoint_weights = if viewpoints == 2 {
            vec![first, 1.0 - first]
        } else {
            vec![1.0]
        };
        FrameInput {
            width: size,
            height: size,
            view_proj,
            environment: vec![std::sync::Arc::new(environment)],
            lenses: vec![LensObject {
                name: "sphere".into(),
                positions,
                triangles,
                faces: LensFaces::Front,
                terms,
                layers,
            }],
            viewpoint_weights,
        }
    }

    #[test]
    fn bounds_are_points_without_precision_and_hold_the_nominal_value_with_it() {
        let mut rng = Pcg64::seed_from_u64(13);
        let frame = random_sphere_frame(&mut rng, 64, 16, 3, 2);
        // The exact logarithm lies in the bounds at any precision; lavapipe's (≤ 0.043 low) where
        // the mip precision is as coarse as lavapipe reports (4 bits).
        let precise = FilterPrecision {
            sub_texel_bits: 8,
            mipmap_bits: 8,
        };
        let lavapipe_like = FilterPrecision {
            sub_texel_bits: 8,
            mipmap_bits: 4,
        };
        for (options, precisions) in [
            (
                ModelOptions::default(),
                [FilterPrecision::SPEC_MINIMUM, precise],
            ),
            (
                ModelOptions::lavapipe(),
                [FilterPrecision::SPEC_MINIMUM, lavapipe_like],
            ),
        ] {
            let nominal = render_model_with(&frame, &options);
            for (rgba, bounds) in nominal.rgba.iter().zip(&nominal.bounds) {
                assert_eq!(*bounds, rgba.map(|v| [v, v]));
            }
            for precision in precisions {
                let image = render_model_with(
                    &frame,
                    &ModelOptions {
                        precision: Some(precision),
                        ..options
                    },
                );
                // The same frame, the same nominal values; bounds around them.
                assert_eq!(image.rgba, nominal.rgba);
                let mut widths = Vec::new();
                for i in 0..image.rgba.len() {
                    if image.exclusion[i].is_some() {
                        continue;
                    }
                    // Up to the f64 rounding of two evaluation orders.
                    assert!(image.distance_outside_bounds(i, image.rgba[i]) < 1e-12);
                    let width = image.bounds[i]
                        .iter()
                        .map(|[lo, hi]| hi - lo)
                        .fold(0.0, f64::max);
                    if image.lens_mask[i] {
                        widths.push(width);
                    } else {
                        assert_eq!(width, 0.0, "environment pixels are exact");
                    }
                }
                widths.sort_by(f64::total_cmp);
                let median = widths[widths.len() / 2];
                eprintln!(
                    "{:?} {precision:?}: lens interval width median {median:.2e}, largest {:.2e}",
                    options.lod_log2,
                    widths.last().unwrap()
                );
                assert!(median > 0.0);
                // α stays a coverage: its bounds lie in [0, 1].
                for bounds in &image.bounds {
                    assert!(0.0 <= bounds[3][0] && bounds[3][1] <= 1.0 + 1e-12);
                }
            }
        }
        // A 1 is exact in any order of arithmetic: the helper reports distances, 0 inside.
        let image = render_model(&frame);
        let i = image.index(32, 32);
        let mut outside = image.rgba[i];
        outside[2] += 0.25;
        assert!((image.distance_outside_bounds(i, outside) - 0.25).abs() < 1e-12);
        assert_eq!(image.distance_outside_bounds(i, image.rgba[i]), 0.0);
        assert_eq!(
            image.distance_outside_bounds(i, [f64::NAN; 4]),
            f64::INFINITY
        );
    }

    #[test]
    fn light_map_bounds_hold_the_bilinear_sample() {
        let mut rng = Pcg64::seed_from_u64(15);
        let map = LightMap {
            width: 5,
            height: 3,
            texels: (0..15)
                .map(|_| {
                    [
                        rng.gen_range(0.0f32..4.0),
                        0.5,
                        rng.gen_range(0.0f32..1.0),
                        1.0,
                    ]
                })
                .map(|t| t.map(half::f16::from_f32))
                .collect(),
        };
        for _ in 0..500 {
            let uv = DVec2::new(rng.gen_range(-0.2..1.2), rng.gen_range(-0.2..1.2));
            let nominal = map.sample_bilinear(uv);
            let bounds = light_map_bounds(&map, uv, FilterPrecision::SPEC_MINIMUM);
            for c in 0..3 {
                assert!(bounds[c][0] - 1e-12 <= nominal[c] && nominal[c] <= bounds[c][1] + 1e-12);
            }
            // A uniform channel stays a point.
            assert!((bounds[1][0] - 0.5).abs() < 1e-12 && (bounds[1][1] - 0.5).abs() < 1e-12);
        }
    }

    #[test]
    fn interval_blend_contains_every_blend_of_its_members() {
        let mut rng = Pcg64::seed_from_u64(14);
        let interval = |rng: &mut Pcg64, lo: f64, hi: f64| {
            let (a, b) = (rng.gen_range(lo..hi), rng.gen_range(lo..hi));
            [a.min(b), a.max(b)]
        };
        for _ in 0..2000 {
            // Mostly premultiplied values in [0, 1]; sometimes beyond, for the general product.
            let (lo, hi) = if rng.gen_bool(0.7) {
                (0.0, 1.0)
            } else {
                (-0.5, 1.5)
            };
            let dst: [Interval; 4] = std::array::from_fn(|_| interval(&mut rng, lo, hi));
            let src: [Interval; 4] = std::array::from_fn(|_| interval(&mut rng, lo, hi));
            let out = blend_front_to_back_bounds(dst, src);
            for _ in 0..20 {
                let pick = |i: Interval, rng: &mut Pcg64| i[0] + (i[1] - i[0]) * rng.r#gen::<f64>();
                let d: [f64; 4] = std::array::from_fn(|c| pick(dst[c], &mut rng));
                let s: [f64; 4] = std::array::from_fn(|c| pick(src[c], &mut rng));
                let blended = blend_front_to_back(d, s);
                for c in 0..4 {
                    assert!(out[c][0] - 1e-12 <= blended[c] && blended[c] <= out[c][1] + 1e-12);
                }
            }
        }
    }

    #[test]
    fn random_sphere_frame_keeps_most_lens_pixels_comparable() {
        let mut rng = Pcg64::seed_from_u64(12);
        for (layer_count, viewpoints) in [(1, 1), (4, 2)] {
            let frame = random_sphere_frame(&mut rng, 128, 16, layer_count, viewpoints);
            for options in [ModelOptions::default(), ModelOptions::lavapipe()] {
                let image = render_model_with(&frame, &options);
                let lens = image.lens_mask.iter().filter(|&&m| m).count();
                let comparable = image.comparable_lens_pixels();
                eprintln!(
                    "n={layer_count} viewpoints={viewpoints} {:?}: {comparable}/{lens} lens \
                     pixels comparable; excluded {:?}",
                    options.lod_log2,
                    image.exclusion_counts()
                );
                assert!(lens > 1500, "{lens}");
                assert!(comparable as f64 > 0.9 * lens as f64);
                // Lens pixels hold finite premultiplied values: α ∈ [0, 1].
                for (rgba, _) in image.rgba.iter().zip(&image.lens_mask).filter(|(_, m)| **m) {
                    assert!(rgba.iter().all(|v| v.is_finite()));
                    assert!((0.0..=1.0).contains(&rgba[3]));
                }
                // Deterministic.
                assert_eq!(render_model_with(&frame, &options), image);
            }
        }
    }
}
