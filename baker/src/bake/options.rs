//! What decides a bake's maps ([`BakeOptions`], whose [`BakeOptions::hash`] is a bake's options
//! identity) and the constants of the baker's method.

use lensmap::{
    hybrid::{
        FresnelModel, HybridOptions, ShadingTerms, paths::VertexPrecision,
        tessellate::TessellationOptions,
    },
    identity::{Canonical, Encoder, identity},
    layers::projected::MAX_EM_SIZE,
    options::OptionError,
    render::{BlendScheme, Variant},
};

use super::failure::{BakeFailure, BakeInputError};
use super::names;
use crate::infer::{DEFAULT_MAX_EM_SIZE, EmSize, InferOptions};
use crate::solve::{SolveMethod, SolveOptions};

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
/// mirror-teapot and −0.03 / +0.10 / +0.23 dB on glass-sphere (`docs/results.md#bake-judged`):
/// better in 7 of 9 cases, for 2.4× the bake time (teapot-room: 65 s per sample against 27 s on
/// 2 cores).
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
    /// By bounce for every lens object (the PEM paper's, [`crate::bounce`]): a local ellipsoid
    /// and a distant box; a lens object with a glass surface is refused.
    Bounce,
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
    /// (`docs/results.md#bake-shared-layers`).
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
    /// The identity of everything that changes the maps (not `judge`): the canonical encoding
    /// of [`lensmap::identity`] of every field and the [`BAKER_REVISION`].
    pub fn hash(&self) -> String {
        identity("bake options", self)
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
            names::EM_SIZE,
            size,
            format!("give auto or a power of two from 1 to {MAX_EM_SIZE}, e.g. 128"),
        )?;
        if let LayerCount::Count(n) = self.layers {
            OptionError::require(
                (1..=8).contains(&n),
                names::LAYERS,
                n,
                "give auto or a count from 1 to 8",
            )?;
        }
        let tolerance = self.infer.solve.tolerance;
        OptionError::require(
            tolerance.is_finite() && tolerance > 0.0 && tolerance < 1.0,
            names::TOLERANCE,
            tolerance,
            "give a relative residual in (0, 1), e.g. 1e-4",
        )?;
        let theta = self.infer.theta_c.to_degrees();
        OptionError::require(
            theta.is_finite() && theta > 0.0 && theta < 180.0,
            names::CONFIDENCE,
            theta,
            "give an angle in (0, 180), e.g. 30",
        )?;
        let elevation = self.view_elevation_degrees;
        OptionError::require(
            elevation.is_finite() && (0.0..90.0).contains(&elevation),
            names::VIEW_ELEVATION,
            elevation,
            "give an angle in [0, 90), e.g. 15 (0: no raised view)",
        )?;
        OptionError::require(
            (1..=9).contains(&self.multi_view),
            names::MULTI_VIEW,
            self.multi_view,
            "give a view count from 1 to 9 (1 turns multi-view off)",
        )?;
        if let ShadingTerms::Classes(classes) = self.infer.hybrid.terms {
            // Path classes are traced on the CPU in f64 with exact Fresnel, as in a frame.
            self.infer.hybrid.validate_classes(classes)?;
            OptionError::require(
                self.layers != LayerCount::Bounce,
                lensmap::options::names::TERMS,
                classes.name(),
                "path classes follow a path until it leaves, but layers by bounce stop at the first bounce; give a layer count or auto (layers by distance), or greedy",
            )?;
        }
        Ok(self.infer.hybrid.validate()?)
    }
}

/// Every field that changes the maps, in a fixed order (each struct destructured whole, so a new
/// field cannot be left out unnoticed); `judge` does not change them and is left out, as is the
/// inference's `em_size`, which the plan replaces.
impl Canonical for BakeOptions {
    fn encode(&self, encoder: &mut Encoder) {
        let BakeOptions {
            width,
            height,
            supersampling,
            em_size,
            layers,
            multi_view,
            view_elevation_degrees,
            share_layers,
            infer,
            judge: _,
        } = self;
        encoder
            .value(&BAKER_REVISION)
            .value(width)
            .value(height)
            .value(supersampling);
        match em_size {
            EmSize::Auto { cap } => encoder.tag(0).value(cap),
            EmSize::Fixed(size) => encoder.tag(1).value(size),
        };
        match layers {
            LayerCount::Auto => encoder.tag(0),
            LayerCount::Scene => encoder.tag(1),
            LayerCount::Count(count) => encoder.tag(2).value(count),
            LayerCount::Bounce => encoder.tag(3),
        };
        encoder
            .value(multi_view)
            .value(view_elevation_degrees)
            .value(share_layers);
        let InferOptions {
            hybrid,
            compositing,
            em_size: _,
            theta_c,
            direct_images,
            solve,
        } = infer;
        encode_hybrid(encoder, hybrid);
        encoder.tag(match compositing.variant() {
            Variant::Multipass => 0,
            Variant::SinglePass => 1,
        });
        // The paper's front-to-back scheme adds nothing, so that bakes made before schemes
        // could be chosen keep their identity.
        if compositing.blend() != BlendScheme::FrontToBack {
            encoder.value(compositing.blend().name());
        }
        encoder.value(theta_c).value(direct_images);
        let SolveOptions {
            method,
            smoothness,
            tolerance,
            max_iterations,
        } = solve;
        encoder
            .tag(match method {
                SolveMethod::ConjugateGradient => 0,
                SolveMethod::Lsqr => 1,
            })
            .value(smoothness)
            .value(tolerance)
            .value(max_iterations);
        encode_fresnel(encoder, hybrid.fresnel);
        encode_hull_split(encoder, *layers, hybrid.hull_split);
        encode_terms(encoder, infer);
    }
}

