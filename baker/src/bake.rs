//! The offline stage over a whole view space (hybrid-rendering paper §4): a *plan* fixed for the
//! scene and the options (layer placement, shells, EM size), then every requested viewpoint
//! sample as one unit of work (records traced from K views around the sample, one EM per lens
//! object and layer inferred against all K views at once), staged sample by sample and committed
//! as one bake directory (`lensmap::layers::bake`).
//!
//! **Plan** ([`plan`]). Each lens object's EM origin is its centroid. Its layers come from LBG
//! clustering of intersection distances over [`PLACEMENT_SAMPLES`] viewpoints spread over the
//! whole view space, shells fitted per layer ([`crate::placement`]); [`LayerCount::Scene`] takes
//! the scene file's named shells as they are instead. Fitted shells render teapot-room better
//! than the scene's named ones, most of all away from the samples (halfway between samples,
//! K = 3: 26.20 against 22.25 dB; `docs/results.md#bake-error-budget`, "Shells on teapot-room"),
//! so [`LayerCount::Auto`] only takes the scene's layer *count* where it names layers. With `Auto`
//! and no named layers, the layer count grows from 1 while one more layer raises the lens
//! object's PSNR (projected EMs on the placed shells, at view-space sample 0, against the
//! reference) by more than [`AUTO_LAYER_GAIN_DB`], up to [`MAX_AUTO_LAYERS`]; a lens object whose
//! environment is distant gets one layer that way (and one that sample 0 does not see gets one,
//! for want of pixels to judge by). The EM size is searched (finest level read) at view-space
//! sample 0. The plan depends only on the scene and the options, never on which samples a
//! process bakes, so shards agree on it.
//!
//! **Shared distant layers** ([`shared`]; paper §4.3: "to conserve texture memory … share more
//! distant EM layers between local lens objects … add more equations … simultaneously solving for
//! a single EM"; [`BakeOptions::share_layers`]). Clustered lens objects whose farthest layers hold
//! the same scene objects (one set within the other) get one far shell, fitted to all their hits
//! about the first one's EM origin, when it fits each within [`SHARED_FIT_SLACK`] of its own
//! shell ([`SharedLayer`]). Each sample solves that layer once, on every member's equations, and
//! the bake stores it once: the member's layer lists the owner's files and origin.
//!
//! **Multi-view** ([`views`]). Sample i's EMs are solved against K views spread uniformly over
//! its share of the view space: rotations of the sample about the vertical through the look-at
//! point by `s·((j + ½)/K − ½)`, j = 0…K−1, s the angle to the nearest other sample (so K = 1 is
//! the sample alone, and odd K include it). With [`BakeOptions::view_elevation_degrees`] E > 0,
//! one more view: the sample rotated up by E about the horizontal axis through the look-at point
//! perpendicular to the direction to it, for cameras that leave the view space's circle (the view
//! space then reaches E above it). In a 2D view space (triangulated on the sphere,
//! [`lensmap::hybrid::sphere`]) the views are the sample and K − 1 views a third of the way
//! towards its triangulation neighbours, chosen evenly round it by bearing (one per neighbour
//! when it has fewer).
//!
//! **Staging, resume, shards** ([`run`], [`merge`](mod@merge)). Work goes into `Staging`
//! (`.NAME.baking` beside the bake): the plan ([`PLAN_FILE`]), then per sample its cube maps
//! ([`sample`]) and last its report `sample-NNN.json`, which marks it complete. A killed bake
//! loses at most the sample in flight; the bake at NAME is replaced only by the final commit.
//! [`BakeJob::resume`] keeps a staging directory whose plan matches and takes complete samples
//! from it and from a bake at NAME made with the same scene and options. Everything is
//! deterministic (fixed reductions, ordered sums, a deterministic device), so a resumed bake, a
//! merged set of shards and a single-process bake give the same bytes. [`reuse`] says whether a
//! bake directory already holds what a caller needs.
//!
//! The rooms: [`options`], [`spec`] (sample lists and shards), [`plan`], [`shared`], [`views`],
//! [`judge`], [`sample`], [`run`], [`merge`](mod@merge), [`reuse`], [`failure`] (errors).

pub mod failure;
pub mod judge;
pub mod merge;
pub mod names;
pub mod options;
pub mod plan;
pub mod reuse;
pub mod run;
pub mod sample;
pub mod shared;
pub mod spec;
pub mod views;

pub use failure::{BakeFailure, BakeInputError};
pub use merge::{MergeError, merge};
pub use options::{
    AUTO_LAYER_GAIN_DB, BAKER_REVISION, BakeOptions, DEFAULT_MULTI_VIEW, FAR_SHELL_METRES,
    LayerCount, MAX_AUTO_LAYERS, PLACEMENT_SAMPLES, PLACEMENT_SCALE, SINGLE_SAMPLE_SPREAD_DEGREES,
};
pub use plan::{PLAN_FILE, Plan, PlannedLens, make_plan, working_scene};
pub use run::{BakeJob, BakeSummary, Progress, bake, report_file_name};
pub use sample::{LensReport, SampleReport, StageSeconds, Step, bake_sample};
pub use shared::{SHARED_FIT_SLACK, SharedLayer};
pub use spec::{Shard, parse_samples, parse_shard, shard_samples};
pub use views::{placement_cameras, view_cameras};
