#!/usr/bin/env python3
"""Enlarged versions of the Middlebury scenes of ../shared/data for speed tests (issue 3).

For each scene and factor k (default 2 and 4): left/right upsampled k times (bicubic) and the
ground truth upsampled (nearest) with its disparities multiplied by k, written as PFM (0 = unknown
stays 0 -> inf in PFM, so the shared stereo_eval.py treats it as invalid). Output goes to
OUT/<scene>x<k>/{left.png,right.png,gt.pfm} plus OUT/scenes.tsv (scene, ndisp = k * suggested).
Plus one camera-sized pair (--hd, default cones): scaled to 1920 px wide and cropped to the
middle 1080 rows, searched over 256 disparities (OUT/cones-1080p). Never written into the
repository.

Usage: /tmp/peer-venv/bin/python scripts/enlarge.py [--data ../shared/data] [--out /tmp/enlarged] [--factors 2,4]
"""
import argparse
import os
import sys

import cv2
import numpy as np


def write_pfm(path, disp):
    disp = np.flipud(disp.astype(np.float32))
    with open(path, "wb") as f:
        f.write(b"Pf\n%d %d\n-1.0\n" % (disp.shape[1], disp.shape[0]))
        f.write(disp.tobytes())


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default=os.path.join(here, "..", "..", "shared", "data"))
    ap.add_argument("--out", default="/tmp/enlarged")
    ap.add_argument("--factors", default="2,4")
    ap.add_argument("--scenes", default=None, help="comma list (default: all)")
    ap.add_argument("--hd", default="cones",
                    help="scene also scaled to 1920 px wide and cropped to 1920x1080 rows, 256 disparities, "
                         "as <scene>-1080p ('' for none)")
    args = ap.parse_args()
    factors = [int(k) for k in args.factors.split(",")]
    os.makedirs(args.out, exist_ok=True)
    rows = []
    with open(os.path.join(args.data, "scenes.tsv")) as f:
        header = f.readline().rstrip("\n").split("\t")
        for line in f:
            r = dict(zip(header, line.rstrip("\n").split("\t")))
            if args.scenes and r["scene"] not in args.scenes.split(","):
                continue
            d = os.path.join(args.data, r["scene"])
            left = cv2.imread(os.path.join(d, r["left"]), cv2.IMREAD_UNCHANGED)
            right = cv2.imread(os.path.join(d, r["right"]), cv2.IMREAD_UNCHANGED)
            gt = cv2.imread(os.path.join(d, r["gt_left"]), cv2.IMREAD_UNCHANGED).astype(np.float32)
            invalid = gt == float(r["invalid_value"])
            gt = gt / float(r["gt_scale"])
            gt[invalid] = np.inf
            for k in factors:
                name = f"{r['scene']}x{k}"
                o = os.path.join(args.out, name)
                os.makedirs(o, exist_ok=True)
                size = (left.shape[1] * k, left.shape[0] * k)
                cv2.imwrite(os.path.join(o, "left.png"), cv2.resize(left, size, interpolation=cv2.INTER_CUBIC))
                cv2.imwrite(os.path.join(o, "right.png"), cv2.resize(right, size, interpolation=cv2.INTER_CUBIC))
                big = cv2.resize(gt, size, interpolation=cv2.INTER_NEAREST) * k
                write_pfm(os.path.join(o, "gt.pfm"), big)
                rows.append((name, int(r["suggested_ndisp"]) * k, size[0], size[1]))
                print(f"{name}: {size[0]}x{size[1]} ndisp {int(r['suggested_ndisp']) * k}", file=sys.stderr)
            if r["scene"] == args.hd:
                # A camera-sized pair: 1920 px wide (disparities scaled alike), the middle 1080 rows.
                f = 1920 / left.shape[1]
                size = (1920, round(left.shape[0] * f))
                if size[1] < 1080:
                    continue
                top = (size[1] - 1080) // 2
                name = f"{r['scene']}-1080p"
                o = os.path.join(args.out, name)
                os.makedirs(o, exist_ok=True)
                for view, img in (("left", left), ("right", right)):
                    big = cv2.resize(img, size, interpolation=cv2.INTER_CUBIC)[top:top + 1080]
                    cv2.imwrite(os.path.join(o, f"{view}.png"), big)
                big = cv2.resize(gt, size, interpolation=cv2.INTER_NEAREST)[top:top + 1080] * f
                write_pfm(os.path.join(o, "gt.pfm"), big)
                rows.append((name, 256, 1920, 1080))
                print(f"{name}: 1920x1080 ndisp 256", file=sys.stderr)
    with open(os.path.join(args.out, "scenes.tsv"), "w") as f:
        f.write("scene\tndisp\twidth\theight\n")
        for row in rows:
            f.write("\t".join(map(str, row)) + "\n")


if __name__ == "__main__":
    main()
