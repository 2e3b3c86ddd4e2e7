"""Tests for ihrcf_env.core.estimators on synthetic data of known answer (no simulator)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from ihrcf_env.core.estimators import (
    APRILTAG_CORNER_OFFSET_PX,
    DEFAULT_ESTIMATORS,
    ESTIMATORS,
    R_DECK_MARKER,
    TAG_NOT_FOUND,
    ATDAEstimator,
    DeckPoseEstimator,
    DeckPoseSource,
    EstimatorConfig,
    IHRCFEstimator,
    ImuSample,
    PoseEstimate,
    SensorFrame,
    TagDetector,
    atda_estimate,
    build_estimators,
    ihrcf_estimate,
)
from ihrcf_env.core.frames import (
    body_pose_to_cam,
    cam_pose_to_body,
    euler_from_matrix,
    matrix_from_euler,
    rotation_angle,
)
from ihrcf_env.core.rig import SensorRig, intrinsics_from_fov, tag_corners_deck

RIG = SensorRig()
K = intrinsics_from_fov(512, 512, math.radians(60))  # f = 443.4 px
TAG = 0.4


def project(R_cd: np.ndarray, t_cd: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Exact pinhole projection (OpenCV pixel centres) of deck-frame points X (N, 3)."""
    x = X @ R_cd.T + t_cd
    p = x @ K.T
    return p[:, :2] / p[:, 2:3]