/// The terms the bake's equations are of ([`InferOptions::frame_options`]). Path classes came
/// after identity version 1: the greedy terms, what every earlier bake and every bake whose
/// options leave the terms to the scene file solves, write nothing, so their identities stand;
/// classes write tag 3 (distinct from [`encode_fresnel`]'s and [`encode_hull_split`]'s) and the
/// set's name. Written last, it cannot be confused with another field.
fn encode_terms(encoder: &mut Encoder, infer: &InferOptions) {
    if let ShadingTerms::Classes(set) = infer.frame_options().terms {
        encoder.tag(3).value(&set.name());
    }
}

/// The convex-hull split of the test renderings, which changes the local layer a lens object
/// layered by bounce infers (hull triangles do not constrain it). It came after identity
/// version 1, and every earlier bake keeps its identity and its meaning: a bake with
/// `--layers bounce` then had no split, so it writes tag 2 (distinct from [`encode_fresnel`]'s
/// tag 1) only with the split on; a bake whose layer count is left to the scene or the baker then
/// had no lens by bounce (the scene file's `layering` came with the split), so the split being on
/// changed nothing and writes nothing, and off writes the tag. An explicit layer count has no
/// lens by bounce: nothing either way.
fn encode_hull_split(encoder: &mut Encoder, layers: LayerCount, hull_split: bool) {
    let tagged = match layers {
        LayerCount::Bounce => hull_split,
        LayerCount::Auto | LayerCount::Scene => !hull_split,
        LayerCount::Count(_) => false,
    };
    if tagged {
        encoder.tag(2);
    }
}

/// The test renderings' Fresnel model. It is in the identity because it changes the maps: the
/// rendering matrix is drawn with each vertex's F·G, which a table changes (unlike the viewpoint
/// blending, which the test renderings never use). The model came after identity version 1 was
/// fixed: the exact one, what every earlier bake used, writes nothing, so their identities stand;
/// a table writes tag 1 and its size. Written after everything else, whose encoding delimits
/// itself, it cannot be confused with another field.
fn encode_fresnel(encoder: &mut Encoder, fresnel: FresnelModel) {
    match fresnel {
        FresnelModel::Exact => {}
        FresnelModel::Table { texels } => {
            encoder.tag(1).value(&texels);
        }
    }
}

