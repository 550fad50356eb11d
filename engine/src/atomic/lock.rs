//! One writer per directory: [`DirectoryLock`], the lock file `.NAME.lock` beside directory
//! `NAME`, held by whoever is building a replacement for `NAME`.
//!
//! **When a lock is held.** Its holder keeps an exclusive `flock` on the lock file for as long as
//! it writes. The kernel drops that lock when the holder exits, however it exits (a `kill -9`, a
//! crash, a scheduler's time limit), so a lock left by a dead process on this host is stale at
//! once and the next writer takes it over. On a shared file system `flock` reaches other hosts
//! where the file system forwards it (NFSv4 does, as a byte-range lock whose server drops a dead
//! client's locks when the client's lease expires, 90 s by default); where it does not (an NFS
//! mount with `local_lock=flock`, some FUSE file systems), the heartbeat decides: the holder
//! touches the lock file every [`HEARTBEAT`], and a lock naming another host is held while its
//! last heartbeat (the file's modification time) is younger than [`STALE_AFTER`]. Hosts' clocks
//! must agree within that margin for the heartbeat rule to hold.
//!
//! **What it names.** The lock file holds its holder's host, process id and start time (one JSON
//! line), so a refusal says who to wait for.
//!
//! A lock is not re-entrant: a second [`DirectoryLock::acquire`] of one directory in one process
//! is refused like any other, where `flock` is the kernel's own. On NFS, Linux implements `flock`
//! as a POSIX lock, which belongs to the process: there a second acquire in the same process
//! succeeds (lensmap never takes one directory's lock twice), and other processes and hosts are
//! still refused.

use std::fs::{self, File, OpenOptions};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use rustix::fs::{FlockOperation, flock};
use serde::{Deserialize, Serialize};

/// How often a holder refreshes its lock file's modification time.
pub const HEARTBEAT: Duration = Duration::from_secs(10);

/// How old another host's heartbeat may be before its lock is stale, where `flock` does not
/// reach across hosts (see the module documentation).
pub const STALE_AFTER: Duration = Duration::from_secs(60);

/// The suffix of a lock file's name: `.NAME.lock` beside directory `NAME`.
pub const LOCK_SUFFIX: &str = ".lock";

/// Who holds a lock, as its lock file says.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Holder {
    /// The holder's host name.
    pub host: String,
    /// The holder's process id on that host.
    pub pid: u32,
    /// When it took the lock, seconds since the Unix epoch.
    pub since_unix: u64,
}

impl Holder {
    /// This process.
    fn this_process() -> Holder {
        Holder {
            host: host_name(),
            pid: std::process::id(),
            since_unix: SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map_or(0, |d| d.as_secs()),
        }
    }
}

impl std::fmt::Display for Holder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "pid {} on host {}", self.pid, self.host)
    }
}

/// Why a directory could not be locked.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another writer holds the lock.
    #[error(
        "{}: another process is writing it ({}, lock {}); wait for it to finish or write elsewhere{}",
        dir.display(),
        holder.as_ref().map_or_else(|| "holder not yet named".to_owned(), Holder::to_string),
        lock.display(),
        if holder.as_ref().is_some_and(|h| h.host != host_name()) {
            format!("; a lock of another host is stale {} s after its last heartbeat", STALE_AFTER.as_secs())
        } else {
            String::new()
        }
    )]
    Held {
        /// The directory.
        dir: PathBuf,
        /// The lock file.
        lock: PathBuf,
        /// Who holds it, when the lock file names it (a writer that has just taken the lock may
        /// not have written its name yet).
        holder: Option<Holder>,
    },
    /// The file system refused a step.
    #[error(
        "{}: cannot {action} its lock {}: {source}{}",
        dir.display(),
        lock.display(),
        if source.raw_os_error() == Some(rustix::io::Errno::NOLCK.raw_os_error())
            || source.kind() == std::io::ErrorKind::Unsupported
        {
            "; this file system has no file locks: write the bake on one that has (a local disk, NFSv4)"
        } else {
            ""
        }
    )]
    Io {
        /// The directory.
        dir: PathBuf,
        /// The lock file.
        lock: PathBuf,
        /// What was being done.
        action: &'static str,
        /// The operating system's error.
        source: std::io::Error,
    },
}

