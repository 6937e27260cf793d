"""Arrays of every supported layout and type give the result of the contiguous grey array."""

import threading

import numpy as np
import pytest

import stereo_depth as sd
from conftest import DATA, scene


@pytest.fixture(scope="module")
def pair():
    return scene(width=192, height=128, disparity=8)


@pytest.fixture(scope="module")
def matcher():
    return sd.Matcher(max_disparity=32)


def same(a, b):
    assert np.array_equal(a, b, equal_nan=True)


def test_strided_views_are_read_in_place(pair, matcher):
    left, right = pair
    # Padded rows: a crop of a wider buffer is read in place and equals the cropped copy.
    wide_l = np.zeros((128, 256), np.uint8)
    wide_r = np.zeros((128, 256), np.uint8)
    wide_l[:, 10:202], wide_r[:, 10:202] = left, right
    view_l, view_r = wide_l[:, 10:202], wide_r[:, 10:202]
    assert not view_l.flags.c_contiguous
    res = matcher.compute_detailed(view_l, view_r)
    assert res.copied == (False, False)
    same(res.disparity, matcher.compute(left, right))


@pytest.mark.parametrize("layout", ["fortran", "reversed", "column-strided"])
def test_other_layouts_are_copied(pair, matcher, layout):
    left, right = pair
    if layout == "fortran":
        l, r = np.asfortranarray(left), np.asfortranarray(right)
        expected = matcher.compute(left, right)
    elif layout == "reversed":
        l, r = left[::-1], right[::-1]
        expected = matcher.compute(np.ascontiguousarray(l), np.ascontiguousarray(r))
    else:
        big_l, big_r = np.repeat(left, 2, axis=1), np.repeat(right, 2, axis=1)
        l, r = big_l[:, ::2], big_r[:, ::2]
        expected = matcher.compute(left, right)
    res = matcher.compute_detailed(l, r)
    assert res.copied == (True, True)
    same(res.disparity, expected)


def test_colour_and_16_bit_convert_like_files(pair, matcher):
    left, right = pair
    expected = matcher.compute(left, right)
    # 8-bit values are scaled by 257 to the working 16 bits.
    same(matcher.compute(left.astype(np.uint16) * 257, right.astype(np.uint16) * 257), expected)
    # Equal channels: luma is the grey value; alpha is ignored.
    rgb_l, rgb_r = np.stack([left] * 3, -1), np.stack([right] * 3, -1)
    same(matcher.compute(rgb_l, rgb_r), expected)
    rgba_l = np.concatenate([rgb_l, np.full(left.shape + (1,), 7, np.uint8)], -1)
    rgba_r = np.concatenate([rgb_r, np.full(left.shape + (1,), 200, np.uint8)], -1)
    same(matcher.compute(rgba_l, rgba_r), expected)
    # A view of the RGB channels of an RGBA buffer is read in place.
    res = matcher.compute_detailed(rgba_l[..., :3], rgba_r[..., :3])
    same(res.disparity, expected)
    # Mixed inputs: a grey array on the left, a colour one on the right.
    same(matcher.compute(left, rgb_r), expected)


def test_paths_and_pathlike():
    m = sd.Matcher(max_disparity=64)
    left, right = DATA / "slanted" / "left.png", DATA / "slanted" / "right.png"
    same(m.compute(left, right), m.compute(str(left), str(right)))
    same(m.compute(left, sd.read_image(right)), m.compute(left, right))


