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
//! `.NAME.writing-PID`, fsyncs every file and the directory, then swaps it in: the old bake is
//! renamed to `.NAME.previous`, the staging directory to `NAME`, and the old one is removed. An
//! interruption before the swap leaves the old bake untouched at `NAME`; one during the swap
//! leaves it at `.NAME.previous`, which the next write restores before it starts (and which
//! [`Bake::read`] names in its error). One writer per directory at a time; a staging directory
//! left by a killed writer is removed by the next write from the same process id only, and is
//! otherwise safe to delete.
//!
//! **Validation.** [`Bake::read`] checks everything and fails on the first problem with one line
//! naming the file, the field (or EXR part and texel) and the fix. [`Bake::write`] applies the
//! same checks before anything is written, so it never produces a bake that cannot be read.

use std::collections::{HashMap, HashSet};
use std::fs::{self, File};
use std::io::{BufReader, Cursor, Write};
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use super::shell::LayerShell;
pub use crate::cubemap::ALPHA_TOLERANCE;
use crate::cubemap::{CubeMap, CubeMapError, TexelProblem, check_face_texels};

/// The manifest format this code writes and reads.
pub const FORMAT_VERSION: u32 = 1;

/// File name of the manifest inside a bake directory.
pub const MANIFEST_FILE_NAME: &str = "manifest.json";

/// Face names in Vulkan layer order, as used in EXR part names.
pub const FACE_NAMES: [&str; 6] = ["+X", "-X", "+Y", "-Y", "+Z", "-Z"];

/// The lossless, deterministic encoding of every part.
const ENCODING: exr::prelude::Encoding = exr::prelude::Encoding::SMALL_LOSSLESS;

/// `manifest.json`: everything about a bake except the texels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Always [`FORMAT_VERSION`] for this code.
    pub format_version: u32,
    /// Name of the scene the bake was made from.
    pub scene: String,
    /// What wrote the bake (program and version), for people reading the file.
    pub created_by: String,
    /// Edge length in texels of every cube map's level-0 faces: a power of two ≥ 1.
    pub cube_map_size: u32,
    /// Viewpoint sample positions in world space, metres (the eye positions the maps were inferred
    /// for); at least one.
    pub viewpoints: Vec<Vec3>,
    /// The lens objects, at least one, with unique non-empty names.
    pub lenses: Vec<ManifestLens>,
    /// Where the bake came from (written by `lensmap bake`; absent in bakes written from
    /// projected EMs): what resuming, merging and rendering check the bake against.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<Provenance>,
}

/// What a bake was made from, so that one made from another scene or with other options is
/// refused instead of rendered wrong.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Provenance {
    /// The scene's content hash (`Scene::content_hash`): geometry, materials, lights, the
    /// environment, the lens objects, the view space and the camera's aim.
    pub scene_hash: String,
    /// Hash of every bake option that changes the maps (resolution, EM size, layers, views…).
    pub options_hash: String,
    /// The view-space index of each viewpoint, in the order of `viewpoints`: strictly increasing.
    pub samples: Vec<usize>,
}

/// One lens object in the manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestLens {
    /// The lens object's name in the scene.
    pub name: String,
    /// The EM origin in world space, metres: cube-map directions are shell hit − this point, for
    /// every layer that names no origin of its own.
    pub em_origin: DVec3,
    /// The layers, nearest shell first; at least one.
    pub layers: Vec<ManifestLayer>,
}

/// One layer of a lens object's layered EM in the manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestLayer {
    /// The layer's shell (the same for every viewpoint sample).
    pub shell: LayerShell,
    /// The layer's own EM origin, metres, where it differs from the lens object's: a distant
    /// layer shared between lens objects is one map, parameterized about one origin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub em_origin: Option<DVec3>,
    /// Per viewpoint sample, the cube-map file relative to the bake directory (plain relative
    /// path, no `..`); as many as there are viewpoints. A file may be listed more than once (a
    /// layer shared between lens objects, or one map for several viewpoints) when every listing
    /// has the same shell and EM origin; it is stored and read once.
    pub maps: Vec<String>,
}

impl ManifestLens {
    /// The EM origin of layer `layer`: its own, else the lens object's.
    pub fn layer_origin(&self, layer: usize) -> DVec3 {
        self.layers
            .get(layer)
            .and_then(|l| l.em_origin)
            .unwrap_or(self.em_origin)
    }
}

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
    /// `maps[viewpoint][layer]`: premultiplied RGBA cube maps with full mip chains, all of the
    /// bake's one size. A layer whose maps are, at every viewpoint, the very maps (`Arc`
    /// identity) of an earlier layer (of this or an earlier lens object) with the same shell and
    /// EM origin is shared: written once and listed by both.
    pub maps: Vec<Vec<Arc<CubeMap>>>,
}

