//! Assembling a hybrid scene: everything a hybrid frame is made from that does not change with
//! the camera. The scene's ray-tracing structures, each lens object's layered EMs (projected
//! from the scene, or a bake's), the light-mapped opaque environment, the sky dome, and which
//! faces of each lens object are drawn. [`HybridScene::new`] is the one way to make one; it is
//! data, read through its accessors, and every change goes through a setter that bumps its
//! [`SceneVersion`], which the frames built from it are keyed by.

use std::{
    path::PathBuf,
    sync::{Arc, OnceLock},
    time::Instant,
};

use glam::{DVec3, Vec3};

use super::{
    ViewpointBlending,
    glossy::GlossyScene,
    sky::SkyDome,
    viewpoints::{self, ViewSpaceBlender, ViewSpaceFit, ViewpointBlend},
};
use crate::{
    cubemap::CubeMap,
    identity::{Encoder, IDENTITY_VERSION},
    index::LensIndex,
    layers::{
        Bake, BakedLens, LayerShell, Layering, Provenance,
        bake::default_created_by,
        projected::{ProjectedOptions, em_origin, lens_shells, project_layers},
    },
    lightmap::{
        LightMapOptions, LightMapStats, PlanError, Viewers, build_light_mapped_mesh, plan_atlases,
    },
    options::{LibraryWords, OptionWords, Worded, names},
    render::{EnvironmentMesh, LensFaces, MeshLightMap},
    scene::{Camera, Scene, TriangleMesh},
    trace::world::TraceScene,
};

/// A lens object's layered EMs.
#[derive(Clone, Debug)]
pub struct LensLayers {
    /// Per layer, the EM origin its cube-map directions are taken from (shell hit − origin),
    /// metres: the lens object's centroid, or for a layer shared with other lens objects the
    /// shared map's origin (that of the lens object that owns it).
    pub em_origins: Vec<DVec3>,
    /// Shells, nearest first.
    pub shells: Vec<LayerShell>,
    /// How rays are split between the layers; by bounce, the runtime's paths stop at their first
    /// bounce.
    pub layering: Layering,
    /// `maps[viewpoint sample][layer]`, one entry per sample of [`HybridScene::viewpoints`];
    /// projected EMs do not depend on the viewpoint, so they have a single entry that every
    /// sample shares.
    pub maps: Vec<Vec<Arc<CubeMap>>>,
}

/// Why a hybrid scene cannot be assembled.
#[derive(Debug, thiserror::Error)]
pub enum HybridError {
    /// The ray tracer refused the scene.
    #[error(transparent)]
    Trace(#[from] crate::trace::TraceError),
    /// A bake that does not identify itself as made from this scene.
    #[error("{0}")]
    Identity(#[from] BakeIdentityError),
    /// A bake does not fit the scene; the message names the field and the fix.
    #[error("{0}")]
    BakeMismatch(String),
    /// An environment object's light map cannot be made.
    #[error("object \"{object}\": light map: {error}")]
    LightMap {
        /// The scene object.
        object: String,
        /// Why.
        error: crate::lightmap::AtlasError,
    },
    /// The light maps together pass their texel budget.
    #[error("light maps: {0}")]
    LightMapBudget(PlanError),
}

impl Worded for HybridError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        match self {
            HybridError::Identity(error) => error.worded(words),
            _ => self.to_string(),
        }
    }
}

/// A bake used with a scene it does not name as its own (its [`Provenance`]). The message
/// names the option that accepts any bake (`accept_any_bake`) and how to bake the scene, in
/// each front end's words ([`Worded`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}", self.worded(&LibraryWords))]
pub enum BakeIdentityError {
    /// The bake was made from other scene content: its provenance names another content hash.
    OtherScene {
        /// The bake's directory, where it was read from one (the message then names its
        /// manifest by path).
        bake: Option<PathBuf>,
        /// The scene the bake was made from (its manifest's `scene`).
        baked_scene: String,
        /// The scene it was used with.
        scene: String,
    },
    /// The bake says nothing of the scene it was made from (it has no provenance), and any bake
    /// was not accepted.
    Unidentified {
        /// The bake's directory (the message names its manifest alone).
        bake: PathBuf,
    },
    /// The bake's provenance was written with another identity version than this lensmap's
    /// ([`Provenance::is_current`]), so what it was made from cannot be compared.
    OtherIdentityVersion {
        /// The bake's directory, where it was read from one.
        bake: Option<PathBuf>,
        /// The version the bake names (0: before lensmap had one).
        version: u32,
    },
}

