"""Every bad input raises the right exception type with a one-line message."""

import numpy as np
import pytest

import stereo_depth as sd
from conftest import DATA

L = np.zeros((64, 96), np.uint8)


def one_line(excinfo, *words):
    message = str(excinfo.value)
    assert "\n" not in message and message
    for w in words:
        assert w in message, message


@pytest.mark.parametrize(
    "left,right,words",
    [
        (np.zeros((64, 96, 2), np.uint8), np.zeros((64, 96, 2), np.uint8), ["shape", "(H, W, 3)"]),
        (np.zeros((64,), np.uint8), np.zeros((64,), np.uint8), ["shape"]),
        (np.zeros((64, 96), np.float32), L, ["dtype", "uint8"]),
        (L, np.zeros((64, 96), np.int16), ["right", "dtype"]),
        (L, np.zeros((64, 95), np.uint8), ["96x64", "95x64"]),
        (np.zeros((0, 96), np.uint8), np.zeros((0, 96), np.uint8), ["0"]),
        (np.zeros((64, 96), ">u2"), np.zeros((64, 96), ">u2"), ["dtype"]),
    ],
)
def test_bad_arrays_raise_value_error(left, right, words):
    with pytest.raises(ValueError) as e:
        sd.Matcher(max_disparity=16).compute(left, right)
    one_line(e, *words)


def test_range_wider_than_image():
    with pytest.raises(ValueError) as e:
        sd.Matcher(max_disparity=200).compute(L, L)
    one_line(e, "wider than the image")
    with pytest.raises(ValueError) as e:
        sd.Matcher(min_disparity=40).compute(L, L)  # default max for 96 px is 32
    one_line(e, "empty disparity range")


def test_not_an_array_raises_type_error():
    with pytest.raises(TypeError):
        sd.Matcher().compute([[1, 2]], [[1, 2]])


@pytest.mark.parametrize(
    "kwargs,words",
    [
        (dict(matcher="sgmx"), ["matcher", "sgmx"]),
        (dict(preset="slow"), ["preset"]),
        (dict(matcher="bm", block_size=4), ["block_size", "odd"]),
        (dict(matcher="bm", fill=True), ["fill", "sgm"]),
        (dict(block_size=5), ["block_size", "bm"]),
        (dict(paths=6), ["paths"]),
        (dict(p1=-1), ["p1"]),
        (dict(p2=70000), ["p2"]),
        (dict(min_confidence=1.5), ["min_confidence"]),
        (dict(lr_max_diff=-1), ["lr_max_diff"]),
        (dict(lr_max_diff=1, lr_check=False), ["lr_max_diff"]),
        (dict(min_disparity=10, max_disparity=10), ["empty disparity range"]),
        (dict(subpixel="cubic"), ["subpixel"]),
        (dict(bm_cost="ssd", matcher="bm"), ["bm_cost"]),
        (dict(max_memory="4Q"), ["max_memory"]),
        (dict(max_memory=0), ["max_memory"]),
        (dict(threads=0), ["threads"]),
        (dict(speckle_size=-3), ["speckle_size"]),
    ],
)
def test_bad_options_raise_value_error(kwargs, words):
    with pytest.raises(ValueError) as e:
        sd.Matcher(**kwargs)
    one_line(e, *words)


def test_unknown_keyword_is_a_type_error():
    with pytest.raises(TypeError):
        sd.Matcher(max_disparty=64)


def test_memory_limit_raises_memory_error():
    with pytest.raises(MemoryError) as e:
        sd.Matcher(max_disparity=64, max_memory="1K").compute(DATA / "slanted" / "left.png", DATA / "slanted" / "right.png")
    one_line(e, "bytes")


def test_max_pixels():
    with pytest.raises(ValueError) as e:
        sd.Matcher(max_pixels=1000).compute(L, L)
    one_line(e, "max_pixels")


def test_files(tmp_path):
    with pytest.raises(FileNotFoundError) as e:
        sd.Matcher().compute(tmp_path / "missing.png", tmp_path / "missing.png")
    one_line(e, "missing.png")
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not an image at all")
    with pytest.raises(OSError) as e:
        sd.Matcher().compute(bad, bad)
    one_line(e, "bad.png")
    with pytest.raises(FileNotFoundError):
        sd.read_pfm(tmp_path / "missing.pfm")
    with pytest.raises(OSError):
        sd.read_pfm(bad)
    with pytest.raises(FileNotFoundError):
        sd.read_image(tmp_path / "missing.png")
    with pytest.raises(FileNotFoundError):
        sd.Rig.from_calib(tmp_path / "calib.txt")
    with pytest.raises(OSError):
        sd.write_pfm(tmp_path / "no" / "such" / "folder" / "d.pfm", np.zeros((2, 2), np.float32))


def test_rig_and_calc_errors():
    for kwargs, words in [
        (dict(baseline_mm=-80, focal_mm=12, pixel_um=4), ["baseline", "-80"]),
        (dict(baseline_mm=80, focal_mm=12), ["pixel_um"]),
        (dict(baseline_mm=80), ["focal"]),
        (dict(baseline_mm=80, focal_mm=12, pixel_um=4, focal_px=3000), ["conflicting"]),
        (dict(baseline_mm=80, focal_px=float("nan")), ["focal length"]),
        (dict(baseline_mm=80, focal_px=3000, cx=1), ["cx and cy"]),
    ]:
        with pytest.raises(ValueError) as e:
            sd.Rig(**kwargs)
        one_line(e, *words)
    with pytest.raises(ValueError) as e:
        sd.calc(baseline_mm=200, focal_mm=6, pixel_um=0, disparity_px=150)
    one_line(e, "pixel_um")
    rig = sd.Rig(80, focal_px=3000)
    with pytest.raises(ValueError):
        rig.depth(np.zeros((4, 4), np.int32))
    with pytest.raises(ValueError):
        rig.depth(np.zeros((4, 4, 2), np.float32))
    with pytest.raises(ValueError):
        rig.depth(np.zeros((4, 4), np.float32), min_depth=2, max_depth=1)
    with pytest.raises(ValueError):
        rig.points(np.ones((4, 4), np.float32), colors=np.zeros((3, 4, 3), np.uint8))