/// Why a bake cannot be read or written. Every message is one line naming the file, the field
/// and the fix.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// The file system refused.
    #[error("{}: cannot {action}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What was being done ("read", "create", …).
        action: &'static str,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The bake directory does not exist.
    #[error("{}: no such bake directory; bake one first (`lensmap bake`) or check the path", dir.display())]
    MissingDirectory {
        /// The directory asked for.
        dir: PathBuf,
    },
    /// A write was interrupted between its two renames: the old bake is at `previous`.
    #[error(
        "{}: missing, but {} holds the previous bake (a write was interrupted while swapping); rename it back, or write the bake again (which restores it first)",
        dir.display(), previous.display()
    )]
    InterruptedSwap {
        /// The directory asked for.
        dir: PathBuf,
        /// Where the previous bake is.
        previous: PathBuf,
    },
    /// The directory has no `manifest.json`.
    #[error("{}: not found, so this is not a bake directory; write one with `lensmap bake`", path.display())]
    MissingManifest {
        /// The manifest path looked for.
        path: PathBuf,
    },
    /// `manifest.json` is not valid JSON or does not match the manifest's fields.
    #[error("{}:{line}:{column}: {message}; fix the manifest or write the bake again", path.display())]
    ManifestSyntax {
        /// The manifest path.
        path: PathBuf,
        /// 1-based line of the problem.
        line: usize,
        /// 1-based column of the problem.
        column: usize,
        /// serde_json's description.
        message: String,
    },
    /// The manifest's format version is not [`FORMAT_VERSION`].
    #[error(
        "{}: format_version is {found}, but this lensmap reads version {expected}; write the bake again with this lensmap",
        path.display()
    )]
    WrongVersion {
        /// The manifest path.
        path: PathBuf,
        /// What the file says (`missing` when absent).
        found: String,
        /// [`FORMAT_VERSION`].
        expected: u32,
    },
    /// `cube_map_size` is not a power of two.
    #[error(
        "{}: cube_map_size is {size}, not a power of two ≥ 1; bake with a power-of-two size such as 64",
        path.display()
    )]
    NonPowerOfTwo {
        /// The manifest path (or the directory being written).
        path: PathBuf,
        /// The size found.
        size: u32,
    },
    /// Two lists that must have the same length do not (layers per viewpoint, maps per layer).
    #[error("{}: {field} has {found} {what} but {expected_from} has {expected}; {fix}", path.display())]
    InconsistentCount {
        /// The manifest path (or the directory being written).
        path: PathBuf,
        /// The list whose length is wrong, e.g. `lenses[0].layers[1].maps`.
        field: String,
        /// Its length.
        found: usize,
        /// What it counts ("files", "layers", …).
        what: &'static str,
        /// The list it must match.
        expected_from: String,
        /// The length it must have.
        expected: usize,
        /// How to fix it.
        fix: &'static str,
    },
    /// Some other field of the manifest (or of the bake being written) is invalid.
    #[error("{}: {field} {problem}; {fix}", path.display())]
    Invalid {
        /// The manifest path (or the directory being written).
        path: PathBuf,
        /// The field, e.g. `lenses[0].em_origin`.
        field: String,
        /// What is wrong.
        problem: String,
        /// How to fix it.
        fix: &'static str,
    },
    /// [`Bake::write`] was pointed at a directory that is not a bake; it will not replace it.
    #[error(
        "{}: exists and is not a bake (no manifest.json); writing would replace it, so choose another directory or remove it",
        dir.display()
    )]
    NotABake {
        /// The directory.
        dir: PathBuf,
    },
    /// A cube-map file listed in the manifest is missing.
    #[error("{}: not found (listed in manifest.json at {field}); restore the file or write the bake again", path.display())]
    MissingMap {
        /// The file.
        path: PathBuf,
        /// Where the manifest lists it.
        field: String,
    },
    /// A cube-map file is not readable OpenEXR.
    #[error("{}: not a readable OpenEXR file ({message}); write the bake again", path.display())]
    Exr {
        /// The file.
        path: PathBuf,
        /// The exr crate's description.
        message: String,
    },
    /// A part of a cube-map file is unexpected, duplicated or lacks an f32 RGBA channel.
    #[error("{}: part '{part}' {problem}; write the bake again", path.display())]
    BadPart {
        /// The file.
        path: PathBuf,
        /// The part name.
        part: String,
        /// What is wrong.
        problem: String,
    },
    /// A cube map lacks a mip level (or a face of one).
    #[error(
        "{}: part '{part}' is missing (a {size}² cube map stores all {levels} mip levels of all six faces); write the bake again",
        path.display()
    )]
    MissingLevel {
        /// The file.
        path: PathBuf,
        /// The missing part, `level{l}/{face}`.
        part: String,
        /// The cube-map size.
        size: u32,
        /// Levels of the full chain.
        levels: u32,
    },
    /// A face of some level has the wrong number of texels.
    #[error(
        "{}: part '{part}' is {found}, expected {expected}×{expected} texels for cube_map_size {size}; write the bake again with one size throughout",
        path.display()
    )]
    WrongSize {
        /// The file.
        path: PathBuf,
        /// The part, `level{l}/{face}`.
        part: String,
        /// What was found, e.g. `32×32` or `1000 texels`.
        found: String,
        /// The expected edge length.
        expected: u32,
        /// The bake's cube-map size.
        size: u32,
    },
    /// A texel is NaN or infinite.
    #[error(
        "{}: part '{part}' texel ({x}, {y}) channel {channel} is {value}; environment maps must be finite, so fix the writer's output and write the bake again",
        path.display()
    )]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// The part, `level{l}/{face}`.
        part: String,
        /// Column.
        x: usize,
        /// Row.
        y: usize,
        /// `R`, `G`, `B` or `A`.
        channel: char,
        /// The value.
        value: f32,
    },
    /// A texel's α is outside [0, 1] by more than [`ALPHA_TOLERANCE`].
    #[error(
        "{}: part '{part}' texel ({x}, {y}) has alpha {value}, outside [0, 1] (tolerance {ALPHA_TOLERANCE}); premultiplied texels need 0 ≤ α ≤ 1, so clamp α in the writer",
        path.display()
    )]
    AlphaOutOfRange {
        /// The file.
        path: PathBuf,
        /// The part, `level{l}/{face}`.
        part: String,
        /// Column.
        x: usize,
        /// Row.
        y: usize,
        /// The α found.
        value: f32,
    },
}