impl Worded for BakeIdentityError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        let bake_command = |scene| {
            words
                .bake_command(scene)
                .map_or_else(String::new, |command| format!(" ({command})"))
        };
        match self {
            BakeIdentityError::OtherScene {
                bake,
                baked_scene,
                scene,
            } => format!(
                "{}manifest.json: provenance.scene_hash: the bake was made from scene \"{baked_scene}\" with other content than scene \"{scene}\"; bake this scene{} or pass the scene it was made from",
                bake.as_ref()
                    .map_or_else(String::new, |dir| format!("{}/", dir.display())),
                bake_command(Some(scene))
            ),
            BakeIdentityError::Unidentified { .. } => format!(
                "manifest.json: provenance: the bake does not say which scene it was made from; bake this scene{}, or {} to use it anyway",
                bake_command(None),
                words.switch_on(names::ACCEPT_ANY_BAKE)
            ),
            BakeIdentityError::OtherIdentityVersion { bake, version } => format!(
                "{}manifest.json: provenance.identity_version: the bake names its scene and options in identity version {version}, this lensmap in version {IDENTITY_VERSION}, so it cannot tell what the bake was made from; bake the scene again{}, or {} to use it anyway",
                bake.as_ref()
                    .map_or_else(String::new, |dir| format!("{}/", dir.display())),
                bake_command(None),
                words.switch_on(names::ACCEPT_ANY_BAKE)
            ),
        }
    }
}

/// Where a hybrid scene's layered EMs come from.
#[derive(Clone, Debug, PartialEq)]
pub enum LayeredEms {
    /// Projected from the scene ([`crate::layers::projected`]) onto the layer shells its file
    /// names for each lens object (one sphere where it names none).
    Projected(ProjectedOptions),
    /// Projected onto the given shells: `shells[lens]` is the EM origin and the shells of lens
    /// object `lens` (TraceScene order), nearest first; one entry per lens object.
    ProjectedOn {
        /// Per lens object, its EM origin (metres) and shells.
        shells: Vec<(DVec3, Vec<LayerShell>)>,
        /// How the maps are projected.
        options: ProjectedOptions,
    },
    /// A bake's, matched to lens objects by name. A bake that carries its scene's identity
    /// ([`Provenance`]) must have been made from this very scene content.
    Baked(Bake),
}

/// How a [`HybridScene`] is assembled.
#[derive(Clone, Debug, PartialEq)]
pub struct HybridSceneOptions {
    /// Where the layered EMs come from.
    pub ems: LayeredEms,
    /// How the opaque environment's light maps are made.
    pub light_maps: LightMapOptions,
}

impl Default for HybridSceneOptions {
    /// EMs projected with the default options onto the scene's shells; default light maps.
    fn default() -> Self {
        HybridSceneOptions {
            ems: LayeredEms::Projected(ProjectedOptions::default()),
            light_maps: LightMapOptions::default(),
        }
    }
}

impl From<LayeredEms> for HybridSceneOptions {
    /// These EMs with default light maps.
    fn from(ems: LayeredEms) -> Self {
        HybridSceneOptions {
            ems,
            ..HybridSceneOptions::default()
        }
    }
}

