//! What the command-line tests share: the `lensmap` binary run with the validation layer on, a
//! render small enough for CI, scratch folders, and the check that a run succeeded.
// Each test file includes this module and uses part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A frame small enough for CI: 16×12 at 1×1.
pub const TINY_FRAME: [&str; 6] = ["--width", "16", "--height", "12", "--supersampling", "1"];

/// Render options small enough for CI: [`TINY_FRAME`] with 8² projected maps.
pub const TINY_RENDER: [&str; 9] = {
    let [width, w, height, h, supersampling, k] = TINY_FRAME;
    [
        "--projected",
        width,
        w,
        height,
        h,
        supersampling,
        k,
        "--em-size",
        "8",
    ]
};

/// An empty scratch folder `lensmap-GROUP-NAME-PID` in the system's temporary folder.
pub fn temp_dir(group: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensmap-{group}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch folder");
    dir
}

/// The `lensmap` binary with `args`, the Khronos validation layer on. A failure of the test from
/// then on names the device and driver the binary runs on.
pub fn lensmap_command(args: &[&str]) -> Command {
    lensmap_tests::name_the_binarys_driver_on_failure();
    let mut command = Command::new(env!("CARGO_BIN_EXE_lensmap"));
    command.args(args).env("LENSMAP_VALIDATION", "1");
    command
}

/// Runs `lensmap args` to completion.
pub fn lensmap(args: &[&str]) -> Output {
    lensmap_command(args)
        .output()
        .expect("the lensmap binary runs")
}

/// Fails the test unless `output` is a successful run without a panic, showing its exit code,
/// stdout and stderr; `case` says which run it was.
pub fn assert_success(case: &str, output: &Output) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success() && !stderr.contains("panicked"),
        "{case}: exit {:?}\nstdout: {}\nstderr: {stderr}",
        output.status.code(),
        String::from_utf8_lossy(&output.stdout),
    );
}

/// Runs `lensmap args`, which must succeed ([`assert_success`]); its output.
pub fn succeeds(args: &[&str]) -> Output {
    let output = lensmap(args);
    assert_success(&format!("{args:?}"), &output);
    output
}

/// The bytes of the file at `path`.
pub fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Runs `lensmap args` (validation layer on) as if the disk holding `dir` were full but for
/// `free_kib` KiB: in a mount namespace of the run's own (`unshare`), `dir` becomes a tmpfs
/// holding a copy of what it held and filled to `free_kib` KiB free, so lensmap's writes there
/// fail with ENOSPC. Afterwards `dir` holds what the tmpfs held (without the filler): what a
/// full disk left. Returns the run's output (a death by a signal as exit 128 + n) and how long
/// it took.
///
/// Why not `ulimit -f`: a file-size limit also caps the files a driver keeps for itself. Mesa
/// 25.0's lavapipe backs device memory with memfd files; under `ulimit -f 64` its `ftruncate` of
/// a 64 MiB block fails with EFBIG, `vkAllocateMemory` still succeeds, and lensmap's first copy
/// into the mapped memory dies by SIGBUS inside the driver (measured with gdb). A full disk
/// leaves the driver's memory alone: this one is only `dir`.
pub fn on_full_disk(dir: &Path, free_kib: u32, args: &[&str]) -> (Output, std::time::Duration) {
    const SCRIPT: &str = r#"
dir=$1 stage=$2 free_kib=$3 lensmap=$4
shift 4
mode=$(stat -c %a "$dir") && rm -rf "$stage" && mkdir "$stage" && cp -a "$dir/." "$stage/" &&
mount -t tmpfs -o "size=64m,mode=$mode" lensmap-full-disk "$dir" &&
cp -a "$stage/." "$dir/" &&
{ dd if=/dev/zero of="$dir/.filler" bs=4096 >/dev/null 2>&1; true; } &&
truncate -s "-${free_kib}K" "$dir/.filler" ||
    { rm -rf "$stage"; echo "cannot make a full disk at $dir" >&2; exit 125; }
"$lensmap" "$@"
status=$?
rm -f "$dir/.filler"
find "$stage" -mindepth 1 -delete && cp -a "$dir/." "$stage/" && umount "$dir" &&
find "$dir" -mindepth 1 -delete && cp -a "$stage/." "$dir/" && rm -rf "$stage" ||
    { echo "cannot copy back from the full disk at $dir" >&2; exit 125; }
exit $status
"#;
    // Root makes a mount namespace directly; anyone else through a user namespace.
    let namespace: &[&str] = [&["-m"][..], &["-r", "-m"][..]]
        .into_iter()
        .find(|flags| {
            Command::new("unshare")
                .args(*flags)
                .arg("true")
                .output()
                .is_ok_and(|o| o.status.success())
        })
        .expect(
            "no full disk can be made here: `unshare -m` (root) or `unshare -r -m` (user \
             namespaces) is needed",
        );
    lensmap_tests::name_the_binarys_driver_on_failure();
    let mut stage = dir.as_os_str().to_owned();
    stage.push(".full-disk-stage");
    let start = std::time::Instant::now();
    let output = Command::new("unshare")
        .args(namespace)
        .args(["sh", "-c", SCRIPT, "sh"])
        .arg(dir)
        .arg(&stage)
        .arg(free_kib.to_string())
        .arg(env!("CARGO_BIN_EXE_lensmap"))
        .args(args)
        .env("LENSMAP_VALIDATION", "1")
        .output()
        .expect("unshare runs (util-linux)");
    assert_ne!(
        output.status.code(),
        Some(125),
        "no full disk could be made here: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    (output, start.elapsed())
}
