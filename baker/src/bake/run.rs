//! A bake run ([`bake`]): the plan (staged, or made), the samples already complete (staged, or
//! in the bake being resumed), every other requested sample baked and staged, and the commit
//! that makes the staging directory the bake directory.

use std::{
    collections::{BTreeMap, HashSet},
    path::Path,
    time::Instant,
};

use glam::Vec3;
use lensmap::{
    gpu::DeviceId,
    index::{LayerIndex, LensIndex},
    layers::{
        Manifest, MapReader, Provenance, Staging,
        bake::{
            BakeError, BakedOn, MANIFEST_FILE_NAME, ManifestLayer, ManifestLens,
            compress::uncompressed_name, default_created_by,
        },
    },
    runner::FrameRunner,
    scene::Scene,
};
use serde::Serialize;

use super::{
    failure::{BakeFailure, BakeInputError},
    options::BakeOptions,
    plan::{PLAN_FILE, Plan, make_plan, working_scene},
    sample::{SampleReport, StageSeconds, Step, bake_sample},
};

/// What one [`bake`] run does: which samples go where, with which options.
#[derive(Clone, Copy, Debug)]
pub struct BakeJob<'a> {
    /// The bake directory to write: replaced atomically when the bake is complete.
    pub dir: &'a Path,
    /// View-space indices of the samples to bake (see [`super::parse_samples`] and
    /// [`super::shard_samples`]); at least one.
    pub samples: &'a [usize],
    /// The bake options.
    pub options: &'a BakeOptions,
    /// Keep samples already complete (staged, or in the bake at `dir` made with the same scene
    /// and options) and bake only the rest; the bake then holds every complete sample, asked for
    /// or not. Without it, staged work is discarded.
    pub resume: bool,
}

/// The staged report file of sample `sample`.
pub fn report_file_name(sample: usize) -> String {
    format!("sample-{sample:03}.json")
}

/// What [`bake`] did.
#[derive(Clone, Debug, Serialize)]
pub struct BakeSummary {
    /// The plan.
    pub plan: Plan,
    /// Samples in the bake now (view-space indices).
    pub samples: Vec<usize>,
    /// Samples baked by this run.
    pub baked: Vec<usize>,
    /// Samples taken complete from staging or the previous bake.
    pub resumed: Vec<usize>,
    /// Reports of the samples baked by this run (and of resumed ones whose report was staged).
    pub reports: Vec<SampleReport>,
    /// Seconds making (or reading) the plan.
    pub plan_seconds: f64,
}

/// Progress of a bake, for progress bars.
pub enum Progress<'a> {
    /// The plan is being made.
    Plan(&'a str),
    /// Sample `done` of `of` (this run's) is at `step`.
    Sample {
        /// View-space index.
        sample: usize,
        /// Samples finished so far in this run.
        done: usize,
        /// Samples this run bakes.
        of: usize,
        /// The stage and its progress.
        step: Step<'a>,
    },
}

/// Bakes `job.samples` of `scene` into `job.dir` (module docs of [`super`]): plans, bakes each
/// sample not already complete (with `job.resume`), stages it, and commits the bake directory at
/// the end.
pub fn bake(
    runner: &mut FrameRunner,
    scene: &Scene,
    job: &BakeJob<'_>,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<BakeSummary, BakeFailure> {
    job.options.validate()?;
    let positions = scene.view_space.samples();
    if let Some(&bad) = job.samples.iter().find(|&&s| s >= positions.len()) {
        return Err(BakeInputError::MissingSample {
            sample: bad,
            scene: scene.name.clone(),
            count: positions.len(),
        }
        .into());
    }
    if job.samples.is_empty() {
        return Err(BakeInputError::NoSamples.into());
    }
    let staging = Staging::open(job.dir)?;
    let plan_start = Instant::now();
    let plan = staged_or_new_plan(runner, scene, &staging, job, progress)?;
    let plan_seconds = plan_start.elapsed().as_secs_f64();
    // Complete samples: staged ones, then (resuming) those of the previous bake at `dir`.
    let mut complete = staged_samples(&staging, &plan, positions.len())?;
    let mut resumed: Vec<usize> = complete.keys().copied().collect();
    // Who baked the samples taken from the bake at `dir`, as its provenance says.
    let mut resumed_on = BTreeMap::new();
    if job.resume {
        for (sample, device) in
            resume_from_bake(&staging, job.dir, &plan, &positions, &mut complete)?
        {
            resumed.push(sample);
            resumed_on.extend(device.map(|d| (sample, d)));
        }
    }
    resumed.sort_unstable();
    let todo: Vec<usize> = job
        .samples
        .iter()
        .copied()
        .filter(|s| !complete.contains_key(s))
        .collect();
    let mut reports: Vec<SampleReport> = complete.values().flatten().cloned().collect();
    if !todo.is_empty() {
        let mut hybrid = working_scene(scene, &plan)?;
        for (done, &sample) in todo.iter().enumerate() {
            let of = todo.len();
            let mut sample_progress = |step: Step<'_>| {
                progress(Progress::Sample {
                    sample,
                    done,
                    of,
                    step,
                })
            };
            let (maps, mut report) = bake_sample(
                runner,
                scene,
                &mut hybrid,
                &plan,
                sample,
                job.options,
                &mut sample_progress,
            )?;
            sample_progress(Step {
                stage: "writing",
                position: 0,
                of: 1,
            });
            stage_sample(&staging, &plan, &maps, &mut report)?;
            complete.insert(sample, Some(report.clone()));
            reports.push(report);
        }
    }
    reports.sort_by_key(|r| r.sample);
    let in_bake: Vec<usize> = complete.keys().copied().collect();
    let mut manifest = plan_manifest(&plan, &in_bake, &positions);
    if let Some(provenance) = manifest.provenance.as_mut() {
        provenance.baked_on = BakedOn::group(complete.iter().map(|(&sample, report)| {
            let device = report.as_ref().and_then(|r| r.baked_on.clone());
            (sample, device.or_else(|| resumed_on.get(&sample).cloned()))
        }));
    }
    staging.commit(&manifest)?;
    Ok(BakeSummary {
        plan,
        samples: in_bake,
        baked: todo,
        resumed,
        reports,
        plan_seconds,
    })
}

