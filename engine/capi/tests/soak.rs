//! The short soak through the C ABI (`soak_harness`, whose full run is `examples/soak.rs`):
//! 300 frames with a moving camera and alternating scenes and options on one context, then 4
//! context and scene cycles, validation on. The heap, resident and device memory must stay
//! within the bounds of [`soak_harness::Plan::short`] once warm, and the validation layer
//! silent.

mod soak_harness;

use soak_harness::{Plan, run_cycles, run_frames};

#[test]
fn memory_stays_flat_over_frames_and_context_cycles() {
    let plan = Plan::short();
    eprintln!("device: {}", soak_harness::device_named());
    let frames = run_frames(&plan).unwrap_or_else(|e| panic!("{e}"));
    eprint!("{}", frames.table());
    let cycles = run_cycles(&plan).unwrap_or_else(|e| panic!("{e}"));
    eprint!("{}", cycles.table());
    // The frames were what the schedule says: some reused, some traced on the device.
    assert!(frames.reused > 0 && frames.traced_on_gpu > 0, "{frames:?}");
    let failures = [frames.failures(), cycles.failures()].concat();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
