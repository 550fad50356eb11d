//! Whether a bake directory already holds what a caller needs: the samples of a scene baked with
//! given options. The bake's provenance (the scene's content hash, the options hash and the
//! samples, written by [`super::bake`]) is the key; the maps are not read. A front end that keeps
//! a bake as a cache (the demo, a viewer, a C host) asks [`check`] and bakes only when told why
//! not.

use std::path::Path;

use lensmap::{
    layers::{BakeError, Manifest},
    scene::Scene,
};

use super::options::BakeOptions;

/// Why a bake directory cannot be reused for a scene, options and samples.
#[derive(Debug, thiserror::Error)]
pub enum NotReusable {
    /// There is no readable bake there (no directory, no manifest, a damaged one).
    #[error(transparent)]
    Unreadable(#[from] BakeError),
    /// The bake has no provenance (written from projected EMs, not baked), so what it was made
    /// from is unknown.
    #[error("the bake has no provenance, so what it was made from is unknown")]
    NoProvenance,
    /// The bake names what it was made from in another identity version than this lensmap's
    /// (0: before lensmap had one), so it cannot be compared.
    #[error("the bake's identity is of version {0}, not this lensmap's")]
    OtherIdentityVersion(u32),
    /// The bake was made from another scene (or another version of it).
    #[error("the bake was made from another scene")]
    OtherScene,
    /// The bake was made with other bake options.
    #[error("the bake was made with other bake options")]
    OtherOptions,
    /// The bake lacks some of the samples.
    #[error("the bake lacks samples {0:?}")]
    MissingSamples(Vec<usize>),
}

/// Whether the bake at `dir` holds `samples` (view-space indices) of `scene` baked with
/// `options`, as its manifest's provenance says: `Ok` with its manifest, else why not. Reads only
/// the manifest.
pub fn check(
    dir: &Path,
    scene: &Scene,
    options: &BakeOptions,
    samples: &[usize],
) -> Result<Manifest, NotReusable> {
    let manifest = Manifest::read(dir)?;
    let provenance = manifest
        .provenance
        .as_ref()
        .ok_or(NotReusable::NoProvenance)?;
    if !provenance.is_current() {
        return Err(NotReusable::OtherIdentityVersion(
            provenance.identity_version,
        ));
    }
    if provenance.scene_hash != scene.content_hash() {
        return Err(NotReusable::OtherScene);
    }
    if provenance.options_hash != options.hash() {
        return Err(NotReusable::OtherOptions);
    }
    let missing: Vec<usize> = samples
        .iter()
        .copied()
        .filter(|s| !provenance.samples.contains(s))
        .collect();
    if !missing.is_empty() {
        return Err(NotReusable::MissingSamples(missing));
    }
    Ok(manifest)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lensmap::layers::Provenance;

    #[test]
    fn a_bake_is_reused_only_for_its_scene_options_and_samples() {
        let scene = Scene::load_named("glass-sphere").unwrap();
        let options = BakeOptions::default();
        let dir = std::env::temp_dir().join(format!("lensmap-reuse-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        assert!(matches!(
            check(&dir, &scene, &options, &[0]),
            Err(NotReusable::Unreadable(_))
        ));
        let write = |provenance: Option<Provenance>| {
            let mut bake = lensmap::layers::Bake {
                scene: scene.name.clone(),
                created_by: "test".into(),
                viewpoints: vec![glam::Vec3::ZERO, glam::Vec3::X],
                lenses: vec![lensmap::layers::BakedLens {
                    name: "ball".into(),
                    em_origins: vec![glam::DVec3::ZERO],
                    shells: vec![lensmap::layers::LayerShell::Sphere {
                        centre: glam::DVec3::ZERO,
                        radius: 5.0,
                    }],
                    maps: Vec::new(),
                    layering: lensmap::layers::Layering::Distance,
                }],
                provenance,
            };
            let map = std::sync::Arc::new(lensmap::cubemap::CubeMap::uniform(1, [0.0; 4]));
            bake.lenses[0].maps = vec![vec![map.clone()], vec![map]];
            bake.write(&dir).unwrap();
        };
        let provenance = |scene_hash: String, options_hash: String| {
            Provenance::new(scene_hash, options_hash, vec![1, 3])
        };
        write(None);
        assert!(matches!(
            check(&dir, &scene, &options, &[1]),
            Err(NotReusable::NoProvenance)
        ));
        // A bake whose hashes were computed by an older identity encoding.
        let mut older = provenance(scene.content_hash(), options.hash());
        older.identity_version = 0;
        write(Some(older));
        assert!(matches!(
            check(&dir, &scene, &options, &[1]),
            Err(NotReusable::OtherIdentityVersion(0))
        ));
        write(Some(provenance("other".into(), options.hash())));
        assert!(matches!(
            check(&dir, &scene, &options, &[1]),
            Err(NotReusable::OtherScene)
        ));
        write(Some(provenance(scene.content_hash(), "other".into())));
        assert!(matches!(
            check(&dir, &scene, &options, &[1]),
            Err(NotReusable::OtherOptions)
        ));
        write(Some(provenance(scene.content_hash(), options.hash())));
        assert!(check(&dir, &scene, &options, &[3, 1]).is_ok());
        match check(&dir, &scene, &options, &[0, 1, 2]) {
            Err(NotReusable::MissingSamples(missing)) => assert_eq!(missing, [0, 2]),
            other => panic!("{other:?}"),
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