/// Everything a hybrid frame is made from that does not change with the camera.
pub struct HybridScene {
    /// The scene.
    scene: Scene,
    /// Its ray-tracing structures.
    trace: TraceScene,
    /// The viewpoint samples and how a frame blends them (1D or triangulated 2D).
    view_space: ViewSpaceBlender,
    /// Per lens object (TraceScene order).
    lenses: Vec<LensLayers>,
    /// Per lens object (TraceScene order), which faces are traced and drawn (see
    /// [`HybridScene::lens_faces`]).
    faces: Vec<LensFaces>,
    /// The opaque environment for the GPU, light-mapped (see
    /// [`HybridScene::light_mapped_environment`]).
    environment: Vec<Arc<EnvironmentMesh>>,
    /// What making the environment's light maps cost.
    light_maps: LightMapStats,
    /// The environment at infinity for the GPU, drawn behind everything; `None` when it is black.
    sky: Option<SkyDome>,
    /// The glossy objects drawn by reflection-space IBR (see
    /// [`HybridScene::use_radiance_maps`]); `None`: they are light-mapped environment meshes.
    glossy: Option<GlossyScene>,
    /// Per scene object, which of its triangles lie on the convex hull of the lens geometry
    /// ([`super::hull`]): worked out the first time a frame needs it (a lens object layered by
    /// bounce, with the split on), then kept, as the geometry does not change.
    hull: Vec<OnceLock<Vec<bool>>>,
    /// This scene's identity and how many times it was changed.
    version: SceneVersion,
}

/// Which scene, and which version of it: a frame built from another version is another frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SceneVersion {
    /// Unique to the scene in the process; its geometry never changes under it.
    pub id: u64,
    /// How many times a setter changed it since it was built.
    pub generation: u64,
}

/// The next [`HybridScene`]'s identity.
static SCENE_IDENTITY: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

impl HybridScene {
    /// Assembles the hybrid scene of `scene` with the layered EMs and light maps `options` asks
    /// for; also returns the rays cast to project EMs (0 for a bake). Projected EMs do not
    /// depend on the viewpoint: every viewpoint sample of the scene's view space shares them.
    pub fn new(
        scene: Scene,
        options: HybridSceneOptions,
    ) -> Result<(HybridScene, u64), HybridError> {
        let HybridSceneOptions { ems, light_maps } = options;
        if let LayeredEms::Baked(bake) = &ems {
            check_provenance(&scene, bake)?;
        }
        let trace = TraceScene::new(&scene)?;
        let scene_viewpoints = || {
            scene
                .view_space
                .samples()
                .iter()
                .map(|p| p.as_dvec3())
                .collect()
        };
        let (viewpoints, lenses, rays) = match ems {
            LayeredEms::Projected(options) => {
                let shells = (0..trace.lenses.len())
                    .map(|lens| {
                        let origin = em_origin(&scene, lens);
                        (origin, lens_shells(&trace, &scene, lens, origin))
                    })
                    .collect();
                let (lenses, rays) = projected_layers(&scene, &trace, shells, &options)?;
                (scene_viewpoints(), lenses, rays)
            }
            LayeredEms::ProjectedOn { shells, options } => {
                let (lenses, rays) = projected_layers(&scene, &trace, shells, &options)?;
                (scene_viewpoints(), lenses, rays)
            }
            LayeredEms::Baked(bake) => {
                let viewpoints = bake.viewpoints.iter().map(|p| p.as_dvec3()).collect();
                (viewpoints, baked_layers(&scene, &trace, bake.lenses)?, 0)
            }
        };
        let (environment, light_map_stats) =
            Self::light_mapped_environment(&scene, &trace, &light_maps)?;
        let faces = Self::lens_faces(&scene, &trace);
        let sky = SkyDome::new(&trace);
        let hull = (0..scene.objects.len()).map(|_| OnceLock::new()).collect();
        Ok((
            HybridScene {
                view_space: ViewSpaceBlender::new(
                    viewpoints,
                    scene.view_space.centre(scene.camera.look_at).as_dvec3(),
                    scene.view_space.is_surface(),
                ),
                scene,
                trace,
                lenses,
                faces,
                environment,
                light_maps: light_map_stats,
                sky,
                glossy: None,
                hull,
                version: SceneVersion {
                    id: SCENE_IDENTITY.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
                    generation: 0,
                },
            },
            rays,
        ))
    }

    /// Unique to this scene in the process (its geometry is fixed once built): what a device's
    /// resident copy of its geometry is kept by.
    pub(crate) fn identity(&self) -> u64 {
        self.version.id
    }

