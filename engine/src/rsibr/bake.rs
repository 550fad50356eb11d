//! A radiance-map bake: the glossy objects' radiance maps at every view sample, written by
//! `lensmap bake --radiance-maps` with the layered bake's guarantees.
//!
//! ```text
//! DIR/
//!   radiance.json                          the RadianceManifest, pretty-printed JSON
//!   glossy3-teapot.v000.specular.exr       one cube map per (object, view sample, lobe)
//!   …
//! ```
//!
//! - **Units of work** are view samples: each is computed for every glossy object and staged in
//!   `.NAME.radiance-baking` beside the bake, its maps first and its record
//!   (`sample-NNN.json`) last, each file written atomically; a record present means the sample is
//!   complete.
//! - **Resume** keeps the staged samples and those of the bake at `DIR` made from the same scene
//!   and options; other options or another scene start afresh.
//! - **Shards** bake a subset of samples; **merge** joins shards of the same scene and options.
//! - **Commit** writes the manifest (every complete sample) and swaps the staging directory in
//!   for the old bake in one atomic exchange ([`DirectorySwap`]). The writer holds the bake's
//!   lock `.NAME.lock` from opening the staging directory to the commit
//!   ([`crate::atomic::lock::DirectoryLock`]).
//! - Maps are the layered bake's cube-map EXRs ([`crate::layers::bake::exr`]): premultiplied RGBA
//!   f32, every mip level stored, lossless.

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::maps::{GlossyMaps, GlossyObject, MapLobe, RadianceMapOptions, glossy_objects};
use super::views::GlossyViews;
use crate::atomic::{self, DirectorySwap, WhenSwapFails, lock::DirectoryLock};
use crate::gpu::DeviceId;
use crate::identity::{Encoder, IDENTITY_VERSION};
use crate::layers::bake::error::io_error;
use crate::layers::bake::{BakeError, check_cube_map, encode_cube_map_exr, read_cube_map_exr};
use crate::scene::Scene;

/// The manifest format this code writes and reads.
pub const RADIANCE_FORMAT_VERSION: u32 = 1;

/// File name of the manifest inside a radiance-map bake.
pub const RADIANCE_MANIFEST: &str = "radiance.json";

/// Suffix of the staging directory beside the bake.
const STAGING_SUFFIX: &str = ".radiance-baking";

/// `radiance.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RadianceManifest {
    /// Always [`RADIANCE_FORMAT_VERSION`].
    pub format_version: u32,
    /// The scene's name.
    pub scene: String,
    /// What wrote it.
    pub created_by: String,
    /// What it was made from and with.
    pub identity: RadianceIdentity,
    /// Face size, samples per texel, seed and view count.
    pub size: u32,
    /// Directions sampled per texel.
    pub samples_per_texel: u32,
    /// Seed of the samples.
    pub seed: u64,
    /// The view space's sample count (its directions are [`GlossyViews::geodesic`]'s).
    pub views: usize,
    /// The complete samples, increasing, with their records.
    pub samples: Vec<SampleRecord>,
    /// The glossy objects.
    pub objects: Vec<ManifestObject>,
}

/// The identity a bake is resumed, merged and rendered against.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RadianceIdentity {
    /// [`IDENTITY_VERSION`] of the hashes.
    pub identity_version: u32,
    /// The scene's content hash.
    pub scene_hash: String,
    /// Hash of the map options.
    pub options_hash: String,
}

/// One complete view sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SampleRecord {
    /// The sample's index.
    pub sample: usize,
    /// Per object, the largest standard error of a texel's radiance over its lobes' maps.
    pub max_standard_error: Vec<f32>,
    /// Per object, the root mean square of the texels' standard errors where confidence > 0.
    pub rms_standard_error: Vec<f32>,
    /// Rays traced for the sample.
    pub rays: u64,
    /// Wall time, seconds.
    pub seconds: f64,
    /// The machine that computed it, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device: Option<DeviceId>,
}

