//! Glossy objects in hybrid frames: drawn by the glossy pass from their radiance maps
//! (reflection-space IBR, [`crate::rsibr`]) instead of from their light maps, once a scene is
//! given maps ([`super::HybridScene::use_radiance_maps`]).

use std::sync::Arc;

use glam::DVec3;

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
    pub(super) light_mapped: Vec<(usize, Arc<EnvironmentMesh>)>,
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