/// SHA-256 of `value`'s `Debug` text, as 64 hex digits: the identity of a scene or of a bake's
/// options in a bake's [`Provenance`]. The text is streamed into the hasher, never held whole.
/// Stable for the same lensmap build; a change to any value changes it.
pub fn debug_hash(value: &impl std::fmt::Debug) -> String {
    use sha2::Digest;
    use std::fmt::Write as _;
    struct Hasher(sha2::Sha256);
    impl std::fmt::Write for Hasher {
        fn write_str(&mut self, text: &str) -> std::fmt::Result {
            self.0.update(text.as_bytes());
            Ok(())
        }
    }
    let mut hasher = Hasher(sha2::Sha256::new());
    // Writing into a hasher cannot fail.
    let _ = write!(hasher, "{value:?}");
    hasher
        .0
        .finalize()
        .iter()
        .fold(String::with_capacity(64), |mut hex, byte| {
            let _ = write!(hex, "{byte:02x}");
            hex
        })
}

/// `"lensmap <version>"`, the usual [`Bake::created_by`].
pub fn default_created_by() -> String {
    concat!("lensmap ", env!("CARGO_PKG_VERSION")).to_owned()
}

/// The file name [`Bake::write`] gives the cube map of a lens object (by index and name), viewpoint
/// sample and layer: `lens{i}-{name}.v{viewpoint:03}.layer{layer}.exr`, the name reduced to
/// ASCII letters, digits, `-` and `_`.
pub fn map_file_name(lens_index: usize, lens_name: &str, viewpoint: usize, layer: usize) -> String {
    let name: String = lens_name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("lens{lens_index}-{name}.v{viewpoint:03}.layer{layer}.exr")
}

