//! The full soak through the C ABI (`tools/scripts/soak.sh` runs it in release): 10,000 frames
//! with a moving camera and alternating scenes and options on one context, then 200 context
//! and scene cycles, validation on; prints the memory samples, the drift and the cycles, and
//! exits 1 when memory grew past the bounds of `Plan::full` or the validation layer spoke.
//!
//! ```sh
//! cargo run --release -p lensmap-capi --example soak -- [--short] [--no-validation] [--frames N] [--cycles N]
//! ```

#[path = "../tests/soak_harness/mod.rs"]
mod soak_harness;

use std::process::ExitCode;

use soak_harness::{Plan, run_cycles, run_frames};

/// The plan, with `--short`, `--no-validation`, `--frames N` and `--cycles N` from the command line. Parsed by hand: two
/// numbers do not justify a command-line dependency in the C ABI's crate.
fn plan() -> Result<Plan, String> {
    let mut plan = Plan::full();
    let mut args = std::env::args().skip(1);
    while let Some(flag) = args.next() {
        if flag == "--no-validation" {
            // To tell the validation layer's memory from lensmap's and the driver's.
            plan.validation = false;
            continue;
        }
        if flag == "--short" {
            // The plan `cargo test` runs, whatever came before.
            plan = Plan::short();
            continue;
        }
        let value = args.next().and_then(|v| v.parse::<u32>().ok());
        match (flag.as_str(), value) {
            ("--frames", Some(n)) if n >= plan.warm_frames.max(plan.drift_window) => {
                plan.frames = n
            }
            ("--cycles", Some(n)) if n >= plan.warm_cycles => plan.cycles = n,
            _ => {
                return Err(format!(
                    "{flag}: give --short (the plan of `cargo test`), --no-validation, --frames N (at least {}) or --cycles N (at least {})",
                    plan.warm_frames.max(plan.drift_window),
                    plan.warm_cycles
                ));
            }
        }
    }
    Ok(plan)
}

fn main() -> ExitCode {
    let plan = match plan() {
        Ok(plan) => plan,
        Err(message) => {
            eprintln!("soak: {message}");
            return ExitCode::from(2);
        }
    };
    println!("device: {}", soak_harness::device_named());
    let frames = match run_frames(&plan) {
        Ok(frames) => frames,
        Err(message) => {
            eprintln!("soak: {message}");
            return ExitCode::FAILURE;
        }
    };
    print!("{}", frames.table());
    let cycles = match run_cycles(&plan) {
        Ok(cycles) => cycles,
        Err(message) => {
            eprintln!("soak: {message}");
            return ExitCode::FAILURE;
        }
    };
    print!("{}", cycles.table());
    let failures = [frames.failures(), cycles.failures()].concat();
    for failure in &failures {
        eprintln!("soak: FAILED: {failure}");
    }
    if failures.is_empty() {
        println!("soak: held");
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
