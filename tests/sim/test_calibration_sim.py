"""Simulated calibration (paper sections 2.1-2.2): pads and chessboard rendered by PyBullet's TinyRenderer,
the ascent, the CLI and the shipped calibration file.

Ground truth throughout is the renderer's true K (``CameraConfig.intrinsics``) applied to camera-frame
points; the estimators never see it.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest

from ihrcf_env import HOVER_ID
from ihrcf_env.cli.calibrate import main as calibrate_main
from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.calibration import (
    YCBCR_THRESHOLDS,
    Calibration,
    CalibrationError,
    default_calibration_path,
    rgb_to_ycbcr,
    segment_pads,
    ycbcr_mask,
)
from ihrcf_env.core.frames import matrix_from_euler, quat_from_matrix
from ihrcf_env.core.profiles import CallableProfile, StaticProfile
from ihrcf_env.core.rig import PAD_COLOURS, SensorRig
from ihrcf_env.sim.calibration_procedure import (
    AscentSettings,
    CalibrationFailed,
    ChessboardSettings,
    run_ascent,
    run_calibration,
    run_chessboard,
    table_errors_px,
)
from ihrcf_env.sim.calibration_scene import DEFAULT_PAD_RADIUS, CalibrationScene
from ihrcf_env.sim.world import World

CAM = CameraConfig()
K_TRUE = CAM.intrinsics
RIG = SensorRig()


@pytest.fixture(scope="module")
def world():
    w = World(WorldConfig())
    yield w
    w.close()


@pytest.fixture(scope="module")
def scene(world):
    s = CalibrationScene(world)
    yield s
    s.close()


def _set_deck(world: World, rpy: tuple[float, float, float]) -> None:
    """Hold the deck still at home position with orientation ``rpy`` (rad)."""
    r = np.asarray(rpy, dtype=np.float64)
    profile = StaticProfile() if not np.any(r) else CallableProfile(lambda t: (np.zeros(3), r))
    world.reset(profile, 0.1, altitude=1.0)


def _place_drone(world: World, pos: np.ndarray, R_wb: np.ndarray) -> None:
    p.resetBasePositionAndOrientation(
        world.quad.body, pos.tolist(), quat_from_matrix(R_wb).tolist(), physicsClientId=world.client
    )


def _touch_points(world: World) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ranges (4,), hit (4,), world touch points (4, 3)) of the ideal ToF beams now."""
    pos, R = world.drone_pose()
    ranges, hit = world.tof.true_ranges(pos, R)
    touch = RIG.sensor_positions_body @ R.T + pos - R[:, 2] * ranges[:, None]
    return ranges, hit, touch


def _analytic_pads(world: World, touch: np.ndarray, radius: float) -> list[np.ndarray]:
    """Exact image masks of the four pad discs (true K, pixel centres): back-project every pixel
    centre onto the pad's plane and keep those within ``radius`` of the pad centre."""
    pos, R_wb = world.drone_pose()
    eye, R_wc = world.camera.pose(pos, R_wb)
    _, R_wd = world.deck.pose()
    vv, uu = np.mgrid[0 : CAM.height, 0 : CAM.width].astype(np.float64)
    rays = np.stack([uu, vv, np.ones_like(uu)], axis=-1) @ np.linalg.inv(K_TRUE).T  # camera frame
    n = R_wc.T @ R_wd[:, 2]
    masks = []
    for c_w in touch:
        c = R_wc.T @ (c_w - eye)
        t = (n @ c) / (rays @ n)
        x = rays * t[..., None]
        masks.append((t > 0) & (np.linalg.norm(x - c, axis=-1) <= radius))
    return masks


def _true_pixels(ranges: np.ndarray) -> np.ndarray:
    pts = np.column_stack([RIG.sensor_xy_cam, ranges]) @ K_TRUE.T
    return pts[:, :2] / pts[:, 2:]


def _level_hover(world: World, scene: CalibrationScene, d: float) -> tuple[np.ndarray, np.ndarray]:
    """Level deck, level drone with its camera ``d`` m above the deck, pads on the touch points."""
    _set_deck(world, (0.0, 0.0, 0.0))
    deck_pos, R_wd = world.deck.pose()
    _place_drone(world, deck_pos + np.array([0.0, 0.0, d - RIG.camera_position[2]]), np.eye(3))
    ranges, hit, touch = _touch_points(world)
    assert hit.all()
    scene.place_pads(touch, R_wd)
    return ranges, touch