/// The lock of one directory, held until dropped (see the module documentation). Dropping it
/// stops the heartbeat and removes the lock file.
#[derive(Debug)]
pub struct DirectoryLock {
    path: PathBuf,
    file: File,
    /// Dropping the sender stops the heartbeat thread.
    heartbeat: Option<(mpsc::Sender<()>, thread::JoinHandle<()>)>,
}

impl DirectoryLock {
    /// The lock file of directory `dir`: `.NAME.lock` beside it.
    pub fn path_of(dir: &Path) -> Option<PathBuf> {
        Some(super::DirectorySwap::new(dir)?.beside(LOCK_SUFFIX))
    }

    /// Takes the lock of directory `dir` (its parent folders are created), or refuses at once
    /// with [`LockError::Held`] naming the holder. A stale lock (module documentation) is taken
    /// over.
    pub fn acquire(dir: &Path) -> Result<DirectoryLock, LockError> {
        let Some(path) = DirectoryLock::path_of(dir) else {
            return Err(LockError::Io {
                dir: dir.to_owned(),
                lock: dir.to_owned(),
                action: "name",
                source: std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    "the directory has no final name in UTF-8",
                ),
            });
        };
        let io = |action: &'static str| {
            let (dir, lock) = (dir.to_owned(), path.clone());
            move |source: std::io::Error| LockError::Io {
                dir,
                lock,
                action,
                source,
            }
        };
        if let Some(parent) = path.parent() {
            fs::create_dir_all(parent).map_err(io("create the folder of"))?;
        }
        // A lock file removed by its holder between our open and our flock is not the lock any
        // more: lock again until the file we hold is the one at the path.
        loop {
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(io("open"))?;
            match flock(&file, FlockOperation::NonBlockingLockExclusive) {
                Ok(()) => {}
                Err(rustix::io::Errno::WOULDBLOCK) => {
                    return Err(LockError::Held {
                        dir: dir.to_owned(),
                        holder: read_holder(&mut file),
                        lock: path,
                    });
                }
                Err(errno) => return Err(io("lock")(errno.into())),
            }
            let held = rustix::fs::fstat(&file).map_err(|e| io("inspect")(e.into()))?;
            match rustix::fs::stat(&path) {
                Ok(at_path) if (at_path.st_dev, at_path.st_ino) == (held.st_dev, held.st_ino) => {}
                Ok(_) | Err(rustix::io::Errno::NOENT) => continue,
                Err(errno) => return Err(io("inspect")(errno.into())),
            }
            // A heartbeat in the future (the holder's clock ahead of ours) is fresh.
            if let Some(holder) = read_holder(&mut file)
                && holder.host != host_name()
                && heartbeat_age(&file).is_none_or(|age| age < STALE_AFTER)
            {
                return Err(LockError::Held {
                    dir: dir.to_owned(),
                    holder: Some(holder),
                    lock: path,
                });
            }
            write_holder(&mut file, &Holder::this_process()).map_err(io("write"))?;
            let heartbeat = start_heartbeat(&file);
            return Ok(DirectoryLock {
                path,
                file,
                heartbeat,
            });
        }
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for DirectoryLock {
    fn drop(&mut self) {
        if let Some((stop, thread)) = self.heartbeat.take() {
            drop(stop);
            let _ = thread.join();
        }
        // Removed while still locked, so that no writer locks the file about to vanish (one that
        // opened it before the removal finds it gone from the path and locks again).
        let _ = fs::remove_file(&self.path);
        let _ = flock(&self.file, FlockOperation::Unlock);
    }
}

/// The holder a lock file names, if it names one.
fn read_holder(file: &mut File) -> Option<Holder> {
    let mut text = String::new();
    file.rewind().ok()?;
    file.read_to_string(&mut text).ok()?;
    serde_json::from_str(text.trim()).ok()
}

fn write_holder(file: &mut File, holder: &Holder) -> std::io::Result<()> {
    let line = serde_json::to_string(holder).map_err(std::io::Error::other)?;
    file.set_len(0)?;
    file.rewind()?;
    file.write_all(format!("{line}\n").as_bytes())?;
    file.sync_all()
}

