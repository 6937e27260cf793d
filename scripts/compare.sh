#!/usr/bin/env bash
# Our matchers beside OpenCV (StereoBM and the four StereoSGBM modes) on the Middlebury scenes of
# ../shared/data, in one run on one machine, using the shared opencv-compare tool (not a copy).
# Not run in CI: it needs the Python venv the tool sets up and takes minutes.
#
# Usage: scripts/compare.sh [RUNS=5] [THREADS=2] [-- EXTRA stereo-depth ARGS...]
#   e.g. scripts/compare.sh 9 2 -- --paths 4        (SGM 4 paths)
#        scripts/compare.sh 5 2 -- --matcher bm     (block matching)
# Env: OURS_TEMPLATE overrides the whole command template ({left} {right} {ndisp} {out} are
#      substituted by run.sh); RESULTS sets the output folder (default /tmp/opencv-compare);
#      TOOL points at run.sh; NO_BUILD=1 skips `cargo build --release`.
# Our time in the table is the whole process (load, match, write); OpenCV's is compute() alone.
# The stats JSON of the CLI has the match time alone (timings_ms.match) for MDE/s figures.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
RUNS="${1:-5}"; THREADS="${2:-2}"
shift $(( $# >= 2 ? 2 : $# ))
[ "${1:-}" = "--" ] && shift
EXTRA="$*"
TOOL="${TOOL:-$ROOT/../shared/tools/opencv-compare/run.sh}"
[ -f "$TOOL" ] || { echo "opencv-compare tool not found at $TOOL (set TOOL=...)" >&2; exit 1; }
cd "$ROOT"
[ -n "${NO_BUILD:-}" ] || cargo build --release --bin stereo-depth >&2
BIN="$ROOT/target/release/stereo-depth"
# The rig values only scale depth; the disparity map (what is scored) does not depend on them.
RIG="--baseline 100 --focal 4 --pixel 2"
# (Built in two steps: a "}" inside ${VAR:-default} would end the expansion.)
DEFAULT_TEMPLATE="$BIN {left} {right} $RIG --threads $THREADS --max-disparity {ndisp} --disparity {out} -o /tmp/stereo-depth-compare.exr --quiet $EXTRA"
TEMPLATE="${OURS_TEMPLATE:-$DEFAULT_TEMPLATE}"
echo "ours: $TEMPLATE" >&2
exec bash "$TOOL" "$RUNS" "$THREADS" "$TEMPLATE"
