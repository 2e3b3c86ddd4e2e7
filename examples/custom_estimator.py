"""Add your own deck-pose estimator from user code and see it in the observation.

The toy estimator below back-projects the centroid of the four tag corners at the mean of the valid
ToF ranges: a crude deck position (m, body frame) that assumes a level deck, with no attitude. It is
registered under the name ``"mytoy"`` and then requested like the built-in estimators:

    python examples/custom_estimator.py --steps 100
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import ihrcf_env
from ihrcf_env.core.estimators import PoseEstimate, SensorFrame
from ihrcf_env.core.estimators.registry import EstimatorConfig
from ihrcf_env.core.frames import R_BODY_CAM


class CentroidEstimator:
    """Tag-corner centroid back-projected at the mean valid range (a :class:`DeckPoseSource`)."""

    def __init__(self, config: EstimatorConfig, name: str = "mytoy") -> None:
        self._name = name
        self.K_inv = np.linalg.inv(config.K)  # camera matrix (px) from the calibration file
        self.camera_position = np.asarray(config.rig.camera_position, dtype=np.float64)  # m, body

    @property
    def name(self) -> str:
        return self._name

    def reset(self) -> None:
        """No state to forget: every frame is estimated on its own."""

    def update(self, frame: SensorFrame) -> PoseEstimate:
        if frame.corners is None:
            return PoseEstimate.invalid(frame.corners_reason)
        ranges = frame.ranges[frame.ranges_valid]
        if ranges.size == 0:
            return PoseEstimate.invalid("no valid range")
        u, v = frame.corners.mean(axis=0)
        ray = self.K_inv @ np.array([u, v, 1.0])  # camera frame, z = 1
        p_cam = float(np.mean(ranges)) * ray  # the ranges run along the optical axis (camera z)
        p_body = R_BODY_CAM @ p_cam + self.camera_position
        return PoseEstimate.from_body_pose(np.eye(3), p_body, residual=0.0)  # level deck assumed


def main(argv: list[str] | None = None) -> int:
    """Command line entry point; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=100, help="control steps (20 Hz)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)

    ihrcf_env.register_estimator("mytoy", CentroidEstimator)
    with gym.make("ihrcf_env/DeckHover-v0", estimators=("ihrcf", "mytoy"), camera_model="projected") as env:
        obs, info = env.reset(seed=args.seed)
        errors, valid = [], 0
        for _ in range(args.steps):
            obs, reward, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
            toy = obs["mytoy"]
            if toy["valid"]:
                valid += 1
                errors.append(np.abs(toy["position"] - info["deck_position_body"]))
            if terminated or truncated:
                break
    print(f"obs keys: {sorted(obs)}")
    print(f"mytoy: valid on {valid} of {args.steps} steps", end="")
    if errors:
        mae = 1e3 * np.mean(errors, axis=0)
        print(f", position MAE X {mae[0]:.1f} Y {mae[1]:.1f} Z {mae[2]:.1f} mm")
    else:
        print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
