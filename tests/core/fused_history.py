"""Synthetic sensor histories of the fused filter, one per env: deck and drone motion, pixel and
range noise, dropped frames, lost ranges, a lost tag beyond the timeout, outliers, unknown times,
missing IMU samples, camera latency, held frames, a reset mid-sequence (used by the JAX filter's
test, tests/fast/test_fast_fused.py, against the single filter)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
from test_fused import NoisyImu, Pose, observe, paper_like_deck, still_deck
from test_fused_delay import heaving_deck, imu_at, swaying_drone

from ihrcf_env.core.estimators import ImuSample, SensorFrame

HZ = 20.0
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
