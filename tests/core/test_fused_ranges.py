"""The fused estimator's range-only update (``range_only_update``) and ``drop_lost_track``, on
synthetic sequences of known answer (no simulator; helpers from test_fused)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from test_fused import DEG, HZ, RIG, TAG, K, Pose, simulate, still_deck, touch_pixels

from ihrcf_env.core.estimators import FusedEstimator, FusedParams, SensorFrame
from ihrcf_env.core.estimators.fused_ranges import ranges_plane, ranges_tilt
from ihrcf_env.core.frames import R_BODY_CAM, matrix_from_euler

LOST = (4.0, 4.9)  # the tag out of view (s): shorter than lost_timeout


def heaving_tilting_deck(t: float) -> Pose:
    """A deck heaving 4 cm at 3 s and rolling 4 deg at 4 s, pitching 3 deg at 5 s."""
    w = 2 * math.pi
    rpy = (4 * DEG * math.sin(w * t / 4), 3 * DEG * math.sin(w * t / 5), 0.3)
    return matrix_from_euler(*rpy), np.array([0.0, 0.0, 0.04 * math.sin(w * t / 3 + 1.0)])


def low_drone(t: float) -> Pose:
    return np.eye(3), np.array([0.02, -0.01, 0.6])


def lost(t: float) -> bool:
    return LOST[0] <= t < LOST[1]


def run_with(params: FusedParams, seconds: float = 5.0, sigma_r: float = 0.003, **kw: object):  # type: ignore[no-untyped-def]
    est = FusedEstimator(touch_pixels, RIG, TAG, K, params=params)
    run = simulate(
        seconds,
        heaving_tilting_deck,
        low_drone,
        sigma_r=sigma_r,
        lost=lost,
        estimator=est,
        **kw,  # type: ignore[arg-type]
    )
    return run, est


def tilt_errors(run, rows: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Angle (deg) between the estimated and the true deck normal, per row."""
    out = []
    for k in rows:
        n_est, n_true = run.estimates[k].rotation[:, 2], run.R_true[k][:, 2]
        out.append(math.degrees(math.acos(min(1.0, float(n_est @ n_true)))))
    return np.array(out)


def test_option_is_checked_and_off_by_default() -> None:
    assert FusedParams().range_only_update is False and FusedParams().drop_lost_track is False
    for name in ("range_only_update", "drop_lost_track"):
        with pytest.raises(TypeError, match=name):
            FusedParams(**{name: 1})  # type: ignore[arg-type]


def test_ranges_tilt_inverts_the_euler_angles() -> None:
    R_wb = matrix_from_euler(0.05, -0.08, 1.0)
    for roll, pitch, yaw in ((0.1, -0.05, 0.3), (-0.2, 0.15, -2.5), (0.0, 0.0, 3.0)):
        R_bd = R_wb.T @ matrix_from_euler(roll, pitch, yaw)
        normal = -(R_BODY_CAM.T @ R_bd[:, 2])  # into the deck, camera frame
        assert np.allclose(ranges_tilt(normal, R_wb, yaw), [roll, pitch], atol=1e-12)


def test_ranges_plane_needs_three_valid_ranges() -> None:
    r = np.array([0.5, 0.52, 0.51, 0.49])
    assert ranges_plane(r, np.array([True, False, False, True]), RIG.sensor_xy_cam) is None
    assert ranges_plane(np.array([0.5, np.nan, -1.0, 0.5]), np.ones(4, bool), RIG.sensor_xy_cam) is None
    plane = ranges_plane(r, np.array([True, True, False, True]), RIG.sensor_xy_cam)
    assert plane is not None and plane[1].tolist() == [True, True, False, True] and plane[0][2] > 0.9


def test_range_only_update_tracks_a_heaving_tilting_deck_without_corners() -> None:
    on, _ = run_with(FusedParams(range_only_update=True))
    off, _ = run_with(FusedParams())
    t = np.array([f.time for f in on.frames])
    gap = np.flatnonzero((t >= LOST[0]) & (t < LOST[1]))
    assert on.valid[gap].all() and off.valid[gap].all()  # within lost_timeout both stay valid
    z_on = np.array([abs(on.estimates[k].position[2] - on.p_true[k][2]) for k in gap])
    z_off = np.array([abs(off.estimates[k].position[2] - off.p_true[k][2]) for k in gap])
    tilt_on, tilt_off = tilt_errors(on, gap), tilt_errors(off, gap)
    # the ranges keep the height along the body axis and the tilt; the coasting filter drifts
    assert z_on.max() < 0.006, z_on.max()
    assert z_off[-5:].min() > 3 * z_on.max(), (z_off, z_on)
    assert tilt_on.max() < 2.0, tilt_on.max()
    assert tilt_off[-5:].min() > 3 * tilt_on[-5:].max(), (tilt_off, tilt_on)
    # after the gap the tag is measured again, no reinitialisation
    after = np.flatnonzero(t >= LOST[1] + 0.05)
    assert on.valid[after].all()


def test_lateral_part_still_times_out() -> None:
    """Ranges alone keep the estimate valid only until lost_timeout after the last tag frame."""
    p = FusedParams(range_only_update=True)
    est = FusedEstimator(touch_pixels, RIG, TAG, K, params=p)
    run = simulate(
        6.0, heaving_tilting_deck, low_drone, sigma_r=0.003, lost=lambda t: t >= 4.0, estimator=est
    )
    t = np.array([f.time for f in run.frames])
    last_tag = 3.95
    assert run.valid[(t >= 4.0) & (t - last_tag < p.lost_timeout - 1e-6)].all()
    after = np.flatnonzero(t - last_tag > p.lost_timeout + 1e-6)
    assert not run.valid[after].any()
    assert "tag lost for" in run.estimates[after[0]].reason


