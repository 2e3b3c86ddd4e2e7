"""Tests of ihrcf_env.core.calibration: YCbCr (eq. 2), Table 1, pad segmentation (eqs. 3-7), PCHIP tables,
chessboard intrinsics and the calibration file."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from ihrcf_env.core.calibration import (
    FORMAT_VERSION,
    YCBCR_THRESHOLDS,
    Calibration,
    CalibrationError,
    RangePixelTable,
    SensorTable,
    calibrate_intrinsics,
    chessboard_object_points,
    colour_mask,
    default_calibration_path,
    find_chessboard,
    rgb_to_ycbcr,
    segment_mask,
    segment_pad,
    segment_pads,
)
from ihrcf_env.core.frames import matrix_from_euler
from ihrcf_env.core.rig import PAD_COLOURS, SensorRig, intrinsics_from_fov

# ------------------------------------------------------------------------------------ YCbCr / Table 1


def _px(rgb: tuple[float, float, float]) -> np.ndarray:
    return np.array(rgb, dtype=np.float64).reshape(1, 1, 3)


@pytest.mark.parametrize(
    ("rgb", "expected"),
    [
        ((0.0, 0.0, 0.0), (16.0, 128.0, 128.0)),
        ((1.0, 1.0, 1.0), (235.0, 128.0, 128.0)),
        # rows of eq. (2) by hand: Y = 16 + 65.481, Cb = 128 - 37.797, Cr = 128 + 112
        ((1.0, 0.0, 0.0), (81.481, 90.203, 240.0)),
        ((0.0, 1.0, 0.0), (144.553, 53.797, 34.214)),
        ((0.0, 0.0, 1.0), (40.966, 240.0, 109.786)),
    ],
)
def test_ycbcr_known_colours(rgb, expected):
    np.testing.assert_allclose(rgb_to_ycbcr(_px(rgb))[0, 0], expected, atol=1e-9)


def test_ycbcr_uint8_matches_float_and_range():
    rng = np.random.default_rng(1)
    img = rng.integers(0, 256, size=(17, 23, 3), dtype=np.uint8)
    y8 = rgb_to_ycbcr(img)
    assert y8.dtype == np.float64 and y8.shape == (17, 23, 3)
    np.testing.assert_allclose(y8, rgb_to_ycbcr(img / 255.0), atol=1e-12)
    # a pixel by hand
    r, g, b = img[3, 5] / 255.0
    assert y8[3, 5, 0] == pytest.approx(16 + 65.481 * r + 128.553 * g + 24.966 * b)
    assert y8[3, 5, 1] == pytest.approx(128 - 37.797 * r - 74.203 * g + 112 * b)
    assert y8[3, 5, 2] == pytest.approx(128 + 112 * r - 93.786 * g - 18.214 * b)
    assert 16 <= y8[..., 0].min() and y8[..., 0].max() <= 235
    assert 16 <= y8[..., 1:].min() and y8[..., 1:].max() <= 240


@pytest.mark.parametrize("bad", [np.zeros((4, 4)), np.zeros((4, 4, 4), np.uint8), np.zeros(3)])
def test_ycbcr_bad_shape_names_shape(bad):
    with pytest.raises(ValueError, match=re.escape(str(bad.shape))):
        rgb_to_ycbcr(bad)


def test_ycbcr_rejects_float_0_255_and_int64():
    with pytest.raises(ValueError):
        rgb_to_ycbcr(np.full((2, 2, 3), 200.0))
    with pytest.raises(ValueError, match="dtype"):
        rgb_to_ycbcr(np.zeros((2, 2, 3), dtype=np.int64))


def _boxes(rgb: tuple[float, float, float]) -> set[str]:
    return {c for c in YCBCR_THRESHOLDS if colour_mask(_px(rgb), c)[0, 0]}


def test_table1_values():
    assert YCBCR_THRESHOLDS["blue"] == ((0, 165), (139, 255), (0, 255))
    assert YCBCR_THRESHOLDS["green"] == ((0, 255), (0, 155), (0, 90))
    assert YCBCR_THRESHOLDS["yellow"] == ((103, 255), (0, 95), (0, 255))
    assert YCBCR_THRESHOLDS["red"] == ((0, 160), (0, 255), (167, 255))
    assert tuple(YCBCR_THRESHOLDS) == PAD_COLOURS


DARK = 0.68  # TinyRenderer's darkening of an upward-facing flat colour (FIELD-NOTES)


@pytest.mark.parametrize(
    ("rgb", "expected"),
    [
        ((0.0, 0.0, DARK), {"blue"}),
        ((DARK, DARK, 0.0), {"yellow"}),
        ((DARK, 0.0, 0.0), {"red"}),
        ((0.0, DARK, 0.0), {"green", "yellow"}),  # Y = 103.4 >= 103 and Cb = 77.5 <= 95: also yellow
        ((0.0, 0.8 * DARK, 0.0), {"green"}),  # Y = 85.9 < 103: green only
        ((0.0, 0.5 * DARK, 0.0), set()),  # Cr = 96.1 > 90: in no box
        ((0.5, 0.5, 0.5), set()),  # grey background: no pad
    ],
)
def test_table1_membership_darkened(rgb, expected):
    assert _boxes(rgb) == expected
    # the same holds after uint8 quantisation of a rendered frame
    q = np.round(np.array(rgb) * 255).astype(np.uint8).reshape(1, 1, 3)
    assert {c for c in YCBCR_THRESHOLDS if colour_mask(q, c)[0, 0]} == expected


def test_table1_bounds_inclusive():
    # pure green's Y = 144.553: choose a green level whose darkened Y is exactly 103 (yellow's lower bound)
    g = (103.0 - 16.0) / 128.553
    assert "yellow" in _boxes((0.0, g, 0.0))
    assert "yellow" not in _boxes((0.0, g - 1e-6, 0.0))


def test_unknown_colour():
    with pytest.raises(ValueError, match="purple"):
        colour_mask(np.zeros((2, 2, 3), np.uint8), "purple")


# ------------------------------------------------------------------------------------ segmentation

SHIFT = 8


def _disc(img: np.ndarray, centre: tuple[float, float], r: float, colour) -> None:
    s = 1 << SHIFT
    cv2.circle(img, (round(centre[0] * s), round(centre[1] * s)), round(r * s), colour, -1, cv2.LINE_8, SHIFT)


def _analytic_disc(shape, centre, r) -> np.ndarray:
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    return (xx - centre[0]) ** 2 + (yy - centre[1]) ** 2 <= r * r


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


@pytest.mark.parametrize(("centre", "r"), [((100.37, 80.81), 30.0), ((61.5, 140.25), 25.6)])
def test_segment_subpixel_disc(centre, r):
    img = np.full((200, 240, 3), 128, np.uint8)
    _disc(img, centre, r, (0, 0, 255))  # blue in RGB
    det = segment_pad(img, "blue")
    assert det is not None
    truth = _analytic_disc(img.shape[:2], centre, r)
    assert _iou(det.mask, truth) >= 0.9
    assert np.max(np.abs(det.centroid - centre)) < 0.1
    # eq. (7): the centroid is the mean (u, v) = (column, row) of the mask pixels
    rows, cols = np.nonzero(det.mask)
    np.testing.assert_allclose(det.centroid, [cols.mean(), rows.mean()], atol=1e-9)
    assert det.area_px == det.mask.sum()
    assert det.area_px == pytest.approx(math.pi * r * r, rel=0.05)
    assert segment_pad(img, "red") is None


def test_segment_pixel_centre_convention():
    mask = np.zeros((30, 40), bool)
    mask[10:13, 20:25] = True  # rows 10..12, columns 20..24
    det = segment_mask(mask, min_area_px=1)
    np.testing.assert_allclose(det.centroid, [22.0, 11.0])


def test_convex_hull_closes_hole_and_notch():
    centre, r = (120.3, 90.6), 40.0
    img = np.full((200, 240, 3), 128, np.uint8)
    _disc(img, centre, r, (255, 0, 0))
    _disc(img, (centre[0] + 8, centre[1] - 5), 12.0, (128, 128, 128))  # hole
    cx, cy = centre
    notch = np.array([[cx, cy], [cx + 60, cy - 15], [cx + 60, cy + 15]])
    cv2.fillConvexPoly(img, np.round(notch).astype(np.int32), (128, 128, 128))  # wedge to the right edge
    raw = colour_mask(img, "red")
    det = segment_pad(img, "red")
    truth = _analytic_disc(img.shape[:2], centre, r)
    assert _iou(raw, truth) < 0.85  # the hole and the notch really remove a lot
    assert _iou(det.mask, truth) >= 0.97
    assert not np.any(raw & ~det.mask)  # the hull contains the blob
    assert np.max(np.abs(det.centroid - centre)) < 0.6  # chord of the notch stays cut: small bias
    raw_c = np.array([np.nonzero(raw)[1].mean(), np.nonzero(raw)[0].mean()])
    assert np.linalg.norm(det.centroid - centre) < np.linalg.norm(raw_c - centre) / 3


def test_segment_largest_blob_border_and_min_area():
    img = np.full((120, 160, 3), 128, np.uint8)
    _disc(img, (40.2, 60.7), 15.0, (255, 255, 0))
    _disc(img, (120.0, 60.0), 5.0, (255, 255, 0))  # smaller distractor
    det = segment_pad(img, "yellow")
    assert np.max(np.abs(det.centroid - (40.2, 60.7))) < 0.2
    assert segment_pad(img, "yellow", min_area_px=2000) is None
    cut = np.full((120, 160, 3), 128, np.uint8)
    _disc(cut, (5.0, 60.0), 15.0, (255, 255, 0))  # cut by the left border
    assert segment_pad(cut, "yellow") is None


def test_segment_pads_darkened_pads():
    img = np.full((240, 240, 3), 60, np.uint8)
    rgb = {"blue": (0, 0, 1), "green": (0, 0.8, 0), "yellow": (1, 1, 0), "red": (1, 0, 0)}
    centres = {"blue": (60.3, 60.6), "green": (180.1, 60.2), "yellow": (180.7, 180.4), "red": (60.5, 180.9)}
    for c in PAD_COLOURS:
        _disc(img, centres[c], 28.0, tuple(round(255 * DARK * x) for x in rgb[c]))
    dets = segment_pads(img)
    for c in PAD_COLOURS:
        assert np.max(np.abs(dets[c].centroid - centres[c])) < 0.15, c


# ------------------------------------------------------------------------------------ PCHIP tables


def _u_of_d(d):  # pixel column of a beam offset 0.07 m from the axis, f = 443 px: smooth and monotone
    return 255.5 - 443.4 * 0.07 / np.asarray(d)


def _v_of_d(d):
    return 255.5 + 443.4 * 0.07 / np.asarray(d)


def _samples(n=120, lo=0.3, hi=3.0):
    d = np.linspace(lo, hi, n)
    return d, np.column_stack([_u_of_d(d), _v_of_d(d)])


def test_pchip_accuracy_on_smooth_function():
    d, px = _samples()
    t = SensorTable(d, px, name="ps1")
    q = np.random.default_rng(2).uniform(0.3, 3.0, 500)
    uv, ok = t(q)
    assert ok.all()
    err = np.abs(uv - np.column_stack([_u_of_d(q), _v_of_d(q)]))
    assert err.max() < 0.02
    np.testing.assert_allclose(t(d)[0], px, atol=1e-9)  # interpolates the knots
    assert t.span == (0.3, 3.0)


def test_pchip_is_monotone_no_overshoot():
    d = np.array([0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1])
    u = np.array([10.0, 10.0, 10.0, 50.0, 50.0, 50.0, 50.0])  # step: a cubic spline would overshoot
    t = SensorTable(d, np.column_stack([u, -u]))
    uv, _ = t(np.linspace(0.5, 1.1, 601))
    assert np.all(np.diff(uv[:, 0]) >= -1e-12)
    assert uv[:, 0].min() >= 10 - 1e-12 and uv[:, 0].max() <= 50 + 1e-12


def test_table_unsorted_duplicates_and_nonfinite_samples():
    d, px = _samples(20)
    ref = SensorTable(d, px)
    rng = np.random.default_rng(3)
    dd = np.concatenate([d, d[[4, 9]], d[[4, 9]], [np.nan, 1.0]])
    pp = np.concatenate([px, px[[4, 9]] + 1.0, px[[4, 9]] - 1.0, [[1.0, 2.0], [np.nan, 0.0]]])
    perm = rng.permutation(dd.size)
    t = SensorTable(dd[perm], pp[perm])
    np.testing.assert_array_equal(t.ranges, ref.ranges)
    np.testing.assert_allclose(t.pixels, ref.pixels, atol=1e-12)  # duplicates averaged back to the truth
    q = np.linspace(0.3, 3.0, 57)
    np.testing.assert_allclose(t(q)[0], ref(q)[0], atol=1e-12)


def test_table_out_of_range_clamped_and_flagged():
    d, px = _samples(30, 0.5, 2.0)
    t = SensorTable(d, px)
    q = np.array([0.1, 0.5, 1.3, 2.0, 2.5, np.nan, np.inf, -np.inf])
    uv, ok = t(q)
    assert np.all(np.isfinite(uv))
    np.testing.assert_array_equal(ok, [False, True, True, True, False, False, False, False])
    np.testing.assert_allclose(uv[0], px[0])
    np.testing.assert_allclose(uv[4], px[-1])
    np.testing.assert_allclose(uv[6], px[-1])
    np.testing.assert_allclose(uv[7], px[0])


def test_table_too_few_samples_names_sensor():
    with pytest.raises(ValueError, match="ps3"):
        SensorTable([0.5, 0.6, 0.7], [[0, 0], [1, 1], [2, 2]], name="ps3")
    with pytest.raises(ValueError, match="ps2"):  # 5 samples but only 3 distinct finite ranges
        SensorTable([0.5, 0.5, 0.6, 0.7, np.nan], np.zeros((5, 2)), name="ps2")
    with pytest.raises(ValueError):
        SensorTable([0.5, 0.6, 0.7, 0.8], np.zeros((4, 3)))
    d = np.linspace(0.5, 1.0, 6)
    with pytest.raises(ValueError, match="ps4"):
        pixels = np.zeros((6, 4, 2))
        pixels[:3, 3] = np.nan  # ps4's pad not found in 3 of 6 stages: 3 samples left
        RangePixelTable.from_samples(np.tile(d[:, None], 4), pixels)


def _rig_table() -> RangePixelTable:
    d = np.linspace(0.3, 3.0, 40)
    xy = SensorRig().sensor_xy_cam
    K = intrinsics_from_fov(512, 512, math.radians(60))
    ranges = np.tile(d[:, None], 4)
    u = K[0, 0] * xy[:, 0] / d[:, None] + K[0, 2]
    v = K[1, 1] * xy[:, 1] / d[:, None] + K[1, 2]
    pixels = np.stack([u, v], axis=2)
    return RangePixelTable.from_samples(ranges, pixels)


def test_range_pixel_table_lookup_and_roundtrip():
    tab = _rig_table()
    uv, ok = tab(np.array([1.0, 1.2, 0.1, np.nan]))
    assert uv.shape == (4, 2) and uv.dtype == np.float64 and np.all(np.isfinite(uv))
    np.testing.assert_array_equal(ok, [True, True, False, False])
    K = intrinsics_from_fov(512, 512, math.radians(60))
    xy = SensorRig().sensor_xy_cam
    np.testing.assert_allclose(uv[0], K[0, 0] * xy[0] / 1.0 + K[:2, 2], atol=0.01)  # ps1 top-left
    assert uv[0, 0] < K[0, 2] and uv[0, 1] < K[1, 2]
    np.testing.assert_allclose(tab.spans, [[0.3, 3.0]] * 4)
    back = RangePixelTable.from_dict(json.loads(json.dumps(tab.to_dict())))
    q = np.array([0.7, 1.1, 2.2, 2.9])
    np.testing.assert_array_equal(back(q)[0], tab(q)[0])
    with pytest.raises(ValueError):
        tab(np.ones(3))


def test_scalar_pixel_lookup_is_the_pchip_interpolant():
    # RangePixelTable evaluates each sensor's cubic pieces in plain floats (SensorTable.pixel): the
    # same values as scipy's PCHIP (SensorTable.__call__), the same clamping and flags.
    rng = np.random.default_rng(3)
    r = np.sort(rng.uniform(0.2, 3.0, 40))
    t = SensorTable(r, np.c_[200 + 100 * np.cos(r), 100 + 50 * np.sin(3 * r)])
    d = np.r_[rng.uniform(0.1, 3.2, 500), r, np.nan, np.inf, -np.inf, 0.0]
    uv, ok = t(d)
    scalar = np.array([t.pixel(float(x)) for x in d])
    np.testing.assert_allclose(scalar[:, :2], uv, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(scalar[:, 2].astype(bool), ok)
    tab = _rig_table()
    q = np.array([0.31, 1.7, np.nan, 5.0])
    uv4, ok4 = tab(q)
    for i, table in enumerate(tab.tables):
        ref_uv, ref_ok = table(q[i : i + 1])
        np.testing.assert_allclose(uv4[i], ref_uv[0], rtol=0, atol=1e-9)
        assert ok4[i] == ref_ok[0]


# ------------------------------------------------------------------------------------ chessboard


def _chessboard_views(K, pattern, square, size):
    px = 40  # texture pixels per square
    margin = 40
    nx, ny = pattern[0] + 1, pattern[1] + 1
    tex = np.full((ny * px + 2 * margin, nx * px + 2 * margin), 255, np.uint8)
    for j in range(ny):
        for i in range(nx):
            if (i + j) % 2 == 0:
                tex[margin + j * px : margin + (j + 1) * px, margin + i * px : margin + (i + 1) * px] = 0
    off = margin + px - 0.5  # first inner corner in texture pixel-centre coordinates
    S = np.array([[square / px, 0, -off * square / px], [0, square / px, -off * square / px], [0, 0, 1]])
    poses = [
        (0.2, 0.1, 0.0, (-0.08, -0.1, 0.45)),
        (-0.25, 0.15, 0.3, (-0.05, -0.12, 0.5)),
        (0.1, -0.3, -0.2, (-0.1, -0.08, 0.5)),
        (0.3, 0.3, 0.5, (-0.06, -0.1, 0.55)),
        (-0.2, -0.2, -0.4, (-0.09, -0.09, 0.45)),
        (0.0, 0.35, 0.1, (-0.1, -0.1, 0.5)),
    ]
    obj = chessboard_object_points(pattern, square)
    views = []
    for roll, pitch, yaw, t in poses:
        R = matrix_from_euler(roll, pitch, yaw)
        H = K @ np.column_stack([R[:, 0], R[:, 1], t]) @ S
        img = cv2.warpPerspective(tex, H, size, flags=cv2.INTER_LINEAR, borderValue=128)
        proj = (obj @ R.T + np.array(t)) @ K.T
        views.append((img, proj[:, :2] / proj[:, 2:]))
    return views


def test_chessboard_calibration_recovers_focal():
    K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
    pattern, square, size = (7, 9), 0.025, (640, 480)
    pts = []
    for img, truth in _chessboard_views(K, pattern, square, size):
        c = find_chessboard(img, pattern)
        assert c is not None and c.shape == (63, 2)
        # OpenCV may number the symmetric board from either end
        err = min(np.linalg.norm(c - truth, axis=1).mean(), np.linalg.norm(c[::-1] - truth, axis=1).mean())
        assert err < 0.3
        pts.append(c)
    res = calibrate_intrinsics(pts, pattern, square, size)
    assert res.n_views == 6 and res.K.shape == (3, 3) and res.dist.shape == (5,)
    assert abs(res.K[0, 0] / 600 - 1) < 0.01 and abs(res.K[1, 1] / 600 - 1) < 0.01
    assert abs(res.K[0, 2] - 319.5) < 5 and abs(res.K[1, 2] - 239.5) < 5
    assert res.rms < 0.5
    with pytest.raises(ValueError, match="3"):
        calibrate_intrinsics(pts[:2], pattern, square, size)


def test_find_chessboard_none_on_blank():
    assert find_chessboard(np.full((100, 120), 128, np.uint8)) is None


def test_object_points():
    p = chessboard_object_points((7, 9), 0.025)
    assert p.shape == (63, 3)
    np.testing.assert_allclose(p[1], [0.025, 0, 0])
    np.testing.assert_allclose(p[7], [0, 0.025, 0])


# ------------------------------------------------------------------------------------ calibration file


def _calibration(**kw) -> Calibration:
    args = dict(
        image_width=512,
        image_height=512,
        fov=math.radians(60),
        rig=SensorRig().to_dict(),
        tables=_rig_table(),
        K=intrinsics_from_fov(512, 512, math.radians(60)) * np.array([[1.001], [0.999], [1]]),
        dist=np.array([1e-3, -2e-4, 0.0, 0.0, 1.0 / 3.0]),
        chessboard_rms=0.1234567890123,
        seed=7,
        report={"stages": 120, "skipped": ["none"], "rms": np.float64(0.1)},
    )
    args.update(kw)
    return Calibration(**args)


def test_calibration_roundtrip_byte_identical(tmp_path: Path):
    cal = _calibration()
    p1 = cal.save(tmp_path / "a.json")
    back = Calibration.load(p1)
    assert back.format_version == FORMAT_VERSION == 1
    np.testing.assert_array_equal(back.K, cal.K)
    np.testing.assert_array_equal(back.dist, cal.dist)
    assert back.chessboard_rms == cal.chessboard_rms and back.seed == 7 and back.rig == cal.rig
    q = np.array([0.5, 1.0, 1.5, 2.5])
    np.testing.assert_array_equal(back.tables(q)[0], cal.tables(q)[0])
    p2 = back.save(tmp_path / "b.json")
    assert p1.read_bytes() == p2.read_bytes()
    assert _calibration().save(tmp_path / "c.json").read_bytes() == p1.read_bytes()
    data = json.loads(p1.read_text())
    assert list(data) == sorted(data)


def test_calibration_save_rejects_nonfinite(tmp_path: Path):
    with pytest.raises(ValueError):
        _calibration(report={"x": float("nan")}).save(tmp_path / "x.json")
    with pytest.raises(ValueError):
        _calibration(K=np.full((3, 3), np.nan))


def _mutated(tmp_path: Path, fn) -> Path:
    p = _calibration().save(tmp_path / "good.json")
    d = json.loads(p.read_text())
    fn(d)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    return bad


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda d: d.update(format_version=2), "format_version"),
        (lambda d: d.pop("format_version"), "format_version"),
        (lambda d: d.pop("K"), "K"),
        (lambda d: d.update(K=[[1, 0], [0, 1]]), "K"),
        (lambda d: d.update(dist=[0, 0, 0]), "dist"),
        (lambda d: d["tables"].pop("ps2"), "ps2"),
        (lambda d: d["tables"]["ps1"].update(ranges=[0.5, 0.6], pixels=[[0, 0], [1, 1]]), "ps1"),
        (lambda d: d["rig"].pop("theta"), "theta"),
    ],
)
def test_calibration_load_errors_name_file(tmp_path: Path, mutate, match):
    bad = _mutated(tmp_path, mutate)
    with pytest.raises(CalibrationError, match=match) as ei:
        Calibration.load(bad)
    assert str(bad) in str(ei.value)


def test_calibration_load_corrupt_missing_nonfinite(tmp_path: Path):
    missing = tmp_path / "nope.json"
    with pytest.raises(CalibrationError, match="not found") as ei:
        Calibration.load(missing)
    assert str(missing) in str(ei.value)
    corrupt = tmp_path / "corrupt.json"
    corrupt.write_text('{"format_version": 1, "K": [')
    with pytest.raises(CalibrationError, match="JSON") as ei:
        Calibration.load(corrupt)
    assert str(corrupt) in str(ei.value)
    good = _calibration().save(tmp_path / "g.json")
    nan = tmp_path / "nan.json"
    nan.write_text(good.read_text().replace("0.1234567890123", "NaN"))
    with pytest.raises(CalibrationError, match="non-finite") as ei:
        Calibration.load(nan)
    assert str(nan) in str(ei.value)
    assert issubclass(CalibrationError, ValueError)


def test_check_matches(tmp_path: Path):
    p = _calibration().save(tmp_path / "cal.json")
    cal = Calibration.load(p)
    cal.check_matches(512, 512, math.radians(60), SensorRig())  # matches: no error
    with pytest.raises(CalibrationError) as ei:
        cal.check_matches(640, 480, math.radians(70), SensorRig(), output="out/cal640.json")
    msg = str(ei.value)
    cmd = "python -m ihrcf_env.calibrate --width 640 --height 480 --fov-deg 70 --output out/cal640.json"
    assert cmd in msg
    assert str(p) in msg and "512x512" in msg
    with pytest.raises(CalibrationError, match="rig a") as ei:
        cal.check_matches(512, 512, math.radians(60), SensorRig(a=0.12))
    assert "--width 512 --height 512 --fov-deg 60 --output" in str(ei.value)


def test_default_calibration_path():
    p = default_calibration_path()
    assert p.name == "calibration_default.json"


def test_module_does_not_import_pybullet():
    code = "import sys, ihrcf_env.core.calibration; sys.exit('pybullet' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
