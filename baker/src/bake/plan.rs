//! The plan: what is fixed for a scene and options before any sample is baked (module docs of
//! [`super`]): each lens object's EM origin and shells, shared layers, and the EM size.

use std::collections::BTreeSet;

use glam::DVec3;
use lensmap::{
    hybrid::{FrameBuilder, HybridScene},
    index::{LayerIndex, LayerRef, LensIndex},
    layers::{
        LayerShell, Layering,
        bake::map_file_name,
        projected::{em_origin, lens_shells},
    },
    metrics::Mask,
    runner::FrameRunner,
    scene::{Camera, Scene},
    trace::{
        LensSelection, TraceOptions, image::ReferenceImage, render_reference, world::TraceScene,
    },
};
use serde::{Deserialize, Serialize};

use super::{
    failure::{BakeFailure, BakeInputError},
    judge::{masked_psnr, project_into, projected_scene},
    options::{
        AUTO_LAYER_GAIN_DB, BakeOptions, FAR_SHELL_METRES, LayerCount, MAX_AUTO_LAYERS,
        PLACEMENT_SCALE,
    },
    shared::{SharedLayer, share_far_layers, share_maps},
    views::{placement_cameras, sample_camera},
};
use crate::{
    bounce::place_by_bounce,
    infer::{DeviceRenderer, EmSize, InferError, finest_level_of_frames},
    matrix::LayerFrames,
    placement::{Placement, PlacementError, lens_hits, place_layers},
};

/// The staged plan's file name.
pub const PLAN_FILE: &str = "plan.json";

/// Face size of the projected EMs the plan judges layer counts with (and, capped by the EM size
/// cap, searches the EM size on).
const JUDGE_EM_SIZE: u32 = 64;

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
    /// The path classes the maps are solved over (`None`: the greedy terms), for the manifest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub terms: Option<String>,
}

impl Plan {
    /// The layer whose map layer `at` uses: its own, or a shared layer's owner.
    pub fn map_owner(&self, at: LayerRef) -> LayerRef {
        self.shared
            .iter()
            .find(|s| s.members.contains(&at))
            .map_or(at, |s| s.members[0])
    }

    /// The EM origin of every layer of lens object `lens`: the owner's centroid.
    pub fn layer_origins(&self, lens: LensIndex) -> Vec<DVec3> {
        LayerIndex::all(self.lenses[lens.index()].shells.len())
            .map(|layer| self.lenses[self.map_owner(lens.layer(layer)).lens.index()].em_origin)
            .collect()
    }

