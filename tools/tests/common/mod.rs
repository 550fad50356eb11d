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

/// The `lensmap` binary with `args`, the Khronos validation layer on.
pub fn lensmap_command(args: &[&str]) -> Command {
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
