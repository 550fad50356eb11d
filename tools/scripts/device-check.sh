#!/usr/bin/env bash
# device-check.sh — every GPU figure in one call of a lent GPU machine: the GPU-touching tests with
# validation on, `bench hybrid` on both tracers and both GPU walks, `bench passes`, `bench glossy`,
# the headline table at the paper's setting and a 1920×1080 frame.
#
# Usage:  tools/scripts/device-check.sh pack [DIR]         here: build and pack into DIR (.device)
#         tools/scripts/device-check.sh run OUTDIR [DIR]   there, from the repository's root
#         tools/scripts/device-check.sh --dry-run          here, on lavapipe: the same path, quickly
#
# The lent machine (../shared/FACTS.md, /work/.library/device/README.md) has no Rust toolchain and
# no Vulkan loader, and takes one command of at most 2,000 characters that runs at most 9 minutes
# over a copy of the working tree plus the carried paths, 64 MiB in all; at most 8 files come back.
# So `pack` builds the release `lensmap` and the test binaries of TESTS here, strips them, archives
# them with the Debian packages of the Vulkan loader and the Khronos validation layer into DIR
# (git-ignored), and checks that DIR and the working tree together stay under 64 MiB. Then, with
# the device tool:
#
#     run(command: "bash tools/scripts/device-check.sh run $OUT", carry: [".device"], timeout_s: 600)
#
# `run` unpacks the packages into / where the machine lacks them (it is bare, and is given back
# after the call), selects NVIDIA's ICD where the machine has it, names the device and driver it
# finds (assuming none in particular), and runs the parts
# below, each under its own time budget (`timeout`), the budgets summing to under 9 minutes on the
# lent machine's 16 threads. Each part writes its file into OUTDIR as it finishes and appends its
# lines to OUTDIR/summary.txt, so a run cut short still reports what it reached; a failing part is
# recorded and the next one runs. OUTDIR gets at most 8 files (what the tool brings back):
#
#   summary.txt    device, driver, each part's status and time, and its main figures
#   tests.txt      the test binaries' output, one section each
#   hybrid.jsonl   bench hybrid: --tracer cpu, --tracer gpu --traversal bvh, --traversal driver
#   passes.jsonl   bench passes --blend all --viewpoints both (the command of docs/results.md)
#   glossy.jsonl   bench glossy: its frame-time part at the documented setting (see part_glossy)
#   headline.txt   tools/scripts/headline.sh at the paper's setting, 3 runs, and the runs' JSON
#   frame.jsonl    render of teapot-room at 1920×1080 with --compare
#   frame.png      that frame
#
# Each .jsonl line is one command: its argv, exit code, seconds, its stderr's end and its JSON.
#
# `--dry-run` runs the same path end to end on this machine's driver, as CI does after the test
# suite: it packs the suite's own debug build (target/debug; no release build), downloads the
# packages unless offline, unpacks them into a scratch folder instead of /, checks the size limit
# and its refusal, checks the lent machine's command lines with --validate-only, runs the packed
# tests and every part at tiny sizes and one run, checks that OUTDIR holds what the tool can bring
# back, and prints the device command with its length. It exits 1 on any failure. About 2 min on
# 2 cores (docs/testing.md#device-check).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
SCRIPT=tools/scripts/device-check.sh

# The GPU-touching test binaries, PACKAGE:TEST: the compositor and its blending schemes, the GPU
# vertex tracer and tessellation, the hybrid frame (end to end, into a host's image, streamed),
# the glossy pass, the validation messenger itself, and the C ABI. None reads a file of the
# repository at run time (pack checks that no packed binary holds this checkout's path).
TESTS=(
    lensmap-tests:compositor
    lensmap-tests:blending
    lensmap-tests:gpu_tracer
    lensmap-tests:gpu_tessellation
    lensmap-tests:hybrid
    lensmap-tests:host_image
    lensmap-tests:frame_stream
    lensmap-tests:glossy_pass
    lensmap-tests:validation
    lensmap-capi:abi
)
# The benches' settings there, and the dry run's tiny ones (each part's comment says why). The dry
# run also checks the lent machine's command lines with --validate-only.
HYBRID=()
HYBRID_DRY=(--width 64 --height 48 --frames 1 --em-size 16)
PASSES=(--blend all --viewpoints both)
PASSES_DRY=(--blend all --viewpoints both --width 64 --height 48 --frames 1 --max-layers 2)
GLOSSY=(--views 12 --map-samples 4 --reference-samples 4 --width 40 --height 30)
GLOSSY_DRY=(--scenes glossy-studio --views 12 --map-size 8 --map-samples 16 --reference-samples 16
    --width 32 --height 24 --frames 1 --frame-width 64)