def test_diagnostics_name_the_range_only_blocks() -> None:
    p = FusedParams(range_only_update=True)
    est = FusedEstimator(touch_pixels, RIG, TAG, K, params=p)
    run = simulate(
        4.5, heaving_tilting_deck, low_drone, sigma_r=0.003, lost=lambda t: t >= 4.0, estimator=est
    )
    names = [n for n, _ in est.diagnostics["accepted"]]
    assert names == ["ranges.tilt", "ranges.distance"]
    assert 0.5 < est.diagnostics["lateral_coasting"] < 0.6
    assert run.valid[-1]


def test_off_the_old_behaviour_ignores_the_ranges_of_corner_less_frames() -> None:
    """Without the option a frame without corners is a pure IMU prediction: the same outputs with
    its ranges made invalid."""

    def blind(k: int, frame: SensorFrame) -> SensorFrame:
        if frame.corners is None:
            return dataclasses.replace(frame, ranges_valid=np.zeros(4, bool))
        return frame

    a, _ = run_with(FusedParams())
    b, _ = run_with(FusedParams(), corrupt=blind)
    for ea, eb in zip(a.estimates, b.estimates, strict=True):
        assert ea.valid == eb.valid and ea.reason == eb.reason
        assert np.array_equal(ea.position, eb.position) and np.array_equal(ea.rotation, eb.rotation)
    # with the option, the ranges change the outputs of those frames
    c, _ = run_with(FusedParams(range_only_update=True))
    k = int(LOST[0] * HZ) + 5
    assert not np.allclose(a.estimates[k].position, c.estimates[k].position, atol=1e-4)


def test_ranges_off_the_plane_are_not_used() -> None:
    """Four ranges whose plane-fit residual is far beyond the range noise (one beam off the deck)
    give no range-only update."""

    def off_deck(k: int, frame: SensorFrame) -> SensorFrame:
        if frame.corners is None:
            return dataclasses.replace(frame, ranges=frame.ranges + np.array([0.0, 0.0, 0.3, 0.0]))
        return frame

    run, est = run_with(FusedParams(range_only_update=True), seconds=4.2, corrupt=off_deck)
    assert ("ranges.plane", math.inf) in est.diagnostics["rejected"]
    assert not [n for n, _ in est.diagnostics["accepted"]]


def test_lost_track_filter_is_not_coasted_on() -> None:
    """Regression: the deck jumps 10 cm (the filter loses track: every position measurement gated
    out) and the tag leaves the view right after max_rejections frames. The old rule re-initialised
    only in a frame with a measurement, so the output coasted, valid and 10 cm wrong, until
    lost_timeout; with drop_lost_track it turns invalid once the track is lost."""
    jump, n_rej = 4.0, 5

    def deck(t: float) -> Pose:
        R, pos = still_deck(t)
        return R, pos + (np.array([0.0, 0.0, 0.1]) if t >= jump else 0.0)

    def gone(t: float) -> bool:
        return t >= jump + n_rej / HZ

    for drop in (False, True):
        p = FusedParams(max_rejections=n_rej, drop_lost_track=drop)
        est = FusedEstimator(touch_pixels, RIG, TAG, K, params=p)
        run = simulate(4.8, deck, sigma_r=0.005, lost=gone, estimator=est)
        t = np.array([f.time for f in run.frames])
        coast = np.flatnonzero(t >= jump + n_rej / HZ)
        err = run.errors()
        if drop:
            assert not run.valid[coast].any()
            assert run.estimates[coast[0] - 1].reason.startswith("position not initialised")
        else:  # the defect: valid while 10 cm off
            assert run.valid[coast].all()
            assert np.nanmin(err[coast, 2]) > 80.0


def test_reseed_follows_a_jump_that_both_measurements_agree_on() -> None:
    """The deck jumps 10 cm with the tag in view: every position measurement is gated out. Without
    ``reseed_agreeing`` the filter coasts on its wrong prediction until ``max_rejections`` and then
    restarts (invalid while it converges again); with it, IHRCF and ATDA agree, so the position
    restarts at them on the second rejected frame and the output stays valid and right."""
    jump = 4.0

    def deck(t: float) -> Pose:
        R, pos = still_deck(t)
        return R, pos + (np.array([0.0, 0.0, 0.1]) if t >= jump else 0.0)

    assert FusedParams().reseed_agreeing is False
    with pytest.raises(TypeError, match="reseed_agreeing"):
        FusedParams(reseed_agreeing=1)  # type: ignore[arg-type]
    for reseed in (False, True):
        est = FusedEstimator(touch_pixels, RIG, TAG, K, params=FusedParams(reseed_agreeing=reseed))
        run = simulate(5.0, deck, sigma_r=0.005, estimator=est)
        t = np.array([f.time for f in run.frames])
        after = np.flatnonzero(t >= jump + 2.5 / HZ)  # from the third frame after the jump
        err = run.errors()  # per row: position error (mm) in column 2
        if reseed:
            assert run.valid[after].all()
            assert np.nanmax(err[after, 2]) < 10.0
        else:  # coasting 10 cm off, then converging again: wrong or invalid for 0.5 s or more
            wrong = ~run.valid[after] | (np.nan_to_num(err[after, 2], nan=1e9) > 50.0)
            assert wrong.sum() >= 10