/// One glossy object in the manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestObject {
    /// The object's index in the scene.
    pub object: usize,
    /// The object's name in the scene.
    pub name: String,
    /// The centre the maps are about, metres.
    pub centre: DVec3,
    /// The sphere the maps' rays start on, metres.
    pub radius: f64,
    /// The lobes, by name, in map order.
    pub lobes: Vec<String>,
}

impl RadianceIdentity {
    /// The identity of maps of `scene` made with `options`.
    pub fn of(scene: &Scene, options: &RadianceMapOptions) -> RadianceIdentity {
        let mut encoder = Encoder::new("radiance map options");
        encoder
            .u64(u64::from(options.size.max(1).next_power_of_two()))
            .u64(u64::from(options.samples))
            .u64(options.seed)
            .tag(options.views)
            .u64(MAP_REVISION);
        RadianceIdentity {
            identity_version: IDENTITY_VERSION,
            scene_hash: scene.content_hash(),
            options_hash: encoder.finish(),
        }
    }
}

/// Raised when the maps' computation changes, so that older bakes are not resumed into newer.
const MAP_REVISION: u64 = 2;

/// The file of `object`'s map of `lobe` at `sample`.
pub fn map_file_name(object: &GlossyObject, sample: usize, lobe: MapLobe) -> String {
    file_name(object.object, &object.name, sample, lobe.name())
}

/// `glossy{object}-{name}.v{sample:03}.{lobe}.exr`, the name reduced to ASCII letters, digits,
/// `-` and `_`.
fn file_name(object: usize, name: &str, sample: usize, lobe: &str) -> String {
    let name = crate::layers::bake::file_name_part(name);
    format!("glossy{object}-{name}.v{sample:03}.{lobe}.exr")
}

fn record_name(sample: usize) -> String {
    format!("sample-{sample:03}.json")
}

fn invalid(path: &Path, field: &str, problem: String, fix: &'static str) -> BakeError {
    BakeError::Invalid {
        path: path.to_owned(),
        field: field.to_owned(),
        problem,
        fix,
    }
}

/// A radiance-map bake being built in its staging directory.
pub struct RadianceStaging {
    swap: DirectorySwap,
    path: PathBuf,
    identity: RadianceIdentity,
    /// Held from opening to the commit: one baker per directory.
    _lock: DirectoryLock,
}

impl RadianceStaging {
    /// Opens the staging directory of bake `dir` for maps of `identity`. Without `resume`, or
    /// when what is staged has another identity, it starts empty; with `resume`, the samples of
    /// the bake already at `dir` with this identity are staged too.
    pub fn open(
        dir: &Path,
        identity: RadianceIdentity,
        resume: bool,
    ) -> Result<RadianceStaging, BakeError> {
        let swap = DirectorySwap::new(dir).ok_or_else(|| {
            invalid(
                dir,
                "the bake directory",
                "has no final name".into(),
                "name the directory itself, e.g. out/radiance",
            )
        })?;
        let lock = DirectoryLock::acquire(dir)?;
        swap.prepare()?;
        let is_ours = dir.join(RADIANCE_MANIFEST).is_file()
            || fs::read_dir(dir).is_ok_and(|mut entries| entries.next().is_none());
        if dir.exists() && !is_ours {
            return Err(invalid(
                dir,
                "the bake directory",
                format!("exists and is not a radiance-map bake (no {RADIANCE_MANIFEST})"),
                "choose another directory or remove it",
            ));
        }
        let path = swap.beside(STAGING_SUFFIX);
        let identity_path = path.join("identity.json");
        let staged_identity = fs::read(&identity_path)
            .ok()
            .and_then(|bytes| serde_json::from_slice::<RadianceIdentity>(&bytes).ok());
        if path.exists() && !(resume && staged_identity.as_ref() == Some(&identity)) {
            fs::remove_dir_all(&path).map_err(io_error(&path, "remove"))?;
        }
        fs::create_dir_all(&path).map_err(io_error(&path, "create"))?;
        let json = serde_json::to_vec_pretty(&identity).expect("plain data serializes");
        atomic::write_atomically(&identity_path, &json)
            .map_err(io_error(&identity_path, "write"))?;
        crate::layers::bake::staging::remove_temporaries(&path)?;
        let staging = RadianceStaging {
            swap,
            path,
            identity,
            _lock: lock,
        };
        if resume
            && let Ok(old) = read_manifest(dir)
            && old.identity == staging.identity
        {
            staging.take_in(dir, &old)?;
        }
        Ok(staging)
    }

