#!/usr/bin/env bash
# Our matcher (default and --fill) beside OpenCV's best StereoSGBM mode on degraded versions of
# the Middlebury scenes: each degradation class at its strongest level, made with
# `stereo-depth degrade`. Prints a markdown table and writes a TSV.
#
# Usage: scripts/degraded-compare.sh [DATA_DIR]     (default ../shared/data from the repo root;
#                                                     a folder with scenes.tsv)
# Env:
#   SCENES="cones teddy"            scenes to run (default: every scene of scenes.tsv)
#   DEGRADATIONS="gain0.6 noise6"   classes to run (default: all, see CLASSES below)
#   BIN=path                        stereo-depth binary (default target/release/stereo-depth;
#                                   built with `cargo build --release` unless NO_BUILD=1 or BIN set)
#   OURS_FLAGS="--paths 4"          extra flags for both of our runs
#   CACHE=dir                       OpenCV results cache (default /tmp/degraded-compare-cache)
#   WORK=dir                        degraded pairs, disparities, results.tsv
#                                   (default /tmp/degraded-compare)
#   TSV=path                        results TSV (default $WORK/results.tsv)
#   SEED=N                          noise seed of the degrade command (default 1)
#   TOOL=path                       stereo_eval.py (default ../shared/tools/opencv-compare/)
#
# OpenCV's results are cached per scene, class and the checksums of the degraded images, so a new
# build of ours reuses them, and a change to the degradations recomputes them. OpenCV runs once
# per mode (--runs 1 --warmup 0): only accuracy matters here.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
DATA="${1:-$ROOT/../shared/data}"
CACHE="${CACHE:-/tmp/degraded-compare-cache}"
WORK="${WORK:-/tmp/degraded-compare}"
SEED="${SEED:-1}"
OURS_FLAGS="${OURS_FLAGS:-}"
TOOL="${TOOL:-$ROOT/../shared/tools/opencv-compare/stereo_eval.py}"
HELPER="$ROOT/scripts/degraded_compare.py"

# class -> "VIEW SPEC [VIEW SPEC]" (VIEW: right, left, or both for per-view independent noise/JPEG;
# a one-view spec overrides the same keys of a both-views one). The issue's table is ORDER; the
# classes of EXTRA run when named in DEGRADATIONS.
declare -A CLASSES=(
  [clean]="right none"
  [gain0.6]="right gain=0.6"
  [gain1.6]="right gain=1.6"
  [gamma0.5]="right gamma=0.5"
  [gamma2.0]="right gamma=2"
  [bias+40]="right bias=40"
  [bias-40]="right bias=-40"
  [vignette0.4]="right vignette=0.4"
  [noise6]="both noise=6"
  [jpeg50]="both jpeg=50"
  [blur1.5]="right blur=1.5"
  [vshift1.0]="right vshift=1"
  [vshift0.5]="right vshift=0.5"
  [rotate0.1]="right rotate=0.1"
  # Several at once, as a real rig has them (not in the issue's table; run with DEGRADATIONS=...):
  # the second camera brighter, with its own tone curve and a little misaligned and soft, both
  # vignetted, noisy and JPEG-compressed. Mild: a well-matched rig; strong: a cheap one.
  [camera-mild]="right gain=1.15,gamma=0.9,vignette=0.2,vshift=0.3,blur=0.5 both vignette=0.1,noise=2,jpeg=90"
  [camera-strong]="right gain=1.4,gamma=0.7,vignette=0.4,vshift=0.7,rotate=0.05,blur=1 both vignette=0.2,noise=4,jpeg=70"
  # The left camera the odd one out (the matcher's corrections must not assume it is the right).
  [left-gain1.6]="left gain=1.6"
  [left-gamma2.0]="left gamma=2"
  [left-bias-40]="left bias=-40"
  [left-vignette0.4]="left vignette=0.4"
  [left-blur1.5]="left blur=1.5"
  [left-blur0.75]="left blur=0.75"
  [left-vshift1.0]="left vshift=1"
  # A soft, vignetted left lens (both corrections on the reference view).
  [left-soft]="left vignette=0.4,blur=1.5"
)
EXTRA="camera-mild camera-strong left-gain1.6 left-gamma2.0 left-bias-40 left-vignette0.4 left-blur1.5 left-blur0.75 left-vshift1.0 left-soft"
ORDER="clean gain0.6 gain1.6 gamma0.5 gamma2.0 bias+40 bias-40 vignette0.4 noise6 jpeg50 blur1.5 vshift1.0 vshift0.5 rotate0.1"
DEGRADATIONS="${DEGRADATIONS:-$ORDER}"
for d in $DEGRADATIONS; do
  [ -n "${CLASSES[$d]:-}" ] || { echo "unknown degradation class '$d' (known: $ORDER $EXTRA)" >&2; exit 2; }
done

