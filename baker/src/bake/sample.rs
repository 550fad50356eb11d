//! One viewpoint sample's bake: records traced from its K views, every lens object's EMs
//! inferred against all of them at once (shared layers solved once), and, when asked, the
//! sample judged against a reference traced there.

use std::{sync::Arc, time::Instant};

use glam::Vec3;

use lensmap::{
    cubemap::CubeMap,
    hybrid::HybridScene,
    index::{LayerRef, LensIndex},
    layers::Layering,
    metrics::Mask,
    runner::FrameRunner,
    scene::{Camera, Scene},
    trace::{
        GreedyOptions, LensSelection, RecordSet, TraceOptions, compile_records, render_reference,
    },
};
use serde::{Deserialize, Serialize};

use super::{
    failure::BakeFailure,
    judge::masked_psnr,
    options::BakeOptions,
    plan::{Plan, PlannedLens},
    views::{sample_camera, view_cameras},
};
use crate::infer::{
    DeviceRenderer, EmSize, InferError, InferOptions, InferStep, Prepared, SolvedLens, View,
    prepare, solve_layers,
};

/// What one sample's bake took and reached (also the sample's completion mark on disk).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampleReport {
    /// View-space index.
    pub sample: usize,
    /// Position, metres.
    pub position: Vec3,
    /// The plan's options hash, so a report of another plan is never taken for this one.
    pub options_hash: String,
    /// Per lens object.
    pub lenses: Vec<LensReport>,
    /// Lens PSNR at the sample (sRGB) with the inferred EMs against a reference traced at the
    /// sample with the targets' supersampling; `None` when not judged.
    pub psnr_db: Option<f64>,
    /// The same with projected EMs on the same shells.
    pub projected_psnr_db: Option<f64>,
    /// Seconds per stage.
    pub seconds: StageSeconds,
    /// The device and driver that baked the sample (absent in reports of lensmap builds that
    /// did not record it, and for a sample taken from an earlier bake that did not).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baked_on: Option<lensmap::gpu::DeviceId>,
}

/// One lens object at one sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LensReport {
    /// Name.
    pub name: String,
    /// Shell kinds, nearest first.
    pub shells: Vec<String>,
    /// Per layer: non-zeros of all its matrices (all views and terms).
    pub nonzeros: Vec<usize>,
    /// Per layer: solver iterations.
    pub iterations: Vec<usize>,
    /// Per layer: relative residual.
    pub residual: Vec<f64>,
    /// Views that saw the lens object.
    pub views: usize,
}

impl LensReport {
    /// The report of a lens object no view lets the baker fit (its projected maps stand in).
    pub(super) fn unseen(planned: &PlannedLens) -> LensReport {
        let n = planned.shells.len();
        LensReport {
            name: planned.name.clone(),
            shells: planned.shells.iter().map(|s| s.kind().to_owned()).collect(),
            nonzeros: vec![0; n],
            iterations: vec![0; n],
            residual: vec![0.0; n],
            views: 0,
        }
    }
}

/// Seconds per stage of one sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StageSeconds {
    /// Tracing the views' intersection records.
    pub tracing: f64,
    /// Hybrid frames of the views (tessellation, texgen).
    pub frames: f64,
    /// Test renderings read back into rendering matrices.
    pub matrices: f64,
    /// Targets and confidence.
    pub targets: f64,
    /// The solves.
    pub solve: f64,
    /// The reference and the frames that judge the sample.
    pub judge: f64,
    /// Writing the maps.
    pub write: f64,
    /// Everything.
    pub total: f64,
}

/// A stage of one sample's bake and how far along it is: `position` of `of` steps done (views
/// traced, layers measured or solved).
#[derive(Clone, Copy, Debug)]
pub struct Step<'a> {
    /// The stage: `tracing`, `matrices "lens"`, `solve "lens"`, `judging`, `writing`.
    pub stage: &'a str,
    /// Steps done.
    pub position: usize,
    /// Steps in the stage.
    pub of: usize,
}

