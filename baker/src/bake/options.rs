//! What decides a bake's maps ([`BakeOptions`], whose [`BakeOptions::hash`] is a bake's options
//! identity) and the constants of the baker's method.

use lensmap::{
    layers::{bake::debug_hash, projected::MAX_EM_SIZE},
    options::OptionError,
};

use super::failure::{BakeFailure, BakeInputError};
use crate::infer::{DEFAULT_MAX_EM_SIZE, EmSize, InferOptions};

/// Viewpoints (spread evenly over the view space) whose records place the layers.
pub const PLACEMENT_SAMPLES: usize = 8;

/// Placement records are traced at this fraction of the bake's resolution, 1 sample per pixel.
pub const PLACEMENT_SCALE: u32 = 4;

/// [`LayerCount::Auto`] stops adding layers when one more raises the lens PSNR by no more than this.
pub const AUTO_LAYER_GAIN_DB: f64 = 0.5;

/// [`LayerCount::Auto`] places at most this many layers.
pub const MAX_AUTO_LAYERS: usize = 4;

/// The default number of views per sample. Measured with `lensmap bench bake` (640×480, 3×3
/// targets, lens PSNR against a 6×6 reference; on sample 0, halfway to sample 1, 15° above):
/// K = 3 against K = 1 is +0.18 / +0.59 / −0.35 dB on teapot-room, +0.94 / +1.01 / +0.06 dB on
/// mirror-teapot and −0.03 / +0.10 / +0.23 dB on glass-sphere: better in 7 of 9 cases, for 2.4×
/// the bake time (teapot-room: 65 s per sample against 27 s on 2 cores).
pub const DEFAULT_MULTI_VIEW: usize = 3;

/// The spread of the views around a sample when the view space has a single sample, degrees.
pub const SINGLE_SAMPLE_SPREAD_DEGREES: f64 = 8.0;

/// Bumped whenever the baker's algorithm changes its output, so that a bake or staging
/// directory of an older baker is never resumed or merged with a newer one's.
pub const BAKER_REVISION: u32 = 1;

/// The radius of the one shell of a lens object whose views hit nothing, metres.
pub const FAR_SHELL_METRES: f64 = 100.0;

/// How many layers each lens object gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayerCount {
    /// As many layers as the scene names for the lens object, placed by clustering with fitted
    /// shells; where it names none, grown while they help (module docs).
    Auto,
    /// The scene's named shells exactly (where it names none, as `Auto`).
    Scene,
    /// This many, placed by clustering (at most; empty clusters are dropped).
    Count(usize),
}

/// Everything that decides a bake's maps (and so its options hash), and whether to judge it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeOptions {
    /// Target views' width in pixels.
    pub width: u32,
    /// Target views' height in pixels.
    pub height: u32,
    /// Target views' k×k supersampling (the hybrid test frames' too).
    pub supersampling: u32,
    /// The EM face size: searched at sample 0 up to a cap, or fixed.
    pub em_size: EmSize,
    /// Layers per lens object.
    pub layers: LayerCount,
    /// K: views per sample.
    pub multi_view: usize,
    /// When > 0, one more view per sample, raised this many degrees above it (module docs):
    /// for cameras that leave the view space's circle. 0: none.
    pub view_elevation_degrees: f64,
    /// Share the farthest layer between lens objects that see the same scene objects there
    /// (module docs): one map, solved on every sharing lens object's equations. Off by default:
    /// on teapot-room it stores 4 maps per sample instead of 5 but costs the cup 0.8–2.1 dB
    /// (README).
    pub share_layers: bool,
    /// Inference options (θc, solver, tessellation, compositor variant); its `em_size` is
    /// replaced by the plan's.
    pub infer: InferOptions,
    /// Whether each sample's lens PSNR is measured against a reference traced at the sample
    /// (does not change the maps).
    pub judge: bool,
}

impl Default for BakeOptions {
    fn default() -> Self {
        BakeOptions {
            width: 640,
            height: 480,
            supersampling: 3,
            em_size: EmSize::Auto {
                cap: DEFAULT_MAX_EM_SIZE,
            },
            layers: LayerCount::Auto,
            multi_view: DEFAULT_MULTI_VIEW,
            view_elevation_degrees: 0.0,
            share_layers: false,
            infer: InferOptions::default(),
            judge: true,
        }
    }
}

impl BakeOptions {
    /// The identity of everything that changes the maps (not `judge`). Without shared layers it
    /// is the hash bakes had before the option existed (their maps are the same), so those bakes
    /// are still resumed, merged and reused.
    pub fn hash(&self) -> String {
        let infer = &self.infer;
        let hash = debug_hash(&(
            BAKER_REVISION,
            (self.width, self.height, self.supersampling),
            self.em_size,
            self.layers,
            self.multi_view,
            (infer.hybrid, infer.variant, infer.theta_c, infer.solve),
            infer.direct_images,
        ));
        let hash = if self.share_layers {
            debug_hash(&(hash, "shared far layers"))
        } else {
            hash
        };
        if self.view_elevation_degrees > 0.0 {
            debug_hash(&(hash, "raised view", self.view_elevation_degrees.to_bits()))
        } else {
            hash
        }
    }
    /// Checks the options: each out of range is an [`OptionError`] naming the option by its
    /// field (`em_size`; `confidence_degrees` for [`InferOptions::theta_c`] in degrees,
    /// `tolerance` for the solver's), the target views' size a [`BakeInputError::Resolution`].
    pub fn validate(&self) -> Result<(), BakeFailure> {
        if self.width == 0 || self.height == 0 || self.supersampling == 0 {
            return Err(BakeInputError::Resolution {
                width: self.width,
                height: self.height,
                supersampling: self.supersampling,
            }
            .into());
        }
        let size = match self.em_size {
            EmSize::Auto { cap } => cap,
            EmSize::Fixed(size) => size,
        };
        OptionError::require(
            size.is_power_of_two() && size <= MAX_EM_SIZE,
            "em_size",
            size,
            format!("give auto or a power of two from 1 to {MAX_EM_SIZE}, e.g. 128"),
        )?;
        if let LayerCount::Count(n) = self.layers {
            OptionError::require(
                (1..=8).contains(&n),
                "layers",
                n,
                "give auto or a count from 1 to 8",
            )?;
        }
        let tolerance = self.infer.solve.tolerance;
        OptionError::require(
            tolerance.is_finite() && tolerance > 0.0 && tolerance < 1.0,
            "tolerance",
            tolerance,
            "give a relative residual in (0, 1), e.g. 1e-4",
        )?;
        let theta = self.infer.theta_c.to_degrees();
        OptionError::require(
            theta.is_finite() && theta > 0.0 && theta < 180.0,
            "confidence_degrees",
            theta,
            "give an angle in (0, 180), e.g. 30",
        )?;
        let elevation = self.view_elevation_degrees;
        OptionError::require(
            elevation.is_finite() && (0.0..90.0).contains(&elevation),
            "view_elevation_degrees",
            elevation,
            "give an angle in [0, 90), e.g. 15 (0: no raised view)",
        )?;
        OptionError::require(
            (1..=9).contains(&self.multi_view),
            "multi_view",
            self.multi_view,
            "give a view count from 1 to 9 (1 turns multi-view off)",
        )?;
        Ok(self.infer.hybrid.validate()?)
    }
}