    /// This scene and its version.
    pub fn version(&self) -> SceneVersion {
        self.version
    }

    /// The scene description.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Its ray-tracing structures.
    pub fn trace(&self) -> &TraceScene {
        &self.trace
    }

    /// Per lens object (TraceScene order), its layered EMs.
    pub fn lenses(&self) -> &[LensLayers] {
        &self.lenses
    }

    /// Per lens object (TraceScene order), which faces are traced and drawn.
    pub fn faces(&self) -> &[LensFaces] {
        &self.faces
    }

    /// The opaque environment for the GPU, light-mapped.
    pub fn environment(&self) -> &[Arc<EnvironmentMesh>] {
        &self.environment
    }

    /// What making the environment's light maps cost.
    pub fn light_maps(&self) -> &LightMapStats {
        &self.light_maps
    }

    /// The environment at infinity for the GPU; `None` when it is black.
    pub fn sky(&self) -> Option<&SkyDome> {
        self.sky.as_ref()
    }

    /// The glossy objects drawn by reflection-space IBR; `None` while they are light-mapped.
    pub fn glossy(&self) -> Option<&GlossyScene> {
        self.glossy.as_ref()
    }

    /// Replaces lens object `lens`'s layered EMs (its EM origins, shells, layering and maps) by
    /// `layers`: the baker's and the viewer's experiments. A new version of the scene.
    pub fn set_lens_layers(&mut self, lens: LensIndex, layers: LensLayers) {
        if let Some(slot) = self.lenses.get_mut(lens.index()) {
            *slot = layers;
            self.changed();
        }
    }

    /// Replaces lens object `lens`'s maps (`maps[viewpoint sample][layer]`, as
    /// [`LensLayers::maps`]), keeping its shells: the baker's judged maps, the viewer's layers
    /// switched off. A new version of the scene.
    pub fn set_lens_maps(&mut self, lens: LensIndex, maps: Vec<Vec<Arc<CubeMap>>>) {
        if let Some(slot) = self.lenses.get_mut(lens.index()) {
            slot.maps = maps;
            self.changed();
        }
    }

    /// Reconstructs the glossy objects' maps by `reconstruction` (no effect while they are
    /// light-mapped). A new version of the scene.
    pub fn set_glossy_reconstruction(&mut self, reconstruction: crate::rsibr::Reconstruction) {
        if let Some(glossy) = &mut self.glossy {
            glossy.reconstruction = reconstruction;
            self.changed();
        }
    }

    /// Draws the environment at infinity from `sky` (`None`: black). A new version of the
    /// scene.
    pub fn set_sky(&mut self, sky: Option<SkyDome>) {
        self.sky = sky;
        self.changed();
    }

    /// The glossy objects drawn by reflection-space IBR (`glossy`), and the environment meshes
    /// left light-mapped: what [`HybridScene::use_radiance_maps`] sets. A new version.
    pub(super) fn set_glossy(
        &mut self,
        glossy: Option<GlossyScene>,
        environment: Vec<Arc<EnvironmentMesh>>,
    ) {
        self.glossy = glossy;
        self.environment = environment;
        self.changed();
    }

    /// Notes a change: frames built before are of another version.
    fn changed(&mut self) {
        self.version.generation += 1;
    }

    /// Per input triangle of scene object `object`, whether it lies on the convex hull of the
    /// lens geometry (computed once per object).
    pub(crate) fn hull_triangles(&self, object: usize) -> &[bool] {
        self.hull[object].get_or_init(|| {
            let points: Vec<Vec3> = self
                .trace
                .lenses
                .iter()
                .flat_map(|lens| &lens.objects)
                .flat_map(|&o| self.scene.objects[o].mesh.positions.iter().copied())
                .collect();
            super::hull::hull_triangles(&self.scene.objects[object].mesh, &points)
        })
    }

    /// The viewpoint sample positions, metres: the bake's samples, or the scene's view space
    /// for projected EMs.
    pub fn viewpoints(&self) -> &[DVec3] {
        self.view_space.positions()
    }

    /// The viewpoint samples and how a frame blends them.
    pub fn view_space(&self) -> &ViewSpaceBlender {
        &self.view_space
    }

