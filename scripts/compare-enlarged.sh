#!/usr/bin/env bash
# Our SGM modes beside OpenCV on the Middlebury scenes at 1x, 2x and 4x and on a 1920x1080 pair
# with 256 disparities (issues 3 and 17): makes the pairs in $OUT with scripts/enlarge.py, runs
# OpenCV through the shared tool's `stereo_eval.py opencv` (colour modes for accuracy, grey
# SGBM_3WAY, its fastest configuration, for speed), our CLI per mode, scores ours with
# `stereo_eval.py score`, and prints one table: match ms (median of RUNS, timings_ms.match of the
# stats JSON), bad2, OpenCV's grey SGBM_3WAY ms over ours ("speed", >1 = we are faster) and our
# bad2 over the best OpenCV mode's ("bad2 ratio"), all from the same run.
# Two timings of ours: "cold", the CLI's match time (each run a fresh process: the first touch
# of every buffer and cold caches included), and "warm", timed as the shared tool times OpenCV
# (one warm-up call, then the median of RUNS calls in one process: examples/time_pipeline.rs,
# the same matcher parameters; modes other than --preset/--fill get no warm time).
# Not run in CI (needs the Python venv with numpy + opencv, takes many minutes).
#
# Usage: scripts/compare-enlarged.sh [RUNS=3] [THREADS=2]
# Env: PY (python with numpy/cv2, default /tmp/peer-venv/bin/python), OUT (default /tmp/enlarged),
#      FACTORS (default 1,2,4), SCENES (comma list of generated names, e.g. conesx4,cones-1080p),
#      MODES (our CLI arg sets separated by ';', default "--preset balanced;--preset fast"),
#      OPENCV (colour modes, default SGBM_3WAY,HH,SGBM), NO_BUILD=1, NO_ENLARGE=1.
#      NO_BUILD=1 expects target/release/examples/time_pipeline to exist.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
RUNS="${1:-3}"; THREADS="${2:-2}"
PY="${PY:-/tmp/peer-venv/bin/python}"
OUT="${OUT:-/tmp/enlarged}"
TOOL_DIR="${TOOL_DIR:-$ROOT/../shared/tools/opencv-compare}"
EVAL="$TOOL_DIR/stereo_eval.py"
MODES="${MODES:---preset balanced;--preset fast}"
OPENCV="${OPENCV:-SGBM_3WAY,HH,SGBM}"
cd "$ROOT"
[ -n "${NO_BUILD:-}" ] || cargo build --release --bin stereo-depth --example time_pipeline >&2
BIN="$ROOT/target/release/stereo-depth"
WARM_BIN="$ROOT/target/release/examples/time_pipeline"
RIG="--baseline 100 --focal 4 --pixel 2"
[ -n "${NO_ENLARGE:-}" ] || "$PY" scripts/enlarge.py --out "$OUT" --factors "${FACTORS:-1,2,4}" >&2
results="$OUT/results.tsv"
: > "$results"
tail -n +2 "$OUT/scenes.tsv" | while IFS=$'\t' read -r name ndisp w h; do
  [ -z "${SCENES:-}" ] || [[ ",$SCENES," == *",$name,"* ]] || continue
  dir="$OUT/$name"
  for colour in colour grey; do
    extra=(); matchers="$OPENCV"
    if [ "$colour" = grey ]; then extra=(--gray); matchers=SGBM_3WAY; fi
    "$PY" "$EVAL" opencv --left "$dir/left.png" --right "$dir/right.png" --gt "$dir/gt.pfm" \
      --ndisp "$ndisp" --runs "$RUNS" --threads "$THREADS" --matchers "$matchers" --name "$name" \
      "${extra[@]}" --json "$dir/opencv-$colour.json" >/dev/null
    "$PY" - "$dir/opencv-$colour.json" "$name" >> "$results" <<'PYEOF'
import json, sys
for r in json.load(open(sys.argv[1]))["results"]:
    print(f"{sys.argv[2]}\topencv {r['matcher']}\t{r['ms_median']:.1f}\t{r.get('metrics', {}).get('bad2', float('nan')):.2f}")
PYEOF
  done
  IFS=';' read -ra mode_list <<< "$MODES"
  for mode in "${mode_list[@]}"; do
    times=()
    for _ in $(seq "$RUNS"); do
      # shellcheck disable=SC2086
      "$BIN" "$dir/left.png" "$dir/right.png" $RIG --threads "$THREADS" --max-disparity "$ndisp" \
        --disparity "$dir/ours.pfm" --stats "$dir/ours.json" -o /tmp/stereo-depth-enlarged.exr --quiet $mode >/dev/null 2>&1
      times+=("$("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1]))["timings_ms"]["match"])' "$dir/ours.json")")
    done
    ms="$(printf '%s\n' "${times[@]}" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')"
    "$PY" "$EVAL" score --est "$dir/ours.pfm" --gt "$dir/gt.pfm" --ms "$ms" --ndisp "$ndisp" \
      --json "$dir/ours-score.json" >/dev/null
    search="$("$PY" -c 'import json,sys; m=json.load(open(sys.argv[1]))["matcher"]; print(m.get("search", "full"))' "$dir/ours.json")"
    warm=nan
    if [[ " $mode " =~ ^(\ +(--preset\ +(fast|balanced|accurate)|--fill))+\ +$ ]]; then
      # shellcheck disable=SC2086
      warm="$("$WARM_BIN" "$dir/left.png" "$dir/right.png" "$ndisp" "$RUNS" --threads "$THREADS" $mode \
        | "$PY" -c 'import json,sys; print(json.load(sys.stdin)["match_ms"])')"
    fi
    "$PY" - "$dir/ours-score.json" "$name" "ours $mode ($search)" "$warm" >> "$results" <<'PYEOF'
import json, sys
r = json.load(open(sys.argv[1]))["result"]
print(f"{sys.argv[2]}\t{sys.argv[3]}\t{r['ms_median']:.1f}\t{r['metrics']['bad2']:.2f}\t{float(sys.argv[4]):.1f}")
PYEOF
  done
done
"$PY" - "$results" <<'PYEOF'
import sys
rows = [l.rstrip("\n").split("\t") for l in open(sys.argv[1]) if l.strip()]
print(f"{'scene':<14} {'matcher':<44} {'cold ms':>8} {'speed':>6} {'warm ms':>8} {'speed':>6} {'bad2':>6} {'bad2 ratio':>10}")
for scene in dict.fromkeys(r[0] for r in rows):
    mine = [r for r in rows if r[0] == scene]
    grey = [float(r[2]) for r in mine if r[1] == "opencv SGBM-SGBM_3WAY-grey"]
    best = min((float(r[3]) for r in mine if r[1].startswith("opencv")), default=float("nan"))
    for r in mine:
        matcher, ms, bad2 = r[1], float(r[2]), float(r[3])
        # OpenCV is timed warm (one warm-up, then RUNS calls in one process).
        warm = float(r[4]) if len(r) > 4 else ms
        speed = grey[0] / ms if grey else float("nan")
        warm_speed = grey[0] / warm if grey else float("nan")
        print(f"{scene:<14} {matcher:<44} {ms:8.1f} {speed:6.2f} {warm:8.1f} {warm_speed:6.2f} {bad2:6.2f} {bad2 / best:10.2f}")
PYEOF
