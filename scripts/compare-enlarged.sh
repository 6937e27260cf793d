#!/usr/bin/env bash
# Our SGM modes beside OpenCV on the 2x/4x enlarged Middlebury scenes (issue 3): makes the
# enlarged pairs in $OUT with scripts/enlarge.py, runs OpenCV through the shared tool's
# `stereo_eval.py opencv` and our CLI per mode, scores ours with `stereo_eval.py score`, and
# prints one table of ms (match time, timings_ms.match of the stats JSON), MDE/s and bad2.
# Not run in CI (needs the Python venv with numpy + opencv, takes many minutes).
#
# Usage: scripts/compare-enlarged.sh [RUNS=3] [THREADS=2]
# Env: PY (python with numpy/cv2, default /tmp/peer-venv/bin/python), OUT (default /tmp/enlarged),
#      FACTORS (default 2,4), SCENES (comma list), MODES (our CLI arg sets separated by ';',
#      default "--preset balanced;--preset fast"), OPENCV (default SGBM_3WAY,HH),
#      NO_BUILD=1.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
RUNS="${1:-3}"; THREADS="${2:-2}"
PY="${PY:-/tmp/peer-venv/bin/python}"
OUT="${OUT:-/tmp/enlarged}"
TOOL_DIR="${TOOL_DIR:-$ROOT/../shared/tools/opencv-compare}"
EVAL="$TOOL_DIR/stereo_eval.py"
MODES="${MODES:---preset balanced;--preset fast}"
OPENCV="${OPENCV:-SGBM_3WAY,HH}"
cd "$ROOT"
[ -n "${NO_BUILD:-}" ] || cargo build --release --bin stereo-depth >&2
BIN="$ROOT/target/release/stereo-depth"
RIG="--baseline 100 --focal 4 --pixel 2"
"$PY" scripts/enlarge.py --out "$OUT" --factors "${FACTORS:-2,4}" ${SCENES:+--scenes "$SCENES"}
printf '%-12s %-28s %9s %8s %7s\n' scene matcher match_ms MDE/s bad2
tail -n +2 "$OUT/scenes.tsv" | while IFS=$'\t' read -r name ndisp w h; do
  dir="$OUT/$name"
  "$PY" "$EVAL" opencv --left "$dir/left.png" --right "$dir/right.png" --gt "$dir/gt.pfm" \
    --ndisp "$ndisp" --runs "$RUNS" --threads "$THREADS" --matchers "$OPENCV" --name "$name" \
    --json "$dir/opencv.json" >/dev/null
  "$PY" - "$dir/opencv.json" "$name" <<'PYEOF'
import json, sys
doc = json.load(open(sys.argv[1]))
for r in doc["results"]:
    m = r.get("metrics", {})
    print(f"{sys.argv[2]:<12} {'opencv ' + r['matcher']:<28} {r['ms_median']:9.1f} {r.get('mde_s', 0):8.0f} {m.get('bad2', float('nan')):7.2f}")
PYEOF
  IFS=';' read -ra mode_list <<< "$MODES"
  for mode in "${mode_list[@]}"; do
    times=()
    for _ in $(seq "$RUNS"); do
      # shellcheck disable=SC2086
      "$BIN" "$dir/left.png" "$dir/right.png" $RIG --threads "$THREADS" --max-disparity "$ndisp" \
        --disparity "$dir/ours.pfm" --stats "$dir/ours.json" -o /tmp/stereo-depth-enlarged.exr --quiet $mode >/dev/null
      times+=("$("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1]))["timings_ms"]["match"])' "$dir/ours.json")")
    done
    ms="$(printf '%s\n' "${times[@]}" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')"
    "$PY" "$EVAL" score --est "$dir/ours.pfm" --gt "$dir/gt.pfm" --ms "$ms" --ndisp "$ndisp" \
      --json "$dir/ours-score.json" >/dev/null
    "$PY" - "$dir/ours-score.json" "$name" "ours $mode" <<'PYEOF'
import json, sys
r = json.load(open(sys.argv[1]))["result"]
print(f"{sys.argv[2]:<12} {sys.argv[3]:<28} {r['ms_median']:9.1f} {r['mde_s']:8.0f} {r['metrics']['bad2']:7.2f}")
PYEOF
  done
done
