"""Per-frame cost of the single-frame estimators (one call per frame) against the batched ones
(one call for N frames): ``python -m ihrcf_env.core.batch.bench [--repeats R]``.

Frames are random deck poses (1-3 m, tilt up to 0.3 rad, any yaw) seen through the packaged
calibration's camera, with 0.3 px corner noise and 3 mm range noise; the table printed gives
microseconds per frame and the single / batched ratio for each N. The single ATDA is the cv2 path
(:func:`~ihrcf_env.core.estimators.atda.atda_estimate`); the row ``atda-n1`` times the batched code
called once per frame (:func:`~ihrcf_env.core.batch.single.atda_single`) against it (at N = 1
only: both are per frame).
The fused filter (``fused``)
runs :data:`FUSED_STEPS` steps of N envs (each a slowly moving deck under a hovering drone):
N :class:`FusedEstimator` s against one :class:`~ihrcf_env.core.batch.fused.BatchFused`, both
with ATDA (cv2's, the batched PnP), microseconds per env and step.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.batch.fused import BatchFused
from ihrcf_env.core.batch.fused_frames import BatchFrames, stack_frames
from ihrcf_env.core.batch.ihrcf import ihrcf_batch
from ihrcf_env.core.batch.pnp import atda_batch
from ihrcf_env.core.batch.single import atda_single as atda_n1
from ihrcf_env.core.batch.tables import BatchTable
from ihrcf_env.core.calibration import Calibration, default_calibration_path
from ihrcf_env.core.estimators.atda import atda_estimate
from ihrcf_env.core.estimators.base import ImuSample, SensorFrame
from ihrcf_env.core.estimators.fused import FusedEstimator
from ihrcf_env.core.estimators.ihrcf import ihrcf_estimate
from ihrcf_env.core.frames import body_pose_to_cam, matrix_from_euler
from ihrcf_env.core.rig import SensorRig, tag_corners_deck

SIZES = (1, 8, 32, 128)
TAG = 0.4
#: steps of the fused filter's timing (20 Hz)
FUSED_STEPS = 40


def make_frames(
    n: int, cal: Calibration, rig: SensorRig, seed: int = 0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Corners (n, 4, 2) px and ranges (n, 4) m of random deck poses."""
    rng = np.random.default_rng(seed)
    corners, ranges = np.zeros((n, 4, 2)), np.zeros((n, 4))
    for i in range(n):
        eul = rng.uniform(-0.3, 0.3, 3)
        eul[2] = rng.uniform(-math.pi, math.pi)
        h = rng.uniform(1.0, 3.0)
        p = np.array([rng.uniform(-0.1, 0.1) * h, rng.uniform(-0.1, 0.1) * h, -h])
        R_cd, t_cd = body_pose_to_cam(matrix_from_euler(*eul), p, rig.camera_position)
        px, _ = cv2.projectPoints(tag_corners_deck(TAG), cv2.Rodrigues(R_cd)[0], t_cd, cal.K, cal.dist)
        corners[i] = px.reshape(4, 2) + rng.normal(0.0, 0.3, (4, 2))
        nrm = R_cd[:, 2]
        ranges[i] = (nrm @ t_cd - rig.sensor_xy_cam @ nrm[:2]) / nrm[2] + rng.normal(0.0, 0.003, 4)
    return corners, ranges


