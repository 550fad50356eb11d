//! The bake directory: what the baker writes and the runtime reads, the layered environment maps
//! of every lens object at every viewpoint sample of the view space.
//!
//! ```text
//! DIR/
//!   manifest.json                       the Manifest (format_version 1), pretty-printed JSON
//!   lens0-teapot.v000.layer0.exr        one cube map per (lens object, viewpoint sample, layer)
//!   lens0-teapot.v000.layer1.exr
//!   …
//! ```
//!
//! **Shared layers.** A distant layer shared between lens objects is one map: the sharing lens
//! objects' layers list the same files (one per viewpoint), with the same shell and the same EM
//! origin (a layer's own `em_origin` where it differs from its lens object's). It is written and
//! read once, and in memory both layers hold the same `Arc<CubeMap>`.
//!
//! **Cube-map files.** Each EXR is a multi-part OpenEXR file holding one part per (mip level,
//! face): `6·(log2(size) + 1)` parts named `level{l}/{face}` (`face` one of `+X -X +Y -Y +Z -Z`,
//! Vulkan's layer order), written level by level and face by face in that order. Part
//! `level{l}/{face}` is `(size >> l)²` pixels with four 32-bit float channels `R G B A` holding
//! the *premultiplied* texel `(α·r, α·g, α·b, α)` (OpenEXR's own convention); pixel row 0 is the
//! face's row 0 (`t = 0`), column 0 is `s = 0`, exactly the layout of [`CubeMap`]. Every level is
//! stored, not regenerated on reading: the baker solves all levels together. Compression is
//! lossless ZIP in increasing line order, so files round-trip bit-exactly and the same bake gives
//! the same bytes.
//!
//! **Atomic writes.** [`Bake::write`] writes everything into a sibling staging directory
//! `.NAME.writing-PID`, fsyncs every file and the directory, then swaps it in with
//! [`crate::atomic::DirectorySwap`] (one atomic exchange of the two names, or two renames on a
//! file system without it), and removes the old bake. A reader finds the old bake or the new one
//! at `NAME` at every moment, and [`Bake::read`] never mixes the two. An interruption before the
//! swap leaves the old bake untouched at `NAME`; one between the two renames of the fallback
//! leaves it at `.NAME.previous`, which the next write restores before it starts (and which
//! [`Bake::read`] names in its error). One writer per directory at a time: every writer holds the
//! lock `.NAME.lock` ([`crate::atomic::lock::DirectoryLock`]) from before it touches anything to
//! after the swap, and a second writer is refused at once, naming the holder's host and pid. A
//! staging directory left by a killed writer is removed by the next write. [`Staging`] builds a bake sample by sample the same
//! way.
//!
//! The rooms: [`manifest`] (the JSON and its checks), [`exr`] (cube-map files), [`staging`]
//! (a bake built piece by piece), [`error`] (what goes wrong, said with the paths a user knows).
//!
//! **Validation.** [`Bake::read`] checks everything and fails on the first problem with one line
//! naming the file, the field (or EXR part and texel) and the fix. [`Bake::write`] applies the
//! same checks before anything is written, so it never produces a bake that cannot be read.

pub mod compress;
pub mod error;
pub mod exr;
pub mod manifest;
pub mod staging;

use crate::layers::Layering;
use std::collections::{HashMap, HashSet};
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DVec3, Vec3};

use super::shell::LayerShell;
use crate::atomic::{self, DirectorySwap, WhenSwapFails, lock::DirectoryLock};
pub use crate::cubemap::ALPHA_TOLERANCE;
use crate::cubemap::CubeMap;
use crate::index::{LayerIndex, LayerRef, LensIndex};
pub use compress::{CompressOptions, CompressSummary, Compression, MapReader, compress};
pub use error::BakeError;
use error::{CountCheck, io_error};
pub use exr::{
    FACE_NAMES, check_cube_map, encode_cube_map_exr, part_name, read_cube_map_exr,
    write_cube_map_exr,
};
pub use manifest::{
    BakedOn, FORMAT_VERSION, MANIFEST_FILE_NAME, MAX_EM_ORIGIN_METRES, Manifest, ManifestLayer,
    ManifestLens, Provenance,
};
pub use staging::Staging;

/// A bake in memory: the layered EMs of every lens object at every viewpoint sample.
#[derive(Clone, Debug, PartialEq)]
pub struct Bake {
    /// Name of the scene the bake was made from.
    pub scene: String,
    /// What wrote the bake (see [`default_created_by`]).
    pub created_by: String,
    /// Viewpoint sample positions in world space, metres.
    pub viewpoints: Vec<Vec3>,
    /// The lens objects.
    pub lenses: Vec<BakedLens>,
    /// Where it came from (see [`Provenance`]), when known.
    pub provenance: Option<Provenance>,
}