    /// The staging directory that keeps bake directory `dir`'s finished samples until the bake
    /// is complete: `.NAME.radiance-baking` beside it.
    pub fn path_of(dir: &Path) -> Option<PathBuf> {
        Some(DirectorySwap::new(dir)?.beside(STAGING_SUFFIX))
    }

    /// Stages every complete sample of the bake `manifest` at `dir` describes (files copied
    /// unchanged) that is not staged yet.
    pub fn take_in(&self, dir: &Path, manifest: &RadianceManifest) -> Result<(), BakeError> {
        for record in &manifest.samples {
            if self.is_complete(record.sample) {
                continue;
            }
            for (k, object) in manifest.objects.iter().enumerate() {
                for lobe in &object.lobes {
                    let name = manifest_map_name(manifest, k, record.sample, lobe);
                    let from = dir.join(&name);
                    let bytes = fs::read(&from).map_err(io_error(&from, "read"))?;
                    self.write(&name, &bytes)?;
                }
            }
            self.write_record(record)?;
        }
        Ok(())
    }

    /// Whether sample `sample` is complete in staging.
    pub fn is_complete(&self, sample: usize) -> bool {
        self.path.join(record_name(sample)).is_file()
    }

    fn write(&self, name: &str, bytes: &[u8]) -> Result<(), BakeError> {
        let path = self.path.join(name);
        atomic::write_atomically(&path, bytes).map_err(io_error(&path, "write"))
    }

    /// Stages the maps of one sample (`maps[object][lobe]`), then its record.
    pub fn write_sample(
        &self,
        objects: &[GlossyObject],
        maps: &[Vec<Arc<crate::cubemap::CubeMap>>],
        record: &SampleRecord,
    ) -> Result<(), BakeError> {
        for (object, lobes) in objects.iter().zip(maps) {
            for (lobe, map) in object.lobes.iter().zip(lobes) {
                let name = map_file_name(object, record.sample, *lobe);
                let final_path = self.swap.target().join(&name);
                check_cube_map(map, map.size, &final_path)?;
                self.write(&name, &encode_cube_map_exr(map, &final_path)?)?;
            }
        }
        self.write_record(record)
    }

    fn write_record(&self, record: &SampleRecord) -> Result<(), BakeError> {
        let json = serde_json::to_vec_pretty(record).expect("plain data serializes");
        self.write(&record_name(record.sample), &json)
    }

    /// The staged samples' records, increasing.
    pub fn records(&self) -> Result<Vec<SampleRecord>, BakeError> {
        let mut records = Vec::new();
        for entry in fs::read_dir(&self.path).map_err(io_error(&self.path, "list"))? {
            let path = entry.map_err(io_error(&self.path, "list"))?.path();
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if name.starts_with("sample-") && name.ends_with(".json") {
                let bytes = fs::read(&path).map_err(io_error(&path, "read"))?;
                let record: SampleRecord = serde_json::from_slice(&bytes).map_err(|e| {
                    invalid(&path, "the record", e.to_string(), "bake the sample again")
                })?;
                records.push(record);
            }
        }
        records.sort_by_key(|r| r.sample);
        Ok(records)
    }