def _best_time(fn: Callable[[], object], repeats: int) -> float:
    """Fastest of ``repeats`` wall-clock timings of ``fn()``, s."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def run(repeats: int = 5) -> list[tuple[str, int, float, float]]:
    """(estimator, N, single us/frame, batched us/frame) for IHRCF, ATDA and ATDA's batched code at
    N = 1 at each N of :data:`SIZES` (single and batched timings interleaved)."""
    cal = Calibration.load(default_calibration_path())
    rig = SensorRig()
    table = BatchTable(cal.tables)
    corners, ranges = make_frames(max(SIZES), cal, rig)
    ok = np.ones((max(SIZES), 4), dtype=bool)
    rows = []
    for n in SIZES:
        c, r, v, d = corners[:n], ranges[:n], ok[:n], np.ones(n, dtype=bool)

        def ihrcf_single(c=c, r=r, v=v) -> None:
            for i in range(len(c)):
                ihrcf_estimate(c[i], r[i], v[i], cal.tables, rig, TAG)

        def atda_single(c=c) -> None:
            for i in range(len(c)):
                atda_estimate(c[i], cal.K, cal.dist, TAG, rig)

        def atda_batched_n1(c=c) -> None:
            for i in range(len(c)):
                atda_n1(c[i], cal.K, cal.dist, TAG, rig)

        cases = (
            ("ihrcf", ihrcf_single, lambda c=c, r=r, v=v, d=d: ihrcf_batch(c, r, v, d, table, rig, TAG)),
            ("atda", atda_single, lambda c=c, d=d: atda_batch(c, d, cal.K, cal.dist, TAG, rig)),
            ("atda-n1", atda_single, atda_batched_n1),
        )
        for name, single, batched in cases if n == 1 else cases[:2]:
            ts, tb = math.inf, math.inf
            for _ in range(repeats):  # interleaved: a loaded machine slows both alike
                ts = min(ts, _best_time(single, 1) / n * 1e6)
                tb = min(tb, _best_time(batched, 1) / n * 1e6)
            rows.append((name, n, ts, tb))
    return rows


def fused_frames(
    n: int, steps: int, cal: Calibration, rig: SensorRig, seed: int = 0
) -> list[list[SensorFrame]]:
    """``steps`` frames (20 Hz) of n envs: each a deck pose drifting slowly about a random one,
    under a hovering drone with an ideal IMU (outer list: steps)."""
    rng = np.random.default_rng(seed)
    imu = ImuSample(np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.array([0.0, 0.0, 9.81]))
    base = [(rng.uniform(-0.2, 0.2, 3), rng.uniform(1.0, 2.5)) for _ in range(n)]
    out: list[list[SensorFrame]] = []
    for k in range(steps):
        t = k / 20.0
        row = []
        for eul0, h in base:
            eul = eul0 + 0.03 * math.sin(0.5 * t)
            p = np.array([0.05 * h, -0.05 * h, -h + 0.02 * math.sin(0.7 * t)])
            R_cd, t_cd = body_pose_to_cam(matrix_from_euler(*eul), p, rig.camera_position)
            px, _ = cv2.projectPoints(tag_corners_deck(TAG), cv2.Rodrigues(R_cd)[0], t_cd, cal.K, cal.dist)
            nrm = R_cd[:, 2]
            r = (nrm @ t_cd - rig.sensor_xy_cam @ nrm[:2]) / nrm[2] + rng.normal(0.0, 0.003, 4)
            corners = px.reshape(4, 2) + rng.normal(0.0, 0.3, (4, 2))
            row.append(SensorFrame(t, corners, r, np.ones(4, dtype=bool), imu=imu))
        out.append(row)
    return out


def run_fused(repeats: int = 1) -> list[tuple[str, int, float, float]]:
    """("fused", N, single us per env-step, batched us per env-step) at each N of :data:`SIZES`
    (the stacking of the frames into arrays is not timed: a vector env builds them directly)."""
    cal = Calibration.load(default_calibration_path())
    rig = SensorRig()
    table = BatchTable(cal.tables)
    frames = fused_frames(max(SIZES), FUSED_STEPS, cal, rig)
    rows = []
    for n in SIZES:
        seq = [row[:n] for row in frames]
        stacked: list[BatchFrames] = [stack_frames(row) for row in seq]

        def single(seq: list[list[SensorFrame]] = seq, n: int = n) -> None:
            ests = [FusedEstimator(cal.tables, rig, TAG, cal.K, cal.dist) for _ in range(n)]
            for row in seq:
                for est, f in zip(ests, row, strict=True):
                    est.update(f)

        def batched(stacked: list[BatchFrames] = stacked, n: int = n) -> None:
            bf = BatchFused(n, table, rig, TAG, cal.K, cal.dist)
            for fr in stacked:
                bf.update(fr)

        per = n * FUSED_STEPS / 1e6
        rows.append(("fused", n, _best_time(single, repeats) / per, _best_time(batched, repeats) / per))
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timings per case (the fastest is kept)")
    parser.add_argument("--fused-only", action="store_true", help="time the fused filter only")
    args = parser.parse_args(argv)
    print(f"{'estimator':<10}{'N':>5}{'single us/frame':>18}{'batched us/frame':>18}{'single/batched':>16}")
    rows = [] if args.fused_only else run(args.repeats)
    for name, n, ts, tb in rows + run_fused(max(1, args.repeats // 2)):
        print(f"{name:<10}{n:>5}{ts:>18.1f}{tb:>18.1f}{ts / tb:>16.2f}")


if __name__ == "__main__":
    main()

__all__ = [
    "FUSED_STEPS",
    "SIZES",
    "TAG",
    "fused_frames",
    "main",
    "make_frames",
    "run",
    "run_fused",
]
