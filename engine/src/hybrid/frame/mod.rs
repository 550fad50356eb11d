//! Building one hybrid frame: trace and tessellate every lens object from the real camera,
//! generate the layered-EM texture coordinates (`texgen`), pick the viewpoint samples, and
//! assemble the [`FrameInput`] the compositor renders, timed per stage like the paper's table.
//!
//! A [`FrameBuilder`] builds the frames of any [`HybridScene`] and keeps the last one: a frame
//! equal to it (same scene version, camera, options and vertex stage) is reused whole. The
//! vertex stage is chosen once per frame ([`VertexStage`]): [`CpuStage`], [`GpuReadBack`] or
//! [`GpuResident`]. The frame with the exact radiance at every vertex, which the error budget
//! measures the tessellation by, is a builder of its own ([`vertex_exact_frame`]).

mod device;
mod exact;
mod options;
mod stage;
mod stats;
mod view;
mod wireframe;

use std::{num::NonZeroU64, sync::Arc, time::Instant};

pub use device::{GpuReadBack, GpuResident};
pub use exact::vertex_exact_frame;
pub use options::{
    DEFAULT_ANGLE_DEGREES, FresnelModel, HybridOptions, MAX_FOOTPRINT_COARSENING, ShadingTerms,
    VertexPrecision, VertexTracer, ViewpointBlending,
};
pub use stage::{BuiltLens, CpuStage, FrameJob, StageKey, VertexBudget, VertexStage};
pub use stats::HybridStats;
pub use view::{FrameView, LensJob};
pub use wireframe::{Wireframe, WireframeLens};

use super::{
    scene::{HybridScene, SceneVersion},
    tessellate::TessellationError,
    viewpoints::ViewpointBlend,
};
use crate::{
    index::LensIndex,
    options::{OptionError, names},
    render::{EnvironmentMesh, FrameInput, LensObject},
    scene::Camera,
    trace::stats::TraceCounters,
};

/// The identity of a frame a [`FrameBuilder`] built, unique in the process: what tells a caller
/// holding its upload that the next frame is the same one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FrameId(NonZeroU64);

impl FrameId {
    /// A new identity, never given before.
    fn next() -> FrameId {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        let value = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        FrameId(NonZeroU64::new(value).unwrap_or(NonZeroU64::MIN))
    }
}

/// A frame from [`FrameBuilder::frame_unless`].
#[derive(Debug)]
pub enum BuiltFrame {
    /// The frame the caller already holds (same identity): nothing to build or upload.
    Unchanged(HybridStats),
    /// A frame to upload, with its identity.
    New(Arc<FrameInput>, HybridStats, FrameId),
}

/// Everything a hybrid frame depends on: a frame with an equal key is the same frame.
#[derive(Clone, Debug, PartialEq)]
struct FrameKey {
    /// The scene and the version of it the frame was made from (any change to a scene bumps
    /// its version).
    scene: SceneVersion,
    camera: Camera,
    options: HybridOptions,
    /// Which stage made it: the GPU's f32 paths are another frame than the CPU's, and a frame
    /// drawn from a tracer's buffers is that tracer's frame.
    stage: StageKey,
}

/// The last frame a builder built, with its identity.
struct CachedFrame {
    key: FrameKey,
    /// Shared with the caller that uploads it: caching a frame copies nothing.
    frame: Arc<FrameInput>,
    /// Per lens object of `frame`, each triangle's subdivision depth (parallel to its
    /// `triangles`).
    depths: Vec<Vec<u8>>,
    stats: HybridStats,
    identity: FrameId,
}

/// Builds hybrid frames of any scene and keeps the last one, reused while nothing it depends on
/// changed. A [`crate::runner::FrameRunner`] owns one; a caller without a device can make its own.
#[derive(Default)]
pub struct FrameBuilder {
    last: Option<CachedFrame>,
}

impl FrameBuilder {
    /// A builder with no frame yet.
    pub fn new() -> FrameBuilder {
        FrameBuilder::default()
    }

