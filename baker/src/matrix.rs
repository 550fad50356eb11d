//! Rendering matrices read back from the device (hybrid-rendering paper §4.3; PEM paper, "EM
//! Inference"): the linear map A from every texel of one layer's cube map — all six faces and all
//! MIP levels, each a separate unknown — to the display pixels of the final image, after the box
//! filter of supersampling.
//!
//! # What A is, and what it leaves out (the one place this is said)
//!
//! A row is a display pixel (row-major, the camera's width × height); a column is a texel
//! ([`TexelLayout`]). A is measured on a *layer frame* ([`LayerFrame`]): the hybrid frame of one
//! lens object with **one term and one layer**, F·G = 1 at every vertex, viewpoint weight 1,
//! opaque geometry drawn black (it still occludes) and no other lens object shaded. So A holds
//! only the geometry of the hardware's sampling — which texels each pixel reads, with which
//! filter weights, and how the supersampled pixels are averaged. It leaves out:
//!
//! - **F·G** (Fresnel × attenuation) and the **viewpoint weight**: the targets exclude them too.
//!   They are *incident* radiance (PEM paper), so Fresnel stays out of the EM and the runtime
//!   multiplies it back per vertex. The runtime frame's pixel is therefore ≈ F·G·w·(A x) on
//!   smooth regions, exactly A x in the layer frame.
//! - **Alpha**: texels are premultiplied (α·rgb, α), filtering is linear in each channel alike, so
//!   one matrix serves all four channels: pixel rgba = A·(texel rgba).
//! - The **opaque geometry's** own colour: the layer frame's pixel is `base + A x`, where `base`
//!   is the frame of the all-zero EM (black opaque pixels with α = 1, zero elsewhere).
//!
//! # Test renderings, and why decoding them is unambiguous
//!
//! One pixel fragment takes one trilinear, seamless sample: at most a 2×2 footprint in each of two
//! *adjacent* MIP levels (no anisotropy: the runtime's sampler has none), the footprint reaching
//! into the *adjacent* faces at a seam (a corner: three mutually adjacent faces). So texels that
//! cannot meet in one fragment are lit together:
//!
//! - **levels of one parity** (even or odd): a fragment reads levels ⌊λ⌋ and ⌊λ⌋ + 1;
//! - **one pair of opposite faces** (±X, ±Y or ±Z): a footprint never reaches the opposite face;
//! - **one phase** (x mod 2, y mod 2) within a face: a 2×2 footprint holds one texel of each phase.
//!
//! That makes 2 parities × 3 face pairs × 4 phases = 24 subsets; the four phases go in the four
//! colour channels (channels filter independently), so **6 groups** of renders per layer frame.
//! Within a subset each fragment reads at most one lit texel; a box-filtered display pixel may mix
//! several fragments, so decoding happens per framebuffer pixel and the box filter is applied to
//! the decoded entries. Per group:
//!
//! - one **weight render**, lit texels = 1: the fragment's value is that texel's filter weight w;
//! - D **digit renders** that write the texel's index in its subset, one base-B digit per
//!   render, in one of two encodings ([`DigitEncoding`]):
//!   - **integers** (tried first): the lit texel = (2·digit + 1) / 2B for an integer
//!     0 ≤ digit < B, with B = 2^⌈log₂ L / D⌉ for the largest subset L and D = ⌈log₂ L / 16⌉ (so
//!     B ≤ 2^16, the texel is exact in the f32 map and within (0, 1) as a frame's texels must
//!     be). B·value / w − ½ is the digit up to the filter's rounding, accepted within ±0.1 of an
//!     integer. The odd numerators make a device that drops mantissa bits of the texels (an f32
//!     map filtered at lower precision) land exactly half-way between digits, where it is
//!     refused, rather than on a wrong digit. On lavapipe the largest distance from an integer
//!     over every matrix of a teapot-room sample (B = 16384) is 0.0023. **One** digit render per
//!     group up to 256² maps (L ≤ 2^16), two beyond;
//!   - **powers of two** (the fallback when an integer decode is refused): the lit texel =
//!     2^(−digit), B = 32. Scaling an input by a power of two scales every floating-point product
//!     and sum of the filter exactly, so value / w is exactly a power of two and the digit is read
//!     without rounding ambiguity on any linear filter (decoding still accepts a relative error
//!     of 1e-3 and reports anything else); D = ⌈log₃₂ L⌉, 3 at 128². Once a device needed it,
//!     the baker keeps it for the rest of the inference ([`Digits::Starting`]).
//!
//! Renders per layer frame: 1 (the base, all-zero EM) + 6 × (1 + D): 13 with integer digits up
//! to 256² maps (19 at 512²); with powers of two 25 at 128² and 31 at 512². Groups with no texels
//! are skipped. A fragment that reads two lit texels of one subset (no linear filter does, by
//! the subsets' construction) gives a weighted mean of two digits: with powers of two nearly
//! never a power of two, with integers within 0.1 of an integer for about a fifth of the
//! weights. One such fragment can therefore pass the integer decode unnoticed; a device that
//! mixes texels in many fragments is refused by both encodings and reported (tested).

use std::sync::Arc;

use lensmap::{
    cubemap::{CubeFace, CubeMap},
    index::{LayerIndex, LensIndex},
    render::{EnvironmentMesh, FrameInput, LensObject, TermVertices},
    trace::Term,
};
use rayon::prelude::*;
use sprs::{CsMat, TriMat};

/// Base of the power-of-two digits (exponents 0..32 of 2^(−digit)).
const POWER_BASE: usize = 32;
/// Relative mismatch between a power-of-two digit render's ratio and the nearest power of two
/// beyond which the device is reported as not linear.
const POWER_TOLERANCE: f64 = 1e-3;
/// Bits per integer digit at most: numerators 2·digit + 1 below 2^17 are exact in f32 with 7
/// bits to spare for the filter weight's rounding.
const INTEGER_BITS: u32 = 16;
/// Distance from the nearest integer beyond which an integer digit render's ratio is not
/// accepted (the matrix is then measured again with power-of-two digits).
const INTEGER_TOLERANCE: f64 = 0.1;
/// Colour channels, each an independent group of lit texels.
const CHANNELS: usize = 4;
/// Render groups per layer frame: 2 level parities × 3 opposite-face pairs.
pub const GROUPS: usize = 6;