/// Bakes view-space sample `sample`: the maps of every lens object (`maps[lens][layer]`) and
/// the report. `hybrid` is [`super::working_scene`]; its maps are left as they were.
pub fn bake_sample(
    runner: &mut FrameRunner,
    scene: &Scene,
    hybrid: &mut HybridScene,
    plan: &Plan,
    sample: usize,
    options: &BakeOptions,
    progress: &mut dyn FnMut(Step<'_>),
) -> Result<(Vec<Vec<CubeMap>>, SampleReport), BakeFailure> {
    let start = Instant::now();
    let mut seconds = StageSeconds::default();
    let cameras = view_cameras(scene, sample, options);
    // Each layering's records, traced only where a lens object has it.
    let mut records = [Vec::new(), Vec::new()];
    for (slot, layering) in [Layering::Distance, Layering::Bounce]
        .into_iter()
        .enumerate()
    {
        if hybrid.lenses().iter().any(|l| l.layering == layering) {
            let views = Views {
                cameras: &cameras,
                layering,
                model: options.infer.model(),
            };
            records[slot] = trace_views(hybrid, &views, &mut seconds, progress)?;
        }
    }
    let infer = InferOptions {
        em_size: EmSize::Fixed(plan.em_size),
        ..options.infer
    };
    let view_lists = lens_views(plan, &cameras, &records);
    let prepared = prepare_lenses(hybrid, &view_lists, &infer)?;
    for p in prepared.iter().flatten() {
        seconds.frames += p.frame_ms() / 1e3;
    }
    let solved = solve_lenses(runner, hybrid, plan, prepared, &infer, progress)?;
    let (maps, lenses) = sample_maps(plan, hybrid, solved, &view_lists, &mut seconds);
    let (mut psnr_db, mut projected_psnr_db) = (None, None);
    if options.judge {
        progress(Step {
            stage: "judging",
            position: 0,
            of: 1,
        });
        let t = Instant::now();
        (psnr_db, projected_psnr_db) = judge_sample(runner, scene, hybrid, sample, &maps, options)?;
        seconds.judge = t.elapsed().as_secs_f64();
    }
    seconds.total = start.elapsed().as_secs_f64();
    Ok((
        maps,
        SampleReport {
            sample,
            position: scene.view_space.samples()[sample],
            options_hash: plan.options_hash.clone(),
            lenses,
            psnr_db,
            projected_psnr_db,
            seconds,
            baked_on: Some(runner.gpu().device_id().clone()),
        },
    ))
}

/// The views a record set is traced at: their cameras, the layering of the lens objects it is
/// for and the frames' ray-path model (the greedy terms or path classes; a record set for
/// lens objects layered by bounce is of greedy first bounces whatever it says).
struct Views<'a> {
    cameras: &'a [Camera],
    layering: Layering,
    model: lensmap::trace::PathModel,
}

/// The intersection records of every view of `views`, timed into `seconds.tracing`.
fn trace_views(
    hybrid: &HybridScene,
    views: &Views<'_>,
    seconds: &mut StageSeconds,
    progress: &mut dyn FnMut(Step<'_>),
) -> Result<Vec<RecordSet>, BakeFailure> {
    let mut records = Vec::with_capacity(views.cameras.len());
    for (j, camera) in views.cameras.iter().enumerate() {
        progress(Step {
            stage: "tracing",
            position: j,
            of: views.cameras.len(),
        });
        let t = Instant::now();
        let options = TraceOptions {
            greedy: GreedyOptions {
                bounces: views.layering.bounces(),
                ..GreedyOptions::default()
            },
            model: views.model,
            ..TraceOptions::default()
        };
        records.push(compile_records(hybrid.trace(), camera, &options)?);
        seconds.tracing += t.elapsed().as_secs_f64();
    }
    Ok(records)
}

/// Per lens object of `plan`, the views that see it (any visible record), with the records of
/// its layering (`records[0]` by distance, `records[1]` by bounce).
fn lens_views<'v>(
    plan: &Plan,
    cameras: &'v [Camera],
    records: &'v [Vec<RecordSet>; 2],
) -> Vec<Vec<View<'v>>> {
    (0..plan.lenses.len())
        .map(|lens| {
            let slot = usize::from(plan.lenses[lens].layering == Layering::Bounce);
            cameras
                .iter()
                .zip(&records[slot])
                .filter(|(_, set)| set.lenses[lens].records.iter().any(|r| r.visible))
                .map(|(camera, set)| View {
                    camera,
                    records: &set.lenses[lens],
                })
                .collect()
        })
        .collect()
}

/// Every lens object's frames and targets at the views that see it; `None` where none does or
/// nothing covers a pixel centre (a sliver at the frame's edge): nothing to fit.
fn prepare_lenses<'v>(
    hybrid: &HybridScene,
    view_lists: &[Vec<View<'v>>],
    infer: &InferOptions,
) -> Result<Vec<Option<Prepared<'v>>>, BakeFailure> {
    let mut prepared = Vec::with_capacity(view_lists.len());
    for (lens, views) in LensIndex::all(view_lists.len()).zip(view_lists) {
        prepared.push(if views.is_empty() {
            None
        } else {
            match prepare(hybrid, lens, views, infer) {
                Ok(p) => Some(p),
                Err(InferError::NoLensPixels { .. }) => None,
                Err(error) => return Err(error.into()),
            }
        });
    }
    Ok(prepared)
}

