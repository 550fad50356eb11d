//! A frame's options: tessellation, the paper's angle threshold, footprint coarsening, the
//! precision and Fresnel model of the vertex paths, the viewpoint blending, the convex-hull split,
//! and where the lens vertices are traced.

pub use crate::hybrid::paths::VertexPrecision;
pub use crate::hybrid::viewpoints::ViewpointBlending;
use crate::trace::classes::ClassSet;
pub use crate::trace::schlick_table::FresnelModel;
use crate::{hybrid::tessellate::TessellationOptions, options::OptionError};

/// The paper's angle threshold: outgoing rays further apart than this make vertices differ.
pub const DEFAULT_ANGLE_DEGREES: f64 = 3.0;

/// Per-frame options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HybridOptions {
    /// Adaptive tessellation: the threshold t in subpixels (one default, one check, in
    /// [`TessellationOptions`]) and the depth cap.
    pub tessellation: TessellationOptions,
    /// Outgoing rays further apart than this (radians) make vertices differ (paper: 3°); in
    /// (0, π).
    pub angle_radians: f64,
    /// Footprint coarsening, in subpixels; 0 (the default) turns it off. A lens object whose
    /// screen footprint (the longer side of its projected bounding box) spans fewer subpixels
    /// than this is tessellated with `t × footprint / extent` (at most 8 t): a distant or tiny
    /// object gets proportionally fewer vertices. Changes the image where it applies.
    pub footprint_subpixels: f32,
    /// The float type of the per-vertex stages (vertex paths, texgen): f64 (the default), or
    /// f32 to measure what single precision would cost.
    pub precision: VertexPrecision,
    /// Which viewpoint samples a frame blends: the view space's own rule (the default), or
    /// fewer, to measure what the blend is worth.
    pub viewpoint_blending: ViewpointBlending,
    /// How the vertex paths evaluate Fresnel: exactly (the default: Schlick for mirrors, exact
    /// dielectric Fresnel for glass), or Schlick with its fifth-order term looked up in a 1D
    /// table per vertex (the PEM paper's 1D texture).
    pub fresnel: FresnelModel,
    /// The convex-hull split (PEM paper §4): a lens object layered by bounce draws its triangles
    /// on the convex hull of the lens geometry (facing the camera) with the distant layer only,
    /// since they cannot show self-reflections ([`crate::hybrid::hull`]). On by default; no
    /// effect on lens objects layered by distance.
    pub hull_split: bool,
    /// Where the lens vertices are ray traced: on the CPU, on the GPU, or as the device suits.
    pub tracer: VertexTracer,
    /// How the GPU tracer finds a ray's hits.
    pub traversal: crate::hybrid::gpu::Traversal,
    /// What the GPU tracer computes in: f32 (the default, every device), or f64, the CPU
    /// oracle's precision (devices with `shaderFloat64`). `precision` is the CPU's.
    pub gpu_precision: VertexPrecision,
    /// The shading terms of the lens objects: each one's scene-file setting (the default;
    /// greedy where it has none), the papers' two greedy terms, or one term per path class
    /// ([`crate::trace::classes`]) for every lens object. Classes are traced by either tracer
    /// (the CPU's in f64) and composited by the single pass while its varyings carry them, else
    /// by the multipass variant.
    pub terms: ShadingTerms,
}

/// Which shading terms a frame's lens objects sum (`--terms`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ShadingTerms {
    /// Each lens object's `terms` in the scene file; the greedy terms where it has none.
    #[default]
    Scene,
    /// The papers' two greedy terms for every lens object.
    Greedy,
    /// These path classes for every lens object.
    Classes(ClassSet),
}

impl ShadingTerms {
    /// Its name as the command line takes it: `scene`, `greedy`, or the class set.
    pub fn name(&self) -> String {
        match self {
            ShadingTerms::Scene => "scene".into(),
            ShadingTerms::Greedy => "greedy".into(),
            ShadingTerms::Classes(set) => set.name(),
        }
    }

    /// The path classes of a lens object whose scene file says `scene` (`None`: greedy).
    pub fn of(&self, scene: Option<ClassSet>) -> Option<ClassSet> {
        match *self {
            ShadingTerms::Scene => scene,
            ShadingTerms::Greedy => None,
            ShadingTerms::Classes(set) => Some(set),
        }
    }
}