/// Why a rendering matrix cannot be measured.
#[derive(Debug, thiserror::Error)]
pub enum MatrixError {
    /// The frame does not have what the layer frame needs; names the field and the fix.
    #[error("rendering matrix: {0}")]
    BadInput(String),
    /// A test rendering failed on the device.
    #[error("rendering matrix: test rendering failed: {0}")]
    Render(String),
    /// A test rendering's value is not what a linear filter gives: the device's filtering is not
    /// linear in the texels (or a fragment read two lit texels of one subset).
    #[error(
        "rendering matrix: framebuffer pixel ({x}, {y}) channel {channel}: {problem}; the device's filtering is not linear in the texels, so no rendering matrix describes it"
    )]
    Decode {
        /// Framebuffer x.
        x: u32,
        /// Framebuffer y.
        y: u32,
        /// Channel 0..4.
        channel: usize,
        /// What was found.
        problem: String,
    },
}

/// Column numbering of a cube map's texels: level by level (finest first), face by face in
/// Vulkan's order, row by row.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TexelLayout {
    /// Level-0 face size (a power of two).
    pub size: u32,
    /// First column of each level; the last entry is the total.
    offsets: Vec<usize>,
}

/// One texel: MIP level, face, column x, row y.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Texel {
    /// MIP level (0 = finest).
    pub level: usize,
    /// Face.
    pub face: CubeFace,
    /// Column within the face.
    pub x: u32,
    /// Row within the face.
    pub y: u32,
}

impl TexelLayout {
    /// The layout of a full-chain cube map of face size `size` (a power of two ≥ 1).
    pub fn new(size: u32) -> TexelLayout {
        let levels = CubeMap::full_chain_levels(size) as usize;
        let mut offsets = vec![0];
        for level in 0..levels {
            let edge = (size >> level).max(1) as usize;
            offsets.push(offsets[level] + 6 * edge * edge);
        }
        TexelLayout { size, offsets }
    }

    /// Number of MIP levels.
    pub fn levels(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Edge of `level`.
    pub fn edge(&self, level: usize) -> u32 {
        (self.size >> level).max(1)
    }

    /// Number of texels (columns).
    pub fn len(&self) -> usize {
        self.offsets[self.levels()]
    }

    /// Never empty (a 1² cube has six texels); for clippy's `len` convention.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Column of `texel`.
    pub fn column(&self, texel: Texel) -> usize {
        let edge = self.edge(texel.level) as usize;
        self.offsets[texel.level]
            + texel.face.index() * edge * edge
            + texel.y as usize * edge
            + texel.x as usize
    }

    /// Texel of `column` (< [`Self::len`]).
    pub fn texel(&self, column: usize) -> Texel {
        let level = self.offsets.partition_point(|&o| o <= column) - 1;
        let edge = self.edge(level) as usize;
        let within = column - self.offsets[level];
        let face = CubeFace::ALL[within / (edge * edge)];
        let pixel = within % (edge * edge);
        Texel {
            level,
            face,
            x: (pixel % edge) as u32,
            y: (pixel / edge) as u32,
        }
    }

    /// Columns of `level`.
    pub fn level_columns(&self, level: usize) -> std::ops::Range<usize> {
        self.offsets[level]..self.offsets[level + 1]
    }

    /// A cube map from a column vector of premultiplied texels.
    pub fn to_cube(&self, x: &[[f64; 4]]) -> CubeMap {
        let levels = (0..self.levels())
            .map(|level| {
                let edge = self.edge(level) as usize;
                let start = self.offsets[level];
                std::array::from_fn(|face| {
                    let from = start + face * edge * edge;
                    x[from..from + edge * edge]
                        .iter()
                        .map(|t| t.map(|v| v as f32))
                        .collect()
                })
            })
            .collect();
        CubeMap {
            size: self.size,
            levels,
        }
    }

    /// The column vector of a cube map of this layout's size.
    pub fn from_cube(&self, cube: &CubeMap) -> Vec<[f64; 4]> {
        cube.levels
            .iter()
            .flat_map(|faces| faces.iter().flatten())
            .map(|t| t.map(f64::from))
            .collect()
    }

    /// The test-rendering subset of a texel: (group, channel). See the module documentation.
    fn subset(texel: Texel) -> (usize, usize) {
        let parity = texel.level % 2;
        let pair = texel.face.index() / 2;
        let phase = (texel.x % 2 + 2 * (texel.y % 2)) as usize;
        (parity * 3 + pair, phase)
    }
}

/// How the digit renders write a texel's index within its subset (see the module
/// documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DigitEncoding {
    /// Digits 0 ≤ d < B (B ≤ 2^16) written as (2d + 1) / 2B: one digit render per group up to
    /// 256² maps.
    Integers,
    /// Digits written as 2^(−digit), base 32: exact on any linear filter, more renders.
    PowersOfTwo,
}

impl DigitEncoding {
    /// The base B and the number of digits D that name every index below `largest`.
    fn digits(self, largest: usize) -> (usize, u32) {
        match self {
            DigitEncoding::Integers => {
                // ⌈log₂ largest⌉ bits, split evenly over the fewest digits of ≤ INTEGER_BITS.
                let bits = usize::BITS - largest.saturating_sub(1).leading_zeros();
                let count = bits.div_ceil(INTEGER_BITS);
                (1 << bits.div_ceil(count.max(1)), count)
            }
            DigitEncoding::PowersOfTwo => {
                let mut count = 0;
                while POWER_BASE.pow(count) < largest {
                    count += 1;
                }
                (POWER_BASE, count)
            }
        }
    }

    /// The texel value that writes digit `digit` (< `base`): within (0, 1], as a frame's texels
    /// must be.
    fn value(self, digit: usize, base: usize) -> f64 {
        match self {
            // (2·digit + 1) / 2B: B is a power of two, so the division is exact and so is the
            // decode's multiplication by B.
            DigitEncoding::Integers => (2 * digit + 1) as f64 / (2 * base) as f64,
            DigitEncoding::PowersOfTwo => (-(digit as f64)).exp2(),
        }
    }

    /// The digit that a fragment's `ratio` (value / weight) writes, or what is wrong with it.
    fn decode(self, ratio: f64, base: usize) -> Result<usize, String> {
        let (digit, off) = match self {
            DigitEncoding::Integers => {
                let ratio = ratio * base as f64 - 0.5;
                let digit = ratio.round();
                (digit, (ratio - digit).abs() > INTEGER_TOLERANCE)
            }
            DigitEncoding::PowersOfTwo => {
                let digit = (-ratio.log2()).round();
                (digit, (ratio * digit.exp2() - 1.0).abs() > POWER_TOLERANCE)
            }
        };
        if !(0.0..base as f64).contains(&digit) || off {
            return Err(match self {
                DigitEncoding::Integers => {
                    format!("not within {INTEGER_TOLERANCE} of an integer below {base}")
                }
                DigitEncoding::PowersOfTwo => {
                    format!("not a power of two 2^-d with d < {base}")
                }
            });
        }
        Ok(digit as usize)
    }
}

