//! What the command-line tests share: the `lensmap` binary run with the validation layer on, a
//! render small enough for CI, and scratch folders.
// Each test file includes this module and uses part of it.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::{Command, Output};

/// Render options small enough for CI: 16×12 at 1×1 with 8² projected maps.
pub const TINY_RENDER: [&str; 9] = [
    "--projected",
    "--width",
    "16",
    "--height",
    "12",
    "--supersampling",
    "1",
    "--em-size",
    "8",
];

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
