//! `manifest.json`: everything about a bake but the texels ([`Manifest`]), its reader (format
//! version first, then the fields, then every check of [`Manifest::validate`]) and its writer.

use std::collections::{HashMap, HashSet};
use std::fs;
use std::path::{Component, Path, PathBuf};

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use super::compress::Compression;
use super::error::{BakeError, CountCheck, io_error};
use crate::atomic::DirectorySwap;
use crate::gpu::DeviceId;
use crate::identity::IDENTITY_VERSION;
use crate::index::{LayerIndex, LayerRef, LensIndex};
use crate::layers::{Layering, shell::LayerShell};

/// The manifest format this code writes and reads.
pub const FORMAT_VERSION: u32 = 1;

/// File name of the manifest inside a bake directory.
pub const MANIFEST_FILE_NAME: &str = "manifest.json";

/// The farthest an EM origin may lie from the scene origin along any axis, metres: f32 texture
/// directions (`hit − origin`) lose all precision beyond it, so a manifest naming a farther
/// point is corrupt, not a scene.
pub const MAX_EM_ORIGIN_METRES: f64 = 1e6;

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
    /// How the maps are compressed (see [`super::compress`]); absent in an uncompressed bake,
    /// whose maps are EXR files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compression: Option<Compression>,
}

/// What a bake was made from, so that one made from another scene or with other options is
/// refused instead of rendered wrong.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Provenance {
    /// The version of the canonical encoding the two hashes were computed with
    /// ([`crate::identity::IDENTITY_VERSION`]). A bake written before lensmap had one reads as 0:
    /// its hashes (of `Debug` text) cannot be compared with this lensmap's, see
    /// [`Provenance::is_current`].
    #[serde(default)]
    pub identity_version: u32,
    /// The scene's content hash (`Scene::content_hash`): geometry, materials, lights, the
    /// environment, the lens objects, the view space and the camera's aim.
    pub scene_hash: String,
    /// Hash of every bake option that changes the maps (resolution, EM size, layers, views…).
    pub options_hash: String,
    /// The view-space index of each viewpoint, in the order of `viewpoints`: strictly increasing.
    pub samples: Vec<usize>,
    /// Which device and driver baked which samples (absent in bakes made before lensmap
    /// recorded it). Provenance, not identity: resuming, merging and rendering do not compare
    /// it, since the rendering matrices come from the device and two conformant drivers' maps
    /// of one sample differ only by what their rasterization may differ by.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub baked_on: Vec<BakedOn>,
    /// The path classes whose equations the maps were solved over
    /// ([`crate::trace::classes::ClassSet::name`], e.g. `"4"`); absent for the papers' two
    /// greedy terms, what every bake made before classes solved. In the options hash too; here
    /// so that a frame drawing the bake can say when its own terms are others.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub terms: Option<String>,
}

/// Samples of a bake made on one device and driver.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BakedOn {
    /// The device and its driver.
    pub device: DeviceId,
    /// The view-space indices it baked, increasing.
    pub samples: Vec<usize>,
}

impl BakedOn {
    /// `(sample, device)` pairs grouped by device, in the order devices first appear, each
    /// group's samples increasing; pairs without a device (samples whose baker is not known)
    /// are left out.
    pub fn group(pairs: impl IntoIterator<Item = (usize, Option<DeviceId>)>) -> Vec<BakedOn> {
        let mut groups: Vec<BakedOn> = Vec::new();
        for (sample, device) in pairs {
            let Some(device) = device else { continue };
            match groups.iter_mut().find(|g| g.device == device) {
                Some(group) => group.samples.push(sample),
                None => groups.push(BakedOn {
                    device,
                    samples: vec![sample],
                }),
            }
        }
        for group in &mut groups {
            group.samples.sort_unstable();
            group.samples.dedup();
        }
        groups
    }

