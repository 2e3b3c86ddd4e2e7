"""The fields of the landing tasks' flat observation (the layout
:class:`~ihrcf_env.wrappers.landing_obs.LandingObservation` and the JAX observation
:mod:`ihrcf_env.fast.observe` both build): the sensor block, one block per estimator, the fused
filter's deck motion, the deck-motion forecast and the ground truth. The module docstring of
:mod:`ihrcf_env.wrappers.landing_obs` describes each field, :mod:`ihrcf_env.wrappers.forecast_feed`
the forecast's (:func:`forecast_fields`).
"""

from __future__ import annotations

from collections.abc import Iterable

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators import DEFAULT_ESTIMATORS
from ihrcf_env.core.layout import Block, Field

#: Largest age (s) shown for an estimate; also the age of one never seen.
MAX_AGE = 10.0
POSITION_SCALE = 2.0  # m
RATE_SCALE = 5.0  # rad/s
#: Observation block of the fused filter's deck motion (``deck_motion=True``).
MOTION = "motion"
#: Observation block (and ``info`` key) of the ground truth (``privileged=True``).
GROUND_TRUTH = "ground_truth"
#: Observation block (and ``info`` key) of the deck-motion forecast (``deck_forecast``).
FORECAST = "forecast"
#: The forecast's outputs per horizon, their units, scales and scaled bounds.
FORECAST_OUTPUTS = ("heave", "heave_rate", "roll", "pitch")
FORECAST_UNITS = ("m", "m/s", "rad", "rad")
FORECAST_SCALES = (0.1, 1.0, 0.1, 0.1)
FORECAST_BOUNDS = (10.0, 20.0, 10.0, 10.0)
_FORECAST_MEANINGS = (
    "forecast deck heave about its mean height, per horizon",
    "forecast deck heave rate, per horizon",
    "forecast deck roll (about the heading frame's x), per horizon",
    "forecast deck pitch (about the heading frame's y), per horizon",
)


def _f(
    name: str,
    size: int,
    scale: float,
    bound: float,
    non_negative: bool = False,
    unit: str = "",
    meaning: str = "",
) -> Field:
    return Field(name, size, 0.0 if non_negative else -bound, bound, scale, unit, meaning)


def sensor_fields(max_range: float = 4.0) -> tuple[Field, ...]:
    """The sensor block; ranges are scaled by the ToF ``max_range`` (m)."""
    return (
        _f(
            "ranges",
            4,
            max_range,
            1.0,
            True,
            "m",
            "ToF ranges ps1..ps4 (scale: the ToF max range); an invalid reading reads 1",
        ),
        _f("ranges_valid", 4, 1.0, 1.0, True, "", "1 = valid"),
        _f("imu.up", 3, 1.0, 1.0, False, "", "the world's up axis in the body frame (IMU attitude)"),
        _f("imu.angular_velocity", 3, RATE_SCALE, 50.0 / RATE_SCALE, False, "rad/s", "body rates"),
        _f(
            "imu.linear_acceleration",
            3,
            GRAVITY,
            200.0 / GRAVITY,
            False,
            "m/s^2",
            "specific force, body frame",
        ),
        _f("nav_velocity", 3, 1.0, 20.0, False, "m/s", "the autopilot's velocity estimate, heading frame"),
    )


ESTIMATE_FIELDS: tuple[Field, ...] = (
    _f(
        "position",
        3,
        POSITION_SCALE,
        10.0 / POSITION_SCALE,
        False,
        "m",
        "deck origin (tag centre), heading frame",
    ),
    _f("normal", 3, 1.0, 1.0, False, "", "deck normal, heading frame"),
    _f("yaw", 2, 1.0, 1.0, False, "", "cos, sin of the deck's yaw relative to the drone"),
    _f("valid", 1, 1.0, 1.0, True, "", "1 = valid this step"),
    _f(
        "age",
        1,
        1.0,
        MAX_AGE,
        True,
        "s",
        "age of the values shown (an invalid estimate keeps its last values and its age grows)",
    ),
)
TRUTH_FIELDS: tuple[Field, ...] = (
    _f("position", 3, POSITION_SCALE, 10.0 / POSITION_SCALE, False, "m", "true deck origin, heading frame"),
    _f("normal", 3, 1.0, 1.0, False, "", "true deck normal, heading frame"),
    _f("yaw", 2, 1.0, 1.0, False, "", "cos, sin of the true deck yaw relative to the drone"),
    _f("velocity", 3, 1.0, 20.0, False, "m/s", "the drone's velocity relative to the deck, heading frame"),
    _f("wind", 3, 1.0, 40.0, False, "m/s", "the wind, heading frame"),
)
MOTION_FIELDS: tuple[Field, ...] = (
    _f("velocity", 3, 1.0, 20.0, False, "m/s", "the deck's velocity relative to the drone, heading frame"),
    _f("normal_rate", 3, 1.0, 20.0, False, "1/s", "the rate of the deck normal, heading frame"),
)


def forecast_fields(horizons: int) -> tuple[Field, ...]:
    """The fields of the forecast block for ``horizons`` forecast horizons: per output the
    forecast at each horizon, then their standard deviations, then ``quiet`` and ``valid``."""
    items = zip(FORECAST_OUTPUTS, FORECAST_SCALES, FORECAST_BOUNDS, FORECAST_UNITS, strict=True)
    rows = list(items)
    means = tuple(
        Field(n, horizons, -b, b, s, u, m) for (n, s, b, u), m in zip(rows, _FORECAST_MEANINGS, strict=True)
    )
    stds = tuple(
        Field(f"{n}_std", horizons, 0.0, b, s, u, f"standard deviation of forecast.{n}")
        for n, s, b, u in rows
    )
    return (
        *means,
        *stds,
        Field("quiet", 1, 0.0, 1.0, 1.0, "", "probability that the touchdown window ahead is quiet"),
        Field("valid", 1, 0.0, 1.0, 1.0, "", "1 = the forecaster has fitted its model (else the block is 0)"),
    )


def landing_blocks(
    estimators: Iterable[str] = DEFAULT_ESTIMATORS,
    max_range: float = 4.0,
    privileged: bool = False,
    deck_motion: bool = False,
    forecast: Block | None = None,
) -> list[Block]:
    """The blocks of the landing observation, in order: sensors, one block per estimator, the deck
    motion (``deck_motion``), the ``forecast`` block when given, the ground truth (``privileged``)."""
    blocks: list[Block] = [("", sensor_fields(max_range))]
    blocks += [(name, ESTIMATE_FIELDS) for name in estimators]
    if deck_motion:
        blocks.append((MOTION, MOTION_FIELDS))
    if forecast is not None:
        blocks.append(forecast)
    if privileged:
        blocks.append((GROUND_TRUTH, TRUTH_FIELDS))
    return blocks


__all__ = [
    "ESTIMATE_FIELDS",
    "FORECAST",
    "FORECAST_BOUNDS",
    "FORECAST_OUTPUTS",
    "FORECAST_SCALES",
    "FORECAST_UNITS",
    "GROUND_TRUTH",
    "MAX_AGE",
    "MOTION",
    "MOTION_FIELDS",
    "POSITION_SCALE",
    "RATE_SCALE",
    "TRUTH_FIELDS",
    "forecast_fields",
    "landing_blocks",
    "sensor_fields",
]
