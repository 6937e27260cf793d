#!/usr/bin/env python3
"""Speed against OpenCV's grey SGBM_3WAY in interleaved rounds (issue 17, docs/performance.md).

On a shared VM one run of scripts/compare-enlarged.sh can catch OpenCV and our matcher in
different moods (the shared tool timed tsukuba 1x at 4.2-8.7 ms in four consecutive runs). Here
each round times OpenCV's grey SGBM_3WAY on a pair (the shared tool's `stereo_eval.py opencv`:
one warm-up, then RUNS calls, median) and right after it each of our builds on the same pair
(RUNS one-shot CLI runs, median `timings_ms.match`: "cold"; with --warm, RUNS calls of
examples/time_pipeline.rs in one process: "warm"), and the ratio OpenCV ms / ours is taken per
round. Prints, per pair, preset and build, the median ratio over the rounds and its range.

Usage:
  scripts/speed-rounds.py [--rounds 5] [--runs 3] [--threads 2] [--pairs DIR] [--scenes a,b]
      [--presets balanced,fast] [--warm PATH/time_pipeline] NAME=PATH/stereo-depth [NAME=PATH ...]

DIR holds pairs made by scripts/enlarge.py (default /tmp/enlarged: scenes.tsv, NAME/left.png,
right.png, gt.pfm). Needs the shared tool's Python (PY, default /tmp/peer-venv/bin/python, as
scripts/compare-enlarged.sh). Not run in CI.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EVAL = ROOT.parent / "shared" / "tools" / "opencv-compare" / "stereo_eval.py"


def opencv_ms(py, pair, ndisp, runs, threads, name):
    out = Path("/tmp/speed-rounds-opencv.json")
    subprocess.run(
        [py, str(EVAL), "opencv", "--left", str(pair / "left.png"), "--right", str(pair / "right.png"),
         "--gt", str(pair / "gt.pfm"), "--ndisp", str(ndisp), "--runs", str(runs), "--threads", str(threads),
         "--matchers", "SGBM_3WAY", "--gray", "--name", name, "--json", str(out)],
        capture_output=True, check=True)
    return json.loads(out.read_text())["results"][0]["ms_median"]


def cli_ms(binary, pair, ndisp, runs, threads, preset):
    stats = Path("/tmp/speed-rounds-stats.json")
    times = []
    for _ in range(runs):
        subprocess.run(
            [binary, str(pair / "left.png"), str(pair / "right.png"), "--max-disparity", str(ndisp),
             "--threads", str(threads), "--preset", preset, "--stats", str(stats),
             "--disparity", "/tmp/speed-rounds.pfm", "--quiet"],
            capture_output=True, check=True)
        times.append(json.loads(stats.read_text())["timings_ms"]["match"])
    return statistics.median(times)


def warm_ms(binary, pair, ndisp, runs, threads, preset):
    out = subprocess.run(
        [binary, str(pair / "left.png"), str(pair / "right.png"), str(ndisp), str(runs),
         "--threads", str(threads), "--preset", preset],
        capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])["match_ms"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--pairs", default="/tmp/enlarged")
    ap.add_argument("--scenes", default="")
    ap.add_argument("--presets", default="balanced,fast")
    ap.add_argument("--warm", help="examples/time_pipeline of the first build, for warm times")
    ap.add_argument("builds", nargs="+", help="NAME=PATH of a stereo-depth binary")
    args = ap.parse_args()
    py = os.environ.get("PY", "/tmp/peer-venv/bin/python")
    pairs = Path(args.pairs)
    rows = [line.split("\t") for line in (pairs / "scenes.tsv").read_text().splitlines()[1:] if line]
    ndisp = {r[0]: int(r[1]) for r in rows}
    scenes = args.scenes.split(",") if args.scenes else list(ndisp)
    builds = [b.split("=", 1) for b in args.builds]
    presets = args.presets.split(",")
    ratios = {}
    for r in range(args.rounds):
        for scene in scenes:
            pair = pairs / scene
            cv = opencv_ms(py, pair, ndisp[scene], args.runs, args.threads, scene)
            ratios.setdefault((scene, "-", "opencv ms"), []).append(cv)
            for preset in presets:
                for name, binary in builds:
                    ms = cli_ms(binary, pair, ndisp[scene], args.runs, args.threads, preset)
                    ratios.setdefault((scene, preset, f"{name} cold"), []).append(cv / ms)
                if args.warm:
                    ms = warm_ms(args.warm, pair, ndisp[scene], args.runs, args.threads, preset)
                    ratios.setdefault((scene, preset, f"{builds[0][0]} warm"), []).append(cv / ms)
        print(f"round {r + 1} of {args.rounds} done", file=sys.stderr, flush=True)
    print("speed = OpenCV grey SGBM_3WAY ms / ours, per round; median (range) over the rounds")
    for (scene, preset, what), values in ratios.items():
        label = "OpenCV ms" if what == "opencv ms" else "speed"
        print(f"{scene:<12} {preset:<9} {what:<14} {label} {statistics.median(values):8.2f}"
              f"  ({min(values):.2f}-{max(values):.2f}, {len(values)} rounds)")


if __name__ == "__main__":
    main()