/// The texels lit together, per group and channel, in column order; a texel's index in its list
/// is what the digit renders encode.
struct Subsets {
    members: Vec<[Vec<usize>; CHANNELS]>,
    /// The most texels of one subset.
    largest: usize,
}

impl Subsets {
    fn new(layout: &TexelLayout) -> Subsets {
        let mut members: Vec<[Vec<usize>; CHANNELS]> =
            (0..GROUPS).map(|_| Default::default()).collect();
        for column in 0..layout.len() {
            let (group, channel) = TexelLayout::subset(layout.texel(column));
            members[group][channel].push(column);
        }
        let largest = members.iter().flatten().map(Vec::len).max().unwrap_or(0);
        Subsets { members, largest }
    }

    /// The test cube of `group`: its texels = 1 (`digit` None), or the value that writes digit
    /// `d` of their index in `encoding`, base `base`.
    fn cube(
        &self,
        layout: &TexelLayout,
        group: usize,
        digit: Option<(DigitEncoding, usize, u32)>,
    ) -> CubeMap {
        let mut x = vec![[0.0f64; 4]; layout.len()];
        for (channel, columns) in self.members[group].iter().enumerate() {
            for (index, &column) in columns.iter().enumerate() {
                x[column][channel] = match digit {
                    None => 1.0,
                    Some((encoding, base, d)) => encoding.value((index / base.pow(d)) % base, base),
                };
            }
        }
        layout.to_cube(&x)
    }
}

/// Renders test frames at framebuffer resolution: the Vulkan device (through
/// [`lensmap::runner::FrameRunner`]) in the baker, or a CPU model in tests. A test frame is
/// begun once and then rendered with one cube map after another, so a device uploads the frame
/// once and only the maps after that.
pub trait TestRenderer {
    /// Makes `frame` (one lens object with one layer) the frame later renderings draw.
    fn begin(&mut self, frame: &FrameInput) -> Result<(), MatrixError>;
    /// Renders the begun frame with `em` (the begun map's face size) as the lens object's layer:
    /// framebuffer pixels, row-major, premultiplied RGBA, f32 as the RGBA32F target holds them.
    fn render(&mut self, em: Arc<CubeMap>) -> Result<Vec<[f32; 4]>, MatrixError>;
}

/// A renderer that counts its renderings (those of an attempt that failed to decode).
struct Counted<'a> {
    inner: &'a mut dyn TestRenderer,
    renders: usize,
}

impl TestRenderer for Counted<'_> {
    fn begin(&mut self, frame: &FrameInput) -> Result<(), MatrixError> {
        self.inner.begin(frame)
    }

    fn render(&mut self, em: Arc<CubeMap>) -> Result<Vec<[f32; 4]>, MatrixError> {
        self.renders += 1;
        self.inner.render(em)
    }
}

/// The frame whose lens pixels are `base + A x`: one lens object, one term, one layer, F·G = 1,
/// weight 1, opaque geometry black. Made from a runtime frame by [`LayerFrames`].
#[derive(Clone, Debug)]
pub struct LayerFrame {
    frame: FrameInput,
    /// Where the (cropped) framebuffer lies in the runtime frame's.
    crop: Crop,
    /// The term.
    pub term: Term,
    /// The layer.
    pub layer: LayerIndex,
}

impl LayerFrame {
    /// The layer frame with `em` as the layer's cube map (set in place: test renderings change
    /// only the map, never copy the lens mesh).
    pub fn with_em(&mut self, em: Arc<CubeMap>) -> &FrameInput {
        self.frame.lenses[0].layers = vec![vec![em]];
        &self.frame
    }

    /// Framebuffer width and height (the crop's).
    pub fn size(&self) -> (u32, u32) {
        (self.frame.width, self.frame.height)
    }

    /// Where the framebuffer lies in the runtime frame's.
    pub fn crop(&self) -> Crop {
        self.crop
    }

    /// A rendering of this frame box-filtered by `k` and placed in the runtime frame's display
    /// image (zero outside the crop): what `base + A x` is compared with.
    pub fn to_display(&self, pixels: &[[f32; 4]], k: u32) -> Vec<[f64; 4]> {
        let k = k.max(1);
        let crop = self.crop;
        let display = (crop.full.0 / k, crop.full.1 / k);
        let scale = 1.0 / f64::from(k * k);
        let mut image = vec![[0.0f64; 4]; (display.0 * display.1) as usize];
        for (i, p) in pixels.iter().enumerate() {
            let target = &mut image[crop.display_pixel(i, k)];
            for c in 0..CHANNELS {
                target[c] += f64::from(p[c]) * scale;
            }
        }
        image
    }
}

/// A rectangle of the runtime frame's framebuffer, in pixels, aligned to the supersampling so
/// that it holds whole display pixels. Test renderings draw only it: the lens object's screen
/// box (what lies outside has no lens pixel), with the projection shifted and scaled so that
/// every pixel centre is where it was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crop {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// The runtime frame's framebuffer width and height.
    pub full: (u32, u32),
}

impl Crop {
    /// The crop around NDC box `bounds` (the whole frame when `None`), widened by a pixel and
    /// aligned to multiples of `k`.
    fn around(bounds: Option<(glam::Vec2, glam::Vec2)>, width: u32, height: u32, k: u32) -> Crop {
        let full = (width, height);
        let whole = Crop {
            x: 0,
            y: 0,
            width,
            height,
            full,
        };
        let Some((lo, hi)) = bounds else {
            return whole;
        };
        let to_pixels = |ndc: f32, size: u32| (ndc + 1.0) * 0.5 * size as f32;
        let span = |lo: f32, hi: f32, size: u32| -> (u32, u32) {
            let start = (to_pixels(lo, size).floor() - 1.0).clamp(0.0, size as f32) as u32;
            let end = (to_pixels(hi, size).ceil() + 1.0).clamp(0.0, size as f32) as u32;
            let start = start / k * k;
            let end = end.div_ceil(k) * k;
            (start, end.min(size).max(start))
        };
        let (x0, x1) = span(lo.x, hi.x, full.0);
        let (y0, y1) = span(lo.y, hi.y, full.1);
        if x1 == x0 || y1 == y0 {
            return whole;
        }
        Crop {
            x: x0,
            y: y0,
            width: x1 - x0,
            height: y1 - y0,
            full,
        }
    }

