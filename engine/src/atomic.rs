//! Atomic writes. A file is written beside its target under a temporary name, fsynced and
//! renamed over the target, so a failed write (a full disk, a killed process) leaves any earlier
//! file at that path intact, and a reader never sees half a file. A directory is built complete
//! beside its target and swapped in by one atomic exchange ([`DirectorySwap`]), with the same
//! guarantee for the directory as a whole; a reader that reads a directory's files one by one
//! sees one version of it with [`read_consistently`]. One writer per directory at a time:
//! [`lock::DirectoryLock`].

pub mod lock;

use std::fs::{self, File};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

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
    fs::create_dir_all(parent_of(path))?;
    let temporary = temporary_path(path);
    if let Err(error) = write_synced(&temporary, bytes) {
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
        let _ = sync_directory(parent_of(&target));
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

/// The `NAME` a temporary name this module gives stands for: `.NAME.PID.tmp` (a staged file)
/// and `.NAME.previous` (a directory moved aside by [`DirectorySwap`]) are `NAME`; `None` for any
/// other name.
pub fn stands_for(name: &str) -> Option<&str> {
    let rest = name.strip_prefix('.')?;
    let public = match rest.strip_suffix(".tmp") {
        Some(staged) => staged
            .rsplit_once('.')
            .filter(|(_, pid)| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
            .map_or(staged, |(name, _)| name),
        None => rest.strip_suffix(PREVIOUS_SUFFIX)?,
    };
    (!public.is_empty()).then_some(public)
}

/// The folder holding `path` (`.` for a bare name).
fn parent_of(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// Creates `path`, writes `bytes` and fsyncs the file: not atomic by itself, for the files of a
/// directory that is swapped in whole ([`DirectorySwap`]) and for [`stage`]'s temporaries.
pub fn write_synced(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut file = File::create(path)?;
    file.write_all(bytes)?;
    file.sync_all()
}

/// fsyncs a folder so that the names in it (a rename, a new file) are durable.
pub fn sync_directory(dir: &Path) -> std::io::Result<()> {
    File::open(dir).and_then(|folder| folder.sync_all())
}

/// The suffix of the name an old directory is moved aside to during a swap.
const PREVIOUS_SUFFIX: &str = ".previous";

/// The suffix of the lock file of a swap by two renames ([`DirectorySwap::swapping_path`]).
const SWAPPING_SUFFIX: &str = ".swapping";

/// A step of a directory swap that the file system refused: which path, doing what.
#[derive(Debug, thiserror::Error)]
#[error("{}: cannot {action}: {source}", path.display())]
pub struct StepError {
    /// The file or folder.
    pub path: PathBuf,
    /// What was being done (`create`, `move aside`, `restore`, …).
    pub action: &'static str,
    /// The operating system's error.
    pub source: std::io::Error,
}

impl StepError {
    /// The error of `action` on `path`, for `map_err`.
    pub fn of(path: &Path, action: &'static str) -> impl FnOnce(std::io::Error) -> StepError {
        let path = path.to_owned();
        move |source| StepError {
            path,
            action,
            source,
        }
    }
}

/// What becomes of a built directory whose swap fails.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WhenSwapFails {
    /// Removed (a temporary nobody resumes).
    Remove,
    /// Kept where it is (work that a later run resumes).
    Keep,
}

/// A directory `NAME` replaced as a whole. The replacement is built complete under a hidden name
/// beside it ([`DirectorySwap::beside`]), every file fsynced, then swapped in
/// ([`DirectorySwap::swap_in`]) by one atomic exchange of the two names (Linux `renameat2` with
/// `RENAME_EXCHANGE`), after which the old directory, now under the hidden name, is removed: at
/// every moment `NAME` is the old directory or the new one. On a file system without the
/// exchange (NFS, an old kernel) it takes two renames instead: the old directory to
/// `.NAME.previous`, the new one to `NAME`, under an exclusive `flock` on the file
/// `.NAME.swapping` that [`read_consistently`] takes shared to tell a swap under way from a
/// missing directory; an interruption between them leaves the old one at `.NAME.previous`,
/// which [`DirectorySwap::prepare`] puts back (or, if the new one made it to `NAME`, removes)
/// before the next swap starts. An
/// interruption before the swap leaves the old directory untouched at `NAME`. One writer per
/// directory at a time ([`lock::DirectoryLock`]).
#[derive(Clone, Debug)]
pub struct DirectorySwap {
    target: PathBuf,
    parent: PathBuf,
    name: String,
    previous: PathBuf,
}

impl DirectorySwap {
    /// The swap of directory `target`; `None` when it has no final name in UTF-8 (`..`, `/`).
    /// Touches nothing.
    pub fn new(target: &Path) -> Option<DirectorySwap> {
        let name = target.file_name()?.to_str()?.to_owned();
        let parent = parent_of(target).to_owned();
        Some(DirectorySwap {
            target: target.to_owned(),
            previous: parent.join(format!(".{name}{PREVIOUS_SUFFIX}")),
            parent,
            name,
        })
    }

    /// The directory replaced.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// `.NAME{suffix}` beside the target: a hidden place to build the replacement in.
    pub fn beside(&self, suffix: &str) -> PathBuf {
        self.parent.join(format!(".{}{suffix}", self.name))
    }

    /// Where the old directory lies while a swap is under way, when a swap was interrupted
    /// between its two renames (the target is missing and the old directory is there).
    pub fn interrupted(&self) -> Option<&Path> {
        (!self.target.is_dir() && self.previous.is_dir()).then_some(self.previous.as_path())
    }

    /// `.NAME.swapping`: the file a swap by two renames holds an exclusive `flock` on between
    /// them. It is created before the first such swap and then left in place (removing a lock
    /// file races with its next taker).
    fn swapping_path(&self) -> PathBuf {
        self.beside(SWAPPING_SUFFIX)
    }

    /// Takes the exclusive lock of a swap by two renames ([`DirectorySwap::swapping_path`]),
    /// waiting for readers that hold it shared for the moment of one `stat`.
    fn swapping_lock(&self) -> Result<File, StepError> {
        let path = self.swapping_path();
        let file = fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(StepError::of(&path, "create"))?;
        rustix::fs::flock(&file, rustix::fs::FlockOperation::LockExclusive)
            .map_err(|e| StepError::of(&path, "lock")(e.into()))?;
        Ok(file)
    }

    /// Whether the target is missing with no swap by two renames between its renames: a swap
    /// started after the target went missing creates `.NAME.swapping` before its first rename,
    /// so no such file means none was under way; otherwise the target is looked at again while
    /// holding that file's lock shared, which no swap on this host can start or be halfway
    /// through, and the moved-aside `.NAME.previous` must be absent too (a swap from another
    /// host where `flock` stays on each host, or one interrupted for good: the caller's retries
    /// then end in the read's error). `None` when that cannot be told now (the caller tries
    /// again).
    fn missing_with_no_swap_under_way(&self) -> Option<bool> {
        let lock = match File::open(self.swapping_path()) {
            Ok(lock) => lock,
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => return Some(true),
            Err(_) => return None,
        };
        match rustix::fs::flock(&lock, rustix::fs::FlockOperation::NonBlockingLockShared) {
            Err(rustix::io::Errno::WOULDBLOCK) => None,
            // Held shared, or a file system without flock: the moved-aside directory tells.
            _ => Some(version_of(&self.target).is_none() && !self.previous.is_dir()),
        }
    }

    /// Creates the parent folders and finishes a swap an earlier run left half done: with the
    /// target gone and the old directory at `.NAME.previous`, puts it back; with both present
    /// (a crash after the swap), removes the old one.
    pub fn prepare(&self) -> Result<(), StepError> {
        fs::create_dir_all(&self.parent).map_err(StepError::of(&self.parent, "create"))?;
        if !self.previous.exists() {
            return Ok(());
        }
        if self.target.exists() {
            fs::remove_dir_all(&self.previous).map_err(StepError::of(&self.previous, "remove"))
        } else {
            fs::rename(&self.previous, &self.target)
                .map_err(StepError::of(&self.previous, "restore"))
        }
    }

    /// Makes the complete directory `built` the target (see the type's documentation) and syncs
    /// the parent folder. When the exchange or a rename fails, the old directory stays (or is put
    /// back) and `built` is removed or kept as `when_fails` says.
    pub fn swap_in(&self, built: &Path, when_fails: WhenSwapFails) -> Result<(), StepError> {
        self.swap_in_by(built, when_fails, SwapMethod::Exchange)
    }

    /// [`DirectorySwap::swap_in`] by `method` (tests force the fallback of two renames).
    fn swap_in_by(
        &self,
        built: &Path,
        when_fails: WhenSwapFails,
        method: SwapMethod,
    ) -> Result<(), StepError> {
        let had_old = self.target.exists();
        if had_old && method == SwapMethod::Exchange {
            match exchange(built, &self.target) {
                Ok(()) => {
                    sync_directory(&self.parent).map_err(StepError::of(&self.parent, "fsync"))?;
                    // `built` now names the old directory.
                    let _ = fs::remove_dir_all(built);
                    SWAPS_DONE.fetch_add(1, std::sync::atomic::Ordering::Release);
                    return Ok(());
                }
                Err(error) if !exchange_unsupported(&error) => {
                    if when_fails == WhenSwapFails::Remove {
                        let _ = fs::remove_dir_all(built);
                    }
                    return Err(StepError::of(
                        &self.target,
                        "exchange the staging directory with",
                    )(error));
                }
                // A file system without the exchange: two renames, below.
                Err(_) => {}
            }
        }
        // Readers that find the target missing wait for this lock before they believe it.
        let swapping = had_old.then(|| self.swapping_lock()).transpose()?;
        if had_old {
            fs::rename(&self.target, &self.previous)
                .map_err(StepError::of(&self.target, "move aside"))?;
        }
        if let Err(error) = fs::rename(built, &self.target) {
            if had_old {
                let _ = fs::rename(&self.previous, &self.target);
            }
            drop(swapping);
            if when_fails == WhenSwapFails::Remove {
                let _ = fs::remove_dir_all(built);
            }
            return Err(StepError::of(
                &self.target,
                "rename the staging directory to",
            )(error));
        }
        drop(swapping);
        sync_directory(&self.parent).map_err(StepError::of(&self.parent, "fsync"))?;
        if had_old {
            // The new directory is in place; an old one left over is removed by the next prepare.
            let _ = fs::remove_dir_all(&self.previous);
        }
        SWAPS_DONE.fetch_add(1, std::sync::atomic::Ordering::Release);
        Ok(())
    }
}

/// How [`DirectorySwap::swap_in_by`] swaps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SwapMethod {
    /// One atomic exchange where the file system has it, else two renames.
    Exchange,
    /// Two renames.
    #[cfg_attr(not(test), allow(dead_code))]
    Renames,
}

/// Exchanges two existing paths in one step (Linux `renameat2` with `RENAME_EXCHANGE`): a reader
/// of either path finds something there at every moment.
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    use rustix::fs::{CWD, RenameFlags, renameat_with};
    renameat_with(CWD, a, CWD, b, RenameFlags::EXCHANGE).map_err(std::io::Error::from)
}

