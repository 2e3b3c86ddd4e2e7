"""A scripted landing that commits to a touchdown window the deck-motion forecast predicts quiet.

:class:`ForecastLanding` is :class:`~ihrcf_env.control.policies.ScriptedLanding` (the v2 landing
controller on the fused estimate) whose commit decision reads the deck-motion forecast of the
observation (``deck_forecast``: the ``forecast.*`` fields, fed by the fused estimate, never the
truth) instead of extrapolating the deck's motion now:

1. **approach** and **hold** as the scripted landing: centre on the tag and hold ``hold_height``
   above the deck, leaning into the wind.
2. **commit**: each step in the hold, the arrival time of a drop from the current height is
   estimated from the descent profile (:meth:`LandingController.drop_duration`); the drop is
   committed when, at every one of ``points`` times spread over ``arrival`` +- ``arrival_spread``,
   the forecast relative tilt between the deck normal and the drone's own (low-passed) up axis,
   plus ``k_sigma`` of its standard deviation, stays below ``max_tilt``, and the relative vertical
   speed (the drone's touchdown speed plus the forecast heave rate, plus ``k_sigma`` of its
   standard deviation) below ``max_speed`` (:func:`check_window`).
3. **abort**: in the drop, while the clearance is above ``abort_clearance``, the same check on the
   remaining time with ``k_abort`` sends the drone back to the hold (at most ``max_aborts`` times).

A forecast is used only when ``forecast.valid`` is set and its tilts and their standard
deviations are plausible (``max_forecast_tilt``, ``max_forecast_std``). Without a usable forecast
the drone waits; from ``fallback_time`` s after the episode start it decides as the scripted
landing does (the deck's motion now). From ``late_time`` s, ``k_late`` replaces ``k_sigma``.

Frames: the forecast's roll and pitch are the deck normal's rotations about the drone's heading
frame's x and y (``n`` along ``(tan pitch, -tan roll, 1)``); the drone's up axis is the
controller's low-passed lean in the same level heading frame.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.control.landing import LandingConfig, LandingController, Measurement
from ihrcf_env.control.policies import V2_LANDING_CONFIG, ScriptedLanding
from ihrcf_env.core.checks import check_int, check_real, from_fields, set_field
from ihrcf_env.core.rig import SensorRig

__all__ = [
    "FORECAST_HORIZONS",
    "FORECAST_POLICY_OPTIONS",
    "ForecastCommitConfig",
    "ForecastLanding",
    "ForecastLandingController",
    "WindowCheck",
    "check_window",
    "forecast_commit_config",
    "relative_tilt",
]

#: Forecast horizons (s) the policy asks of the observation: every 0.25 s up to 4 s.
FORECAST_HORIZONS: tuple[float, ...] = tuple(0.25 * i for i in range(1, 17))
#: The ``deck_forecast`` option of the env the policy flies in.
FORECAST_POLICY_OPTIONS: dict[str, Any] = {"horizons": FORECAST_HORIZONS}

_FIELDS = ("heave_rate", "roll", "pitch")
_BOUNDS: dict[str, tuple[float, float, str]] = {
    "max_tilt": (0.0, math.pi / 2, "rad"),
    "max_speed": (0.0, 10.0, "m/s"),
    "k_sigma": (0.0, 10.0, ""),
    "k_late": (0.0, 10.0, ""),
    "k_abort": (0.0, 10.0, ""),
    "abort_margin": (0.0, math.pi / 2, "rad"),
    "arrival_spread": (0.0, 5.0, "s"),
    "abort_clearance": (0.0, 10.0, "m"),
    "fallback_time": (0.0, 1e4, "s"),
    "late_time": (0.0, 1e4, "s"),
    "max_forecast_tilt": (0.0, math.pi / 2, "rad"),
    "max_forecast_std": (0.0, math.pi / 2, "rad"),
}


@dataclass(frozen=True)
class ForecastCommitConfig:
    """Tunables of the forecast commit rule (module docstring; m, s, rad)."""

    max_tilt: float = math.radians(19.0)  # forecast relative tilt allowed at touchdown (+ k sigma)
    max_speed: float = 0.45  # forecast relative vertical speed allowed at touchdown (+ k sigma)
    k_sigma: float = 0.5  # standard deviations of margin
    k_late: float = 0.0  # margin from late_time on
    k_abort: float = 0.0  # margin of the abort check in the drop
    abort_margin: float = math.radians(2.0)  # the abort needs max_tilt exceeded by this much
    arrival_spread: float = 0.3  # s either side of the estimated arrival time
    points: int = 5  # times checked over the arrival window
    abort_clearance: float = 0.35  # m of clearance below which the drop is never aborted
    max_aborts: int = 2
    fallback_time: float = 22.0  # s from the episode start: decide on the motion now without a forecast
    late_time: float = 18.0  # s from the episode start: k_late replaces k_sigma
    max_forecast_tilt: float = math.radians(15.0)  # a forecast tilting the deck more is not used
    max_forecast_std: float = math.radians(6.0)  # nor one this uncertain

    def __post_init__(self) -> None:
        for attr, (low, high, unit) in _BOUNDS.items():
            v = check_real(f"ForecastCommitConfig.{attr}", getattr(self, attr), unit, low=low, high=high)
            set_field(self, attr, v)
        set_field(self, "points", check_int("ForecastCommitConfig.points", self.points, low=1, high=64))
        set_field(
            self, "max_aborts", check_int("ForecastCommitConfig.max_aborts", self.max_aborts, low=0, high=100)
        )


def forecast_commit_config(value: ForecastCommitConfig | Mapping[str, Any] | None) -> ForecastCommitConfig:
    """A :class:`ForecastCommitConfig` from itself, a dict of its fields or None (the defaults)."""
    return from_fields("forecast_commit", ForecastCommitConfig, value if value is not None else {})


def relative_tilt(roll: ArrayLike, pitch: ArrayLike, up: ArrayLike) -> NDArray[np.float64]:
    """Angle (rad) between the deck normal of ``roll``, ``pitch`` (rad, about the level heading
    frame's x and y) and the drone's up axis ``up`` (3, level heading frame, any length)."""
    r, p = np.asarray(roll, dtype=np.float64), np.asarray(pitch, dtype=np.float64)
    n = np.stack([np.tan(p), -np.tan(r), np.ones_like(r)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    u = np.asarray(up, dtype=np.float64)
    u = u / max(float(np.linalg.norm(u)), 1e-12)
    return np.asarray(np.arccos(np.clip(n @ u, -1.0, 1.0)))


@dataclass(frozen=True)
class WindowCheck:
    """The outcome of :func:`check_window`: ``ok``; the largest relative tilt (rad) and relative
    vertical speed (m/s) over the window, margins included."""

    ok: bool
    tilt: float
    speed: float


def check_window(
    horizons: ArrayLike,
    mean: ArrayLike,
    std: ArrayLike,
    up: ArrayLike,
    arrival: float,
    touch_speed: float,
    config: ForecastCommitConfig,
    k: float | None = None,
    max_tilt: float | None = None,
) -> WindowCheck:
    """Whether the forecast touchdown window around ``arrival`` s from now is inside the limits.

    ``horizons`` (H,) s, increasing; ``mean`` and ``std`` (H, 4) of heave (m), heave rate (m/s),
    roll and pitch (rad, the level heading frame); ``up`` the drone's up axis (3, level heading
    frame); ``touch_speed`` (m/s) the drone's descent speed at touchdown. At ``config.points`` times
    over ``arrival`` +- ``config.arrival_spread`` (clipped to the horizons) the relative tilt plus
    ``k`` (default ``config.k_sigma``) standard deviations must stay below ``max_tilt`` (default
    ``config.max_tilt``), and ``touch_speed`` plus the heave rate plus ``k`` of its standard
    deviation below ``config.max_speed``.
    """
    h = np.asarray(horizons, dtype=np.float64).reshape(-1)
    m = np.asarray(mean, dtype=np.float64).reshape(h.size, 4)
    s = np.asarray(std, dtype=np.float64).reshape(h.size, 4)
    kk = config.k_sigma if k is None else float(k)
    limit = config.max_tilt if max_tilt is None else float(max_tilt)
    spread = config.arrival_spread
    times = np.clip(np.linspace(arrival - spread, arrival + spread, config.points), h[0], h[-1])

    def at(col: int, arr: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.interp(times, h, arr[:, col])

    roll, pitch = at(2, m), at(3, m)
    sr, sp = at(2, s), at(3, s)
    tilt = relative_tilt(roll, pitch, up)
    eps = 1e-4  # rad: the tilt's sensitivity to roll and pitch, by finite differences
    d_r = (relative_tilt(roll + eps, pitch, up) - tilt) / eps
    d_p = (relative_tilt(roll, pitch + eps, up) - tilt) / eps
    sigma = np.sqrt((d_r * sr) ** 2 + (d_p * sp) ** 2)
    tilt_hi = float(np.max(tilt + kk * sigma))
    rate, rate_s = at(1, m), at(1, s)
    speed_hi = float(np.max(touch_speed + rate + kk * rate_s))
    ok = bool(tilt_hi < limit and speed_hi < config.max_speed)
    return WindowCheck(ok, tilt_hi, speed_hi)


@dataclass
class _Forecast:
    """The forecast of one observation (physical units, level heading frame)."""

    mean: NDArray[np.float64]
    std: NDArray[np.float64]
    valid: bool


class ForecastLandingController(LandingController):
    """:class:`LandingController` whose commit (and abort) follow the forecast (module docstring).

    Set :attr:`forecast` (``(mean, std, valid)`` at :attr:`horizons`) before each
    :meth:`act_measured`.

    Args:
        horizons: the forecast's horizons (s).
        commit: the forecast commit rule's tunables.
        others: as :class:`LandingController`.
    """

    def __init__(
        self,
        horizons: Sequence[float],
        control_hz: int = 20,
        max_velocity: Sequence[float] = (1.0, 1.0, 1.0, 1.0),
        rig: SensorRig | None = None,
        config: LandingConfig | None = None,
        commit: ForecastCommitConfig | None = None,
        estimator: str = "fused",
    ) -> None:
        h = np.asarray(horizons, dtype=np.float64).reshape(-1)
        if h.size < 2 or not np.all(np.isfinite(h)) or np.any(np.diff(h) <= 0) or h[0] <= 0:
            raise ValueError(f"horizons must be 2 or more increasing positive times (s), got {horizons!r}")
        self.horizons = h
        self.commit = commit if commit is not None else ForecastCommitConfig()
        self.forecast: _Forecast | None = None
        super().__init__(control_hz, max_velocity, rig, config, estimator)

    def reset(self) -> None:
        super().reset()
        self.forecast = None
        self.aborts = 0
        #: the last window check in the hold or the drop (None: none yet)
        self.last_check: WindowCheck | None = None

    def usable(self) -> bool:
        """True when the forecast is valid and plausible (finite, tilts and their standard
        deviations within ``max_forecast_tilt`` / ``max_forecast_std``)."""
        f, c = self.forecast, self.commit
        if f is None or not f.valid:
            return False
        if not (np.all(np.isfinite(f.mean)) and np.all(np.isfinite(f.std))):
            return False
        return bool(
            np.max(np.abs(f.mean[:, 2:4])) <= c.max_forecast_tilt
            and np.max(f.std[:, 2:4]) <= c.max_forecast_std
        )

    def up_axis(self) -> NDArray[np.float64]:
        """The drone's low-passed up axis in the level heading frame."""
        return np.array([self.lean[0], self.lean[1], self.lean_z])

    def window(self, arrival: float, k: float | None = None, max_tilt: float | None = None) -> WindowCheck:
        """:func:`check_window` of the current forecast at ``arrival`` s from now."""
        assert self.forecast is not None
        return check_window(
            self.horizons,
            self.forecast.mean,
            self.forecast.std,
            self.up_axis(),
            arrival,
            self.cfg.touch_speed,
            self.commit,
            k,
            max_tilt,
        )

    def _ready_to_commit(self, m: Measurement) -> bool:
        c, fc = self.cfg, self.commit
        if self.settled_for < c.settle_time:
            return False
        if not self.usable():
            return self.t >= fc.fallback_time and super()._ready_to_commit(m)
        now = self.predicted_tilt(0.0)
        if now is not None and now >= c.max_tilt_now:
            return False
        k = fc.k_late if self.t >= fc.late_time else fc.k_sigma
        self.last_check = self.window(self.drop_duration(), k)
        return self.last_check.ok

    def act_measured(self, m: Measurement) -> NDArray[np.float32]:
        c, fc = self.cfg, self.commit
        if self.phase == "drop" and self.aborts < fc.max_aborts and self.usable():
            h = self.height
            if h is not None and h - c.leg_length > fc.abort_clearance:
                check = self.window(self.drop_duration(), fc.k_abort, fc.max_tilt + fc.abort_margin)
                self.last_check = check
                if not check.ok:  # the forecast turned: back to the hold
                    self.phase = "hold"
                    self.settled_for = 0.0
                    self.commit_time = None
                    self.aborts += 1
        return super().act_measured(m)