FRAME=(--scene teapot-room --projected --width 1920 --height 1080 --supersampling 1 --compare)
FRAME_DRY=(--scene teapot-room --projected --width 192 --height 108 --supersampling 1 --compare)

LIMIT_MIB=64            # what travels: the working tree and the carried pack together
COMMAND_LIMIT=2000      # characters of the device command
RESULT_FILES=8          # files the device tool brings back, 16 MiB each at most
RESULT_FILE_MIB=16
DEADLINE_S=530          # the command's 9 minutes, less a margin for the tool's own start
ICD=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
PACKAGES=(libvulkan1 vulkan-validationlayers)
# shellcheck disable=SC2016 # $OUT is the device machine's, expanded there
DEVICE_COMMAND='bash tools/scripts/device-check.sh run $OUT'

die() { echo "device-check: $*" >&2; exit 1; }
now_ms() { echo $(($(date +%s%N) / 1000000)); }

# ---------------------------------------------------------------------------------------------
# pack

# The executables cargo reports on stdin (`--message-format=json`), for TESTS: lines
# "TEST PACKAGE_DIR EXECUTABLE", the package folder relative to the root. Cargo's "executable"
# field names the binary it built; its hash is not guessed.
pick_tests() {
    python3 -c '
import json, os, sys
root, wanted = sys.argv[1], sys.argv[2:]
found = {}
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") != "compiler-artifact" or not m.get("executable"):
        continue
    if m["target"]["kind"] != ["test"]:
        continue
    package_dir = os.path.dirname(m["manifest_path"])
    # package_id is "path+file:///dir#name@version", or "...#version" when the folder is named
    # after the package.
    fragment = m["package_id"].rpartition("#")[2]
    package = fragment.split("@")[0] if "@" in fragment else os.path.basename(package_dir)
    key = package + ":" + m["target"]["name"]
    if key in wanted:
        found[key] = (os.path.relpath(package_dir, root), m["executable"])
missing = [w for w in wanted if w not in found]
if missing:
    sys.exit("cargo built no test binary for " + ", ".join(missing))
for key in wanted:
    print(key.split(":")[1], *found[key])' "$ROOT" "${TESTS[@]}"
}

# The `lensmap` executable cargo reports on stdin.
pick_binary() {
    python3 -c '
import json, sys
paths = [m["executable"] for m in map(json.loads, sys.stdin)
         if m.get("reason") == "compiler-artifact" and m.get("executable")
         and m["target"]["kind"] == ["bin"] and m["target"]["name"] == "lensmap"
         and not m["profile"]["test"]]
if not paths:
    sys.exit("cargo built no lensmap binary")
print(paths[-1])'
}

# MiB (one decimal) of the files under the given paths.
mib() {
    python3 - "$@" <<'PY'
import os, sys
total = 0
for top in sys.argv[1:]:
    for folder, _, files in os.walk(top):
        total += sum(os.path.getsize(os.path.join(folder, f)) for f in files)
print(f"{total / 2**20:.1f}")
PY
}