def test_compute_detailed(pair):
    left, right = pair
    m = sd.Matcher(max_disparity=32, fill=True, confidence=True)
    res = m.compute_detailed(left, right)
    assert res.disparity.dtype == np.float32 and res.disparity.shape == left.shape
    assert res.confidence.dtype == np.float32 and res.confidence.shape == left.shape
    assert res.filled.dtype == np.bool_ and res.filled.any()
    assert not np.isnan(res.disparity).any()  # dense
    assert (res.confidence[res.filled] == 0).all()
    assert set(res.timings_ms) >= {"convert", "rectification", "match", "total"}
    assert res.range == (0, 32)
    assert res.rectification["verdict"] == "aligned"
    same(res.disparity, m.compute(left, right))
    # Without fill nothing is filled; BM has no confidence.
    assert not sd.Matcher(max_disparity=32).compute_detailed(left, right).filled.any()
    bm = sd.Matcher(matcher="bm", max_disparity=32).compute_detailed(left, right)
    assert bm.confidence is None and bm.adaptation is None and bm.search is None
    # Which search ran: the whole range at 32 disparities, bands with search="hierarchical".
    assert res.search == {
        "search": "full", "levels": 0, "mean_disparities_searched": 32.0, "downscale": 1, "rows_halved": False
    }
    coarse = sd.Matcher(max_disparity=32, search="hierarchical").compute_detailed(left, right).search
    assert coarse["search"] == "hierarchical" and coarse["levels"] == 1
    assert 0 < coarse["mean_disparities_searched"] <= 32
    # A reduced match: the map keeps the pair's size, the report says by how much.
    halved = sd.Matcher(max_disparity=32, downscale=2).compute_detailed(left, right)
    assert halved.disparity.shape == left.shape and halved.search["downscale"] == 2
    assert sd.Matcher(max_disparity=32, downscale="auto").compute_detailed(left, right).search["downscale"] == 1
    # The fast preset halves a sharp pair whose halved range keeps 16 disparities ("coarse");
    # downscale=1 keeps it at full resolution.
    big_left, big_right = scene(width=400, height=300, disparity=12)
    cases = (({"preset": "fast"}, 2), ({"downscale": "coarse"}, 2), ({"preset": "fast", "downscale": 1}, 1))
    for options, factor in cases:
        res = sd.Matcher(max_disparity=32, **options).compute_detailed(big_left, big_right)
        assert res.search["downscale"] == factor and res.disparity.shape == big_left.shape, options
        assert not res.search["rows_halved"]
    # A range too short to halve (16 disparities): the rows alone are halved.
    short = sd.Matcher(max_disparity=16, preset="fast").compute_detailed(big_left, big_right)
    assert (short.search["downscale"], short.search["rows_halved"]) == (1, True)
    assert short.disparity.shape == big_left.shape
    assert np.nanmedian(short.disparity) == pytest.approx(12, abs=0.5)
    for bad in (0, 9, "half", 1.5):
        with pytest.raises(ValueError, match="downscale"):
            sd.Matcher(max_disparity=32, downscale=bad)


def test_default_range_is_a_quarter_of_the_width(pair):
    left, right = pair
    assert sd.Matcher().compute_detailed(left, right).range == (0, 48)  # 192 / 4


def test_threads_option_gives_the_same_result(pair):
    left, right = pair
    same(sd.Matcher(max_disparity=32, threads=1).compute(left, right), sd.Matcher(max_disparity=32).compute(left, right))


def test_a_matcher_is_shared_between_threads(pair, matcher):
    left, right = pair
    expected = matcher.compute(left, right)
    results = [None] * 4

    def work(i):
        results[i] = matcher.compute(left, right)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in results:
        same(r, expected)


def test_help_lists_every_option_with_its_default():
    text = sd.Matcher.__doc__
    for option in ["min_disparity", "max_disparity", "matcher", "preset", "fill", "speckle_size", "edge_snap",
                   "confidence", "min_confidence", "single_pass", "paths", "search", "downscale", "p1", "p2", "uniqueness",
                   "lr_max_diff", "lr_check", "subpixel", "block_size", "bm_cost", "align", "rectification_check", "max_memory",
                   "max_pixels", "threads"]:
        assert f"``{option}`` [" in text, option
    # The defaults the docstring states are the library's.
    p = sd.Matcher().params
    assert (p["p1"], p["p2"], p["paths"], p["uniqueness"], p["lr_max_diff"], p["subpixel"], p["edge_snap"]) == (
        20, 80, 8, 0, 3.0, "equiangular", 5)
    assert "[None: 20]" in text and "[None: 80]" in text
    b = sd.Matcher(matcher="bm").params
    assert (b["block_size"], b["bm_cost"], b["uniqueness"], b["lr_max_diff"], b["subpixel"]) == (
        11, "census", 10, 1.0, "parabola")
    assert sd.Matcher(fill=True).params["speckle_size"] == 400
    assert sd.Matcher(fill=True).params["lr_max_diff"] == 1.0
    assert sd.Matcher().params["lr_left_neighbour"] and not sd.Matcher(fill=True).params["lr_left_neighbour"]
    assert sd.Matcher(preset="fast").params["paths"] == 4
    assert sd.Matcher().params["search"] == "auto"
    assert sd.Matcher(search="hierarchical").params["search"] == "hierarchical"