/// One lens object's layered EMs.
#[derive(Clone, Debug, PartialEq)]
pub struct BakedLens {
    /// The lens object's name in the scene (unique within the bake).
    pub name: String,
    /// Per layer, the EM origin in world space, metres.
    pub em_origins: Vec<DVec3>,
    /// The layer shells, nearest first.
    pub shells: Vec<LayerShell>,
    /// How rays are split between the layers.
    pub layering: Layering,
    /// `maps[viewpoint][layer]`: premultiplied RGBA cube maps with full mip chains, all of the
    /// bake's one size. A layer whose maps are, at every viewpoint, the very maps (`Arc`
    /// identity) of an earlier layer (of this or an earlier lens object) with the same shell and
    /// EM origin is shared: written once and listed by both.
    pub maps: Vec<Vec<Arc<CubeMap>>>,
}

/// `"lensmap <version>"`, the usual [`Bake::created_by`].
pub fn default_created_by() -> String {
    concat!("lensmap ", env!("CARGO_PKG_VERSION")).to_owned()
}

/// The file name [`Bake::write`] gives the cube map of layer `at` (its lens object named
/// `lens_name`) at viewpoint sample `viewpoint`: `lens{i}-{name}.v{viewpoint:03}.layer{layer}.exr`,
/// the name reduced to ASCII letters, digits, `-` and `_`.
pub fn map_file_name(at: LayerRef, lens_name: &str, viewpoint: usize) -> String {
    let name = file_name_part(lens_name);
    let LayerRef { lens, layer } = at;
    format!("lens{lens}-{name}.v{viewpoint:03}.layer{layer}.exr")
}