/// Solves the layers of every prepared lens object ([`solve_layers`], the plan's shared layers
/// once), telling `progress` of each lens object's matrices and solves.
fn solve_lenses(
    runner: &mut FrameRunner,
    hybrid: &HybridScene,
    plan: &Plan,
    prepared: Vec<Option<Prepared<'_>>>,
    infer: &InferOptions,
    progress: &mut dyn FnMut(Step<'_>),
) -> Result<Vec<Option<SolvedLens>>, BakeFailure> {
    let stages: Vec<(String, String)> = plan
        .lenses
        .iter()
        .map(|l| {
            (
                format!("matrices \"{}\"", l.name),
                format!("solve \"{}\"", l.name),
            )
        })
        .collect();
    let mut renderer = DeviceRenderer::new(runner, infer.compositing);
    Ok(solve_layers(
        &mut renderer,
        hybrid,
        prepared,
        &plan.shared_groups(),
        plan.em_size,
        infer,
        &mut |lens, step| {
            let (matrices, solving) = &stages[lens.index()];
            progress(match step {
                InferStep::Matrices { layer, layers } => Step {
                    stage: matrices,
                    position: layer.index(),
                    of: layers,
                },
                InferStep::Solve { layer, layers } => Step {
                    stage: solving,
                    position: layer.index(),
                    of: layers,
                },
            })
        },
    )?)
}

/// The sample's maps (`maps[lens][layer]`) and per lens object reports from what was solved:
/// a lens object unseen from this sample, or with a layer no pixel reads, keeps its projected
/// maps (nothing of it to fit, as a one-lens inference says); a shared layer's inferred map is
/// every member's, also a member this sample does not see. Adds the stages' times to `seconds`.
fn sample_maps(
    plan: &Plan,
    hybrid: &HybridScene,
    solved: Vec<Option<SolvedLens>>,
    view_lists: &[Vec<View<'_>>],
    seconds: &mut StageSeconds,
) -> (Vec<Vec<CubeMap>>, Vec<LensReport>) {
    let mut maps: Vec<Vec<CubeMap>> = Vec::new();
    // Which lens objects' maps were inferred (the rest are projected, every layer).
    let mut inferred: Vec<bool> = Vec::new();
    let mut lenses = Vec::new();
    for (lens, (planned, solved)) in plan.lenses.iter().zip(solved).enumerate() {
        let projected = |layer: usize| CubeMap::clone(&hybrid.lenses()[lens].maps[0][layer]);
        let Some(solved) = solved.filter(|s| s.maps.iter().all(Option::is_some)) else {
            maps.push((0..planned.shells.len()).map(projected).collect());
            inferred.push(false);
            lenses.push(LensReport::unseen(planned));
            continue;
        };
        inferred.push(true);
        for layer in &solved.layers {
            seconds.matrices += layer.matrix_ms / 1e3;
            seconds.targets += layer.targets_ms / 1e3;
            seconds.solve += layer.solve.ms / 1e3;
        }
        lenses.push(LensReport {
            name: planned.name.clone(),
            shells: planned.shells.iter().map(|s| s.kind().to_owned()).collect(),
            nonzeros: solved
                .layers
                .iter()
                .map(|l| l.nonzeros.iter().sum())
                .collect(),
            iterations: solved.layers.iter().map(|l| l.solve.iterations).collect(),
            residual: solved
                .layers
                .iter()
                .map(|l| l.solve.relative_residual)
                .collect(),
            views: view_lists[lens].len(),
        });
        maps.push(solved.maps.into_iter().flatten().collect());
    }
    for shared in &plan.shared {
        let inferred_member = shared.members.iter().find(|m| inferred[m.lens.index()]);
        if let Some(&LayerRef { lens, layer }) = inferred_member {
            let map = maps[lens.index()][layer.index()].clone();
            for &LayerRef { lens, layer } in &shared.members {
                maps[lens.index()][layer.index()] = map.clone();
            }
        }
    }
    (maps, lenses)
}

/// Lens PSNR at sample `sample` (sRGB) with the inferred `maps` and with `hybrid`'s projected
/// ones, against a reference traced there; `None` for both when the sample sees no lens pixel.
/// `hybrid`'s maps are left as they were.
fn judge_sample(
    runner: &mut FrameRunner,
    scene: &Scene,
    hybrid: &mut HybridScene,
    sample: usize,
    maps: &[Vec<CubeMap>],
    options: &BakeOptions,
) -> Result<(Option<f64>, Option<f64>), BakeFailure> {
    let camera = sample_camera(scene, scene.view_space.samples()[sample], options);
    let reference = render_reference(
        hybrid.trace(),
        &camera,
        &TraceOptions {
            model: options.infer.model(),
            ..TraceOptions::default()
        },
        &|_| {},
    )?;
    let mask = Mask::lens(&reference.lens_pixels, LensSelection::All);
    if mask.selected() == 0 {
        return Ok((None, None));
    }
    let projected_psnr = masked_psnr(runner, hybrid, &camera, &reference.radiance, &mask, options)?;
    let projected: Vec<_> = hybrid.lenses().iter().map(|l| l.maps.clone()).collect();
    for (lens, inferred) in LensIndex::all(projected.len()).zip(maps) {
        hybrid.set_lens_maps(lens, vec![inferred.iter().cloned().map(Arc::new).collect()]);
    }
    let judged = masked_psnr(runner, hybrid, &camera, &reference.radiance, &mask, options);
    for (lens, maps) in LensIndex::all(projected.len()).zip(projected) {
        hybrid.set_lens_maps(lens, maps);
    }
    Ok((Some(judged?), Some(projected_psnr)))
}