    /// The frame of `scene` for `camera` (its resolution × supersampling is the framebuffer
    /// size), its vertices traced on the CPU; `options.tracer` must not ask for the GPU, which
    /// only a [`crate::runner::FrameRunner`] has. A frame equal to the last one is copied from
    /// it rather than traced again (`stats.reused`).
    pub fn frame(
        &mut self,
        scene: &HybridScene,
        camera: &Camera,
        options: &HybridOptions,
    ) -> Result<(FrameInput, HybridStats), TessellationError> {
        if options.tracer == VertexTracer::Gpu {
            return Err(gpu_without_device().into());
        }
        let (frame, stats, _) = self.latest(scene, camera, options, &CpuStage)?;
        // The cache keeps its share: the caller gets its own copy.
        Ok((Arc::unwrap_or_clone(frame), stats))
    }

    /// The frame of `scene` for `camera` made by `stage`, or [`BuiltFrame::Unchanged`] when it
    /// is the frame `held` (one this builder built, which the caller still holds): a still
    /// camera then costs no CPU stage at all. Otherwise as [`FrameBuilder::frame`], with the new
    /// frame's identity.
    pub fn frame_unless(
        &mut self,
        scene: &HybridScene,
        camera: &Camera,
        options: &HybridOptions,
        stage: &dyn VertexStage,
        held: Option<FrameId>,
    ) -> Result<BuiltFrame, TessellationError> {
        let (frame, stats, identity) = self.latest(scene, camera, options, stage)?;
        Ok(if stats.reused && held == Some(identity) {
            BuiltFrame::Unchanged(stats)
        } else {
            BuiltFrame::New(frame, stats, identity)
        })
    }

    /// The last frame when it is the one asked for (`stats.reused`), else the frame built now
    /// and kept.
    fn latest(
        &mut self,
        scene: &HybridScene,
        camera: &Camera,
        options: &HybridOptions,
        stage: &dyn VertexStage,
    ) -> Result<(Arc<FrameInput>, HybridStats, FrameId), TessellationError> {
        let key = FrameKey {
            scene: scene.version(),
            camera: *camera,
            options: *options,
            stage: stage.key(),
        };
        if let Some(cached) = self.last.as_ref().filter(|c| c.key == key) {
            let stats = HybridStats {
                reused: true,
                trace_ms: 0.0,
                tessellation_ms: 0.0,
                texgen_ms: 0.0,
                assemble_ms: 0.0,
                counters: TraceCounters::default(),
                vertices_traced: 0,
                ..cached.stats
            };
            return Ok((Arc::clone(&cached.frame), stats, cached.identity));
        }
        let built = build(scene, camera, options, stage)?;
        let frame = Arc::new(built.frame);
        let identity = FrameId::next();
        self.last = Some(CachedFrame {
            key,
            frame: Arc::clone(&frame),
            depths: built.depths,
            stats: built.stats,
            identity,
        });
        Ok((frame, built.stats, identity))
    }

    /// Forgets the last frame, so that the next one is built from scratch even for the same
    /// camera: what timing a full frame needs.
    pub fn forget(&mut self) {
        self.last = None;
    }

    /// The tessellation wireframe of the last frame this builder built or reused: per lens
    /// object (TraceScene order) its tessellated mesh as drawn and each triangle's subdivision
    /// depth, what the hybrid-rendering paper's Figure 5 colours. `None` before any frame and
    /// after [`FrameBuilder::forget`].
    pub fn last_wireframe(&self) -> Option<Wireframe> {
        let cached = self.last.as_ref()?;
        Some(Wireframe {
            lenses: cached
                .frame
                .lenses
                .iter()
                .zip(&cached.depths)
                .map(|(lens, depths)| WireframeLens {
                    name: lens.name.clone(),
                    positions: lens.positions.clone(),
                    triangles: lens.triangles.clone(),
                    depths: depths.clone(),
                })
                .collect(),
        })
    }
}

/// A frame built by [`build`].
struct Built {
    frame: FrameInput,
    stats: HybridStats,
    /// Per lens object, each triangle's subdivision depth.
    depths: Vec<Vec<u8>>,
}

