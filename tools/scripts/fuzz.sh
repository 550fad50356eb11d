#!/usr/bin/env bash
# Coverage-guided fuzzing of lensmap's readers and C ABI on stable Rust (cargo afl, AFL++).
#
#   tools/scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]     (default: 600 s; every target)
#
# Targets (tests/fuzz/src/bin): scene, asset, bake, capi. Builds them instrumented into
# tests/fuzz/target (not the workspace's target), then runs afl-fuzz on each in turn, niced, one
# at a time, from its seed corpus tests/fuzz/corpus/<target> for the stated time, and prints per
# target: run time, executions, executions per second, edges found (of the map's total) and map
# density, crashes and hangs. A crash includes an allocation past the harness's 512 MiB budget
# (tests/fuzz/src/budget.rs); a hang is an input over the target's timeout. Findings are left in
# tests/fuzz/target/afl/<target>/default/{crashes,hangs}; replay one with
#   LENSMAP_FUZZ_SHOW=1 tests/fuzz/target/release/<target> < FILE
# KEEP=1 also minimises each queue (afl-cmin) and copies its smallest inputs into
# tests/fuzz/corpus/<target> while that folder stays under 256 KB.
# Needs: cargo install cargo-afl (it builds AFL++ on first use: cargo afl config --build).
set -euo pipefail

root=$(cd "$(dirname "$0")/../.." && pwd)
seconds=${1:-600}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(scene asset bake capi)

export CARGO_INCREMENTAL=0
# cargo-afl's own AFL++ tools first: afl-cmin must find the afl-showmap of the same version,
# not an older one from the system (Debian's afl++ 4.04c lacks options it passes).
afl_bin=$(ls -d "${XDG_DATA_HOME:-$HOME/.local/share}"/afl.rs/*/afl.rs-*/afl/bin 2>/dev/null | tail -1)
[ -z "$afl_bin" ] || export PATH="$afl_bin:$PATH"
(cd "$root/tests/fuzz" && nice cargo afl build --release --quiet)

# Per-input timeouts (ms): the readers take milliseconds; a C ABI input loads a scene and
# renders frames on lavapipe.
declare -A timeout=([scene]=2000 [asset]=2000 [bake]=2000 [capi]=20000)

# afl-fuzz settings for a shared machine: no CPU binding, no frequency or core-pattern checks,
# no curses screen.
export AFL_NO_UI=1 AFL_NO_AFFINITY=1 AFL_SKIP_CPUFREQ=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1
export AFL_SKIP_CRASHES=1 AFL_SHUFFLE_QUEUE=0

stat() { sed -n "s/^$1 *: *//p" "$2"; }

rows=()
for target in "${targets[@]}"; do
  binary="$root/tests/fuzz/target/release/$target"
  corpus="$root/tests/fuzz/corpus/$target"
  out="$root/tests/fuzz/target/afl/$target"
  [ -x "$binary" ] || { echo "fuzz.sh: no target $target (see tests/fuzz/src/bin)" >&2; exit 2; }
  rm -rf "$out" "$out.log"
  mkdir -p "$(dirname "$out")"
  echo "fuzz.sh: $target for ${seconds} s" >&2
  nice cargo afl fuzz -i "$corpus" -o "$out" -V "$seconds" -t "${timeout[$target]:-2000}" \
    -- "$binary" >"$out.log" 2>&1 || { tail -20 "$out.log" >&2; exit 1; }
  stats="$out/default/fuzzer_stats"
  crashes=$(find "$out/default/crashes" -type f -name 'id:*' | wc -l)
  hangs=$(find "$out/default/hangs" -type f -name 'id:*' | wc -l)
  rows+=("$(printf '%-6s %7s s %10s %8s/s %6s/%-6s %7s %7s %5s' "$target" \
    "$(stat run_time "$stats")" "$(stat execs_done "$stats")" "$(stat execs_per_sec "$stats")" \
    "$(stat edges_found "$stats")" "$(stat total_edges "$stats")" "$(stat bitmap_cvg "$stats")" \
    "$crashes" "$hangs")")
  if [ "${KEEP:-0}" = 1 ]; then
    minimised="$out/cmin"
    nice cargo afl cmin -i "$out/default/queue" -o "$minimised" -t "${timeout[$target]:-2000}" \
      -- "$binary" >"$out.cmin.log" 2>&1 || { tail -5 "$out.cmin.log" >&2; exit 1; }
    # Smallest first; names without afl's ':' and ',' (kept portable).
    for file in $(ls -Sr "$minimised"); do
      [ "$(du -sb "$corpus" | cut -f1)" -lt 262144 ] || break
      cp "$minimised/$file" "$corpus/queue-$(echo "$file" | cut -c1-9 | tr ':,' '--')"
    done
  fi
done

printf '%-6s %9s %10s %10s %13s %7s %7s %5s\n' target time executions exec/s edges density crashes hangs
printf '%s\n' "${rows[@]}"