/// The EXR part name of a face of a mip level: `level{level}/{face}`.
pub fn part_name(level: usize, face: usize) -> String {
    format!("level{level}/{}", FACE_NAMES[face])
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
        for (index, lens) in self.lenses.iter().enumerate() {
            if lens.maps.len() != self.viewpoints.len() {
                return Err(BakeError::InconsistentCount {
                    path: dir.to_owned(),
                    field: format!("lenses[{index}].maps"),
                    found: lens.maps.len(),
                    what: "viewpoints",
                    expected_from: "viewpoints".to_owned(),
                    expected: self.viewpoints.len(),
                    fix: "give every lens object one list of maps per viewpoint sample",
                });
            }
            if lens.em_origins.len() != lens.shells.len() {
                return Err(BakeError::InconsistentCount {
                    path: dir.to_owned(),
                    field: format!("lenses[{index}].em_origins"),
                    found: lens.em_origins.len(),
                    what: "origins",
                    expected_from: format!("lenses[{index}].shells"),
                    expected: lens.shells.len(),
                    fix: "give every layer shell its EM origin",
                });
            }
            for (viewpoint, maps) in lens.maps.iter().enumerate() {
                if maps.len() != lens.shells.len() {
                    return Err(BakeError::InconsistentCount {
                        path: dir.to_owned(),
                        field: format!("lenses[{index}].maps[{viewpoint}]"),
                        found: maps.len(),
                        what: "layers",
                        expected_from: format!("lenses[{index}].shells"),
                        expected: lens.shells.len(),
                        fix: "give every viewpoint sample one cube map per layer shell",
                    });
                }
            }
        }
        // A layer holding, at every viewpoint, the very maps of an earlier layer with the same
        // shell and origin lists that layer's files.
        let shared_with = |index: usize, layer: usize| -> Option<(usize, usize)> {
            let lens = &self.lenses[index];
            let same_maps = |other: &BakedLens, other_layer: usize| {
                lens.maps
                    .iter()
                    .zip(&other.maps)
                    .all(|(a, b)| Arc::ptr_eq(&a[layer], &b[other_layer]))
            };
            (0..=index).find_map(|earlier| {
                let other = &self.lenses[earlier];
                let layers = if earlier == index {
                    layer
                } else {
                    other.shells.len()
                };
                (0..layers).find_map(|other_layer| {
                    (other.shells[other_layer] == lens.shells[layer]
                        && other.em_origins[other_layer] == lens.em_origins[layer]
                        && same_maps(other, other_layer))
                    .then_some((earlier, other_layer))
                })
            })
        };
        let lenses = self
            .lenses
            .iter()
            .enumerate()
            .map(|(index, lens)| {
                let lens_origin = lens.em_origins.first().copied().unwrap_or(DVec3::ZERO);
                ManifestLens {
                    name: lens.name.clone(),
                    em_origin: lens_origin,
                    layers: lens
                        .shells
                        .iter()
                        .zip(&lens.em_origins)
                        .enumerate()
                        .map(|(layer, (shell, &origin))| {
                            let (owner, owner_layer) =
                                shared_with(index, layer).unwrap_or((index, layer));
                            let owner_name = &self.lenses[owner].name;
                            ManifestLayer {
                                shell: *shell,
                                em_origin: (origin != lens_origin).then_some(origin),
                                maps: (0..self.viewpoints.len())
                                    .map(|viewpoint| {
                                        map_file_name(owner, owner_name, viewpoint, owner_layer)
                                    })
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
        let (parent, name) = split_directory(dir)?;
        fs::create_dir_all(&parent).map_err(io_error(&parent, "create"))?;
        let previous = parent.join(format!(".{name}.previous"));
        restore_interrupted_swap(dir, &previous)?;
        if dir.exists() && !is_bake_or_empty(dir) {
            return Err(BakeError::NotABake {
                dir: dir.to_owned(),
            });
        }
        let staging = parent.join(format!(".{name}.writing-{}", std::process::id()));
        if staging.exists() {
            fs::remove_dir_all(&staging).map_err(io_error(&staging, "remove"))?;
        }
        fs::create_dir(&staging).map_err(io_error(&staging, "create"))?;
        if let Err(error) = self.write_staging(&staging, dir, &manifest) {
            // Best effort: a leftover staging directory is harmless and removed by the next write.
            let _ = fs::remove_dir_all(&staging);
            return Err(error);
        }
        swap_in(&staging, dir, &previous, &parent)
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
        write_synced(&manifest_path, manifest.to_json().as_bytes())?;
        sync_directory(staging)
    }

    /// Reads and validates the bake in `dir`: the manifest, then every cube map it lists.
    pub fn read(dir: &Path) -> Result<Bake, BakeError> {
        let manifest = Manifest::read(dir)?;
        let size = manifest.cube_map_size;
        // A file listed by several layers (a shared layer) is read once and shared.
        let mut read: HashMap<PathBuf, Arc<CubeMap>> = HashMap::new();
        let mut lenses = Vec::with_capacity(manifest.lenses.len());
        for (index, lens) in manifest.lenses.iter().enumerate() {
            let mut maps = Vec::with_capacity(manifest.viewpoints.len());
            for viewpoint in 0..manifest.viewpoints.len() {
                let mut layers = Vec::with_capacity(lens.layers.len());
                for (layer_index, layer) in lens.layers.iter().enumerate() {
                    let file: PathBuf = Path::new(&layer.maps[viewpoint]).components().collect();
                    if let Some(cube) = read.get(&file) {
                        layers.push(cube.clone());
                        continue;
                    }
                    let path = dir.join(&file);
                    if !path.is_file() {
                        return Err(BakeError::MissingMap {
                            path,
                            field: format!(
                                "lenses[{index}].layers[{layer_index}].maps[{viewpoint}]"
                            ),
                        });
                    }
                    let cube = Arc::new(read_cube_map_exr(&path, size)?);
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
            });
        }
        Ok(Bake {
            scene: manifest.scene,
            created_by: manifest.created_by,
            viewpoints: manifest.viewpoints,
            lenses,
            provenance: manifest.provenance,
        })
    }
}

/// A bake built piece by piece in a staging directory beside its final place, `.NAME.baking`,
/// then committed atomically in one swap (as [`Bake::write`] does): what `lensmap bake` writes
/// sample by sample, so that a killed bake loses at most the sample in flight and never the
/// bake already at `NAME`. Every file is written under a temporary name, fsynced and renamed,
/// so a file present under its own name is complete. One baker per directory at a time.
#[derive(Debug)]
pub struct Staging {
    dir: PathBuf,
    parent: PathBuf,
    previous: PathBuf,
    path: PathBuf,
}

impl Staging {
    /// The staging directory of bake directory `dir`, created (with `dir`'s parents) when absent
    /// and kept when present, for resuming. A swap an earlier write left half done is finished
    /// first; an existing `dir` that is not a bake is refused.
    pub fn open(dir: &Path) -> Result<Staging, BakeError> {
        let (parent, name) = split_directory(dir)?;
        fs::create_dir_all(&parent).map_err(io_error(&parent, "create"))?;
        let previous = parent.join(format!(".{name}.previous"));
        restore_interrupted_swap(dir, &previous)?;
        if dir.exists() && !is_bake_or_empty(dir) {
            return Err(BakeError::NotABake {
                dir: dir.to_owned(),
            });
        }
        let path = parent.join(format!(".{name}.baking"));
        if !path.is_dir() {
            fs::create_dir(&path).map_err(io_error(&path, "create"))?;
        }
        Ok(Staging {
            dir: dir.to_owned(),
            parent,
            previous,
            path,
        })
    }

    /// Empties the staging directory (a fresh start: nothing of an earlier bake is reused).
    pub fn clear(&self) -> Result<(), BakeError> {
        fs::remove_dir_all(&self.path).map_err(io_error(&self.path, "remove"))?;
        fs::create_dir(&self.path).map_err(io_error(&self.path, "create"))
    }

    /// The staging directory.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The bake directory it will become.
    pub fn final_dir(&self) -> &Path {
        &self.dir
    }

    /// Whether the complete file `name` is staged.
    pub fn contains(&self, name: &str) -> bool {
        self.path.join(name).is_file()
    }

    /// Writes `bytes` to `name` in the staging directory: a temporary file, fsynced, renamed.
    pub fn write_file(&self, name: &str, bytes: &[u8]) -> Result<(), BakeError> {
        let temporary = self.path.join(format!(".{name}.tmp"));
        write_synced(&temporary, bytes)?;
        self.rename_into(&temporary, name)
    }

    /// Checks `cube` (face size `size`) and writes it as cube-map EXR `name`, as
    /// [`Staging::write_file`] does; errors name the file's final path.
    pub fn write_cube_map(&self, name: &str, cube: &CubeMap, size: u32) -> Result<(), BakeError> {
        check_cube_map(cube, size, &self.dir.join(name))?;
        let temporary = self.path.join(format!(".{name}.tmp"));
        write_cube_map_exr(cube, &temporary)?;
        self.rename_into(&temporary, name)
    }

    /// Copies the complete file `from` in as `name` (bytes unchanged), as
    /// [`Staging::write_file`] does.
    pub fn copy_in(&self, from: &Path, name: &str) -> Result<(), BakeError> {
        let bytes = fs::read(from).map_err(io_error(from, "read"))?;
        self.write_file(name, &bytes)
    }

    fn rename_into(&self, temporary: &Path, name: &str) -> Result<(), BakeError> {
        let target = self.path.join(name);
        fs::rename(temporary, &target).map_err(io_error(&target, "rename into place"))?;
        sync_directory(&self.path)
    }

    /// Makes the staged bake the bake directory: checks `manifest` (which must list only staged
    /// map files), writes it, swaps the staging directory in for the old bake in one rename (see
    /// the module docs), then removes from the new bake every file the manifest does not list
    /// (the staged plan and reports).
    pub fn commit(self, manifest: &Manifest) -> Result<(), BakeError> {
        manifest.validate(&self.dir.join(MANIFEST_FILE_NAME))?;
        let mut listed = HashSet::new();
        for (index, lens) in manifest.lenses.iter().enumerate() {
            for (layer_index, layer) in lens.layers.iter().enumerate() {
                for (viewpoint, file) in layer.maps.iter().enumerate() {
                    if !self.contains(file) {
                        return Err(BakeError::MissingMap {
                            path: self.path.join(file),
                            field: format!(
                                "lenses[{index}].layers[{layer_index}].maps[{viewpoint}]"
                            ),
                        });
                    }
                    listed.insert(file.clone());
                }
            }
        }
        write_synced(
            &self.path.join(MANIFEST_FILE_NAME),
            manifest.to_json().as_bytes(),
        )?;
        sync_directory(&self.path)?;
        // Swap first, tidy after: until the new bake is in place the staged plan and reports
        // stay, so a kill or a failure here still resumes (and a failed swap keeps staging).
        swap_in_keeping(&self.path, &self.dir, &self.previous, &self.parent, true)?;
        let entries = fs::read_dir(&self.dir).map_err(io_error(&self.dir, "list"))?;
        for entry in entries {
            let entry = entry.map_err(io_error(&self.dir, "list"))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            if name != MANIFEST_FILE_NAME && !listed.contains(&name) {
                let path = entry.path();
                fs::remove_file(&path).map_err(io_error(&path, "remove"))?;
            }
        }
        sync_directory(&self.dir)
    }
}

impl Manifest {
    /// Reads `dir/manifest.json`, checks its format version, parses it and validates it
    /// ([`Manifest::validate`]); the cube-map files are not opened.
    pub fn read(dir: &Path) -> Result<Manifest, BakeError> {
        if !dir.is_dir() {
            if let Ok((parent, name)) = split_directory(dir) {
                let previous = parent.join(format!(".{name}.previous"));
                if previous.is_dir() {
                    return Err(BakeError::InterruptedSwap {
                        dir: dir.to_owned(),
                        previous,
                    });
                }
            }
            return Err(BakeError::MissingDirectory {
                dir: dir.to_owned(),
            });
        }
        let path = dir.join(MANIFEST_FILE_NAME);
        let text = match fs::read_to_string(&path) {
            Ok(text) => text,
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => {
                return Err(BakeError::MissingManifest { path });
            }
            Err(error) => return Err(io_error(&path, "read")(error)),
        };
        let syntax = |error: serde_json::Error| BakeError::ManifestSyntax {
            path: path.clone(),
            line: error.line(),
            column: error.column(),
            message: error.to_string(),
        };
        // The version first, so a newer format is reported as such rather than as odd fields.
        #[derive(Deserialize)]
        struct VersionOnly {
            format_version: Option<serde_json::Value>,
        }
        let version: VersionOnly = serde_json::from_str(&text).map_err(syntax)?;
        match version.format_version {
            Some(serde_json::Value::Number(n)) if n.as_u64() == Some(u64::from(FORMAT_VERSION)) => {
            }
            found => {
                return Err(BakeError::WrongVersion {
                    path,
                    found: found.map_or("missing".to_owned(), |v| v.to_string()),
                    expected: FORMAT_VERSION,
                });
            }
        }
        let manifest: Manifest = serde_json::from_str(&text).map_err(syntax)?;
        manifest.validate(&path)?;
        Ok(manifest)
    }

    /// The manifest as pretty-printed JSON (what `manifest.json` holds).
    pub fn to_json(&self) -> String {
        let mut json = serde_json::to_string_pretty(self)
            .unwrap_or_else(|error| unreachable!("a manifest always serializes: {error}"));
        json.push('\n');
        json
    }

    /// Checks the version, the cube-map size, that viewpoints and lens objects exist with finite
    /// positions and unique names, every shell ([`LayerShell::validate`]), one map file per
    /// viewpoint per layer, and that file names stay inside the bake directory. `path` is used in
    /// error messages.
    pub fn validate(&self, path: &Path) -> Result<(), BakeError> {
        let invalid = |field: String, problem: String, fix: &'static str| {
            Err(BakeError::Invalid {
                path: path.to_owned(),
                field,
                problem,
                fix,
            })
        };
        if self.format_version != FORMAT_VERSION {
            return Err(BakeError::WrongVersion {
                path: path.to_owned(),
                found: self.format_version.to_string(),
                expected: FORMAT_VERSION,
            });
        }
        if self.viewpoints.is_empty() {
            return invalid(
                "viewpoints".into(),
                "is empty".into(),
                "a bake needs at least one viewpoint sample",
            );
        }
        if let Some(i) = self.viewpoints.iter().position(|v| !v.is_finite()) {
            return invalid(
                format!("viewpoints[{i}]"),
                format!("is {} (not finite)", self.viewpoints[i]),
                "viewpoint positions must be finite metres",
            );
        }
        if self.lenses.is_empty() {
            return invalid(
                "lenses".into(),
                "is empty".into(),
                "a bake needs at least one lens object",
            );
        }
        if !self.cube_map_size.is_power_of_two() {
            return Err(BakeError::NonPowerOfTwo {
                path: path.to_owned(),
                size: self.cube_map_size,
            });
        }
        if let Some(provenance) = &self.provenance {
            if provenance.samples.len() != self.viewpoints.len() {
                return Err(BakeError::InconsistentCount {
                    path: path.to_owned(),
                    field: "provenance.samples".into(),
                    found: provenance.samples.len(),
                    what: "indices",
                    expected_from: "viewpoints".to_owned(),
                    expected: self.viewpoints.len(),
                    fix: "list one view-space index per viewpoint, or bake again",
                });
            }
            if provenance.samples.windows(2).any(|w| w[0] >= w[1]) {
                return invalid(
                    "provenance.samples".into(),
                    format!("{:?} is not strictly increasing", provenance.samples),
                    "list each view-space index once, in increasing order, or bake again",
                );
            }
        }
        let mut names = HashSet::new();
        // Every file listed so far (its path's components): (shell, EM origin) and the field
        // that listed it.
        let mut files: HashMap<PathBuf, ((LayerShell, DVec3), String)> = HashMap::new();
        for (index, lens) in self.lenses.iter().enumerate() {
            if lens.name.is_empty() || !names.insert(lens.name.as_str()) {
                return invalid(
                    format!("lenses[{index}].name"),
                    format!("'{}' is empty or used twice", lens.name),
                    "give every lens object a unique name",
                );
            }
            if !lens.em_origin.is_finite()
                || lens.em_origin.abs().max_element() > MAX_EM_ORIGIN_METRES
            {
                return invalid(
                    format!("lenses[{index}].em_origin"),
                    format!(
                        "is {} (not a finite point within {MAX_EM_ORIGIN_METRES:e} m of the origin)",
                        lens.em_origin
                    ),
                    "the EM origin is the lens object's centroid in metres; bake the scene again",
                );
            }
            if lens.layers.is_empty() {
                return invalid(
                    format!("lenses[{index}].layers"),
                    "is empty".into(),
                    "a lens object needs at least one layer",
                );
            }
            for (layer_index, layer) in lens.layers.iter().enumerate() {
                let field = format!("lenses[{index}].layers[{layer_index}]");
                if let Some(origin) = layer.em_origin
                    && (!origin.is_finite() || origin.abs().max_element() > MAX_EM_ORIGIN_METRES)
                {
                    return invalid(
                        format!("{field}.em_origin"),
                        format!(
                            "is {origin} (not a finite point within {MAX_EM_ORIGIN_METRES:e} m of the origin)"
                        ),
                        "a layer's EM origin is a point in metres; bake the scene again",
                    );
                }
                if let Err(error) = layer.shell.validate() {
                    return invalid(
                        format!("{field}.shell.{}", error.field),
                        error.problem,
                        "fix the shell's parameters",
                    );
                }
                if layer.maps.len() != self.viewpoints.len() {
                    return Err(BakeError::InconsistentCount {
                        path: path.to_owned(),
                        field: format!("{field}.maps"),
                        found: layer.maps.len(),
                        what: "files",
                        expected_from: "viewpoints".to_owned(),
                        expected: self.viewpoints.len(),
                        fix: "list one cube-map file per viewpoint sample for every layer",
                    });
                }
                for (viewpoint, file) in layer.maps.iter().enumerate() {
                    // A file listed twice is one map (a shared layer, or one map for several
                    // viewpoints): one shell and one origin parameterize it.
                    let listed = (layer.shell, lens.layer_origin(layer_index));
                    let key: PathBuf = Path::new(file).components().collect();
                    match files.get(&key) {
                        None => {
                            files.insert(key, (listed, format!("{field}.maps[{viewpoint}]")));
                        }
                        Some((first, first_field)) if *first != listed => {
                            return invalid(
                                format!("{field}.maps[{viewpoint}]"),
                                format!(
                                    "'{file}' is also {first_field}, with another shell or EM origin"
                                ),
                                "a map file may be listed twice only by layers that share it (same shell and EM origin); bake the scene again",
                            );
                        }
                        Some(_) => {}
                    }
                    let inside = !file.is_empty()
                        && Path::new(file)
                            .components()
                            .all(|c| matches!(c, Component::Normal(_)));
                    if !inside {
                        return invalid(
                            format!("{field}.maps[{viewpoint}]"),
                            format!("'{file}' is not a plain relative path"),
                            "name files relative to the bake directory, without '..'",
                        );
                    }
                }
            }
        }
        Ok(())
    }
}

/// Checks a cube map with the one cube-map validator ([`CubeMap::validate`]: size, full chain,
/// texel counts, finite texels with α in [0, 1] within [`ALPHA_TOLERANCE`]) and reports a problem
/// as the bake error that names `path` and the EXR part.
pub fn check_cube_map(cube: &CubeMap, size: u32, path: &Path) -> Result<(), BakeError> {
    cube.validate(Some(size))
        .map_err(|error| cube_map_error(error, path))
}

/// A cube-map problem as the bake error naming the file and its EXR part.
fn cube_map_error(error: CubeMapError, path: &Path) -> BakeError {
    let path = path.to_owned();
    match error {
        CubeMapError::NotPowerOfTwo { size } => BakeError::NonPowerOfTwo { path, size },
        CubeMapError::WrongSize { found, expected } => BakeError::WrongSize {
            path,
            part: part_name(0, 0),
            found: format!("{found}×{found}"),
            expected,
            size: expected,
        },
        CubeMapError::ExtraLevel {
            level,
            size,
            levels,
        } => BakeError::BadPart {
            path,
            part: part_name(level, 0),
            problem: format!("is beyond the {levels} levels of a {size}² cube map"),
        },
        CubeMapError::MissingLevel {
            level,
            size,
            levels,
        } => BakeError::MissingLevel {
            path,
            part: part_name(level, 0),
            size,
            levels,
        },
        CubeMapError::TexelCount {
            level,
            face,
            found,
            edge,
        } => BakeError::WrongSize {
            path,
            part: part_name(level, face.index()),
            found: format!("{found} texels"),
            expected: edge,
            size: edge << level,
        },
        CubeMapError::Texel {
            level,
            face,
            x,
            y,
            problem,
        } => texel_error(path, part_name(level, face.index()), x, y, problem),
    }
}

/// A bad texel as the bake error naming the file and part.
fn texel_error(
    path: PathBuf,
    part: String,
    x: usize,
    y: usize,
    problem: TexelProblem,
) -> BakeError {
    match problem {
        TexelProblem::NonFinite { channel, value } => BakeError::NonFinite {
            path,
            part,
            x,
            y,
            channel: ['R', 'G', 'B', 'A'][channel],
            value,
        },
        TexelProblem::AlphaOutOfRange { value } => BakeError::AlphaOutOfRange {
            path,
            part,
            x,
            y,
            value,
        },
    }
}

/// Writes `cube` as a cube-map EXR (the layout in the module docs) to `path` and fsyncs it.
/// Writes whatever levels `cube` has without checking its values (see [`check_cube_map`]); fails
/// only if a face's texel count does not match its level's size, or on I/O errors.
pub fn write_cube_map_exr(cube: &CubeMap, path: &Path) -> Result<(), BakeError> {
    use exr::prelude::*;
    let mut parts = Vec::with_capacity(cube.levels.len() * 6);
    for (level, faces) in cube.levels.iter().enumerate() {
        let edge = cube.level_size(level) as usize;
        for (face, texels) in faces.iter().enumerate() {
            let name = part_name(level, face);
            if texels.len() != edge * edge {
                return Err(BakeError::WrongSize {
                    path: path.to_owned(),
                    part: name,
                    found: format!("{} texels", texels.len()),
                    expected: edge as u32,
                    size: cube.size,
                });
            }
            let channel = |index: usize, channel_name: &str| {
                AnyChannel::new(
                    channel_name,
                    FlatSamples::F32(texels.iter().map(|texel| texel[index]).collect()),
                )
            };
            let channels = AnyChannels::sort(SmallVec::from_vec(vec![
                channel(0, "R"),
                channel(1, "G"),
                channel(2, "B"),
                channel(3, "A"),
            ]));
            parts.push(Layer::new(
                (edge, edge),
                LayerAttributes::named(name.as_str()),
                ENCODING,
                channels,
            ));
        }
    }
    let size = cube.size.max(1) as usize;
    let image = Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions((size, size))),
        parts,
    );
    let mut bytes = Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut bytes)
        .map_err(|error| BakeError::Exr {
            path: path.to_owned(),
            message: error.to_string(),
        })?;
    write_synced(path, bytes.get_ref())
}

/// Reads a cube-map EXR written by [`write_cube_map_exr`] and checks it against `size`: every
/// part of the full chain present once with f32 `R G B A` channels of the right size, and every
/// texel finite with α in [0, 1] (tolerance [`ALPHA_TOLERANCE`]).
pub fn read_cube_map_exr(path: &Path, size: u32) -> Result<CubeMap, BakeError> {
    use exr::prelude::*;
    let file = File::open(path).map_err(io_error(path, "open"))?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(BufReader::new(file))
        .map_err(|error| BakeError::Exr {
            path: path.to_owned(),
            message: error.to_string(),
        })?;
    let levels = CubeMap::full_chain_levels(size) as usize;
    let mut found: Vec<[Option<Vec<[f32; 4]>>; 6]> =
        (0..levels).map(|_| Default::default()).collect();
    for part in &image.layer_data {
        let name = part
            .attributes
            .layer_name
            .as_ref()
            .map_or_else(String::new, |name| name.to_string());
        let bad = |problem: String| BakeError::BadPart {
            path: path.to_owned(),
            part: name.clone(),
            problem,
        };
        let Some((level, face)) = parse_part_name(&name).filter(|(level, _)| *level < levels)
        else {
            return Err(bad(format!(
                "is not one of level0/+X … level{}/-Z",
                levels - 1
            )));
        };
        if found[level][face].is_some() {
            return Err(bad("appears twice".to_owned()));
        }
        let edge = (size >> level).max(1) as usize;
        if part.size.0 != edge || part.size.1 != edge {
            return Err(BakeError::WrongSize {
                path: path.to_owned(),
                part: name,
                found: format!("{}×{}", part.size.0, part.size.1),
                expected: edge as u32,
                size,
            });
        }
        let mut texels = vec![[0.0f32; 4]; edge * edge];
        for (index, channel_name) in ["R", "G", "B", "A"].into_iter().enumerate() {
            let channel = part
                .channel_data
                .list
                .iter()
                .find(|channel| channel.name.eq(channel_name))
                .ok_or_else(|| bad(format!("has no channel {channel_name}")))?;
            let FlatSamples::F32(samples) = &channel.sample_data else {
                return Err(bad(format!("channel {channel_name} is not 32-bit float")));
            };
            for (texel, value) in texels.iter_mut().zip(samples) {
                texel[index] = *value;
            }
        }
        check_face_texels(&texels, edge)
            .map_err(|(x, y, problem)| texel_error(path.to_owned(), name.clone(), x, y, problem))?;
        found[level][face] = Some(texels);
    }
    let mut chain = Vec::with_capacity(levels);
    for (level, faces) in found.into_iter().enumerate() {
        let mut complete = Vec::with_capacity(6);
        for (face, texels) in faces.into_iter().enumerate() {
            complete.push(texels.ok_or_else(|| BakeError::MissingLevel {
                path: path.to_owned(),
                part: part_name(level, face),
                size,
                levels: levels as u32,
            })?);
        }
        let faces: [Vec<[f32; 4]>; 6] = complete
            .try_into()
            .unwrap_or_else(|_| unreachable!("six faces were pushed"));
        chain.push(faces);
    }
    Ok(CubeMap {
        size,
        levels: chain,
    })
}

/// `level{l}/{face}` → `(l, face index)`.
fn parse_part_name(name: &str) -> Option<(usize, usize)> {
    let (level, face) = name.strip_prefix("level")?.split_once('/')?;
    let level = level.parse().ok()?;
    let face = FACE_NAMES.iter().position(|f| *f == face)?;
    Some((level, face))
}

/// The parent (`.` for a bare name) and final component of a bake directory path.
fn split_directory(dir: &Path) -> Result<(PathBuf, String), BakeError> {
    let name = dir
        .file_name()
        .and_then(|name| name.to_str())
        .ok_or_else(|| BakeError::Invalid {
            path: dir.to_owned(),
            field: "the bake directory".into(),
            problem: "has no final name (or is not UTF-8)".into(),
            fix: "name the directory itself, e.g. out/bake",
        })?;
    let parent = match dir.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_owned(),
        _ => PathBuf::from("."),
    };
    Ok((parent, name.to_owned()))
}