    /// How `camera` sits in the view space of [`HybridScene::viewpoints`] about its centre
    /// ([`ViewSpaceBlender::fit`](crate::hybrid::ViewSpaceBlender::fit)): its nearest sample and whether it has left the space the
    /// samples cover (2D: its direction is in no triangle). `None` without viewpoint samples, or
    /// for a camera at the centre or not finite.
    pub fn view_space_fit(&self, camera: &Camera) -> Option<ViewSpaceFit> {
        self.view_space.fit(camera.position.as_dvec3())
    }

    /// Per lens object (TraceScene order), its name and the axis-aligned bounds `(min, max)` of
    /// all its scene objects' meshes, metres: where a viewer stops a camera short of a lens
    /// object. A lens object none of whose meshes has a vertex has no bounds and is left out.
    pub fn lens_bounds(&self) -> Vec<(String, Vec3, Vec3)> {
        self.trace
            .lenses
            .iter()
            .filter_map(|lens| {
                let (lo, hi) = lens
                    .objects
                    .iter()
                    .filter_map(|&object| self.scene.objects.get(object)?.mesh.bounds())
                    .reduce(|(lo, hi), (a, b)| (lo.min(a), hi.max(b)))?;
                Some((lens.name.clone(), lo, hi))
            })
            .collect()
    }

    /// The viewpoint samples (indices into [`HybridScene::viewpoints`]) a frame seen by
    /// `camera` blends by `blending` and their weights, summing to 1, largest first
    /// ([`ViewSpaceBlender::blend`](crate::hybrid::ViewSpaceBlender::blend): two along a 1D view space, up to three in a 2D one, the
    /// nearest point of the region for a camera outside it).
    /// EMs shared by every viewpoint sample (projected ones) need no blending: one sample,
    /// weight 1, half the compositing work. Sample 0 with weight 1 when there is no sample or
    /// the camera sits at its look-at point.
    pub fn viewpoint_blend(&self, camera: &Camera, blending: ViewpointBlending) -> ViewpointBlend {
        self.placed(camera, blending).0
    }

    /// [`HybridScene::viewpoint_blend`] and whether the camera is outside the view space, with
    /// one point location for the view space's own blending.
    pub(crate) fn placed(
        &self,
        camera: &Camera,
        blending: ViewpointBlending,
    ) -> (ViewpointBlend, bool) {
        let position = camera.position.as_dvec3();
        let view_space = &self.view_space;
        let placed = view_space.place(position);
        let outside = placed.as_ref().is_some_and(|(_, outside)| *outside);
        let blend = match blending {
            ViewpointBlending::ViewSpace => placed.map(|(blend, _)| blend),
            ViewpointBlending::TwoNearest | ViewpointBlending::Nearest => {
                viewpoints::blend(view_space.positions(), view_space.centre(), position)
            }
        };
        let blend = blend.unwrap_or(ViewpointBlend {
            samples: vec![(0, 1.0)],
        });
        let blend = if self.lenses.iter().all(|l| l.maps.len() == 1)
            || blending == ViewpointBlending::Nearest
        {
            ViewpointBlend {
                samples: vec![(blend.samples[0].0, 1.0)],
            }
        } else {
            blend
        };
        (blend, outside)
    }

    /// Draws the glossy objects from the radiance-map bake at `dir` (made from this scene, every
    /// sample complete; [`crate::rsibr::bake::read_maps`]) by `reconstruction`; returns its
    /// manifest.
    pub fn use_radiance_bake(
        &mut self,
        dir: &std::path::Path,
        reconstruction: crate::rsibr::Reconstruction,
    ) -> Result<crate::rsibr::bake::RadianceManifest, crate::layers::bake::BakeError> {
        let (manifest, views, maps) = crate::rsibr::bake::read_maps(dir, self.scene())?;
        self.use_radiance_maps(views, maps, reconstruction);
        Ok(manifest)
    }

