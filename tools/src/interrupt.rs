//! A long bake stops at once on SIGTERM (a batch scheduler's preemption or time-limit signal;
//! Slurm sends SIGKILL 30 s later by default) or SIGINT (Ctrl-C): every finished sample is
//! already durable in the staging directory (each file fsynced and renamed into place, a sample's
//! report last), so nothing is left to save. The process says what it keeps and how to resume,
//! and exits with 128 + the signal's number (143 for SIGTERM, 130 for SIGINT), the shell's code
//! for "ended by that signal", which schedulers report as such. The sample in flight is
//! discarded: it has no report, so `--resume` bakes it again (overwriting any of its maps that
//! were staged).
//!
//! Why not finish the sample in flight: one sample of a real bake takes minutes, far beyond the
//! 30 s before SIGKILL. Why `_exit` from the signal's thread rather than a flag the bake polls:
//! the same reason, and the bake's GPU and solver loops have no point to stop at within seconds.

use std::path::{Path, PathBuf};

use signal_hook::consts::{SIGINT, SIGTERM};
use signal_hook::iterator::Signals;

/// What an interruption tells: the bake directory, its staging directory, and the flag that
/// resumes the same command.
pub struct Interruptible {
    /// The bake directory being written (`--out`).
    pub out: PathBuf,
    /// Where its finished samples are staged.
    pub staging: PathBuf,
}

/// Stops the process on SIGTERM or SIGINT from now on, as the module documentation says. Fails
/// only when the signal handlers cannot be installed.
pub fn stop_on_signals(bake: Interruptible) -> anyhow::Result<()> {
    let mut signals = Signals::new([SIGTERM, SIGINT])?;
    std::thread::Builder::new()
        .name("lensmap-signals".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                interrupted(&bake, signal);
            }
        })?;
    Ok(())
}

/// Says what was kept and ends the process with 128 + `signal`; or, when the bake was already
/// swapped in complete, says so and ends it with 0.
fn interrupted(bake: &Interruptible, signal: i32) -> ! {
    let name = if signal == SIGTERM {
        "SIGTERM"
    } else {
        "SIGINT"
    };
    // Never between a swap and its tidying; held until the process ends.
    let _barrier = lensmap::atomic::swap_barrier();
    if lensmap::atomic::swaps_done() > 0 {
        // The bake's one swap, its commit, is done: the bake is complete in place.
        crate::common::tell(format_args!(
            "\n{name} after the bake was complete in {}: nothing to resume",
            bake.out.display()
        ));
        // SAFETY: as below.
        unsafe { libc::_exit(0) }
    }
    let kept = finished_samples(&bake.staging);
    let code = 128 + signal;
    // `./.NAME.baking` for a bake named without a folder: said as the user would write it.
    let staging = bake.staging.strip_prefix(".").unwrap_or(&bake.staging);
    let line = format!(
        "interrupted by {name}: {} finished sample(s) kept in {}{}; the sample in flight is discarded; run the same command with --resume to finish the bake into {}",
        kept.len(),
        staging.display(),
        if kept.is_empty() {
            String::new()
        } else {
            format!(
                " ({})",
                kept.iter()
                    .map(usize::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        },
        bake.out.display(),
    );
    if crate::common::voice().json {
        crate::common::tell(format_args!(
            "{}",
            serde_json::json!({
                "error": line,
                "exit_code": code,
                "interrupted": name,
                "kept": kept,
            })
        ));
    } else {
        // A progress bar may be mid-line.
        crate::common::tell(format_args!("\nerror: {line}"));
    }
    release_lock(&bake.out);
    // SAFETY: `_exit` ends the process without running exit handlers or destructors, which
    // other threads (the GPU driver's among them) may be using at this moment; every finished
    // sample is already on disk, and the kernel releases the lock and the device.
    unsafe { libc::_exit(code) }
}

/// The view-space indices of the samples whose report (`sample-NNN.json`, written last) is in
/// `staging`: the finished ones, for the layered and the radiance-map bake alike.
fn finished_samples(staging: &Path) -> Vec<usize> {
    let mut samples: Vec<usize> = std::fs::read_dir(staging)
        .into_iter()
        .flatten()
        .filter_map(|entry| {
            let name = entry.ok()?.file_name();
            let name = name.to_str()?;
            name.strip_prefix("sample-")?
                .strip_suffix(".json")?
                .parse()
                .ok()
        })
        .collect();
    samples.sort_unstable();
    samples
}

/// Removes the bake directory's lock file when it names this process: the kernel drops the
/// lock itself at exit, and this leaves nothing stale behind.
fn release_lock(out: &Path) {
    let Some(path) = lensmap::atomic::lock::DirectoryLock::path_of(out) else {
        return;
    };
    let ours = std::fs::read_to_string(&path)
        .ok()
        .and_then(|text| serde_json::from_str::<lensmap::atomic::lock::Holder>(text.trim()).ok())
        .is_some_and(|holder| {
            holder.pid == std::process::id() && holder.host == lensmap::atomic::lock::host_name()
        });
    if ours {
        let _ = std::fs::remove_file(&path);
    }
}
