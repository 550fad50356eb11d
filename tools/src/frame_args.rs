//! The hybrid frame's flags, one set for every command that renders one (`render`, `view`,
//! `bench hybrid`, `bench bake`, `bench infer`): flattened into each command's arguments, and
//! made into [`FrameOptions`] in one place ([`FrameArgs::options`]), checked once.

use clap::Args;
use lensmap::{
    hybrid::{
        DEFAULT_ANGLE_DEGREES, FresnelModel, HybridOptions, ShadingTerms,
        tessellate::{DEFAULT_MAX_VERTICES, DEFAULT_T, TessellationOptions},
    },
    options::Worded,
    render::{BlendScheme, Compositing, TargetFormat, Variant},
    runner::FrameOptions,
};

use crate::common::{
    BadUsage, BlendArg, FRESNEL_HELP, FormatArg, GpuPrecisionArg, HULL_SPLIT_HELP, OnOff,
    TracerArg, TraversalArg, VariantArg, flag_error, parse_fresnel, parse_terms,
};
use crate::words::Flags;

/// How a hybrid frame is made: tessellation, ray paths, compositing and the framebuffer.
#[derive(Args, Clone, Debug)]
pub struct FrameArgs {
    /// Tessellation threshold: triangles stop splitting when their edges are shorter than t
    /// subpixels.
    /// Range: (0, ∞).
    #[arg(long, default_value_t = DEFAULT_T, allow_negative_numbers = true)]
    pub t: f32,
    /// Outgoing rays further apart than this many degrees split a triangle.
    /// Range: (0, 180).
    #[arg(long, default_value_t = DEFAULT_ANGLE_DEGREES, allow_negative_numbers = true)]
    pub angle_degrees: f64,
    #[arg(long, value_name = "exact|table:N", default_value = "exact", value_parser = parse_fresnel, help = FRESNEL_HELP)]
    pub fresnel: FresnelModel,
    #[arg(long, value_enum, default_value = "on", help = HULL_SPLIT_HELP)]
    pub hull_split: OnOff,
    /// Where the lens vertices are ray traced.
    #[arg(long, value_enum, default_value = "auto")]
    pub tracer: TracerArg,
    /// How the GPU tracer finds a ray's hits (with the GPU tracer only).
    #[arg(long, value_enum, default_value = "auto")]
    pub traversal: TraversalArg,
    /// What the GPU tracer computes in (with the GPU tracer only).
    #[arg(long, value_enum, default_value = "f32")]
    pub gpu_precision: GpuPrecisionArg,
    /// Footprint coarsening: a lens object spanning fewer subpixels than this on screen is
    /// tessellated with a proportionally larger t (up to 8×); 0 turns it off.
    /// Range: [0, ∞).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub footprint: f32,
    /// The frame's budget of lens vertices (each is ray traced): past it no triangle is split
    /// further, and a warning says how many were left unsplit.
    /// Range: [0, 2^32).
    #[arg(long, default_value_t = DEFAULT_MAX_VERTICES, allow_negative_numbers = true)]
    pub max_vertices: usize,
    /// Shading terms per lens object: `scene` (each lens object's `terms` in the scene file,
    /// greedy where it has none), `greedy` (the papers' two terms), a count N of path classes
    /// (the first N of R, TT, TRT, TRRT, … for glass; of R, RR, … for mirrors), a list such as
    /// `R,TT,TRT,TRRT`, or `greedy:D` (the ray tree expanded to D events, greedy below). Path
    /// classes are traced by either tracer (the CPU's in f64 only) with exact Fresnel, and
    /// composited by the single pass while its 16 varyings carry them (K classes of n layers
    /// take K·(n + 1)); past them the frame runs multipass front-to-back.
    #[arg(long, default_value = "scene", value_parser = parse_terms)]
    pub terms: ShadingTerms,
    /// Compositor variant.
    #[arg(long, value_enum, default_value = "single-pass")]
    pub variant: VariantArg,
    /// How the multipass variant combines layers and (viewpoint, term) groups (the single pass
    /// takes only front-to-back).
    #[arg(long, value_enum, default_value = "front-to-back")]
    pub blend: BlendArg,
    /// Framebuffer format.
    #[arg(long, value_enum, default_value = "rgba16f")]
    pub format: FormatArg,
}

impl FrameArgs {
    /// The frame options the flags ask for, checked: a blending scheme the single pass does not
    /// take, and every option out of range, is one line naming the flag.
    pub fn options(&self) -> anyhow::Result<FrameOptions> {
        let options = FrameOptions {
            hybrid: HybridOptions {
                tessellation: TessellationOptions {
                    t: self.t,
                    max_vertices: self.max_vertices,
                    ..TessellationOptions::default()
                },
                angle_radians: self.angle_degrees.to_radians(),
                footprint_subpixels: self.footprint,
                fresnel: self.fresnel,
                hull_split: self.hull_split.is_on(),
                tracer: self.tracer.into(),
                traversal: self.traversal.into(),
                gpu_precision: self.gpu_precision.into(),
                terms: self.terms,
                ..HybridOptions::default()
            },
            compositing: Compositing::new(
                Variant::from(self.variant),
                BlendScheme::from(self.blend),
            )
            .map_err(|error| BadUsage(error.worded(&Flags)))?,
            format: TargetFormat::from(self.format),
        };
        options.validate().map_err(flag_error)?;
        Ok(options)
    }
}