    /// Draws the glossy objects `maps` holds (made at `views`' samples) by reflection-space IBR
    /// from now on, no longer as light-mapped environment meshes.
    pub fn use_radiance_maps(
        &mut self,
        views: crate::rsibr::GlossyViews,
        maps: Vec<crate::rsibr::GlossyMaps>,
        reconstruction: crate::rsibr::Reconstruction,
    ) {
        // The environment meshes are the objects of no lens object, in scene order: put back
        // those earlier maps replaced, then take out those these maps replace.
        let (scene, trace) = (self.scene(), self.trace());
        let earlier = self.glossy();
        let mut environment: Vec<(usize, Arc<EnvironmentMesh>)> = (0..scene.objects.len())
            .filter(|&o| trace.object_lens.get(o).is_some_and(|l| l.is_none()))
            .filter(|o| {
                !earlier.is_some_and(|g| g.light_mapped.iter().any(|(object, _)| object == o))
            })
            .zip(self.environment().iter().cloned())
            .collect();
        if let Some(earlier) = earlier {
            environment.extend(earlier.light_mapped.iter().cloned());
            environment.sort_by_key(|(object, _)| *object);
        }
        let glossy: Vec<usize> = maps.iter().map(|m| m.object.object).collect();
        let (light_mapped, kept): (Vec<_>, Vec<_>) = environment
            .into_iter()
            .partition(|(object, _)| glossy.contains(object));
        // Maps of an object this scene does not have are left out.
        let objects = maps
            .into_iter()
            .filter_map(|maps| {
                let mesh = &scene.objects.get(maps.object.object)?.mesh;
                let mesh = Arc::new(crate::render::GlossyMesh {
                    positions: mesh.positions.clone(),
                    normals: mesh.normals.clone(),
                    triangles: mesh.triangles.clone(),
                });
                Some((mesh, maps))
            })
            .collect();
        let glossy = GlossyScene {
            views,
            objects,
            reconstruction,
            light_mapped,
        };
        self.set_glossy(
            Some(glossy),
            kept.into_iter().map(|(_, mesh)| mesh).collect(),
        );
    }

    /// Moves the viewpoint samples to `positions` (one per sample of the layered EMs, same
    /// order), triangulated again when the scene's view space is 2D.
    pub fn set_viewpoints(&mut self, positions: Vec<DVec3>) {
        self.view_space = ViewSpaceBlender::new(
            positions,
            self.view_space.centre(),
            self.scene.view_space.is_surface(),
        );
        self.changed();
    }

    /// These layered EMs as a bake: projected EMs become a bake with one viewpoint sample. The
    /// bake carries this scene's identity ([`Provenance`]), so a scene other than this one
    /// refuses it, even one whose lens objects have the same names.
    pub fn to_bake(&self) -> Bake {
        let shared = self.lenses.iter().all(|l| l.maps.len() == 1);
        let samples = if shared {
            vec![0]
        } else {
            (0..self.viewpoints().len()).collect()
        };
        // What shaped the maps: their origins, shells and sizes (the maps themselves are in the
        // bake).
        let mut shaped_by = Encoder::new("maps written from a hybrid scene");
        shaped_by.tag(self.lenses.len());
        for lens in &self.lenses {
            let size = lens.maps.first().and_then(|m| m.first()).map(|c| c.size);
            shaped_by
                .value(&lens.em_origins)
                .value(&lens.shells)
                .value(&size);
        }
        let provenance = Provenance::new(self.scene.content_hash(), shaped_by.finish(), samples);
        Bake {
            scene: self.scene.name.clone(),
            created_by: default_created_by(),
            viewpoints: if shared {
                vec![
                    self.viewpoints()
                        .first()
                        .copied()
                        .unwrap_or(DVec3::Z)
                        .as_vec3(),
                ]
            } else {
                self.viewpoints().iter().map(|p| p.as_vec3()).collect()
            },
            lenses: self
                .lenses
                .iter()
                .zip(&self.trace.lenses)
                .map(|(layers, lens)| BakedLens {
                    name: lens.name.clone(),
                    em_origins: layers.em_origins.clone(),
                    shells: layers.shells.clone(),
                    maps: layers.maps.clone(),
                    layering: layers.layering,
                })
                .collect(),
            provenance: Some(provenance),
        }
    }