/// Elsewhere there is no atomic exchange: the caller falls back to two renames.
#[cfg(not(target_os = "linux"))]
fn exchange(_: &Path, _: &Path) -> std::io::Result<()> {
    Err(std::io::ErrorKind::Unsupported.into())
}

/// Whether `exchange` failed for want of support (an old kernel, a file system without it, such
/// as NFS) rather than for the paths.
fn exchange_unsupported(error: &std::io::Error) -> bool {
    use rustix::io::Errno;
    error.kind() == std::io::ErrorKind::Unsupported
        || [Errno::INVAL, Errno::NOSYS, Errno::OPNOTSUPP]
            .iter()
            .any(|errno| error.raw_os_error() == Some(errno.raw_os_error()))
}

/// What identifies one version of a directory: its device, inode and change time.
type Version = (u64, u64, i64, i64);

fn version_from(stat: &rustix::fs::Stat) -> Version {
    #[allow(clippy::unnecessary_cast, clippy::useless_conversion)]
    (
        stat.st_dev as u64,
        stat.st_ino as u64,
        stat.st_ctime as i64,
        stat.st_ctime_nsec as i64,
    )
}

/// The version of the directory at `dir` now, `None` when there is none.
fn version_of(dir: &Path) -> Option<Version> {
    rustix::fs::stat(dir).ok().map(|stat| version_from(&stat))
}

