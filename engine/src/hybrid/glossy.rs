//! Glossy objects in hybrid frames: drawn by the glossy pass from their radiance maps
//! (reflection-space IBR, [`crate::rsibr`]) instead of from their light maps, once a scene is
//! given maps ([`HybridScene::use_radiance_maps`]).

use std::sync::Arc;

use glam::DVec3;

use super::HybridScene;
use crate::render::{GlossyDraw, GlossyMesh, GlossySlot};
use crate::rsibr::{GlossyMaps, GlossyViews, Reconstruction};

/// The glossy objects a hybrid scene draws by reflection-space IBR.
pub struct GlossyScene {
    /// The view samples the maps were made at.
    pub views: GlossyViews,
    /// Per glossy object, its mesh for the GPU and its maps.
    pub objects: Vec<(Arc<GlossyMesh>, GlossyMaps)>,
    /// How frames reconstruct the maps (the paper's: [`Reconstruction::Warped`]).
    pub reconstruction: Reconstruction,
}

impl GlossyScene {
    /// The draws of a frame seen from `eye`; with the maps each reads, counted.
    pub fn draws(&self, eye: DVec3) -> (Vec<GlossyDraw>, usize) {
        let mut maps_read = 0;
        let draws = self
            .objects
            .iter()
            .filter_map(|(mesh, maps)| {
                let object = &maps.object;
                let slots = self.views.slots(eye - object.centre, self.reconstruction)?;
                let slots: Vec<GlossySlot> = slots
                    .into_iter()
                    .map(|slot| GlossySlot {
                        weight: slot.weight as f32,
                        rotation: slot.rotation.as_mat3(),
                        maps: maps.maps[slot.sample].clone(),
                    })
                    .collect();
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
    /// Draws the glossy objects `maps` holds (made at `views`' samples) by reflection-space IBR
    /// from now on, no longer as light-mapped environment meshes.
    pub fn use_radiance_maps(
        &mut self,
        views: GlossyViews,
        maps: Vec<GlossyMaps>,
        reconstruction: Reconstruction,
    ) {
        // The environment meshes are the objects of no lens object, in scene order.
        let environment_objects: Vec<usize> = (0..self.scene.objects.len())
            .filter(|&o| self.trace.object_lens.get(o).is_some_and(|l| l.is_none()))
            .collect();
        let glossy: Vec<usize> = maps.iter().map(|m| m.object.object).collect();
        let environment = std::mem::take(&mut self.environment);
        self.environment = environment
            .into_iter()
            .zip(&environment_objects)
            .filter(|(_, object)| !glossy.contains(object))
            .map(|(mesh, _)| mesh)
            .collect();
        let objects = maps
            .into_iter()
            .map(|maps| {
                let mesh = &self.scene.objects[maps.object.object].mesh;
                let mesh = Arc::new(GlossyMesh {
                    positions: mesh.positions.clone(),
                    normals: mesh.normals.clone(),
                    triangles: mesh.triangles.clone(),
                });
                (mesh, maps)
            })
            .collect();
        self.glossy = Some(GlossyScene {
            views,
            objects,
            reconstruction,
        });
        self.cache = Default::default();
    }
}
