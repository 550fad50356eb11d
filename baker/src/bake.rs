//! The offline stage over a whole view space (hybrid-rendering paper §4): a *plan* fixed for the
//! scene and the options (layer placement, shells, EM size), then every requested viewpoint
//! sample as one unit of work (records traced from K views around the sample, one EM per lens
//! object and layer inferred against all K views at once), staged sample by sample and committed
//! as one bake directory (`lensmap::layers::bake`).
//!
//! **Plan.** Each lens object's EM origin is its centroid. Its layers come from LBG clustering of
//! intersection distances over [`PLACEMENT_SAMPLES`] viewpoints spread over the whole view space,
//! shells fitted per layer ([`crate::placement`]); `--layers scene` takes the scene file's named
//! shells as they are instead. Fitted shells measured better on teapot-room than the scene's
//! (README: 25.1 against 21.5 dB halfway between samples), so `auto` only takes the scene's layer
//! *count* where it names layers. With `auto` and no named layers, the layer count grows from 1 while one
//! more layer raises the lens object's PSNR (projected EMs on the placed shells, at view-space
//! sample 0, against the reference) by more than [`AUTO_LAYER_GAIN_DB`], up to
//! [`MAX_AUTO_LAYERS`]; a lens object whose environment is distant gets one layer that way (and
//! one that sample 0 does not see gets one, for want of pixels to judge by). The
//! EM size is searched (finest level read) at view-space sample 0. The plan depends only on the
//! scene and the options, never on which samples a process bakes, so shards agree on it.
//!
//! **Shared distant layers** (paper §4.3: "to conserve texture memory … share more distant EM
//! layers between local lens objects … add more equations … simultaneously solving for a single
//! EM"; `--share-layers`, [`BakeOptions::share_layers`]). Clustered lens objects whose farthest
//! layers hold the same scene objects (one set within the other) get one far shell, fitted to all
//! their hits about the first one's EM origin, when it fits each within [`SHARED_FIT_SLACK`] of
//! its own shell ([`SharedLayer`]). Each sample solves that layer once, on every member's
//! equations, and the bake stores it once: the member's layer lists the owner's files and origin.
//!
//! **Multi-view.** Sample i's EMs are solved against K views spread uniformly over its share of
//! the view space: rotations of the sample about the vertical through the look-at point by
//! `s·((j + ½)/K − ½)`, j = 0…K−1, s the angle to the nearest other sample (so K = 1 is the
//! sample alone, and odd K include it). With `--view-elevation-degrees E` > 0, one more view:
//! the sample rotated up by E about the horizontal axis through the look-at point perpendicular to
//! the direction to it, for cameras that leave the view space's circle (the view space then
//! reaches E above it).
//!
//! **Staging, resume, shards.** Work goes into `Staging` (`.NAME.baking` beside the bake): the
//! plan (`plan.json`), then per sample its cube maps and last its report `sample-NNN.json`,
//! which marks it complete. A killed bake loses at most the sample in flight; the bake at NAME is
//! replaced only by the final commit. `resume` keeps a staging directory whose plan matches and
//! takes complete samples from it and from a bake at NAME made with the same scene and options.
//! Everything is deterministic (fixed reductions, ordered sums, a deterministic device), so a
//! resumed bake, a merged set of shards and a single-process bake give the same bytes.

use std::{
    collections::{BTreeMap, BTreeSet},
    path::{Path, PathBuf},
    sync::Arc,
    time::Instant,
};

use glam::{DQuat, DVec3, Vec3};
use lensmap::{
    cubemap::CubeMap,
    hybrid::{HybridError, HybridScene, LensLayers, viewpoints::angle},
    layers::{
        LayerShell, Manifest, Provenance, Staging,
        bake::{
            BakeError, ManifestLayer, ManifestLens, debug_hash, default_created_by, map_file_name,
        },
        projected::{ProjectedOptions, em_origin, lens_shells, project_layers},
    },
    metrics::{self, Channels, Encoding, Mask},
    render::TargetFormat,
    runner::{FrameOptions, FrameRunner, RunError},
    scene::{Camera, Scene},
    trace::{
        LensRecords, TraceError, TraceOptions, compile_records, render_reference, world::TraceScene,
    },
};
use serde::{Deserialize, Serialize};

use crate::{
    infer::{
        DEFAULT_MAX_EM_SIZE, DeviceRenderer, EmSize, InferError, InferOptions, InferStep, View,
        prepare, solve_layers,
    },
    matrix::LayerFrames,
    placement::{PlacementError, lens_hits, place_layers},
};

/// Viewpoints (spread evenly over the view space) whose records place the layers.
pub const PLACEMENT_SAMPLES: usize = 8;

/// Placement records are traced at this fraction of the bake's resolution, 1 sample per pixel.
pub const PLACEMENT_SCALE: u32 = 4;

/// `--layers auto` stops adding layers when one more raises the lens PSNR by no more than this.
pub const AUTO_LAYER_GAIN_DB: f64 = 0.5;

/// `--layers auto` places at most this many layers.
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

/// Face size of the projected EMs the plan judges layer counts with (and, capped by the EM size
/// cap, searches the EM size on).
const JUDGE_EM_SIZE: u32 = 64;

/// The staged plan's file name.
pub const PLAN_FILE: &str = "plan.json";

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

    /// Checks the options; the message names the option and the fix.
    pub fn validate(&self) -> Result<(), BakeFailure> {
        let bad = |text: String| Err(BakeFailure::BadInput(text));
        if self.width == 0 || self.height == 0 || self.supersampling == 0 {
            return bad(format!(
                "--width {} --height {} --supersampling {}: give values ≥ 1",
                self.width, self.height, self.supersampling
            ));
        }
        let size = match self.em_size {
            EmSize::Auto { cap } => cap,
            EmSize::Fixed(size) => size,
        };
        if !size.is_power_of_two() || size > lensmap::layers::projected::MAX_EM_SIZE {
            return bad(format!(
                "--em-size {size}: give auto or a power of two from 1 to {}, e.g. 128",
                lensmap::layers::projected::MAX_EM_SIZE
            ));
        }
        if let LayerCount::Count(n) = self.layers
            && !(1..=8).contains(&n)
        {
            return bad(format!("--layers {n}: give auto or a count from 1 to 8"));
        }
        let tolerance = self.infer.solve.tolerance;
        if !(tolerance.is_finite() && tolerance > 0.0 && tolerance < 1.0) {
            return bad(format!(
                "--tolerance {tolerance}: give a relative residual in (0, 1), e.g. 1e-4"
            ));
        }
        let theta = self.infer.theta_c.to_degrees();
        if !(theta.is_finite() && theta > 0.0 && theta < 180.0) {
            return bad(format!(
                "--confidence-degrees {theta}: give an angle in (0, 180), e.g. 30"
            ));
        }
        let elevation = self.view_elevation_degrees;
        if !(elevation.is_finite() && (0.0..90.0).contains(&elevation)) {
            return bad(format!(
                "--view-elevation-degrees {elevation}: give an angle in [0, 90), e.g. 15 (0: no raised view)"
            ));
        }
        if !(1..=9).contains(&self.multi_view) {
            return bad(format!(
                "--multi-view {}: give a view count from 1 to 9 (1 turns multi-view off)",
                self.multi_view
            ));
        }
        self.infer
            .hybrid
            .validate()
            .map_err(|e| BakeFailure::BadInput(e.to_string()))
    }
}