/// The directory at `dir` opened, with its version: while the handle is open its inode number
/// cannot be given to another directory on this host, so finding the same number at `dir` later
/// means the same directory (a swap that removes it and creates the next would otherwise be free
/// to reuse the number, and ext4 does; across hosts, on NFS, the change time still tells). When
/// it exists but cannot be opened, its version alone. `None` when there is none.
fn pin(dir: &Path) -> Option<(Option<rustix::fd::OwnedFd>, Version)> {
    use rustix::fs::{Mode, OFlags, open};
    // `O_PATH` where there is one: it needs no read permission on the directory, as `stat` does
    // not.
    #[cfg(any(target_os = "linux", target_os = "android"))]
    let access = OFlags::PATH;
    #[cfg(not(any(target_os = "linux", target_os = "android")))]
    let access = OFlags::RDONLY;
    match open(
        dir,
        access | OFlags::DIRECTORY | OFlags::CLOEXEC,
        Mode::empty(),
    ) {
        Ok(fd) => {
            let version = version_from(&rustix::fs::fstat(&fd).ok()?);
            Some((Some(fd), version))
        }
        Err(rustix::io::Errno::NOENT) => None,
        Err(_) => version_of(dir).map(|version| (None, version)),
    }
}

/// How many times [`read_consistently`] reads a directory that keeps being replaced before it
/// gives up.
pub const CONSISTENT_READ_ATTEMPTS: usize = 20;