/// Where a frame's lens vertices are ray traced (`--tracer`). The library's default is the CPU,
/// so that a caller's frames do not change with the device; the command line's is `auto`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum VertexTracer {
    /// On the CPU, in the frame's [`VertexPrecision`]: the paper's reference implementation.
    #[default]
    Cpu,
    /// On the GPU, in f32, by the compute pass of [`crate::hybrid::gpu`] (the CPU oracle's rules);
    /// only through a [`crate::runner::FrameRunner`], which owns the device.
    Gpu,
    /// The GPU on a hardware device, the CPU on a CPU device (lavapipe), where the CPU path is
    /// measured faster (`docs/results.md#gpu-frames`); the CPU without a device, or where the
    /// device cannot hold the scene's geometry.
    Auto,
}

impl VertexTracer {
    /// The name `--tracer` takes.
    pub fn name(self) -> &'static str {
        match self {
            VertexTracer::Cpu => "cpu",
            VertexTracer::Gpu => "gpu",
            VertexTracer::Auto => "auto",
        }
    }

    /// Whether this choice traces on `gpu` (for `auto`: whether it is not a CPU device).
    pub fn on_gpu(self, gpu: &crate::gpu::Gpu) -> bool {
        match self {
            VertexTracer::Cpu => false,
            VertexTracer::Gpu => true,
            VertexTracer::Auto => !gpu.is_cpu_device(),
        }
    }
}

impl Default for HybridOptions {
    fn default() -> Self {
        HybridOptions {
            tessellation: TessellationOptions::default(),
            angle_radians: DEFAULT_ANGLE_DEGREES.to_radians(),
            footprint_subpixels: 0.0,
            precision: VertexPrecision::F64,
            viewpoint_blending: ViewpointBlending::ViewSpace,
            fresnel: FresnelModel::Exact,
            hull_split: true,
            tracer: VertexTracer::Cpu,
            traversal: crate::hybrid::gpu::Traversal::Auto,
            gpu_precision: VertexPrecision::F32,
            terms: ShadingTerms::Scene,
        }
    }
}

/// The most footprint coarsening multiplies `t` by.
pub const MAX_FOOTPRINT_COARSENING: f32 = 8.0;

impl HybridOptions {
    /// Checks that path classes `classes` can be traced under these options: with exact
    /// Fresnel, and on the CPU tracer in f64 (the GPU tracer traces them in its own precision).
    pub fn validate_classes(&self, classes: ClassSet) -> Result<(), OptionError> {
        OptionError::require(
            self.tracer == VertexTracer::Gpu || self.precision == VertexPrecision::F64,
            crate::options::names::TERMS,
            classes.name(),
            "the CPU tracer traces path classes in f64 only; give greedy to measure the f32 vertex paths, or the GPU tracer",
        )?;
        OptionError::require(
            self.fresnel == FresnelModel::Exact,
            crate::options::names::FRESNEL,
            self.fresnel.name(),
            "path classes evaluate Fresnel exactly; give exact, or greedy terms for the table",
        )
    }

    /// The defaults with tessellation threshold `t` (subpixels).
    pub fn with_t(t: f32) -> HybridOptions {
        HybridOptions {
            tessellation: TessellationOptions {
                t,
                ..TessellationOptions::default()
            },
            ..HybridOptions::default()
        }
    }

    /// Checks every option: `t` ([`TessellationOptions::validate`]), the footprint (finite,
    /// ≥ 0), the angle in (0°, 180°), the Fresnel table's size ([`FresnelModel::validate`]),
    /// and path classes only where they are traced ([`HybridOptions::validate_classes`]).
    pub fn validate(&self) -> Result<(), OptionError> {
        self.tessellation.validate()?;
        self.fresnel.validate()?;
        if let ShadingTerms::Classes(classes) = self.terms {
            self.validate_classes(classes)?;
        }
        OptionError::require(
            self.footprint_subpixels.is_finite() && self.footprint_subpixels >= 0.0,
            crate::options::names::FOOTPRINT,
            self.footprint_subpixels,
            "give a number of subpixels ≥ 0 (0 turns footprint coarsening off), e.g. 64",
        )?;
        // The check is on the radians the oracle uses (an angle that underflows to 0 is out);
        // the message shows degrees as the user wrote them, at f32 precision so that the trip
        // through radians does not show (`-3`, not `-3.0000000000000004`).
        let radians = self.angle_radians;
        OptionError::require(
            radians.is_finite() && radians > 0.0 && radians < std::f64::consts::PI,
            crate::options::names::ANGLE,
            radians.to_degrees() as f32,
            "give an angle in (0, 180), e.g. 3",
        )
    }
}