/// Finishes a swap an earlier write left half done: with `dir` gone and the old bake at
/// `previous`, puts it back; with both present (crash after the swap), drops `previous`.
fn restore_interrupted_swap(dir: &Path, previous: &Path) -> Result<(), BakeError> {
    if !previous.exists() {
        return Ok(());
    }
    if dir.exists() {
        fs::remove_dir_all(previous).map_err(io_error(previous, "remove"))
    } else {
        fs::rename(previous, dir).map_err(io_error(previous, "restore"))
    }
}

/// Whether a directory may be replaced: it holds a manifest, or nothing at all.
fn is_bake_or_empty(dir: &Path) -> bool {
    dir.join(MANIFEST_FILE_NAME).is_file()
        || fs::read_dir(dir).is_ok_and(|mut entries| entries.next().is_none())
}

/// Renames the complete `staging` directory to `dir`, moving an old bake aside to `previous`
/// first and removing it afterwards.
fn swap_in(staging: &Path, dir: &Path, previous: &Path, parent: &Path) -> Result<(), BakeError> {
    swap_in_keeping(staging, dir, previous, parent, false)
}

/// [`swap_in`]; with `keep_staging`, a failed rename leaves `staging` in place (a resumable
/// bake's staged work) instead of removing it.
fn swap_in_keeping(
    staging: &Path,
    dir: &Path,
    previous: &Path,
    parent: &Path,
    keep_staging: bool,
) -> Result<(), BakeError> {
    let had_old = dir.exists();
    if had_old {
        fs::rename(dir, previous).map_err(io_error(dir, "move aside"))?;
    }
    if let Err(error) = fs::rename(staging, dir) {
        if had_old {
            let _ = fs::rename(previous, dir);
        }
        if !keep_staging {
            let _ = fs::remove_dir_all(staging);
        }
        return Err(io_error(dir, "rename the staging directory to")(error));
    }
    sync_directory(parent)?;
    if had_old {
        // The new bake is in place; a leftover old one is removed by the next write.
        let _ = fs::remove_dir_all(previous);
    }
    Ok(())
}