/// Runs `read` (which reads files of directory `dir` one by one) until it ran while `dir` stayed
/// one version: the same directory, held open, before and after, no [`DirectorySwap`] in
/// between. So a reader sees the old directory or the new one, never files of both, and never
/// "not found" while a swap by two renames is under way (it leaves the path missing for a
/// moment; the swap's lock tells). When every one of [`CONSISTENT_READ_ATTEMPTS`] reads
/// overlapped a swap, the last read's error is returned if it failed (a swap interrupted for
/// good, between its two renames, is reported so), else the error `kept_changing` makes: never a
/// read that may mix two versions.
pub fn read_consistently<T, E>(
    dir: &Path,
    mut read: impl FnMut() -> Result<T, E>,
    kept_changing: impl FnOnce() -> E,
) -> Result<T, E> {
    let swap = DirectorySwap::new(dir);
    let mut last_error = None;
    for attempt in 1..=CONSISTENT_READ_ATTEMPTS {
        let before = pin(dir);
        let result = read();
        let after = version_of(dir);
        let stable = match (&before, after) {
            (Some((_, before)), Some(after)) => *before == after,
            // Missing throughout, and no swap is halfway through: truly missing. A read that
            // succeeded found a directory that came and went meanwhile: read again.
            (None, None) if result.is_err() => {
                swap.as_ref()
                    .map_or(Some(true), DirectorySwap::missing_with_no_swap_under_way)
                    == Some(true)
            }
            _ => false,
        };
        drop(before);
        if stable {
            return result;
        }
        last_error = result.err();
        // A swap is a few system calls: the next read almost always sees one version.
        std::thread::sleep(Duration::from_millis(attempt as u64));
    }
    // An error mixes nothing: the last one says what is wrong (a swap interrupted for good
    // names the previous directory); a read that succeeded across a swap is never returned.
    Err(last_error.unwrap_or_else(kept_changing))
}

/// How many swaps this process has completed ([`swaps_done`]).
static SWAPS_DONE: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// How many [`DirectorySwap::swap_in`]s this process has completed: a signal handler holding the
/// [`swap_barrier`] tells from it whether a command's one write is already in place.
pub fn swaps_done() -> usize {
    SWAPS_DONE.load(std::sync::atomic::Ordering::Acquire)
}

