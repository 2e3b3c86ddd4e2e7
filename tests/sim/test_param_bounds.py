"""Every real field of the simulation's parameter dataclasses has physical bounds: each field at each
bound runs the model without NaN/inf or an exception, and absurd values (1e300, -1e300, 1e-170 where
the lower bound is positive, NaN, a bool, a string) raise TypeError/ValueError naming the field."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pytest

from ihrcf_env.config.sensors import (
    IMU_NOISE_BOUNDS,
    MAX_RANGE_BOUNDS,
    VL53L1X,
    VL53L1X_BOUNDS,
    IMUConfig,
    IMUNoise,
    ToFConfig,
)
from ihrcf_env.config.vehicle import (
    GAIN_BOUNDS,
    NAVIGATION_ERROR_BOUNDS,
    QUAD_BOUNDS,
    NavigationErrors,
    QuadParams,
    VelocityGains,
)
from ihrcf_env.config.wind import DRAG_BOUNDS, WIND_BOUNDS, DragModel, WindParams
from ihrcf_env.config.world import DECK_BOUNDS, DeckConfig, WorldConfig
from ihrcf_env.control.filters import AlphaBeta
from ihrcf_env.control.hover import HoverGains, tracking_action
from ihrcf_env.control.landing import LANDING_BOUNDS, LANDING_OFF_AT_INF, LandingConfig, LandingController
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.frames import quat_from_matrix
from ihrcf_env.core.profiles import (
    MAX_ROTATION,
    MAX_TRANSLATION,
    SEA_STATE_AMPLITUDES,
    ShiftedProfile,
    StaticProfile,
    SumOfSines,
    paper_profile,
    sea_state_profile,
)
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.sim.disturbances import Wind, disturbance_force
from ihrcf_env.sim.navigation import GNSSINSNavigation
from ihrcf_env.sim.noise import GaussianNoise, GaussMarkov, WhiteNoise
from ihrcf_env.sim.sensors.base import BodyState
from ihrcf_env.sim.sensors.imu import IMU
from ihrcf_env.sim.world import World

# Fields whose bound alone breaks a cross-field rule get a companion value.
COMPANIONS: dict[tuple[type, str, str], dict[str, Any]] = {
    (VL53L1X, "ambient_range", "high"): {"dark_range": VL53L1X_BOUNDS["dark_range"][1]},
    (VL53L1X, "dark_range", "low"): {"ambient_range": VL53L1X_BOUNDS["ambient_range"][0]},
    (WindParams, "mean_speed_min", "high"): {"mean_speed_max": WIND_BOUNDS["mean_speed_max"][1]},
    (DeckConfig, "tag_size", "high"): {"size": DECK_BOUNDS["size"][1]},
    (DeckConfig, "size", "low"): {"tag_size": DECK_BOUNDS["tag_size"][0]},
}

TABLES: dict[type, Mapping[str, tuple[float, float]]] = {
    VL53L1X: VL53L1X_BOUNDS,
    IMUNoise: IMU_NOISE_BOUNDS,
    NavigationErrors: NAVIGATION_ERROR_BOUNDS,
    WindParams: WIND_BOUNDS,
    DragModel: DRAG_BOUNDS,
    QuadParams: QUAD_BOUNDS,
    VelocityGains: GAIN_BOUNDS,
    DeckConfig: DECK_BOUNDS,
    LandingConfig: LANDING_BOUNDS,
    HoverGains: {f: (0.0, 100.0) for f in ("k_xy", "k_z", "k_yaw")},
    ToFConfig: {"max_range": MAX_RANGE_BOUNDS},
}


def test_every_real_field_has_bounds() -> None:
    """No real-valued field is left unbounded (a new field must be added to its table)."""
    for cls, table in TABLES.items():
        for f in dataclasses.fields(cls):  # type: ignore[arg-type]
            if f.type in ("float", "tuple[float, float, float]", "float | tuple[float, float, float]"):
                assert f.name in table, f"{cls.__name__}.{f.name} has no bounds"


def _build(cls: type, field: str, value: object, side: str = "") -> Any:
    return cls(**{field: value, **COMPANIONS.get((cls, field, side), {})})


def _cases() -> list[tuple[type, str, str]]:
    return [(cls, f, side) for cls, table in TABLES.items() for f in table for side in ("low", "high")]


def _finite(x: object) -> None:
    if isinstance(x, Mapping):
        for v in x.values():
            _finite(v)
    elif isinstance(x, np.ndarray) and x.dtype.kind == "f":
        assert np.isfinite(x).all()
    elif isinstance(x, tuple | list):
        assert all(math.isfinite(float(v)) for v in x)


# -- runners: a few steps of the model that uses the parameters --------------------------------------
def _run_world(**config: Any) -> None:
    w = World(WorldConfig(camera=None, imu=IMUConfig("realistic"), **config))
    try:
        w.reset(paper_profile(), 5.0, altitude=1.0)
        rng = np.random.default_rng(0)
        w.reset_random(rng)
        for _ in range(5):
            w.step()
            _finite(w.sensing.read_sensors(rng))
            _finite(tuple(w.drone_pose()[0]))
            _finite(tuple(w.deck.pose()[0]))
    finally:
        w.close()


def _body_state(t: float) -> BodyState:
    R = np.eye(3)
    return BodyState(
        t, np.array([0.0, 0.0, 1.0]), R, quat_from_matrix(R), np.zeros(3), np.zeros(3), np.zeros(3)
    )


def _run_imu(noise: IMUNoise) -> None:
    imu = IMU.from_config(IMUConfig(noise))
    rng = np.random.default_rng(1)
    imu.reset(rng)
    for k in range(600):  # 30 s at 20 Hz: the heading drift accumulates
        out = imu.read(_body_state(k * 0.05), 0.05, rng)
    _finite(out)
    assert np.linalg.norm(out["quaternion"]) == pytest.approx(1.0)


def _run_navigation(errors: NavigationErrors) -> None:
    nav = GNSSINSNavigation(errors, 1 / 240)
    nav.reset(np.random.default_rng(2))
    for k in range(600):
        pos, vel = nav.estimate(k / 240, (0.0, 0.0, 1.0), (0.1, 0.0, 0.0))
        _finite(pos)
        _finite(vel)
    _finite(errors.drift_std(30.0))


def _run_wind(params: WindParams) -> None:
    wind = Wind(params)
    wind.reset(np.random.default_rng(3))
    for k in range(400):
        _finite(disturbance_force(wind, k * 0.05, (0.0, 0.0, 1.0), (0.5, -0.2, 0.1)))
        _finite(tuple(wind.velocity(k * 0.05)))


def _landing_obs(height: float) -> dict[str, Any]:
    sensors = SensorRig().sensor_positions_body
    ranges = np.array([height + s[2] for s in sensors], dtype=np.float32)  # a level deck below
    return {
        "ranges": ranges,
        "ranges_valid": np.ones(4, np.int8),
        "imu": {
            "quaternion": quat_from_matrix(np.eye(3)).astype(np.float32),
            "angular_velocity": np.zeros(3, np.float32),
            "linear_acceleration": np.array([0.0, 0.0, GRAVITY], np.float32),
        },
        "ihrcf": {
            "position": np.array([0.02, -0.01, -height], np.float32),
            "euler": np.zeros(3, np.float32),
            "valid": 1,
        },
    }


def _run_landing(config: LandingConfig) -> None:
    ctrl = LandingController(config=config)
    for k in range(100):
        a = ctrl.act(_landing_obs(1.0 - 0.008 * k))
        assert np.isfinite(a).all() and np.all(np.abs(a) <= 1.0)
    ctrl.drop_duration()


RUNNERS: dict[type, Callable[[Any], None]] = {
    VL53L1X: lambda m: _run_world(tof=ToFConfig(noise=m)),
    ToFConfig: lambda c: _run_world(tof=dataclasses.replace(c, noise="realistic")),
    IMUNoise: _run_imu,
    NavigationErrors: _run_navigation,
    WindParams: _run_wind,
    DragModel: lambda d: _run_wind(WindParams(mean_speed_min=5.0, mean_speed_max=10.0, drag=d)),
    QuadParams: lambda q: _run_world(quad=q),
    VelocityGains: lambda g: _run_world(gains=g),
    DeckConfig: lambda d: _run_world(deck=d),
    LandingConfig: _run_landing,
    HoverGains: lambda g: _finite(
        tracking_action(
            {"valid": 1, "position": [0.1, 0.2, -1.0], "euler": [0, 0, 0.3]}, [0, 0, 0, 1], 1.0, [1] * 4, g
        )
    ),
}


@pytest.mark.parametrize(("cls", "field", "side"), _cases(), ids=lambda v: getattr(v, "__name__", v))
def test_each_field_at_each_bound_runs(cls: type, field: str, side: str) -> None:
    low, high = TABLES[cls][field]
    bound = low if side == "low" else high
    current = getattr(cls(), field)
    value: object = tuple(bound for _ in current) if isinstance(current, tuple) else bound
    obj = _build(cls, field, value, side)
    RUNNERS[cls](obj)


def _bad_values(low: float) -> list[tuple[object, type]]:
    bad: list[tuple[object, type]] = [(1e300, ValueError), (-1e300, ValueError), (math.nan, ValueError)]
    bad += [(math.inf, ValueError), (True, TypeError), ("x", TypeError), (None, TypeError)]
    if low > 1e-170:
        bad.append((1e-170, ValueError))
    return bad


@pytest.mark.parametrize(("cls", "field"), [(c, f) for c, t in TABLES.items() for f in t], ids=str)
def test_absurd_values_are_refused_naming_the_field(cls: type, field: str) -> None:
    low, _ = TABLES[cls][field]
    for value, error in _bad_values(low):
        if value == math.inf and cls is LandingConfig and field in LANDING_OFF_AT_INF:
            LandingConfig(**{field: math.inf})  # inf: the feature is off
            continue
        ftype = {f.name: f.type for f in dataclasses.fields(cls)}[field]  # type: ignore[arg-type]
        tuple_only = ftype == "tuple[float, float, float]"  # a number is the wrong kind: TypeError
        with pytest.raises((TypeError, ValueError) if tuple_only else error, match=field):
            _build(cls, field, value)
        current = getattr(cls(), field)
        if isinstance(current, tuple):  # one bad element of a per-axis field
            with pytest.raises(error, match=field):
                _build(cls, field, (current[0], value, current[2]))


# -- the defects measured through gym.make's options ------------------------------------------------
@pytest.mark.parametrize(
    ("cls", "kwargs", "field"),
    [
        (NavigationErrors, {"horizontal_sigma": 1e200}, "horizontal_sigma"),
        (NavigationErrors, {"velocity_noise": 1e300}, "velocity_noise"),
        (NavigationErrors, {"position_time_constant": 1e-170}, "position_time_constant"),
        (WindParams, {"turbulence": 1e200}, "turbulence"),
        (WindParams, {"height": 1e300}, "height"),
        (VL53L1X, {"sigma_floor": 1e300}, "sigma_floor"),
        (VL53L1X, {"offset_sigma": 1e300}, "offset_sigma"),
        (VL53L1X, {"dark_range": 1e300}, "dark_range"),
        (IMUNoise, {"tilt_sigma": 1e300}, "tilt_sigma"),
        (IMUNoise, {"yaw_drift_rate": 1e300}, "yaw_drift_rate"),
    ],
)
def test_measured_defects_fail_at_construction(cls: type, kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        cls(**kwargs)


def test_env_options_name_the_parameter() -> None:
    from ihrcf_env.config.make import make_config

    with pytest.raises(ValueError, match=r"autopilot_feedback\['horizontal_sigma'\].*horizontal_sigma"):
        make_config(camera=False, autopilot_feedback={"horizontal_sigma": 1e200})
    with pytest.raises(ValueError, match=r"tof_noise\['sigma_floor'\]"):
        make_config(camera=False, tof_noise={"sigma_floor": 1e300})
    with pytest.raises(ValueError, match=r"imu_noise\['tilt_sigma'\]"):
        make_config(camera=False, imu_noise={"tilt_sigma": 1e300})


# -- generic noise models, profiles, filters ---------------------------------------------------------
def test_noise_models_are_bounded() -> None:
    for bad in (1e300, -1.0, math.nan):
        with pytest.raises(ValueError, match="sigma"):
            GaussianNoise(bad)
        with pytest.raises(ValueError, match="density"):
            WhiteNoise(bad)
        with pytest.raises(ValueError, match=r"density\[1\]"):
            WhiteNoise((0.1, bad, 0.1))
    for bad in (1e-170, 1e300, 0.0):
        with pytest.raises(ValueError, match="tau"):
            GaussMarkov(0.1, bad)
    with pytest.raises(TypeError, match="size"):  # the size of a vector model is an integer
        WhiteNoise(0.1, size=2.5)  # type: ignore[arg-type]


def test_profile_parameters_are_bounded() -> None:
    ok = SumOfSines((((MAX_TRANSLATION, 50.0, 1e3),), (), (), ((-MAX_ROTATION, 0.0, -1e3),)))
    off, rpy = ok.sample(np.linspace(0.0, 100.0, 7))
    assert np.isfinite(off).all() and np.isfinite(rpy).all()
    for bad, error in ((1e300, ValueError), (math.nan, ValueError), (True, TypeError), ("x", TypeError)):
        for j, what in enumerate(("amplitude", "frequency", "phase")):
            comp = [0.01, 0.1, 0.0]
            comp[j] = bad
            with pytest.raises(
                error, match=r"components\[2\]\[0\]" + (f".*{what}" if error is ValueError else "")
            ):
                SumOfSines(((), (), (tuple(comp),)))
    with pytest.raises(ValueError, match="heave"):
        sea_state_profile(np.random.default_rng(0), {"heave": 1e300})
    with pytest.raises(ValueError, match="period_range"):
        sea_state_profile(np.random.default_rng(0), period_range=(1e-170, 5.0))
    with pytest.raises(ValueError, match="period_range"):
        sea_state_profile(np.random.default_rng(0), period_range=(4.0, 1e300))
    with pytest.raises(TypeError, match="n_components"):
        sea_state_profile(np.random.default_rng(0), n_components=2.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="start time"):
        ShiftedProfile(StaticProfile(), 1e300)
    assert set(SEA_STATE_AMPLITUDES) == {"surge", "sway", "heave", "roll", "pitch", "yaw"}


def test_alpha_beta_gains_are_bounded() -> None:
    with pytest.raises(ValueError, match="alpha"):
        AlphaBeta(1e300, 0.1)
    with pytest.raises(TypeError, match="beta"):
        AlphaBeta(0.5, "x")  # type: ignore[arg-type]