    /// The file of layer `at` at view-space sample `sample` (a shared layer's is its owner's).
    pub fn map_name(&self, at: LayerRef, sample: usize) -> String {
        let owner = self.map_owner(at);
        map_file_name(owner, &self.lenses[owner.lens.index()].name, sample)
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
            let shell = |&LayerRef { lens, layer }: &LayerRef| {
                self.lenses
                    .get(lens.index())
                    .and_then(|l| l.shells.get(layer.index()))
            };
            let distinct: BTreeSet<LensIndex> = s.members.iter().map(|m| m.lens).collect();
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

    /// The files of every lens object's layers at view-space sample `sample`
    /// (`names[lens][layer]`; a shared layer's are its owner's).
    pub fn map_names(&self, sample: usize) -> Vec<Vec<String>> {
        LensIndex::all(self.lenses.len())
            .zip(&self.lenses)
            .map(|(lens, planned)| {
                LayerIndex::all(planned.shells.len())
                    .map(|layer| self.map_name(lens.layer(layer), sample))
                    .collect()
            })
            .collect()
    }

    /// The shared layers as groups of layers, for [`crate::infer::solve_layers`].
    pub fn shared_groups(&self) -> Vec<Vec<LayerRef>> {
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
    /// [`LayerCount::Auto`] without named layers: lens PSNR (dB) with 1, 2, … layers as tried.
    pub auto_psnr_db: Vec<f64>,
    /// How rays are split between the layers.
    #[serde(default)]
    pub layering: Layering,
}

impl PlannedLens {
    /// Takes the shells, objects and fits of a placement; returns the farthest layer's hits
    /// (world space), what a shared shell is fitted to.
    pub(super) fn adopt(&mut self, placement: &crate::placement::Placement) -> Vec<DVec3> {
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

/// Makes the plan for `scene` and `options` (module docs of [`super`]): every lens object's
/// layers, the shared layers, then the EM size. `progress` hears each step.
pub fn make_plan(
    runner: &mut FrameRunner,
    scene: &Scene,
    options: &BakeOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<Plan, BakeFailure> {
    options.validate()?;
    let trace = TraceScene::new(scene)?;
    let lens_count = trace.lenses.len();
    if lens_count == 0 {
        return Err(BakeInputError::NoLensObjects {
            scene: scene.name.clone(),
        }
        .into());
    }
    let placement_views = placement_cameras(scene, options);
    let mut judge = Judge::new(scene, &trace, options);
    let mut lenses = Vec::with_capacity(lens_count);
    // Per lens object, its farthest clustered layer's hits (empty otherwise).
    let mut far_hits: Vec<Vec<DVec3>> = Vec::with_capacity(lens_count);
    for lens in LensIndex::all(lens_count) {
        let (planned, far) = plan_lens(
            runner,
            &mut judge,
            lens,
            &placement_views,
            options,
            progress,
        )?;
        lenses.push(planned);
        far_hits.push(far);
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
        terms: match options.infer.model() {
            lensmap::trace::PathModel::Classes(set) => Some(set.name()),
            lensmap::trace::PathModel::Greedy | lensmap::trace::PathModel::Full => None,
        },
        em_size: 0,
        lenses,
        shared,
    };
    plan.em_size = match options.em_size {
        EmSize::Fixed(size) => size,
        EmSize::Auto { cap } => {
            progress("searching the EM size at sample 0");
            search_em_size(runner, &mut judge, &plan, cap, options)?
        }
    };
    Ok(plan)
}

/// What the plan judges layer counts and searches the EM size with, each made when first needed:
/// the reference at sample 0 (at a fraction of the bake's resolution), and one
/// hybrid scene with every lens object on its default shells at [`JUDGE_EM_SIZE`] (its
/// environment and light maps do not depend on the shells, so only a lens object's projected
/// layers change between candidates).
struct Judge<'s> {
    scene: &'s Scene,
    trace: &'s TraceScene,
    camera: Camera,
    /// The reference's options: the bake's ray-path model ([`super::InferOptions::model`]).
    reference_options: TraceOptions,
    reference: Option<ReferenceImage>,
    hybrid: Option<HybridScene>,
}

impl<'s> Judge<'s> {
    fn new(scene: &'s Scene, trace: &'s TraceScene, options: &BakeOptions) -> Judge<'s> {
        let camera = sample_camera(scene, scene.view_space.samples()[0], options).with_resolution(
            (options.width / PLACEMENT_SCALE).max(1),
            (options.height / PLACEMENT_SCALE).max(1),
            2,
        );
        Judge {
            scene,
            trace,
            camera,
            reference_options: TraceOptions {
                model: options.infer.model(),
                ..TraceOptions::default()
            },
            reference: None,
            hybrid: None,
        }
    }

    /// Lens object `lens`'s pixels at the judging camera (the reference traced first if needed).
    fn lens_pixels(
        &mut self,
        lens: LensIndex,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Mask, BakeFailure> {
        let reference = match self.reference.take() {
            Some(traced) => self.reference.insert(traced),
            None => {
                progress("tracing the reference that judges layer counts");
                let reference =
                    render_reference(self.trace, &self.camera, &self.reference_options, &|_| {})?;
                self.reference.insert(reference)
            }
        };
        Ok(Mask::lens(
            &reference.lens_pixels,
            LensSelection::Object(lens.index()),
        ))
    }

    /// The judging hybrid scene, made on the default shells if needed.
    fn hybrid(&mut self) -> Result<&mut HybridScene, BakeFailure> {
        Self::hybrid_in(&mut self.hybrid, self.scene, self.trace)
    }

    fn hybrid_in<'h>(
        slot: &'h mut Option<HybridScene>,
        scene: &Scene,
        trace: &TraceScene,
    ) -> Result<&'h mut HybridScene, BakeFailure> {
        match slot {
            Some(hybrid) => Ok(hybrid),
            None => {
                let default_shells = |lens: usize| {
                    let origin = em_origin(scene, lens);
                    (origin, lens_shells(trace, scene, lens, origin))
                };
                let shells = (0..trace.lenses.len()).map(default_shells).collect();
                Ok(slot.insert(projected_scene(scene, shells, JUDGE_EM_SIZE)?))
            }
        }
    }

    /// Lens PSNR at the judging camera over `mask` with lens object `lens` on `shells` about
    /// `origin` (projected EMs at [`JUDGE_EM_SIZE`]); the lens object keeps those layers in the
    /// judging scene. `mask` comes from [`Judge::lens_pixels`].
    fn psnr_on(
        &mut self,
        runner: &mut FrameRunner,
        lens: LensIndex,
        origin: DVec3,
        shells: Vec<LayerShell>,
        mask: &Mask,
        options: &BakeOptions,
    ) -> Result<f64, BakeFailure> {
        let hybrid = Self::hybrid_in(&mut self.hybrid, self.scene, self.trace)?;
        let Some(reference) = &self.reference else {
            unreachable!("the mask was taken from the reference")
        };
        project_into(hybrid, lens, origin, shells, JUDGE_EM_SIZE);
        masked_psnr(
            runner,
            hybrid,
            &self.camera,
            &reference.radiance,
            mask,
            options,
        )
    }
}

/// Lens object `lens`'s plan, and its farthest clustered layer's hits (empty when it has no
/// clustered layers): the scene's named shells, one far shell when nothing is around it, or
/// clustered layers, as many as `options` or the scene say or else grown ([`grow_layers`]).
fn plan_lens(
    runner: &mut FrameRunner,
    judge: &mut Judge<'_>,
    lens: LensIndex,
    placement_views: &[Camera],
    options: &BakeOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<(PlannedLens, Vec<DVec3>), BakeFailure> {
    let (scene, trace) = (judge.scene, judge.trace);
    let position = lens.index();
    let name = trace.lenses[position].name.clone();
    let origin = em_origin(scene, position);
    let named = !scene.lenses[position].layers.is_empty();
    let mut planned = PlannedLens {
        name: name.clone(),
        em_origin: origin,
        shells: Vec::new(),
        source: "scene".into(),
        objects: Vec::new(),
        fit_rms: Vec::new(),
        auto_psnr_db: Vec::new(),
        layering: Layering::Distance,
    };
    // By bounce when asked for every lens object, or when the scene file asks it for this one
    // and the layer count is left to the scene or the baker (an explicit count means distance).
    let by_bounce = match options.layers {
        LayerCount::Bounce => true,
        LayerCount::Auto | LayerCount::Scene => scene.lenses[position].layering == Layering::Bounce,
        LayerCount::Count(_) => false,
    };
    if let (true, lensmap::trace::PathModel::Classes(set)) = (by_bounce, options.infer.model()) {
        // Refused before any work: the frames of classes cannot shade a lens by bounce.
        return Err(lensmap::options::OptionError::new(
            lensmap::options::names::TERMS,
            set.name(),
            format!("lens object \"{name}\" is layered by bounce (its scene entry's `layering`), whose paths stop at the first bounce; give a layer count (layers by distance), or greedy"),
        )
        .into());
    }
    if by_bounce {
        progress(&format!("fitting layers by bounce for \"{name}\""));
        planned.shells = place_by_bounce(scene, trace, position, origin, placement_views)?.to_vec();
        planned.source = "bounce".into();
        planned.objects = vec![Vec::new(); 2];
        planned.layering = Layering::Bounce;
        return Ok((planned, Vec::new()));
    }
    if options.layers == LayerCount::Scene && named {
        planned.shells = lens_shells(trace, scene, position, origin);
        return Ok((planned, Vec::new()));
    }
    progress(&format!("placing layers of \"{name}\""));
    let hits = lens_hits(trace, position, placement_views, &TraceOptions::default())?;
    if hits.is_empty() {
        // Nothing around it: one shell far away holds the environment at infinity.
        planned.source = "clustered (nothing around it: one far layer)".into();
        planned.shells = vec![LayerShell::Sphere {
            centre: origin,
            radius: FAR_SHELL_METRES,
        }];
        planned.objects = vec![Vec::new()];
        return Ok((planned, Vec::new()));
    }
    planned.source = "clustered".into();
    let place = |k: usize| place_layers(scene, &name, origin, &hits, k);
    let count = match options.layers {
        LayerCount::Count(k) => Some(k),
        _ if named => Some(scene.lenses[position].layers.len()),
        _ => None,
    };
    let far = match count {
        Some(k) => planned.adopt(&place(k)?),
        None => grow_layers(runner, judge, lens, &mut planned, &place, options, progress)?,
    };
    Ok((planned, far))
}

/// Grows lens object `lens`'s clustered layers (placed by `place`) from one while a layer helps
/// its pixels at sample 0 by more than [`AUTO_LAYER_GAIN_DB`], up to [`MAX_AUTO_LAYERS`];
/// records each count's PSNR in `planned` and adopts the best placement. Returns its farthest
/// layer's hits.
fn grow_layers(
    runner: &mut FrameRunner,
    judge: &mut Judge<'_>,
    lens: LensIndex,
    planned: &mut PlannedLens,
    place: &dyn Fn(usize) -> Result<Placement, PlacementError>,
    options: &BakeOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<DVec3>, BakeFailure> {
    let mask = judge.lens_pixels(lens, progress)?;
    if mask.selected() == 0 {
        // Sample 0 does not see this lens object: nothing to judge a layer count by, so one
        // layer (a PSNR over no pixel is an error, not a figure).
        planned.source = "clustered (unseen at sample 0: one layer)".into();
        return Ok(planned.adopt(&place(1)?));
    }
    let default_layers = judge.hybrid()?.lenses()[lens.index()].clone();
    let mut best: Option<(f64, Placement)> = None;
    for k in 1..=MAX_AUTO_LAYERS {
        let placement = place(k)?;
        if best
            .as_ref()
            .is_some_and(|(_, b)| b.layers.len() >= placement.layers.len())
        {
            break; // no more distinct clusters
        }
        progress(&format!("judging {k} layer(s) for \"{}\"", planned.name));
        let shells = placement.layers.iter().map(|l| l.shell).collect();
        let psnr = judge.psnr_on(runner, lens, planned.em_origin, shells, &mask, options)?;
        planned.auto_psnr_db.push(psnr);
        match &best {
            Some((previous, _)) if psnr <= previous + AUTO_LAYER_GAIN_DB => break,
            _ => best = Some((psnr, placement)),
        }
    }
    judge.hybrid()?.set_lens_layers(lens, default_layers);
    let Some((_, placement)) = best else {
        unreachable!("k = 1 always places a layer")
    };
    Ok(planned.adopt(&placement))
}

/// The EM size for `plan` with [`EmSize::Auto`] up to `cap`: the smallest whose finest level is
/// the finest any lens pixel reads at sample 0, with the plan's shells projected at
/// `cap.min(JUDGE_EM_SIZE)` (the cap when no lens pixel is seen).
fn search_em_size(
    runner: &mut FrameRunner,
    judge: &mut Judge<'_>,
    plan: &Plan,
    cap: u32,
    options: &BakeOptions,
) -> Result<u32, BakeFailure> {
    let judge_size = cap.min(JUDGE_EM_SIZE);
    let scene = judge.scene;
    let planned_shells = plan
        .lenses
        .iter()
        .map(|l| (l.em_origin, l.shells.clone()))
        .collect::<Vec<_>>();
    let hybrid = match judge.hybrid.as_mut() {
        Some(hybrid) => {
            for (lens, (origin, shells)) in LensIndex::all(plan.lenses.len()).zip(planned_shells) {
                project_into(hybrid, lens, origin, shells, judge_size);
            }
            hybrid
        }
        None => judge
            .hybrid
            .insert(projected_scene(scene, planned_shells, judge_size)?),
    };
    share_maps(hybrid, plan);
    adopt_layering(hybrid, plan);
    let camera = sample_camera(scene, scene.view_space.samples()[0], options);
    let (frame, _) = FrameBuilder::new()
        .frame(hybrid, &camera, &options.infer.frame_options())
        .map_err(|e| InferError::Frame(e.to_string()))?;
    let mut renderer = DeviceRenderer::new(runner, options.infer.compositing);
    let mut finest: Option<usize> = None;
    for (lens, planned) in LensIndex::all(plan.lenses.len()).zip(&plan.lenses) {
        let frames = LayerFrames::new(&frame, lens, camera.supersampling.max(1))
            .map_err(InferError::from)?;
        let (level, _) = finest_level_of_frames(&mut renderer, &frames, planned.shells.len(), cap)
            .map_err(InferError::from)?;
        if let Some(level) = level {
            finest = Some(finest.map_or(level, |f: usize| f.min(level)));
        }
    }
    // No lens pixel at sample 0: the cap.
    Ok((cap >> finest.unwrap_or(0)).max(1))
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
    adopt_layering(&mut hybrid, plan);
    Ok(hybrid)
}

/// Gives each lens object of `hybrid` its layering in `plan`.
fn adopt_layering(hybrid: &mut HybridScene, plan: &Plan) {
    for (lens, planned) in LensIndex::all(plan.lenses.len()).zip(&plan.lenses) {
        let mut layers = hybrid.lenses()[lens.index()].clone();
        layers.layering = planned.layering;
        hybrid.set_lens_layers(lens, layers);
    }
}