class ForecastLanding(ScriptedLanding):
    """The scripted landing that commits to a forecast quiet window, on the v2 flat observation with
    ``deck_forecast`` (module docstring).

    Args:
        slices, scales: the observation layout (with the ``forecast.*`` fields).
        horizons: the forecast's horizons (s), one per value of each ``forecast.*`` field.
        commit: the commit rule's tunables (a :class:`ForecastCommitConfig` or a dict of its fields).
        others: as :class:`ScriptedLanding` (default config :data:`V2_LANDING_CONFIG`).
    """

    def __init__(
        self,
        slices: Mapping[str, slice],
        scales: Mapping[str, float],
        horizons: Sequence[float],
        control_hz: int = 20,
        max_velocity: Sequence[float] = (1.0, 1.0, 1.0, 1.0),
        rig: SensorRig | None = None,
        config: LandingConfig | None = None,
        commit: ForecastCommitConfig | Mapping[str, Any] | None = None,
        estimator: str = "fused",
    ) -> None:
        cfg = config if config is not None else V2_LANDING_CONFIG
        super().__init__(slices, scales, control_hz, max_velocity, rig, cfg, estimator)
        names = (
            [f"forecast.{f}" for f in _FIELDS] + [f"forecast.{f}_std" for f in _FIELDS] + ["forecast.valid"]
        )
        missing = [n for n in names if n not in slices or n not in scales]
        if missing:
            raise ValueError(
                f"the observation layout lacks {missing}: ForecastLanding needs the landing observation "
                "with deck_forecast (e.g. gym.make('ihrcf_env/DeckLanding-v2', deck_forecast=True))"
            )
        h = np.asarray(horizons, dtype=np.float64).reshape(-1)
        size = slices["forecast.roll"].stop - slices["forecast.roll"].start
        if h.size != size:
            raise ValueError(f"horizons: {h.size} given, the observation's forecast has {size}")
        self.controller = ForecastLandingController(
            tuple(h.tolist()),
            control_hz,
            tuple(self.controller.max_velocity.tolist()),
            self.controller.rig,
            cfg,
            forecast_commit_config(commit),
            estimator,
        )

    @classmethod
    def from_env(
        cls,
        env: Any,
        estimator: str = "fused",
        config: LandingConfig | None = None,
        commit: ForecastCommitConfig | Mapping[str, Any] | None = None,
    ) -> ForecastLanding:
        """The policy for a landing env with ``deck_forecast`` (duck-typed): its layout, control rate,
        action scale, rig and forecast horizons. AttributeError if the env has no landing layout;
        ValueError if it has no forecast."""
        base = env.unwrapped
        feed = env.get_wrapper_attr("forecast")
        if feed is None:
            raise ValueError("the env has no deck-motion forecast: make it with deck_forecast=True")
        return cls(
            env.get_wrapper_attr("obs_slices"),
            env.get_wrapper_attr("obs_scales"),
            tuple(float(v) for v in feed.horizons),
            int(base.config.world.control_hz),
            tuple(float(v) for v in getattr(base, "max_velocity", np.ones(4))),
            base.rig,
            config,
            commit,
            estimator,
        )

    def act(self, obs: NDArray[np.float32]) -> NDArray[np.float32]:
        cols = [self._get(obs, f"forecast.{f}") for f in _FIELDS]
        stds = [self._get(obs, f"forecast.{f}_std") for f in _FIELDS]
        zeros = np.zeros_like(cols[0])
        mean = np.column_stack([zeros, *cols])
        std = np.column_stack([zeros, *stds])
        valid = float(obs[self.slices["forecast.valid"]][0]) > 0.5
        ctrl = self.controller
        assert isinstance(ctrl, ForecastLandingController)
        ctrl.forecast = _Forecast(mean, std, valid)
        return super().act(obs)
