//! Glossy objects in hybrid frames: drawn by the glossy pass from their radiance maps
//! (reflection-space IBR, [`crate::rsibr`]) instead of from their light maps, once a scene is
//! given maps ([`HybridScene::use_radiance_maps`]).

use std::sync::Arc;

use glam::DVec3;

use super::HybridScene;
use crate::render::{EnvironmentMesh, GlossyDraw, GlossyMesh, GlossySlot};
use crate::rsibr::{GlossyMaps, GlossyViews, Reconstruction};

/// The glossy objects a hybrid scene draws by reflection-space IBR.
pub struct GlossyScene {
    /// The view samples the maps were made at.
    pub views: GlossyViews,
    /// Per glossy object, its mesh for the GPU and its maps.
    pub objects: Vec<(Arc<GlossyMesh>, GlossyMaps)>,
    /// How frames reconstruct the maps (the paper's: [`Reconstruction::Warped`]).
    pub reconstruction: Reconstruction,
    /// The light-mapped environment meshes these objects replace, with their scene object:
    /// put back when other maps replace these.
    light_mapped: Vec<(usize, Arc<EnvironmentMesh>)>,
}

/// What identifies the glossy objects' part of a frame: the reconstruction and, per object, the
/// address of its mesh and of every map.
pub(super) type GlossyKey = (Reconstruction, Vec<(usize, Vec<Vec<usize>>)>);

impl GlossyScene {
    /// The frame cache's key of these objects.
    pub(super) fn key(&self) -> GlossyKey {
        let objects = self
            .objects
            .iter()
            .map(|(mesh, maps)| {
                let addresses = maps
                    .maps
                    .iter()
                    .map(|lobes| lobes.iter().map(|m| Arc::as_ptr(m) as usize).collect())
                    .collect();
                (Arc::as_ptr(mesh) as usize, addresses)
            })
            .collect();
        (self.reconstruction, objects)
    }

    /// The draws of a frame seen from `eye`; with the maps each reads, counted.
    pub fn draws(&self, eye: DVec3) -> (Vec<GlossyDraw>, usize) {
        let mut maps_read = 0;
        let draws = self
            .objects
            .iter()
            .filter_map(|(mesh, maps)| {
                let object = &maps.object;
                let slots = self.views.slots(eye - object.centre, self.reconstruction)?;
                // Maps missing a sample (not from a complete bake) leave the object undrawn.
                let slots: Vec<GlossySlot> = slots
                    .into_iter()
                    .map(|slot| {
                        Some(GlossySlot {
                            weight: slot.weight as f32,
                            rotation: slot.rotation.as_mat3(),
                            maps: maps.maps.get(slot.sample)?.clone(),
                        })
                    })
                    .collect::<Option<_>>()?;
                maps_read += slots.len() * object.lobes.len();
                Some(GlossyDraw {
                    name: object.name.clone(),
                    mesh: mesh.clone(),
                    brdf: object.brdf,
                    lobes: object.lobes.clone(),
                    slots,
                    eye: eye.as_vec3(),
                })
            })
            .collect();
        (draws, maps_read)
    }
}

impl HybridScene {
    /// Draws the glossy objects from the radiance-map bake at `dir` (made from this scene, every
    /// sample complete; [`crate::rsibr::bake::read_maps`]) by `reconstruction`; returns its
    /// manifest.
    pub fn use_radiance_bake(
        &mut self,
        dir: &std::path::Path,
        reconstruction: Reconstruction,
    ) -> Result<crate::rsibr::bake::RadianceManifest, crate::layers::bake::BakeError> {
        let (manifest, views, maps) = crate::rsibr::bake::read_maps(dir, &self.scene)?;
        self.use_radiance_maps(views, maps, reconstruction);
        Ok(manifest)
    }

    /// Draws the glossy objects `maps` holds (made at `views`' samples) by reflection-space IBR
    /// from now on, no longer as light-mapped environment meshes.
    pub fn use_radiance_maps(
        &mut self,
        views: GlossyViews,
        maps: Vec<GlossyMaps>,
        reconstruction: Reconstruction,
    ) {
        // The environment meshes are the objects of no lens object, in scene order: put back
        // those earlier maps replaced, then take out those these maps replace.
        let mut environment: Vec<(usize, Arc<EnvironmentMesh>)> = (0..self.scene.objects.len())
            .filter(|&o| self.trace.object_lens.get(o).is_some_and(|l| l.is_none()))
            .filter(|o| {
                !self
                    .glossy
                    .as_ref()
                    .is_some_and(|g| g.light_mapped.iter().any(|(object, _)| object == o))
            })
            .zip(std::mem::take(&mut self.environment))
            .collect();
        if let Some(earlier) = self.glossy.take() {
            environment.extend(earlier.light_mapped);
            environment.sort_by_key(|(object, _)| *object);
        }
        let glossy: Vec<usize> = maps.iter().map(|m| m.object.object).collect();
        let (light_mapped, kept): (Vec<_>, Vec<_>) = environment
            .into_iter()
            .partition(|(object, _)| glossy.contains(object));
        self.environment = kept.into_iter().map(|(_, mesh)| mesh).collect();
        // Maps of an object this scene does not have are left out.
        let objects = maps
            .into_iter()
            .filter_map(|maps| {
                let mesh = &self.scene.objects.get(maps.object.object)?.mesh;
                let mesh = Arc::new(GlossyMesh {
                    positions: mesh.positions.clone(),
                    normals: mesh.normals.clone(),
                    triangles: mesh.triangles.clone(),
                });
                Some((mesh, maps))
            })
            .collect();
        self.glossy = Some(GlossyScene {
            views,
            objects,
            reconstruction,
            light_mapped,
        });
        self.cache = Default::default();
    }
}
