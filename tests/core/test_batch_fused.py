"""The batched fused filter (ihrcf_env.core.batch.fused) equals N single filters, env by env.

Each env gets its own synthetic history (deck and drone motion, pixel and range noise, dropped
frames, lost ranges, a lost tag beyond the timeout, outliers, unknown times, missing IMU samples,
camera latency, held frames, a reset mid-sequence); the single filters and the batched one are fed
the same frames (and the same ATDA candidates) and every output is compared at every step.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest
from test_fused import RIG, TAG, K, NoisyImu, Pose, observe, paper_like_deck, still_deck, touch_pixels
from test_fused_delay import heaving_deck, imu_at, swaying_drone

from ihrcf_env.core.batch.fused import BatchFused
from ihrcf_env.core.batch.fused_frames import stack_atda_candidates, stack_frames
from ihrcf_env.core.batch.result import FEW_RANGES
from ihrcf_env.core.estimators import FusedEstimator, FusedParams, ImuSample, SensorFrame
from ihrcf_env.core.estimators.atda import atda_candidates

HZ = 20.0
TOL = 1e-9
STEPS = 240


def hover(t: float) -> Pose:
    return np.eye(3), np.array([0.02, -0.01, 1.2])


def _body(deck: Callable[[float], Pose], drone: Callable[[float], Pose], t: float) -> Pose:
    R_wd, p_wd = deck(t)
    R_wb, p_wb = drone(t)
    return R_wb.T @ R_wd, R_wb.T @ (p_wd - p_wb)


def history(env: int, steps: int = STEPS) -> tuple[list[SensorFrame | None], set[int]]:
    """Env ``env``'s frames (None: the env is not stepped: a held frame) and its reset steps."""
    rng = np.random.default_rng(100 + env)
    deck = (still_deck, paper_like_deck, heaving_deck, paper_like_deck, heaving_deck, still_deck)[env % 6]
    drone = swaying_drone if env % 2 else hover
    latency = 0.06 if env in (2, 4) else 0.0
    noisy = NoisyImu(np.random.default_rng(env)) if env in (1, 5) else None
    frames: list[SensorFrame | None] = []
    for k in range(steps):
        t = k / HZ
        if env == 4 and k % 3 == 2:  # held camera frame: not stepped
            frames.append(None)
            continue
        corners, ranges = observe(*_body(deck, drone, t))
        corners = corners + rng.normal(0, 0.2, (4, 2))
        ranges = ranges + rng.normal(0, 0.004, 4)
        valid = np.ones(4, bool)
        if env in (1, 3) and rng.random() < 0.15:  # a lost range
            valid[rng.integers(4)] = False
        if env == 5 and rng.random() < 0.05:  # too few ranges
            valid[:2] = False
        imu = imu_at(t, drone)
        if noisy is not None:
            Rw = drone(t)[0]
            imu = noisy.sample(t, 1 / HZ, Rw, imu.angular_velocity, imu.specific_force)
        det = True
        if env in (1, 4) and rng.random() < 0.1:  # dropped detection
            det = False
        if env == 3 and 60 <= k < 90:  # tag lost 1.5 s > lost_timeout
            det = False
        if env == 5 and k in (70, 71, 72, 73, 130):  # outliers
            corners = corners + np.array([25.0, -15.0])
        frame = SensorFrame(
            t,
            corners if det else None,
            ranges,
            valid,
            corners_reason="" if det else "tag occluded",
            imu=None if (env == 5 and k % 17 == 5) else imu,
        )
        if env == 5 and k == 110:  # a broken IMU sample
            frame = dataclasses.replace(
                frame, imu=ImuSample(imu.quaternion, imu.angular_velocity, [np.nan] * 3)
            )
        if env == 5 and k % 23 == 7:
            frame = dataclasses.replace(frame, time=math.nan)
        if env == 5 and k == 150:  # time going backwards
            frame = dataclasses.replace(frame, time=t - 0.5)
        if latency:
            frame = dataclasses.replace(
                frame,
                time=t - latency,
                ranges_time=t - latency - 0.02,
                arrival_time=t,
                arrival_imu=imu_at(t, drone)
                if k != 100
                else ImuSample(np.zeros(4), np.zeros(3), np.zeros(3)),
            )
        frames.append(frame)
    resets = {150} if env == 3 else ({200} if env == 0 else set())
    return frames, resets


CONFIGS = {
    "default": (FusedParams(), K),
    "options": (
        FusedParams(accel_hold="trapezoid", range_offset_sigma=0.003, refit=False, max_rejections=3),
        K,
    ),
    "ihrcf_only": (FusedParams(use_atda_position=False), None),
    "ranges_only": (FusedParams(range_only_update=True, drop_lost_track=True, max_rejections=3), K),
    "reseed": (FusedParams(reseed_agreeing=True), K),
}