# ------------------------------------------------------------------------------ pads and Table 1


@pytest.mark.parametrize(
    "rpy_deg", [(0.0, 0.0, 0.0), (15.0, 0.0, 0.0), (-10.6, 10.6, 0.0), (0.0, -15.0, 5.0)]
)
def test_rendered_pads_fall_only_in_their_own_table1_box(world, scene, rpy_deg):
    """Lighting + pad colours: on a rendered frame (deck level or tilted 15 deg towards/away from the
    light), every pixel well inside a pad passes that pad's Table 1 box and no other, and no pixel
    outside the pads (deck, legs, background) passes any box."""
    _set_deck(world, tuple(math.radians(a) for a in rpy_deg))
    deck_pos, R_wd = world.deck.pose()
    _place_drone(world, deck_pos + np.array([0.0, 0.0, 1.0]), np.eye(3))
    ranges, hit, touch = _touch_points(world)
    assert hit.all()
    scene.place_pads(touch, R_wd)
    img = scene.render()
    scene.hide_pads()
    ycc = rgb_to_ycbcr(img)
    boxes = {c: ycbcr_mask(ycc, c) for c in YCBCR_THRESHOLDS}
    inner = _analytic_pads(world, touch, DEFAULT_PAD_RADIUS * 0.85)  # away from the edge pixels
    outer = _analytic_pads(world, touch, DEFAULT_PAD_RADIUS * 1.15)
    for colour, m in zip(PAD_COLOURS, inner, strict=True):
        assert m.sum() > 300
        for other, box in boxes.items():
            frac = box[m].mean()
            if other == colour:
                assert frac == 1.0, f"{colour} pad: {frac:.3f} of its pixels in the {colour} box"
            else:
                assert frac == 0.0, f"{colour} pad: {frac:.3f} of its pixels in the {other} box"
    outside = ~np.logical_or.reduce(outer)
    for colour, box in boxes.items():
        assert not box[outside].any(), f"{int(box[outside].sum())} non-pad pixels in the {colour} box"


@pytest.mark.parametrize("d", [0.35, 1.0, 2.0, 3.9])
def test_pad_segmentation_matches_analytic_disc(world, scene, d):
    """Each rendered pad, segmented (YCbCr, Table 1, filled hull), overlaps the analytic projection of
    its circle with IoU >= 0.9, and its centroid is within 0.3 px of the projected touch point."""
    ranges, touch = _level_hover(world, scene, d)
    img = scene.render()
    scene.hide_pads()
    dets = segment_pads(img)
    truth = _analytic_pads(world, touch, DEFAULT_PAD_RADIUS)
    true_px = _true_pixels(ranges)
    for i, colour in enumerate(PAD_COLOURS):
        det = dets[colour]
        assert det is not None, f"{colour} pad not found at {d} m"
        iou = (det.mask & truth[i]).sum() / (det.mask | truth[i]).sum()
        assert iou >= 0.9, f"{colour} at {d} m: IoU {iou:.3f}"
        assert np.linalg.norm(det.centroid - true_px[i]) < 0.3


def test_pads_cut_by_the_border_are_not_found(world, scene):
    """At 0.17 m the pads reach past the image border (their analytic discs touch it): no pad is
    reported, so such a stage can only be skipped."""
    ranges, touch = _level_hover(world, scene, 0.17)
    img = scene.render()
    scene.hide_pads()
    for m in _analytic_pads(world, touch, DEFAULT_PAD_RADIUS):
        assert m[0, :].any() or m[-1, :].any() or m[:, 0].any() or m[:, -1].any()
    assert all(det is None for det in segment_pads(img).values())


# ------------------------------------------------------------------------------ shipped table


@pytest.fixture(scope="module")
def shipped() -> Calibration:
    cal = Calibration.load(default_calibration_path())
    cal.check_matches(CAM.width, CAM.height, CAM.fov, RIG)  # made for the default camera and rig
    return cal


def test_shipped_file_contents(shipped):
    rep = shipped.report
    lo, hi = shipped.tables.spans[:, 0].max(), shipped.tables.spans[:, 1].min()
    assert lo < 0.25 and hi >= 0.999 * WorldConfig().tof.max_range  # up to the sensors' max range
    assert rep["procedure"]["stages"] == 120
    assert rep["stages_used"] + len(rep["stages_skipped"]) == 120
    assert rep["stages_used"] >= 110
    for s in rep["stages_skipped"]:  # only the lowest stages, where the pads leave the image
        assert s["range_m"] < 0.2 and "pad" in s["reason"]
    # The chessboard part of the file (for ATDA).
    assert shipped.chessboard_rms is not None and shipped.chessboard_rms < 0.3
    assert abs(shipped.K[0, 0] / K_TRUE[0, 0] - 1) < 0.005
    assert abs(shipped.K[1, 1] / K_TRUE[1, 1] - 1) < 0.005


