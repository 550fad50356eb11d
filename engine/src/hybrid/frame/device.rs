//! The GPU's two vertex stages: the whole tessellation and texgen of each scene object run on
//! the device ([`crate::hybrid::gpu`]), then either read back and assembled on the host
//! ([`GpuReadBack`]: the mesh and its per-vertex data, the depths for the wireframe, the counts
//! at once), or left where the device made them for the frame to draw ([`GpuResident`]: nothing
//! per vertex read back; the counts read once the frame is done).

use std::{sync::Arc, time::Instant};

use super::{
    HybridStats,
    stage::{
        BuiltLens, Counted, FrameJob, MergedLens, StageKey, VertexBudget, VertexStage,
        count_tessellation,
    },
    view::LensJob,
};
use crate::{
    gpu::GpuError,
    hybrid::{
        gpu::{
            DeviceExtras, GpuPaths, GpuStageMs, GpuTessellationRequest, PreparedObject,
            TexgenRequest,
        },
        paths::{OracleSettings, PathOracle},
        tessellate::{TessellationError, TessellationOptions},
        texgen::{self, LensMesh, texgen},
    },
    render::{DeviceLensPart, LensObject, ResidentLens, TermVertices, compute::ComputeWork},
    trace::stats::TraceCounters,
};

/// Vertices traced, tessellated and given texture coordinates on the GPU, and read back.
#[derive(Clone, Copy)]
pub struct GpuReadBack<'a> {
    /// The device and the tracer resident on it.
    pub paths: GpuPaths<'a>,
}

/// Vertices traced, tessellated and given texture coordinates on the GPU, and drawn where the
/// device left them.
#[derive(Clone, Copy)]
pub struct GpuResident<'a> {
    /// The device and the tracer resident on it.
    pub paths: GpuPaths<'a>,
}

/// What the GPU's texgen needs of lens object `job`.
fn texgen_request<'a>(job: &'a LensJob<'_>) -> TexgenRequest<'a> {
    let layers = &job.scene.lenses()[job.lens.index()];
    TexgenRequest {
        shells: &layers.shells,
        em_origins: &layers.em_origins,
        refraction: texgen::has_refraction(job.scene.trace(), job.lens.index()),
        classes: &job.classes,
    }
}

/// The GPU tessellation's request of `oracle`'s settings (its camera, paths and criterion) with
/// `options` and what `extras` adds.
fn request<'a>(
    settings: &'a OracleSettings,
    options: &'a TessellationOptions,
    extras: DeviceExtras<'a>,
) -> GpuTessellationRequest<'a> {
    GpuTessellationRequest {
        camera: &settings.camera,
        settings: &settings.paths,
        cos_threshold: settings.cos_threshold,
        back_faces: settings.back_faces,
        options,
        texgen: extras.texgen,
        hull: extras.hull,
        continue_budget: extras.continue_budget,
    }
}

/// Refuses a GPU tracer made from another scene than `oracle`'s.
fn check_holds(paths: GpuPaths<'_>, oracle: &PathOracle<'_>) -> Result<(), TessellationError> {
    if !paths.tracer.holds(oracle.trace_scene()) {
        return Err(GpuError::Internal(
            "the GPU tracer: it holds another scene's geometry than the one traced".into(),
        )
        .into());
    }
    Ok(())
}

/// Adds a GPU tessellation's tracing time and rays to `oracle`'s: the trace passes' device time
/// when timed, else the submission's wall time (every pass, the split passes too; no read-back
/// or rebuilding of the mesh on the CPU).
fn add_gpu_time(
    oracle: &PathOracle<'_>,
    stage_ms: Option<GpuStageMs>,
    submission_ms: f64,
    counters: TraceCounters,
) {
    oracle.add_traced(
        stage_ms.map_or(submission_ms, |stages| stages.trace),
        counters,
    );
}