/// Creates `path`, writes `bytes` and fsyncs the file.
fn write_synced(path: &Path, bytes: &[u8]) -> Result<(), BakeError> {
    let mut file = File::create(path).map_err(io_error(path, "create"))?;
    file.write_all(bytes).map_err(io_error(path, "write"))?;
    file.sync_all().map_err(io_error(path, "fsync"))
}

/// fsyncs a directory so that the names in it are durable.
fn sync_directory(dir: &Path) -> Result<(), BakeError> {
    File::open(dir)
        .and_then(|directory| directory.sync_all())
        .map_err(io_error(dir, "fsync"))
}

/// The farthest an EM origin may lie from the scene origin along any axis, metres: f32 texture
/// directions (`hit − origin`) lose all precision beyond it, so a manifest naming a farther
/// point is corrupt, not a scene.
pub const MAX_EM_ORIGIN_METRES: f64 = 1e6;

/// An I/O error naming the path a user knows: a path inside the staging, previous or temporary
/// names this module writes through is said as the bake path it stands for.
fn io_error(path: &Path, action: &'static str) -> impl FnOnce(std::io::Error) -> BakeError {
    let path = public_path(path);
    move |source| BakeError::Io {
        path,
        action,
        source,
    }
}

/// `path` with each internal name (`.NAME.baking`, `.NAME.writing-PID`, `.NAME.previous`,
/// `.NAME.tmp`) replaced by the `NAME` it stands for.
fn public_path(path: &Path) -> PathBuf {
    path.components()
        .map(|component| {
            let text = component.as_os_str().to_string_lossy();
            let public = text.strip_prefix('.').and_then(|rest| {
                [".baking", ".previous", ".tmp"]
                    .iter()
                    .find_map(|suffix| rest.strip_suffix(suffix))
                    .or_else(|| rest.rsplit_once(".writing-").map(|(name, _)| name))
            });
            match public {
                Some(name) if !name.is_empty() => std::ffi::OsString::from(name),
                _ => component.as_os_str().to_owned(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::public_path;
    use std::path::Path;

    #[test]
    fn errors_name_the_bake_paths_a_user_knows() {
        for (internal, public) in [
            (
                "/a/.bake.writing-4242/manifest.json",
                "/a/bake/manifest.json",
            ),
            ("/a/.bake.baking/.x.exr.tmp", "/a/bake/x.exr"),
            ("/a/.bake.previous", "/a/bake"),
            ("out/bake/lens0.exr", "out/bake/lens0.exr"),
            ("/a/.hidden/b", "/a/.hidden/b"),
            ("/a/..tmp", "/a/..tmp"),
        ] {
            assert_eq!(
                public_path(Path::new(internal)),
                Path::new(public),
                "{internal}"
            );
        }
    }
}
