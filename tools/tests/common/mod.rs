//! What the command-line tests share: the `lensmap` binary run with the validation layer on.

use std::process::{Command, Output};

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