/// A lens object with no scene object inside the view: its (empty) mesh given texture
/// coordinates on the CPU, as every stage draws it.
fn empty_lens(job: &LensJob<'_>, mesh: LensMesh) -> LensObject {
    let scene = job.scene;
    texgen(
        scene.trace(),
        job.lens.index(),
        &scene.lenses()[job.lens.index()],
        mesh,
        &[],
        &[],
        job.blend,
        job.options.precision,
    )
}

impl VertexStage for GpuReadBack<'_> {
    fn key(&self) -> StageKey {
        StageKey::GpuReadBack {
            tracer: self.paths.tracer.id(),
        }
    }

    fn lens(
        &self,
        job: &LensJob<'_>,
        budget: &mut VertexBudget,
        stats: &mut HybridStats,
    ) -> Result<BuiltLens, TessellationError> {
        let request = texgen_request(job);
        let mut merged = MergedLens::default();
        let mut terms: Option<Vec<TermVertices>> = None;
        for &object in &job.objects {
            let mesh = &job.scene.scene().objects[object].mesh;
            let oracle = job.oracle(object);
            let start = Instant::now();
            // The whole tessellation runs on the device, every level's records kept there, and
            // texgen with it; `texgen_ms` is that pass's device time when it is timed.
            check_holds(self.paths, &oracle)?;
            let settings = oracle.gpu_settings()?;
            let options = budget.options_for(&job.tessellation, mesh);
            let extras = DeviceExtras {
                texgen: Some(request),
                hull: None,
                continue_budget: false,
            };
            let made = self.paths.tracer.tessellate(
                self.paths.gpu,
                object,
                mesh,
                &self::request(&settings, &options, extras),
            )?;
            add_gpu_time(&oracle, made.stage_ms, made.submission_ms, made.counters);
            let texgen_ms = made.stage_ms.map_or(0.0, |stages| stages.texgen);
            if let Some(stages) = made.stage_ms {
                *stats.gpu_split_ms.get_or_insert(0.0) += stages.tessellation;
            }
            append_terms(&mut terms, made.terms);
            count_tessellation(
                Counted {
                    mesh,
                    tessellation: &made.tessellation,
                    oracle: &oracle,
                    start,
                    texgen_ms,
                },
                budget,
                stats,
            );
            merged.add(job, object, made.tessellation);
        }
        let (mesh, depths) = merged.finish(job, stats);
        let start = Instant::now();
        let object = match terms {
            // Made on the GPU: assembled only.
            Some(terms) => texgen::lens_object(
                job.scene.trace().lenses[job.lens.index()].name.clone(),
                &job.scene.lenses()[job.lens.index()],
                mesh,
                terms,
                job.blend,
            ),
            None => empty_lens(job, mesh),
        };
        stats.texgen_ms += start.elapsed().as_secs_f64() * 1e3;
        Ok(BuiltLens { object, depths })
    }
}

