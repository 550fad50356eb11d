#!/usr/bin/env bash
# same-output.sh — prove that a refactor changed no behaviour of the `lensmap` CLI.
#
# Usage:  tools/scripts/same-output.sh [OPTIONS] BEFORE_BINARY AFTER_BINARY [WORKDIR]
#
# Runs both binaries on the same fixed set of commands (demo, synthetic demo, render in several
# variants/formats/scenes, a bake written and read back, passes plans, the three benchmarks,
# reference, two bad-input cases), each binary into its own directory (WORKDIR/before,
# WORKDIR/after; captured stdout/stderr/exit codes in WORKDIR/logs/{before,after}). WORKDIR
# defaults to a fresh `mktemp -d`; if given, only its before/, after/ and logs/ are replaced.
# Then it compares:
#   1. every PNG/EXR written: byte-identical (cmp). One known exception, see EXR below: an EXR
#      that is not byte-identical passes if its header is byte-identical and it holds the same
#      chunks (tiles/scanline blocks, by coordinate) with the same bytes, only stored in another
#      order; if chunk bytes differ, they are decoded and the pixels compared;
#   2. every JSON written or printed: same structure (keys recursively, array lengths) and equal
#      values for every field that is not a wall-clock timing (see TIMING below); strings have
#      the output directory normalized to <DIR>. manifest.json of a bake: the `created_by` field
#      is left out;
#   3. every stdout text: same lines after masking every number by `#` and collapsing spaces
#      (the same fields in the same order); `passes` tables are compared exactly (deterministic
#      plans); output-dir paths are normalized to <DIR> first;
#   4. exit codes: equal; every command that should succeed must exit 0 on both sides; the two
#      bad-input cases must print exactly one stderr line on each side (texts shown, not compared);
# and fails on any Khronos validation message (LENSMAP_VALIDATION=1 is set): a
# "validation messages: N" line with N > 0, or a "validation <SEVERITY>: ..." line on stderr.
#
# Declared changes. A refactoring sometimes changes a few outputs on purpose (a new JSON field, a
# new table column, a sum taken in another order). Rather than reading such differences out of a
# DIFFERENT run by eye, the reviewer states them on the command line; each declared difference is
# then listed (so it stays visible) but is not a problem, and any other difference still is:
#   --added-field NAME   (repeatable) a JSON key NAME, at any depth, may exist only in AFTER:
#                        printed as `added (expected): $.path`. A NAME present on both sides is
#                        compared as usual; a NAME present only in BEFORE is still a problem.
#   --rtol X             (default 0: exact) deterministic (non-timing) JSON numbers of the same
#                        type that differ by |a-b| <= X*max(|a|,|b|) count as equal; printed as
#                        `equal within rtol: $.path a vs b`. For results whose floating-point
#                        summation order changed (differences ~1e-16 relative).
#   --text-change LABEL  (repeatable) the text output with this LABEL (as printed, e.g.
#                        "demo stdout") may differ, but only by extension: every BEFORE line
#                        (numbers masked) must still be found, in order, at the start of an AFTER
#                        line, followed by nothing or by a new word (new columns or text appended
#                        at its end: `tri tests` -> `tri testsX` does not count), and blank lines
#                        must stay blank; other AFTER lines are inserted lines. Printed as
#                        `extended (expected): LABEL` with the extended and inserted lines.
#                        A LABEL that names no text output is a problem (a typo would otherwise
#                        go unnoticed).
#   --changed-field NAME (repeatable) the value of a JSON key NAME, at any depth, may differ (a
#                        figure whose definition changed on purpose): each difference is printed
#                        as `changed (expected): $.path a vs b`, so the change is measured.
#   --changed-text LABEL (repeatable) the text output with this LABEL may differ in any line;
#                        the differing lines are printed.
# Declared changes that do not occur are noted in the summary but are not problems, so the
# self-check below also passes with options.
#
# Prints one line per comparison, a summary and finally `SAME` (exit 0) or
# `DIFFERENT (k problems)` (exit 1). Exit 2 on usage errors.
#
# Needs a Vulkan driver (lavapipe: mesa-vulkan-drivers, libvulkan1) and vulkan-validationlayers,
# and python3 (standard library only). About 15 s of run time per binary on 2 CPU cores.
# Self-check: running it with the same binary twice (BEFORE == AFTER) must print SAME; this
# checks that every compared output is deterministic and that the timing masks are right.
set -uo pipefail