/// `name` as a part of a bake's file names: ASCII letters, digits, `-` and `_` kept, every other
/// character `_`.
pub fn file_name_part(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

impl Bake {
    /// The edge length of the bake's cube maps (that of the first map), `None` if it has none.
    pub fn cube_map_size(&self) -> Option<u32> {
        self.lenses
            .iter()
            .flat_map(|lens| lens.maps.iter().flatten())
            .map(|cube| cube.size)
            .next()
    }

    /// The manifest [`Bake::write`] stores, after checking that the lists' lengths agree and the
    /// manifest is valid. `dir` is only used in error messages.
    pub fn manifest(&self, dir: &Path) -> Result<Manifest, BakeError> {
        let per_viewpoint = CountCheck {
            path: dir,
            expected_from: "viewpoints",
            expected: self.viewpoints.len(),
        };
        for (index, lens) in self.lenses.iter().enumerate() {
            per_viewpoint.require(
                format!("lenses[{index}].maps"),
                lens.maps.len(),
                "viewpoints",
                "give every lens object one list of maps per viewpoint sample",
            )?;
            let per_shell = CountCheck {
                path: dir,
                expected_from: &format!("lenses[{index}].shells"),
                expected: lens.shells.len(),
            };
            per_shell.require(
                format!("lenses[{index}].em_origins"),
                lens.em_origins.len(),
                "origins",
                "give every layer shell its EM origin",
            )?;
            for (viewpoint, maps) in lens.maps.iter().enumerate() {
                per_shell.require(
                    format!("lenses[{index}].maps[{viewpoint}]"),
                    maps.len(),
                    "layers",
                    "give every viewpoint sample one cube map per layer shell",
                )?;
            }
        }
        // A layer holding, at every viewpoint, the very maps of an earlier layer with the same
        // shell and origin lists that layer's files.
        let shared_with = |at: LayerRef| -> Option<LayerRef> {
            let (lens, layer) = (&self.lenses[at.lens.index()], at.layer.index());
            let same_maps = |other: &BakedLens, other_layer: usize| {
                lens.maps
                    .iter()
                    .zip(&other.maps)
                    .all(|(a, b)| Arc::ptr_eq(&a[layer], &b[other_layer]))
            };
            LensIndex::all(at.lens.index() + 1).find_map(|earlier| {
                let other = &self.lenses[earlier.index()];
                let layers = if earlier == at.lens {
                    layer
                } else {
                    other.shells.len()
                };
                LayerIndex::all(layers).find_map(|other_layer| {
                    let j = other_layer.index();
                    (other.shells[j] == lens.shells[layer]
                        && other.em_origins[j] == lens.em_origins[layer]
                        && same_maps(other, j))
                    .then_some(earlier.layer(other_layer))
                })
            })
        };
        let lenses = LensIndex::all(self.lenses.len())
            .zip(&self.lenses)
            .map(|(index, lens)| {
                let lens_origin = lens.em_origins.first().copied().unwrap_or(DVec3::ZERO);
                ManifestLens {
                    name: lens.name.clone(),
                    em_origin: lens_origin,
                    layering: lens.layering,
                    layers: LayerIndex::all(lens.shells.len())
                        .zip(lens.shells.iter().zip(&lens.em_origins))
                        .map(|(layer, (shell, &origin))| {
                            let at = index.layer(layer);
                            let owner = shared_with(at).unwrap_or(at);
                            let owner_name = &self.lenses[owner.lens.index()].name;
                            ManifestLayer {
                                shell: *shell,
                                em_origin: (origin != lens_origin).then_some(origin),
                                maps: (0..self.viewpoints.len())
                                    .map(|viewpoint| map_file_name(owner, owner_name, viewpoint))
                                    .collect(),
                            }
                        })
                        .collect(),
                }
            })
            .collect();
        let manifest = Manifest {
            format_version: FORMAT_VERSION,
            scene: self.scene.clone(),
            created_by: self.created_by.clone(),
            cube_map_size: self.cube_map_size().unwrap_or(0),
            viewpoints: self.viewpoints.clone(),
            lenses,
            provenance: self.provenance.clone(),
            compression: None,
        };
        manifest.validate(dir)?;
        Ok(manifest)
    }

    /// Writes the bake to `dir` atomically (see the module docs): validates everything first,
    /// writes and fsyncs a staging directory beside `dir`, then swaps it in. An existing `dir`
    /// must be a bake (it has a `manifest.json`) or empty; it is replaced only when the new bake is
    /// complete on disk. Parent directories are created.
    pub fn write(&self, dir: &Path) -> Result<(), BakeError> {
        let manifest = self.manifest(dir)?;
        write_directory(dir, |staging| self.write_staging(staging, dir, &manifest))
    }

    /// Writes every cube map, then the manifest, into `staging`, fsyncing each file and the
    /// directory. Texels are checked against `final_dir`'s file names so errors name them.
    fn write_staging(
        &self,
        staging: &Path,
        final_dir: &Path,
        manifest: &Manifest,
    ) -> Result<(), BakeError> {
        let mut written = HashSet::new();
        for (lens, listed) in self.lenses.iter().zip(&manifest.lenses) {
            for (viewpoint, maps) in lens.maps.iter().enumerate() {
                for (cube, layer) in maps.iter().zip(&listed.layers) {
                    let file = &layer.maps[viewpoint];
                    // A shared layer's file is written by the layer that owns it.
                    if written.insert(file.as_str()) {
                        check_cube_map(cube, manifest.cube_map_size, &final_dir.join(file))?;
                        write_cube_map_exr(cube, &staging.join(file))?;
                    }
                }
            }
        }
        let manifest_path = staging.join(MANIFEST_FILE_NAME);
        atomic::write_synced(&manifest_path, manifest.to_json().as_bytes())
            .map_err(io_error(&manifest_path, "write"))?;
        atomic::sync_directory(staging).map_err(io_error(staging, "fsync"))
    }

    /// Reads and validates the bake in `dir`: the manifest, then every cube map it lists. A bake
    /// replaced while it is read is read again ([`atomic::read_consistently`]): the result is
    /// the old bake or the new one, never maps of both.
    pub fn read(dir: &Path) -> Result<Bake, BakeError> {
        atomic::read_consistently(dir, || Bake::read_once(dir), || replaced_throughout(dir))
    }

    /// [`Bake::read`] without the check for a concurrent replacement.
    fn read_once(dir: &Path) -> Result<Bake, BakeError> {
        let manifest = Manifest::read(dir)?;
        let mut reader = MapReader::new(dir, &manifest);
        // A file listed by several layers (a shared layer) is read once and shared.
        let mut read: HashMap<PathBuf, Arc<CubeMap>> = HashMap::new();
        let mut lenses = Vec::with_capacity(manifest.lenses.len());
        for (index, lens) in manifest.lenses.iter().enumerate() {
            let mut maps = Vec::with_capacity(manifest.viewpoints.len());
            for viewpoint in 0..manifest.viewpoints.len() {
                let mut layers = Vec::with_capacity(lens.layers.len());
                for (layer_index, layer) in lens.layers.iter().enumerate() {
                    let name = &layer.maps[viewpoint];
                    let file: PathBuf = Path::new(name).components().collect();
                    if let Some(cube) = read.get(&file) {
                        layers.push(cube.clone());
                        continue;
                    }
                    let path = dir.join(&file);
                    if !path.is_file() {
                        return Err(BakeError::MissingMap {
                            path,
                            manifest: MANIFEST_FILE_NAME,
                            field: format!(
                                "lenses[{index}].layers[{layer_index}].maps[{viewpoint}]"
                            ),
                        });
                    }
                    let cube = Arc::new(reader.read(name)?);
                    read.insert(file, cube.clone());
                    layers.push(cube);
                }
                maps.push(layers);
            }
            lenses.push(BakedLens {
                name: lens.name.clone(),
                em_origins: (0..lens.layers.len())
                    .map(|layer| lens.layer_origin(layer))
                    .collect(),
                shells: lens.layers.iter().map(|layer| layer.shell).collect(),
                maps,
                layering: lens.layering,
            });
        }
        Ok(Bake {
            scene: manifest.scene,
            created_by: manifest.created_by,
            viewpoints: manifest.viewpoints,
            lenses,
            provenance: manifest.provenance.clone(),
        })
    }
}

/// Writes bake directory `dir` atomically (see the module docs): `fill` writes and fsyncs
/// everything into the staging directory it is given, then the staging directory is swapped in
/// for `dir`. On any failure the staging directory is removed and `dir` is left as it was.
pub(crate) fn write_directory(
    dir: &Path,
    fill: impl FnOnce(&Path) -> Result<(), BakeError>,
) -> Result<(), BakeError> {
    let (swap, _lock) = prepare_destination(dir)?;
    // Every writer's leftover (a killed one's staging, or the old bake a killed swap had not yet
    // removed): the lock is held, so none is in use.
    let leftover = swap.beside(WRITING_SUFFIX);
    let parent = leftover.parent().unwrap_or(Path::new("."));
    let leftover = leftover
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or_default();
    for entry in fs::read_dir(parent)
        .map_err(io_error(parent, "list"))?
        .flatten()
    {
        if entry
            .file_name()
            .to_str()
            // `.NAME.writing-PID` exactly: not the staging of a bake whose own name starts so.
            .and_then(|n| n.strip_prefix(leftover))
            .is_some_and(|pid| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
        {
            let path = entry.path();
            fs::remove_dir_all(&path).map_err(io_error(&path, "remove"))?;
        }
    }
    let staging = swap.beside(&format!("{WRITING_SUFFIX}{}", std::process::id()));
    fs::create_dir(&staging).map_err(io_error(&staging, "create"))?;
    if let Err(error) = fill(&staging) {
        // Best effort: a leftover staging directory is harmless and removed by the next write.
        let _ = fs::remove_dir_all(&staging);
        return Err(error);
    }
    let _barrier = atomic::swap_barrier();
    Ok(swap.swap_in(&staging, WhenSwapFails::Remove)?)
}

/// The error of a bake that was replaced during every read ([`atomic::read_consistently`]).
pub(crate) fn replaced_throughout(dir: &Path) -> BakeError {
    io_error(dir, "read")(std::io::Error::other(format!(
        "it was replaced during each of {} reads; read it when its writer is done",
        atomic::CONSISTENT_READ_ATTEMPTS
    )))
}

/// The suffix of [`Bake::write`]'s staging directory's name, followed by the process id:
/// `.NAME.writing-PID` beside bake directory `NAME`.
const WRITING_SUFFIX: &str = ".writing-";

/// The swap that replaces bake directory `dir`, made ready, and the directory's lock, which the
/// writer holds until the swap is done: the lock taken (or refused, naming its holder), parent
/// folders created, a swap an earlier write left half done finished, and an existing `dir`
/// checked to be a bake (or empty), since it is about to be replaced.
fn prepare_destination(dir: &Path) -> Result<(DirectorySwap, DirectoryLock), BakeError> {
    let swap = DirectorySwap::new(dir).ok_or_else(|| BakeError::Invalid {
        path: dir.to_owned(),
        field: "the bake directory".into(),
        problem: "has no final name (or is not UTF-8)".into(),
        fix: "name the directory itself, e.g. out/bake",
    })?;
    let lock = DirectoryLock::acquire(dir)?;
    swap.prepare()?;
    if dir.exists() && !is_bake_or_empty(dir) {
        return Err(BakeError::NotABake {
            dir: dir.to_owned(),
        });
    }
    Ok((swap, lock))
}

/// Whether a directory may be replaced: it holds a manifest, or nothing at all.
fn is_bake_or_empty(dir: &Path) -> bool {
    dir.join(MANIFEST_FILE_NAME).is_file()
        || fs::read_dir(dir).is_ok_and(|mut entries| entries.next().is_none())
}