@pytest.mark.parametrize("config", list(CONFIGS))
def test_batched_fused_equals_single_filters(config: str) -> None:
    params, Km = CONFIGS[config]
    n = 6
    hist = [history(e) for e in range(n)]
    singles = [FusedEstimator(touch_pixels, RIG, TAG, Km, params=params) for _ in range(n)]
    batch = BatchFused(n, touch_pixels, RIG, TAG, Km, params=params)
    worst = 0.0
    valid_rows = 0
    reasons_seen: set[str] = set()
    events = {"rejected": 0, "reinitialised": 0}
    few_ranges = 0
    ranges_only = 0  # frames with an accepted range-only update
    reseeds = 0  # frames whose position restarted at agreeing measurements
    for k in range(STEPS):
        resets = np.array([k in hist[e][1] for e in range(n)])
        for e in np.flatnonzero(resets):
            singles[e].reset()
        batch.reset(resets)
        row = [hist[e][0][k] for e in range(n)]
        active = np.array([f is not None for f in row])
        cands = [
            atda_candidates(f.corners, Km, None, TAG, RIG)
            if (f is not None and f.corners is not None and Km is not None)
            else "tag not found"
            for f in row
        ]
        out = batch.update(stack_frames(row), active, stack_atda_candidates(cands))
        for e in np.flatnonzero(active):
            s = singles[e].update(row[e])
            b = out.estimate(e)
            assert s.valid == b.valid, (config, k, e, s.reason, b.reason)
            assert s.reason == b.reason, (config, k, e)
            reasons_seen.add(s.reason)
            few_ranges += int(out.ihrcf_code[e]) == FEW_RANGES
            for key in events:
                events[key] += bool(singles[e].diagnostics.get(key))
            accepted = [name for name, _ in singles[e].diagnostics.get("accepted", [])]
            ranges_only += "ranges.distance" in accepted
            reseeds += "pos (reseeded)" in singles[e].diagnostics.get("reinitialised", [])
            diff = max(
                np.abs(s.position - b.position).max(),
                np.abs(s.rotation - b.rotation).max(),
                np.abs(s.euler - b.euler).max(),
                abs(s.residual - b.residual),
            )
            m = singles[e].motion()
            assert (m is not None) == bool(out.motion_valid[e]), (config, k, e)
            if m is not None:
                diff = max(
                    diff, np.abs(m[0] - out.velocity[e]).max(), np.abs(m[1] - out.normal_rate[e]).max()
                )
            assert diff < TOL, (config, k, e, diff)
            worst = max(worst, diff)
            valid_rows += s.valid
            assert abs(singles[e].range_sigma - batch.range_sigma[e]) < TOL
    print(f"{config}: max |single - batched| = {worst:.3g} over {valid_rows} valid outputs; {events}")
    text = " | ".join(reasons_seen)
    for part in (
        "tag lost for", "tag occluded", "time went backwards", "converging: ", "not initialised",
        "non-finite IMU sample", "arrival zero IMU quaternion",
    ):  # fmt: skip
        assert part in text, part
    assert events["rejected"] > 0 and few_ranges > 0
    assert (ranges_only > 20) == params.range_only_update, ranges_only
    assert (reseeds > 0) == params.reseed_agreeing, reseeds
    assert valid_rows > n * STEPS * 0.4


def test_own_batched_atda_agrees_with_the_cv2_path() -> None:
    """Without given candidates the filter runs the batched PnP, whose LM converges further than
    cv2's: the outputs agree to the ATDA difference, not to rounding."""
    n = 3
    hist = [history(e, 80) for e in range(n)]
    singles = [FusedEstimator(touch_pixels, RIG, TAG, K) for _ in range(n)]
    batch = BatchFused(n, touch_pixels, RIG, TAG, K)
    both = 0
    for k in range(80):
        row = [hist[e][0][k] for e in range(n)]
        out = batch.update(stack_frames(row))
        for e in range(n):
            s = singles[e].update(row[e])  # type: ignore[arg-type]
            if s.valid and out.valid[e]:
                both += 1
                assert np.abs(s.position - out.position[e]).max() < 1e-3
    assert both > 100


def test_frames_must_match_the_batch() -> None:
    batch = BatchFused(2, touch_pixels, RIG, TAG, K)
    with pytest.raises(ValueError, match="2 rows"):
        batch.update(stack_frames([None, None, None]))