    /// Which faces of each lens object (TraceScene order) are traced and drawn: both when any of
    /// its meshes is open ([`TriangleMesh::is_closed`] says no), because the camera can then see
    /// the inside of the surface (the Newell teapot between lid and rim), whose back faces the
    /// reference tracer shades; front faces only for closed meshes, whose back faces are hidden
    /// from any camera outside them, so they cost nothing.
    pub fn lens_faces(scene: &Scene, trace: &TraceScene) -> Vec<LensFaces> {
        trace
            .lenses
            .iter()
            .map(|lens| {
                let open = lens.objects.iter().any(|&object| {
                    scene
                        .objects
                        .get(object)
                        .is_some_and(|o| !o.mesh.is_closed())
                });
                if open {
                    LensFaces::Both
                } else {
                    LensFaces::Front
                }
            })
            .collect()
    }

    /// The opaque environment for the GPU: each environment object with its light map (see
    /// [`crate::lightmap`]: the ray-traced radiance leaving its surface, texture and shadows
    /// included, view independent, so made once per scene), drawn white × the map. Each chart's
    /// texel density follows its distance to the scene's nearest viewpoint
    /// ([`Viewers::of_scene`]). Objects in scene order; also returns what the maps cost.
    pub fn light_mapped_environment(
        scene: &Scene,
        trace: &TraceScene,
        options: &LightMapOptions,
    ) -> Result<(Vec<Arc<EnvironmentMesh>>, LightMapStats), HybridError> {
        let start = Instant::now();
        let objects: Vec<usize> = (0..scene.objects.len())
            .filter(|&object| trace.object_lens.get(object).is_some_and(|l| l.is_none()))
            .collect();
        let meshes: Vec<&TriangleMesh> = objects.iter().map(|&o| &scene.objects[o].mesh).collect();
        let light_map_error = |object: usize, error| HybridError::LightMap {
            object: scene.objects[object].name.clone(),
            error,
        };
        let atlases = plan_atlases(&meshes, &Viewers::of_scene(scene), options).map_err(
            |error| match error {
                PlanError::Mesh { mesh, error } => light_map_error(objects[mesh], error),
                budget => HybridError::LightMapBudget(budget),
            },
        )?;
        let mut stats = LightMapStats::default();
        let mut environment = Vec::new();
        for ((&object, mesh), atlas) in objects.iter().zip(meshes).zip(&atlases) {
            let (mesh, object_stats) =
                build_light_mapped_mesh(trace, mesh, object, atlas, options.supersampling)
                    .map_err(|error| light_map_error(object, error))?;
            stats += object_stats;
            environment.push(Arc::new(EnvironmentMesh {
                colours: vec![Vec3::ONE; mesh.positions.len()],
                positions: mesh.positions,
                triangles: mesh.triangles,
                light_map: Some(MeshLightMap {
                    uvs: mesh.uvs,
                    map: mesh.map,
                }),
            }));
        }
        // Objects were mapped one after another: the sum of their times is the wall time.
        stats.ms = start.elapsed().as_secs_f64() * 1e3;
        Ok((environment, stats))
    }
}

/// A bake that names its scene's identity must name this scene's content.
fn check_provenance(scene: &Scene, bake: &Bake) -> Result<(), BakeIdentityError> {
    match &bake.provenance {
        Some(provenance) if !provenance.is_current() => {
            Err(BakeIdentityError::OtherIdentityVersion {
                bake: None,
                version: provenance.identity_version,
            })
        }
        Some(provenance) if provenance.scene_hash != scene.content_hash() => {
            Err(BakeIdentityError::OtherScene {
                bake: None,
                baked_scene: bake.scene.clone(),
                scene: scene.name.clone(),
            })
        }
        _ => Ok(()),
    }
}

