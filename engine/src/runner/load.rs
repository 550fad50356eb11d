//! Loading a hybrid scene for the runner: its layered EMs read from a bake directory (whose
//! identity is checked against the scene) or projected from the scene, and its light maps.

use std::path::{Path, PathBuf};

use super::RunError;
use crate::{
    hybrid::{BakeIdentityError, HybridError, HybridScene, HybridSceneOptions, LayeredEms},
    layers::{Bake, projected::ProjectedOptions},
    lightmap::LightMapOptions,
    scene::Scene,
};

/// Where a hybrid scene's layered EMs come from.
#[derive(Clone, Debug, PartialEq)]
pub enum EmSource {
    /// A bake directory written by the baker (or `lensmap render --write-bake`) for this very
    /// scene: its manifest's provenance must name the scene's content hash.
    Bake(PathBuf),
    /// A bake directory used whatever scene it was made for (the front ends' option
    /// `accept_any_bake`): for deliberate reuse, e.g. a hand-made bake or one made before the
    /// scene was edited. Lens objects are still matched by name and every map is still
    /// validated.
    AnyBake(PathBuf),
    /// Projected from the scene onto the layer shells its file names.
    Projected(ProjectedOptions),
}

/// How [`load_hybrid_scene`] loads a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// Where the layered EMs come from.
    pub ems: EmSource,
    /// How the opaque environment's light maps are made.
    pub light_maps: LightMapOptions,
}

impl Default for LoadOptions {
    /// EMs projected with the default options; default light maps.
    fn default() -> Self {
        LoadOptions {
            ems: EmSource::Projected(ProjectedOptions::default()),
            light_maps: LightMapOptions::default(),
        }
    }
}

impl From<EmSource> for LoadOptions {
    /// These EMs with default light maps.
    fn from(ems: EmSource) -> Self {
        LoadOptions {
            ems,
            ..LoadOptions::default()
        }
    }
}

/// A bake as [`EmSource`] asks, read from `dir`: one that says nothing of the scene it was made
/// for is refused unless any bake is accepted, and an accepted one loses its provenance, so
/// that no scene check applies to it.
fn checked_identity(
    mut bake: Bake,
    dir: &Path,
    accept_any: bool,
) -> Result<Bake, BakeIdentityError> {
    if accept_any {
        bake.provenance = None;
    } else if bake.provenance.is_none() {
        return Err(BakeIdentityError::Unidentified {
            bake: dir.to_path_buf(),
        });
    }
    Ok(bake)
}

/// `error` of the bake read from `dir`, which names `manifest.json`: said with the directory.
fn in_directory(error: HybridError, dir: &Path) -> HybridError {
    match error {
        HybridError::BakeMismatch(message) => {
            HybridError::BakeMismatch(format!("{}/{message}", dir.display()))
        }
        HybridError::Identity(BakeIdentityError::OtherScene {
            bake: None,
            baked_scene,
            scene,
        }) => HybridError::Identity(BakeIdentityError::OtherScene {
            bake: Some(dir.to_path_buf()),
            baked_scene,
            scene,
        }),
        HybridError::Identity(BakeIdentityError::OtherIdentityVersion {
            bake: None,
            version,
        }) => HybridError::Identity(BakeIdentityError::OtherIdentityVersion {
            bake: Some(dir.to_path_buf()),
            version,
        }),
        other => other,
    }
}

/// Loads `scene` with the layered EMs and light maps `options` asks for; returns the hybrid
/// scene and the rays cast to project EMs (0 for a bake).
pub fn load_hybrid_scene(
    scene: Scene,
    options: &LoadOptions,
) -> Result<(HybridScene, u64), RunError> {
    let light_maps = options.light_maps;
    light_maps.validate()?;
    Ok(match &options.ems {
        EmSource::Bake(dir) | EmSource::AnyBake(dir) => {
            let accept_any = matches!(options.ems, EmSource::AnyBake(_));
            let bake =
                checked_identity(Bake::read(dir)?, dir, accept_any).map_err(HybridError::from)?;
            let options = HybridSceneOptions {
                ems: LayeredEms::Baked(bake),
                light_maps,
            };
            HybridScene::new(scene, options).map_err(|error| in_directory(error, dir))?
        }
        EmSource::Projected(projected) => {
            projected.validate()?;
            let options = HybridSceneOptions {
                ems: LayeredEms::Projected(*projected),
                light_maps,
            };
            HybridScene::new(scene, options)?
        }
    })
}
