#!/usr/bin/env python3
"""A rig streaming frames: `Matcher.compute` per pair with the alignment measured on every pair
(`rectification_check="every"`, the default) and measured once (`"first"`), numbers in
docs/python.md.

Each scene is matched as a stream of the same pair (the grey 16-bit views, as the command line
loads them); rounds alternate the two settings; the median per call of each round, then the
median of the rounds and their ratio.

    python crates/python/bench/stream.py [DATA_DIR] [--presets fast,balanced] [--rounds 5] [--calls 31]
"""

import argparse
import statistics
import time
from pathlib import Path

import stereo_depth as sd

ap = argparse.ArgumentParser()
ap.add_argument("data", nargs="?", default=str(Path(__file__).resolve().parents[3].parent / "shared" / "data"))
ap.add_argument("--presets", default="fast,balanced")
ap.add_argument("--scenes", default="tsukuba,teddy,wood2")
ap.add_argument("--rounds", type=int, default=5)
ap.add_argument("--calls", type=int, default=31)
args = ap.parse_args()

rows = {}
for line in (Path(args.data) / "scenes.tsv").read_text().splitlines()[1:]:
    f = line.split("\t")
    rows[f[0]] = (f[1], f[2], int(f[11]))

print("| scene | preset | every pair (ms per call) | first pair only | ratio |")
print("|---|---|---:|---:|---:|")
for name in args.scenes.split(","):
    left_name, right_name, ndisp = rows[name]
    left = sd.read_image(Path(args.data) / name / left_name)
    right = sd.read_image(Path(args.data) / name / right_name)
    for preset in args.presets.split(","):
        matchers = {check: sd.Matcher(max_disparity=ndisp, preset=preset, rectification_check=check)
                    for check in ("every", "first")}
        for m in matchers.values():
            m.compute(left, right)  # warm up; "first" measures here
        medians = {check: [] for check in matchers}
        for _ in range(args.rounds):
            for check, m in matchers.items():
                times = []
                for _ in range(args.calls):
                    t = time.perf_counter()
                    m.compute(left, right)
                    times.append((time.perf_counter() - t) * 1000)
                medians[check].append(statistics.median(times))
        every, first = (statistics.median(medians[c]) for c in ("every", "first"))
        print(f"| {name} | {preset} | {every:.2f} | {first:.2f} | {first / every:.2f} |", flush=True)
