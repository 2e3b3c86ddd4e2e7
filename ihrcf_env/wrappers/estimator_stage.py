"""The estimator stage of the observation wrappers: raw observations in, deck-pose estimates out.

One :class:`EstimatorStage` per wrapped env. It builds the estimators of an
:class:`~ihrcf_env.envs.config.ObservationConfig` (calibration, names, fused parameters) and turns
each raw observation into a :class:`~ihrcf_env.core.estimators.SensorFrame`: the tag corners (from
``tag_corners``, or detected once in ``image``), the ranges, the IMU sample and the frame's time.
Everything it reads is in the raw observation: a camera frame is new when its ``camera_age`` is 0;
a held frame (``camera_hz`` below the control rate) is not estimated twice. The clock is the
wrapper's own (control steps since reset times the control period, the env's time to the bit).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ihrcf_env.core.calibration import Calibration
from ihrcf_env.core.estimators import (
    DeckPoseEstimator,
    DeckPoseSource,
    FusedParams,
    ImuSample,
    PoseEstimate,
    SensorFrame,
)
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.sim.sensors.base import TAG_STATUS
from ihrcf_env.sim.world import WorldConfig


def _rig(calibration: Calibration) -> SensorRig:
    r = calibration.rig
    cp = r["camera_position"]
    return SensorRig(float(r["a"]), float(r["theta"]), (float(cp[0]), float(cp[1]), float(cp[2])))


def estimator_from_calibration(
    calibration: Calibration,
    tag_size: float,
    tag_id: int,
    max_residual: float = 0.01,
    estimators: tuple[str, ...] | None = None,
    fused_params: FusedParams | None = None,
) -> DeckPoseEstimator:
    """A :class:`DeckPoseEstimator` using a calibration file's table (IHRCF, fused) and chessboard K
    (ATDA, fused)."""
    kwargs: dict[str, Any] = {} if estimators is None else {"estimators": estimators}
    return DeckPoseEstimator(
        rig=_rig(calibration),
        tag_size=tag_size,
        tag_id=tag_id,
        K=calibration.K,
        dist=calibration.dist,
        touch_pixels=calibration.tables,
        max_residual=max_residual,
        fused=fused_params,
        **kwargs,
    )


class EstimatorStage:
    """Estimates of each raw observation (module docstring).

    Attributes:
        estimator: the :class:`DeckPoseEstimator` (detection once per frame + the estimators).
        sources: ordered mapping name -> :class:`DeckPoseSource`.
        last_estimates: name -> :class:`PoseEstimate` of the last observation (None before reset).
        last_frame: the last :class:`SensorFrame` fed to the estimators (None before reset).
        ages: name -> age (s) of the camera frame behind each estimate shown.
        time: the wrapper's clock (s since reset).
    """

    def __init__(
        self,
        world: WorldConfig,
        calibration: Calibration,
        estimators: tuple[str, ...],
        max_residual: float,
        fused_params: FusedParams | None,
    ) -> None:
        deck = world.deck
        self.estimator = estimator_from_calibration(
            calibration, deck.tag_size, deck.tag_id, max_residual, estimators, fused_params
        )
        self.sources: dict[str, DeckPoseSource] = self.estimator.sources
        self._substeps, self._dt = world.substeps, 1.0 / world.physics_hz
        self.reset()

    def reset(self) -> None:
        self.estimator.reset()
        self.last_estimates: dict[str, PoseEstimate] | None = None
        self.last_frame: SensorFrame | None = None
        self.ages: dict[str, float] = {}
        self._steps = 0
        self._frame_time = math.nan  # s, time of the camera frame the estimates come from

    @property
    def time(self) -> float:
        return (self._steps * self._substeps) * self._dt

    def tick(self) -> None:
        """One control step has passed."""
        self._steps += 1

    def frame(self, observation: Mapping[str, Any], time: float) -> SensorFrame:
        """The :class:`SensorFrame` of a raw observation at ``time`` (s)."""
        imu = observation["imu"]
        ranges = observation["ranges"]
        valid = np.asarray(observation["ranges_valid"]).astype(bool)
        sample = ImuSample(imu["quaternion"], imu["angular_velocity"], imu["linear_acceleration"])
        if "image" in observation:
            return self.estimator.frame(observation["image"], ranges, valid, time=time, imu=sample)
        detected = bool(observation["tag_detected"])
        status = int(observation.get("tag_status", 0 if detected else 1))
        reason = TAG_STATUS[status] if 0 < status < len(TAG_STATUS) else "tag not detected"
        return SensorFrame(
            time=time,
            corners=np.asarray(observation["tag_corners"], dtype=np.float64) if detected else None,
            ranges=np.asarray(ranges, dtype=np.float64),
            ranges_valid=valid,
            corners_reason="" if detected else reason,
            imu=sample,
        )

    def update(self, observation: Mapping[str, Any]) -> dict[str, PoseEstimate]:
        """The estimates for a raw observation taken now (:attr:`time`): recomputed on a new camera
        frame (``camera_age`` 0, or no ``camera_age``), held on a repeated one."""
        now = self.time
        age = observation.get("camera_age")
        fresh = self.last_estimates is None or age is None or float(np.asarray(age).reshape(-1)[0]) == 0.0
        if fresh:
            frame = self.frame(observation, now)
            self.last_estimates = self.estimator.update(frame)
            self.last_frame = frame
            self._frame_time = now
        assert self.last_estimates is not None
        self.ages = dict.fromkeys(self.last_estimates, now - self._frame_time)
        return self.last_estimates

    def add_info(self, info: dict[str, Any]) -> None:
        """Each estimate's reason, residual and age into ``info`` (``f"{name}_reason"``, ...)."""
        if self.last_estimates is None:
            return
        for name, est in self.last_estimates.items():
            info[f"{name}_reason"] = est.reason
            info[f"{name}_residual"] = est.residual
            info[f"{name}_age"] = self.ages.get(name, 0.0)
