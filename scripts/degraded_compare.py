#!/usr/bin/env python3
"""Helpers of degraded-compare.sh (standard library only).

  best-opencv COLOUR.json GREY.json   -> "BAD2<TAB>MODE": the lowest bad2 (holes counted) of the
                                         StereoSGBM modes in two `stereo_eval.py opencv --json`
                                         files, MODE like "HH (grey)"
  bad2 EVAL.json                      -> bad2 of a `stereo-depth eval --json` report
  table RESULTS.tsv                   -> the markdown table of the TSV the script writes
"""
import csv
import json
import sys

SGBM_MODES = ("SGBM", "HH", "SGBM_3WAY", "HH4")
# Where ours is flagged: default mode above this share of OpenCV's best bad2, or --fill above.
DEFAULT_LIMIT = 0.75
FILL_LIMIT = 0.45


def best_opencv(colour_path, grey_path):
    best = None
    for path, label in ((colour_path, "colour"), (grey_path, "grey")):
        with open(path) as f:
            doc = json.load(f)
        for r in doc["results"]:
            # Matcher names carry prefixes and suffixes ("SGBM-HH-grey"); the mode is in the
            # parameters, and StereoBM has none.
            mode = r.get("params", {}).get("mode")
            if mode not in SGBM_MODES:
                continue
            bad2 = r["metrics"]["bad2"]
            if best is None or bad2 < best[0]:
                best = (bad2, f"{mode} {label}")
    if best is None:
        sys.exit(f"no StereoSGBM result in {colour_path} or {grey_path}")
    print(f"{best[0]:.4f}\t{best[1]}")


def bad2(path):
    with open(path) as f:
        print(f"{json.load(f)['metrics']['bad2']:.4f}")


def ratio(ours, ref):
    return ours / ref if ref > 0 else float("inf")


def table(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f, delimiter="\t"))
    print(f"bad2 in % of GT pixels (holes count as bad). ! marks default > {DEFAULT_LIMIT}x or "
          f"--fill > {FILL_LIMIT}x OpenCV's best StereoSGBM mode (colour or grey).\n")
    print("| scene | degradation | ours default | ours --fill | OpenCV best (mode) | default/OpenCV | fill/OpenCV |")
    print("|---|---|---:|---:|---|---:|---:|")
    flagged = 0
    for r in rows:
        d, fl, cv = float(r["ours_default_bad2"]), float(r["ours_fill_bad2"]), float(r["opencv_bad2"])
        rd, rf = ratio(d, cv), ratio(fl, cv)
        md = " !" if rd > DEFAULT_LIMIT else ""
        mf = " !" if rf > FILL_LIMIT else ""
        flagged += bool(md or mf)
        print(f"| {r['scene']} | {r['degradation']} | {d:.2f} | {fl:.2f} | {cv:.2f} ({r['opencv_mode']}) "
              f"| {rd:.2f}{md} | {rf:.2f}{mf} |")
    print(f"\n{flagged} of {len(rows)} rows flagged.")


def main(argv):
    if len(argv) == 3 and argv[0] == "best-opencv":
        best_opencv(argv[1], argv[2])
    elif len(argv) == 2 and argv[0] == "bad2":
        bad2(argv[1])
    elif len(argv) == 2 and argv[0] == "table":
        table(argv[1])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv[1:])