/// The frame of `scene` for `camera` with every lens object made by `stage`.
fn build(
    scene: &HybridScene,
    camera: &Camera,
    options: &HybridOptions,
    stage: &dyn VertexStage,
) -> Result<Built, TessellationError> {
    let start = Instant::now();
    let (view, blend, mut stats) = begin_frame(scene, camera, options)?;
    stats.traced_on_gpu = stage.key().on_gpu();
    let jobs = LensIndex::all(scene.trace().lenses.len())
        .map(|lens| LensJob::new(scene, lens, &view, options, &blend, &mut stats))
        .collect::<Result<Vec<_>, _>>()?;
    stage.begin(&FrameJob {
        scene,
        options,
        lenses: &jobs,
    })?;
    let mut budget = VertexBudget::new(options.tessellation.max_vertices);
    let mut lenses = Vec::new();
    let mut depths = Vec::new();
    for job in &jobs {
        let built = stage.lens(job, &mut budget, &mut stats)?;
        lenses.push(built.object);
        depths.push(built.depths);
    }
    stats.counted_on_device = lenses.iter().any(|l| l.resident.is_some());
    let classes = |l: &LensObject| {
        l.terms
            .iter()
            .filter(|t| matches!(t.term, crate::trace::Term::Class(_)))
            .count()
    };
    stats.class_terms = lenses.iter().map(classes).max().unwrap_or(0);
    stats.class_slots = lenses
        .iter()
        .map(|l| crate::render::SinglePassProgram::class_slots(classes(l), l.layer_count()))
        .max()
        .unwrap_or(0);
    let frame = assemble(scene, view, &blend, lenses, Vec::new(), &mut stats);
    stats.assemble_ms = assembled_ms(start, &stats);
    Ok(Built {
        frame,
        stats,
        depths,
    })
}

/// What a frame fixes before any lens object: its view, the viewpoint samples it blends and
/// the stats that says so.
fn begin_frame(
    scene: &HybridScene,
    camera: &Camera,
    options: &HybridOptions,
) -> Result<(FrameView, ViewpointBlend, HybridStats), TessellationError> {
    let view = FrameView::new(scene, camera, options)?;
    let (blend, outside_view_space) = scene.placed(camera, options.viewpoint_blending);
    let stats = HybridStats {
        outside_view_space,
        viewpoints_blended: blend.samples.len(),
        ..HybridStats::default()
    };
    Ok((view, blend, stats))
}

/// The frame of `view` with `lenses` drawn by the compositor and `exact` drawn as opaque
/// environment meshes, the glossy objects' draws counted in `stats`.
fn assemble(
    scene: &HybridScene,
    view: FrameView,
    blend: &ViewpointBlend,
    lenses: Vec<LensObject>,
    exact: Vec<Arc<EnvironmentMesh>>,
    stats: &mut HybridStats,
) -> FrameInput {
    let (glossy, glossy_maps) = scene
        .glossy()
        .map_or_else(|| (Vec::new(), 0), |g| g.draws(view.screen.eye));
    stats.glossy_maps = glossy_maps;
    FrameInput {
        width: view.width,
        height: view.height,
        view_proj: view.view_proj,
        environment: scene
            .environment()
            .iter()
            .cloned()
            .chain(exact)
            .chain(view.sky)
            .collect(),
        glossy,
        lenses,
        viewpoint_weights: blend.samples.iter().map(|(_, w)| *w as f32).collect(),
    }
}

/// The rest of a frame's time since `start` after the stages `stats` counts, ms.
fn assembled_ms(start: Instant, stats: &HybridStats) -> f64 {
    (start.elapsed().as_secs_f64() * 1e3 - stats.trace_ms - stats.tessellation_ms - stats.texgen_ms)
        .max(0.0)
}

/// The GPU tracer asked of a frame built without a device.
fn gpu_without_device() -> OptionError {
    OptionError::new(
        names::TRACER,
        VertexTracer::Gpu.name(),
        "this frame is built without a device, and the GPU tracer runs only through a frame runner, which owns one; give cpu or auto",
    )
}

#[cfg(test)]
mod tests;
