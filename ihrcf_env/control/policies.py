"""Baseline policies on the flat observation of ``ihrcf_env/DeckLanding-v1`` (pure: numpy only).

A policy has ``reset()`` (episode start) and ``act(obs) -> action`` (velocity action in
[-1, 1]^4). The observation's layout is passed in as two mappings, ``slices`` (name -> slice) and
``scales`` (name -> scale: physical value = observation value * scale), as the v1 wrapper exposes
them (``env.get_wrapper_attr("obs_slices")``, ``"obs_scales"``; :mod:`ihrcf_env.wrappers.landing_obs`),
so the same code runs on a vector built from a real drone's sensing.

* :class:`BlindDescent`: constant descent, no lateral command (the baseline a task where sensing
  matters must defeat).
* :class:`ScriptedLanding`: :class:`~ihrcf_env.control.landing.LandingController` on the v1
  observation (one deck-pose estimate, the ToF ranges, the IMU; never ground truth), with
  :data:`V1_LANDING_CONFIG`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.control.landing import LandingConfig, LandingController
from ihrcf_env.core.checks import check_real, check_reals
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.rig import SensorRig

#: The landing controller's tunables on v1: starts up to 3 m high, beyond the ToF's reach in ambient
#: light and where its cones straddle the deck's edge, so the height comes from the estimate until
#: the ranges agree with it; a higher hold (0.75 m: the tag stays in view with the drone leaning
#: into the wind) and a climb when the tag is lost before the drop; a heave estimate that is forgotten
#: without ranges and clipped to 0.3 m/s (a glimpse of the ranges high up must not make the drone
#: chase a phantom heave); no heading alignment (the task
#: does not need it, and in gusts the autopilot's mixer drops yaw when a motor saturates, so a yaw
#: command can run away).
V1_LANDING_CONFIG = LandingConfig(
    estimate_height=True,
    k_yaw=0.0,
    hold_height=0.75,
    reacquire_speed=0.2,
    heave_timeout=0.5,
    max_deck_velocity=0.3,
)

#: The landing controller's tunables on v2 (:data:`V1_LANDING_CONFIG` plus the options for leaning
#: into a 8-15 m/s wind): the tag held on the camera's axis rather than straight below, the commit
#: gated on the tilt relative to the drone's own lean (v2 allows 20 deg at touchdown) with gates
#: for that limit, deck normals from the ToF only when all four beams are on the deck, a looser
#: centring tolerance in gusts, a lost tag dead-reckoned on the autopilot's velocity through the
#: last part of the drop, and the ToF height kept over a disagreeing estimate when all four beams
#: lie on the deck. The heading follows the tag's (the square tag's edges along the image's, so
#: the tag stays in the view lower down), and the heave is hardly fed forward (0.05 m/s at most): a
#: Froude-scaled ship deck heaves with periods near a second, and its filtered velocity lags it by
#: a quarter period, so feeding it forward makes the touchdown harder, not softer.
V2_LANDING_CONFIG = dataclasses.replace(
    V1_LANDING_CONFIG,
    k_yaw=1.0,
    max_deck_velocity=0.05,
    axis_centring=True,
    relative_tilt=True,
    full_plane_tilt=True,
    dead_reckon=2.0,
    dead_reckon_nav=True,
    trust_full_plane=True,
    commit_tilt=math.radians(17.0),
    max_tilt_now=math.radians(19.0),
    centred_tolerance=0.08,
    hold_height=1.0,
    touch_speed=0.2,
    height_tolerance=0.12,
)
#: The scripted landing's tunables per landing task.
LANDING_CONFIGS: dict[str, LandingConfig] = {"landing-v1": V1_LANDING_CONFIG, "landing-v2": V2_LANDING_CONFIG}


class Policy(Protocol):
    """What :mod:`ihrcf_env.cli.evaluate` runs."""

    def reset(self) -> None:
        """Episode start."""

    def act(self, obs: NDArray[np.float32]) -> NDArray[np.float32]:
        """Action in [-1, 1]^4 for one observation."""
        ...


def _max_velocity(max_velocity: Sequence[float]) -> NDArray[np.float64]:
    """The env's action scale (m/s, m/s, m/s, rad/s), each in [1e-3, 100]."""
    return np.array(
        check_reals("max_velocity", max_velocity, 4, "m/s, m/s, m/s, rad/s", low=1e-3, high=100.0)
    )


class BlindDescent:
    """Descend at ``vz`` m/s (> 0) with no lateral and no yaw command."""

    def __init__(self, vz: float, max_velocity: Sequence[float] = (1.0, 1.0, 1.0, 1.0)) -> None:
        mv = _max_velocity(max_velocity)
        self.vz = check_real(
            "vz", vz, "m/s, at most the env's max_velocity[2]", low=0.0, low_open=True, high=mv[2]
        )
        self._action = np.array([0.0, 0.0, -self.vz / mv[2], 0.0], dtype=np.float32)

    def reset(self) -> None:
        pass

    def act(self, obs: NDArray[np.float32]) -> NDArray[np.float32]:
        return self._action.copy()