/// The staged plan when resuming one made for this scene and these options; else a new plan
/// (the staging directory cleared first), staged.
fn staged_or_new_plan(
    runner: &mut FrameRunner,
    scene: &Scene,
    staging: &Staging,
    job: &BakeJob<'_>,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<Plan, BakeFailure> {
    if job.resume && staging.contains(PLAN_FILE) {
        let path = staging.path().join(PLAN_FILE);
        let text = std::fs::read_to_string(&path).map_err(|source| BakeError::Io {
            path: path.clone(),
            action: "read",
            source,
        })?;
        let (scene_hash, options_hash) = (scene.content_hash(), job.options.hash());
        let staged = serde_json::from_str::<Plan>(&text).ok().filter(|p| {
            p.scene_hash == scene_hash && p.options_hash == options_hash && p.is_consistent()
        });
        if let Some(plan) = staged {
            return Ok(plan);
        }
    }
    staging.clear()?;
    let plan = make_plan(runner, scene, job.options, &mut |stage| {
        progress(Progress::Plan(stage))
    })?;
    let json = serde_json::to_string_pretty(&plan)
        .unwrap_or_else(|e| unreachable!("a plan always serializes: {e}"));
    staging.write_file(PLAN_FILE, json.as_bytes())?;
    Ok(plan)
}

/// The samples complete in `staging` for `plan` (a report of its options and every map file),
/// of a view space of `count` samples, with their reports.
fn staged_samples(
    staging: &Staging,
    plan: &Plan,
    count: usize,
) -> Result<BTreeMap<usize, Option<SampleReport>>, BakeFailure> {
    let mut complete = BTreeMap::new();
    for sample in 0..count {
        let name = report_file_name(sample);
        if !staging.contains(&name) {
            continue;
        }
        let path = staging.path().join(&name);
        let report: SampleReport = std::fs::read_to_string(&path)
            .ok()
            .and_then(|text| serde_json::from_str(&text).ok())
            .ok_or_else(|| BakeInputError::Staged {
                path: path.clone(),
                message: "not a sample report of this lensmap".into(),
            })?;
        if report.options_hash == plan.options_hash
            && plan
                .map_names(sample)
                .iter()
                .flatten()
                .all(|m| staging.contains(m))
        {
            complete.insert(sample, Some(report));
        }
    }
    Ok(complete)
}

