//! Atomic file writes: a file is written beside its target under a temporary name, fsynced and
//! renamed over the target, so a failed write (a full disk, a killed process) leaves any earlier
//! file at that path intact, and a reader never sees half a file.

use std::fs::{self, File};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes `bytes` to `path` atomically (see the module documentation), creating the parent
/// folder if needed. Errors are the I/O error of the step that failed; the temporary file is
/// removed on failure.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    stage(path, bytes)?.commit()
}

/// A file written and fsynced beside its target under a temporary name, not yet in place:
/// [`Staged::commit`] renames it over the target, and dropping it uncommitted removes the
/// temporary. Staging every file of a set before committing any keeps the set together: a
/// failure while staging (a full disk) leaves every earlier file of the set as it was, not a new
/// PNG beside an old EXR.
#[derive(Debug)]
#[must_use = "a staged file is removed unless committed"]
pub struct Staged {
    /// The temporary and the target it replaces; `None` once committed, or for a special file
    /// (written directly: it cannot be replaced by renaming).
    pending: Option<(PathBuf, PathBuf)>,
}

/// Writes `bytes` beside `path` under a temporary name and fsyncs it, creating the parent folder
/// if needed; [`Staged::commit`] puts it in place. A symbolic link is written through (its target
/// is what gets replaced); a device, FIFO or other special file (`/dev/null`, `/dev/stdout`) is
/// written to directly here, as renaming cannot replace it.
pub fn stage(path: &Path, bytes: &[u8]) -> std::io::Result<Staged> {
    let resolved;
    let path = match fs::symlink_metadata(path) {
        Ok(meta) if meta.file_type().is_symlink() => {
            resolved = fs::canonicalize(path)?;
            if !fs::metadata(&resolved)?.is_file() {
                fs::write(&resolved, bytes)?;
                return Ok(Staged { pending: None });
            }
            resolved.as_path()
        }
        Ok(meta) if !meta.is_file() && !meta.is_dir() => {
            fs::write(path, bytes)?;
            return Ok(Staged { pending: None });
        }
        _ => path,
    };
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    fs::create_dir_all(parent)?;
    let temporary = temporary_path(path);
    let written = (|| {
        let mut file = File::create(&temporary)?;
        file.write_all(bytes)?;
        file.sync_all()
    })();
    if let Err(error) = written {
        let _ = fs::remove_file(&temporary);
        return Err(error);
    }
    Ok(Staged {
        pending: Some((temporary, path.to_path_buf())),
    })
}

impl Staged {
    /// Renames the staged file over its target and syncs the folder.
    pub fn commit(mut self) -> std::io::Result<()> {
        let Some((temporary, target)) = self.pending.take() else {
            return Ok(());
        };
        if let Err(error) = fs::rename(&temporary, &target) {
            let _ = fs::remove_file(&temporary);
            return Err(error);
        }
        // The rename is durable once the folder is; a folder that cannot be opened to sync (some
        // file systems) still holds the new file.
        let parent = target
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        if let Ok(folder) = File::open(parent) {
            let _ = folder.sync_all();
        }
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if let Some((temporary, _)) = self.pending.take() {
            let _ = fs::remove_file(temporary);
        }
    }
}

/// `.NAME.PID.tmp` beside `path`: hidden, and unique per process.
fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_the_file_and_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("lensmap-atomic-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        let path = dir.join("sub").join("a.txt");
        write_atomically(&path, b"first").unwrap();
        write_atomically(&path, b"second").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"second");
        let names: Vec<_> = fs::read_dir(path.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["a.txt"]);
        // A target that cannot be replaced (a folder is in the way) fails and keeps it.
        let blocked = dir.join("blocked");
        fs::create_dir_all(blocked.join("inside")).unwrap();
        assert!(write_atomically(&blocked, b"x").is_err());
        assert!(blocked.join("inside").is_dir());
        assert_eq!(
            fs::read_dir(&dir).unwrap().count(),
            2,
            "no temporary left behind"
        );
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_staged_file_is_in_place_only_once_committed() {
        let dir = std::env::temp_dir().join(format!("lensmap-staged-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        let (a, b) = (dir.join("a.png"), dir.join("a.exr"));
        write_atomically(&a, b"old a").unwrap();
        write_atomically(&b, b"old b").unwrap();
        // The second of a pair fails to stage (its folder would be a file): the first is dropped
        // uncommitted, and both earlier files stay.
        let staged = stage(&a, b"new a").unwrap();
        assert!(stage(&a.join("b.exr"), b"new b").is_err());
        drop(staged);
        assert_eq!(fs::read(&a).unwrap(), b"old a");
        assert_eq!(fs::read(&b).unwrap(), b"old b");
        let (sa, sb) = (stage(&a, b"new a").unwrap(), stage(&b, b"new b").unwrap());
        sa.commit().unwrap();
        sb.commit().unwrap();
        assert_eq!(fs::read(&a).unwrap(), b"new a");
        assert_eq!(fs::read(&b).unwrap(), b"new b");
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 2, "no temporary left");
        fs::remove_dir_all(&dir).unwrap();
    }
}
