"""The fitted detector model (ihrcf_env.fast.detector) against the closed-form camera's
(sim.sensors.corner_model.model_corners) and DetectorModel.corners, float64."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from ihrcf_env.core.detector_model import QUIET_ZONE_SCALE, CornerTrack, DetectorModel, tag_features
from ihrcf_env.core.rig import SensorRig, intrinsics_from_fov, tag_corners_deck
from ihrcf_env.fast.camera import tag_view
from ihrcf_env.fast.detector import STATUS_DEPTH, STATUS_FRAME_LOST, STATUS_NAMES, detect, detector_params
from ihrcf_env.sim.faults import REASON_FRAME_LOST
from ihrcf_env.sim.sensors.base import TAG_STATUS, tag_status_code
from ihrcf_env.sim.sensors.corner_model import CornerTracks, model_corners
from ihrcf_env.sim.sensors.tag_camera import REASON_DEPTH

from .fast_helpers import Counted, rel_err, rotations

W, H = 640, 480
K = intrinsics_from_fov(W, H, np.radians(60.0))
DIST = np.array([-0.05, 0.01])
CORNERS = tag_corners_deck(0.4)
POINTS = np.vstack([CORNERS, CORNERS * np.array([QUIET_ZONE_SCALE, QUIET_ZONE_SCALE, 1.0]), np.zeros((1, 3))])
OFFSET = np.asarray(SensorRig().camera_position, dtype=np.float64)
MODEL = DetectorModel.load()
VIEW = Counted(
    lambda p, R, dp, dR, pts: tag_view(p, R, dp, dR, pts, OFFSET, K, DIST, 0.01, 10.0),
    in_axes=(0, 0, 0, 0, None),
)


def frames(seed: int, n: int):
    """Views of the tag (full size, then a tenth of it) from near (large, partly outside) to far
    (small), the drone tilted up to 1.2 rad (oblique)."""
    rng = np.random.default_rng(seed)
    out = []
    for scale in (1.0, 0.1):
        R = rotations(rng, n, 1.2)
        dR = rotations(rng, n, 0.2)
        dp = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), rng.uniform(0.5, 1.2, n)])
        p = dp + np.column_stack([rng.uniform(-1.0, 1.0, (n, 2)), rng.uniform(0.25, 9.0, n)])
        v = VIEW(p, R, dp, dR, POINTS * scale)
        keep = np.asarray(v.in_range)
        out.append((np.asarray(v.pixels)[keep], np.asarray(v.quiet)[keep], np.asarray(v.cos_view)[keep]))
    return tuple(np.concatenate(a) for a in zip(*out, strict=True))


def draws(seed: int, n: int):
    rng = np.random.default_rng(seed)
    normals = rng.standard_normal((n, 4, 2))
    uniforms = rng.random(n)
    track = CornerTracks(n)
    track.reset([np.random.default_rng([seed, i]) for i in range(n)])
    return normals, uniforms, track


def test_status_table_is_the_readings() -> None:
    assert STATUS_NAMES == TAG_STATUS
    assert STATUS_FRAME_LOST == tag_status_code(REASON_FRAME_LOST)
    assert STATUS_DEPTH == tag_status_code(REASON_DEPTH)


@pytest.mark.parametrize("quality", ["ideal", "realistic"])
def test_detect_matches_closed_form_model(quality: str) -> None:
    prm = MODEL.params(quality)
    dprm = detector_params(prm)
    c, q, cos_view = frames(3, 2048)
    n = len(c)
    normals, uniforms, track = draws(4, n)
    rng = np.random.default_rng(5)
    cos_view[::7] = rng.uniform(0.0, 0.3, len(cos_view[::7]))  # a grazing view (past the tilt range)
    noise_ratio = rng.uniform(0.0, 0.05, (n, 4)) if quality == "realistic" else np.zeros((n, 4))
    blur = rng.uniform(0.0, 3.0, n) if quality == "realistic" else np.zeros(n)
    want, status = model_corners(prm, c, q, cos_view, W, H, noise_ratio, blur, normals, uniforms, track)
    fn = Counted(lambda *a: detect(dprm, a[0], a[1], a[2], W, H, *a[3:]))
    got, code = fn(c, q, cos_view, noise_ratio, blur, normals, uniforms, track.omega, track.phase)
    assert np.array_equal(np.asarray(code), status)
    counts = np.bincount(status, minlength=len(STATUS_NAMES))
    for s in ("", "tag outside the image", "tag partly outside the image (too close to its border)"):
        assert counts[tag_status_code(s)] > 10, (s, counts)
    for s in (
        "tag too small in the image",
        "tag seen too obliquely",
        "tag's quiet zone cut by the image border",
    ):
        assert counts[tag_status_code(s)] > 3, (s, counts)
    ok = status == 0
    assert rel_err(np.asarray(got)[ok], want[ok]) < 1e-9
    assert np.all(np.isfinite(np.asarray(got)))
    fn(c, q, cos_view, noise_ratio, blur, normals, uniforms, track.omega, track.phase)
    assert fn.traces == 1


def test_detect_matches_scalar_model() -> None:
    """DetectorModel.corners on a few frames, with the same draws and the same episode field."""
    dprm = detector_params(MODEL.params("realistic"))
    c, q, cos_view = frames(7, 64)
    fn = Counted(lambda *a: detect(dprm, a[0], a[1], a[2], W, H, *a[3:]))
    detected = 0
    for i in range(min(len(c), 48)):
        track = CornerTrack(np.random.default_rng([9, i]))
        rng = np.random.default_rng([10, i])
        ahead = copy.deepcopy(rng)
        normals, u = ahead.standard_normal((4, 2)), ahead.random()
        f = tag_features(c[i], q[i], float(cos_view[i]), W, H, 0.02, 0.5)
        want, reason = MODEL.corners(f, rng, "realistic", track)
        got, code = fn(
            c[i : i + 1],
            q[i : i + 1],
            cos_view[i : i + 1],
            np.full((1, 4), 0.02),
            np.full(1, 0.5),
            normals[None],
            np.array([u]),
            track.omega[None],
            track.phase[None],
        )
        assert int(code[0]) == tag_status_code(reason)
        if want is not None:
            detected += 1
            assert rel_err(got[0], want) < 1e-9
    assert detected > 5