    /// The device that baked `sample` according to `baked_on`, if recorded.
    pub fn device_of(baked_on: &[BakedOn], sample: usize) -> Option<&DeviceId> {
        baked_on
            .iter()
            .find(|g| g.samples.contains(&sample))
            .map(|g| &g.device)
    }
}

impl Provenance {
    /// The provenance of a bake of `samples`, made from the scene with content hash `scene_hash`
    /// with the options hashed `options_hash`, in this lensmap's identity version.
    pub fn new(scene_hash: String, options_hash: String, samples: Vec<usize>) -> Provenance {
        Provenance {
            identity_version: IDENTITY_VERSION,
            scene_hash,
            options_hash,
            samples,
            baked_on: Vec::new(),
            terms: None,
        }
    }

    /// Whether the hashes were computed with this lensmap's [`IDENTITY_VERSION`], so that they can
    /// be compared with a scene's and options' hashes at all.
    pub fn is_current(&self) -> bool {
        self.identity_version == IDENTITY_VERSION
    }
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
    /// How rays are split between the layers (absent: by distance). By bounce, there are two
    /// layers: local, then distant.
    #[serde(default, skip_serializing_if = "Layering::is_distance")]
    pub layering: Layering,
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

impl Manifest {
    /// Reads `dir/manifest.json`, checks its format version, parses it and validates it
    /// ([`Manifest::validate`]); the cube-map files are not opened.
    pub fn read(dir: &Path) -> Result<Manifest, BakeError> {
        if !dir.is_dir() {
            if let Some(previous) =
                DirectorySwap::new(dir).and_then(|swap| swap.interrupted().map(Path::to_owned))
            {
                return Err(BakeError::InterruptedSwap {
                    dir: dir.to_owned(),
                    previous,
                });
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
    /// viewpoint per layer, that file names stay inside the bake directory, and the
    /// compression section ([`Compression::validate`]). `path` is used in
    /// error messages.
    pub fn validate(&self, path: &Path) -> Result<(), BakeError> {
        self.validate_header(path)?;
        let mut names = HashSet::new();
        let mut files = ListedFiles::default();
        for (index, lens) in self.lenses.iter().enumerate() {
            if lens.name.is_empty() || !names.insert(lens.name.as_str()) {
                return invalid(
                    path,
                    format!("lenses[{index}].name"),
                    format!("'{}' is empty or used twice", lens.name),
                    "give every lens object a unique name",
                );
            }
            if !within_reach(lens.em_origin) {
                return invalid(
                    path,
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
                    path,
                    format!("lenses[{index}].layers"),
                    "is empty".into(),
                    "a lens object needs at least one layer",
                );
            }
            for layer in LayerIndex::all(lens.layers.len()) {
                let at = LensIndex::new(index).layer(layer);
                self.validate_layer(path, lens, at, &mut files)?;
            }
        }
        if let Some(compression) = &self.compression {
            let listed: Vec<&str> = self
                .lenses
                .iter()
                .flat_map(|lens| &lens.layers)
                .flat_map(|layer| &layer.maps)
                .map(String::as_str)
                .collect();
            compression.validate(path, &listed)?;
        }
        Ok(())
    }

    /// The checks of [`Manifest::validate`] on everything but the lens objects: the version,
    /// the viewpoints, the cube-map size and the provenance.
    fn validate_header(&self, path: &Path) -> Result<(), BakeError> {
        if self.format_version != FORMAT_VERSION {
            return Err(BakeError::WrongVersion {
                path: path.to_owned(),
                found: self.format_version.to_string(),
                expected: FORMAT_VERSION,
            });
        }
        if self.viewpoints.is_empty() {
            return invalid(
                path,
                "viewpoints".into(),
                "is empty".into(),
                "a bake needs at least one viewpoint sample",
            );
        }
        if let Some(i) = self.viewpoints.iter().position(|v| !v.is_finite()) {
            return invalid(
                path,
                format!("viewpoints[{i}]"),
                format!("is {} (not finite)", self.viewpoints[i]),
                "viewpoint positions must be finite metres",
            );
        }
        if self.lenses.is_empty() {
            return invalid(
                path,
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
            self.per_viewpoint(path).require(
                "provenance.samples".into(),
                provenance.samples.len(),
                "indices",
                "list one view-space index per viewpoint, or bake again",
            )?;
            if provenance.samples.windows(2).any(|w| w[0] >= w[1]) {
                return invalid(
                    path,
                    "provenance.samples".into(),
                    format!("{:?} is not strictly increasing", provenance.samples),
                    "list each view-space index once, in increasing order, or bake again",
                );
            }
        }
        Ok(())
    }

    /// The check that a list has one entry per viewpoint.
    pub(super) fn per_viewpoint<'a>(&self, path: &'a Path) -> CountCheck<'a> {
        CountCheck {
            path,
            expected_from: "viewpoints",
            expected: self.viewpoints.len(),
        }
    }

    /// The checks of [`Manifest::validate`] on layer `at` (of lens object `lens`): its EM
    /// origin, its shell and its files, which `files` collects across layers.
    fn validate_layer(
        &self,
        path: &Path,
        lens: &ManifestLens,
        at: LayerRef,
        files: &mut ListedFiles,
    ) -> Result<(), BakeError> {
        let layer = &lens.layers[at.layer.index()];
        let field = format!("lenses[{}].layers[{}]", at.lens, at.layer);
        if let Some(origin) = layer.em_origin
            && !within_reach(origin)
        {
            return invalid(
                path,
                format!("{field}.em_origin"),
                format!(
                    "is {origin} (not a finite point within {MAX_EM_ORIGIN_METRES:e} m of the origin)"
                ),
                "a layer's EM origin is a point in metres; bake the scene again",
            );
        }
        if let Err(error) = layer.shell.validate() {
            return invalid(
                path,
                format!("{field}.shell.{}", error.field),
                error.problem,
                "fix the shell's parameters",
            );
        }
        self.per_viewpoint(path).require(
            format!("{field}.maps"),
            layer.maps.len(),
            "files",
            "list one cube-map file per viewpoint sample for every layer",
        )?;
        for (viewpoint, file) in layer.maps.iter().enumerate() {
            // A file listed twice is one map (a shared layer, or one map for several
            // viewpoints): one shell and one origin parameterize it.
            let listed = (layer.shell, lens.layer_origin(at.layer.index()));
            let key: PathBuf = Path::new(file).components().collect();
            match files.get(&key) {
                None => {
                    files.insert(key, (listed, format!("{field}.maps[{viewpoint}]")));
                }
                Some((first, first_field)) if *first != listed => {
                    return invalid(
                        path,
                        format!("{field}.maps[{viewpoint}]"),
                        format!("'{file}' is also {first_field}, with another shell or EM origin"),
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
                    path,
                    format!("{field}.maps[{viewpoint}]"),
                    format!("'{file}' is not a plain relative path"),
                    "name files relative to the bake directory, without '..'",
                );
            }
        }
        Ok(())
    }
}

/// Every file listed so far (its path's components): the (shell, EM origin) it is listed with
/// and the field that listed it first.
type ListedFiles = HashMap<PathBuf, ((LayerShell, DVec3), String)>;

/// Whether `point` is finite and within [`MAX_EM_ORIGIN_METRES`] of the origin on every axis.
fn within_reach(point: DVec3) -> bool {
    point.is_finite() && point.abs().max_element() <= MAX_EM_ORIGIN_METRES
}

/// [`BakeError::Invalid`] naming `path`, `field`, the problem and the fix.
fn invalid(
    path: &Path,
    field: String,
    problem: String,
    fix: &'static str,
) -> Result<(), BakeError> {
    Err(BakeError::Invalid {
        path: path.to_owned(),
        field,
        problem,
        fix,
    })
}