# What the device tool sends: the tracked files and the untracked ones git does not ignore, plus
# the carried pack. Prints both and fails when together they pass `limit` MiB.
check_size() {
    local pack=$1 limit=$2 tree packed total
    tree=$(cd "$ROOT" && git ls-files -z -co --exclude-standard | python3 -c '
import os, sys
names = [n for n in sys.stdin.buffer.read().split(b"\0") if n]
print(f"{sum(os.path.getsize(n) for n in names if os.path.isfile(n)) / 2**20:.1f}")')
    packed=$(mib "$pack")
    total=$(python3 -c "print(f'{$packed + $tree:.1f}')")
    echo "packed: $packed MiB in $pack; with the working tree ($tree MiB): $total MiB of $limit"
    python3 -c "import sys; sys.exit($packed + $tree > $limit)" || {
        echo "device-check: over the device tool's $limit MiB: pack a smaller TESTS" >&2
        return 1
    }
}

# The loader and the validation layer for the lent machine, downloaded with private package lists
# (the machine's own apt state stays as it is), as FACTS.md says. `offline_ok`: a machine that
# cannot reach the mirror goes on without them, saying so (the dry run; pack needs them).
download_packages() {
    local dir=$1 offline_ok=$2 lists=/tmp/device-check-apt
    local o=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 "-oDir::State::Lists=$lists"
        -oAPT::Sandbox::User=root)
    mkdir -p "$lists/partial"
    rm -f "$dir"/*.deb
    if apt-get "${o[@]}" -qq update &&
        (cd "$dir" && apt-get "${o[@]}" -qq download "${PACKAGES[@]}"); then
        ls "$dir"/*.deb
    elif [ "$offline_ok" = 1 ]; then
        echo "device-check: no package mirror reachable: packed without ${PACKAGES[*]}" >&2
    else
        die "apt-get could not download ${PACKAGES[*]}"
    fi
}

# pack DIR PROFILE: PROFILE release (for the lent machine) or debug (the dry run: the test suite's
# own build, `lensmap` included, which `cargo test --workspace` has made, so the same command is a
# no-op; `-p lensmap-tests -p lensmap-capi` would resolve lensmap's features without the baker's
# dev-dependencies and build it again, and --test filters would leave `lensmap` out).
pack() (
    local dir=$1 profile=$2 stage binary
    mkdir -p "$dir"
    dir=$(cd "$dir" && pwd)
    stage=$(mktemp -d "${TMPDIR:-/tmp}/device-check-stage.XXXXXX")
    trap 'rm -rf "$stage"' EXIT
    mkdir -p "$stage/bin" "$stage/tests"
    cd "$ROOT"
    local packages=() names=() entry built
    for entry in "${TESTS[@]}"; do
        [[ " ${packages[*]} " == *" -p ${entry%%:*} "* ]] || packages+=(-p "${entry%%:*}")
        names+=(--test "${entry#*:}")
    done
    if [ "$profile" = release ]; then
        binary=$(cargo build --release --bin lensmap --message-format=json | pick_binary)
        built=$(cargo test --release --no-run --message-format=json "${packages[@]}" "${names[@]}")
    else
        built=$(cargo test --workspace --no-run --message-format=json)
        binary=$(pick_binary <<<"$built")
    fi
    # Symbols stay (a panic's backtrace names its functions); debug info goes.
    objcopy --strip-debug "$binary" "$stage/bin/lensmap"
    local name package_dir executable
    pick_tests <<<"$built" | while read -r name package_dir executable; do
        objcopy --strip-debug "$executable" "$stage/tests/$name"
        echo "$name $package_dir" >>"$stage/MANIFEST"
    done
    # A path of this checkout compiled in (env!("CARGO_MANIFEST_DIR")) names nothing there.
    local holds
    holds=$(grep -l -F "$ROOT/" "$stage"/bin/* "$stage"/tests/* || true)
    [ -z "$holds" ] || die "these binaries hold the path $ROOT/, which the lent machine lacks: $holds"
    echo "$(git describe --always --dirty) $profile, packed $(date -u +%FT%TZ)" >"$stage/BUILD"
    # One gzip archive: the binaries are 80 MB with their symbols, 29 MB gzipped, and every
    # machine has gzip.
    rm -f "$dir/bundle.tar.gz"
    tar -czf "$dir/bundle.tar.gz" -C "$stage" .
    download_packages "$dir" "$([ "$profile" = debug ] && echo 1 || echo 0)"
    ls -l "$dir"
    check_size "$dir" "$LIMIT_MIB"
)

# ---------------------------------------------------------------------------------------------
# run

# Appends to the summary (and says it).
note() { echo "$*" | tee -a "$OUT/summary.txt"; }

# Seconds left of the current part, at least 1.
left() { local s=$(((PART_END_MS - $(now_ms)) / 1000)); echo $((s > 0 ? s : 1)); }

# One command under the part's remaining time, its stdout and stderr kept in files of the scratch
# folder: limited NAME SECONDS COMMAND...; sets RC and SECONDS_TAKEN.
limited() {
    local name=$1 seconds=$2 t0
    shift 2
    t0=$(now_ms)
    RC=0
    timeout --kill-after=5 "$seconds" "$@" </dev/null >"$WORK/$name.out" 2>"$WORK/$name.err" || RC=$?
    SECONDS_TAKEN=$(python3 -c "print(f'{($(now_ms) - $t0) / 1000:.1f}')")
}

# Appends the command just run by `limited` as one JSON line to FILE: record FILE NAME COMMAND...
record() {
    local file=$1 name=$2
    shift 2
    python3 - "$WORK/$name.out" "$WORK/$name.err" "$name" "$RC" "$SECONDS_TAKEN" "$@" >>"$file" <<'PY'
import json, sys
out, err, name, rc, seconds = sys.argv[1:6]
argv, rc, seconds = sys.argv[6:], int(rc), float(seconds)
text = open(out, errors="replace").read()
try:
    result = json.loads(text)
except ValueError:
    result = None
print(json.dumps({"name": name, "argv": argv, "exit": rc, "timed_out": rc in (124, 137),
                  "seconds": seconds, "stderr": open(err, errors="replace").read()[-4000:],
                  "result": result, **({} if result is not None else {"stdout": text[-4000:]})}))
PY
}

# The main figures of a part's file, for the summary.
digest() {
    python3 - "$1" "$2" <<'PY'
import json, sys
part, path = sys.argv[1], sys.argv[2]
def lines():
    for line in open(path):
        yield json.loads(line)
def ms(v):
    return "-" if v is None else f"{v:.1f} ms"
for run in lines():
    r, head = run["result"], f"  {run['name']}:"
    if r is None:
        err = run["stderr"].strip().splitlines()
        print(head, f"exit {run['exit']}", err[-1][:300] if err else "")
        continue
    if part == "hybrid":
        rows = ", ".join(f"{row['variant']} {ms(row['median_ms']['total'])}" for row in r["rows"])
        tracers, stages = r["cpu_against_gpu_tracer"], r["gpu_stages"]
        where = f"GPU ({r['walk']} walk)" if r["walk"] else "CPU"
        print(head, f"{r['width']}×{r['height']}, vertices traced on the {where},",
              f"{r['threads']} threads: {rows}; CPU tracer {ms(tracers['cpu']['total_ms'])}",
              f"vs GPU {ms(tracers['gpu']['total_ms'])}; GPU stages: trace {ms(stages['trace_ms'])},",
              f"split {ms(stages['split_ms'])}, texgen {ms(stages['texgen_ms'])};",
              f"ray queries {'yes' if r['bvh_against_driver_walk'] is not None else 'no'},",
              f"f64 {'yes' if r['f32_against_f64'] is not None else 'no'}")
    elif part == "passes":
        # One line per viewpoint count and format: the paper's multipass scheme and the single
        # pass for n = 1…N (the file has every scheme).
        table = {}
        for row in r["rows"]:
            if row["variant"] == "single-pass" or row["blend"] == "front-to-back":
                key = (row["viewpoints"], row["format"], row["variant"])
                table.setdefault(key, []).append(f"{row['median_frame_ms']:.2f}")
        for (viewpoints, format, variant), times in sorted(table.items()):
            print(head, f"{viewpoints} viewpoint(s) {format} {variant}, n = 1…{len(times)}:",
                  " / ".join(times), "ms")
        pixels = sorted({row["lens_pixels"] for row in r["rows"]})
        print(head, f"lens pixels {pixels[0]}…{pixels[-1]}; largest error against the reference",
              f"{max(row['max_vs_reference'] for row in r['rows']):.2g}")
    elif part == "glossy":
        for scene in r["frame_time"]:
            for name, t in scene["times"].items():
                print(head, f"{scene['scene']} {name} {scene['width']}×{scene['height']}:",
                      f"frame {ms(t['frame_ms'])}, glossy pass {ms(t['glossy_pass_ms'])},",
                      f"{t['glossy_pixels']} glossy pixels")
    elif part == "frame":
        h = r["hybrid"]
        print(head, f"{r['width']}×{r['height']} {r['variant']}, tracer {r['tracer']}:",
              f"hybrid {ms(h['total_ms'])} (GPU {ms(h['gpu_ms'])}, tracing",
              f"{ms(h['ray_tracing_at_vertices_ms'])}, tessellation {ms(h['tessellation_ms'])}),",
              f"reference {ms(r['reference']['ms'])}, lens PSNR {r['lens_psnr_db']:.2f} dB")
PY
}

# part NAME BUDGET DRY_BUDGET FUNCTION: FUNCTION under BUDGET seconds (DRY_BUDGET in the dry run),
# cut to what is left before the deadline; its status and figures appended to the summary.
part() {
    local name=$1 budget=$2 function=$4 t0 rc=0 status left_s
    [ "$DRY" = 1 ] && budget=$3
    left_s=$(((DEADLINE_MS - $(now_ms)) / 1000))
    ((budget < left_s)) || budget=$left_s
    if ((budget < 5)); then
        note "$(printf '%-9s %-9s %5s  %s' "$name" skipped - "no time left")"
        FAILURES+=("$name")
        return
    fi
    t0=$(now_ms)
    PART_END_MS=$((t0 + budget * 1000))
    PART_NOTE=""
    "$function" || rc=$?
    case $rc in
        0) status=ok ;;
        124 | 137) status="timed-out" ;;
        *) status="failed" ;;
    esac
    [ "$rc" = 0 ] || FAILURES+=("$name")
    note "$(printf '%-9s %-9s %4ds  budget %ds%s' "$name" "$status" $((($(now_ms) - t0) / 1000)) \
        "$budget" "${PART_NOTE:+; $PART_NOTE}")"
    if [ -f "$OUT/$name.jsonl" ]; then
        digest "$name" "$OUT/$name.jsonl" | tee -a "$OUT/summary.txt" || true
    fi
}

# The device and its driver, as lensmap picks them (the cheapest command that names both).
part_device() {
    if command -v nvidia-smi >/dev/null; then
        note "nvidia-smi: $(nvidia-smi --query-gpu=name,driver_version,memory.total \
            --format=csv,noheader 2>&1 | head -3 | tr '\n' ' ')"
    fi
    limited device "$(left)" "$LENSMAP" bench passes --width 16 --height 16 --frames 1 \
        --max-layers 1 --viewpoints 1 --json
    if [ "$RC" = 0 ]; then
        note "$(python3 -c 'import json, sys; r = json.load(open(sys.argv[1]))
print("device: %s; driver: %s" % (r["device"], r["driver"]))' "$WORK/device.out")"
    else
        note "no device: $(tail -c 400 "$WORK/device.err")"
    fi
    return "$RC"
}

# Each test binary from its package's folder with CARGO_MANIFEST_DIR set, as `cargo test` runs
# it, with the validation layer on (the test helpers' default; LENSMAP_TEST_NO_VALIDATION unset).
part_tests() {
    local name package_dir cap=60 rc=0 seconds result
    [ "$DRY" = 1 ] && cap=120
    while read -r name package_dir; do
        seconds=$(left)
        ((seconds < cap)) || seconds=$cap
        echo "== $name ($package_dir), at most ${seconds}s" >>"$OUT/tests.txt"
        limited "test-$name" "$seconds" env -C "$ROOT/$package_dir" \
            CARGO_MANIFEST_DIR="$ROOT/$package_dir" "$WORK/tests/$name"
        cat "$WORK/test-$name.out" "$WORK/test-$name.err" >>"$OUT/tests.txt"
        result=$(grep -h '^test result:' "$WORK/test-$name.out" | tail -1 || true)
        echo "== $name: exit $RC, ${SECONDS_TAKEN}s" >>"$OUT/tests.txt"
        note "  $name: exit $RC, ${SECONDS_TAKEN}s${result:+, ${result#test result: }}"
        [ "$RC" = 0 ] || rc=$RC
    done <"$WORK/MANIFEST"
    return "$rc"
}

# The flags of a hybrid run: cpu, gpu-bvh or gpu-driver.
tracer_flags() {
    case $1 in
        cpu) echo --tracer cpu ;;
        gpu-bvh) echo --tracer gpu --traversal bvh ;;
        gpu-driver) echo --tracer gpu --traversal driver ;;
    esac
}

# The dry run's check of the lent machine's command lines: each accepted by --validate-only
# (every check that needs no device), so that a changed option fails CI, not the lent minutes.
part_settings() {
    local run rc=0 flags
    for run in cpu gpu-bvh gpu-driver; do
        read -ra flags <<<"$(tracer_flags "$run")"
        settings_ok "bench hybrid $run" bench hybrid "${flags[@]}" "${HYBRID[@]}" || rc=1
    done
    settings_ok "bench passes" bench passes "${PASSES[@]}" || rc=1
    settings_ok "bench glossy" bench glossy "${GLOSSY[@]}" || rc=1
    settings_ok render render "${FRAME[@]}" --out "$WORK/frame.png" || rc=1
    return "$rc"
}

settings_ok() {
    local what=$1
    shift
    limited settings "$(left)" "$LENSMAP" "$@" --validate-only
    [ "$RC" = 0 ] || note "  $what: exit $RC: $(tail -c 300 "$WORK/settings.err")"
    return "$RC"
}

# Both tracers and both GPU walks. The driver's walk needs ray queries, which many devices lack
# (lavapipe before Mesa 25): where the GPU run found none (its bvh_against_driver_walk is null),
# the refusal is recorded and is no failure.
part_hybrid() {
    local size=("${HYBRID[@]}") run rc=0 share runs=3 no_ray_queries=0
    [ "$DRY" = 1 ] && size=("${HYBRID_DRY[@]}")
    for run in cpu gpu-bvh gpu-driver; do
        local flags
        read -ra flags <<<"$(tracer_flags "$run")"
        share=$(($(left) / runs)) && runs=$((runs - 1))
        local argv=("$LENSMAP" bench hybrid "${flags[@]}" "${size[@]}" --json)
        limited "$run" "$((share > 1 ? share : 1))" "${argv[@]}"
        record "$OUT/hybrid.jsonl" "$run" "${argv[@]}"
        if [ "$run" = gpu-bvh ] && [ "$RC" = 0 ] && python3 -c 'import json, sys
sys.exit(json.load(open(sys.argv[1]))["bvh_against_driver_walk"] is not None)' "$WORK/$run.out"; then
            no_ray_queries=1
        fi
        if [ "$run" = gpu-driver ] && [ "$RC" = 2 ] && [ "$no_ray_queries" = 1 ]; then
            PART_NOTE="no ray queries on this device: the driver's walk was refused, as it should be"
            continue
        fi
        [ "$RC" = 0 ] || rc=$RC
    done
    return "$rc"
}

# The compositor's frame time, n = 1…4, both variants, every format and blending scheme.
part_passes() {
    local options=("${PASSES[@]}")
    [ "$DRY" = 1 ] && options=("${PASSES_DRY[@]}")
    local argv=("$LENSMAP" bench passes "${options[@]}" --json)
    limited passes "$(left)" "${argv[@]}"
    record "$OUT/passes.jsonl" passes "${argv[@]}"
    return "$RC"
}

# The glossy pass's frame time at its documented setting (the scenes' own materials, 12 samples,
# 640×480, 9 frames; the maps' sample count changes their values, not the pass's work). The
# bench's accuracy part is CPU work, measured in docs/results.md: cut to a minimum here, since
# baking the maps at the default 256 directions a texel would take minutes of the lent machine's
# slower threads (8 min on the 2-core machine).
part_glossy() {
    local options=("${GLOSSY[@]}")
    [ "$DRY" = 1 ] && options=("${GLOSSY_DRY[@]}")
    local argv=("$LENSMAP" bench glossy "${options[@]}" --json)
    limited glossy "$(left)" "${argv[@]}"
    record "$OUT/glossy.jsonl" glossy "${argv[@]}"
    return "$RC"
}

# The README's headline table at the paper's setting (headline.sh bakes samples 2 and 3 of each
# scene first). The dry run gives it tiny bakes, which it takes as they are, and one run.
part_headline() {
    local work=$WORK/headline runs=3 scene rc=0
    if [ "$DRY" = 1 ]; then
        runs=1
        for scene in teapot-room glass-sphere mirror-teapot; do
            [ "$rc" = 0 ] || break
            timeout --kill-after=5 "$(left)" "$LENSMAP" bake --scene "$scene" --samples 2,3 \
                --no-judge --width 32 --height 24 --supersampling 1 --multi-view 1 --em-size 16 \
                --out "$work/bakes/$scene" --quiet </dev/null >>"$OUT/headline.txt" 2>&1 || rc=$?
        done
    fi
    if [ "$rc" = 0 ]; then
        timeout --kill-after=5 "$(left)" bash tools/scripts/headline.sh "$LENSMAP" "$work" "$runs" \
            </dev/null >>"$OUT/headline.txt" 2>&1 || rc=$?
    fi
    grep -v '^baking' "$OUT/headline.txt" | tail -5 | sed 's/^/  /' | tee -a "$OUT/summary.txt"
    echo "== the runs' JSON (headline.sh's WORKDIR/runs)" >>"$OUT/headline.txt"
    for json in "$work"/runs/*.json; do
        [ -s "$json" ] && echo "$(basename "$json"): $(tr -d '\n' <"$json")" >>"$OUT/headline.txt"
    done
    return "$rc"
}

# One 1920×1080 frame (the runtime's default tracer: the GPU on a hardware device) against the
# reference ray tracer.
part_frame() {
    local options=("${FRAME[@]}")
    [ "$DRY" = 1 ] && options=("${FRAME_DRY[@]}")
    local argv=("$LENSMAP" render "${options[@]}" --json --out "$WORK/frame.png")
    limited frame "$(left)" "${argv[@]}"
    record "$OUT/frame.jsonl" frame "${argv[@]}"
    if [ -f "$WORK/frame.png" ] && (($(stat -c %s "$WORK/frame.png") < RESULT_FILE_MIB << 20)); then
        cp "$WORK/frame.png" "$OUT/frame.png"
    fi
    return "$RC"
}

# The Vulkan loader and validation layer from the pack. On the lent machine into / (it has
# neither, and is given back after the call), each only where the machine lacks it, so that `run`
# on a machine with its own keeps them; in the dry run into a scratch root, checked, leaving this
# machine's own packages alone.
install_loader() {
    local pack=$1 deb unpacked=()
    local debs=("$pack"/*.deb)
    if [ ! -e "${debs[0]}" ]; then
        note "loader: no packages in $pack (the dry run packed offline): the system's loader"
        return
    fi
    if [ "$DRY" = 1 ]; then
        for deb in "${debs[@]}"; do
            dpkg -x "$deb" "$WORK/root"
        done
        ls "$WORK"/root/usr/lib/x86_64-linux-gnu/libvulkan.so.1 \
            "$WORK"/root/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json \
            >/dev/null || die "the packages lack the loader or the validation layer"
        note "loader: ${debs[*]##*/} unpack into a scratch root (the dry run keeps the system's)"
        return
    fi
    for deb in "${debs[@]}"; do
        case ${deb##*/} in
            libvulkan1_*) [[ $(ldconfig -p) == *"libvulkan.so.1 "* ]] && continue ;;
            vulkan-validationlayers_*)
                [ -e /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json ] ||
                    [ -e /etc/vulkan/explicit_layer.d/VkLayer_khronos_validation.json ] &&
                    continue ;;
        esac
        dpkg -x "$deb" /
        unpacked+=("${deb##*/}")
    done
    ldconfig
    note "loader: unpacked into /: ${unpacked[*]:-none (the machine has its own)}"
}

