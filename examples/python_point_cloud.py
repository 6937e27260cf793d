#!/usr/bin/env python3
"""Two PNGs -> a coloured point cloud (PLY), with the stereo_depth Python package.

    pip install ./crates/python
    python examples/python_point_cloud.py                      # data/slanted, an 80 mm / 3000 px rig
    python examples/python_point_cloud.py LEFT.png RIGHT.png --baseline 80 --focal-px 3000 \
        --max-disparity 64 -o cloud.ply
    python examples/python_point_cloud.py im0.png im1.png --calib calib.txt -o cloud.ply

Open the PLY in MeshLab, CloudCompare or Open3D. Each step is a plain numpy array, so any of
them can be replaced (e.g. the images could come from OpenCV: convert BGR to RGB first).
"""

import argparse
from pathlib import Path

import numpy as np

import stereo_depth as sd

DATA = Path(__file__).resolve().parents[1] / "data" / "slanted"

parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
parser.add_argument("left", nargs="?", default=DATA / "left.png", type=Path)
parser.add_argument("right", nargs="?", default=DATA / "right.png", type=Path)
parser.add_argument("--baseline", type=float, default=80.0, help="baseline, mm [80]")
parser.add_argument("--focal-px", type=float, default=3000.0, help="focal length, px [3000]")
parser.add_argument("--calib", type=Path, help="Middlebury calib.txt (instead of --baseline/--focal-px)")
parser.add_argument("--max-disparity", type=int, default=None, help="[the calib's ndisp, else 64]")
parser.add_argument("--fill", action="store_true", help="dense disparity (every hole filled)")
parser.add_argument("--step", type=int, default=1, help="keep every N-th pixel in both directions")
parser.add_argument("-o", "--output", type=Path, default=Path("cloud.ply"))
args = parser.parse_args()

# 1. The images as numpy arrays: the colour one for the points' colours; the matcher takes it
#    as it is (RGB is converted to grey exactly as the command line converts a file).
left = sd.read_image(args.left, mode="rgb")  # uint8 (H, W, 3)
right = sd.read_image(args.right, mode="rgb")
print(f"pair: {left.shape[1]}x{left.shape[0]}")

# 2. The rig.
if args.calib:
    rig = sd.Rig.from_calib(args.calib)
    max_disparity = args.max_disparity or rig.ndisp
else:
    rig = sd.Rig(baseline_mm=args.baseline, focal_px=args.focal_px)
    max_disparity = args.max_disparity or 64
print(rig)

# 3. Disparity (float32, NaN where no trustworthy match), with what the pipeline measured.
matcher = sd.Matcher(max_disparity=max_disparity, fill=args.fill)
result = matcher.compute_detailed(left, right)
disparity = result.disparity
valid = np.isfinite(disparity)
print(f"disparity: {valid.mean():.1%} valid, median {np.nanmedian(disparity):.2f} px, "
      f"matched in {result.timings_ms['match']:.0f} ms")

# 4. Depth (metres) and the 3-D points with the left view's colours.
depth = rig.depth(disparity)
print(f"depth: {np.nanmin(depth):.3f} to {np.nanmax(depth):.3f} m")
points, colours = rig.points(disparity, step=args.step, colors=left)

# 5. The coloured point cloud: binary PLY, x right, y down, z forward, metres.
sd.write_ply(args.output, points, colours)
print(f"points: {len(points)} -> {args.output}")
