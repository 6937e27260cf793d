"""The same options give the same disparity as the command line, bit for bit."""

import numpy as np
import pytest

import stereo_depth as sd
from conftest import DATA, SHARED, run_cli, scene, write_png

# (Python keywords, the same options as command line flags)
OPTIONS = [
    (dict(max_disparity=64), ["--max-disparity", "64"]),
    (dict(max_disparity=64, fill=True), ["--max-disparity", "64", "--fill"]),
    (dict(max_disparity=64, preset="fast"), ["--max-disparity", "64", "--preset", "fast"]),
    (dict(max_disparity=64, preset="accurate", p1=12, uniqueness=5),
     ["--max-disparity", "64", "--preset", "accurate", "--p1", "12", "--uniqueness", "5"]),
    (dict(min_disparity=-16, max_disparity=48, subpixel="parabola", lr_check=False),
     ["--min-disparity", "-16", "--max-disparity", "48", "--subpixel", "parabola", "--no-lr-check"]),
    (dict(max_disparity=64, min_confidence=0.3), ["--max-disparity", "64", "--min-confidence", "0.3"]),
    (dict(matcher="bm", max_disparity=64), ["--matcher", "bm", "--max-disparity", "64"]),
    (dict(matcher="bm", max_disparity=64, block_size=7, bm_cost="sad"),
     ["--matcher", "bm", "--max-disparity", "64", "--block-size", "7", "--bm-cost", "sad"]),
    (dict(max_disparity=64, single_pass=True, speckle_size=100, edge_snap=0),
     ["--max-disparity", "64", "--single-pass", "--speckle-size", "100", "--edge-snap", "0"]),
    (dict(max_disparity=64, align=False, paths=4, p2=120, lr_max_diff=2, fill=True),
     ["--max-disparity", "64", "--no-align", "--paths", "4", "--p2", "120", "--lr-max-diff", "2", "--fill"]),
    (dict(max_disparity=64, max_memory="8M"), ["--max-disparity", "64", "--max-memory", "8M"]),
    (dict(max_disparity=64, search="hierarchical"), ["--max-disparity", "64", "--search", "hierarchical"]),
    (dict(max_disparity=64, preset="fast", search="hierarchical"),
     ["--max-disparity", "64", "--preset", "fast", "--search", "hierarchical"]),
    (dict(), []),
]


def identical(a, b):
    assert a.shape == b.shape and a.dtype == b.dtype == np.float32
    # NaN where invalid on both sides, and every other value the same float32 bits.
    assert np.array_equal(np.isnan(a), np.isnan(b))
    valid = ~np.isnan(a)
    assert np.array_equal(a[valid].view(np.uint32), b[valid].view(np.uint32))


def cli_disparity(cli, tmp_path, left, right, flags):
    out = tmp_path / "cli.pfm"
    run_cli(cli, left, right, "--disparity", out, "--quiet", *flags)
    return sd.read_pfm(out)


@pytest.mark.parametrize("kwargs,flags", OPTIONS, ids=[" ".join(f) or "defaults" for _, f in OPTIONS])
def test_slanted_matches_cli(cli, tmp_path, kwargs, flags):
    left, right = DATA / "slanted" / "left.png", DATA / "slanted" / "right.png"
    expected = cli_disparity(cli, tmp_path, left, right, flags)
    m = sd.Matcher(**kwargs)
    # From the arrays the library decodes (uint16 working grey), and from the paths.
    identical(m.compute(sd.read_image(left), sd.read_image(right)), expected)
    identical(m.compute(str(left), right), expected)


@pytest.mark.parametrize("colour", [False, True], ids=["grey", "rgb"])
@pytest.mark.parametrize("kwargs,flags", OPTIONS[:3] + OPTIONS[6:7] + OPTIONS[9:10], ids=["sgm", "fill", "fast", "bm", "single-pass"])
def test_generated_scene_matches_cli(cli, tmp_path, colour, kwargs, flags):
    left, right = scene(colour=colour)
    write_png(tmp_path / "l.png", left)
    write_png(tmp_path / "r.png", right)
    expected = cli_disparity(cli, tmp_path, tmp_path / "l.png", tmp_path / "r.png", flags)
    got = sd.Matcher(**kwargs).compute(left, right)  # uint8 numpy arrays, as decoded by any library
    identical(got, expected)
    # Something was matched: the background plane at 12 px.
    assert abs(np.nanmedian(got) - 12) < 1


def test_generated_16_bit_scene_matches_cli(cli, tmp_path):
    left, right = scene(depth16=True)
    write_png(tmp_path / "l.png", left)
    write_png(tmp_path / "r.png", right)
    expected = cli_disparity(cli, tmp_path, tmp_path / "l.png", tmp_path / "r.png", ["--max-disparity", "48"])
    identical(sd.Matcher(max_disparity=48).compute(left, right), expected)


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/data not present")
@pytest.mark.parametrize("name", ["teddy", "tsukuba"])
def test_shared_data_matches_cli(cli, tmp_path, name):
    left, right = SHARED / name / "left.png", SHARED / name / "right.png"
    expected = cli_disparity(cli, tmp_path, left, right, ["--max-disparity", "64"])
    rgb_l, rgb_r = sd.read_image(left, mode="rgb"), sd.read_image(right, mode="rgb")
    identical(sd.Matcher(max_disparity=64).compute(rgb_l, rgb_r), expected)
