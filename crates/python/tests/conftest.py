"""Shared helpers: the repository's data, the command line binary, generated scenes, PNG writing."""

import os
import struct
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[3]
DATA = REPO / "data"
SHARED = REPO.parent / "shared" / "data"


def cli_path():
    """The stereo-depth binary: $STEREO_DEPTH_CLI, else target/{release,debug} of the workspace."""
    given = os.environ.get("STEREO_DEPTH_CLI")
    if given:
        return Path(given)
    targets = [Path(os.environ["CARGO_TARGET_DIR"])] if os.environ.get("CARGO_TARGET_DIR") else []
    targets.append(REPO / "target")
    for target in targets:
        for profile in ("release", "debug"):
            p = target / profile / "stereo-depth"
            if p.exists():
                return p
    return None


@pytest.fixture(scope="session")
def cli():
    path = cli_path()
    if path is None or not path.exists():
        if os.environ.get("STEREO_DEPTH_REQUIRE_CLI"):
            pytest.fail("STEREO_DEPTH_REQUIRE_CLI is set but no stereo-depth binary was found")
        pytest.skip("no stereo-depth binary (set STEREO_DEPTH_CLI)")
    return path


def run_cli(cli, *args):
    done = subprocess.run([str(cli), *map(str, args)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return done


def write_png(path, image):
    """A minimal PNG writer (8/16-bit grey or RGB), so the tests need no imaging library."""
    image = np.ascontiguousarray(image)
    h, w = image.shape[:2]
    colour = {2: 0, 3: 2}[image.ndim]
    depth = 8 if image.dtype == np.uint8 else 16
    rows = image.astype(">u2") if depth == 16 else image
    raw = b"".join(b"\x00" + rows[y].tobytes() for y in range(h))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, 0)
    Path(path).write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    )


def scene(width=320, height=240, disparity=12.0, seed=1, colour=False, depth16=False):
    """A generated rectified pair: a textured background plane at `disparity` px and a nearer
    square at twice that. Returns (left, right) uint8 (or uint16) arrays, (H, W) or (H, W, 3)."""
    rng = np.random.default_rng(seed)
    # A smooth random texture: noise blurred by box filters, wide enough for the shifts.
    pad = int(4 * disparity) + 8
    noise = rng.random((height, width + pad, 3 if colour else 1))
    for axis in (0, 1):
        noise = (noise + np.roll(noise, 1, axis) + np.roll(noise, -1, axis)) / 3
    texture = (noise - noise.min()) / (noise.max() - noise.min())
    xs = np.arange(width)
    d = np.full((height, width), disparity)
    y0, y1, x0, x1 = height // 4, 3 * height // 4, width // 3, 2 * width // 3
    d[y0:y1, x0:x1] = 2 * disparity
    left = texture[:, : width]
    # right(x) = left(x + d): sample the texture at x + d (linear interpolation along rows).
    right = np.empty_like(left)
    for y in range(height):
        src = xs + d[y]
        for c in range(texture.shape[2]):
            right[y, :, c] = np.interp(src, np.arange(texture.shape[1]), texture[y, :, c])
    scale = 65535 if depth16 else 255
    dtype = np.uint16 if depth16 else np.uint8
    left, right = [np.round(v * scale).astype(dtype) for v in (left, right)]
    if not colour:
        left, right = left[..., 0], right[..., 0]
    return np.ascontiguousarray(left), np.ascontiguousarray(right)
