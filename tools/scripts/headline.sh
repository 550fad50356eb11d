#!/usr/bin/env bash
# headline.sh — the README's headline table: per built-in scene, the hybrid frame time, the lens
# PSNR and the speed against the reference ray tracer, at the demo's setting.
#
# Usage:  tools/scripts/headline.sh LENSMAP_BINARY WORKDIR [RUNS]
#
# For each built-in scene: `lensmap bake --samples 2,3 --no-judge` (the demo's bake: 640×480
# with 3×3 supersampling, the default options) into WORKDIR/bakes/SCENE unless a bake with those
# samples is already there (the bake's provenance decides, through `render --bake`), then RUNS
# (default 3) runs of `lensmap render --compare` at the demo's novel camera (halfway in angle
# between viewpoint samples 2 and 3, at their mean distance from the look-at point), the scenes
# alternated run by run. Prints one row per scene: the median hybrid frame time, the median
# reference time, their ratio, and the lens PSNR (display sRGB and linear; deterministic, the
# same every run), and writes the runs' JSON under WORKDIR/runs/.
set -euo pipefail
[ $# -ge 2 ] || { echo "usage: $0 LENSMAP_BINARY WORKDIR [RUNS]" >&2; exit 2; }
LENSMAP=$(realpath "$1")
WORK=$2
RUNS=${3:-3}
SCENES=(teapot-room glass-sphere mirror-teapot)
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$WORK/bakes" "$WORK/runs"

# The novel camera of `lensmap::runner::novel_camera`, from the scene file's circle of samples.
novel_camera() {
    python3 - "$ROOT/engine/scenes/$1.toml" <<'PY'
import math, sys, tomllib
scene = tomllib.load(open(sys.argv[1], "rb"))
c = scene["view_space"]["circle"]
look = scene["camera"]["look_at"]
def sample(i):
    a = math.radians(c["start_degrees"] + i * c["step_degrees"])
    x, y, z = c["centre"]
    return [x + c["radius"] * math.sin(a), y + c["height"], z + c["radius"] * math.cos(a)]
da = [p - l for p, l in zip(sample(2), look)]
db = [p - l for p, l in zip(sample(3), look)]
na, nb = math.dist(da, [0] * 3), math.dist(db, [0] * 3)
d = [u / na + v / nb for u, v in zip(da, db)]
nd = math.dist(d, [0] * 3)
p = [l + u / nd * 0.5 * (na + nb) for l, u in zip(look, d)]
print(",".join(f"{v:.9g}" for v in p), ",".join(f"{v:.9g}" for v in look))
PY
}

for scene in "${SCENES[@]}"; do
    bake="$WORK/bakes/$scene"
    if ! "$LENSMAP" render --scene "$scene" --bake "$bake" --view 2 --width 8 --height 6 \
        --supersampling 1 --out "$WORK/runs/probe.png" --quiet >/dev/null 2>&1; then
        echo "baking $scene samples 2 and 3 into $bake" >&2
        "$LENSMAP" bake --scene "$scene" --samples 2,3 --no-judge --out "$bake" --quiet
    fi
done

for run in $(seq 1 "$RUNS"); do
    for scene in "${SCENES[@]}"; do
        read -r position look_at < <(novel_camera "$scene")
        "$LENSMAP" render --scene "$scene" --bake "$WORK/bakes/$scene" \
            --camera-position="$position" --look-at="$look_at" --compare --json \
            --out "$WORK/runs/$scene-$run.png" >"$WORK/runs/$scene-$run.json"
    done
done

python3 - "$WORK/runs" "$RUNS" "${SCENES[@]}" <<'PY'
import json, statistics, sys
runs_dir, runs, scenes = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
first = json.load(open(f"{runs_dir}/{scenes[0]}-1.json"))
print(f"device: {first['device']}; {first['width']}×{first['height']} with "
      f"{first['supersampling']}×{first['supersampling']} supersampling, t = {first['t']}, "
      f"{first['variant']}, inferred EMs baked at samples 2 and 3; medians of {runs} runs")
print(f"{'scene':<14} {'hybrid ms':>10} {'reference ms':>13} {'faster':>7} "
      f"{'lens PSNR dB':>13} {'linear dB':>10}")
for scene in scenes:
    rows = [json.load(open(f"{runs_dir}/{scene}-{r}.json")) for r in range(1, runs + 1)]
    hybrid = statistics.median(r["hybrid"]["total_ms"] for r in rows)
    reference = statistics.median(r["reference"]["ms"] for r in rows)
    psnr = {r["lens_psnr_db"] for r in rows}
    linear = {r["lens_psnr_linear_db"] for r in rows}
    assert len(psnr) == 1 and len(linear) == 1, f"{scene}: PSNR differs run to run"
    print(f"{scene:<14} {hybrid:>10.1f} {reference:>13.1f} {reference / hybrid:>6.2f}× "
          f"{psnr.pop():>13.2f} {linear.pop():>10.2f}")
PY
