//! A bake built piece by piece, sample by sample, in a staging directory beside its final place,
//! then committed in one swap ([`Staging`]).

use std::collections::HashSet;
use std::fs;
use std::path::{Path, PathBuf};

use super::compress::{MapReader, uncompressed_name};
use super::error::{BakeError, io_error};
use super::exr::{check_cube_map, encode_cube_map_exr};
use super::manifest::{MANIFEST_FILE_NAME, Manifest};
use crate::atomic::{self, DirectorySwap, WhenSwapFails, lock::DirectoryLock};
use crate::cubemap::CubeMap;

/// The suffix of a staging directory's name: `.NAME.baking` beside bake directory `NAME`.
pub(super) const STAGING_SUFFIX: &str = ".baking";

/// A bake built piece by piece in a staging directory beside its final place, `.NAME.baking`,
/// then committed atomically in one swap (as [`super::Bake::write`] does): what `lensmap bake`
/// writes sample by sample, so that a killed bake loses at most the sample in flight and never
/// the bake already at `NAME`. Every file is written atomically ([`crate::atomic`]), so a file
/// present under its own name is complete. One baker per directory at a time.
#[derive(Debug)]
pub struct Staging {
    swap: DirectorySwap,
    path: PathBuf,
    /// Held from opening to the commit (or until dropped): one baker per directory.
    _lock: DirectoryLock,
}

impl Staging {
    /// The staging directory of bake directory `dir`, created (with `dir`'s parents) when absent
    /// and kept when present, for resuming. The directory's lock is taken first (a bake another
    /// process is writing is refused, naming it), then a swap an earlier write left half done is
    /// finished; an existing `dir` that is not a bake is refused. Temporaries a killed writer
    /// left in staging are removed.
    pub fn open(dir: &Path) -> Result<Staging, BakeError> {
        let (swap, lock) = super::prepare_destination(dir)?;
        let path = swap.beside(STAGING_SUFFIX);
        if !path.is_dir() {
            fs::create_dir(&path).map_err(io_error(&path, "create"))?;
        }
        remove_temporaries(&path)?;
        Ok(Staging {
            swap,
            path,
            _lock: lock,
        })
    }

    /// The staging directory `lensmap bake` keeps bake directory `dir`'s finished samples in
    /// until the bake is complete: `.NAME.baking` beside it.
    pub fn path_of(dir: &Path) -> Option<PathBuf> {
        Some(DirectorySwap::new(dir)?.beside(STAGING_SUFFIX))
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
        self.swap.target()
    }

    /// Whether the complete file `name` is staged.
    pub fn contains(&self, name: &str) -> bool {
        self.path.join(name).is_file()
    }

    /// Writes `bytes` to `name` in the staging directory atomically (a temporary file, fsynced,
    /// renamed).
    pub fn write_file(&self, name: &str, bytes: &[u8]) -> Result<(), BakeError> {
        let path = self.path.join(name);
        atomic::write_atomically(&path, bytes).map_err(io_error(&path, "write"))
    }

    /// Checks `cube` (face size `size`) and writes it as cube-map EXR `name`, as
    /// [`Staging::write_file`] does; errors name the file's final path.
    pub fn write_cube_map(&self, name: &str, cube: &CubeMap, size: u32) -> Result<(), BakeError> {
        let final_path = self.final_dir().join(name);
        check_cube_map(cube, size, &final_path)?;
        self.write_file(name, &encode_cube_map_exr(cube, &final_path)?)
    }

    /// Copies the complete file `from` in as `name` (bytes unchanged), as
    /// [`Staging::write_file`] does.
    pub fn copy_in(&self, from: &Path, name: &str) -> Result<(), BakeError> {
        let bytes = fs::read(from).map_err(io_error(from, "read"))?;
        self.write_file(name, &bytes)
    }

    /// Stages map `name` of the bake `reader` reads, and returns the name it is staged under:
    /// an EXR file is copied as it is; a compressed one is decoded (from its keyframe) and
    /// written as the EXR [`super::compress::uncompressed_name`] names, since a compressed
    /// file cannot leave its chain.
    pub fn copy_map(&self, reader: &mut MapReader<'_>, name: &str) -> Result<String, BakeError> {
        if !reader.is_compressed() {
            self.copy_in(&reader.dir().join(name), name)?;
            return Ok(name.to_owned());
        }
        let staged = uncompressed_name(name);
        let cube = reader.read(name)?;
        self.write_cube_map(&staged, &cube, cube.size)?;
        Ok(staged)
    }

    /// Makes the staged bake the bake directory: checks `manifest` (which must list only staged
    /// map files), writes it, swaps the staging directory in for the old bake in one rename (see
    /// [`DirectorySwap`]), then removes from the new bake every file the manifest does not list
    /// (the staged plan and reports).
    pub fn commit(self, manifest: &Manifest) -> Result<(), BakeError> {
        let dir = self.final_dir();
        manifest.validate(&dir.join(MANIFEST_FILE_NAME))?;
        let mut listed = HashSet::new();
        for (index, lens) in manifest.lenses.iter().enumerate() {
            for (layer_index, layer) in lens.layers.iter().enumerate() {
                for (viewpoint, file) in layer.maps.iter().enumerate() {
                    if !self.contains(file) {
                        return Err(BakeError::MissingMap {
                            path: self.path.join(file),
                            manifest: super::MANIFEST_FILE_NAME,
                            field: format!(
                                "lenses[{index}].layers[{layer_index}].maps[{viewpoint}]"
                            ),
                        });
                    }
                    listed.insert(file.clone());
                }
            }
        }
        let manifest_path = self.path.join(MANIFEST_FILE_NAME);
        atomic::write_synced(&manifest_path, manifest.to_json().as_bytes())
            .map_err(io_error(&manifest_path, "write"))?;
        atomic::sync_directory(&self.path).map_err(io_error(&self.path, "fsync"))?;
        // Swap first, tidy after: until the new bake is in place the staged plan and reports
        // stay, so a kill or a failure here still resumes (and a failed swap keeps staging).
        let _barrier = atomic::swap_barrier();
        self.swap.swap_in(&self.path, WhenSwapFails::Keep)?;
        let entries = fs::read_dir(dir).map_err(io_error(dir, "list"))?;
        for entry in entries {
            let entry = entry.map_err(io_error(dir, "list"))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            if name != MANIFEST_FILE_NAME && !listed.contains(&name) {
                let path = entry.path();
                fs::remove_file(&path).map_err(io_error(&path, "remove"))?;
            }
        }
        atomic::sync_directory(dir).map_err(io_error(dir, "fsync"))
    }
}

/// Removes the temporaries of atomic writes (`.NAME.PID.tmp`) that a killed writer left in
/// staging directory `dir`: the lock is held, so none belongs to a live writer.
pub(crate) fn remove_temporaries(dir: &Path) -> Result<(), BakeError> {
    let entries = fs::read_dir(dir).map_err(io_error(dir, "list"))?;
    for entry in entries {
        let entry = entry.map_err(io_error(dir, "list"))?;
        let name = entry.file_name();
        if name
            .to_str()
            .is_some_and(|n| n.ends_with(".tmp") && atomic::stands_for(n).is_some())
        {
            let path = entry.path();
            fs::remove_file(&path).map_err(io_error(&path, "remove"))?;
        }
    }
    Ok(())
}