    /// Clip space of the full frame → clip space of the crop: pixel (x + i, y + j) of the full
    /// framebuffer becomes pixel (i, j).
    fn clip_transform(&self) -> glam::Mat4 {
        let (full_w, full_h) = (self.full.0 as f32, self.full.1 as f32);
        let (w, h) = (self.width as f32, self.height as f32);
        let sx = full_w / w;
        let sy = full_h / h;
        let tx = (full_w - 2.0 * self.x as f32) / w - 1.0;
        let ty = (full_h - 2.0 * self.y as f32) / h - 1.0;
        glam::Mat4::from_cols(
            glam::Vec4::new(sx, 0.0, 0.0, 0.0),
            glam::Vec4::new(0.0, sy, 0.0, 0.0),
            glam::Vec4::new(0.0, 0.0, 1.0, 0.0),
            glam::Vec4::new(tx, ty, 0.0, 1.0),
        )
    }

    /// The display pixel (of the full frame, box filter `k`) of crop pixel index `i`.
    pub fn display_pixel(&self, i: usize, k: u32) -> usize {
        let (x, y) = (
            self.x + i as u32 % self.width,
            self.y + i as u32 / self.width,
        );
        ((y / k) * (self.full.0 / k) + x / k) as usize
    }
}

/// The layer frames of one lens object of a runtime frame: shares the blackened opaque geometry
/// between them so the renderer uploads it once.
pub struct LayerFrames {
    template: FrameInput,
    lens: LensObject,
    crop: Crop,
}

impl LayerFrames {
    /// From a runtime frame (as [`lensmap::hybrid::HybridScene::frame`] builds it, supersampled
    /// `k`×`k`) and the index of the lens object in it. Other lens objects become black
    /// occluders; the framebuffer is cropped to the lens object's screen box ([`Crop`]).
    pub fn new(frame: &FrameInput, lens: LensIndex, k: u32) -> Result<LayerFrames, MatrixError> {
        let Some(object) = frame.lenses.get(lens.index()) else {
            return Err(MatrixError::BadInput(format!(
                "lens {lens} does not exist; the frame has {} lens objects",
                frame.lenses.len()
            )));
        };
        let black = |positions: &[glam::Vec3], triangles: &[[u32; 3]]| {
            Arc::new(EnvironmentMesh {
                positions: positions.to_vec(),
                colours: vec![glam::Vec3::ZERO; positions.len()],
                triangles: triangles.to_vec(),
                light_map: None,
            })
        };
        // Only opaque triangles that can cover a lens pixel matter (they occlude it); the rest
        // would only cost rasterization in every test rendering. Kept: every triangle whose
        // screen bounding box meets the lens object's, or that crosses the eye plane.
        let lens_box = screen_box(frame, &object.positions, object.triangles.iter());
        let keep = |positions: &[glam::Vec3], triangles: &[[u32; 3]]| -> Vec<[u32; 3]> {
            triangles
                .iter()
                .filter(
                    |t| match (lens_box, screen_box(frame, positions, std::iter::once(*t))) {
                        (Some(lens), Some(own)) => {
                            own.0.x <= lens.1.x
                                && lens.0.x <= own.1.x
                                && own.0.y <= lens.1.y
                                && lens.0.y <= own.1.y
                        }
                        _ => true,
                    },
                )
                .copied()
                .collect()
        };
        let mut environment: Vec<Arc<EnvironmentMesh>> = frame
            .environment
            .iter()
            .map(|m| black(&m.positions, &keep(&m.positions, &m.triangles)))
            .collect();
        environment.extend(
            frame
                .lenses
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != lens.index())
                .map(|(_, other)| {
                    black(&other.positions, &keep(&other.positions, &other.triangles))
                }),
        );
        let k = k.max(1);
        if !frame.width.is_multiple_of(k) || !frame.height.is_multiple_of(k) {
            return Err(MatrixError::BadInput(format!(
                "framebuffer {}×{} is not a multiple of the supersampling {k}",
                frame.width, frame.height
            )));
        }
        let crop = Crop::around(lens_box, frame.width, frame.height, k);
        Ok(LayerFrames {
            template: FrameInput {
                width: crop.width,
                height: crop.height,
                view_proj: crop.clip_transform() * frame.view_proj,
                environment,
                glossy: frame.glossy.clone(),
                lenses: Vec::new(),
                viewpoint_weights: vec![1.0],
            },
            lens: object.clone(),
            crop,
        })
    }

    /// The terms the lens object has.
    pub fn terms(&self) -> Vec<Term> {
        self.lens.terms.iter().map(|t| t.term).collect()
    }

    /// Number of layers.
    pub fn layer_count(&self) -> usize {
        self.lens.terms.first().map_or(0, |t| t.directions.len())
    }

    /// The layer frame of (`term`, `layer`).
    pub fn layer(&self, term: Term, layer: LayerIndex) -> Result<LayerFrame, MatrixError> {
        let Some(vertices) = self.lens.terms.iter().find(|t| t.term == term) else {
            return Err(MatrixError::BadInput(format!(
                "lens \"{}\" has no {term:?} term",
                self.lens.name
            )));
        };
        let Some(directions) = vertices.directions.get(layer.index()) else {
            return Err(MatrixError::BadInput(format!(
                "lens \"{}\" has {} layers; layer {layer} does not exist",
                self.lens.name,
                vertices.directions.len()
            )));
        };
        let mut frame = self.template.clone();
        // A layer frame draws one term's directions with F·G 1, which the compositor draws the
        // same whichever term it is: a path class is drawn under the greedy term it starts
        // like, so that the single pass (which draws only the greedy terms) measures it as it
        // measures them. Under the multipass variant the frame would composite the overlapping
        // surfaces of an open lens mesh by blending, which is not linear in the texels.
        let drawn = match term {
            Term::Class(class) if class.class.starts_reflected() => Term::Reflection,
            Term::Class(_) => Term::Refraction,
            greedy => greedy,
        };
        // A path class covers only the vertices where its path exists (its F·G is zero at the
        // others, whose directions texgen borrows from another class): its frame is drawn with
        // F·G 1 there and 0 elsewhere, so that its equations cover what its targets cover (the
        // records of that class alone). Drawn with 1 everywhere, a pixel the classes share
        // would ask each class's texels, along the borrowed directions, for light only another
        // class carries: on mirror-teapot, whose R, RR, … split the pixels between them, the
        // bake of 4 classes fitted its own model 5.8 dB worse than a greedy bake. The greedy
        // terms keep 1 everywhere, so their bakes are unchanged.
        let fg = match term {
            Term::Class(_) => vertices
                .fg
                .iter()
                .map(|fg| {
                    if fg.max_element() > 0.0 {
                        glam::Vec3::ONE
                    } else {
                        glam::Vec3::ZERO
                    }
                })
                .collect(),
            _ => vec![glam::Vec3::ONE; self.lens.positions.len()],
        };
        frame.lenses.push(LensObject {
            name: self.lens.name.clone(),
            positions: self.lens.positions.clone(),
            triangles: self.lens.triangles.clone(),
            terms: vec![TermVertices {
                term: drawn,
                fg,
                directions: vec![directions.clone()],
            }],
            layers: vec![vec![Arc::new(CubeMap::uniform(1, [0.0; 4]))]],
            faces: self.lens.faces,
            // The convex-hull split leaves the local layer (layer 0) off the hull triangles, so
            // they do not constrain its texels; the other layers cover every triangle.
            hull_triangles: if layer.index() == 0 {
                self.lens.hull_triangles
            } else {
                0
            },
            resident: None,
        });
        Ok(LayerFrame {
            frame,
            crop: self.crop,
            term,
            layer,
        })
    }
}

