//! Shards joined into one bake ([`merge`]): bakes of disjoint samples made with one scene and
//! one set of options, as the jobs of a scheduler's array make them.

use std::{
    collections::{BTreeMap, HashMap},
    path::{Path, PathBuf},
};

use glam::DVec3;
use lensmap::{
    identity::IDENTITY_VERSION,
    layers::{
        LayerShell, Manifest, MapReader, Provenance, Staging,
        bake::{BakedOn, MANIFEST_FILE_NAME},
    },
    options::{LibraryWords, OptionWords, Worded},
};

use super::failure::BakeFailure;
use super::names;

/// Why shards cannot be merged. The shard list is option `merge`; a bake for a shard is made by
/// call `bake` with option `shard`.
#[derive(Debug, thiserror::Error)]
#[error("{}", self.worded(&LibraryWords))]
pub enum MergeError {
    /// Fewer than two bakes to merge.
    TooFew,
    /// A bake without provenance: what it was made from is unknown.
    NoProvenance {
        /// Its manifest.
        manifest: PathBuf,
    },
    /// A bake whose provenance is of another identity version than this lensmap's: what it was
    /// made from cannot be compared.
    OtherIdentityVersion {
        /// Its manifest.
        manifest: PathBuf,
        /// The version it names.
        version: u32,
    },
    /// Two bakes made from other scenes or with other options.
    NotShards {
        /// The first bake.
        first: PathBuf,
        /// The one that differs.
        other: PathBuf,
        /// What differs: `the scenes`, `the bake options`, `the lens objects or their shells`.
        what: &'static str,
    },
    /// Two bakes that hold the same sample.
    SameSample {
        /// The first bake holding it.
        first: PathBuf,
        /// The other.
        other: PathBuf,
        /// The view-space index.
        sample: usize,
    },
}

impl Worded for MergeError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        match self {
            MergeError::TooFew => format!(
                "{} needs at least two bake directories, e.g. {}",
                words.option(names::MERGE),
                words.setting(names::MERGE, "out/shard-1 out/shard-2")
            ),
            MergeError::NoProvenance { manifest } => format!(
                "{}: has no provenance (not written by {}), so it cannot be merged; bake it with {} {}",
                manifest.display(),
                words.call("bake"),
                words.call("bake"),
                words.option(names::SHARD)
            ),
            MergeError::OtherIdentityVersion { manifest, version } => format!(
                "{}: provenance.identity_version: the shard names its scene and options in identity version {version}, this lensmap in version {IDENTITY_VERSION}, so it cannot be merged; bake it again with {} {}",
                manifest.display(),
                words.call("bake"),
                words.option(names::SHARD)
            ),
            MergeError::NotShards { first, other, what } => format!(
                "{} and {}: {what} differ, so these are not shards of one bake; merge only shards made with the same scene and options",
                first.display(),
                other.display()
            ),
            MergeError::SameSample {
                first,
                other,
                sample,
            } => format!(
                "{} and {} both hold sample {sample}; merge shards with disjoint samples",
                first.display(),
                other.display()
            ),
        }
    }
}

/// Joins the bakes in `shards` (each a shard: a bake of [`super::shard_samples`]) into one bake at `out`: they
/// must come from the same scene and options (same provenance hashes, lens objects, shells and
/// EM size) and hold disjoint samples. Every map is read and checked before anything is written.
pub fn merge(shards: &[PathBuf], out: &Path) -> Result<Manifest, BakeFailure> {
    if shards.len() < 2 {
        return Err(MergeError::TooFew.into());
    }
    let mut manifests = Vec::new();
    for dir in shards {
        let manifest = Manifest::read(dir)?;
        let Some(provenance) = manifest.provenance.clone() else {
            return Err(MergeError::NoProvenance {
                manifest: dir.join(MANIFEST_FILE_NAME),
            }
            .into());
        };
        if !provenance.is_current() {
            return Err(MergeError::OtherIdentityVersion {
                manifest: dir.join(MANIFEST_FILE_NAME),
                version: provenance.identity_version,
            }
            .into());
        }
        // Every map readable and valid.
        lensmap::layers::Bake::read(dir)?;
        manifests.push((dir, manifest, provenance));
    }
    let (first_dir, first, first_provenance) = &manifests[0];
    let mut by_sample: BTreeMap<usize, (usize, usize)> = BTreeMap::new();
    for (index, (dir, manifest, provenance)) in manifests.iter().enumerate() {
        let differs = |what: &'static str| {
            Err(MergeError::NotShards {
                first: first_dir.to_path_buf(),
                other: dir.to_path_buf(),
                what,
            }
            .into())
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
                return Err(MergeError::SameSample {
                    first: manifests[other].0.to_path_buf(),
                    other: dir.to_path_buf(),
                    sample,
                }
                .into());
            }
        }
    }
    let staging = Staging::open(out)?;
    staging.clear()?;
    let mut merged = Manifest {
        viewpoints: Vec::new(),
        provenance: Some(Provenance {
            samples: Vec::new(),
            // Every shard's record of who baked its samples, in sample order (as one bake of
            // them all records it), whatever the order of the shards.
            baked_on: BakedOn::group(
                manifests
                    .iter()
                    .flat_map(|(_, _, provenance)| {
                        provenance.baked_on.iter().flat_map(|group| {
                            group
                                .samples
                                .iter()
                                .map(|&sample| (sample, Some(group.device.clone())))
                        })
                    })
                    .collect::<BTreeMap<_, _>>(),
            ),
            ..first_provenance.clone()
        }),
        // Compressed shards are merged as EXR maps: compress the merged bake again.
        compression: None,
        ..first.clone()
    };
    let mut readers: Vec<MapReader<'_>> = manifests
        .iter()
        .map(|(dir, manifest, _)| MapReader::new(dir, manifest))
        .collect();
    for lens in &mut merged.lenses {
        for layer in &mut lens.layers {
            layer.maps.clear();
        }
    }
    for (&sample, &(index, position)) in &by_sample {
        let (_, manifest, _) = &manifests[index];
        merged.viewpoints.push(manifest.viewpoints[position]);
        if let Some(p) = merged.provenance.as_mut() {
            p.samples.push(sample);
        }
        let mut copied: HashMap<&String, String> = HashMap::new();
        for (lens, source) in merged.lenses.iter_mut().zip(&manifest.lenses) {
            for (layer, source) in lens.layers.iter_mut().zip(&source.layers) {
                let name = &source.maps[position];
                // A shared layer's file once.
                let staged = match copied.get(name) {
                    Some(staged) => staged.clone(),
                    None => {
                        let staged = staging.copy_map(&mut readers[index], name)?;
                        copied.insert(name, staged.clone());
                        staged
                    }
                };
                layer.maps.push(staged);
            }
        }
    }
    staging.commit(&merged)?;
    Ok(merged)
}