impl VertexStage for GpuResident<'_> {
    fn key(&self) -> StageKey {
        StageKey::GpuResident {
            tracer: self.paths.tracer.id(),
        }
    }

    /// Makes the GPU tracer's buffers hold every lens object's scene objects at once: each
    /// object's work, recorded later by the frame, names those buffers, so they must not be
    /// made again between two objects.
    fn begin(&self, job: &FrameJob<'_>) -> Result<(), TessellationError> {
        let scene = job.scene;
        let mut objects = Vec::new();
        for (lens_index, lens) in scene.trace().lenses.iter().enumerate() {
            let layers = &scene.lenses()[lens_index];
            let classes = job.lenses.get(lens_index).map_or(&[][..], |l| &l.classes);
            let arrays = TexgenRequest {
                shells: &layers.shells,
                em_origins: &layers.em_origins,
                refraction: texgen::has_refraction(scene.trace(), lens_index),
                classes,
            }
            .arrays();
            for &object in &lens.objects {
                objects.push(PreparedObject {
                    object,
                    mesh: &scene.scene().objects[object].mesh,
                    arrays,
                    classes: classes.len(),
                });
            }
        }
        self.paths
            .tracer
            .prepare_frame(self.paths.gpu, &objects, &job.options.tessellation)
    }

    fn lens(
        &self,
        job: &LensJob<'_>,
        budget: &mut VertexBudget,
        stats: &mut HybridStats,
    ) -> Result<BuiltLens, TessellationError> {
        let request = texgen_request(job);
        let mut parts = Vec::new();
        for &object in &job.objects {
            let mesh = &job.scene.scene().objects[object].mesh;
            let oracle = job.oracle(object);
            let extras = DeviceExtras {
                texgen: Some(request),
                hull: job.hull_split.then(|| job.scene.hull_triangles(object)),
                continue_budget: budget.on_device,
            };
            check_holds(self.paths, &oracle)?;
            let settings = oracle.gpu_settings()?;
            let options = budget.options_for(&job.tessellation, mesh);
            let made = self.paths.tracer.tessellate_on_device(
                self.paths.gpu,
                object,
                mesh,
                &self::request(&settings, &options, extras),
            )?;
            add_gpu_time(
                &oracle,
                made.stage_ms,
                made.submission_ms,
                TraceCounters::default(),
            );
            // The device counts the frame's budget from here on.
            budget.on_device = true;
            if let Some(stages) = made.stage_ms {
                *stats.gpu_split_ms.get_or_insert(0.0) += stages.tessellation;
                stats.texgen_ms += stages.texgen;
            }
            stats.trace_ms += oracle.traced_ms();
            stats.triangles_in += mesh.triangles.len();
            parts.push((made.part, made.work));
        }
        // Its counts are the device's, read once the frame is done; the split's triangles too.
        let mesh = LensMesh {
            positions: Vec::new(),
            triangles: Vec::new(),
            faces: job.faces,
            hull_triangles: 0,
        };
        let start = Instant::now();
        let object = if parts.is_empty() {
            empty_lens(job, mesh)
        } else {
            LensObject {
                resident: Some(resident_lens(parts)),
                // Its terms with no per-vertex data: the device holds it.
                ..texgen::lens_object(
                    job.scene.trace().lenses[job.lens.index()].name.clone(),
                    &job.scene.lenses()[job.lens.index()],
                    mesh,
                    texgen::resident_terms(&request),
                    job.blend,
                )
            }
        };
        stats.texgen_ms += start.elapsed().as_secs_f64() * 1e3;
        Ok(BuiltLens {
            object,
            depths: Vec::new(),
        })
    }
}

/// Appends one scene object's terms (made on the GPU) to its lens object's, vertex after vertex.
fn append_terms(all: &mut Option<Vec<TermVertices>>, part: Option<Vec<TermVertices>>) {
    let Some(part) = part else { return };
    match all {
        None => *all = Some(part),
        Some(all) => {
            for (into, from) in all.iter_mut().zip(part) {
                into.fg.extend(from.fg);
                for (layer, directions) in into.directions.iter_mut().zip(from.directions) {
                    layer.extend(directions);
                }
            }
        }
    }
}

/// A scene object's tessellation left on the device, and the work that makes it (`None`: made
/// already).
type ResidentPart = (Arc<DeviceLensPart>, Option<Arc<ComputeWork>>);

/// A lens object drawn from its parts, each made by its work in the frame that draws it (or,
/// where one was made already, a timed tessellation, by their own submissions).
fn resident_lens(parts: Vec<ResidentPart>) -> ResidentLens {
    let works: Option<Vec<_>> = parts.iter().map(|(_, work)| work.clone()).collect();
    // All one way: the tracer times (and then submits) every tessellation of a frame or none.
    debug_assert!(works.is_some() || parts.iter().all(|(_, work)| work.is_none()));
    ResidentLens {
        parts: parts.into_iter().map(|(part, _)| part).collect(),
        works: works.unwrap_or_default(),
    }
}
