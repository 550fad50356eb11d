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
    // A symbolic link is written through (its target replaced, not the link); a device, FIFO
    // or other special file (`/dev/null`, `/dev/stdout`) cannot be replaced by renaming, so it
    // is written to directly.
    let resolved;
    let path = match fs::symlink_metadata(path) {
        Ok(meta) if meta.file_type().is_symlink() => {
            resolved = fs::canonicalize(path)?;
            if !fs::metadata(&resolved)?.is_file() {
                return fs::write(&resolved, bytes);
            }
            resolved.as_path()
        }
        Ok(meta) if !meta.is_file() && !meta.is_dir() => return fs::write(path, bytes),
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
        file.sync_all()?;
        fs::rename(&temporary, path)
    })();
    if written.is_err() {
        let _ = fs::remove_file(&temporary);
        return written;
    }
    // The rename is durable once the folder is; a folder that cannot be opened to sync (some
    // file systems) still holds the new file.
    if let Ok(folder) = File::open(parent) {
        let _ = folder.sync_all();
    }
    Ok(())
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
}