/// Held by a writer while it swaps a directory in and tidies it ([`swap_barrier`]).
static SWAP_BARRIER: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A process-wide barrier around the last steps of a write (the swap and the tidying after it):
/// a writer holds it while it swaps, and code that ends the process abruptly (a signal handler
/// calling `_exit`) takes it first, so that the process never ends between a swap and its
/// tidying, and can tell whether the swap happened.
pub fn swap_barrier() -> std::sync::MutexGuard<'static, ()> {
    SWAP_BARRIER
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
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
    fn temporary_names_stand_for_their_targets() {
        for (name, public) in [
            (".a.exr.4242.tmp", Some("a.exr")),
            (".a.exr.tmp", Some("a.exr")),
            (".bake.previous", Some("bake")),
            (".hidden", None),
            ("..tmp", None),
            ("a.exr", None),
        ] {
            assert_eq!(stands_for(name), public, "{name}");
        }
        let path = Path::new("/x/a.exr");
        let temporary = temporary_path(path);
        let name = temporary.file_name().unwrap().to_str().unwrap();
        assert_eq!(stands_for(name), Some("a.exr"));
    }

    #[test]
    fn a_directory_is_swapped_whole_and_an_interrupted_swap_recovers() {
        let root = std::env::temp_dir().join(format!("lensmap-swap-{}", std::process::id()));
        let _ = fs::remove_dir_all(&root);
        let target = root.join("sub").join("d");
        let swap = DirectorySwap::new(&target).unwrap();
        swap.prepare().unwrap();
        let build = |text: &[u8]| {
            let built = swap.beside(".building");
            fs::create_dir_all(&built).unwrap();
            write_synced(&built.join("f"), text).unwrap();
            built
        };
        swap.swap_in(&build(b"one"), WhenSwapFails::Remove).unwrap();
        swap.swap_in(&build(b"two"), WhenSwapFails::Remove).unwrap();
        assert_eq!(fs::read(target.join("f")).unwrap(), b"two");
        assert_eq!(fs::read_dir(root.join("sub")).unwrap().count(), 1);
        // Killed between the renames: the old directory aside, the target missing.
        fs::rename(&target, root.join("sub").join(".d.previous")).unwrap();
        assert!(swap.interrupted().is_some());
        swap.prepare().unwrap();
        assert!(swap.interrupted().is_none());
        assert_eq!(fs::read(target.join("f")).unwrap(), b"two");
        // A swap whose rename fails (the built directory is missing) puts the old one back.
        let missing = swap.beside(".missing");
        assert!(swap.swap_in(&missing, WhenSwapFails::Keep).is_err());
        assert_eq!(fs::read(target.join("f")).unwrap(), b"two");
        assert!(DirectorySwap::new(Path::new("/")).is_none());
        fs::remove_dir_all(&root).unwrap();
    }

    /// A reader of a directory's two files in a loop while a writer swaps versions in, by the
    /// atomic exchange and by the fallback of two renames: every read sees both files of one
    /// version, and never a missing directory.
    #[test]
    fn a_reader_sees_one_version_whole_during_swaps_by_either_method() {
        for method in [SwapMethod::Exchange, SwapMethod::Renames] {
            let root =
                std::env::temp_dir().join(format!("lensmap-versions-{}", std::process::id()));
            let _ = fs::remove_dir_all(&root);
            let target = root.join("d");
            let swap = DirectorySwap::new(&target).unwrap();
            swap.prepare().unwrap();
            let write_version = |version: u32| {
                let built = swap.beside(".building");
                fs::create_dir_all(&built).unwrap();
                for name in ["a", "b"] {
                    write_synced(&built.join(name), &version.to_le_bytes()).unwrap();
                }
                swap.swap_in_by(&built, WhenSwapFails::Remove, method)
                    .unwrap();
            };
            write_version(0);
            let done = std::sync::atomic::AtomicBool::new(false);
            let reads = std::thread::scope(|scope| {
                scope.spawn(|| {
                    for version in 1..=300 {
                        write_version(version);
                    }
                    done.store(true, std::sync::atomic::Ordering::Release);
                });
                let mut reads = 0;
                while !done.load(std::sync::atomic::Ordering::Acquire) {
                    let (a, b) = read_consistently(
                        &target,
                        || {
                            Ok::<_, std::io::Error>((
                                fs::read(target.join("a"))?,
                                fs::read(target.join("b"))?,
                            ))
                        },
                        || std::io::Error::other("kept changing"),
                    )
                    .unwrap_or_else(|e| panic!("{method:?}, read {reads}: {e}"));
                    assert_eq!(a, b, "{method:?}: read {reads} mixes two versions");
                    reads += 1;
                }
                reads
            });
            assert!(reads > 0);
            let mut left: Vec<_> = fs::read_dir(&root)
                .unwrap()
                .map(|entry| entry.unwrap().file_name().into_string().unwrap())
                .collect();
            left.sort();
            let expected: &[&str] = match method {
                SwapMethod::Exchange => &["d"],
                // The swap lock stays: removing a lock file races with its next taker.
                SwapMethod::Renames => &[".d.swapping", "d"],
            };
            assert_eq!(left, expected, "{method:?}");
            fs::remove_dir_all(&root).unwrap();
        }
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