/// The normalized-device-coordinate bounding box of `triangles`, or `None` when a vertex is at or
/// behind the eye plane (then the box is unbounded and the triangle is kept).
fn screen_box<'a>(
    frame: &FrameInput,
    positions: &[glam::Vec3],
    triangles: impl Iterator<Item = &'a [u32; 3]>,
) -> Option<(glam::Vec2, glam::Vec2)> {
    let mut lo = glam::Vec2::splat(f32::INFINITY);
    let mut hi = glam::Vec2::splat(f32::NEG_INFINITY);
    for t in triangles {
        for &i in t {
            let clip = frame.view_proj * positions[i as usize].extend(1.0);
            if clip.w.is_nan() || clip.w <= 1e-6 {
                return None;
            }
            let ndc = glam::Vec2::new(clip.x, clip.y) / clip.w;
            lo = lo.min(ndc);
            hi = hi.max(ndc);
        }
    }
    Some((lo, hi))
}

/// A measured rendering matrix and how it was measured.
#[derive(Clone, Debug)]
pub struct RenderingMatrix {
    /// Display pixels × texels, CSR. Entries are filter weights / k² (box filter included).
    pub a: CsMat<f64>,
    /// The layer frame of the all-zero EM at display resolution (zero outside the crop): the
    /// frame ([`LayerFrame::to_display`]) is `base + A x`.
    pub base: Vec<[f64; 4]>,
    /// Column layout.
    pub layout: TexelLayout,
    /// Display width and height.
    pub display: (u32, u32),
    /// Test renderings made (those of a failed integer-digit attempt included).
    pub renders: usize,
    /// How the digit renders that decoded A wrote the texel indices.
    pub encoding: DigitEncoding,
}

/// How [`RenderingMatrix::measure`] measures a matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeasureOptions {
    /// Face size of the test cube maps, texels: a power of two.
    pub size: u32,
    /// k: the framebuffer is k× the display resolution per axis, box-filtered (0 reads as 1).
    pub supersampling: u32,
    /// How the digit renders write the texel indices.
    pub digits: Digits,
}

impl MeasureOptions {
    /// Face size `size`, supersampling `supersampling`, digits starting as integers.
    pub fn new(size: u32, supersampling: u32) -> MeasureOptions {
        MeasureOptions {
            size,
            supersampling,
            digits: Digits::Starting(DigitEncoding::Integers),
        }
    }
}

/// Which digit encodings [`RenderingMatrix::measure`] uses (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Digits {
    /// This encoding first; integers the device's filtering is too coarse to decode are measured
    /// again as powers of two. A caller measuring many matrices on one device passes the previous
    /// matrix's [`RenderingMatrix::encoding`], so that a device too coarse for integers pays the
    /// failed attempt once, not per matrix.
    Starting(DigitEncoding),
    /// This encoding only: a failed decode is an error.
    Only(DigitEncoding),
}

impl RenderingMatrix {
    /// Measures A of `layer` through `renderer` as `options` say: test cube maps of face size
    /// `options.size`, a framebuffer `options.supersampling`× the display resolution per axis,
    /// box-filtered, and the digits in `options.digits`.
    pub fn measure(
        renderer: &mut dyn TestRenderer,
        layer: &mut LayerFrame,
        options: &MeasureOptions,
    ) -> Result<RenderingMatrix, MatrixError> {
        let (size, k) = (options.size, options.supersampling);
        let first = match options.digits {
            Digits::Only(encoding) | Digits::Starting(encoding @ DigitEncoding::PowersOfTwo) => {
                return Self::measure_in(renderer, layer, size, k, encoding);
            }
            Digits::Starting(first) => first,
        };
        let mut counted = Counted {
            inner: &mut *renderer,
            renders: 0,
        };
        match Self::measure_in(&mut counted, layer, size, k, first) {
            Err(MatrixError::Decode { .. }) => {
                let failed = counted.renders;
                let mut matrix =
                    Self::measure_in(renderer, layer, size, k, DigitEncoding::PowersOfTwo)?;
                matrix.renders += failed;
                Ok(matrix)
            }
            other => other,
        }
    }