/// Why a bake failed.
#[derive(Debug, thiserror::Error)]
pub enum BakeFailure {
    /// The user's input (options, sample lists, shards to merge): exit code 2.
    #[error("{0}")]
    BadInput(String),
    /// Reading or writing the bake directory.
    #[error(transparent)]
    Bake(#[from] BakeError),
    /// Inference.
    #[error(transparent)]
    Infer(#[from] InferError),
    /// Layer placement.
    #[error(transparent)]
    Placement(#[from] PlacementError),
    /// The ray tracer.
    #[error(transparent)]
    Trace(#[from] TraceError),
    /// Building the hybrid scene.
    #[error(transparent)]
    Hybrid(#[from] HybridError),
    /// A hybrid frame.
    #[error(transparent)]
    Run(#[from] RunError),
    /// A metric.
    #[error(transparent)]
    Metrics(#[from] metrics::MetricsError),
    /// A staged file is not what this code wrote.
    #[error("{}: {message}; delete it (or bake without --resume)", path.display())]
    Staged {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// What is fixed for a scene and options before any sample is baked.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// Scene name.
    pub scene: String,
    /// [`Scene::content_hash`].
    pub scene_hash: String,
    /// [`BakeOptions::hash`].
    pub options_hash: String,
    /// The EM face size of every map.
    pub em_size: u32,
    /// Per lens object (TraceScene order).
    pub lenses: Vec<PlannedLens>,
    /// Distant layers shared between lens objects (one map each).
    #[serde(default)]
    pub shared: Vec<SharedLayer>,
}

/// One layer shared by several lens objects: one shell, one EM origin, one map per sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SharedLayer {
    /// `(lens, layer)` of every lens object holding it; the first owns the map (its file name
    /// and its EM origin, the first lens object's centroid).
    pub members: Vec<(usize, usize)>,
    /// The scene objects in it (those of every member's layer), sorted.
    pub objects: Vec<String>,
    /// Per member, the fit measure (RMS relative depth error) of the shared shell over the
    /// member's hits, seen from the shared EM origin.
    pub fit_rms: Vec<f64>,
    /// Per member, the fit measure of the shell it would have had alone.
    pub separate_fit_rms: Vec<f64>,
}

impl Plan {
    /// The (lens, layer) whose map lens object `lens`'s layer `layer` uses: its own, or a
    /// shared layer's owner.
    pub fn map_owner(&self, lens: usize, layer: usize) -> (usize, usize) {
        self.shared
            .iter()
            .find(|s| s.members.contains(&(lens, layer)))
            .map_or((lens, layer), |s| s.members[0])
    }

    /// The EM origin of every layer of lens object `lens`: the owner's centroid.
    pub fn layer_origins(&self, lens: usize) -> Vec<DVec3> {
        (0..self.lenses[lens].shells.len())
            .map(|layer| self.lenses[self.map_owner(lens, layer).0].em_origin)
            .collect()
    }

    /// The file of lens object `lens`'s layer `layer` at view-space sample `sample` (a shared
    /// layer's is its owner's).
    pub fn map_name(&self, lens: usize, layer: usize, sample: usize) -> String {
        let (owner, owner_layer) = self.map_owner(lens, layer);
        map_file_name(owner, &self.lenses[owner].name, sample, owner_layer)
    }

    /// Whether the plan holds together: every lens object has one fit and one object list per
    /// shell (where clustered), and every shared layer names two or more distinct lens objects'
    /// existing layers, all with one shell. A staged plan that does not (edited by hand) is not
    /// resumed.
    pub fn is_consistent(&self) -> bool {
        let lenses_ok = self.lenses.iter().all(|l| {
            !l.shells.is_empty()
                && (l.objects.is_empty() || l.objects.len() == l.shells.len())
                && (l.fit_rms.is_empty() || l.fit_rms.len() == l.shells.len())
        });
        let shared_ok = self.shared.iter().all(|s| {
            let shell = |&(lens, layer): &(usize, usize)| {
                self.lenses.get(lens).and_then(|l| l.shells.get(layer))
            };
            let distinct: BTreeSet<usize> = s.members.iter().map(|m| m.0).collect();
            s.members.len() >= 2
                && distinct.len() == s.members.len()
                && shell(&s.members[0]).is_some()
                && s.members.iter().all(|m| shell(m) == shell(&s.members[0]))
        });
        let mut owned = BTreeSet::new();
        let disjoint = self
            .shared
            .iter()
            .flat_map(|s| &s.members)
            .all(|m| owned.insert(*m));
        lenses_ok && shared_ok && disjoint
    }

    /// The shared layers as groups of (lens, layer), for [`crate::infer::solve_layers`].
    pub fn shared_groups(&self) -> Vec<Vec<(usize, usize)>> {
        self.shared.iter().map(|s| s.members.clone()).collect()
    }
}

/// One lens object's plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedLens {
    /// Name.
    pub name: String,
    /// EM origin (centroid), metres.
    pub em_origin: DVec3,
    /// Shells, nearest first.
    pub shells: Vec<LayerShell>,
    /// Where they came from: `scene` (named by the scene file) or `clustered`.
    pub source: String,
    /// Per layer, the scene objects in it (clustered layers only).
    pub objects: Vec<Vec<String>>,
    /// Per layer, the fit measure (RMS relative depth error) of the chosen shell (clustered
    /// layers only).
    pub fit_rms: Vec<f64>,
    /// `--layers auto` without named layers: lens PSNR (dB) with 1, 2, … layers as tried.
    pub auto_psnr_db: Vec<f64>,
}

impl PlannedLens {
    /// Takes the shells, objects and fits of a placement; returns the farthest layer's hits
    /// (world space), what a shared shell is fitted to.
    fn adopt(&mut self, placement: &crate::placement::Placement) -> Vec<DVec3> {
        self.shells = placement.layers.iter().map(|l| l.shell).collect();
        self.objects = placement.layers.iter().map(|l| l.objects.clone()).collect();
        self.fit_rms = placement
            .layers
            .iter()
            .map(|l| l.rms_relative_error)
            .collect();
        placement
            .layers
            .last()
            .map(|l| l.points.clone())
            .unwrap_or_default()
    }
}

/// A shared shell may fit a member's hits worse than the member's own shell by at most this
/// much RMS relative depth error.
pub const SHARED_FIT_SLACK: f64 = 0.02;

/// Shares the farthest layer between clustered lens objects that see the same distant scene
/// objects there (the hybrid-rendering paper's shared distant layers): lens objects of two or
/// more layers whose farthest layer's objects are a subset or a superset of the first such lens
/// object's (the lid of a teapot sees two of the walls its body sees) form a group with it; one
/// shell is fitted to every member's hits
/// `far_hits[lens]` about the first member's EM origin, and taken when it fits each member
/// within [`SHARED_FIT_SLACK`] of the member's own shell. Rewrites the members' shells and fits.
fn share_far_layers(lenses: &mut [PlannedLens], far_hits: &[Vec<DVec3>]) -> Vec<SharedLayer> {
    // (members, the first member's far objects, the union of their far objects)
    let mut groups: Vec<(Vec<usize>, BTreeSet<String>, BTreeSet<String>)> = Vec::new();
    for (lens, planned) in lenses.iter().enumerate() {
        // A lens object with one layer has no distant layer of its own to share: its only
        // layer holds what is near it too.
        if planned.objects.len() < 2 || planned.shells.len() != planned.objects.len() {
            continue;
        }
        let Some(objects) = planned.objects.last() else {
            continue;
        };
        if objects.is_empty() || far_hits[lens].is_empty() {
            continue;
        }
        let objects: BTreeSet<String> = objects.iter().cloned().collect();
        match groups
            .iter_mut()
            .find(|(_, owner, _)| objects.is_subset(owner) || owner.is_subset(&objects))
        {
            Some((members, _, union)) => {
                members.push(lens);
                union.extend(objects);
            }
            None => groups.push((vec![lens], objects.clone(), objects)),
        }
    }
    let mut shared = Vec::new();
    for (group, _, objects) in groups.into_iter().filter(|(g, _, _)| g.len() >= 2) {
        let origin = lenses[group[0]].em_origin;
        let relative =
            |lens: usize| -> Vec<DVec3> { far_hits[lens].iter().map(|p| *p - origin).collect() };
        let points: Vec<DVec3> = group.iter().flat_map(|&lens| relative(lens)).collect();
        let (shell, _, _) = crate::placement::fit_shell(origin, &points);
        let fit_rms: Vec<f64> = group
            .iter()
            .map(|&lens| crate::placement::fit_error(&shell, origin, &relative(lens)))
            .collect();
        let separate_fit_rms: Vec<f64> = group
            .iter()
            .map(|&lens| lenses[lens].fit_rms.last().copied().unwrap_or(0.0))
            .collect();
        if fit_rms
            .iter()
            .zip(&separate_fit_rms)
            .any(|(shared, own)| *shared > own + SHARED_FIT_SLACK)
        {
            continue;
        }
        let members: Vec<(usize, usize)> = group
            .iter()
            .map(|&lens| (lens, lenses[lens].shells.len() - 1))
            .collect();
        for (&(lens, layer), &rms) in members.iter().zip(&fit_rms) {
            lenses[lens].shells[layer] = shell;
            lenses[lens].fit_rms[layer] = rms;
        }
        shared.push(SharedLayer {
            objects: objects.into_iter().collect(),
            members,
            fit_rms,
            separate_fit_rms,
        });
    }
    shared
}

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
    fn unseen(planned: &PlannedLens) -> LensReport {
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

/// The view-space indices `spec` names for a view space of `count` samples: `all`, `I,J,K` or
/// `A..B` (B excluded) or `A..=B`; sorted, without repeats.
pub fn parse_samples(spec: &str, count: usize, scene: &str) -> Result<Vec<usize>, BakeFailure> {
    let fix = |problem: String| {
        BakeFailure::BadInput(format!(
            "--samples {spec}: {problem}; scene \"{scene}\" has samples 0..{count} (give all, I,J,K, A..B or A..=B)"
        ))
    };
    let index = |text: &str| -> Result<usize, BakeFailure> {
        let i: usize = text
            .trim()
            .parse()
            .map_err(|_| fix(format!("'{}' is not a sample index", text.trim())))?;
        if i >= count {
            return Err(fix(format!("sample {i} does not exist")));
        }
        Ok(i)
    };
    let mut samples: Vec<usize> = if spec.trim() == "all" {
        (0..count).collect()
    } else if let Some((a, b)) = spec.split_once("..") {
        let (inclusive, b) = match b.strip_prefix('=') {
            Some(b) => (true, b),
            None => (false, b),
        };
        let start = index(a)?;
        let end: usize = b
            .trim()
            .parse()
            .map_err(|_| fix(format!("'{}' is not a sample index", b.trim())))?;
        let end = if inclusive {
            end.checked_add(1)
                .ok_or_else(|| fix(format!("sample {end} does not exist")))?
        } else {
            end
        };
        if end > count {
            return Err(fix(format!("sample {} does not exist", end - 1)));
        }
        if end <= start {
            return Err(fix("the range is empty".into()));
        }
        (start..end).collect()
    } else {
        spec.split(',').map(index).collect::<Result<_, _>>()?
    };
    samples.sort_unstable();
    samples.dedup();
    Ok(samples)
}

/// `I/N`: shard I (1-based) of N.
pub fn parse_shard(spec: &str) -> Result<(usize, usize), BakeFailure> {
    let bad = || {
        BakeFailure::BadInput(format!(
            "--shard {spec}: give I/N with 1 ≤ I ≤ N, e.g. 1/4 for the first of four shards"
        ))
    };
    let (i, n) = spec.split_once('/').ok_or_else(bad)?;
    let (i, n): (usize, usize) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || i == 0 || i > n {
        return Err(bad());
    }
    Ok((i, n))
}

/// The samples shard `i` of `n` bakes: every n-th of `samples`, starting at the i-th.
pub fn shard_samples(samples: &[usize], (i, n): (usize, usize)) -> Vec<usize> {
    samples
        .iter()
        .enumerate()
        .filter(|(position, _)| position % n == i - 1)
        .map(|(_, &s)| s)
        .collect()
}

/// The camera at view-space sample position `position`: the scene camera moved there, at the
/// bake's resolution.
fn sample_camera(scene: &Scene, position: Vec3, options: &BakeOptions) -> Camera {
    scene.camera.with_position(position).with_resolution(
        options.width,
        options.height,
        options.supersampling,
    )
}

/// The K views of sample `sample` (module docs).
pub fn view_cameras(scene: &Scene, sample: usize, options: &BakeOptions) -> Vec<Camera> {
    let positions = scene.view_space.samples();
    let look_at = scene.camera.look_at.as_dvec3();
    let own = positions[sample].as_dvec3() - look_at;
    let spacing = positions
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != sample)
        .map(|(_, p)| angle(own, p.as_dvec3() - look_at))
        .filter(|a| *a > 1e-9)
        .fold(f64::INFINITY, f64::min);
    let spacing = if spacing.is_finite() {
        spacing
    } else {
        SINGLE_SAMPLE_SPREAD_DEGREES.to_radians()
    };
    let k = options.multi_view.max(1);
    let mut cameras: Vec<Camera> = (0..k)
        .map(|j| {
            let offset = spacing * ((j as f64 + 0.5) / k as f64 - 0.5);
            let position = look_at + DQuat::from_rotation_y(offset) * own;
            sample_camera(scene, position.as_vec3(), options)
        })
        .collect();
    let elevation = options.view_elevation_degrees.to_radians();
    if elevation > 0.0 {
        // Up about the horizontal axis perpendicular to the direction to the look-at point (a
        // sample straight above or below it has none: then no raised view).
        let axis = own.cross(DVec3::Y);
        if axis.length() > 1e-9 * own.length() {
            let axis = axis.normalize();
            let raised = [-elevation, elevation]
                .map(|angle| look_at + DQuat::from_axis_angle(axis, angle) * own)
                .into_iter()
                .find(|p| p.y > look_at.y + own.y);
            if let Some(position) = raised {
                cameras.push(sample_camera(scene, position.as_vec3(), options));
            }
        }
    }
    cameras
}

/// The reference's pixels that are all lens object `lens` (every supersample's first hit), from
/// its records at that camera.
fn lens_pixels(records: &LensRecords, camera: &Camera) -> Mask {
    let k = camera.supersampling.max(1);
    let mut counts = vec![0u32; (camera.width * camera.height) as usize];
    for record in records.records.iter().filter(|r| r.visible) {
        let (x, y) = (
            record.image_position.x.floor() as usize,
            record.image_position.y.floor() as usize,
        );
        if let Some(count) = counts.get_mut(y * camera.width as usize + x) {
            *count += 1;
        }
    }
    // Records come one per term: a pixel of a glass lens has 2k² of them.
    let terms = records
        .records
        .iter()
        .map(|r| r.term)
        .collect::<std::collections::BTreeSet<_>>()
        .len()
        .max(1) as u32;
    Mask::from_flags(counts.iter().map(|&c| c == terms * k * k).collect())
}

/// Lens PSNR (sRGB) of `hybrid` at `camera` over `mask` against the reference radiance.
fn masked_psnr(
    runner: &mut FrameRunner,
    hybrid: &HybridScene,
    camera: &Camera,
    reference: &[Vec3],
    mask: &Mask,
    options: &BakeOptions,
) -> Result<f64, BakeFailure> {
    let frame = runner.frame(
        hybrid,
        camera,
        &FrameOptions {
            hybrid: options.infer.hybrid,
            variant: options.infer.variant,
            blend: lensmap::render::BlendScheme::FrontToBack,
            format: TargetFormat::Rgba32f,
        },
    )?;
    Ok(metrics::compare(
        &frame.image.pixels,
        reference,
        mask,
        Encoding::DisplaySrgb,
        Channels::Rgb,
    )?
    .psnr_db)
}

/// Projected EMs of every lens object on `shells` (per lens: origin and shells), at `size`.
fn projected_scene(
    scene: &Scene,
    shells: Vec<(DVec3, Vec<LayerShell>)>,
    size: u32,
) -> Result<HybridScene, BakeFailure> {
    let options = lensmap::hybrid::HybridSceneOptions {
        ems: lensmap::hybrid::LayeredEms::ProjectedOn {
            shells,
            options: ProjectedOptions::with_size(size),
        },
        ..Default::default()
    };
    Ok(HybridScene::new(scene.clone(), options)?.0)
}

/// Replaces lens object `lens`'s layered EMs in `hybrid` by projected ones on `shells` (EM
/// origin `origin`) at face size `size`.
fn project_into(
    hybrid: &mut HybridScene,
    lens: usize,
    origin: DVec3,
    shells: Vec<LayerShell>,
    size: u32,
) {
    let (maps, _) = project_layers(
        &hybrid.trace,
        lens,
        origin,
        &shells,
        &ProjectedOptions::with_size(size),
    );
    hybrid.lenses[lens] = LensLayers {
        em_origins: vec![origin; shells.len()],
        shells,
        maps: vec![maps.into_iter().map(Arc::new).collect()],
    };
}

/// The viewpoints whose records place the layers: [`PLACEMENT_SAMPLES`] spread evenly over the
/// view space, at 1/[`PLACEMENT_SCALE`] of the bake's resolution, one sample per pixel.
pub fn placement_cameras(scene: &Scene, options: &BakeOptions) -> Vec<Camera> {
    let positions = scene.view_space.samples();
    let count = positions.len().min(PLACEMENT_SAMPLES);
    (0..count)
        .map(|i| positions[i * positions.len() / count])
        .map(|p| {
            scene.camera.with_position(p).with_resolution(
                (options.width / PLACEMENT_SCALE).max(1),
                (options.height / PLACEMENT_SCALE).max(1),
                1,
            )
        })
        .collect()
}

/// Makes the plan for `scene` and `options` (module docs). `progress` hears each step.
pub fn make_plan(
    runner: &mut FrameRunner,
    scene: &Scene,
    options: &BakeOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<Plan, BakeFailure> {
    options.validate()?;
    let trace = TraceScene::new(scene)?;
    let trace_options = TraceOptions::default();
    let positions = scene.view_space.samples();
    let lens_count = trace.lenses.len();
    if lens_count == 0 {
        return Err(BakeFailure::BadInput(format!(
            "scene \"{}\" has no lens objects, so there is nothing to bake; add a glass or mirror object",
            scene.name
        )));
    }
    let placement_views = placement_cameras(scene, options);
    let judge_camera = sample_camera(scene, positions[0], options).with_resolution(
        (options.width / PLACEMENT_SCALE).max(1),
        (options.height / PLACEMENT_SCALE).max(1),
        2,
    );
    let mut lenses = Vec::with_capacity(lens_count);
    // Per lens object, its farthest clustered layer's hits (empty otherwise).
    let mut far_hits: Vec<Vec<DVec3>> = vec![Vec::new(); lens_count];
    let mut auto_reference = None;
    // One hybrid scene judges every candidate (and searches the EM size): its environment and
    // light maps do not depend on the shells, so only a lens object's projected layers change.
    // Made when first needed, with every lens object on its default shells at JUDGE_EM_SIZE.
    let mut judge_scene: Option<HybridScene> = None;
    let judge_size = match options.em_size {
        EmSize::Auto { cap } => cap.min(JUDGE_EM_SIZE),
        EmSize::Fixed(_) => JUDGE_EM_SIZE,
    };
    let default_shells = |lens: usize| {
        let origin = em_origin(scene, lens);
        (origin, lens_shells(&trace, scene, lens, origin))
    };
    for (lens, far) in far_hits.iter_mut().enumerate() {
        let name = trace.lenses[lens].name.clone();
        let origin = em_origin(scene, lens);
        let named = !scene.lenses[lens].layers.is_empty();
        let mut planned = PlannedLens {
            name: name.clone(),
            em_origin: origin,
            shells: Vec::new(),
            source: "scene".into(),
            objects: Vec::new(),
            fit_rms: Vec::new(),
            auto_psnr_db: Vec::new(),
        };
        if options.layers == LayerCount::Scene && named {
            planned.shells = lens_shells(&trace, scene, lens, origin);
            lenses.push(planned);
            continue;
        }
        progress(&format!("placing layers of \"{name}\""));
        let hits = lens_hits(&trace, lens, &placement_views, &trace_options)?;
        if hits.is_empty() {
            // Nothing around it: one shell far away holds the environment at infinity.
            planned.source = "clustered (nothing around it: one far layer)".into();
            planned.shells = vec![LayerShell::Sphere {
                centre: origin,
                radius: FAR_SHELL_METRES,
            }];
            planned.objects = vec![Vec::new()];
            lenses.push(planned);
            continue;
        }
        planned.source = "clustered".into();
        let place = |k: usize| place_layers(scene, &name, origin, &hits, k);
        let count = match options.layers {
            LayerCount::Count(k) => Some(k),
            _ if named => Some(scene.lenses[lens].layers.len()),
            _ => None,
        };
        match count {
            Some(k) => {
                *far = planned.adopt(&place(k)?);
            }
            None => {
                // Grow while a layer helps this lens object's pixels at sample 0.
                if auto_reference.is_none() {
                    progress("tracing the reference that judges layer counts");
                    let reference =
                        render_reference(&trace, &judge_camera, &trace_options, &|_| {})?;
                    let records = compile_records(&trace, &judge_camera, &trace_options)?;
                    auto_reference = Some((reference, records));
                }
                let Some((reference, records)) = &auto_reference else {
                    unreachable!("traced just above")
                };
                let mask = lens_pixels(&records.lenses[lens], &judge_camera);
                if mask.selected() == 0 {
                    // Sample 0 does not see this lens object: nothing to judge a layer count
                    // by, so one layer (a PSNR over no pixel is an error, not a figure).
                    planned.source = "clustered (unseen at sample 0: one layer)".into();
                    *far = planned.adopt(&place(1)?);
                    lenses.push(planned);
                    continue;
                }
                let hybrid = match &mut judge_scene {
                    Some(hybrid) => hybrid,
                    judge_scene @ None => judge_scene.insert(projected_scene(
                        scene,
                        (0..lens_count).map(default_shells).collect(),
                        JUDGE_EM_SIZE,
                    )?),
                };
                let default_layers = hybrid.lenses[lens].clone();
                let mut best: Option<(f64, crate::placement::Placement)> = None;
                for k in 1..=MAX_AUTO_LAYERS {
                    let placement = place(k)?;
                    if best
                        .as_ref()
                        .is_some_and(|(_, b)| b.layers.len() >= placement.layers.len())
                    {
                        break; // no more distinct clusters
                    }
                    progress(&format!("judging {k} layer(s) for \"{name}\""));
                    let shells = placement.layers.iter().map(|l| l.shell).collect();
                    project_into(hybrid, lens, origin, shells, JUDGE_EM_SIZE);
                    let psnr = masked_psnr(
                        runner,
                        hybrid,
                        &judge_camera,
                        &reference.radiance,
                        &mask,
                        options,
                    )?;
                    planned.auto_psnr_db.push(psnr);
                    match &best {
                        Some((previous, _)) if psnr <= previous + AUTO_LAYER_GAIN_DB => break,
                        _ => best = Some((psnr, placement)),
                    }
                }
                hybrid.lenses[lens] = default_layers;
                let Some((_, placement)) = best else {
                    unreachable!("k = 1 always places a layer")
                };
                *far = planned.adopt(&placement);
            }
        }
        lenses.push(planned);
    }
    let shared = if options.share_layers {
        share_far_layers(&mut lenses, &far_hits)
    } else {
        Vec::new()
    };
    let mut plan = Plan {
        scene: scene.name.clone(),
        scene_hash: scene.content_hash(),
        options_hash: options.hash(),
        em_size: 0,
        lenses,
        shared,
    };
    let em_size = match options.em_size {
        EmSize::Fixed(size) => size,
        EmSize::Auto { cap } => {
            progress("searching the EM size at sample 0");
            let planned_shells = plan
                .lenses
                .iter()
                .map(|l| (l.em_origin, l.shells.clone()))
                .collect::<Vec<_>>();
            let hybrid = match judge_scene.as_mut() {
                Some(hybrid) => {
                    for (lens, (origin, shells)) in planned_shells.into_iter().enumerate() {
                        project_into(hybrid, lens, origin, shells, judge_size);
                    }
                    hybrid
                }
                None => judge_scene.insert(projected_scene(scene, planned_shells, judge_size)?),
            };
            share_maps(hybrid, &plan);
            let camera = sample_camera(scene, positions[0], options);
            let (frame, _) = hybrid
                .frame(&camera, &options.infer.hybrid)
                .map_err(|e| InferError::Frame(e.to_string()))?;
            let mut renderer = crate::infer::DeviceRenderer::new(runner, options.infer.variant);
            let mut finest: Option<usize> = None;
            for (lens, planned) in plan.lenses.iter().enumerate() {
                let frames = LayerFrames::new(&frame, lens, camera.supersampling.max(1))
                    .map_err(InferError::from)?;
                let (level, _) = crate::infer::finest_level_of_frames(
                    &mut renderer,
                    &frames,
                    planned.shells.len(),
                    cap,
                )
                .map_err(InferError::from)?;
                if let Some(level) = level {
                    finest = Some(finest.map_or(level, |f: usize| f.min(level)));
                }
            }
            // No lens pixel at sample 0: the cap.
            (cap >> finest.unwrap_or(0)).max(1)
        }
    };
    plan.em_size = em_size;
    Ok(plan)
}

/// Gives every shared layer of `plan` in `hybrid` its owner's EM origin and (projected) maps,
/// as the bake will hold them: the owner projected that layer from its own origin.
fn share_maps(hybrid: &mut HybridScene, plan: &Plan) {
    for shared in &plan.shared {
        let (owner, owner_layer) = shared.members[0];
        let origin = hybrid.lenses[owner].em_origins[owner_layer];
        let maps: Vec<_> = hybrid.lenses[owner]
            .maps
            .iter()
            .map(|v| v[owner_layer].clone())
            .collect();
        for &(lens, layer) in &shared.members[1..] {
            let layers = &mut hybrid.lenses[lens];
            layers.em_origins[layer] = origin;
            for (v, map) in layers.maps.iter_mut().zip(&maps) {
                v[layer] = map.clone();
            }
        }
    }
}

/// The hybrid scene a plan's samples are inferred on: the plan's shells with projected EMs (the
/// solver's starting guess) at the plan's EM size, shared layers shared.
pub fn working_scene(scene: &Scene, plan: &Plan) -> Result<HybridScene, BakeFailure> {
    let mut hybrid = projected_scene(
        scene,
        plan.lenses
            .iter()
            .map(|l| (l.em_origin, l.shells.clone()))
            .collect(),
        plan.em_size,
    )?;
    share_maps(&mut hybrid, plan);
    Ok(hybrid)
}

/// Bakes view-space sample `sample`: the maps of every lens object (`maps[lens][layer]`) and
/// the report. `hybrid` is [`working_scene`]; its maps are left as they were.
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
    let trace_options = TraceOptions::default();
    let cameras = view_cameras(scene, sample, options);
    let mut records = Vec::with_capacity(cameras.len());
    for (j, camera) in cameras.iter().enumerate() {
        progress(Step {
            stage: "tracing",
            position: j,
            of: cameras.len(),
        });
        let t = Instant::now();
        records.push(compile_records(&hybrid.trace, camera, &trace_options)?);
        seconds.tracing += t.elapsed().as_secs_f64();
    }
    let infer = InferOptions {
        em_size: EmSize::Fixed(plan.em_size),
        ..options.infer
    };
    // Every lens object's frames and targets at the views that see it; `None` where none does
    // or nothing covers a pixel centre (a sliver at the frame's edge): nothing to fit.
    let view_lists: Vec<Vec<View<'_>>> = (0..plan.lenses.len())
        .map(|lens| {
            cameras
                .iter()
                .zip(&records)
                .filter(|(_, set)| set.lenses[lens].records.iter().any(|r| r.visible))
                .map(|(camera, set)| View {
                    camera,
                    records: &set.lenses[lens],
                })
                .collect()
        })
        .collect();
    let mut prepared = Vec::with_capacity(plan.lenses.len());
    for (lens, views) in view_lists.iter().enumerate() {
        prepared.push(if views.is_empty() {
            None
        } else {
            match prepare(hybrid, lens, views, &infer) {
                Ok(p) => Some(p),
                Err(InferError::NoLensPixels { .. }) => None,
                Err(error) => return Err(error.into()),
            }
        });
    }
    for p in prepared.iter().flatten() {
        seconds.frames += p.frame_ms() / 1e3;
    }
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
    let solved = {
        let mut renderer = DeviceRenderer::new(runner, infer.variant);
        solve_layers(
            &mut renderer,
            hybrid,
            prepared,
            &plan.shared_groups(),
            plan.em_size,
            &infer,
            &mut |lens, step| {
                let (matrices, solving) = &stages[lens];
                progress(match step {
                    InferStep::Matrices { layer, layers } => Step {
                        stage: matrices,
                        position: layer,
                        of: layers,
                    },
                    InferStep::Solve { layer, layers } => Step {
                        stage: solving,
                        position: layer,
                        of: layers,
                    },
                })
            },
        )?
    };
    let mut maps: Vec<Vec<CubeMap>> = Vec::new();
    // Which lens objects' maps were inferred (the rest are projected, every layer).
    let mut inferred: Vec<bool> = Vec::new();
    let mut lenses = Vec::new();
    for (lens, (planned, solved)) in plan.lenses.iter().zip(solved).enumerate() {
        // Unseen from this sample, or a layer no pixel reads (nothing of the lens object to
        // fit, as a one-lens inference says): the projected maps stand in.
        let projected = |layer: usize| CubeMap::clone(&hybrid.lenses[lens].maps[0][layer]);
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
    // A shared layer is one file: every member holds the inferred map, also a member whose lens
    // object this sample does not see.
    for shared in &plan.shared {
        if let Some(&(lens, layer)) = shared.members.iter().find(|&&(l, _)| inferred[l]) {
            let map = maps[lens][layer].clone();
            for &(l, j) in &shared.members {
                maps[l][j] = map.clone();
            }
        }
    }
    let (mut psnr_db, mut projected_psnr_db) = (None, None);
    if options.judge {
        progress(Step {
            stage: "judging",
            position: 0,
            of: 1,
        });
        let t = Instant::now();
        let camera = sample_camera(scene, scene.view_space.samples()[sample], options);
        let reference = render_reference(&hybrid.trace, &camera, &trace_options, &|_| {})?;
        let mask = Mask::from_coverage(&reference.lens_mask, metrics::Coverage::Full);
        if mask.selected() > 0 {
            projected_psnr_db = Some(masked_psnr(
                runner,
                hybrid,
                &camera,
                &reference.radiance,
                &mask,
                options,
            )?);
            let projected: Vec<_> = hybrid.lenses.iter().map(|l| l.maps.clone()).collect();
            for (layers, inferred) in hybrid.lenses.iter_mut().zip(&maps) {
                layers.maps = vec![inferred.iter().cloned().map(Arc::new).collect()];
            }
            let judged = masked_psnr(runner, hybrid, &camera, &reference.radiance, &mask, options);
            for (layers, maps) in hybrid.lenses.iter_mut().zip(projected) {
                layers.maps = maps;
            }
            psnr_db = Some(judged?);
        }
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
        },
    ))
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

/// Bakes `samples` of `scene` into `dir` (module docs): plans, bakes each sample not already
/// complete (with `resume`), stages it, and commits the bake directory at the end.
pub fn bake(
    runner: &mut FrameRunner,
    scene: &Scene,
    dir: &Path,
    samples: &[usize],
    options: &BakeOptions,
    resume: bool,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<BakeSummary, BakeFailure> {
    options.validate()?;
    let positions = scene.view_space.samples();
    if let Some(&bad) = samples.iter().find(|&&s| s >= positions.len()) {
        return Err(BakeFailure::BadInput(format!(
            "--samples: sample {bad} does not exist; scene \"{}\" has samples 0..{}",
            scene.name,
            positions.len()
        )));
    }
    if samples.is_empty() {
        return Err(BakeFailure::BadInput(
            "no samples to bake (the shard or the sample list is empty); give more samples or fewer shards".into(),
        ));
    }
    let staging = Staging::open(dir)?;
    let scene_hash = scene.content_hash();
    let options_hash = options.hash();
    let plan_start = Instant::now();
    // The staged plan, when resuming one made for this scene and these options.
    let staged_plan: Option<Plan> = if resume && staging.contains(PLAN_FILE) {
        let path = staging.path().join(PLAN_FILE);
        let text = std::fs::read_to_string(&path).map_err(|source| BakeError::Io {
            path: path.clone(),
            action: "read",
            source,
        })?;
        serde_json::from_str::<Plan>(&text).ok().filter(|p| {
            p.scene_hash == scene_hash && p.options_hash == options_hash && p.is_consistent()
        })
    } else {
        None
    };
    let plan = match staged_plan {
        Some(plan) => plan,
        None => {
            staging.clear()?;
            let plan = make_plan(runner, scene, options, &mut |stage| {
                progress(Progress::Plan(stage))
            })?;
            let json = serde_json::to_string_pretty(&plan)
                .unwrap_or_else(|e| unreachable!("a plan always serializes: {e}"));
            staging.write_file(PLAN_FILE, json.as_bytes())?;
            plan
        }
    };
    let plan_seconds = plan_start.elapsed().as_secs_f64();
    let map_names = |sample: usize| -> Vec<Vec<String>> {
        plan.lenses
            .iter()
            .enumerate()
            .map(|(lens, planned)| {
                (0..planned.shells.len())
                    .map(|layer| plan.map_name(lens, layer, sample))
                    .collect()
            })
            .collect()
    };
    // Complete samples: staged ones, then (resuming) those of the previous bake at `dir`.
    let mut complete: BTreeMap<usize, Option<SampleReport>> = BTreeMap::new();
    for sample in 0..positions.len() {
        let name = report_file_name(sample);
        if staging.contains(&name) {
            let path = staging.path().join(&name);
            let report: SampleReport = std::fs::read_to_string(&path)
                .ok()
                .and_then(|text| serde_json::from_str(&text).ok())
                .ok_or_else(|| BakeFailure::Staged {
                    path: path.clone(),
                    message: "not a sample report of this lensmap".into(),
                })?;
            if report.options_hash == plan.options_hash
                && map_names(sample)
                    .iter()
                    .flatten()
                    .all(|m| staging.contains(m))
            {
                complete.insert(sample, Some(report));
            }
        }
    }
    let mut resumed: Vec<usize> = complete.keys().copied().collect();
    if resume && let Ok(manifest) = Manifest::read(dir) {
        let same = manifest.provenance.as_ref().is_some_and(|p| {
            p.scene_hash == plan.scene_hash && p.options_hash == plan.options_hash
        }) && manifest.cube_map_size == plan.em_size;
        if let (true, Some(provenance)) = (same, &manifest.provenance) {
            for (position, &sample) in provenance.samples.iter().enumerate() {
                if complete.contains_key(&sample) {
                    continue;
                }
                let names = map_names(sample);
                let listed = manifest.lenses.iter().zip(&names).all(|(lens, names)| {
                    lens.layers.len() == names.len()
                        && lens
                            .layers
                            .iter()
                            .zip(names)
                            .all(|(layer, name)| layer.maps.get(position) == Some(name))
                });
                if !listed {
                    continue;
                }
                let mut copied = std::collections::HashSet::new();
                for name in names.iter().flatten() {
                    // A shared layer's file once.
                    if copied.insert(name) {
                        staging.copy_in(&dir.join(name), name)?;
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
                };
                stage_report(&staging, &marker)?;
                complete.insert(sample, None);
                resumed.push(sample);
            }
        }
    }
    resumed.sort_unstable();
    let todo: Vec<usize> = samples
        .iter()
        .copied()
        .filter(|s| !complete.contains_key(s))
        .collect();
    let mut reports: Vec<SampleReport> = complete.values().flatten().cloned().collect();
    if !todo.is_empty() {
        let mut hybrid = working_scene(scene, &plan)?;
        for (done, &sample) in todo.iter().enumerate() {
            let of = todo.len();
            let (maps, report) = bake_sample(
                runner,
                scene,
                &mut hybrid,
                &plan,
                sample,
                options,
                &mut |step| {
                    progress(Progress::Sample {
                        sample,
                        done,
                        of,
                        step,
                    })
                },
            )?;
            progress(Progress::Sample {
                sample,
                done,
                of,
                step: Step {
                    stage: "writing",
                    position: 0,
                    of: 1,
                },
            });
            let t = Instant::now();
            let mut written = std::collections::HashSet::new();
            for (layers, names) in maps.iter().zip(map_names(sample)) {
                for (cube, name) in layers.iter().zip(names) {
                    // A shared layer's map once (every member holds the same solution).
                    if !written.contains(&name) {
                        staging.write_cube_map(&name, cube, plan.em_size)?;
                        written.insert(name);
                    }
                }
            }
            let mut report = report;
            report.seconds.write = t.elapsed().as_secs_f64();
            report.seconds.total += report.seconds.write;
            // The report last: it marks the sample complete.
            stage_report(&staging, &report)?;
            complete.insert(sample, Some(report.clone()));
            reports.push(report);
        }
    }
    reports.sort_by_key(|r| r.sample);
    let in_bake: Vec<usize> = complete.keys().copied().collect();
    let manifest = plan_manifest(&plan, &in_bake, &positions);
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
        lenses: plan
            .lenses
            .iter()
            .enumerate()
            .map(|(lens, planned)| ManifestLens {
                name: planned.name.clone(),
                em_origin: planned.em_origin,
                layers: planned
                    .shells
                    .iter()
                    .zip(plan.layer_origins(lens))
                    .enumerate()
                    .map(|(layer, (shell, origin))| ManifestLayer {
                        shell: *shell,
                        em_origin: (origin != planned.em_origin).then_some(origin),
                        maps: samples
                            .iter()
                            .map(|&s| plan.map_name(lens, layer, s))
                            .collect(),
                    })
                    .collect(),
            })
            .collect(),
        provenance: Some(Provenance {
            scene_hash: plan.scene_hash.clone(),
            options_hash: plan.options_hash.clone(),
            samples: samples.to_vec(),
        }),
    }
}

/// Joins the bakes in `shards` (made by `lensmap bake --shard`) into one bake at `out`: they
/// must come from the same scene and options (same provenance hashes, lens objects, shells and
/// EM size) and hold disjoint samples. Every map is read and checked before anything is written.
pub fn merge(shards: &[PathBuf], out: &Path) -> Result<Manifest, BakeFailure> {
    if shards.len() < 2 {
        return Err(BakeFailure::BadInput(
            "--merge needs at least two bake directories, e.g. --merge out/shard-1 out/shard-2"
                .into(),
        ));
    }
    let mut manifests = Vec::new();
    for dir in shards {
        let manifest = Manifest::read(dir)?;
        let Some(provenance) = manifest.provenance.clone() else {
            return Err(BakeFailure::BadInput(format!(
                "{}: has no provenance (not written by lensmap bake), so it cannot be merged; bake it with lensmap bake --shard",
                dir.join("manifest.json").display()
            )));
        };
        // Every map readable and valid.
        lensmap::layers::Bake::read(dir)?;
        manifests.push((dir, manifest, provenance));
    }
    let (first_dir, first, first_provenance) = &manifests[0];
    let mut by_sample: BTreeMap<usize, (usize, usize)> = BTreeMap::new();
    for (index, (dir, manifest, provenance)) in manifests.iter().enumerate() {
        let differs = |what: &str| {
            Err(BakeFailure::BadInput(format!(
                "{} and {}: {what} differ, so these are not shards of one bake; merge only shards made with the same scene and options",
                first_dir.display(),
                dir.display()
            )))
        };
        if provenance.scene_hash != first_provenance.scene_hash || manifest.scene != first.scene {
            return differs("the scenes");
        }
        if provenance.options_hash != first_provenance.options_hash
            || manifest.cube_map_size != first.cube_map_size
        {
            return differs("the bake options");
        }
        let shape = |m: &Manifest| -> Vec<(String, Vec<(DVec3, LayerShell)>)> {
            m.lenses
                .iter()
                .map(|l| {
                    (
                        l.name.clone(),
                        (0..l.layers.len())
                            .map(|layer| (l.layer_origin(layer), l.layers[layer].shell))
                            .collect(),
                    )
                })
                .collect()
        };
        if shape(manifest) != shape(first) {
            return differs("the lens objects or their shells");
        }
        for (position, &sample) in provenance.samples.iter().enumerate() {
            if let Some((other, _)) = by_sample.insert(sample, (index, position)) {
                return Err(BakeFailure::BadInput(format!(
                    "{} and {} both hold sample {sample}; merge shards with disjoint samples",
                    manifests[other].0.display(),
                    dir.display()
                )));
            }
        }
    }
    let staging = Staging::open(out)?;
    staging.clear()?;
    let mut merged = Manifest {
        viewpoints: Vec::new(),
        provenance: Some(Provenance {
            samples: Vec::new(),
            ..first_provenance.clone()
        }),
        ..first.clone()
    };
    for lens in &mut merged.lenses {
        for layer in &mut lens.layers {
            layer.maps.clear();
        }
    }
    for (&sample, &(index, position)) in &by_sample {
        let (dir, manifest, _) = &manifests[index];
        merged.viewpoints.push(manifest.viewpoints[position]);
        if let Some(p) = merged.provenance.as_mut() {
            p.samples.push(sample);
        }
        let mut copied = std::collections::HashSet::new();
        for (lens, source) in merged.lenses.iter_mut().zip(&manifest.lenses) {
            for (layer, source) in lens.layers.iter_mut().zip(&source.layers) {
                let name = &source.maps[position];
                // A shared layer's file once.
                if copied.insert(name) {
                    staging.copy_in(&dir.join(name), name)?;
                }
                layer.maps.push(name.clone());
            }
        }
    }
    staging.commit(&merged)?;
    Ok(merged)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_lists_and_shards_parse_or_say_the_fix() {
        assert_eq!(parse_samples("all", 4, "s").unwrap(), vec![0, 1, 2, 3]);
        assert_eq!(parse_samples("3,1,1", 4, "s").unwrap(), vec![1, 3]);
        assert_eq!(parse_samples("1..3", 4, "s").unwrap(), vec![1, 2]);
        assert_eq!(parse_samples("1..=3", 4, "s").unwrap(), vec![1, 2, 3]);
        for bad in ["4", "1..5", "2..2", "x", "1,,2"] {
            let e = parse_samples(bad, 4, "s").unwrap_err().to_string();
            assert!(e.starts_with(&format!("--samples {bad}:")), "{e}");
            assert!(e.contains("0..4"), "{e}");
        }
        assert_eq!(parse_shard("2/3").unwrap(), (2, 3));
        for bad in ["3/2", "0/0", "0/2", "1", "a/b"] {
            assert!(parse_shard(bad).is_err(), "{bad}");
        }
        let all: Vec<usize> = (0..7).collect();
        let shards: Vec<Vec<usize>> = (1..=3).map(|i| shard_samples(&all, (i, 3))).collect();
        assert_eq!(shards, vec![vec![0, 3, 6], vec![1, 4], vec![2, 5]]);
    }

    /// Points of a room (an axis-aligned box about the world origin, half extents 10, 4, 10)
    /// seen from `origin` along a Fibonacci sphere of directions.
    fn room_hits(origin: DVec3, half_extents: DVec3) -> Vec<DVec3> {
        let room = LayerShell::Box {
            centre: DVec3::ZERO,
            half_extents,
        };
        crate::placement::shell_points(&room, origin, 800)
    }

    /// A clustered lens object at `origin` whose farthest layer holds `objects` and `hits`.
    fn planned(name: &str, origin: DVec3, objects: &[&str], hits: &[DVec3]) -> PlannedLens {
        let relative: Vec<DVec3> = hits.iter().map(|p| *p - origin).collect();
        let (shell, rms, _) = crate::placement::fit_shell(origin, &relative);
        PlannedLens {
            name: name.into(),
            em_origin: origin,
            shells: vec![
                LayerShell::Sphere {
                    centre: origin,
                    radius: 0.5,
                },
                shell,
            ],
            source: "clustered".into(),
            objects: vec![
                vec!["near".into()],
                objects.iter().map(|o| o.to_string()).collect(),
            ],
            fit_rms: vec![0.1, rms],
            auto_psnr_db: Vec::new(),
        }
    }

    #[test]
    fn lens_objects_seeing_the_same_far_objects_share_one_far_layer() {
        let half = DVec3::new(10.0, 4.0, 10.0);
        let walls = ["ceiling", "wall-left", "wall-right"];
        let (a, b, c, d) = (
            DVec3::new(0.0, 0.3, 0.0),
            DVec3::new(1.3, 0.2, 0.5),
            DVec3::new(-2.0, 0.5, 1.0),
            DVec3::new(0.0, 0.8, 0.0),
        );
        let hits = [
            room_hits(a, half),
            room_hits(b, half),
            room_hits(c, half),
            room_hits(d, half),
        ];
        let mut lenses = vec![
            planned("teapot", a, &walls, &hits[0]),
            planned("cup", b, &walls, &hits[1]),
            planned("vase", c, &["ceiling", "wall-back"], &hits[2]),
            planned("lid", d, &["wall-left", "wall-right"], &hits[3]),
        ];
        let own_cup_shell = lenses[1].shells[1];
        let shared = share_far_layers(&mut lenses, &hits);
        // The teapot and the cup see the same walls, the lid two of them; the vase sees one that
        // they do not (and they see walls it does not): neither set holds the other.
        assert_eq!(shared.len(), 1, "{shared:?}");
        assert_eq!(shared[0].members, vec![(0, 1), (1, 1), (3, 1)]);
        assert_eq!(shared[0].objects, walls);
        assert_eq!(lenses[0].shells[1], lenses[1].shells[1], "one shell");
        assert_ne!(lenses[1].shells[1], own_cup_shell);
        assert_ne!(
            lenses[2].shells[1], lenses[0].shells[1],
            "the vase keeps its own"
        );
        // Both about the teapot's centroid; each member's fit within the slack of its own.
        for (shared_rms, own) in shared[0].fit_rms.iter().zip(&shared[0].separate_fit_rms) {
            assert!(*shared_rms <= own + SHARED_FIT_SLACK, "{shared:?}");
        }
        assert_eq!(lenses[1].fit_rms[1], shared[0].fit_rms[1]);
        let plan = Plan {
            scene: "s".into(),
            scene_hash: String::new(),
            options_hash: String::new(),
            em_size: 16,
            lenses: lenses.clone(),
            shared: shared.clone(),
        };
        assert_eq!(plan.map_owner(1, 1), (0, 1));
        assert_eq!(plan.map_owner(1, 0), (1, 0));
        assert_eq!(plan.layer_origins(1), vec![b, a]);
        assert_eq!(plan.map_name(1, 1, 7), map_file_name(0, "teapot", 7, 1));
        assert_eq!(plan.map_name(1, 0, 7), map_file_name(1, "cup", 7, 0));
        assert!(plan.is_consistent());
        // A hand-edited staged plan: one lens object twice, a layer that does not exist, one
        // member, another shell: none is resumed.
        for members in [
            vec![(0, 1), (0, 1)],
            vec![(0, 1), (1, 5)],
            vec![(0, 1)],
            vec![(0, 1), (1, 0)],
        ] {
            let mut edited = plan.clone();
            edited.shared[0].members = members.clone();
            assert!(!edited.is_consistent(), "{members:?}");
        }
        // A lens object of one layer: that layer holds what is near it too, so it is not shared.
        let mut one_layer = lenses.clone();
        for l in &mut one_layer {
            l.shells.remove(0);
            l.objects.remove(0);
            l.fit_rms.remove(0);
        }
        assert!(share_far_layers(&mut one_layer, &hits).is_empty());
        // The same objects, but one member's hits lie where no shell about the owner's origin
        // fits them (a sphere of 1 m about the cup, 1.4 m from the teapot): not shared.
        let small: Vec<DVec3> = room_hits(b, half)
            .iter()
            .map(|p| b + (*p - b).normalize())
            .collect();
        let hits = [hits[0].clone(), small];
        let mut lenses = vec![
            planned("teapot", a, &walls, &hits[0]),
            planned("cup", b, &walls, &hits[1]),
        ];
        let before = lenses.clone();
        assert!(share_far_layers(&mut lenses, &hits).is_empty());
        assert_eq!(lenses, before, "nothing rewritten");
    }

    #[test]
    fn views_spread_over_the_samples_share_of_the_circle() {
        let scene = Scene::load_named("glass-sphere").unwrap();
        let options = BakeOptions {
            multi_view: 3,
            ..BakeOptions::default()
        };
        let look_at = scene.camera.look_at.as_dvec3();
        let samples = scene.view_space.samples();
        let cameras = view_cameras(&scene, 5, &options);
        assert_eq!(cameras.len(), 3);
        // The middle view is the sample; the others rotated about the vertical through the
        // look-at point by ±1/3 of the angle s between neighbouring samples (as seen from the
        // look-at point), one on each side.
        assert!(cameras[1].position.distance(samples[5]) < 1e-5);
        let from = |p: Vec3| p.as_dvec3() - look_at;
        let s = angle(from(samples[5]), from(samples[6]));
        let own = from(samples[5]);
        for (camera, side) in [(&cameras[0], -1.0), (&cameras[2], 1.0)] {
            let want = look_at + DQuat::from_rotation_y(side * s / 3.0) * own;
            assert!(camera.position.as_dvec3().distance(want) < 1e-5);
            assert_eq!(camera.look_at, scene.camera.look_at);
        }
        // On opposite sides: towards sample 4 and towards sample 6.
        let towards =
            |camera: &Camera, p: Vec3| angle(from(camera.position), from(p)) < angle(own, from(p));
        assert!(towards(&cameras[0], samples[4]) != towards(&cameras[0], samples[6]));
        assert!(towards(&cameras[2], samples[4]) != towards(&cameras[2], samples[6]));
        assert!(towards(&cameras[0], samples[4]) != towards(&cameras[2], samples[4]));
        let one = BakeOptions {
            multi_view: 1,
            ..BakeOptions::default()
        };
        let single = view_cameras(&scene, 5, &one);
        assert!(single[0].position.distance(samples[5]) < 1e-5);
        // A raised view: the sample, 15° up about the horizontal axis, at the same distance.
        let raised = BakeOptions {
            view_elevation_degrees: 15.0,
            ..options
        };
        let with_raised = view_cameras(&scene, 5, &raised);
        assert_eq!(with_raised.len(), 4);
        assert_eq!(with_raised[..3], cameras[..]);
        let up = from(with_raised[3].position);
        assert!((angle(up, own).to_degrees() - 15.0).abs() < 1e-4);
        assert!((up.length() - own.length()).abs() < 1e-4);
        assert!(with_raised[3].position.y > samples[5].y);
        assert!(
            angle(up - own, glam::DVec3::Y) < angle(own, glam::DVec3::Y),
            "up, not sideways"
        );
        assert_ne!(raised.hash(), options.hash());
        for bad in [-1.0, 90.0, f64::NAN] {
            let e = BakeOptions {
                view_elevation_degrees: bad,
                ..options
            }
            .validate()
            .unwrap_err()
            .to_string();
            assert!(e.starts_with("--view-elevation-degrees"), "{e}");
        }
    }
}