def test_shipped_table_accuracy_on_tilted_deck(world, scene, shipped):
    """Item 4: at random ranges within the calibrated span, deck tilted up to 15 deg, random drone yaw,
    small drone tilt and offset, the table's pixel of each ideal ToF reading is within 0.5 px of the
    true projection K (x_i, y_i, d_i) of the beam's touch point (ray-cast)."""
    rng = np.random.default_rng(42)
    lo, hi = shipped.tables.spans[:, 0].max(), shipped.tables.spans[:, 1].min()
    errors = []
    d_seen = []
    for k in range(8):
        tilt = math.radians(15.0) * (1.0 if k < 2 else rng.uniform(0.3, 1.0))
        az = rng.uniform(0, 2 * math.pi)
        rpy = (tilt * math.cos(az), tilt * math.sin(az), rng.uniform(-0.1, 0.1))
        _set_deck(world, rpy)
        deck_pos, R_wd = world.deck.pose()
        n_ok = 0
        while n_ok < 12:
            d = rng.uniform(lo, hi)
            R_wb = matrix_from_euler(rng.normal(0, 0.03), rng.normal(0, 0.03), rng.uniform(-math.pi, math.pi))
            offset = np.array([*rng.uniform(-0.05, 0.05, 2), d + 0.03])
            _place_drone(world, deck_pos + offset, R_wb)
            ranges, hit, _ = _touch_points(world)
            if not (hit.all() and np.all((ranges >= lo) & (ranges <= hi))):
                continue
            uv, inside = shipped.tables(ranges)
            assert inside.all()
            errors.append(np.linalg.norm(uv - _true_pixels(ranges), axis=1))
            d_seen.append(ranges)
            n_ok += 1
    errors = np.array(errors)
    d_seen = np.array(d_seen)
    assert d_seen.min() < lo + 0.5 and d_seen.max() > hi - 0.5  # the whole span was exercised
    assert np.ptp(d_seen, axis=1).max() > 0.03  # tilted deck: the four ranges differ
    assert errors.max() < 0.5, f"max {errors.max():.3f} px"
    # The same check through table_errors_px (used in the calibration report).
    np.testing.assert_allclose(table_errors_px(shipped.tables, d_seen, RIG, K_TRUE), errors, atol=1e-9)


@pytest.mark.parametrize("d", [0.3, 0.8, 2.0, 3.5])
def test_rendered_pads_on_tilted_deck_sit_at_table_pixels(world, scene, shipped, d):
    """Rendered check of item 4 on a deck tilted 15 deg: pads centred on the beams' touch points are
    found where the table, indexed by range only, puts the touch pixels. A tilted disc's image
    centroid is not the image of its centre (perspective: 1.6-2.3 px at 0.3 m, 0.2-0.3 px at 0.8 m
    for 4 cm pads), so that analytic offset (from the exact disc mask) is added to the table pixel."""
    _set_deck(world, (math.radians(10.6), math.radians(-10.6), 0.0))
    deck_pos, R_wd = world.deck.pose()
    _place_drone(world, deck_pos + np.array([0.02, -0.03, d + 0.03]), matrix_from_euler(0.02, -0.01, 0.7))
    ranges, hit, touch = _touch_points(world)
    assert hit.all() and np.ptp(ranges) > 0.03
    scene.place_pads(touch, R_wd)
    img = scene.render()
    scene.hide_pads()
    uv, inside = shipped.tables(ranges)
    assert inside.all()
    dets = segment_pads(img)
    true_px = _true_pixels(ranges)
    for i, (colour, disc) in enumerate(
        zip(PAD_COLOURS, _analytic_pads(world, touch, DEFAULT_PAD_RADIUS), strict=True)
    ):
        det = dets[colour]
        assert det is not None
        rows, cols = np.nonzero(disc)
        disc_centroid = np.array([cols.mean(), rows.mean()])
        assert np.linalg.norm(det.centroid - disc_centroid) < 0.3  # segmentation on the tilted deck
        expected = uv[i] + (disc_centroid - true_px[i])  # table pixel + perspective offset
        assert np.linalg.norm(det.centroid - expected) < 0.5, f"{colour}: {det.centroid} vs {expected}"


