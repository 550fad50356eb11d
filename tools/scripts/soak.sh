#!/usr/bin/env bash
# soak.sh — the soak through the C ABI: builds the soak harness in release and runs it in full.
#
# Usage:  tools/scripts/soak.sh [--frames N] [--cycles N]
#
# Builds `engine/capi/examples/soak.rs` (it links lensmap-capi and calls its exported
# `extern "C"` functions) with `cargo build --release`, then runs it: 10,000 frames with a
# moving camera and alternating scenes and options on one context (validation on), resident
# memory, the C allocator's live bytes (the heap) and device memory sampled every 500 frames,
# then 200 `lensmap_context_new` / `lensmap_scene_load` / `_free` cycles, resident memory and
# the heap sampled every 10. It prints the samples,
# the frame-time drift and the cycles, and exits 1 when memory grew past the bounds stated in
# `engine/capi/tests/soak_harness/mod.rs` (`Plan::full`) or the validation layer reported
# anything. The driver is the environment's: for Mesa 25.0's lavapipe,
#   env $(.ci/second-driver target/mesa-25) tools/scripts/soak.sh
# A short version of the same runs in `cargo test` (`engine/capi/tests/soak.rs`).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
cd "$ROOT"
export CARGO_INCREMENTAL=${CARGO_INCREMENTAL:-0}
cargo build --release -q -p lensmap-capi --example soak
BIN=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/release/examples/soak
driver=${VK_ICD_FILENAMES:-the system driver}
echo "soak: $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, Vulkan ICD: $driver"
start=$(date +%s)
status=0
"$BIN" "$@" || status=$?
echo "soak: $(( $(date +%s) - start )) s, exit $status"
exit $status