def test_adaptation_reports_the_tone_correction_and_the_clipping(pair):
    left, right = pair
    m = sd.Matcher(max_disparity=32)
    clean = m.compute_detailed(left, right).adaptation
    assert clean["intensity_term"] and clean["tone_corrected_difference"] is None
    assert not clean["clipped_alike"]
    # A darker right view: its tones are mapped onto the left's and the intensity term is kept.
    darker = np.round(right.astype(np.float32) * 0.6).astype(np.uint8)
    a = m.compute_detailed(left, darker).adaptation
    assert a["radiometric_difference"] > 9 and a["tone_corrected_difference"] <= 3
    assert a["intensity_term"] and not a["clipped_alike"]
    # Shadows clipped to black in the right view only: the left view is clipped alike.
    clipped = np.clip(right.astype(np.int16) - 80, 0, 255).astype(np.uint8)
    a = m.compute_detailed(left, clipped).adaptation
    assert a["clipped_alike"] and not a["intensity_term"]


def test_noisy_pairs_take_an_edge_aware_p2_for_the_default_output(pair):
    left, right = pair
    clean = sd.Matcher(max_disparity=32).compute_detailed(left, right).adaptation
    assert not clean["census_smoothing"] and clean["p2_edge_scale"] == 0 and clean["p2"] == 80
    assert clean["census_tolerance"] == 0
    # Independent sensor noise in both views: census on smoothed views with a one-grey-level
    # tolerance, P2 raised and lowered across image edges, for the default output only.
    rng = np.random.default_rng(3)
    noisy = [np.clip(v.astype(np.float32) + rng.normal(0, 12, v.shape), 0, 255).astype(np.uint8) for v in pair]
    a = sd.Matcher(max_disparity=32).compute_detailed(*noisy).adaptation
    assert a["census_smoothing"] and a["p2_edge_scale"] == 30 and a["census_tolerance"] == 1
    f = sd.Matcher(max_disparity=32, fill=True).compute_detailed(*noisy).adaptation
    assert f["census_smoothing"] and f["p2_edge_scale"] == 0 and f["p2"] >= 80 and a["p2"] == 2 * f["p2"]


def test_a_defocused_view_is_reported(pair):
    left, right = pair
    clean = sd.Matcher(max_disparity=32).compute_detailed(left, right).adaptation
    assert clean["defocused_view"] is None and clean["defocus_sigma"] is None
    # The left view blurred (Gaussian σ 1.5 px, rows then columns): found and measured.
    taps = np.exp(-np.arange(-5, 6) ** 2 / (2 * 1.5**2))
    taps /= taps.sum()
    blur = lambda v, axis: np.apply_along_axis(lambda line: np.convolve(np.pad(line, 5, mode="edge"), taps, "valid"), axis, v)
    soft = [np.round(blur(blur(v.astype(np.float64), 1), 0)).astype(np.uint8) for v in pair]
    a = sd.Matcher(max_disparity=32).compute_detailed(soft[0], right).adaptation
    assert a["defocused_view"] == "left" and abs(a["defocus_sigma"] - 1.5) < 0.4, a
    a = sd.Matcher(max_disparity=32).compute_detailed(left, soft[1]).adaptation
    assert a["defocused_view"] == "right" and abs(a["defocus_sigma"] - 1.5) < 0.4, a


def test_rectification_check_first_reuses_the_streams_alignment():
    left, right = scene(width=256, height=192, disparity=8)
    # The right view one row lower, as a drifted rectification leaves it.
    lowered = np.vstack([right[:1], right[:-1]])
    every = sd.Matcher(max_disparity=32)
    first = sd.Matcher(max_disparity=32, rectification_check="first")
    assert first.params["rectification_check"] == "first" and every.params["rectification_check"] == "every"
    measured = first.compute_detailed(left, lowered)
    assert measured.rectification["measured"] and measured.rectification["compensated"]
    assert abs(measured.rectification["vertical_offset_px"] - 1.0) < 0.15
    reused = first.compute_detailed(left, lowered)
    assert not reused.rectification["measured"] and reused.rectification["compensated"]
    assert reused.rectification["vertical_offset_px"] == measured.rectification["vertical_offset_px"]
    same(reused.disparity, measured.disparity)
    same(reused.disparity, every.compute(left, lowered))
    assert every.compute_detailed(left, lowered).rectification["measured"]
    # Another size is measured afresh.
    assert first.compute_detailed(left[:160], lowered[:160]).rectification["measured"]


def test_rectification_check_first_measures_until_a_verdict():
    left, right = scene(width=256, height=192, disparity=8)
    flat = np.full_like(left, 128)
    m = sd.Matcher(max_disparity=32, rectification_check="first")
    none = m.compute_detailed(flat, flat).rectification
    assert none["measured"] and none["verdict"] == "unknown"
    assert m.compute_detailed(left, right).rectification["measured"]
    assert not m.compute_detailed(left, right).rectification["measured"]
    with pytest.raises(ValueError, match="rectification_check"):
        sd.Matcher(rectification_check="never")
