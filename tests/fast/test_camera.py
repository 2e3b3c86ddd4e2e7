"""The tag's projection through the camera (ihrcf_env.fast.camera) against the closed-form camera's
arithmetic and OpenCV's projectPoints, float64."""

from __future__ import annotations

import cv2
import jax.numpy as jnp
import numpy as np

from ihrcf_env.core.detector_model import QUIET_ZONE_SCALE
from ihrcf_env.core.detector_model.features import project_points
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig, intrinsics_from_fov, tag_corners_deck
from ihrcf_env.fast.camera import tag_view

from .fast_helpers import Counted, rel_err, rotations

K = intrinsics_from_fov(640, 480, np.radians(60.0))
DIST = np.array([-0.05, 0.01])
NEAR, FAR = 0.01, 10.0
CORNERS = tag_corners_deck(0.4)
POINTS = np.vstack([CORNERS, CORNERS * np.array([QUIET_ZONE_SCALE, QUIET_ZONE_SCALE, 1.0]), np.zeros((1, 3))])
OFFSET = np.asarray(SensorRig().camera_position, dtype=np.float64)

VIEW = Counted(lambda p, R, dp, dR: tag_view(p, R, dp, dR, jnp.asarray(POINTS), OFFSET, K, DIST, NEAR, FAR))


def scene(seed: int, n: int):
    rng = np.random.default_rng(seed)
    R = rotations(rng, n, 0.25)
    dR = rotations(rng, n, 0.2)
    dp = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), rng.uniform(0.5, 1.2, n)])
    p = dp + np.column_stack([rng.uniform(-0.4, 0.4, (n, 2)), rng.uniform(0.3, 3.0, n)])
    return p, R, dp, dR


def reference(p, R, dp, dR):
    """The closed-form camera's camera-frame points, depth check and view cosine (numpy)."""
    eye = p + R @ OFFSET
    R_wc = R @ R_BODY_CAM
    pts_w = dp[:, None, :] + POINTS @ dR.transpose(0, 2, 1)
    P = (pts_w - eye[:, None, :]) @ R_wc
    z = P[:, :8, 2]
    in_range = ~((z.min(axis=1) <= NEAR) | (z[:, :4].max(axis=1) >= FAR))
    centre = P[:, 8]
    n_c = np.einsum("ni,nij->nj", dR[:, :, 2], R_wc)
    cos_view = np.abs((n_c * centre).sum(1)) / np.linalg.norm(centre, axis=1)
    return P, in_range, cos_view


def test_projection_matches_reference_and_cv2() -> None:
    p, R, dp, dR = scene(0, 256)
    v = VIEW(p, R, dp, dR)
    P, in_range, cos_view = reference(p, R, dp, dR)
    assert rel_err(v.points, P) < 1e-12
    assert np.array_equal(np.asarray(v.in_range), in_range)
    assert rel_err(v.cos_view, cos_view) < 1e-12
    ok = P[:, :8, 2].min(axis=1) > 0.05
    assert ok.sum() > 200
    for i in np.flatnonzero(ok)[:64]:
        want = project_points(P[i, :8], K, tuple(DIST))
        assert rel_err(np.vstack([v.pixels[i], v.quiet[i]]), want) < 1e-12
        cv, _ = cv2.projectPoints(P[i, :8], np.zeros(3), np.zeros(3), K, np.array([*DIST, 0.0, 0.0]))
        assert rel_err(np.vstack([v.pixels[i], v.quiet[i]]), cv[:, 0]) < 1e-9


def test_depth_edge_cases() -> None:
    """A tag behind the camera or beyond the far plane is out of range; the drone above the tag
    looking straight down sees it centred with cos_view 1."""
    p, R, dp, dR = scene(1, 3)
    R[:] = np.eye(3)
    dR[:] = np.eye(3)
    p[0] = dp[0] + [0.0, 0.0, 1.0]  # level, straight above
    p[1] = dp[1] - [0.0, 0.0, 0.5]  # below the deck: the tag is behind the camera
    p[2] = dp[2] + [0.0, 0.0, FAR + 1.0]  # beyond the far plane
    v = VIEW(p, R, dp, dR)
    assert np.asarray(v.in_range).tolist() == [True, False, False]
    assert abs(float(v.cos_view[0]) - 1.0) < 1e-15
    centre_px = np.asarray(v.pixels[0]).mean(axis=0)
    expected = np.array([K[0, 2], K[1, 2]]) + K[0, 0] * np.array([OFFSET[1], OFFSET[0]]) / (1.0 - OFFSET[2])
    # the camera sits OFFSET off the body origin: the tag centre is offset by f * offset / depth
    assert np.abs(centre_px - expected).max() < 1.0


def test_compiles_once_per_shape() -> None:
    before = VIEW.traces
    for seed in (2, 3, 4):
        VIEW(*scene(seed, 64))
    assert VIEW.traces - before <= 1
    VIEW(*scene(5, 64))
    assert VIEW.traces - before <= 1