usage() {
    echo "usage: $0 [--added-field NAME]... [--changed-field NAME]... [--rtol X]" \
        "[--text-change LABEL]... [--changed-text LABEL]..." \
        "BEFORE_BINARY AFTER_BINARY [WORKDIR]" >&2
    exit 2
}
# Declared changes, handed to the comparison (python, below) as KIND VALUE pairs.
RTOL=0
declare -a DECLARED=()
while [ $# -gt 0 ]; do
    case $1 in
        --added-field | --changed-field | --text-change | --changed-text)
            [ $# -ge 2 ] && [ -n "$2" ] || { echo "error: $1 needs a value" >&2; usage; }
            DECLARED+=("${1#--}" "$2")
            shift 2
            ;;
        --rtol)
            [ $# -ge 2 ] || { echo "error: --rtol needs a value" >&2; usage; }
            if ! python3 -c 'import math, sys; x = float(sys.argv[1])
sys.exit(not (math.isfinite(x) and x >= 0))' "$2" 2>/dev/null; then
                echo "error: --rtol $2: not a finite number >= 0" >&2
                usage
            fi
            RTOL=$2
            shift 2
            ;;
        --) shift; break ;;
        -h | --help) usage ;;
        -*) echo "error: unknown option $1" >&2; usage ;;
        *) break ;;
    esac