/// The hybrid frame's options as the inference's test renderings use them.
fn encode_hybrid(encoder: &mut Encoder, hybrid: &HybridOptions) {
    let HybridOptions {
        tessellation,
        angle_radians,
        footprint_subpixels,
        precision,
        // The test renderings are drawn at the samples with each sample's own maps: one
        // viewpoint, whatever the blending.
        viewpoint_blending: _,
        // Written last of all the options ([`encode_fresnel`], [`encode_hull_split`]).
        fresnel: _,
        hull_split: _,
        // The test renderings are built without a device, so on the CPU (`gpu` is refused).
        tracer: _,
        traversal: _,
        gpu_precision: _,
        // Written last of all the options ([`encode_terms`]).
        terms: _,
    } = hybrid;
    let TessellationOptions {
        t,
        max_depth,
        max_vertices,
    } = tessellation;
    encoder
        .value(t)
        .value(max_depth)
        .value(max_vertices)
        .value(angle_radians)
        .value(footprint_subpixels)
        .tag(match precision {
            VertexPrecision::F64 => 0,
            VertexPrecision::F32 => 1,
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use lensmap::trace::classes::ClassSet;

    /// Options with every field set (none left to a default that may move).
    fn fixed() -> BakeOptions {
        BakeOptions {
            width: 320,
            height: 240,
            supersampling: 2,
            em_size: EmSize::Fixed(64),
            layers: LayerCount::Count(3),
            multi_view: 3,
            view_elevation_degrees: 7.5,
            share_layers: true,
            infer: InferOptions {
                hybrid: HybridOptions {
                    tessellation: TessellationOptions {
                        t: 3.0,
                        max_depth: 12,
                        max_vertices: 1_000_000,
                    },
                    angle_radians: 3f64.to_radians(),
                    footprint_subpixels: 0.0,
                    precision: VertexPrecision::F64,
                    viewpoint_blending: lensmap::hybrid::ViewpointBlending::ViewSpace,
                    fresnel: FresnelModel::Exact,
                    hull_split: true,
                    tracer: lensmap::hybrid::VertexTracer::Cpu,
                    traversal: lensmap::hybrid::gpu::Traversal::Auto,
                    gpu_precision: VertexPrecision::F32,
                    terms: ShadingTerms::Scene,
                },
                compositing: lensmap::render::Compositing::SinglePass,
                em_size: EmSize::Fixed(64),
                theta_c: 30f64.to_radians(),
                direct_images: false,
                solve: SolveOptions {
                    method: SolveMethod::ConjugateGradient,
                    smoothness: 0.01,
                    tolerance: 1e-4,
                    max_iterations: 400,
                },
            },
            judge: true,
        }
    }

    /// The identity of fixed options, pinned: a change here means every bake's options identity
    /// moved, which needs a new `lensmap::identity::IDENTITY_VERSION` (or a new
    /// [`BAKER_REVISION`], when the maps change).
    #[test]
    fn the_identity_of_fixed_options_is_pinned() {
        assert_eq!(
            fixed().hash(),
            "9d643eb099a4f548f7df7f39ff03f48d9c372d2497510c1a6a288521b3e6ee67"
        );
    }

    /// Every option that changes the maps changes the identity; judging does not.
    #[test]
    fn the_identity_covers_what_changes_the_maps() {
        let base = fixed().hash();
        let unjudged = BakeOptions {
            judge: false,
            ..fixed()
        };
        assert_eq!(unjudged.hash(), base);
        let mut variants = vec![
            BakeOptions {
                width: 321,
                ..fixed()
            },
            BakeOptions {
                layers: LayerCount::Auto,
                ..fixed()
            },
            BakeOptions {
                share_layers: false,
                ..fixed()
            },
            BakeOptions {
                view_elevation_degrees: 0.0,
                ..fixed()
            },
        ];
        let mut tolerance = fixed();
        tolerance.infer.solve.tolerance = 1e-5;
        variants.push(tolerance);
        let mut precision = fixed();
        precision.infer.hybrid.precision = VertexPrecision::F32;
        variants.push(precision);
        for texels in [64, 65] {
            let mut fresnel = fixed();
            fresnel.infer.hybrid.fresnel = FresnelModel::Table { texels };
            variants.push(fresnel);
        }
        for (i, options) in variants.iter().enumerate() {
            assert_ne!(options.hash(), base, "variant {i}");
        }
        let (table_64, table_65) = (&variants[variants.len() - 2], &variants[variants.len() - 1]);
        assert_ne!(table_64.hash(), table_65.hash());
    }

    /// The terms are in the identity where they are path classes, each set its own; the greedy
    /// terms, asked for or left to the scene file, keep the pinned identity of every earlier
    /// bake ([`encode_terms`]). Classes on layers by bounce, or traced in f32, are refused.
    #[test]
    fn path_classes_are_in_the_identity_and_greedy_bakes_keep_theirs() {
        let with = |terms| {
            let mut options = fixed();
            options.infer.hybrid.terms = terms;
            options
        };
        let class = |text: &str| ShadingTerms::Classes(ClassSet::parse(text).unwrap());
        let pinned = fixed().hash();
        assert_eq!(with(ShadingTerms::Greedy).hash(), pinned);
        let hashes = [
            pinned,
            with(class("4")).hash(),
            with(class("3")).hash(),
            with(class("R,TT,TRT")).hash(),
        ];
        for i in 0..hashes.len() {
            for j in 0..i {
                assert_ne!(hashes[i], hashes[j], "{i} and {j}");
            }
        }
        assert!(with(class("4")).validate().is_ok());
        let mut bounce = with(class("4"));
        bounce.layers = LayerCount::Bounce;
        let error = bounce.validate().unwrap_err().to_string();
        assert!(error.contains("bounce"), "{error}");
        let mut single = with(class("4"));
        single.infer.hybrid.precision = VertexPrecision::F32;
        assert!(single.validate().is_err());
    }

    /// The convex-hull split is in the identity of a bake that may layer by bounce, apart from a
    /// Fresnel table, and every bake made before it keeps its identity ([`encode_hull_split`]).
    #[test]
    fn the_hull_split_is_in_the_identity_of_bakes_by_bounce_only() {
        let with = |layers, hull_split, fresnel| {
            let mut options = fixed();
            options.layers = layers;
            options.infer.hybrid.hull_split = hull_split;
            options.infer.hybrid.fresnel = fresnel;
            options.hash()
        };
        let exact = FresnelModel::Exact;
        let table = FresnelModel::Table { texels: 2 };
        let count = LayerCount::Count(3);
        assert_eq!(with(count, true, exact), with(count, false, exact));
        // Left to the scene, whose file may layer a lens by bounce.
        assert_ne!(
            with(LayerCount::Auto, true, exact),
            with(LayerCount::Auto, false, exact)
        );
        let bounce = [
            with(LayerCount::Bounce, true, exact),
            with(LayerCount::Bounce, false, exact),
            with(LayerCount::Bounce, true, table),
            with(LayerCount::Bounce, false, table),
        ];
        for i in 0..bounce.len() {
            for j in 0..i {
                assert_ne!(bounce[i], bounce[j], "{i} and {j}");
            }
        }
    }
}
