"""Parameters of the fused deck-pose estimator (:class:`FusedParams`).

The design they tune is described in ``docs/fused.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Literal

_DEG = math.pi / 180.0

#: The fused filter's models of the deck's motion (``FusedParams.deck_model``).
DECK_MODELS: tuple[str, ...] = ("kinematic", "oscillator")


@dataclass(frozen=True)
class FusedParams:
    """Parameters of :class:`FusedEstimator` (SI units: m, s, rad). Defaults: the simulator's
    realistic sensors (VL53L1X ranges, sigma a few mm to 10 mm; a BMI088 IMU behind an attitude
    filter with 0.5 deg tilt error; a 512x512 camera with f = 443 px; a 0.4 m tag; 20 Hz) over a
    deck between the paper's slow profile and a sea state. The range noise is estimated online,
    so they also suit exact ranges; with an exact IMU attitude, ``imu_attitude_walk = 0`` smooths
    a little more.

    Range sensors and IHRCF:
        tof_sigma: prior range noise, 1 sigma (m), until the online estimate takes over.
        tof_sigma_window: frames of the online range-noise average (exponential, log domain).
        tof_sigma_min: floor of a one-frame range-noise sample (m).
        ihrcf_tilt_floor: IHRCF tilt noise with exact ranges (rad).
        ihrcf_yaw_floor: IHRCF yaw noise with exact ranges at ``reference_depth`` (rad; x depth).
        ihrcf_yaw_per_range: IHRCF yaw noise per unit of ``sigma_r / depth`` (rad).
        ihrcf_lateral_floor: IHRCF lateral position noise with exact ranges at ``reference_depth``
            (m; x depth).
        ihrcf_depth_floor: IHRCF depth noise with exact ranges (m).
        refit: intersect IHRCF's corner rays with the filter's deck plane (see ``docs/fused.md``).
    ATDA (needs K):
        use_atda_attitude, use_atda_position: fuse ATDA's attitude / position.
        atda_tilt_sigma: roll/pitch noise at ``reference_depth`` (rad; x (depth/ref)^2).
        atda_yaw_sigma: yaw noise at ``reference_depth`` (rad; x depth/ref).
        atda_lateral_sigma: lateral position noise at ``reference_depth`` (m; x depth/ref): wider
            than ATDA's (~1 mm, biased) so the refit's lateral position prevails.
        atda_depth_sigma: depth noise at ``reference_depth`` (m; x (depth/ref)^2).
        reference_depth: depth of the values above (m).
    Common-mode range offset (needs K and ``use_atda_position``):
        range_offset_sigma: prior 1-sigma (m) of a constant offset common to the four ranges,
            estimated against ATDA's depth and subtracted from the ranges (0: no such state).
        atda_depth_bias_sigma: prior 1-sigma (m) of ATDA's own constant depth bias, the other
            half of that comparison.
    Motion models (white-noise spectral densities):
        accel_noise: accelerometer input noise, (m/s^2)/sqrt(Hz).
        accel_drift: random walk of the unmodelled relative acceleration ``b`` (deck acceleration,
            accelerometer bias, gravity leak), (m/s^3)/sqrt(Hz): one level per model of the IMM
            (default: a quiet, a moderate and an agile deck).
        angle_accel_noise: white angular acceleration of the deck, (rad/s^2)/sqrt(Hz).
        angle_drift: random walk of the deck's angular acceleration, (rad/s^3)/sqrt(Hz), one level
            per model.
        model_switch_time: mean time (s) the IMM's Markov chain stays in one model.
        imu_attitude_walk: wander of the IMU attitude's tilt error, (rad/s)/sqrt(Hz): a random walk
            of the filtered roll and pitch, of the relative position (``e x r``) and, through the
            gravity leak, of the horizontal ``b`` (default: a Gauss-Markov tilt error of 0.5 deg
            over 5 s, ``sigma sqrt(2 / tau)``, the simulator's realistic IMU).
        accel_hold: ``"end"`` (a frame's accelerometer sample holds over the interval ending at it)
            or ``"trapezoid"`` (mean of the previous and current samples).
    Initial uncertainty (1 sigma) of the derivatives:
        init_velocity_sigma (m/s), init_accel_sigma (m/s^2), init_rate_sigma (rad/s),
        init_angle_accel_sigma (rad/s^2).
    Gating, validity, timing:
        gate_probability: chi-square probability of the Mahalanobis gate of each measurement.
        max_rejections: consecutive frames in which every measurement of one filter (position or
            attitude) was rejected, after which that filter starts again from the measurements.
        min_updates: accepted frames before the output is valid.
        valid_position_sigma (m), valid_angle_sigma (rad): largest position and angle 1-sigma at
            which a new state counts as converged (checked until it first does).
        lost_timeout: seconds without an accepted measurement after which a filter (position or
            attitude) drops its state and the output turns invalid.
        nominal_dt: frame interval assumed when a frame's time is unknown (NaN), s.
    Options (off by default):
        range_only_update: in a frame without a tag measurement (no corners, or neither IHRCF nor
            ATDA gave an estimate) but with at least three valid ranges on one plane, update the
            deck's tilt and its distance along the plane's normal from the ranges alone; the
            lateral position and the yaw coast on the IMU, and ``lost_timeout`` still counts from
            the last tag measurement (see ``docs/fused.md``).
        drop_lost_track: a filter whose every measurement was rejected for ``max_rejections``
            frames is dropped at once (the output turns invalid until a measurement starts it
            again) instead of coasting, still valid, until the next frame with a measurement.
        reseed_agreeing: when every position measurement is rejected for a second frame in a row
            but IHRCF's and ATDA's positions agree with each other within the gate, the prediction is what is
            wrong (a deck that moved faster than the motion models allow through a gap in the
            frames): the position restarts at the two measurements' combination, its rates kept
            with ``init_velocity_sigma`` added, and the output stays valid.
    Deck model (``docs/fused.md``, :mod:`~ihrcf_env.core.estimators.imm_deck`):
        deck_model: ``"kinematic"`` (default: the motion models above) or ``"oscillator"``: the
            deck's motion as a narrow-band process, a damped oscillator per axis in the state of
            the position and the attitude filters, one model per period of ``deck_periods``
            beside the kinematic ones.
        deck_periods: the oscillators' natural periods (s), 1-8 values.
        deck_damping: their damping ratio (0, 1].
        deck_accel_sigma: stationary 1-sigma of the deck origin's oscillating acceleration per
            axis, m/s^2.
        deck_angle_accel_sigma: the same of the deck's angular acceleration, rad/s^2.
        deck_oscillator_drift: drift of the oscillator models' slow acceleration ``b``, as a
            fraction-free density ((m/s^3)/sqrt(Hz), (rad/s^3)/sqrt(Hz) for the attitude).
    """

    tof_sigma: float = 0.010
    tof_sigma_window: int = 100
    tof_sigma_min: float = 1e-5
    ihrcf_tilt_floor: float = 0.01 * _DEG
    ihrcf_yaw_floor: float = 0.08 * _DEG
    ihrcf_yaw_per_range: float = 0.6
    ihrcf_lateral_floor: float = 0.0005
    ihrcf_depth_floor: float = 0.0002
    refit: bool = True
    use_atda_attitude: bool = True
    use_atda_position: bool = True
    atda_tilt_sigma: float = 0.5 * _DEG
    atda_yaw_sigma: float = 0.1 * _DEG
    atda_lateral_sigma: float = 0.003
    atda_depth_sigma: float = 0.002
    reference_depth: float = 1.0
    range_offset_sigma: float = 0.0
    atda_depth_bias_sigma: float = 0.00075
    accel_noise: float = 0.003
    accel_drift: tuple[float, ...] = (0.001, 0.01, 0.1)
    angle_accel_noise: float = 0.002
    angle_drift: tuple[float, ...] = (0.005, 0.05, 0.5)
    model_switch_time: float = 30.0
    imu_attitude_walk: float = 0.0055
    accel_hold: Literal["end", "trapezoid"] = "end"
    init_velocity_sigma: float = 0.5
    init_accel_sigma: float = 0.5
    init_rate_sigma: float = 20 * _DEG
    init_angle_accel_sigma: float = 10 * _DEG
    gate_probability: float = 0.999
    max_rejections: int = 10
    min_updates: int = 10
    valid_position_sigma: float = 0.01
    valid_angle_sigma: float = 3.0 * _DEG
    lost_timeout: float = 1.0
    nominal_dt: float = 0.05
    range_only_update: bool = False
    drop_lost_track: bool = False
    reseed_agreeing: bool = False
    deck_model: Literal["kinematic", "oscillator"] = "kinematic"
    deck_periods: tuple[float, ...] = (0.8, 1.2, 1.8)
    deck_damping: float = 0.1
    deck_accel_sigma: float = 0.3
    deck_angle_accel_sigma: float = 0.5
    deck_oscillator_drift: float = 0.01

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "accel_hold":
                if v not in ("end", "trapezoid"):
                    raise ValueError(f"accel_hold must be 'end' or 'trapezoid', got {v!r}")
            elif f.name == "deck_model":
                if v not in DECK_MODELS:
                    raise ValueError(f"deck_model must be one of {DECK_MODELS}, got {v!r}")
            elif f.name == "deck_periods":
                if not (
                    isinstance(v, tuple)
                    and 1 <= len(v) <= 8
                    and all(
                        isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) and x > 0
                        for x in v
                    )
                ):
                    raise ValueError(f"deck_periods must be a tuple of 1-8 finite numbers > 0 (s), got {v!r}")
            elif f.name in ("accel_drift", "angle_drift"):
                if not (
                    isinstance(v, tuple)
                    and v
                    and all(
                        isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) and x >= 0
                        for x in v
                    )
                ):
                    raise ValueError(f"{f.name} must be a non-empty tuple of finite numbers >= 0, got {v!r}")
            elif isinstance(f.default, bool):
                if not isinstance(v, bool):
                    raise TypeError(f"{f.name} must be a bool, got {v!r}")
            elif isinstance(f.default, int):
                if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                    raise ValueError(f"{f.name} must be an int >= 1, got {v!r}")
            else:
                if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < 0:
                    raise ValueError(f"{f.name} must be a finite number >= 0, got {v!r}")
        for name in (
            "tof_sigma",
            "tof_sigma_min",
            "reference_depth",
            "nominal_dt",
            "lost_timeout",
            "model_switch_time",
        ):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")
        if not 0.0 < self.deck_damping <= 1.0:
            raise ValueError(f"deck_damping must be in (0, 1], got {self.deck_damping!r}")
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError(f"gate_probability must be in (0, 1), got {self.gate_probability!r}")


__all__ = [
    "DECK_MODELS",
    "FusedParams",
]