done
if [ $# -lt 2 ] || [ $# -gt 3 ]; then
    usage
fi
for bin in "$1" "$2"; do
    if [ ! -x "$bin" ]; then
        echo "error: $bin is not an executable file" >&2
        exit 2
    fi
done
BEFORE=$(realpath "$1")
AFTER=$(realpath "$2")
if [ $# -eq 3 ]; then
    mkdir -p "$3" || exit 2
    WORKDIR=$(cd "$3" && pwd -P)
else
    WORKDIR=$(mktemp -d -t same-output.XXXXXX) || exit 2
    WORKDIR=$(cd "$WORKDIR" && pwd -P)
fi
rm -rf "$WORKDIR/before" "$WORKDIR/after" "$WORKDIR/logs"
mkdir -p "$WORKDIR/before" "$WORKDIR/after" "$WORKDIR/logs/before" "$WORKDIR/logs/after"
CASES="$WORKDIR/logs/cases.tsv"
: >"$CASES"

export LENSMAP_VALIDATION=1

# ---------------------------------------------------------------------------------------------
# The commands. `@DIR@` stands for the side's output directory (WORKDIR/before or WORKDIR/after).
# Kinds: text  = stdout is text, compared with numbers masked
#        exact = stdout is text, compared exactly (deterministic: pass plans)
#        json  = stdout is JSON, compared as JSON
#        bad   = must fail: exit codes equal, stderr one line on each side (text not compared)
# ---------------------------------------------------------------------------------------------
declare -a CASE_NAMES=() CASE_KINDS=() CASE_ARGS=()
case_add() { # NAME KIND ARGS...
    CASE_NAMES+=("$1")
    CASE_KINDS+=("$2")
    shift 2
    local joined="" arg
    for arg in "$@"; do joined+="$arg"$'\x1f'; done
    CASE_ARGS+=("$joined")
}

case_add demo text demo --out @DIR@/demo --width 160 --height 120 --supersampling 2 --report @DIR@/demo.json
case_add demo-synthetic text demo --synthetic --out @DIR@/synthetic --width 160 --height 120 --frames 1

TR=(--scene teapot-room --projected --view 2 --width 160 --height 120 --supersampling 2 --compare --json)
case_add render-tr json render "${TR[@]}" --out @DIR@/render-tr.png
case_add render-tr-multipass-rgba8 json render "${TR[@]}" --variant multipass --format rgba8 --out @DIR@/render-tr-multipass-rgba8.png
case_add render-tr-rgba32f json render "${TR[@]}" --format rgba32f --out @DIR@/render-tr-rgba32f.png
case_add render-gs json render --scene glass-sphere --projected --view 0 --width 96 --height 72 --supersampling 1 --compare --json --out @DIR@/render-gs.png
case_add render-mt json render --scene mirror-teapot --projected --width 96 --height 72 --supersampling 1 --json --out @DIR@/render-mt.png
# The GPU's vertex stages: drawn where the device leaves the meshes (the default of `--tracer
# gpu`), and read back (a frame of the viewer's recording, which reads them back for its counts).
case_add render-tr-gpu json render "${TR[@]}" --tracer gpu --out @DIR@/render-tr-gpu.png
case_add render-mt-gpu-multipass json render --scene mirror-teapot --projected --width 96 --height 72 --supersampling 1 --tracer gpu --variant multipass --json --out @DIR@/render-mt-gpu-multipass.png
# The human-readable report of `render` too (same settings as render-gs).
case_add render-gs-text text render --scene glass-sphere --projected --view 0 --width 96 --height 72 --supersampling 1 --compare --out @DIR@/render-gs-text.png

# A bake written once, then read back (its EXRs and manifest are compared as written files).
case_add render-write-bake json render --scene teapot-room --projected --view 2 --width 160 --height 120 --supersampling 2 --write-bake @DIR@/bake --json --out @DIR@/render-write-bake.png
case_add render-from-bake json render --scene teapot-room --bake @DIR@/bake --view 2 --width 160 --height 120 --supersampling 2 --compare --json --out @DIR@/render-from-bake.png

# Pass plans: layers 1..4 (and 6, the single-pass maximum), 1|2 viewpoints, 1|2 terms,
# both variants, every format; each as a table (exact) and as JSON.
for config in \
    "1 1 1 multipass rgba8" \
    "1 2 2 single-pass rgba16f" \
    "1 1 2 single-pass rgba32f" \
    "2 1 2 multipass rgba16f" \
    "2 2 1 single-pass rgba32f" \
    "2 2 2 multipass rgba32f" \
    "3 2 2 multipass rgba8" \
    "3 1 1 single-pass rgba8" \
    "3 2 1 multipass rgba32f" \
    "4 2 2 multipass rgba16f" \
    "4 1 2 single-pass rgba8" \
    "4 2 2 single-pass rgba32f" \
    "6 2 2 single-pass rgba16f"; do
    read -r layers viewpoints terms variant format <<<"$config"
    name="passes-l$layers-v$viewpoints-t$terms-$variant-$format"
    set -- --layers "$layers" --viewpoints "$viewpoints" --terms "$terms" --variant "$variant" --format "$format"
    case_add "$name" exact passes "$@"
    case_add "$name-json" json passes "$@" --json
done
# The GPU frame's plan: two lens objects' parts tessellated on the device.
case_add passes-gpu-parts exact passes --layers 2 --viewpoints 2 --terms 2 --gpu-parts 2

# The bake and the figures judged over lens pixels: a small bake of a scene with two lens objects
# (its EXRs and manifest compared as files, its judge's PSNR in its JSON), bench bake on it, and
# bench infer, bench error and bench passes on a scene.
case_add bake-mt json bake --scene mirror-teapot --samples 0,1 --em-size 16 --width 48 --height 36 --supersampling 1 --out @DIR@/bake-mt --json
case_add bench-bake-mt json bench bake --scene mirror-teapot --bake @DIR@/bake-mt --width 48 --height 36 --supersampling 1 --reference-supersampling 2 --json
case_add bench-infer-gs json bench infer --scene glass-sphere --width 48 --height 36 --supersampling 1 --reference-supersampling 2 --em-size 16 --runs 1 --json
case_add bench-error-gs json bench error --scene glass-sphere --width 48 --height 36 --reference-supersampling 2 --frames 1 --json
case_add bench-passes-tr json bench passes --scene teapot-room --width 64 --height 48 --frames 1 --blend all --json

case_add bench-passes text bench passes --width 64 --height 48 --frames 1 --max-layers 2 --report @DIR@/bench-passes.json
case_add bench-hybrid text bench hybrid --width 96 --height 72 --frames 1 --report @DIR@/bench-hybrid.json
case_add bench-trace text bench trace --width 48 --height 36 --supersampling 1 --runs 1 --report @DIR@/bench-trace.json
case_add reference json reference --scene glass-sphere --view 0 --width 64 --height 48 --out @DIR@/reference --json
case_add reference-text text reference --scene glass-sphere --view 0 --width 64 --height 48 --out @DIR@/reference-text

# Bad input. `--t -1` (with a space) is rejected by clap as an unknown argument '-1' with a
# multi-line usage message, before lensmap sees it; `--t=-1` reaches lensmap's own check.
case_add bad-passes-layers bad passes --layers 9 --variant single-pass
case_add bad-render-t bad render --scene teapot-room --projected --t=-1

# ---------------------------------------------------------------------------------------------
run_side() { # SIDE BINARY
    local side=$1 bin=$2 dir="$WORKDIR/$1" logs="$WORKDIR/logs/$1" i name
    local started=$SECONDS
    echo "running $side: $bin"
    for i in "${!CASE_NAMES[@]}"; do
        name=${CASE_NAMES[$i]}
        local -a args=()
        local arg
        mapfile -t -d $'\x1f' args < <(printf '%s' "${CASE_ARGS[$i]}")
        for arg in "${!args[@]}"; do args[$arg]=${args[$arg]//@DIR@/$dir}; done
        printf '%s\n' "${args[*]}" >"$logs/$name.cmd"
        # Run inside the side's directory, so that any relative default output lands there too.
        (cd "$dir" && "$bin" "${args[@]}") >"$logs/$name.out" 2>"$logs/$name.err" </dev/null
        echo $? >"$logs/$name.rc"
    done
    echo "  $side: ${#CASE_NAMES[@]} commands in $((SECONDS - started)) s"
}

for i in "${!CASE_NAMES[@]}"; do
    printf '%s\t%s\n' "${CASE_NAMES[$i]}" "${CASE_KINDS[$i]}" >>"$CASES"
done
run_side before "$BEFORE"
run_side after "$AFTER"

# ---------------------------------------------------------------------------------------------
python3 - "$WORKDIR" "$RTOL" "${DECLARED[@]}" <<'PY'
import json, os, re, subprocess, sys

work = sys.argv[1]
# Declared changes (see the header): --rtol, --added-field NAME..., --text-change LABEL...
RTOL = float(sys.argv[2])
declared = list(zip(sys.argv[3::2], sys.argv[4::2]))
ADDED_FIELDS = {v for k, v in declared if k == "added-field"}
CHANGED_FIELDS = {v for k, v in declared if k == "changed-field"}
TEXT_CHANGES = {v for k, v in declared if k == "text-change"}
CHANGED_TEXTS = {v for k, v in declared if k == "changed-text"}
seen = {"added": set(), "changed": set(), "changed_text": set(), "rtol": 0, "extended": set(), "not_extended": set(), "text_labels": set()}

problems = []
counts = {"images": 0, "images_same": 0, "exr_reordered": 0, "json": 0, "json_same": 0, "json_declared": 0,
          "text": 0, "text_same": 0, "text_declared": 0, "exit": 0, "exit_same": 0, "other": 0, "other_same": 0}

def problem(msg):
    problems.append(msg)
    print(f"  PROBLEM: {msg}")

def read(path):
    with open(path, encoding="utf-8", errors="replace") as f:
        return f.read()

def normalize_dir(text, side):
    # Output paths differ only in the side's directory name.
    return text.replace(os.path.join(work, side), "<DIR>")

# ---- JSON -----------------------------------------------------------------------------------
# Wall-clock timings, found in the actual JSON: keys with an underscore-separated word "ms"
# (total_ms, gpu_ms, median_frame_ms, reference.ms, median_ms {...}), "seconds" (seconds,
# median_seconds, prepare_seconds), "time" (reduction_time, reduction.time: ratios of times),
# throughput mrays_per_second, frame rates and speed-ups ("fps", "speedup": fps_in_flight,
# cpu_speedup), `bench hybrid`'s still-camera `ratio` (of two times), and what `bench error`
# derives from its frame times (which points lie on the Pareto frontier, and the default's gap to
# it). Plain substring "ms" would wrongly hit rms_vs_rgba32f and
# terms, which are deterministic. Everything under a timing key is a timing (median_ms {...},
# seconds [...]); its structure is still compared.
TIMING_WORDS = {"ms", "seconds", "time", "speedup", "fps"}
TIMING_KEYS = {"mrays_per_second", "on_frontier", "default_gap_to_frontier_db", "ratio"}
# Not behaviour: who wrote a bake (the version string).
IGNORED_KEYS = {"manifest.json": {"created_by"}}

def is_timing(key):
    return key in TIMING_KEYS or bool(TIMING_WORDS & set(key.lower().split("_")))

def within_rtol(a, b):
    """Two numbers of the same type (not booleans) within the declared --rtol."""
    return (RTOL > 0 and type(a) is type(b) and type(a) in (int, float)
            and abs(a - b) <= RTOL * max(abs(a), abs(b)))

def json_diff(a, b, path, timing, ignored, out, expected):
    """Appends differences to `out` (problems) and declared differences to `expected`."""
    if isinstance(a, dict) and isinstance(b, dict):
        ka, kb = set(a) - ignored, set(b) - ignored
        for k in sorted(ka - kb):
            out.append(f"{path}.{k}: only in before")
        for k in sorted(kb - ka):
            if k in ADDED_FIELDS:
                seen["added"].add(k)
                expected.append(f"added (expected): {path}.{k}")
            else:
                out.append(f"{path}.{k}: only in after")
        for k in sorted(ka & kb):
            json_diff(a[k], b[k], f"{path}.{k}", timing or is_timing(k), ignored, out, expected)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{path}: array length {len(a)} vs {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            json_diff(x, y, f"{path}[{i}]", timing, ignored, out, expected)
    elif timing:
        number = (int, float)
        if not (isinstance(a, number) and isinstance(b, number)) and type(a) is not type(b):
            out.append(f"{path}: timing of type {type(a).__name__} vs {type(b).__name__}")
    elif type(a) is not type(b) or a != b:
        keys = re.findall(r"\.([A-Za-z0-9_]+)", path)
        if keys and keys[-1] in CHANGED_FIELDS:
            seen["changed"].add(keys[-1])
            expected.append(f"changed (expected): {path}: {json.dumps(a)} vs {json.dumps(b)}")
        elif within_rtol(a, b):
            seen["rtol"] += 1
            expected.append(f"equal within rtol: {path} {json.dumps(a)} vs {json.dumps(b)}"
                            f" (relative {abs(a - b) / max(abs(a), abs(b)):.1e})")
        else:
            out.append(f"{path}: {json.dumps(a)} vs {json.dumps(b)}")

def compare_json(label, text_a, text_b, ignored=frozenset()):
    counts["json"] += 1
    try:
        a = json.loads(normalize_dir(text_a, "before"))
        b = json.loads(normalize_dir(text_b, "after"))
    except json.JSONDecodeError as e:
        problem(f"{label}: not valid JSON ({e})")
        return
    diffs, expected = [], []
    json_diff(a, b, "$", False, set(ignored), diffs, expected)
    if diffs:
        problem(f"{label}: JSON differs in {len(diffs)} field(s)")
        for d in diffs[:20]:
            print(f"      {d}")
        if len(diffs) > 20:
            print(f"      ... and {len(diffs) - 20} more")
    elif expected:
        counts["json_declared"] += 1
        print(f"  declared   json   {label}: {len(expected)} declared difference(s)")
    else:
        counts["json_same"] += 1
        print(f"  same       json   {label}")
    for e in expected:  # all of them, even next to problems: each one is a claim to check
        print(f"      {e}")

# ---- text -----------------------------------------------------------------------------------
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")

def mask(text):
    lines = []
    for line in text.splitlines():
        line = NUMBER.sub("#", line)
        lines.append(re.sub(r" +", " ", line).strip())
    return lines

GLUED = re.compile(r"[\w#]")  # characters that continue a word (or a masked number)

def extends(x, y):
    """Whether line y is line x with something appended: x itself, or x followed by a new word
    (so `tri tests` -> `tri testsX` or `#` -> `#ms` is not an extension). Blank stays blank."""
    if not x:
        return not y
    if not y.startswith(x):
        return False
    rest = y[len(x):]
    return not rest or not (GLUED.match(x[-1]) and GLUED.match(rest[0]))

def match_extension(la, lb):
    """For a --text-change: every line of la, in order, extended by a line of lb (earliest match
    first, which finds one if any exists). Returns (extended (i, j) pairs, inserted j, None) or
    (.., .., index of the first la line that has no match)."""
    pairs, j = [], 0
    for i, x in enumerate(la):
        while j < len(lb) and not extends(x, lb[j]):
            j += 1
        if j == len(lb):
            return pairs, [], i
        pairs.append((i, j))
        j += 1
    matched = {j for _, j in pairs}
    return pairs, [j for j in range(len(lb)) if j not in matched], None

def compare_text(label, text_a, text_b, exact):
    counts["text"] += 1
    seen["text_labels"].add(label)
    a, b = normalize_dir(text_a, "before"), normalize_dir(text_b, "after")
    la, lb = (a.splitlines(), b.splitlines()) if exact else (mask(a), mask(b))
    if la == lb:
        counts["text_same"] += 1
        print(f"  same       text   {label}{' (exact)' if exact else ''}")
        return
    how = " (exact comparison)" if exact else " (numbers masked)"
    if label in CHANGED_TEXTS:
        seen["changed_text"].add(label)
        counts["text_declared"] += 1
        print(f"  declared   text   {label}")
        for i in range(max(len(la), len(lb))):
            x = la[i] if i < len(la) else "<missing>"
            y = lb[i] if i < len(lb) else "<missing>"
            if x != y:
                print(f"      changed (expected): line {i + 1}: before: {x}")
                print(f"      {' ' * len(str(i + 1))}                          after:  {y}")
        return
    if label in TEXT_CHANGES:
        pairs, inserted, unmatched = match_extension(la, lb)
        if unmatched is None:
            seen["extended"].add(label)
            counts["text_declared"] += 1
            print(f"  declared   text   {label}")
            print(f"      extended (expected): {label}")
            before_of = {j: i for i, j in pairs}
            for j in range(len(lb)):  # in the after output's order
                if j in inserted:
                    print(f"      line {j + 1} inserted: {lb[j]}")
                elif la[before_of[j]] != lb[j]:
                    print(f"      line {j + 1} extended: before: {la[before_of[j]]}")
                    print(f"      {' ' * len(str(j + 1))}                after:  {lb[j]}")
            return
        seen["not_extended"].add(label)
        problem(f"{label}: text differs{how} beyond the declared --text-change: before line "
                f"{unmatched + 1} is not the start of any later after line: {la[unmatched]}")
    else:
        problem(f"{label}: text differs{how}")
    shown = 0
    for i in range(max(len(la), len(lb))):
        x = la[i] if i < len(la) else "<missing>"
        y = lb[i] if i < len(lb) else "<missing>"
        if x != y and shown < 10:
            print(f"      line {i + 1}: before: {x}")
            print(f"      {' ' * len(str(i + 1))}       after:  {y}")
            shown += 1

# ---- validation -----------------------------------------------------------------------------
COUNT_LINE = re.compile(r"validation messages: (\d+)")
MESSAGE_LINE = re.compile(r"^validation [A-Z_]+: ")
validation_counts = 0

def check_validation(label, side, out, err):
    global validation_counts
    for line in (out + "\n" + err).splitlines():
        m = COUNT_LINE.search(line)
        if m:
            validation_counts += 1
            if int(m.group(1)) > 0:
                problem(f"{label} ({side}): {line.strip()}")
        elif MESSAGE_LINE.match(line):
            problem(f"{label} ({side}): {line.strip()[:300]}")

# ---- the commands' stdout, stderr and exit codes --------------------------------------------
print()
print("== command outputs")
cases = [line.split("\t") for line in read(os.path.join(work, "logs", "cases.tsv")).splitlines()]
for name, kind in cases:
    logs = {s: os.path.join(work, "logs", s, name) for s in ("before", "after")}
    out = {s: read(logs[s] + ".out") for s in logs}
    err = {s: read(logs[s] + ".err") for s in logs}
    rc = {s: int(read(logs[s] + ".rc").strip() or -1) for s in logs}
    for s in logs:
        check_validation(name, s, out[s], err[s])
    counts["exit"] += 1
    if rc["before"] != rc["after"]:
        problem(f"{name}: exit code {rc['before']} (before) vs {rc['after']} (after)")
    else:
        counts["exit_same"] += 1
    if kind == "bad":
        print(f"  {'same' if rc['before'] == rc['after'] else 'DIFFERENT':<10} exit   {name}: "
              f"{rc['before']} vs {rc['after']}")
        if rc["before"] == 0:
            problem(f"{name}: bad input accepted (exit 0)")
        for s in logs:
            lines = err[s].splitlines()
            print(f"      stderr {s:<6}: {' | '.join(lines)}")
            if len(lines) != 1:
                problem(f"{name} ({s}): stderr has {len(lines)} lines, expected 1")
        compare_text(f"{name} stdout", out["before"], out["after"], exact=False)
        continue
    for s in logs:
        if rc[s] != 0:
            problem(f"{name} ({s}): exit code {rc[s]}; stderr: {err[s].strip()[:500]}")
    if kind == "json":
        compare_json(f"{name} stdout", out["before"], out["after"])
    else:
        compare_text(f"{name} stdout", out["before"], out["after"], exact=(kind == "exact"))
    # stderr of a successful command is normally empty; compare it like text
    if err["before"].strip() or err["after"].strip():
        compare_text(f"{name} stderr", err["before"], err["after"], exact=False)

# ---- EXR -------------------------------------------------------------------------------------
# Nondeterminism found by running the same binary twice: the frame EXRs (write_exr in
# engine/src/trace/image.rs, through the `image` crate's OpenEXR encoder) are tiled 64×64, RLE,
# lineOrder RANDOM_Y, and the tiles are stored in the order their parallel compression finishes.
# Run to run the offset table and the tile positions differ (same size, same header, same tiles).
# So an EXR that is not byte-identical is read at the container level: header bytes equal, the
# same chunk coordinates, and per chunk the same bytes, or failing that the same decoded pixel
# bytes (NONE, RLE, ZIPS, ZIP; chunks that would not shrink are stored raw). Bake cube maps
# (scanline, ZIP, lineOrder INCREASING) have been byte-identical run to run.
import struct, zlib
from array import array

EXR_LINES_PER_BLOCK = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 32, 9: 256}

def _cstr(d, i):
    j = d.index(b"\0", i)
    return d[i:j].decode("latin-1"), j + 1

def exr_read(d):
    """EXR file bytes -> (header bytes, {(part, chunk coordinates): (compression, raw size, data)},
    whether every channel is 32-bit float)."""
    if d[:4] != b"\x76\x2f\x31\x01":
        raise ValueError("not an EXR file")
    flags = struct.unpack_from("<I", d, 4)[0]
    if flags & 0x800:
        raise ValueError("deep data is not supported")
    multipart = bool(flags & 0x1000)
    i, headers = 8, []
    while True:
        attrs = {}
        while d[i] != 0:
            name, i = _cstr(d, i)
            _, i = _cstr(d, i)
            size = struct.unpack_from("<i", d, i)[0]
            attrs[name] = d[i + 4:i + 4 + size]
            i += 4 + size
        i += 1
        headers.append(attrs)
        if not multipart or d[i] == 0:
            break
    i += 1 if multipart else 0
    header_bytes, chunks, all_float = d[:i], {}, True
    for part, attrs in enumerate(headers):
        count = struct.unpack("<i", attrs["chunkCount"])[0]
        kind = attrs.get("type", b"tiledimage" if flags & 0x200 else b"scanlineimage")
        tiled = kind.rstrip(b"\0") == b"tiledimage"
        compression = attrs["compression"][0]
        x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"])
        pixel_bytes, k, channels = 0, 0, attrs["channels"]
        while channels[k] != 0:
            _, k = _cstr(channels, k)
            pixel_type = struct.unpack_from("<i", channels, k)[0]
            all_float = all_float and pixel_type == 2
            pixel_bytes += 2 if pixel_type == 1 else 4
            k += 16
        for offset in struct.unpack_from(f"<{count}Q", d, i):
            p = offset + (4 if multipart else 0)
            if tiled:
                key = struct.unpack_from("<4i", d, p)
                p += 16
                tx, ty, lx, ly = key
                xs, ys, mode = struct.unpack_from("<IIB", attrs["tiles"])
                up = bool(mode & 0x10)
                level = lambda n, l: max(1, -(-n // (1 << l)) if up else n >> l)
                w = min(xs, level(x1 - x0 + 1, lx) - tx * xs)
                h = min(ys, level(y1 - y0 + 1, ly) - ty * ys)
            else:
                key = struct.unpack_from("<i", d, p)
                p += 4
                w = x1 - x0 + 1
                h = min(EXR_LINES_PER_BLOCK.get(compression, 1), y1 + 1 - key[0])
            size = struct.unpack_from("<i", d, p)[0]
            chunks[(part, key)] = (compression, w * h * pixel_bytes, d[p + 4:p + 4 + size])
        i += 8 * count
    return header_bytes, chunks, all_float

def _unpredict(t):
    t = bytearray(t)
    for k in range(1, len(t)):
        t[k] = (t[k - 1] + t[k] - 128) & 0xFF
    half = (len(t) + 1) // 2
    out = bytearray(len(t))
    out[0::2], out[1::2] = t[:half], t[half:]
    return bytes(out)

def exr_decode(compression, raw_size, data):
    """A chunk's pixel bytes."""
    if compression == 0 or len(data) >= raw_size:
        return data
    if compression == 1:  # RLE
        out, k = bytearray(), 0
        while k < len(data):
            n = struct.unpack_from("b", data, k)[0]
            if n < 0:
                out += data[k + 1:k + 1 - n]
                k += 1 - n
            else:
                out += data[k + 1:k + 2] * (n + 1)
                k += 2
        return _unpredict(out)
    if compression in (2, 3):  # ZIPS, ZIP
        return _unpredict(zlib.decompress(data))
    raise ValueError(f"EXR compression {compression} cannot be decoded here")

def compare_exr(pa, pb):
    """(equal?, verdict) for two EXRs that are not byte-identical."""
    try:
        ha, ca, floats = exr_read(open(pa, "rb").read())
        hb, cb, _ = exr_read(open(pb, "rb").read())
    except (ValueError, KeyError, IndexError, struct.error) as e:
        return False, f"cannot read as EXR ({e})"
    if ha != hb:
        return False, "EXR headers differ"
    if set(ca) != set(cb):
        return False, f"different chunks ({len(ca)} vs {len(cb)})"
    changed = [key for key in ca if ca[key][2] != cb[key][2]]
    if not changed:
        return True, f"same {len(ca)} chunks, stored in another order"
    differing, worst = 0, 0.0
    for key in changed:
        try:
            xa, xb = exr_decode(*ca[key]), exr_decode(*cb[key])
        except (ValueError, zlib.error) as e:
            return False, f"chunk {key} differs and cannot be decoded ({e})"
        if xa != xb:
            differing += 1
            if floats and len(xa) == len(xb):
                fa, fb = array("f", xa), array("f", xb)
                worst = max([worst] + [abs(x - y) for x, y in zip(fa, fb) if x != y])
    if differing == 0:
        return True, f"same pixels; {len(changed)} chunk(s) compressed differently"
    extra = f", max |difference| {worst:.3e}" if floats else ""
    return False, f"pixels differ in {differing} of {len(ca)} chunks{extra}"

# ---- the files written ----------------------------------------------------------------------
def files_under(root):
    found = set()
    for d, _, names in os.walk(root):
        for n in names:
            found.add(os.path.relpath(os.path.join(d, n), root))
    return found

print()
print("== files written")
root = {s: os.path.join(work, s) for s in ("before", "after")}
fa, fb = files_under(root["before"]), files_under(root["after"])
for rel in sorted(fa - fb):
    problem(f"{rel}: written only by before")
for rel in sorted(fb - fa):
    problem(f"{rel}: written only by after")
for rel in sorted(fa & fb):
    pa, pb = os.path.join(root["before"], rel), os.path.join(root["after"], rel)
    ext = os.path.splitext(rel)[1].lower()
    if ext == ".json":
        compare_json(rel, read(pa), read(pb), IGNORED_KEYS.get(os.path.basename(rel), frozenset()))
        continue
    kind = "image" if ext in (".png", ".exr") else "file"
    key = "images" if kind == "image" else "other"
    counts[key] += 1
    r = subprocess.run(["cmp", pa, pb], capture_output=True, text=True)
    if r.returncode == 0:
        counts[key + "_same"] += 1
        print(f"  identical  {kind:<6} {rel}")
        continue
    cmp_says = (r.stdout + r.stderr).strip().replace(work + "/", "")
    if ext == ".exr":
        equal, verdict = compare_exr(pa, pb)
        if equal:
            counts["exr_reordered"] += 1
            print(f"  same       image  {rel}  (not byte-identical: {verdict})")
        else:
            problem(f"{rel}: EXR differs: {verdict} ({cmp_says})")
    else:
        problem(f"{rel}: {kind} not byte-identical ({cmp_says})")

if counts["images"] == 0:
    problem("no images were written: nothing rendered (is a Vulkan driver installed?)")
for label in sorted((TEXT_CHANGES | CHANGED_TEXTS) - seen["text_labels"]):
    problem(f"--text-change/--changed-text {label!r}: no text output has this label")
if validation_counts == 0:
    problem("no 'validation messages: N' line seen: was the validation layer on?")

print()
print("== summary")
print(f"  images compared:        {counts['images']}, byte-identical: {counts['images_same']}, "
      f"same EXR chunks in another order: {counts['exr_reordered']}")
print(f"  JSON compared:          {counts['json']} (files and stdout), same: {counts['json_same']}, "
      f"only declared differences: {counts['json_declared']}")
print(f"  text outputs compared:  {counts['text']}, same: {counts['text_same']}, "
      f"only declared differences: {counts['text_declared']}")
print(f"  exit codes compared:    {counts['exit']}, equal: {counts['exit_same']}")
if counts["other"]:
    print(f"  other files compared:   {counts['other']}, byte-identical: {counts['other_same']}")
print(f"  validation count lines: {validation_counts} (all must say 0; no message lines allowed)")
if declared or RTOL:
    def seen_or_not(used):
        return "seen" if used else "NOT SEEN (no such difference; not a problem)"
    print("  declared changes:")
    for name in sorted(ADDED_FIELDS):
        print(f"    --added-field {name}: {seen_or_not(name in seen['added'])}")
    for name in sorted(CHANGED_FIELDS):
        print(f"    --changed-field {name}: {seen_or_not(name in seen['changed'])}")
    for label in sorted(CHANGED_TEXTS):
        print(f"    --changed-text {label!r}: {seen_or_not(label in seen['changed_text'])}")
    if RTOL:
        print(f"    --rtol {RTOL:g}: {seen['rtol']} value(s) equal within it")
    for label in sorted(TEXT_CHANGES):
        verdict = ("DIFFERS BEYOND IT (a problem, see above)" if label in seen["not_extended"]
                   else seen_or_not(label in seen["extended"]))
        print(f"    --text-change {label!r}: {verdict}")
print(f"  outputs in {work}")
if problems:
    print(f"DIFFERENT ({len(problems)} problems)")
    sys.exit(1)
print("SAME")
PY