run_checks() {
    local pack
    OUT=$(mkdir -p "$1" && cd "$1" && pwd)
    pack=$(cd "$2" && pwd)
    START_MS=$(now_ms)
    DEADLINE_MS=$((START_MS + DEADLINE_S * 1000))
    cd "$ROOT"
    [ -f "$pack/bundle.tar.gz" ] || die "no $pack/bundle.tar.gz: run '$SCRIPT pack' here first"
    rm -f "$OUT"/{summary.txt,tests.txt,hybrid.jsonl,passes.jsonl,glossy.jsonl,headline.txt} \
        "$OUT"/{frame.jsonl,frame.png}
    WORK=$(mktemp -d "${TMPDIR:-/tmp}/device-check.XXXXXX")
    trap 'rm -rf "$WORK"' EXIT
    tar -xzf "$pack/bundle.tar.gz" -C "$WORK"
    LENSMAP=$WORK/bin/lensmap
    note "lensmap device check of $(cat "$WORK/BUILD"); $(nproc) threads; $(date -u +%FT%TZ)"
    install_loader "$pack"
    if [ -f "$ICD" ]; then
        export VK_DRIVER_FILES=$ICD
        note "driver: VK_DRIVER_FILES=$ICD"
    fi
    # Timings without the validation layer; the tests turn it on themselves.
    unset LENSMAP_VALIDATION LENSMAP_TEST_NO_VALIDATION
    FAILURES=()
    [ "$DRY" = 0 ] || part settings 0 30 part_settings
    part device 20 30 part_device
    part tests 120 240 part_tests
    part hybrid 120 60 part_hybrid
    part passes 40 30 part_passes
    part glossy 40 30 part_glossy
    part headline 140 150 part_headline
    part frame 30 30 part_frame
    note "total: $((($(now_ms) - START_MS) / 1000))s; failed: ${FAILURES[*]:-none}"
    [ ${#FAILURES[@]} = 0 ]
}

# ---------------------------------------------------------------------------------------------
# the dry run

# OUTDIR holds no more files than the device tool brings back, each small enough and plainly named.
check_results() {
    python3 - "$1" "$RESULT_FILES" "$RESULT_FILE_MIB" <<'PY'
import os, re, sys
out, most, mib = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
files = sorted(os.listdir(out))
paths = {f: os.path.join(out, f) for f in files}
bad = [f for f, p in paths.items() if not re.fullmatch(r"[A-Za-z0-9._-]+", f)
       or not os.path.isfile(p) or os.path.getsize(p) > mib << 20]
print(f"results: {len(files)} files ({', '.join(files)})")
if len(files) > most or bad:
    sys.exit(f"device-check: the device tool brings back {most} plain files of at most {mib} MiB:"
             f" {bad or files}")
PY
}

dry_run() {
    local dir=$ROOT/target/device-check-dry-run t0 length
    t0=$(now_ms)
    rm -rf "$dir"
    (pack "$dir/pack" debug)
    # The limit refuses a pack over it.
    if check_size "$dir/pack" 1 >/dev/null 2>&1; then
        die "check_size passed a pack over a 1 MiB limit"
    fi
    echo "check_size refuses a pack over its limit"
    local rc=0
    (DRY=1 run_checks "$dir/out" "$dir/pack") || rc=$?
    check_results "$dir/out" || rc=1
    length=${#DEVICE_COMMAND}
    echo "device command ($length characters of $COMMAND_LIMIT), with carry [\".device\"]:"
    echo "    $DEVICE_COMMAND"
    ((length <= COMMAND_LIMIT)) || rc=1
    echo "dry run: $((($(now_ms) - t0) / 1000))s, results in $dir/out, exit $rc"
    return "$rc"
}

DRY=0
case ${1:-} in
    pack) pack "${2:-$ROOT/.device}" release ;;
    run) [ $# -ge 2 ] || die "usage: $0 run OUTDIR [DIR]"; run_checks "$2" "${3:-$ROOT/.device}" ;;
    --dry-run) dry_run ;;
    *) echo "usage: $0 pack [DIR] | run OUTDIR [DIR] | --dry-run" >&2; exit 2 ;;
esac