def level_from_up(up: NDArray[np.float64]) -> NDArray[np.float64]:
    """Level-heading-from-body rotation (roll and pitch only) for the world up axis ``up`` seen in
    the body frame (the third row of the world-from-body rotation)."""
    u = up / max(float(np.linalg.norm(up)), 1e-9)
    pitch = math.asin(max(-1.0, min(1.0, -float(u[0]))))
    roll = math.atan2(float(u[1]), float(u[2]))
    cp, sp, cr, sr = math.cos(pitch), math.sin(pitch), math.cos(roll), math.sin(roll)
    Ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return Ry @ Rx


class ScriptedLanding:
    """The scripted landing (:class:`LandingController`) on the v1 flat observation.

    Args:
        slices, scales: the observation layout (module docstring).
        control_hz: the env's control rate (Hz).
        max_velocity: the env's velocity action scale.
        rig: the drone's ToF/camera geometry.
        config: the controller's tunables (default :data:`V1_LANDING_CONFIG`).
        estimator: the deck-pose estimate to fly on (``"fused"``: valid high up under the realistic
            preset, where IHRCF's ranges are not).
    """

    def __init__(
        self,
        slices: Mapping[str, slice],
        scales: Mapping[str, float],
        control_hz: int = 20,
        max_velocity: Sequence[float] = (1.0, 1.0, 1.0, 1.0),
        rig: SensorRig | None = None,
        config: LandingConfig | None = None,
        estimator: str = "fused",
    ) -> None:
        need: tuple[str, ...] = ("ranges", "ranges_valid", "imu.up", "imu.linear_acceleration")
        need += tuple(f"{estimator}.{f}" for f in ("position", "normal", "yaw", "valid"))
        missing = [n for n in need if n not in slices or n not in scales]
        if missing:
            raise ValueError(
                f"the observation layout lacks {missing} (estimator {estimator!r}): ScriptedLanding needs "
                "the v1 observation (ihrcf_env/DeckLanding-v1) with that estimator"
            )
        self.slices, self.scales, self.estimator = dict(slices), dict(scales), estimator
        #: fly the altitude filter on the autopilot's vertical velocity (``nav_velocity``) rather than
        #: on the integrated accelerometer
        self.use_nav_velocity = "nav_velocity" in slices and "nav_velocity" in scales
        self.controller = LandingController(
            control_hz,
            tuple(_max_velocity(max_velocity).tolist()),
            rig,
            config if config is not None else V1_LANDING_CONFIG,
        )

    @classmethod
    def from_env(
        cls, env: Any, estimator: str = "fused", config: LandingConfig | None = None
    ) -> ScriptedLanding:
        """The scripted landing for a v1 env (Gymnasium, duck-typed): its observation layout
        (``obs_slices`` / ``obs_scales``), control rate, action scale and rig; ``config`` as in the
        constructor. AttributeError if ``env`` has no v1 observation layout."""
        base = env.unwrapped
        if config is None:
            config = LANDING_CONFIGS.get(str(getattr(base, "task_name", "")), V1_LANDING_CONFIG)
        return cls(
            env.get_wrapper_attr("obs_slices"),
            env.get_wrapper_attr("obs_scales"),
            int(base.config.world.control_hz),
            tuple(float(v) for v in getattr(base, "max_velocity", np.ones(4))),
            base.rig,
            config,
            estimator,
        )

    def _get(self, obs: NDArray[np.float32], name: str) -> NDArray[np.float64]:
        return np.asarray(obs[self.slices[name]], dtype=np.float64) * self.scales[name]

    def reset(self) -> None:
        self.controller.reset()

    @property
    def commit_time(self) -> float | None:
        """Simulated s (from the episode start) when the controller committed to the drop."""
        return self.controller.commit_time

    def act(self, obs: NDArray[np.float32]) -> NDArray[np.float32]:
        up = self._get(obs, "imu.up")
        R_lb = level_from_up(up)
        accel_z = float(up @ self._get(obs, "imu.linear_acceleration")) - GRAVITY
        e = self.estimator
        tag_level = tag_yaw = tag_normal = None
        if float(obs[self.slices[f"{e}.valid"]][0]) > 0.5:
            tag_level = self._get(obs, f"{e}.position")
            tag_normal = self._get(obs, f"{e}.normal")
            c, s = self._get(obs, f"{e}.yaw")
            tag_yaw = math.atan2(s, c)
        m = self.controller.measure_level(
            R_lb,
            accel_z,
            tag_level,
            tag_yaw,
            tag_normal,
            self._get(obs, "ranges"),
            self._get(obs, "ranges_valid") > 0.5,
            float(self._get(obs, "nav_velocity")[2]) if self.use_nav_velocity else None,
            self._get(obs, "nav_velocity")[:2] if self.use_nav_velocity else None,
        )
        return self.controller.act_measured(m)


__all__ = [
    "LANDING_CONFIGS",
    "V1_LANDING_CONFIG",
    "V2_LANDING_CONFIG",
    "BlindDescent",
    "Policy",
    "ScriptedLanding",
    "level_from_up",
]