def scene(R_bd: np.ndarray, p_bd: np.ndarray, rig: SensorRig = RIG):
    """Corners (4, 2), exact ranges (4,) and an exact touch-pixel table for a deck pose in the body frame."""
    R_cd, t_cd = body_pose_to_cam(R_bd, p_bd, rig.camera_position)
    corners = project(R_cd, t_cd, tag_corners_deck(TAG))
    n = R_cd[:, 2]  # deck normal in the camera frame; plane n . x = n . t
    xy = rig.sensor_xy_cam
    ranges = (n @ t_cd - xy @ n[:2]) / n[2]  # beam (x_i, y_i, s) meets the plane

    def touch_pixels(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pts = np.column_stack([xy, r]) @ K.T
        return pts[:, :2] / pts[:, 2:3], np.ones(4, dtype=bool)

    return corners, ranges, touch_pixels, R_cd, t_cd


def random_pose(rng: np.random.Generator, tilt: float = 0.3, height: float = 1.0):
    eul = rng.uniform(-tilt, tilt, 3)
    eul[2] = rng.uniform(-math.pi, math.pi)
    p = np.array([rng.uniform(-0.15, 0.15), rng.uniform(-0.15, 0.15), -height])
    return matrix_from_euler(*eul), p


def render(R_cd: np.ndarray, t_cd: np.ndarray, size: int = 512, ss: int = 4, cell: int = 32) -> np.ndarray:
    """Grey image of tag 36h11 id 0 with a one-cell white quiet zone on the deck, seen by camera K.

    Texture top edge -> deck +x, left edge -> deck +y (rig.tag_corners_deck). Rendered by
    warpPerspective at ``ss`` x supersampling (pixel centres at integers on both sides), then box
    down-sampled: low-res pixel j covers high-res pixels ss*j .. ss*j+ss-1, centre ss*j + (ss-1)/2.
    """
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    marker = cv2.aruco.generateImageMarker(dictionary, 0, 8 * cell, borderBits=1)
    tex = cv2.copyMakeBorder(marker, cell, cell, cell, cell, cv2.BORDER_CONSTANT, value=255)
    k = TAG / (8 * cell)
    o = TAG / 2 + k * (cell - 0.5)  # texture pixel-centre coordinate cell - 0.5 is the black border's edge
    A = np.array([[0.0, -k, o], [-k, 0.0, o], [0.0, 0.0, 1.0]])  # texture (u, v) -> deck (x, y)
    S = np.array([[ss, 0.0, (ss - 1) / 2], [0.0, ss, (ss - 1) / 2], [0.0, 0.0, 1.0]])
    H = S @ K @ np.column_stack([R_cd[:, 0], R_cd[:, 1], t_cd]) @ A
    hi = cv2.warpPerspective(
        tex, H, (size * ss, size * ss), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=90
    )
    return cv2.resize(hi, (size, size), interpolation=cv2.INTER_AREA)


def assert_invalid(est: PoseEstimate, reason: str) -> None:
    assert not est.valid
    assert reason in est.reason
    assert np.array_equal(est.position, np.zeros(3)) and np.array_equal(est.euler, np.zeros(3))
    assert np.array_equal(est.rotation, np.eye(3))
    assert est.residual == 0.0


# ----------------------------------------------------------------------------------------- PoseEstimate


def test_pose_estimate_invalid_and_immutable() -> None:
    est = PoseEstimate.invalid("because")
    assert_invalid(est, "because")
    with pytest.raises(ValueError):
        est.position[0] = 1.0
    with pytest.raises(AttributeError):
        est.valid = True  # type: ignore[misc]
    with pytest.raises(ValueError, match="position"):
        PoseEstimate(np.zeros(2), np.zeros(3), np.eye(3), True, 0.0)


# ----------------------------------------------------------------------------------------------- IHRCF


def test_ihrcf_exact_recovery() -> None:
    rng = np.random.default_rng(0)
    for height in (0.5, 1.0, 2.0):
        for _ in range(10):
            R_bd, p_bd = random_pose(rng, height=height)
            corners, ranges, tp, _, _ = scene(R_bd, p_bd)
            est = ihrcf_estimate(corners, ranges, np.ones(4, bool), tp, RIG, TAG)
            assert est.valid and est.reason == ""
            assert np.max(np.abs(est.position - p_bd)) < 1e-6
            assert rotation_angle(est.rotation, R_bd) < 1e-6
            np.testing.assert_allclose(est.euler, euler_from_matrix(R_bd), atol=1e-6)
            assert est.residual < 1e-6


def test_ihrcf_level_deck_reads_zero_angles() -> None:
    corners, ranges, tp, _, _ = scene(np.eye(3), np.array([0.0, 0.0, -1.0]))
    est = ihrcf_estimate(corners, ranges, np.ones(4, bool), tp, RIG, TAG)
    np.testing.assert_allclose(est.position, [0, 0, -1], atol=1e-9)
    np.testing.assert_allclose(est.euler, 0, atol=1e-9)


@pytest.mark.parametrize("missing", range(4))
def test_ihrcf_three_ranges_predicts_the_fourth(missing: int) -> None:
    rng = np.random.default_rng(10 + missing)
    R_bd, p_bd = random_pose(rng)
    corners, ranges, tp, _, _ = scene(R_bd, p_bd)
    seen: list[np.ndarray] = []

    def spy(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        seen.append(r.copy())
        return tp(r)

    valid = np.ones(4, bool)
    valid[missing] = False
    bad = ranges.copy()
    bad[missing] = 123.0  # must be ignored
    est = ihrcf_estimate(corners, bad, valid, spy, RIG, TAG)
    assert est.valid
    np.testing.assert_allclose(seen[0], ranges, atol=1e-12)  # predicted range from the plane
    assert np.max(np.abs(est.position - p_bd)) < 1e-6
    assert rotation_angle(est.rotation, R_bd) < 1e-6
    # A NaN range flagged valid counts as missing too.
    bad[missing] = np.nan
    est2 = ihrcf_estimate(corners, bad, np.ones(4, bool), tp, RIG, TAG)
    assert est2.valid and np.max(np.abs(est2.position - p_bd)) < 1e-6


def test_ihrcf_invalid_inputs() -> None:
    R_bd, p_bd = matrix_from_euler(0.1, -0.05, 0.7), np.array([0.05, -0.02, -1.0])
    corners, ranges, tp, _, _ = scene(R_bd, p_bd)
    ok = np.ones(4, bool)

    assert_invalid(ihrcf_estimate(corners, ranges, [True, False, True, False], tp, RIG, TAG), "fewer than 3")
    r = ranges.copy()
    r[[0, 1]] = [np.nan, -1.0]
    assert_invalid(ihrcf_estimate(corners, r, ok, tp, RIG, TAG), "fewer than 3 valid ranges")

    def out_of_table(rr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        px, _ = tp(rr)
        return px, np.array([True, True, False, True])

    assert_invalid(ihrcf_estimate(corners, ranges, ok, out_of_table, RIG, TAG), "calibration table")

    def collinear_pixels(rr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.array([[100.0, 100.0], [200.0, 200.0], [300.0, 300.0], [100.0, 300.0]]), np.ones(4, bool)

    assert_invalid(ihrcf_estimate(corners, ranges, ok, collinear_pixels, RIG, TAG), "degenerate touch pixels")

    def nan_pixels(rr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.full((4, 2), np.nan), np.ones(4, bool)

    assert_invalid(ihrcf_estimate(corners, ranges, ok, nan_pixels, RIG, TAG), "non-finite")
    assert_invalid(ihrcf_estimate(np.full((4, 2), np.nan), ranges, ok, tp, RIG, TAG), "non-finite")


def test_ihrcf_residual_threshold() -> None:
    R_bd, p_bd = matrix_from_euler(0.1, -0.05, 0.7), np.array([0.05, -0.02, -1.0])
    corners, ranges, tp, _, _ = scene(R_bd, p_bd)
    bad = corners.copy()
    bad[0] += [15.0, -10.0]  # ~4 cm off at 1 m: the corners no longer form the tag square
    assert_invalid(ihrcf_estimate(bad, ranges, np.ones(4, bool), tp, RIG, TAG), "fit residual")
    loose = ihrcf_estimate(bad, ranges, np.ones(4, bool), tp, RIG, TAG, max_residual=1.0)
    assert loose.valid and 0.01 < loose.residual < 1.0


def test_ihrcf_programmer_errors_raise() -> None:
    corners, ranges, tp, _, _ = scene(np.eye(3), np.array([0.0, 0.0, -1.0]))
    with pytest.raises(ValueError, match="corners_px"):
        ihrcf_estimate(corners[:3], ranges, np.ones(4, bool), tp, RIG, TAG)
    with pytest.raises(ValueError, match="ranges"):
        ihrcf_estimate(corners, ranges[:3], np.ones(4, bool), tp, RIG, TAG)
    with pytest.raises(ValueError, match="ranges_valid"):
        ihrcf_estimate(corners, ranges, np.ones(5, bool), tp, RIG, TAG)
    with pytest.raises(ValueError, match="touch_pixels"):
        ihrcf_estimate(corners, ranges, np.ones(4, bool), lambda r: (np.zeros((3, 2)), np.ones(4)), RIG, TAG)


# ------------------------------------------------------------------------------------------------ ATDA


def test_atda_exact_corners_recover_pose() -> None:
    rng = np.random.default_rng(5)
    for _ in range(10):
        R_bd, p_bd = random_pose(rng, tilt=0.4)
        corners, *_ = scene(R_bd, p_bd)
        est = atda_estimate(corners, K, None, TAG, RIG)
        assert est.valid
        assert np.max(np.abs(est.position - p_bd)) < 1e-6
        assert rotation_angle(est.rotation, R_bd) < 1e-6
        assert est.residual < 1e-6


def test_marker_frame_conversion_matches_deck_corners() -> None:
    h = TAG / 2
    marker = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])  # IPPE_SQUARE order
    np.testing.assert_allclose(marker @ R_DECK_MARKER.T, tag_corners_deck(TAG))


def _ippe_candidates(corners: np.ndarray) -> list[tuple[float, np.ndarray]]:
    h = TAG / 2
    obj = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
    img = corners.reshape(4, 1, 2)
    _, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, K, None, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    out = []
    for rv, tv in zip(rvecs, tvecs, strict=True):
        rv, tv = cv2.solvePnPRefineLM(obj, img, K, np.zeros(5), rv.copy(), tv.copy())
        proj, _ = cv2.projectPoints(obj, rv, tv, K, np.zeros(5))
        err = float(np.sqrt(np.mean(np.sum((proj.reshape(4, 2) - corners) ** 2, axis=1))))
        R_bd, _ = cam_pose_to_body(cv2.Rodrigues(rv)[0] @ R_DECK_MARKER.T, tv.ravel(), RIG.camera_position)
        out.append((err, R_bd))
    return sorted(out, key=lambda c: c[0])


def test_atda_prior_resolves_flip_ambiguity() -> None:
    # Far, nearly frontal, noisy corners: find a case with two distinct solutions of similar error.
    rng = np.random.default_rng(42)
    for _ in range(500):
        R_bd, p_bd = random_pose(rng, tilt=0.05, height=3.0)
        corners = scene(R_bd, p_bd)[0] + rng.normal(0, 0.5, (4, 2))
        cands = _ippe_candidates(corners)
        similar = len(cands) == 2 and cands[1][0] < 1.5 * cands[0][0]
        if similar and rotation_angle(cands[0][1], cands[1][1]) > 0.05:
            break
    else:
        pytest.fail("no ambiguous case found")
    (e0, R0), (e1, R1) = cands
    no_prior = atda_estimate(corners, K, None, TAG, RIG)
    assert rotation_angle(no_prior.rotation, R0) < 1e-6
    assert no_prior.residual == pytest.approx(e0, rel=1e-6)
    with_prior = atda_estimate(corners, K, None, TAG, RIG, prior_rotation=R1)
    assert rotation_angle(with_prior.rotation, R1) < 1e-6
    assert with_prior.residual == pytest.approx(e1, rel=1e-6)
    # A prior never overrides a clearly better solution: exact corners, prior = a wrong, tilted pose.
    R_bd, p_bd = matrix_from_euler(0.3, 0.0, 0.0), np.array([0.0, 0.0, -1.0])
    corners = scene(R_bd, p_bd)[0]
    est = atda_estimate(corners, K, None, TAG, RIG, prior_rotation=matrix_from_euler(-0.3, 0.0, 0.0))
    assert rotation_angle(est.rotation, R_bd) < 1e-6


def test_atda_invalid_and_errors() -> None:
    assert_invalid(atda_estimate(np.full((4, 2), np.nan), K, None, TAG, RIG), "non-finite")
    line = np.array([[0.0, 0.0], [10.0, 10.0], [20.0, 20.0], [0.0, 20.0]])
    assert_invalid(atda_estimate(line, K, None, TAG, RIG), "degenerate")
    with pytest.raises(ValueError, match="K"):
        atda_estimate(np.zeros((4, 2)), np.eye(2), None, TAG, RIG)
    with pytest.raises(ValueError, match="prior_rotation"):
        atda_estimate(np.zeros((4, 2)), K, None, TAG, RIG, prior_rotation=np.eye(2))


# ------------------------------------------------------------------------------- detector on images


@pytest.fixture(scope="module")
def rendered() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    R_bd, p_bd = matrix_from_euler(0.12, -0.08, 2.2), np.array([0.06, -0.04, -1.0])
    R_cd, t_cd = body_pose_to_cam(R_bd, p_bd, RIG.camera_position)
    return render(R_cd, t_cd), project(R_cd, t_cd, tag_corners_deck(TAG)), R_bd, p_bd, R_cd


def test_detector_corner_order_and_accuracy(rendered) -> None:
    image, truth, *_ = rendered
    det = TagDetector(0)
    corners = det.detect(image)
    assert corners is not None and corners.shape == (4, 2) and corners.dtype == np.float64
    # Same order as tag_corners_deck: each detected corner is nearest to its own projected corner.
    err = np.linalg.norm(corners - truth, axis=1)
    assert err.max() < 0.5, err
    rgb = det.detect(np.repeat(image[:, :, None], 3, axis=2))
    np.testing.assert_allclose(rgb, corners, atol=1e-9)
    assert TagDetector(1).detect(image) is None
    assert det.detect(np.full((64, 64), 200, np.uint8)) is None
    with pytest.raises(ValueError, match="uint8"):
        det.detect(image.astype(np.float32))
    with pytest.raises(ValueError, match="refine"):
        TagDetector(0, refine="magic")


def test_detector_apriltag_offset(rendered) -> None:
    image, truth, *_ = rendered
    raw = TagDetector(0, refine="apriltag", apriltag_offset=0.0).detect(image)
    fixed = TagDetector(0, refine="apriltag").detect(image)
    assert raw is not None and fixed is not None
    np.testing.assert_allclose(raw - fixed, APRILTAG_CORNER_OFFSET_PX)
    assert np.all(np.abs((raw - truth).mean(axis=0) - APRILTAG_CORNER_OFFSET_PX) < 0.1)
    assert np.linalg.norm(fixed - truth, axis=1).mean() < np.linalg.norm(raw - truth, axis=1).mean()


def test_atda_on_rendered_image(rendered) -> None:
    image, _, R_bd, p_bd, _ = rendered
    corners = TagDetector(0).detect(image)
    est = atda_estimate(corners, K, np.zeros(5), TAG, RIG)
    assert est.valid
    assert np.linalg.norm(est.position - p_bd) < 0.005
    assert math.degrees(rotation_angle(est.rotation, R_bd)) < 1.0
    assert est.residual < 0.5


def test_deck_pose_estimator(rendered) -> None:
    image, _, R_bd, p_bd, _ = rendered
    _, ranges, tp, _, _ = scene(R_bd, p_bd)
    dpe = DeckPoseEstimator(RIG, TAG, 0, K, None, tp)
    out = dpe.update(dpe.frame(image, ranges, np.ones(4, bool)))
    ihrcf, atda = out["ihrcf"], out["atda"]
    for est in (ihrcf, atda):
        assert est.valid
        assert np.linalg.norm(est.position - p_bd) < 0.005
        assert math.degrees(rotation_angle(est.rotation, R_bd)) < 1.0
    assert np.array_equal(dpe.prior_rotation, atda.rotation)
    lost = dpe.update(dpe.frame(np.full((512, 512, 3), 255, np.uint8), ranges, np.ones(4, bool)))
    lost_i, lost_a = lost["ihrcf"], lost["atda"]
    assert_invalid(lost_i, "tag not found")
    assert_invalid(lost_a, "tag not found")
    assert np.array_equal(dpe.prior_rotation, atda.rotation)  # kept across a lost frame
    dpe.reset()
    assert dpe.prior_rotation is None


# ------------------------------------------------------------------------- the estimator interface


def _frame(corners, ranges, t: float = 0.0, **kw) -> SensorFrame:
    return SensorFrame(time=t, corners=corners, ranges=ranges, ranges_valid=np.ones(4, bool), **kw)


def test_sensor_frame_is_read_only_and_checked() -> None:
    R_bd, p_bd = matrix_from_euler(0.05, -0.03, 0.4), np.array([0.02, 0.01, -1.0])
    corners, ranges, *_ = scene(R_bd, p_bd)
    imu = ImuSample([0, 0, 0, 1], np.zeros(3), [0, 0, 9.81])
    f = _frame(corners, ranges, 1.25, imu=imu)
    assert f.time == 1.25 and f.corners_reason == "" and f.image is None
    assert f.ranges.dtype == np.float64 and f.ranges_valid.dtype == bool
    with pytest.raises(ValueError):
        f.corners[0, 0] = 0.0
    with pytest.raises(ValueError):
        imu.specific_force[2] = 0.0
    assert _frame(None, ranges).corners_reason == TAG_NOT_FOUND
    assert (
        _frame(None, ranges, corners_reason="tag outside the image").corners_reason == "tag outside the image"
    )
    assert math.isnan(_frame(None, ranges, math.nan).time)  # unknown time
    with pytest.raises(ValueError, match="corners"):
        _frame(np.zeros((3, 2)), ranges)
    with pytest.raises(ValueError, match="ranges"):
        _frame(corners, np.ones(3))
    with pytest.raises(ValueError, match="time"):
        _frame(corners, ranges, math.inf)
    with pytest.raises(TypeError, match="imu"):
        _frame(corners, ranges, imu={"quaternion": [0, 0, 0, 1]})
    with pytest.raises(ValueError, match="quaternion"):
        ImuSample([0, 0, 1], np.zeros(3), np.zeros(3))


def test_estimator_classes_match_the_pure_functions() -> None:
    rng = np.random.default_rng(5)
    ihrcf = IHRCFEstimator(None, RIG, TAG)  # touch_pixels set per scene below
    atda = ATDAEstimator(K, None, TAG, RIG)
    assert isinstance(ihrcf, DeckPoseSource) and isinstance(atda, DeckPoseSource)
    assert (ihrcf.name, atda.name) == ("ihrcf", "atda")
    for _ in range(5):
        R_bd, p_bd = random_pose(rng, tilt=0.2)
        corners, ranges, tp, _, _ = scene(R_bd, p_bd)
        ihrcf.touch_pixels = tp
        frame = _frame(corners + rng.normal(0, 0.2, (4, 2)), ranges)
        a = ihrcf.update(frame)
        b = ihrcf_estimate(frame.corners, ranges, np.ones(4, bool), tp, RIG, TAG)
        np.testing.assert_array_equal(a.position, b.position)
        np.testing.assert_array_equal(a.rotation, b.rotation)
        prior = atda.prior_rotation
        c = atda.update(frame)
        d = atda_estimate(frame.corners, K, None, TAG, RIG, prior)
        np.testing.assert_array_equal(c.rotation, d.rotation)
        assert c.valid and np.array_equal(atda.prior_rotation, c.rotation)
    lost = _frame(None, ranges, corners_reason="no image")
    assert_invalid(ihrcf.update(lost), "no image")
    assert_invalid(atda.update(lost), "no image")
    assert atda.prior_rotation is not None  # kept across a lost frame
    atda.reset()
    assert atda.prior_rotation is None
    with pytest.raises(ValueError, match="max_residual"):
        IHRCFEstimator(None, RIG, TAG, max_residual=0.0)


def test_registry_builds_named_estimators_in_order(monkeypatch: pytest.MonkeyPatch) -> None:
    _, _, tp, _, _ = scene(np.eye(3), np.array([0.0, 0.0, -1.0]))
    cfg = EstimatorConfig(rig=RIG, tag_size=TAG, K=K, dist=None, touch_pixels=tp)
    assert DEFAULT_ESTIMATORS == ("ihrcf", "atda", "fused")
    built = build_estimators(cfg)
    assert list(built) == ["ihrcf", "atda", "fused"]
    assert list(build_estimators(cfg, ["atda", "ihrcf"])) == ["atda", "ihrcf"]
    for bad, err, match in [
        (["ihrcf", "ihrcf"], ValueError, "twice"),
        (["kalman"], ValueError, "unknown name 'kalman'"),
        (["ground_truth"], ValueError, "reserved"),
        ([], ValueError, "at least one"),
        ("ihrcf", TypeError, "sequence of names"),
        ([1], TypeError, "names"),
    ]:
        with pytest.raises(err, match=match):
            build_estimators(cfg, bad)

    class Named:
        def __init__(self, name: str) -> None:
            self.name = name

        def reset(self) -> None:
            pass

        def update(self, frame: SensorFrame) -> PoseEstimate:
            return PoseEstimate.invalid("never")

    monkeypatch.setitem(ESTIMATORS, "liar", lambda c: Named("other"))
    with pytest.raises(ValueError, match="calls itself 'other'"):
        build_estimators(cfg, ["liar"])


def test_pipeline_detects_once_and_feeds_every_estimator(rendered, monkeypatch: pytest.MonkeyPatch) -> None:
    image, _, R_bd, p_bd, _ = rendered
    _, ranges, tp, _, _ = scene(R_bd, p_bd)
    seen: list[SensorFrame] = []

    class Recorder:
        name = "recorder"

        def reset(self) -> None:
            seen.clear()

        def update(self, frame: SensorFrame) -> PoseEstimate:
            seen.append(frame)
            return PoseEstimate.invalid(frame.corners_reason or "recorded")

    monkeypatch.setitem(ESTIMATORS, "recorder", lambda c: Recorder())
    dpe = DeckPoseEstimator(RIG, TAG, 0, K, None, tp, estimators=("ihrcf", "recorder", "atda"))
    calls = []
    detect = dpe.detector.detect
    monkeypatch.setattr(dpe.detector, "detect", lambda img: calls.append(1) or detect(img))
    imu = ImuSample([0, 0, 0, 1], np.zeros(3), [0, 0, 9.81])
    frame = dpe.frame(image, ranges, np.ones(4, bool), time=0.05, imu=imu)
    assert len(calls) == 1 and frame.corners is not None and frame.time == 0.05 and frame.imu is imu
    out = dpe.update(frame)
    assert list(out) == ["ihrcf", "recorder", "atda"] == list(dpe.names)
    assert out["ihrcf"].valid and out["atda"].valid and seen == [frame]
    assert len(calls) == 1  # the estimators share the frame's corners
    lost = dpe.update(dpe.frame(np.full((512, 512), 255, np.uint8), ranges, np.ones(4, bool), time=0.1))
    assert seen[-1].corners is None and seen[-1].time == 0.1  # a lost frame still reaches every estimator
    assert all(e.reason == TAG_NOT_FOUND for e in lost.values())
    dpe.reset()
    assert seen == [] and dpe.prior_rotation is None
    only_ihrcf = DeckPoseEstimator(RIG, TAG, 0, K, None, tp, estimators=("ihrcf",))
    assert only_ihrcf.prior_rotation is None
    assert list(only_ihrcf.update(only_ihrcf.frame(image, ranges, np.ones(4, bool)))) == ["ihrcf"]
