"""Triangulation, the design calculator and the file functions."""

import numpy as np
import pytest

import stereo_depth as sd


def test_depth_and_points():
    rig = sd.Rig(baseline_mm=80, focal_mm=12, pixel_um=4)  # 3000 px
    assert rig.focal_px == 3000
    disp = np.full((3, 5), 400, np.float32)
    disp[0, 0] = np.nan
    disp[1, 1] = -5
    z = rig.depth(disp)
    assert z.dtype == np.float32 and z.shape == (3, 5)
    assert np.isnan(z[0, 0]) and np.isnan(z[1, 1])
    assert z[2, 2] == pytest.approx(0.6)  # 80 mm * 3000 px / 400 px
    xyz = rig.points(disp)
    assert xyz.dtype == np.float32 and xyz.shape == (13, 3)
    # The centre pixel (2, 1) of a 5x3 image is on the optical axis; x right, y down.
    centre = xyz[np.argmin(np.abs(xyz[:, 0]) + np.abs(xyz[:, 1]))]
    assert centre == pytest.approx([0, 0, 0.6])
    colours = np.arange(3 * 5 * 3, dtype=np.uint8).reshape(3, 5, 3)
    xyz2, rgb = rig.points(disp, colors=colours)
    assert np.array_equal(xyz, xyz2) and rgb.shape == (13, 3) and rgb.dtype == np.uint8
    assert list(rgb[0]) == list(colours[0, 1])  # (0, 0) is invalid: the first point is (0, 1)
    assert rig.points(disp, step=2).shape[0] == 5
    # Depth limits, as --min-depth / --max-depth.
    disp[2, 4] = 800  # 0.3 m
    assert np.isnan(rig.depth(disp, min_depth=0.5)[2, 4]) and not np.isnan(rig.depth(disp)[2, 4])
    assert rig.depth_at(400) == pytest.approx(0.6)
    assert rig.disparity_at(0.6) == pytest.approx(400)
    assert sd.Rig(80, focal_px=3000, doffs=100).depth_at(300) == pytest.approx(0.6)


def test_from_calib(tmp_path):
    calib = tmp_path / "calib.txt"
    calib.write_text(
        "cam0=[3997.684 0 1176.728; 0 3997.684 1011.728; 0 0 1]\n"
        "cam1=[3997.684 0 1307.839; 0 3997.684 1011.728; 0 0 1]\n"
        "doffs=131.111\nbaseline=193.001\nwidth=2964\nheight=1988\nndisp=280\n"
    )
    rig = sd.Rig.from_calib(calib)
    assert rig.baseline_mm == pytest.approx(193.001) and rig.focal_px == pytest.approx(3997.684)
    assert rig.doffs == pytest.approx(131.111) and rig.principal_point == pytest.approx((1176.728, 1011.728))
    assert rig.calib_size == (2964, 1988) and rig.ndisp == 280
    assert sd.Rig.from_calib(str(calib), baseline_mm=100).baseline_mm == 100


def test_calc():
    out = sd.calc(baseline_mm=200, focal_mm=6, pixel_um=2.5, disparity_px=150)
    assert out["distance_m"] == pytest.approx(3.2)
    assert out["focal_px"] == pytest.approx(2400)
    assert out["disparity_mm"] == pytest.approx(0.375)
    assert "working_range" in out and "depth_resolution_mm" in out
    at = sd.calc(baseline_mm=80, focal_mm=12, pixel_um=4, distance_m=0.6, width_px=1600, table=True)
    assert at["disparity_px"] == pytest.approx(400)
    assert at["horizontal_fov_deg"] > 0 and len(at["table"]) > 3


def test_pfm_exr_ply_roundtrip(tmp_path):
    disp = np.arange(12, dtype=np.float32).reshape(3, 4)
    disp[1, 2] = np.nan
    sd.write_pfm(tmp_path / "d.pfm", disp)
    assert np.array_equal(sd.read_pfm(tmp_path / "d.pfm"), disp, equal_nan=True)
    # A non-contiguous view is written as what it shows.
    sd.write_pfm(tmp_path / "t.pfm", disp.T)
    assert np.array_equal(sd.read_pfm(tmp_path / "t.pfm"), disp.T, equal_nan=True)
    sd.write_exr(tmp_path / "z.exr", disp, channels={"confidence": np.ones((3, 4), np.float32)})
    assert (tmp_path / "z.exr").read_bytes()[:4] == b"\x76\x2f\x31\x01"
    with pytest.raises(ValueError):
        sd.write_exr(tmp_path / "y.exr", disp, channels={"c": np.ones((2, 2), np.float32)})
    pts = np.array([[0, 0, 1], [1, 2, 3]], np.float32)
    sd.write_ply(tmp_path / "p.ply", pts, np.array([[255, 0, 0], [0, 255, 0]], np.uint8))
    data = (tmp_path / "p.ply").read_bytes()
    assert data.startswith(b"ply\n") and b"element vertex 2" in data
    body = data[data.index(b"end_header\n") + 11:]
    assert len(body) == 2 * 15
    assert np.frombuffer(body[15:27], "<f4").tolist() == [1, 2, 3]


def test_read_image_modes():
    from conftest import DATA
    grey = sd.read_image(DATA / "slanted" / "left.png")
    rgb = sd.read_image(DATA / "slanted" / "left.png", mode="rgb")
    assert grey.dtype == np.uint16 and rgb.dtype == np.uint8 and rgb.shape == grey.shape + (3,)
    assert np.array_equal(grey, rgb[..., 0].astype(np.uint16) * 257)
    with pytest.raises(ValueError):
        sd.read_image(DATA / "slanted" / "left.png", mode="hsv")