def test_estimator_loader_uses_the_shipped_file_and_names_bad_files(tmp_path: Path):
    """Item 5 through the estimator-facing loader (the env's pose-estimate wrapper): the default env
    loads the shipped file; a corrupt or inconsistent file gives an error naming it and the problem."""
    env = gym.make(HOVER_ID)
    try:
        cal = env.get_wrapper_attr("calibration")
        assert cal.source == str(default_calibration_path())
    finally:
        env.close()
    text = Path(str(default_calibration_path())).read_text(encoding="utf-8")
    corrupt = tmp_path / "corrupt.json"
    corrupt.write_text(text[: len(text) // 2], encoding="utf-8")
    with pytest.raises(CalibrationError, match=r"corrupt\.json.*not a valid calibration JSON"):
        gym.make(HOVER_ID, calibration=corrupt)
    data = json.loads(text)
    data["tables"]["ps3"]["ranges"] = data["tables"]["ps3"]["ranges"][:3]
    data["tables"]["ps3"]["pixels"] = data["tables"]["ps3"]["pixels"][:3]
    short = tmp_path / "short.json"
    short.write_text(json.dumps(data), encoding="utf-8")
    with pytest.raises(CalibrationError, match=r"short\.json: bad 'tables'.*ps3.*at least 4"):
        gym.make(HOVER_ID, calibration=short)
    with pytest.raises(CalibrationError, match=r"nothere\.json.*not found.*ihrcf-calibrate"):
        gym.make(HOVER_ID, calibration=tmp_path / "nothere.json")
    # A camera config the shipped file was not made for: the error gives the command to make one.
    with pytest.raises(CalibrationError, match="--width 320 --height 240 --fov-deg 70"):
        Calibration.load(default_calibration_path()).check_matches(320, 240, math.radians(70), RIG)


# ------------------------------------------------------------------------------ procedures


def test_chessboard_fast(world, scene):
    """Item 1 with 8 views (fast set). Over seeds 0-7 the focal error of 8-view runs was 0.06-0.8 %,
    the principal point error 0.7-2.2 px, RMS <= 0.26 px; the full 30-view run is the slow test."""
    world.reset(StaticProfile(), 0.1, altitude=2.5)
    res = run_chessboard(world, scene, ChessboardSettings(n_views=8), np.random.default_rng(0))
    assert res.intrinsics.n_views == 8 and res.views_tried <= 12
    assert res.intrinsics.rms < 0.3
    assert res.focal_error_rel < 0.015
    assert res.principal_point_error_px < 3.0
    np.testing.assert_array_equal(res.K_true, K_TRUE)


def test_chessboard_full(world, scene):
    """Item 1: >= 15 views (30, the CLI default), focal error < 0.5 %, RMS < 0.3 px, for several seeds."""
    world.reset(StaticProfile(), 0.1, altitude=2.5)
    for seed in range(3):
        res = run_chessboard(world, scene, ChessboardSettings(n_views=30), np.random.default_rng(seed))
        assert res.intrinsics.rms < 0.3
        assert res.focal_error_rel < 0.005, f"seed {seed}: {100 * res.focal_error_rel:.3f} %"
        assert res.principal_point_error_px < 1.5


def test_too_few_usable_stages_is_a_clear_error(world, scene):
    with pytest.raises(CalibrationFailed, match=r"only 0 of 6 calibration stages were usable.*pad"):
        run_ascent(world, scene, AscentSettings(stages=6, bottom=0.1, top=0.18, min_usable_stages=4))


def _short_run(seed: int) -> Calibration:
    return run_calibration(
        ascent=AscentSettings(stages=20), chessboard=ChessboardSettings(n_views=4), seed=seed
    ).calibration


def test_same_seed_gives_identical_file_and_skips_are_reported(tmp_path: Path):
    a = _short_run(7).save(tmp_path / "a.json")
    b = _short_run(7).save(tmp_path / "b.json")
    c = _short_run(8).save(tmp_path / "c.json")
    assert a.read_bytes() == b.read_bytes()
    assert a.read_bytes() != c.read_bytes()  # the seed matters (chessboard poses)
    cal = Calibration.load(a)
    assert cal.seed == 7
    rep = cal.report
    # Stage 0 (0.15 m): the pads are cut by the image border -> skipped and reported, not a crash.
    assert [s["stage"] for s in rep["stages_skipped"]] == [0]
    assert "cut by the image border" in rep["stages_skipped"][0]["reason"]
    assert rep["stages_used"] == 19 and all(t.ranges.size == 19 for t in cal.tables.tables)
    assert rep["table_error_at_samples_px"]["max"] < 0.5
    assert rep["max_pad_drift_m"] < 1e-4  # the hover kept the beams on the pad centres


def test_cli_writes_file_prints_summary_and_progress(tmp_path: Path, capsys):
    out = tmp_path / "sub" / "cal.json"
    rc = calibrate_main(["--stages", "12", "--views", "4", "--seed", "3", "--output", str(out)])
    assert rc == 0
    captured = capsys.readouterr()
    for text in ("focal error", "principal point error", "RMS", "skipped 1 stage(s)", "stage 0 at 0.150 m"):
        assert text in captured.out
    assert "ascent" in captured.err and "12/12" in captured.err
    cal = Calibration.load(out)
    cal.check_matches(512, 512, math.radians(60), RIG)
    assert cal.seed == 3 and cal.report["procedure"]["stages"] == 12


def test_cli_reports_failure_without_traceback(tmp_path: Path, capsys):
    rc = calibrate_main(
        [
            "--stages",
            "5",
            "--top",
            "0.18",
            "--bottom",
            "0.1",
            "--views",
            "3",
            "--quiet",
            "--output",
            str(tmp_path / "x.json"),
        ]
    )
    assert rc == 1
    err = capsys.readouterr().err
    assert "calibration failed" in err and "usable" in err
    assert not (tmp_path / "x.json").exists()


#: Cross-machine tolerance of a re-made calibration file: the same procedure on another CPU differs
#: in the last digits (OpenCV's calibrateCamera and BLAS reorder sums), e.g. 0.7650400624926729 vs
#: ...6733. Every number in the file is in px, m, rad or a ratio of them, so 1e-6 absolute means a
#: micro-pixel / micrometre, far below anything physical, while a real change of the procedure moves
#: table pixels by > 1e-3 px. Strings, integers and the structure must match exactly.
FILE_ATOL = 1e-6
FILE_RTOL = 1e-9


def _json_differences(a: object, b: object, path: str = "") -> list[str]:
    """Where two parsed JSON documents differ beyond FILE_ATOL / FILE_RTOL (floats) or at all (rest)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [f"{path}: keys {sorted(set(a) ^ set(b))} differ"]
        return [d for k in a for d in _json_differences(a[k], b[k], f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: length {len(a)} != {len(b)}"]
        return [
            d
            for i, (x, y) in enumerate(zip(a, b, strict=True))
            for d in _json_differences(x, y, f"{path}[{i}]")
        ]
    if isinstance(a, float) or isinstance(b, float):
        if (
            isinstance(a, bool)
            or isinstance(b, bool)
            or not isinstance(a, int | float)
            or not isinstance(b, int | float)
        ):
            return [f"{path}: {a!r} != {b!r}"]
        return [] if abs(a - b) <= FILE_ATOL + FILE_RTOL * abs(b) else [f"{path}: {a!r} != {b!r}"]
    return [] if a == b and type(a) is type(b) else [f"{path}: {a!r} != {b!r}"]


def test_json_differences_tolerates_last_digits_only():
    a = {"K": [[443.0, 0.0], [0.0, 0.7650400624926729]], "n": 3, "s": "x", "drift": 0.0}
    b = {"K": [[443.0, 0.0], [0.0, 0.7650400624926733]], "n": 3, "s": "x", "drift": 9.8e-17}
    assert _json_differences(a, b) == []
    assert _json_differences(a, {**b, "n": 4}) == [".n: 3 != 4"]
    assert _json_differences(a, {**b, "K": [[443.001, 0.0], [0.0, 0.765]]}) != []
    assert _json_differences(a, {**b, "s": "y"}) != []
    assert _json_differences({"a": 1}, {"a": 1, "b": 2}) != []


def test_shipped_file_is_reproduced_by_the_cli(tmp_path: Path, capsys):
    """The shipped default file is what ``python -m ihrcf_env.calibrate`` writes by default, to
    FILE_ATOL on every number (not byte for byte: see FILE_ATOL)."""
    out = tmp_path / "default.json"
    assert calibrate_main(["--quiet", "--output", str(out)]) == 0
    made = json.loads(out.read_text())
    shipped = json.loads(Path(str(default_calibration_path())).read_text())
    assert _json_differences(made, shipped) == []