    /// Writes `template` (its samples replaced by every staged sample's record) as the manifest
    /// and swaps the staging directory in.
    pub fn commit(self, template: &RadianceManifest) -> Result<RadianceManifest, BakeError> {
        let manifest = RadianceManifest {
            identity: self.identity.clone(),
            samples: self.records()?,
            ..template.clone()
        };
        let path = self.path.join(RADIANCE_MANIFEST);
        let json = serde_json::to_vec_pretty(&manifest).expect("plain data serializes");
        atomic::write_synced(&path, &json).map_err(io_error(&path, "write"))?;
        atomic::sync_directory(&self.path).map_err(io_error(&self.path, "fsync"))?;
        // Swap first, tidy after: until the bake is in place the staged records stay, so a
        // failure here still resumes. The records live on in the manifest.
        let _barrier = atomic::swap_barrier();
        self.swap.swap_in(&self.path, WhenSwapFails::Keep)?;
        let dir = self.swap.target();
        for entry in fs::read_dir(dir).map_err(io_error(dir, "list"))? {
            let path = entry.map_err(io_error(dir, "list"))?.path();
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if name == "identity.json" || (name.starts_with("sample-") && name.ends_with(".json")) {
                fs::remove_file(&path).map_err(io_error(&path, "remove"))?;
            }
        }
        atomic::sync_directory(dir).map_err(io_error(dir, "fsync"))?;
        Ok(manifest)
    }
}

impl RadianceManifest {
    /// The manifest of a bake of `scene`'s glossy objects with `options`, without samples yet.
    pub fn template(scene: &Scene, options: &RadianceMapOptions) -> RadianceManifest {
        RadianceManifest {
            format_version: RADIANCE_FORMAT_VERSION,
            scene: scene.name.clone(),
            created_by: crate::layers::bake::default_created_by(),
            identity: RadianceIdentity::of(scene, options),
            size: options.size.max(1).next_power_of_two(),
            samples_per_texel: options.samples,
            seed: options.seed,
            views: options.views,
            samples: Vec::new(),
            objects: glossy_objects(scene)
                .iter()
                .map(|o| ManifestObject {
                    object: o.object,
                    name: o.name.clone(),
                    centre: o.centre,
                    radius: o.radius,
                    lobes: o.lobes.iter().map(|l| l.name().to_owned()).collect(),
                })
                .collect(),
        }
    }
}

/// Joins the radiance-map bakes `shards` (of one scene and options, no sample twice) into `out`.
pub fn merge(shards: &[PathBuf], out: &Path) -> Result<RadianceManifest, BakeError> {
    let manifests = shards
        .iter()
        .map(|dir| read_manifest(dir))
        .collect::<Result<Vec<_>, _>>()?;
    let Some(first) = manifests.first() else {
        return Err(invalid(
            out,
            "the shards",
            "are none".into(),
            "name the shard directories to join",
        ));
    };
    let mut seen = std::collections::HashSet::new();
    for (dir, manifest) in shards.iter().zip(&manifests) {
        let path = dir.join(RADIANCE_MANIFEST);
        if manifest.identity != first.identity || manifest.objects != first.objects {
            return Err(invalid(
                &path,
                "identity",
                format!(
                    "differs from {}'s: another scene or other options",
                    shards[0].display()
                ),
                "merge shards of one bake only",
            ));
        }
        if let Some(record) = manifest.samples.iter().find(|r| !seen.insert(r.sample)) {
            return Err(invalid(
                &path,
                "samples",
                format!("repeats sample {} of an earlier shard", record.sample),
                "merge shards with no sample in common",
            ));
        }
    }
    let staging = RadianceStaging::open(out, first.identity.clone(), false)?;
    for (dir, manifest) in shards.iter().zip(&manifests) {
        staging.take_in(dir, manifest)?;
    }
    staging.commit(first)
}

/// The file name a manifest gives object `k`'s map of lobe `lobe` at `sample`.
fn manifest_map_name(manifest: &RadianceManifest, k: usize, sample: usize, lobe: &str) -> String {
    let object = &manifest.objects[k];
    file_name(object.object, &object.name, sample, lobe)
}

/// Reads and checks `dir/radiance.json`.
pub fn read_manifest(dir: &Path) -> Result<RadianceManifest, BakeError> {
    let path = dir.join(RADIANCE_MANIFEST);
    if !path.is_file() {
        return Err(BakeError::MissingManifest { path });
    }
    let bytes = fs::read(&path).map_err(io_error(&path, "read"))?;
    let manifest: RadianceManifest = serde_json::from_slice(&bytes).map_err(|e| {
        invalid(
            &path,
            "the manifest",
            e.to_string(),
            "write the radiance-map bake again",
        )
    })?;
    if manifest.format_version != RADIANCE_FORMAT_VERSION {
        return Err(invalid(
            &path,
            "format_version",
            format!(
                "is {}, this lensmap reads {RADIANCE_FORMAT_VERSION}",
                manifest.format_version
            ),
            "write the bake again with this lensmap",
        ));
    }
    Ok(manifest)
}