    /// [`RenderingMatrix::measure`] with the digits in `encoding` and no fallback.
    fn measure_in(
        renderer: &mut dyn TestRenderer,
        layer: &mut LayerFrame,
        size: u32,
        k: u32,
        encoding: DigitEncoding,
    ) -> Result<RenderingMatrix, MatrixError> {
        if !size.is_power_of_two() {
            return Err(MatrixError::BadInput(format!(
                "cube-map size {size} is not a power of two; give 1, 2, 4, …"
            )));
        }
        let k = k.max(1);
        let (fb_width, fb_height) = layer.size();
        let crop = layer.crop();
        if !crop.full.0.is_multiple_of(k) || !crop.full.1.is_multiple_of(k) {
            return Err(MatrixError::BadInput(format!(
                "framebuffer {}×{} is not a multiple of the supersampling {k}",
                crop.full.0, crop.full.1
            )));
        }
        let display = (crop.full.0 / k, crop.full.1 / k);
        let layout = TexelLayout::new(size);
        let subsets = Subsets::new(&layout);
        let (base, digits) = encoding.digits(subsets.largest);
        let zero = Arc::new(CubeMap::uniform(size, [0.0; 4]));
        renderer.begin(layer.with_em(zero.clone()))?;
        let mut renders = 0;
        let mut render = |cube: Arc<CubeMap>, renders: &mut usize| {
            *renders += 1;
            let pixels = renderer.render(cube)?;
            if pixels.len() != (fb_width * fb_height) as usize {
                return Err(MatrixError::Render(format!(
                    "{} pixels read back for a {fb_width}×{fb_height} framebuffer",
                    pixels.len()
                )));
            }
            Ok(pixels)
        };
        let base_fb = render(zero, &mut renders)?;
        let mut triplets: Vec<(usize, usize, f64)> = Vec::new();
        let scale = 1.0 / f64::from(k * k);
        let display_pixel = |i: usize| crop.display_pixel(i, k);
        for group in 0..GROUPS {
            if subsets.members[group].iter().all(Vec::is_empty) {
                continue;
            }
            let weights = render(Arc::new(subsets.cube(&layout, group, None)), &mut renders)?;
            // (framebuffer pixel, channel, weight) of every fragment that read a lit texel.
            let lit: Vec<(usize, usize, f64)> = weights
                .par_iter()
                .zip(&base_fb)
                .enumerate()
                .flat_map_iter(|(i, (w, b))| {
                    (0..CHANNELS).filter_map(move |c| {
                        let weight = f64::from(w[c]) - f64::from(b[c]);
                        (weight != 0.0).then_some((i, c, weight))
                    })
                })
                .collect();
            let mut index = vec![0usize; lit.len()];
            for digit in 0..digits {
                let values = render(
                    Arc::new(subsets.cube(&layout, group, Some((encoding, base, digit)))),
                    &mut renders,
                )?;
                let decoded: Vec<Result<usize, MatrixError>> = lit
                    .par_iter()
                    .map(|&(i, c, weight)| {
                        let ratio =
                            (f64::from(values[i][c]) - f64::from(base_fb[i][c])) / weight;
                        encoding
                            .decode(ratio, base)
                            .map(|value| value * base.pow(digit))
                            .map_err(|problem| MatrixError::Decode {
                                x: crop.x + i as u32 % fb_width,
                                y: crop.y + i as u32 / fb_width,
                                channel: c,
                                problem: format!(
                                    "digit render {digit} gave {ratio} × the weight {weight}: {problem}"
                                ),
                            })
                    })
                    .collect();
                for (slot, part) in index.iter_mut().zip(decoded) {
                    *slot += part?;
                }
            }
            for (&(i, c, weight), &index) in lit.iter().zip(&index) {
                let Some(&column) = subsets.members[group][c].get(index) else {
                    return Err(MatrixError::Decode {
                        x: crop.x + i as u32 % fb_width,
                        y: crop.y + i as u32 / fb_width,
                        channel: c,
                        problem: format!(
                            "decoded texel index {index} but the subset has {} texels",
                            subsets.members[group][c].len()
                        ),
                    });
                };
                triplets.push((display_pixel(i), column, weight * scale));
            }
        }
        let rows = (display.0 * display.1) as usize;
        let mut tri = TriMat::with_capacity((rows, layout.len()), triplets.len());
        for (row, column, value) in triplets {
            tri.add_triplet(row, column, value);
        }
        let base = layer.to_display(&base_fb, k);
        Ok(RenderingMatrix {
            a: tri.to_csr(),
            base,
            layout,
            display,
            renders,
            encoding,
        })
    }

    /// `A x` (no base), per display pixel, premultiplied RGBA.
    pub fn apply(&self, x: &[[f64; 4]]) -> Vec<[f64; 4]> {
        multiply(&self.a, x)
    }

    /// The display pixels any texel reaches, and their coverage by the lens: the row sums of A
    /// (1 where a pixel is lens in every subsample).
    pub fn coverage(&self) -> Vec<f64> {
        self.a
            .outer_iterator()
            .map(|row| row.data().iter().sum())
            .collect()
    }

    /// The number of non-zero entries.
    pub fn nnz(&self) -> usize {
        self.a.nnz()
    }
}