[ -f "$DATA/scenes.tsv" ] || { echo "no scenes.tsv in $DATA" >&2; exit 2; }
[ -f "$TOOL" ] || { echo "stereo_eval.py not found at $TOOL (set TOOL=...)" >&2; exit 2; }
if [ -z "${BIN:-}" ]; then
  BIN="$ROOT/target/release/stereo-depth"
  [ -n "${NO_BUILD:-}" ] || (cd "$ROOT" && cargo build --release --bin stereo-depth >&2)
fi
[ -x "$BIN" ] || { echo "binary not found: $BIN" >&2; exit 2; }
PY="$(bash "$(dirname "$TOOL")/setup.sh" 2>/dev/null | tail -1)"
[ -x "$PY" ] || { echo "cannot set up the OpenCV venv (setup.sh)" >&2; exit 1; }

ALL_SCENES="$(awk -F'\t' 'NR > 1 { print $1 }' "$DATA/scenes.tsv")"
SCENES="${SCENES:-$ALL_SCENES}"
mkdir -p "$CACHE" "$WORK"
TSV="${TSV:-$WORK/results.tsv}"
printf 'scene\tdegradation\tspec\tours_default_bad2\tours_fill_bad2\topencv_bad2\topencv_mode\n' >"$TSV"
echo "ours: $BIN LEFT RIGHT --max-disparity NDISP $OURS_FLAGS [--fill]; work in $WORK, cache in $CACHE" >&2

for scene in $SCENES; do
  row="$(awk -F'\t' -v s="$scene" '$1 == s' "$DATA/scenes.tsv")"
  [ -n "$row" ] || { echo "scene '$scene' is not in $DATA/scenes.tsv" >&2; exit 2; }
  IFS=$'\t' read -r _ left right gt _ gt_scale _ _ _ _ _ ndisp <<<"$row"
  src="$DATA/$scene"
  for class in $DEGRADATIONS; do
    read -r -a words <<<"${CLASSES[$class]}"
    degrade=(); spec_text=""
    for ((i = 0; i < ${#words[@]}; i += 2)); do
      degrade+=("--${words[i]}" "${words[i + 1]}")
      spec_text="${spec_text:+$spec_text }${words[i]}:${words[i + 1]}"
    done
    dir="$WORK/$scene/$class"
    mkdir -p "$dir"
    if [ "$class" = clean ]; then
      L="$src/$left"; R="$src/$right"
    else
      "$BIN" degrade "$src/$left" "$src/$right" --out "$dir" "${degrade[@]}" --seed "$SEED" --quiet
      L="$dir/left.png"; R="$dir/right.png"
    fi

    # OpenCV: cached on the exact input bytes.
    key="$(cat "$L" "$R" | sha256sum | cut -c1-16)"
    cached="$CACHE/$scene.$class.$key"
    if [ ! -f "$cached.colour.json" ] || [ ! -f "$cached.grey.json" ]; then
      echo "  $scene $class: OpenCV (colour and grey) ..." >&2
      for mode in colour grey; do
        gray=(); [ "$mode" = grey ] && gray=(--gray)
        "$PY" "$TOOL" opencv --left "$L" --right "$R" --gt "$src/$gt" --gt-scale "$gt_scale" \
          --ndisp "$ndisp" --matchers SGBM,HH,SGBM_3WAY,HH4 --runs 1 --warmup 0 "${gray[@]}" \
          --name "$scene-$class" --json "$cached.$mode.json.tmp" >/dev/null 2>"$dir/opencv-$mode.log"
        mv "$cached.$mode.json.tmp" "$cached.$mode.json"
      done
    fi
    IFS=$'\t' read -r cv_bad2 cv_mode < <(python3 "$HELPER" best-opencv "$cached.colour.json" "$cached.grey.json")

    # Ours, default and --fill; scored by our own eval (the same metrics as stereo_eval.py score).
    scores=()
    for variant in default fill; do
      fill=(); [ "$variant" = fill ] && fill=(--fill)
      # shellcheck disable=SC2086 # OURS_FLAGS is a list of flags
      "$BIN" "$L" "$R" --max-disparity "$ndisp" --disparity "$dir/ours-$variant.pfm" --quiet \
        "${fill[@]}" $OURS_FLAGS >/dev/null
      "$BIN" eval "$dir/ours-$variant.pfm" "$src/$gt" --gt-scale "$gt_scale" --json >"$dir/eval-$variant.json"
      scores+=("$(python3 "$HELPER" bad2 "$dir/eval-$variant.json")")
    done
    printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$scene" "$class" "$spec_text" "${scores[0]}" "${scores[1]}" \
      "$cv_bad2" "$cv_mode" >>"$TSV"
    echo "  $scene $class: ours ${scores[0]} / fill ${scores[1]} / OpenCV $cv_bad2 ($cv_mode)" >&2
  done
done

python3 "$HELPER" table "$TSV"
echo "TSV: $TSV" >&2