/// Projected layered EMs on `shells` (one entry per lens object: its EM origin and shells),
/// and the rays the projection cast.
fn projected_layers(
    scene: &Scene,
    trace: &TraceScene,
    shells: Vec<(DVec3, Vec<LayerShell>)>,
    options: &ProjectedOptions,
) -> Result<(Vec<LensLayers>, u64), HybridError> {
    if shells.len() != trace.lenses.len() {
        return Err(HybridError::BakeMismatch(format!(
            "{} lens objects given shells, but scene \"{}\" has {}; give shells for every lens object",
            shells.len(),
            scene.name,
            trace.lenses.len()
        )));
    }
    let mut rays = 0;
    let lenses = shells
        .into_iter()
        .enumerate()
        .map(|(lens, (origin, shells))| {
            let (maps, cast) = project_layers(trace, lens, origin, &shells, options);
            rays += cast;
            LensLayers {
                em_origins: vec![origin; shells.len()],
                layering: Layering::Distance,
                shells,
                maps: vec![maps.into_iter().map(Arc::new).collect()],
            }
        })
        .collect();
    Ok((lenses, rays))
}

/// A bake's layered EMs for each lens object of `trace`, matched by name; each must have one
/// EM origin and one map per shell at every viewpoint sample.
fn baked_layers(
    scene: &Scene,
    trace: &TraceScene,
    baked: Vec<BakedLens>,
) -> Result<Vec<LensLayers>, HybridError> {
    let mut baked: Vec<Option<BakedLens>> = baked.into_iter().map(Some).collect();
    let mut lenses = Vec::new();
    for lens in &trace.lenses {
        let Some(found) = baked
            .iter_mut()
            .find(|b| b.as_ref().is_some_and(|b| b.name == lens.name))
            .and_then(Option::take)
        else {
            return Err(HybridError::BakeMismatch(format!(
                "manifest.json: lenses: no entry for lens object \"{}\" of scene \"{}\"; bake this scene again",
                lens.name, scene.name
            )));
        };
        let layers = found.shells.len();
        if found.em_origins.len() != layers || found.maps.iter().any(|v| v.len() != layers) {
            return Err(HybridError::BakeMismatch(format!(
                "lens object \"{}\": {layers} shells but {} EM origins and {:?} maps per viewpoint; give one origin and one map per shell",
                lens.name,
                found.em_origins.len(),
                found.maps.iter().map(Vec::len).collect::<Vec<_>>()
            )));
        }
        lenses.push(LensLayers {
            layering: found.layering,
            em_origins: found.em_origins,
            shells: found.shells,
            maps: found.maps,
        });
    }
    Ok(lenses)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A front end that names options in capitals and bakes with a `BAKE(scene)` call.
    struct Capitals;

    impl OptionWords for Capitals {
        fn option(&self, name: crate::options::OptionName) -> String {
            name.field.to_uppercase()
        }

        fn switch_on(&self, name: crate::options::OptionName) -> String {
            format!("turn on {}", self.option(name))
        }

        fn bake_command(&self, scene: Option<&str>) -> Option<String> {
            Some(format!("BAKE({})", scene.unwrap_or("?")))
        }
    }

    #[test]
    fn bake_identity_errors_name_options_only_through_the_front_ends_words() {
        let other = BakeIdentityError::OtherScene {
            bake: Some(PathBuf::from("out/bake")),
            baked_scene: "glass-sphere".into(),
            scene: "mirror-teapot".into(),
        };
        let said = "out/bake/manifest.json: provenance.scene_hash: the bake was made from scene \"glass-sphere\" with other content than scene \"mirror-teapot\"; bake this scene";
        assert_eq!(
            other.to_string(),
            format!("{said} or pass the scene it was made from")
        );
        assert_eq!(
            other.worded(&Capitals),
            format!("{said} (BAKE(mirror-teapot)) or pass the scene it was made from")
        );
        let unnamed = BakeIdentityError::Unidentified {
            bake: PathBuf::from("out/bake"),
        };
        let said = "manifest.json: provenance: the bake does not say which scene it was made from; bake this scene";
        assert_eq!(
            unnamed.to_string(),
            format!("{said}, or set `EmSource.AnyBake` to use it anyway")
        );
        assert_eq!(
            unnamed.worded(&Capitals),
            format!("{said} (BAKE(?)), or turn on ANYBAKE to use it anyway")
        );
    }
}
