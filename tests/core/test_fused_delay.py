"""The fused filter's delay compensation on synthetic sequences (no simulator).

Frames are exposed at 20 Hz and reach the filter ``latency`` s later; the truth is the deck pose in
the body frame at the arrival, the instant the estimate is used.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from test_fused import HZ, RIG, TAG, K, Pose, observe, touch_pixels

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators import FusedEstimator, ImuSample, PoseEstimate, SensorFrame
from ihrcf_env.core.frames import matrix_from_euler, quat_from_matrix

DEG = math.pi / 180


def heaving_deck(t: float) -> Pose:
    """A deck heaving 0.12 m at 3 s and rolling 6 deg at 5 s, swaying 0.05 m at 4 s."""
    w = 2 * math.pi
    rpy = (6 * DEG * math.sin(w * t / 5), 3 * DEG * math.sin(w * t / 7), 0.3)
    p = np.array([0.05 * math.sin(w * t / 4), 0.0, 0.12 * math.sin(w * t / 3)])
    return matrix_from_euler(*rpy), p


def swaying_drone(t: float) -> Pose:
    """A drone drifting 0.1 m at 6 s sideways, tilted accordingly."""
    w = 2 * math.pi
    return matrix_from_euler(0.03 * math.sin(w * t / 6), 0.02, 0.1), np.array(
        [0.0, 0.1 * math.sin(w * t / 6), 1.0]
    )


def imu_at(t: float, drone: Callable[[float], Pose]) -> ImuSample:
    """The ideal IMU sample of the drone at ``t`` (central differences)."""
    h = 1e-3
    R_wb, p_wb = drone(t)
    acc = (drone(t + h)[1] - 2 * p_wb + drone(t - h)[1]) / (h * h)
    dR = (drone(t + h)[0] - drone(t - h)[0]) / (2 * h)
    W = R_wb.T @ dR
    omega = np.array([W[2, 1], W[0, 2], W[1, 0]])
    return ImuSample(quat_from_matrix(R_wb), omega, R_wb.T @ (acc + np.array([0.0, 0.0, GRAVITY])))


def body_pose(t: float, drone: Callable[[float], Pose]) -> Pose:
    R_wd, p_wd = heaving_deck(t)
    R_wb, p_wb = drone(t)
    return R_wb.T @ R_wd, R_wb.T @ (p_wd - p_wb)


def run(
    latency: float,
    mode: str,
    seconds: float = 12.0,
    ranges_lag: float = 0.0,
    seed: int = 0,
    drone: Callable[[float], Pose] = swaying_drone,
) -> tuple[list[PoseEstimate], list[Pose]]:
    """Estimates and truths (at the arrival) of one sequence. ``mode``: ``"compensated"`` (frames
    stamped with their exposure and arrival), ``"arrival"`` (stamped with their arrival, as a filter
    unaware of the delay), ``"plain"`` (no arrival fields: latency must be 0). ``ranges_lag``: the
    ranges are measured this many s before the exposure (and stamped so, except in ``"arrival"``)."""
    rng = np.random.default_rng(seed)
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    out: list[PoseEstimate] = []
    truth: list[Pose] = []
    for k in range(int(round(seconds * HZ)) + 1):
        t_e = k / HZ
        t_a = t_e + latency
        corners, _ = observe(*body_pose(t_e, drone))
        _, ranges = observe(*body_pose(t_e - ranges_lag, drone))
        corners = corners + rng.normal(0, 0.2, (4, 2))
        ranges = ranges + rng.normal(0, 0.003, 4)
        ok = np.ones(4, bool)
        if mode == "arrival":
            frame = SensorFrame(t_a, corners, ranges, ok, imu=imu_at(t_a, drone))
        elif mode == "plain":
            frame = SensorFrame(t_e, corners, ranges, ok, imu=imu_at(t_e, drone))
        else:
            frame = SensorFrame(
                t_e,
                corners,
                ranges,
                ok,
                imu=imu_at(t_e, drone),
                ranges_time=t_e - ranges_lag,
                arrival_time=t_a,
                arrival_imu=imu_at(t_a, drone),
            )
        out.append(est.update(frame))
        truth.append(body_pose(t_a, drone))
    return out, truth


def position_error_mm(estimates: list[PoseEstimate], truth: list[Pose], after: float = 3.0) -> float:
    """Mean |position error| (mm) of the valid estimates from ``after`` s on."""
    errors = [
        float(np.linalg.norm(e.position - p)) * 1000
        for k, (e, (_, p)) in enumerate(zip(estimates, truth, strict=True))
        if e.valid and k / HZ >= after
    ]
    assert len(errors) > 0.9 * (len(estimates) - after * HZ)
    return float(np.mean(errors))


def test_a_60_ms_latency_is_compensated() -> None:
    """On a moving deck, a 60 ms old frame fused as if it were current lags the deck; fused at its
    exposure and predicted to its arrival it does not (errors printed with -s)."""
    with_comp = position_error_mm(*run(0.06, "compensated"))
    without = position_error_mm(*run(0.06, "arrival"))
    no_latency = position_error_mm(*run(0.0, "plain"))
    print(
        f"60 ms latency: compensated {with_comp:.2f} mm, not compensated {without:.2f} mm;"
        f" no latency {no_latency:.2f} mm"
    )
    assert with_comp < 0.5 * without
    assert with_comp < no_latency + 2.0  # close to the filter without any latency


def test_latency_zero_is_bit_identical() -> None:
    """Arrival at the exposure (and ranges at the exposure) change nothing, bit for bit."""
    a, _ = run(0.0, "plain", seconds=4.0)
    b, _ = run(0.0, "compensated", seconds=4.0)
    assert sum(e.valid for e in a) > 40
    for x, y in zip(a, b, strict=True):
        assert x.valid == y.valid and x.reason == y.reason
        assert np.array_equal(x.position, y.position) and np.array_equal(x.rotation, y.rotation)
        assert x.residual == y.residual


def test_ranges_measured_before_the_exposure_are_moved_to_it() -> None:
    """Ranges 25 ms older than the corners, stamped with their time, are moved along the filter's
    relative velocity: the error is below that of treating them as simultaneous."""
    stamped = position_error_mm(*run(0.0, "compensated", ranges_lag=0.025, drone=swaying_drone))
    est, truth = run(0.0, "compensated", ranges_lag=0.0)
    simultaneous = position_error_mm(est, truth)
    # the same lagged ranges without their stamp
    unstamped_est, unstamped_truth = _run_unstamped_lag(0.025)
    unstamped = position_error_mm(unstamped_est, unstamped_truth)
    print(
        f"ranges 25 ms early: stamped {stamped:.2f} mm, unstamped {unstamped:.2f} mm, none {simultaneous:.2f}"
    )
    assert stamped < unstamped


def _run_unstamped_lag(lag: float) -> tuple[list[PoseEstimate], list[Pose]]:
    rng = np.random.default_rng(0)
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    out, truth = [], []
    for k in range(int(round(12.0 * HZ)) + 1):
        t = k / HZ
        corners, _ = observe(*body_pose(t, swaying_drone))
        _, ranges = observe(*body_pose(t - lag, swaying_drone))
        corners = corners + rng.normal(0, 0.2, (4, 2))
        ranges = ranges + rng.normal(0, 0.003, 4)
        out.append(
            est.update(SensorFrame(t, corners, ranges, np.ones(4, bool), imu=imu_at(t, swaying_drone)))
        )
        truth.append(body_pose(t, swaying_drone))
    return out, truth


def test_motion_is_predicted_to_the_arrival() -> None:
    """The deck motion the filter reports after a late frame is the one at the arrival."""
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    for k in range(int(6 * HZ)):
        t = k / HZ
        corners, ranges = observe(*body_pose(t, swaying_drone))
        frame = SensorFrame(
            t,
            corners,
            ranges,
            np.ones(4, bool),
            imu=imu_at(t, swaying_drone),
            arrival_time=t + 0.06,
            arrival_imu=imu_at(t + 0.06, swaying_drone),
        )
        est.update(frame)
    motion = est.motion()
    assert motion is not None
    assert est._ahead is not None and est._ahead[0] is not None
    assert np.array_equal(motion[0], est._ahead[0].x[3:6])
    assert est._pos is not None and not np.array_equal(est._ahead[0].x, est._pos.x)


def test_frame_checks_its_times() -> None:
    ok = np.ones(4, bool)
    with pytest.raises(ValueError, match="arrival_time"):
        SensorFrame(0.0, None, np.ones(4), ok, arrival_time=math.inf)
    with pytest.raises(ValueError, match="ranges_time"):
        SensorFrame(0.0, None, np.ones(4), ok, ranges_time=-math.inf)
    with pytest.raises(TypeError, match="arrival_imu"):
        SensorFrame(0.0, None, np.ones(4), ok, arrival_imu="imu")  # type: ignore[arg-type]
