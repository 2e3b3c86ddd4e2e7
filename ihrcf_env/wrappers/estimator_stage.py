"""The estimator stage of the observation wrappers: raw observations in, deck-pose estimates out.

One :class:`EstimatorStage` per wrapped env. It builds the estimators of an
:class:`~ihrcf_env.config.observation.ObservationConfig` (calibration, names, fused parameters) and turns
each raw observation into a :class:`~ihrcf_env.core.estimators.SensorFrame`: the tag corners (from
``tag_corners``, or detected once in ``image``), the ranges, the IMU sample and the frame's time.
Everything it reads is in the raw observation: a camera frame is new when its ``camera_age`` is 0,
or, with a camera latency, when ``camera_frame`` (frames delivered) changes; a held frame
(``camera_hz`` below the control rate) is not estimated twice. The clock is the wrapper's own
(control steps since reset times the control period, the env's time to the bit).

Timestamps (camera latency, ``CameraConfig.latency`` > 0): a frame's time is its exposure (the
observation's time minus ``camera_age``), its IMU sample the one observed at that step, its
ranges the observed ones measured nearest to the exposure (``tof_age``: when the ToF runs on its
own clock), and its ``arrival_time`` / ``arrival_imu`` the observation's (see
:class:`~ihrcf_env.core.estimators.SensorFrame`): the fused filter fuses the frame at its exposure
and predicts its output to the arrival. ``compensate_latency=False`` stamps frames with their
arrival instead (as without latency). Each estimate's age is the age of the exposure behind it.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from ihrcf_env.config.observation import ObservationConfig
from ihrcf_env.config.world import WorldConfig
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
from ihrcf_env.sim.sensors.timing import NO_FRAME_YET


class _Step(NamedTuple):
    """What one observation shows of the fast sensors, for the frames exposed at its step."""

    time: float  # s
    imu: ImuSample
    ranges: np.ndarray
    ranges_valid: np.ndarray
    ranges_time: float  # s


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
        ages: name -> age (s) since the exposure of the camera frame behind each estimate shown
            (NaN before the first frame arrives).
        time: the wrapper's clock (s since reset).
        compensate_latency: stamp frames with their exposure time (module docstring; default
            True, no effect without a camera latency).
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
        self.calibration = calibration
        self._substeps, self._dt = world.substeps, 1.0 / world.physics_hz
        self.latency = world.camera.latency if world.camera is not None else 0.0
        self.compensate_latency = True
        # the observations of the last latency + one camera period (+ margin), for the exposures
        span = self.latency + world.camera_every / world.control_hz
        self._steps_kept = math.ceil(span * world.control_hz) + 2
        self.reset()

    @classmethod
    def for_world(cls, world: WorldConfig, observation: ObservationConfig) -> EstimatorStage:
        """The stage of an env's ``world`` for its resolved ``observation``
        (:func:`~ihrcf_env.config.observation.resolve_observation`: the calibration loaded and matched
        to the camera, the fused parameters chosen). ValueError for a raw observation."""
        if observation.raw or observation.calibration is None:
            raise ValueError(
                "the estimator stage needs a resolved, non-raw observation config "
                "(ihrcf_env.config.observation.resolve_observation)"
            )
        return cls(
            world,
            observation.calibration,
            observation.estimators,
            observation.max_residual,
            observation.fused_params,
        )

    def reset(self) -> None:
        self.estimator.reset()
        self.last_estimates: dict[str, PoseEstimate] | None = None
        self.last_frame: SensorFrame | None = None
        self.ages: dict[str, float] = {}
        self._steps = 0
        self._frame_time = math.nan  # s, time of the camera frame the estimates come from
        self._frame_count = -1  # ``camera_frame`` of the last frame estimated
        self._history: deque[_Step] = deque(maxlen=self._steps_kept)
        self._pending: tuple[SensorFrame, float] | None = None  # prepare's frame, its time (s)

    @property
    def time(self) -> float:
        return (self._steps * self._substeps) * self._dt

    def tick(self) -> None:
        """One control step has passed."""
        self._steps += 1

    def frame(
        self, observation: Mapping[str, Any], time: float, exposure: float | None = None
    ) -> SensorFrame:
        """The :class:`SensorFrame` of a raw observation at ``time`` (s); ``exposure``: the time (s)
        of its camera frame when earlier (a camera latency: see the module docstring)."""
        imu = observation["imu"]
        sample = ImuSample(imu["quaternion"], imu["angular_velocity"], imu["linear_acceleration"])
        ranges, valid = observation["ranges"], observation["ranges_valid"]
        if exposure is None or exposure >= time or not self.compensate_latency:
            return self._frame(observation, time, sample, ranges, valid)
        # a late frame: the IMU sample of the exposure's step, the ranges measured nearest to it
        steps = self._history
        at = min(steps, key=lambda s: abs(s.time - exposure)) if steps else None
        near = min(steps, key=lambda s: abs(s.ranges_time - exposure)) if steps else None
        ranges_time = time
        if near is not None:
            ranges, valid, ranges_time = near.ranges, near.ranges_valid, near.ranges_time
        f = self._frame(observation, exposure, at.imu if at is not None else sample, ranges, valid)
        return dataclasses.replace(f, ranges_time=ranges_time, arrival_time=time, arrival_imu=sample)

    def _frame(
        self, observation: Mapping[str, Any], time: float, imu: ImuSample, ranges: Any, valid: Any
    ) -> SensorFrame:
        """The frame of the observation's camera frame (detected once in its image, or its
        corners) at ``time`` with ``imu`` and the ``ranges`` (m) / ``valid`` given."""
        valid = np.asarray(valid).astype(bool)
        if "image" in observation:
            return self.estimator.frame(observation["image"], ranges, valid, time=time, imu=imu)
        detected = bool(observation["tag_detected"])
        status = int(observation.get("tag_status", 0 if detected else 1))
        reason = TAG_STATUS[status] if 0 < status < len(TAG_STATUS) else "tag not detected"
        return SensorFrame(
            time=time,
            corners=np.asarray(observation["tag_corners"], dtype=np.float64) if detected else None,
            ranges=np.asarray(ranges, dtype=np.float64),
            ranges_valid=valid,
            corners_reason="" if detected else reason,
            imu=imu,
        )

    def _record(self, observation: Mapping[str, Any], now: float) -> None:
        """Keep what this observation shows of the IMU and the ranges (camera latency only)."""
        imu = observation["imu"]
        tof_age = observation.get("tof_age")
        ranges_time = now if tof_age is None else self._on_tick(now - float(np.asarray(tof_age).ravel()[0]))
        self._history.append(
            _Step(
                now,
                ImuSample(imu["quaternion"], imu["angular_velocity"], imu["linear_acceleration"]),
                np.asarray(observation["ranges"], dtype=np.float64).copy(),
                np.asarray(observation["ranges_valid"]).astype(bool),
                ranges_time,
            )
        )

    def _on_tick(self, t: float) -> float:
        """``t`` (s) rounded to the physics tick (the observation's ages are float32)."""
        return round(t / self._dt) * self._dt

    def update(self, observation: Mapping[str, Any]) -> dict[str, PoseEstimate]:
        """The estimates for a raw observation taken now (:attr:`time`): recomputed on a new camera
        frame (``camera_age`` 0, a new ``camera_frame``, or no ``camera_age``), held on a repeated
        one. The same as :meth:`prepare`, the estimator's ``update`` of its frame, :meth:`finish`."""
        frame = self.prepare(observation)
        return self.finish(None if frame is None else self.estimator.update(frame))

    def prepare(self, observation: Mapping[str, Any]) -> SensorFrame | None:
        """The frame the estimators take for a raw observation taken now, or None when its camera
        frame is one already estimated (held). Give the estimates of the frame to :meth:`finish`."""
        now = self.time
        age = observation.get("camera_age")
        count = observation.get("camera_frame")
        if self.latency > 0:
            self._record(observation, now)
        exposure: float | None = None
        if count is not None:  # a camera latency: frames counted, stamped with their exposure
            n = int(np.asarray(count).ravel()[0])
            fresh = self.last_estimates is None or n != self._frame_count
            self._frame_count = n
            if fresh and n > 0 and age is not None:
                exposure = self._on_tick(now - float(np.asarray(age).ravel()[0]))
        else:
            fresh = self.last_estimates is None or age is None or float(np.asarray(age).reshape(-1)[0]) == 0.0
        self._pending = None
        if not fresh:
            return None
        if count is not None and exposure is None:  # no frame has arrived yet
            frame = dataclasses.replace(
                self.frame(observation, now), corners=None, corners_reason=NO_FRAME_YET
            )
            frame_time = math.nan
        else:
            frame = self.frame(observation, now, exposure)
            frame_time = exposure if exposure is not None and not self.compensate_latency else frame.time
        self._pending = (frame, frame_time)
        return frame

    def finish(self, estimates: dict[str, PoseEstimate] | None) -> dict[str, PoseEstimate]:
        """Take the ``estimates`` of the frame :meth:`prepare` returned (None when it returned
        None: the last estimates are held) and return the estimates shown now."""
        pending, self._pending = self._pending, None
        if (pending is None) != (estimates is None):
            raise RuntimeError("finish: estimates must be given exactly when prepare returned a frame")
        if pending is not None:
            self.last_frame, self._frame_time = pending
            self.last_estimates = estimates
        assert self.last_estimates is not None
        self.ages = dict.fromkeys(self.last_estimates, self.time - self._frame_time)
        return self.last_estimates

    def add_info(self, info: dict[str, Any]) -> None:
        """Each estimate's reason, residual and age into ``info`` (``f"{name}_reason"``, ...)."""
        if self.last_estimates is None:
            return
        for name, est in self.last_estimates.items():
            info[f"{name}_reason"] = est.reason
            info[f"{name}_residual"] = est.residual
            info[f"{name}_age"] = self.ages.get(name, 0.0)


__all__ = [
    "EstimatorStage",
    "estimator_from_calibration",
]
