"""A large synthetic rectified pair for memory and speed checks (not run in CI).

Blurred random texture; the right view samples the left at x + d(x) with d rising linearly from
40 to 300 px across the image, so the left pixel x' = x + d(x) has disparity d(x) (the truth is
recomputed from the same formula when scoring).

Usage: /tmp/peer-venv/bin/python scripts/make-big-pair.py [OUT_DIR=/tmp] [WIDTH=6000] [HEIGHT=4000]
then:  target/release/stereo-depth OUT/big_left.png OUT/big_right.png --max-disparity 320 \\
           --max-memory 4G --disparity big.pfm --stats big.json
"""
import sys

import cv2
import numpy as np

out = sys.argv[1] if len(sys.argv) > 1 else "/tmp"
W = int(sys.argv[2]) if len(sys.argv) > 2 else 6000
H = int(sys.argv[3]) if len(sys.argv) > 3 else 4000
rng = np.random.default_rng(7)
base = rng.integers(0, 256, (H, W + 400), dtype=np.uint8).astype(np.float32)
base = cv2.GaussianBlur(base, (0, 0), 1.2)
base = cv2.normalize(base, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
x = np.arange(W, dtype=np.float32)
mapx = np.tile(x + 40 + 260 * x / W, (H, 1)).astype(np.float32)
mapy = np.tile(np.arange(H, dtype=np.float32)[:, None], (1, W))
cv2.imwrite(f"{out}/big_left.png", base[:, :W])
cv2.imwrite(f"{out}/big_right.png", cv2.remap(base, mapx, mapy, cv2.INTER_LINEAR))