/// How long ago the lock file was last touched; `None` when its time is unknown or in the future
/// (the holder's clock ahead of ours).
fn heartbeat_age(file: &File) -> Option<Duration> {
    let modified = file.metadata().ok()?.modified().ok()?;
    SystemTime::now().duration_since(modified).ok()
}

/// A thread touching the lock file every [`HEARTBEAT`] until its sender is dropped; `None` when
/// the file cannot be shared with a thread (the lock then has no heartbeat, which only matters
/// where `flock` does not reach other hosts).
fn start_heartbeat(file: &File) -> Option<(mpsc::Sender<()>, thread::JoinHandle<()>)> {
    let file = file.try_clone().ok()?;
    let (stop, stopped) = mpsc::channel::<()>();
    let thread = thread::Builder::new()
        .name("lensmap-lock-heartbeat".into())
        .spawn(move || {
            while let Err(mpsc::RecvTimeoutError::Timeout) = stopped.recv_timeout(HEARTBEAT) {
                let _ = file.set_modified(SystemTime::now());
            }
        })
        .ok()?;
    Some((stop, thread))
}

/// This host's name (`uname`'s node name).
pub fn host_name() -> String {
    rustix::system::uname()
        .nodename()
        .to_string_lossy()
        .into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("lensmap-lock-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_second_writer_is_refused_with_the_holder_named_and_takes_over_once_released() {
        let root = scratch("second");
        let dir = root.join("bake");
        let first = DirectoryLock::acquire(&dir).unwrap();
        let lock_path = first.path().to_owned();
        assert_eq!(lock_path, root.join(".bake.lock"));
        let error = DirectoryLock::acquire(&dir).unwrap_err();
        let LockError::Held { holder, .. } = &error else {
            panic!("{error}");
        };
        assert_eq!(holder.as_ref().map(|h| h.pid), Some(std::process::id()));
        let message = error.to_string();
        assert!(
            message.contains(&format!("pid {}", std::process::id()))
                && message.contains(&host_name())
                && message.contains(".bake.lock"),
            "{message}"
        );
        drop(first);
        assert!(!lock_path.exists(), "a released lock removes its file");
        let again = DirectoryLock::acquire(&dir).unwrap();
        drop(again);
        fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_lock_file_left_by_a_dead_holder_is_taken_over() {
        let root = scratch("stale");
        let dir = root.join("bake");
        // What a killed process leaves: the file naming it, no flock (the kernel dropped it).
        let dead = Holder {
            host: host_name(),
            pid: u32::MAX - 1,
            since_unix: 1,
        };
        let path = DirectoryLock::path_of(&dir).unwrap();
        fs::write(&path, serde_json::to_string(&dead).unwrap()).unwrap();
        let lock = DirectoryLock::acquire(&dir).unwrap();
        let named = read_holder(&mut File::open(&path).unwrap()).unwrap();
        assert_eq!(named.pid, std::process::id());
        drop(lock);
        fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn another_hosts_lock_holds_while_its_heartbeat_is_fresh() {
        let root = scratch("host");
        let dir = root.join("bake");
        let path = DirectoryLock::path_of(&dir).unwrap();
        let elsewhere = Holder {
            host: format!("not-{}", host_name()),
            pid: 7,
            since_unix: 1,
        };
        // A file system whose flock does not reach this host: only the heartbeat tells.
        fs::write(&path, serde_json::to_string(&elsewhere).unwrap()).unwrap();
        let error = DirectoryLock::acquire(&dir).unwrap_err();
        assert!(
            error
                .to_string()
                .contains("stale 60 s after its last heartbeat"),
            "{error}"
        );
        // Its heartbeat stopped longer ago than STALE_AFTER: taken over.
        let old = SystemTime::now() - STALE_AFTER - Duration::from_secs(5);
        File::options()
            .write(true)
            .open(&path)
            .unwrap()
            .set_modified(old)
            .unwrap();
        drop(DirectoryLock::acquire(&dir).unwrap());
        fs::remove_dir_all(&root).unwrap();
    }
}
