"""The README's figure: a Middlebury scene's left view, stereo-depth's disparity and the ground
truth side by side, disparities on one Turbo scale (0 to ndisp), invalid pixels black.

Usage: /tmp/peer-venv/bin/python scripts/readme-figure.py [SCENE=cones] [DATA=../shared/data] [OUT=docs/cones.jpg]
(runs target/release/stereo-depth with its defaults; build it first).
"""
import os
import subprocess
import sys
import tempfile

import cv2
import numpy as np

scene = sys.argv[1] if len(sys.argv) > 1 else "cones"
data = sys.argv[2] if len(sys.argv) > 2 else "../shared/data"
out = sys.argv[3] if len(sys.argv) > 3 else "docs/cones.jpg"
with open(os.path.join(data, "scenes.tsv")) as f:
    header = f.readline().rstrip("\n").split("\t")
    rows = [dict(zip(header, line.rstrip("\n").split("\t"))) for line in f]
r = next(r for r in rows if r["scene"] == scene)
d = os.path.join(data, scene)
ndisp = int(r["suggested_ndisp"])


def read_pfm(path):
    with open(path, "rb") as f:
        assert f.readline().strip() == b"Pf"
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        a = np.fromfile(f, dtype="<f4" if scale < 0 else ">f4").reshape(h, w)
    return np.flipud(a)


def colour(disparity):
    valid = np.isfinite(disparity)
    scaled = np.clip(np.where(valid, disparity, 0) / ndisp * 255, 0, 255).astype(np.uint8)
    img = cv2.applyColorMap(scaled, cv2.COLORMAP_TURBO)
    img[~valid] = 0
    return img


with tempfile.TemporaryDirectory() as tmp:
    pfm = os.path.join(tmp, "d.pfm")
    subprocess.run(
        ["target/release/stereo-depth", os.path.join(d, r["left"]), os.path.join(d, r["right"]),
         "--max-disparity", str(ndisp), "--disparity", pfm, "--quiet"],
        check=True, stdout=subprocess.DEVNULL)
    ours = read_pfm(pfm)
gt = cv2.imread(os.path.join(d, r["gt_left"]), cv2.IMREAD_UNCHANGED).astype(np.float32)
gt = np.where(gt == float(r["invalid_value"]), np.nan, gt / float(r["gt_scale"]))
left = cv2.imread(os.path.join(d, r["left"]), cv2.IMREAD_COLOR)
cv2.imwrite(out, np.hstack([left, colour(ours), colour(gt)]), [cv2.IMWRITE_JPEG_QUALITY, 88])