/// `m x` for a CSR matrix and a vector of RGBA, rows in parallel.
pub fn multiply(m: &CsMat<f64>, x: &[[f64; 4]]) -> Vec<[f64; 4]> {
    debug_assert!(m.is_csr());
    let (indptr, indices, data) = (m.indptr(), m.indices(), m.data());
    (0..m.rows())
        .into_par_iter()
        .map(|row| {
            let mut sum = [0.0; 4];
            for k in indptr.outer_inds_sz(row) {
                for c in 0..CHANNELS {
                    sum[c] += data[k] * x[indices[k]][c];
                }
            }
            sum
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_layout_numbers_every_texel_once() {
        for size in [1, 2, 8] {
            let layout = TexelLayout::new(size);
            let total: usize = (0..layout.levels())
                .map(|l| 6 * (layout.edge(l) as usize).pow(2))
                .sum();
            assert_eq!(layout.len(), total);
            for column in 0..layout.len() {
                assert_eq!(layout.column(layout.texel(column)), column);
            }
            let cube = CubeMap::from_fn(size, |d| [d.x as f32, d.y as f32, d.z as f32, 1.0]);
            assert_eq!(layout.to_cube(&layout.from_cube(&cube)), cube);
        }
    }

    /// A device whose every framebuffer pixel reads a footprint given by hand — texel columns
    /// and filter weights — so the decoded matrix can be compared with the truth entry by entry.
    struct CraftedDevice {
        layout: TexelLayout,
        footprints: Vec<Vec<(usize, f32)>>,
    }

    impl TestRenderer for CraftedDevice {
        fn begin(&mut self, _frame: &FrameInput) -> Result<(), MatrixError> {
            Ok(())
        }

        fn render(&mut self, em: Arc<CubeMap>) -> Result<Vec<[f32; 4]>, MatrixError> {
            let x = self.layout.from_cube(&em);
            Ok(self
                .footprints
                .iter()
                .map(|footprint| {
                    let mut sum = [0.0f32; 4];
                    for &(column, weight) in footprint {
                        for c in 0..4 {
                            sum[c] += weight * x[column][c] as f32;
                        }
                    }
                    sum
                })
                .collect())
        }
    }

    /// A frame of `width × height` with one lens triangle, one term and one layer: what
    /// [`LayerFrames`] needs; the crafted device ignores its geometry. The triangle covers the
    /// whole screen so the crop is the whole frame.
    fn crafted_frame(width: u32, height: u32) -> FrameInput {
        let positions = vec![
            glam::Vec3::new(-10.0, -10.0, 0.5),
            glam::Vec3::new(10.0, -10.0, 0.5),
            glam::Vec3::new(0.0, 10.0, 0.5),
        ];
        FrameInput {
            width,
            height,
            view_proj: glam::Mat4::IDENTITY,
            environment: Vec::new(),
            glossy: Vec::new(),
            lenses: vec![LensObject {
                name: "crafted".into(),
                positions: positions.clone(),
                triangles: vec![[0, 1, 2]],
                terms: vec![TermVertices {
                    term: Term::Reflection,
                    fg: vec![glam::Vec3::ONE; 3],
                    directions: vec![positions],
                }],
                layers: vec![vec![Arc::new(CubeMap::uniform(1, [0.0; 4]))]],
                faces: lensmap::render::LensFaces::Front,
                hull_triangles: 0,
                resident: None,
            }],
            viewpoint_weights: vec![1.0],
        }
    }

    /// Trilinear footprints for every framebuffer pixel of a `pixels`-pixel frame: a 2×2
    /// bilinear footprint at level l and at l + 1, anywhere on a face — including past its edges,
    /// where the seam's texels come from the neighbouring face, and at corners, where only three
    /// texels exist (the spec's corner rule averages them; here the fourth weight goes to the
    /// three). Some pixels read nothing.
    fn crafted_footprints(layout: &TexelLayout, pixels: u32, seed: u64) -> Vec<Vec<(usize, f32)>> {
        use lensmap::cubemap::face::texel_source;
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let bilinear = |level: usize, face: CubeFace, i: i64, j: i64, weights: [f32; 4]| {
            let edge = layout.edge(level);
            let mut taps = Vec::new();
            let corners = [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)];
            let found: Vec<Option<usize>> = corners
                .iter()
                .map(|&(x, y)| {
                    texel_source(face, edge, x, y)
                        .map(|(face, x, y)| layout.column(Texel { level, face, x, y }))
                })
                .collect();
            let missing: f32 = found
                .iter()
                .zip(weights)
                .filter(|(f, _)| f.is_none())
                .map(|(_, w)| w)
                .sum();
            let present = found.iter().filter(|f| f.is_some()).count() as f32;
            for (f, w) in found.iter().zip(weights) {
                if let Some(column) = f {
                    taps.push((*column, w + missing / present));
                }
            }
            taps
        };
        (0..pixels)
            .map(|p| {
                if p % 7 == 3 {
                    return Vec::new();
                }
                let level = rng.gen_range(0..layout.levels() - 1);
                let face = CubeFace::ALL[rng.gen_range(0..6)];
                let edge = i64::from(layout.edge(level));
                let i = rng.gen_range(-1..edge);
                let j = rng.gen_range(-1..edge);
                let (fx, fy, fl): (f32, f32, f32) = (
                    rng.gen_range(0.0..1.0),
                    rng.gen_range(0.0..1.0),
                    rng.gen_range(0.0..1.0),
                );
                let w = [
                    (1.0 - fx) * (1.0 - fy),
                    fx * (1.0 - fy),
                    (1.0 - fx) * fy,
                    fx * fy,
                ];
                let mut taps: Vec<(usize, f32)> =
                    bilinear(level, face, i, j, w.map(|v| v * (1.0 - fl)));
                taps.extend(bilinear(
                    level + 1,
                    face,
                    i.div_euclid(2),
                    j.div_euclid(2),
                    w.map(|v| v * fl),
                ));
                taps
            })
            .collect()
    }

    /// Measures the crafted `footprints` (of a `width`×`height` display, supersampled `k`) as
    /// `options` say, checks every decoded entry against the box-filtered taps to `relative`, and
    /// returns the matrix.
    fn check_crafted(
        device: &mut dyn TestRenderer,
        footprints: &[Vec<(usize, f32)>],
        width: u32,
        height: u32,
        k: u32,
        options: &MeasureOptions,
        relative: f64,
    ) -> RenderingMatrix {
        let frames =
            LayerFrames::new(&crafted_frame(width * k, height * k), LensIndex::new(0), k).unwrap();
        let mut layer = frames.layer(Term::Reflection, LayerIndex::new(0)).unwrap();
        assert_eq!(layer.crop().width, width * k, "the crop is the whole frame");
        let matrix = RenderingMatrix::measure(device, &mut layer, options).unwrap();
        assert_eq!(matrix.layout, TexelLayout::new(options.size));
        // The truth: every tap of every framebuffer pixel, box-filtered.
        let mut truth =
            vec![std::collections::BTreeMap::<usize, f64>::new(); (width * height) as usize];
        for (p, footprint) in footprints.iter().enumerate() {
            let row = layer.crop().display_pixel(p, k);
            for &(column, weight) in footprint {
                *truth[row].entry(column).or_default() += f64::from(weight) / f64::from(k * k);
            }
        }
        let mut entries = 0;
        for (row, expected) in matrix.a.outer_iterator().zip(&truth) {
            let decoded: std::collections::BTreeMap<usize, f64> =
                row.iter().map(|(c, v)| (c, *v)).collect();
            assert_eq!(
                decoded.keys().collect::<Vec<_>>(),
                expected.keys().collect::<Vec<_>>()
            );
            for (column, value) in expected {
                assert!(
                    (decoded[column] - value).abs() <= relative * value.abs() + 1e-7,
                    "{column}: {} vs {value}",
                    decoded[column]
                );
                entries += 1;
            }
        }
        assert!(entries > 2000, "{entries} entries");
        matrix
    }

    #[test]
    fn decoding_recovers_crafted_footprints_across_seams_corners_and_levels() {
        let size = 8;
        let layout = TexelLayout::new(size);
        let (width, height, k) = (12u32, 10u32, 2u32);
        let footprints = crafted_footprints(&layout, width * k * height * k, 0xdec0de);
        let mut device = CraftedDevice {
            layout: layout.clone(),
            footprints: footprints.clone(),
        };
        // Integer digits: 1 base + 6 groups × (1 weight + 1 digit render): the largest subset
        // (34 texels) takes one digit of base 64.
        let matrix = check_crafted(
            &mut device,
            &footprints,
            width,
            height,
            k,
            &MeasureOptions::new(size, k),
            0.0,
        );
        assert_eq!(matrix.encoding, DigitEncoding::Integers);
        assert_eq!(matrix.renders, 1 + 6 * 2);
        // Powers of two, base 32: two digit renders per group; the same matrix.
        let powers = check_crafted(
            &mut device,
            &footprints,
            width,
            height,
            k,
            &MeasureOptions {
                digits: Digits::Only(DigitEncoding::PowersOfTwo),
                ..MeasureOptions::new(size, k)
            },
            0.0,
        );
        assert_eq!(powers.renders, 1 + 6 * 3);
        assert_eq!(powers.a, matrix.a);
    }

    /// The crafted device with every output scaled by 1 + e, |e| ≤ `relative`, pseudo-random per
    /// pixel, channel and rendering: a filter of reduced precision.
    struct CoarseDevice {
        device: CraftedDevice,
        relative: f32,
        renders: u32,
    }

    impl TestRenderer for CoarseDevice {
        fn begin(&mut self, frame: &FrameInput) -> Result<(), MatrixError> {
            self.device.begin(frame)
        }

        fn render(&mut self, em: Arc<CubeMap>) -> Result<Vec<[f32; 4]>, MatrixError> {
            self.renders += 1;
            let mut pixels = self.device.render(em)?;
            for (i, pixel) in pixels.iter_mut().enumerate() {
                for (c, value) in pixel.iter_mut().enumerate() {
                    let phase = (i * 4 + c) as f32 * 0.618 + self.renders as f32 * 1.7;
                    *value *= 1.0 + self.relative * phase.sin();
                }
            }
            Ok(pixels)
        }
    }

    #[test]
    fn a_coarse_filter_falls_back_to_power_of_two_digits() {
        // At 128² the largest subset (8,738 texels) takes one integer digit of base 16,384: a
        // relative error of 1e-4 moves large digits by more than 0.1, so the integer decode is
        // refused and the powers of two (tolerance 1e-3 relative) decode the matrix.
        let size = 128;
        let layout = TexelLayout::new(size);
        let (width, height, k) = (40u32, 30u32, 2u32);
        let footprints = crafted_footprints(&layout, width * k * height * k, 0xc0a75e);
        let mut device = CoarseDevice {
            device: CraftedDevice {
                layout: layout.clone(),
                footprints: footprints.clone(),
            },
            relative: 1e-4,
            renders: 0,
        };
        let matrix = check_crafted(
            &mut device,
            &footprints,
            width,
            height,
            k,
            &MeasureOptions::new(size, k),
            3e-4,
        );
        assert_eq!(matrix.encoding, DigitEncoding::PowersOfTwo);
        // The failed integer attempt's renders (it stops at the first group that fails) are
        // counted with the 1 + 6 × (1 + 3) of the powers of two.
        assert_eq!(matrix.renders, device.renders as usize);
        assert!(matrix.renders > 25, "{}", matrix.renders);
        // Told the device's encoding, the next matrix makes no failed attempt: 1 + 6 × 4.
        let before = device.renders;
        let again = check_crafted(
            &mut device,
            &footprints,
            width,
            height,
            k,
            &MeasureOptions {
                digits: Digits::Starting(matrix.encoding),
                ..MeasureOptions::new(size, k)
            },
            3e-4,
        );
        assert_eq!(again.renders, 1 + 6 * 4);
        assert_eq!(device.renders - before, 1 + 6 * 4);
        // The same device measured exactly (no error) decodes with integers.
        device.relative = 0.0;
        let exact = check_crafted(
            &mut device,
            &footprints,
            width,
            height,
            k,
            &MeasureOptions::new(size, k),
            0.0,
        );
        assert_eq!(exact.encoding, DigitEncoding::Integers);
        assert_eq!(exact.renders, 1 + 6 * 2);
    }

    #[test]
    fn digit_bases_name_every_index() {
        for largest in [0, 1, 2, 33, 34, 8_738, 65_536, 65_537, 174_763, 1 << 24] {
            for encoding in [DigitEncoding::Integers, DigitEncoding::PowersOfTwo] {
                let (base, count) = encoding.digits(largest);
                assert!(
                    base.pow(count) >= largest,
                    "{encoding:?} {largest}: {base}^{count}"
                );
                if encoding == DigitEncoding::Integers {
                    assert!(base <= 1 << INTEGER_BITS);
                    // The fewest digits of at most 16 bits.
                    assert!(
                        count == 0 || (1usize << (INTEGER_BITS * (count - 1))) < largest,
                        "{largest}: {count} digits"
                    );
                    // Every digit is exact in f32, and decodes to itself.
                    for digit in [0, 1, base / 2, base - 1].into_iter().filter(|&d| d < base) {
                        let value = encoding.value(digit, base);
                        assert_eq!(f64::from(value as f32), value);
                        assert!((0.0..=1.0).contains(&value));
                        assert_eq!(encoding.decode(value, base), Ok(digit));
                    }
                }
            }
        }
        assert_eq!(DigitEncoding::Integers.digits(8_738), (16_384, 1));
        assert_eq!(DigitEncoding::Integers.digits(174_763), (512, 2));
        assert_eq!(DigitEncoding::PowersOfTwo.digits(8_738), (32, 3));
        // A weighted mean of two digits is refused in both encodings.
        assert!(DigitEncoding::Integers.decode(3.0 / 64.0, 64).is_err());
        // An odd numerator that lost its last bit (a coarse texel) lands half-way: refused.
        assert!(DigitEncoding::Integers.decode(6.0 / 128.0, 64).is_err());
        assert!(DigitEncoding::PowersOfTwo.decode(0.625, 32).is_err());
    }

    #[test]
    fn fragments_reading_two_lit_texels_of_one_subset_are_reported() {
        // Every fragment reads two texels of the same subset (level 0, +X, phase (0, 0)) with
        // pseudo-random weights: no linear filter does that, and decoding must say so rather
        // than invent texels. A single such fragment can pass the integer decode (its weighted
        // mean of two digits may lie within 0.1 of an integer); hundreds cannot, in either
        // encoding.
        use rand::{Rng, SeedableRng};
        let size = 8;
        let layout = TexelLayout::new(size);
        let column = |x, y| {
            layout.column(Texel {
                level: 0,
                face: CubeFace::PositiveX,
                x,
                y,
            })
        };
        let mut rng = rand_pcg::Pcg64::seed_from_u64(0x2117);
        let footprints: Vec<Vec<(usize, f32)>> = (0..20 * 20)
            .map(|_| {
                let first = (2 * rng.gen_range(0..4), 2 * rng.gen_range(0..4));
                let mut second = first;
                while second == first {
                    second = (2 * rng.gen_range(0..4), 2 * rng.gen_range(0..4));
                }
                let w: f32 = rng.gen_range(0.05..0.95);
                vec![
                    (column(first.0, first.1), w),
                    (column(second.0, second.1), 1.0 - w),
                ]
            })
            .collect();
        let mut device = CraftedDevice {
            layout: layout.clone(),
            footprints,
        };
        let frames = LayerFrames::new(&crafted_frame(20, 20), LensIndex::new(0), 1).unwrap();
        let mut layer = frames.layer(Term::Reflection, LayerIndex::new(0)).unwrap();
        for encoding in [DigitEncoding::Integers, DigitEncoding::PowersOfTwo] {
            let only = MeasureOptions {
                digits: Digits::Only(encoding),
                ..MeasureOptions::new(size, 1)
            };
            let error = RenderingMatrix::measure(&mut device, &mut layer, &only).unwrap_err();
            assert!(matches!(error, MatrixError::Decode { .. }), "{error}");
        }
        let error =
            RenderingMatrix::measure(&mut device, &mut layer, &MeasureOptions::new(size, 1))
                .unwrap_err();
        assert!(matches!(error, MatrixError::Decode { .. }), "{error}");
    }
}