/// The maps of every glossy object of `scene` from the bake at `dir`, which must have been made
/// from this scene and hold every view sample; with the manifest and the view samples.
/// A bake replaced while it is read is read again ([`atomic::read_consistently`]).
pub fn read_maps(
    dir: &Path,
    scene: &Scene,
) -> Result<(RadianceManifest, GlossyViews, Vec<GlossyMaps>), BakeError> {
    atomic::read_consistently(
        dir,
        || read_maps_once(dir, scene),
        || crate::layers::bake::replaced_throughout(dir),
    )
}

/// [`read_maps`] without the check for a concurrent replacement.
fn read_maps_once(
    dir: &Path,
    scene: &Scene,
) -> Result<(RadianceManifest, GlossyViews, Vec<GlossyMaps>), BakeError> {
    let manifest = read_manifest(dir)?;
    let path = dir.join(RADIANCE_MANIFEST);
    let options = RadianceMapOptions {
        size: manifest.size,
        samples: manifest.samples_per_texel,
        seed: manifest.seed,
        views: manifest.views,
    };
    let expected = RadianceManifest::template(scene, &options);
    if manifest.identity.identity_version != IDENTITY_VERSION
        || manifest.identity.scene_hash != expected.identity.scene_hash
    {
        return Err(invalid(
            &path,
            "identity.scene_hash",
            format!("is not scene \"{}\" as it is now", scene.name),
            "bake this scene's radiance maps again",
        ));
    }
    // The options the manifest states must be those its maps were made with, and its objects
    // the scene's: an edited or older manifest is refused, not read as something else.
    if manifest.identity.options_hash != expected.identity.options_hash {
        return Err(invalid(
            &path,
            "identity.options_hash",
            "does not match the size, samples, seed and views the manifest states, or the maps were made by an older lensmap".into(),
            "write the radiance-map bake again",
        ));
    }
    if manifest.objects != expected.objects {
        return Err(invalid(
            &path,
            "objects",
            format!("differ from scene \"{}\"'s glossy objects", scene.name),
            "bake this scene's radiance maps again",
        ));
    }
    let views = GlossyViews::geodesic(manifest.views).ok_or_else(|| {
        invalid(
            &path,
            "views",
            format!("{} is not a geodesic count", manifest.views),
            "write the bake again",
        )
    })?;
    let complete: Vec<usize> = manifest.samples.iter().map(|r| r.sample).collect();
    if complete != (0..views.directions().len()).collect::<Vec<_>>() {
        return Err(invalid(
            &path,
            "samples",
            format!(
                "holds {} of the {} view samples",
                complete.len(),
                views.directions().len()
            ),
            "bake the missing samples (resume the bake) or merge the shards",
        ));
    }
    let objects = glossy_objects(scene);
    let mut all = Vec::with_capacity(objects.len());
    for object in objects {
        let mut maps = Vec::with_capacity(complete.len());
        for &sample in &complete {
            let mut lobes = Vec::with_capacity(object.lobes.len());
            for &lobe in &object.lobes {
                let file = dir.join(map_file_name(&object, sample, lobe));
                // A missing map is a bad bake, as a layered bake's is (exit 2), not a failed
                // read of the work's.
                if !file.is_file() {
                    return Err(BakeError::MissingMap {
                        path: file,
                        manifest: RADIANCE_MANIFEST,
                        field: format!("samples[{sample}]"),
                    });
                }
                lobes.push(Arc::new(read_cube_map_exr(&file, manifest.size)?));
            }
            maps.push(lobes);
        }
        all.push(GlossyMaps { object, maps });
    }
    Ok((manifest, views, all))
}
