//! Why a bake cannot be read or written ([`BakeError`]): every message one line naming the file,
//! the field and the fix, and a path the user knows (never a staging or temporary name).

use std::path::{Path, PathBuf};

use super::ALPHA_TOLERANCE;
use crate::atomic::StepError;

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
    /// The manifest's format version is not [`FORMAT_VERSION`](super::FORMAT_VERSION).
    #[error(
        "{}: format_version is {found}, but this lensmap reads version {expected}; write the bake again with this lensmap",
        path.display()
    )]
    WrongVersion {
        /// The manifest path.
        path: PathBuf,
        /// What the file says (`missing` when absent).
        found: String,
        /// [`FORMAT_VERSION`](super::FORMAT_VERSION).
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
    /// [`Bake::write`](super::Bake::write) was pointed at a directory that is not a bake; it will not replace it.
    #[error(
        "{}: exists and is not a bake (no manifest.json); writing would replace it, so choose another directory or remove it",
        dir.display()
    )]
    NotABake {
        /// The directory.
        dir: PathBuf,
    },
    /// A cube-map file listed in the manifest is missing.
    #[error("{}: not found (listed in {manifest} at {field}); restore the file or write the bake again", path.display())]
    MissingMap {
        /// The file.
        path: PathBuf,
        /// The manifest that lists it (`manifest.json`, `radiance.json`).
        manifest: &'static str,
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
    /// A compressed cube-map file is truncated, changed, of another scene or undecodable.
    #[error("{}: {problem}; {fix}", path.display())]
    Compressed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
        /// How to fix it.
        fix: &'static str,
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
    /// Another writer holds the bake directory's lock, or the lock could not be taken.
    #[error(transparent)]
    Lock(#[from] crate::atomic::lock::LockError),
}

impl From<StepError> for BakeError {
    fn from(error: StepError) -> BakeError {
        io_error(&error.path, error.action)(error.source)
    }
}

/// Checks the length of lists that must have one entry per entry of another list (`expected_from`,
/// of length `expected`), naming `path` in the error.
pub(super) struct CountCheck<'a> {
    /// The manifest path (or the directory being written).
    pub path: &'a Path,
    /// The list the lengths must match, e.g. `viewpoints`.
    pub expected_from: &'a str,
    /// Its length.
    pub expected: usize,
}

impl CountCheck<'_> {
    /// `Ok` when list `field` (of `found` `what`) has the expected length, else
    /// [`BakeError::InconsistentCount`] with `fix`.
    pub fn require(
        &self,
        field: String,
        found: usize,
        what: &'static str,
        fix: &'static str,
    ) -> Result<(), BakeError> {
        if found == self.expected {
            return Ok(());
        }
        Err(BakeError::InconsistentCount {
            path: self.path.to_owned(),
            field,
            found,
            what,
            expected_from: self.expected_from.to_owned(),
            expected: self.expected,
            fix,
        })
    }
}

/// An I/O error naming the path a user knows: a path inside the staging, previous or temporary
/// names a bake is written through is said as the bake path it stands for.
pub(crate) fn io_error(
    path: &Path,
    action: &'static str,
) -> impl FnOnce(std::io::Error) -> BakeError {
    let path = public_path(path);
    move |source| BakeError::Io {
        path,
        action,
        source,
    }
}

/// `path` with each internal name (`.NAME.baking`, `.NAME.writing-PID`, and the temporary names
/// of [`crate::atomic`]: `.NAME.previous`, `.NAME.PID.tmp`) replaced by the `NAME` it stands for.
fn public_path(path: &Path) -> PathBuf {
    path.components()
        .map(|component| {
            let text = component.as_os_str().to_string_lossy();
            let public = crate::atomic::stands_for(&text).or_else(|| {
                let rest = text.strip_prefix('.')?;
                rest.strip_suffix(super::staging::STAGING_SUFFIX)
                    .or_else(|| {
                        rest.rsplit_once(super::WRITING_SUFFIX)
                            .map(|(name, _)| name)
                    })
                    .filter(|name| !name.is_empty())
            });
            match public {
                Some(name) => std::ffi::OsString::from(name),
                None => component.as_os_str().to_owned(),
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
            ("/a/.bake.baking/.x.exr.4242.tmp", "/a/bake/x.exr"),
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