/// Copies into `staging` every sample of the bake at `dir` that `complete` lacks, when that bake
/// was made with `plan`'s scene, options and EM size and lists the plan's files for the sample;
/// marks each complete (with a report that holds no figures). Returns the samples taken, each
/// with the device that baked it if that bake recorded one.
fn resume_from_bake(
    staging: &Staging,
    dir: &Path,
    plan: &Plan,
    positions: &[Vec3],
    complete: &mut BTreeMap<usize, Option<SampleReport>>,
) -> Result<Vec<(usize, Option<DeviceId>)>, BakeFailure> {
    let Ok(manifest) = Manifest::read(dir) else {
        return Ok(Vec::new());
    };
    if let Some(provenance) = manifest.provenance.as_ref().filter(|p| !p.is_current()) {
        return Err(BakeInputError::OtherIdentityVersion {
            manifest: dir.join(MANIFEST_FILE_NAME),
            version: provenance.identity_version,
        }
        .into());
    }
    let Some(provenance) = manifest.provenance.as_ref().filter(|p| {
        p.scene_hash == plan.scene_hash
            && p.options_hash == plan.options_hash
            && manifest.cube_map_size == plan.em_size
    }) else {
        return Ok(Vec::new());
    };
    let mut taken = Vec::new();
    let mut reader = MapReader::new(dir, &manifest);
    // The name a listed map is staged under: a compressed map is staged decoded, as an EXR.
    let staged_name = |listed: &String| match manifest.compression {
        Some(_) => uncompressed_name(listed),
        None => listed.clone(),
    };
    for (position, &sample) in provenance.samples.iter().enumerate() {
        if complete.contains_key(&sample) {
            continue;
        }
        let names = plan.map_names(sample);
        let listed = manifest.lenses.iter().zip(&names).all(|(lens, names)| {
            lens.layers.len() == names.len()
                && lens.layers.iter().zip(names).all(|(layer, name)| {
                    layer.maps.get(position).map(staged_name).as_ref() == Some(name)
                })
        });
        if !listed {
            continue;
        }
        let mut copied = HashSet::new();
        for (lens, names) in manifest.lenses.iter().zip(&names) {
            for (layer, name) in lens.layers.iter().zip(names) {
                // A shared layer's file once.
                if copied.insert(name) {
                    staging.copy_map(&mut reader, &layer.maps[position])?;
                }
            }
        }
        let marker = SampleReport {
            sample,
            position: positions[sample],
            options_hash: plan.options_hash.clone(),
            lenses: Vec::new(),
            psnr_db: None,
            projected_psnr_db: None,
            seconds: StageSeconds::default(),
            baked_on: BakedOn::device_of(&provenance.baked_on, sample).cloned(),
        };
        stage_report(staging, &marker)?;
        complete.insert(sample, None);
        taken.push((sample, marker.baked_on));
    }
    Ok(taken)
}

/// Stages a baked sample: its maps (a shared layer's once: every member holds the same
/// solution), then its report, which marks it complete; the writing time goes into the report.
fn stage_sample(
    staging: &Staging,
    plan: &Plan,
    maps: &[Vec<lensmap::cubemap::CubeMap>],
    report: &mut SampleReport,
) -> Result<(), BakeFailure> {
    let t = Instant::now();
    let mut written = HashSet::new();
    for (layers, names) in maps.iter().zip(plan.map_names(report.sample)) {
        for (cube, name) in layers.iter().zip(names) {
            if !written.contains(&name) {
                staging.write_cube_map(&name, cube, plan.em_size)?;
                written.insert(name);
            }
        }
    }
    report.seconds.write = t.elapsed().as_secs_f64();
    report.seconds.total += report.seconds.write;
    stage_report(staging, report)
}

/// Stages `report` as its sample's report file.
fn stage_report(staging: &Staging, report: &SampleReport) -> Result<(), BakeFailure> {
    let json = serde_json::to_string_pretty(report)
        .unwrap_or_else(|e| unreachable!("a report always serializes: {e}"));
    staging.write_file(&report_file_name(report.sample), json.as_bytes())?;
    Ok(())
}

/// The manifest of a bake of `samples` (view-space indices, increasing) under `plan`.
fn plan_manifest(plan: &Plan, samples: &[usize], positions: &[Vec3]) -> Manifest {
    Manifest {
        format_version: lensmap::layers::bake::FORMAT_VERSION,
        scene: plan.scene.clone(),
        created_by: default_created_by(),
        cube_map_size: plan.em_size,
        viewpoints: samples.iter().map(|&s| positions[s]).collect(),
        lenses: LensIndex::all(plan.lenses.len())
            .zip(&plan.lenses)
            .map(|(lens, planned)| ManifestLens {
                name: planned.name.clone(),
                em_origin: planned.em_origin,
                layering: planned.layering,
                layers: LayerIndex::all(planned.shells.len())
                    .zip(planned.shells.iter().zip(plan.layer_origins(lens)))
                    .map(|(layer, (shell, origin))| ManifestLayer {
                        shell: *shell,
                        em_origin: (origin != planned.em_origin).then_some(origin),
                        maps: samples
                            .iter()
                            .map(|&s| plan.map_name(lens.layer(layer), s))
                            .collect(),
                    })
                    .collect(),
            })
            .collect(),
        provenance: Some(Provenance {
            terms: plan.terms.clone(),
            ..Provenance::new(
                plan.scene_hash.clone(),
                plan.options_hash.clone(),
                samples.to_vec(),
            )
        }),
        compression: None,
    }
}
