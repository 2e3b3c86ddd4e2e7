"""What a hostile user tries: absurd magnitudes, odd actions and reset options, disturbances that
return garbage. Each gets a clear error naming the thing, never NaN in an observation."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import ihrcf_env

RAW = {"camera": False}


@pytest.mark.parametrize(
    ("options", "name"),
    [
        (
            {"reward_weights": dict.fromkeys(("distance", "height", "speed", "time", "success"), 1e308)},
            "reward",
        ),
        ({"reward_weights": {"crash": math.inf}}, "crash"),
        ({"autopilot_feedback": {"horizontal_sigma": 1e200}}, "horizontal_sigma"),
        ({"autopilot_feedback": {"velocity_noise": 1e300}}, "velocity_noise"),
        ({"autopilot_feedback": {"position_time_constant": 1e-170}}, "position_time_constant"),
        ({"wind": {"turbulence": 1e200}}, "turbulence"),
        ({"wind": {"height": 1e300}}, "height"),
        ({"tof_noise": {"sigma_floor": 1e300}}, "sigma_floor"),
        ({"tof_noise": {"offset_sigma": 1e300}}, "offset_sigma"),
        ({"tof_noise": {"dark_range": 1e300}}, "dark_range"),
        ({"imu_noise": {"tilt_sigma": 1e300}}, "tilt_sigma"),
        ({"imu_noise": {"yaw_drift_rate": 1e300}}, "yaw_drift_rate"),
        ({"max_velocity": (1e300, 1.0, 1.0, 1.0)}, "max_velocity"),
        ({"start_offset": 1e300}, "start_offset"),
        ({"arena_half_width": 1e300}, "arena_half_width"),
        ({"tof_max_range": 1e300}, "tof_max_range"),
        ({"control_hz": 10**400}, "control_hz"),
        ({"camera_width": 10**9}, "camera_width"),
    ],
)
def test_absurd_magnitudes_are_refused_by_name(options: dict[str, Any], name: str) -> None:
    from ihrcf_env.config.make import make_config

    with pytest.raises((TypeError, ValueError), match=name):
        make_config(task="landing-v1", raw=True, **options)


@pytest.mark.parametrize(
    ("options", "name"),
    [
        ({"tof_hz": -5}, "tof_hz"),
        ({"tof_hz": 1e9}, "tof_hz"),
        ({"tof_hz": "x"}, "tof_hz"),
        ({"tof_max_range": 0.05}, "tof_max_range"),
        ({"tof_max_range": 1e300}, "tof_max_range"),
        ({"tof_max_range": "x"}, "tof_max_range"),
    ],
)
def test_tof_option_errors_start_with_the_option(options: dict[str, Any], name: str) -> None:
    """The error names the option given, not another one (``tof_noise``)."""
    from ihrcf_env.config.make import make_config

    with pytest.raises((TypeError, ValueError)) as exc:
        make_config(task="landing-v1", raw=True, **options)
    assert str(exc.value).startswith(name), str(exc.value)


@pytest.mark.parametrize(
    "action",
    [np.array([1j, 0, 0, 0]), ["a", "b", "c", "d"], np.array(["0", "0", "0", "0"]), [object()] * 4, None],
)
def test_non_real_actions_are_refused(make_env: Any, action: Any) -> None:
    env = make_env(ihrcf_env.HOVER_RAW_ID, **RAW)
    env.reset(seed=0)
    with pytest.raises((TypeError, ValueError), match="action"):
        env.step(action)


@pytest.mark.parametrize("options", ["abc", 5, ["altitude"], {3: 1.0}])
def test_reset_options_of_the_wrong_kind_are_named(make_env: Any, options: Any) -> None:
    env = make_env(ihrcf_env.HOVER_RAW_ID, **RAW)
    with pytest.raises((TypeError, ValueError), match="reset options"):
        env.reset(seed=0, options=options)


class _Bad:
    def __init__(self, value: Any) -> None:
        self.value = value

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def __call__(self, t: float, position: Any, velocity: Any) -> Any:
        return self.value

    def __repr__(self) -> str:
        return f"_Bad({self.value!r})"


@pytest.mark.parametrize(
    "value", [(math.nan, 0.0, 0.0), (1.0, 0.0), (1.0, 0.0, 0.0, 0.0), "xyz", (1e9, 0, 0)]
)
def test_a_disturbance_returning_garbage_is_named(make_env: Any, value: Any) -> None:
    env = make_env(ihrcf_env.HOVER_RAW_ID, disturbances=[_Bad(value)], **RAW)
    env.reset(seed=0)
    with pytest.raises((TypeError, ValueError), match="_Bad"):
        env.step(np.zeros(4, np.float32))


def test_observations_stay_finite_at_the_bounds(make_env: Any) -> None:
    """The largest accepted noise magnitudes still give finite observations."""
    env = make_env(
        ihrcf_env.LANDING_V1_ID,
        camera_model="projected",
        tof_noise={"ambient": 1.0},
        wind={"mean_speed_min": 20.0, "mean_speed_max": 20.0, "turbulence": 2.0},
    )
    obs, _ = env.reset(seed=0)
    for _ in range(20):
        obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        assert np.isfinite(obs).all() and math.isfinite(reward)
        if terminated or truncated:
            break


# -- user components: reserved names, outputs checked, no NaN in the observation -----------------
class _Const:
    """A user estimator (always the same invalid estimate), sensor (one constant output) or noise
    model (its ``apply`` returns ``value``, or NaN where ``nan`` is set), as the test needs."""

    def __init__(self, name: str = "const", value: Any = None, nan: Any = None) -> None:
        self.name, self.value, self.nan = name, value, nan

    def reset(self, rng: Any = None) -> None:
        pass

    def update(self, frame: Any) -> Any:
        from ihrcf_env.core.estimators import PoseEstimate

        return PoseEstimate.invalid("constant") if self.value is None else self.value

    def read(self, state: Any, dt: float, rng: Any) -> Any:
        return {"level": np.array([1.0])} if self.value is None else self.value

    def apply(self, value: Any, valid: Any, dt: float, rng: Any) -> Any:
        if self.value is not None:
            return self.value
        out = np.array(value, dtype=np.float64)
        if self.nan is not None:
            out[self.nan] = np.nan
        return out, valid


@pytest.fixture
def registries() -> Any:
    """The registries as they were, after the test (whatever it registered)."""
    from ihrcf_env.core.estimators.registry import ESTIMATORS
    from ihrcf_env.sim import registry

    saved = [(d, dict(d)) for d in (ESTIMATORS, registry.SENSORS, registry.NOISE_MODELS, registry.FAULTS)]
    yield registry
    for d, old in saved:
        d.clear()
        d.update(old)


def _env_keys() -> set[str]:
    from ihrcf_env.core.keys import INFO_KEYS, OBSERVATION_KEYS

    return set(OBSERVATION_KEYS | INFO_KEYS)


@pytest.mark.parametrize(
    "key", sorted({"camera_frame", "tof_age", "imu_age", "ihrcf", "fused", "atda"} | _env_keys())
)
def test_a_sensor_output_named_like_an_env_key_is_refused(registries: Any, key: str) -> None:
    out = {key: registries.SensorOutput((1,), 0.0, 1.0)}
    with pytest.raises(ValueError, match=rf"sensor 'baro'.*{key!r}.*reserved"):
        ihrcf_env.register_sensor("baro", lambda world: _Const(), out)
    assert "baro" not in registries.SENSORS
    # also when the option names a sensor whose output clashes (an estimator registered after it)
    from ihrcf_env.config.make import make_config

    registries.SENSORS["baro"] = registries.SensorEntry(lambda world: _Const(), out)
    with pytest.raises(ValueError, match=rf"sensor 'baro'.*{key!r}.*reserved"):
        make_config(raw=True, camera=False, sensors=("baro",))


@pytest.mark.parametrize(
    "name", sorted({"tag", "crash", "camera", "tof", "all", "time", "touchdown", "ranges"} | _env_keys())
)
def test_an_estimator_named_like_an_env_key_is_refused(registries: Any, name: str) -> None:
    from ihrcf_env.config.make import make_config
    from ihrcf_env.core.estimators.registry import ESTIMATORS

    with pytest.raises(ValueError, match=rf"{name!r} is reserved"):
        ihrcf_env.register_estimator(name, lambda config: _Const(name))
    assert name not in ESTIMATORS
    ESTIMATORS[name] = lambda config: _Const(name)  # past the registration: the option refuses it
    with pytest.raises(ValueError, match=rf"estimators: the name {name!r} is reserved"):
        make_config(estimators=("ihrcf", name))


def test_an_estimator_registered_after_a_sensor_of_its_name_is_refused_by_the_option(
    registries: Any,
) -> None:
    from ihrcf_env.config.make import make_config

    ihrcf_env.register_sensor("baro", lambda world: _Const(), {"level": registries.SensorOutput((1,), 0, 2)})
    ihrcf_env.register_estimator("level", lambda config: _Const("level"))
    with pytest.raises(ValueError, match="sensor 'baro'.*'level'.*estimator"):
        make_config(sensors=("baro",), estimators=("fused", "level"))


def test_the_reserved_keys_cover_every_key_the_envs_write(registries: Any, make_env: Any) -> None:
    """Every observation, info and flat-slice key of the envs (in each configuration that adds keys:
    camera latency, sensor clocks, privileged, deck motion, a touchdown) is in the reserved sets,
    except the keys of the user sensor and estimators chosen."""
    from ihrcf_env.core.keys import ESTIMATOR_INFO_SUFFIXES, FLAT_KEYS, INFO_KEYS, OBSERVATION_KEYS

    ihrcf_env.register_sensor("baro", lambda world: _Const(), {"level": registries.SensorOutput((1,), 0, 2)})
    ihrcf_env.register_estimator("mine", lambda config: _Const("mine"))
    estimators = ("ihrcf", "atda", "fused", "mine")
    user = {"level"} | {f"{e}{s}" for e in estimators for s in ("", *ESTIMATOR_INFO_SUFFIXES)}
    common = {"camera_model": "projected", "sensors": ("baro",)}
    runs = [
        (ihrcf_env.HOVER_RAW_ID, {"camera_latency": 0.05, "tof_hz": 10, "imu_hz": 50}),
        (ihrcf_env.HOVER_RAW_ID, {"camera_model": "rendered", "camera_width": 64, "camera_height": 64}),
        (ihrcf_env.HOVER_ID, {"estimators": estimators}),
        (ihrcf_env.LANDING_V1_ID, {"raw": True, "action_mode": "motors"}),
        (ihrcf_env.LANDING_V2_ID, {"estimators": estimators, "privileged": True, "deck_motion": True}),
        (ihrcf_env.LANDING_V2_ID, {"raw": True, "action_mode": "motors"}),
    ]
    obs_keys: set[str] = set()
    info_keys: set[str] = set()
    flat_keys: set[str] = set()
    for env_id, options in runs:
        env = make_env(env_id, **{**common, **options})
        obs, info = env.reset(seed=0)
        seen = [(obs, info)]
        for _ in range(40):  # motors off: a fall to a touchdown
            obs, _, terminated, truncated, info = env.step(-np.ones(4, np.float32))
            seen.append((obs, info))
            if terminated or truncated:
                break
        for o, i in seen:
            obs_keys |= set(o) if isinstance(o, dict) else set()
            info_keys |= set(i)
        try:
            flat_keys |= {k.partition(".")[0] for k in env.get_wrapper_attr("obs_slices")}
        except AttributeError:
            pass
    assert "touchdown" in info_keys and "camera_frame" in obs_keys and "image" in obs_keys
    assert obs_keys - user <= OBSERVATION_KEYS, obs_keys - user - OBSERVATION_KEYS
    assert info_keys - user <= INFO_KEYS, info_keys - user - INFO_KEYS
    assert flat_keys - user <= OBSERVATION_KEYS | FLAT_KEYS, flat_keys - user - OBSERVATION_KEYS - FLAT_KEYS


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_noise_model_returning_nan_ranges_marks_them_invalid(
    registries: Any, make_env: Any, bad: float
) -> None:
    class Bad(_Const):
        def apply(self, value: Any, valid: Any, dt: float, rng: Any) -> Any:
            out = np.array(value, dtype=np.float64)
            out[[0, 2]] = bad
            return out, np.ones_like(valid)  # and claims them valid

    ihrcf_env.register_noise_model("bad", lambda size: Bad())
    raw = make_env(ihrcf_env.HOVER_RAW_ID, camera_model="projected", measurement_noise={"ranges": "bad"})
    v2 = make_env(ihrcf_env.LANDING_V2_ID, camera_model="projected", measurement_noise={"ranges": "bad"})
    for env in (raw, v2):
        obs, _ = env.reset(seed=0)
        for _ in range(3):
            assert env.observation_space.contains(obs)
            if isinstance(obs, dict):
                assert np.isfinite(obs["ranges"]).all() and obs["ranges"][[0, 2]].tolist() == [4.0, 4.0]
                assert obs["ranges_valid"].tolist() == [0, 1, 0, 1]
            else:
                assert np.isfinite(obs).all()
            obs, *_ = env.step(np.zeros(4, np.float32))


def test_a_fault_returning_nan_ranges_flagged_valid_marks_them_invalid(
    registries: Any, make_env: Any
) -> None:
    class NanFault:
        def reset(self, rng: Any) -> None:
            pass

        def apply(self, reading: Any, time: float, dt: float, rng: Any) -> Any:
            out = dict(reading)
            if "ranges" in out:
                out["ranges"] = np.array([np.nan, 1.0, np.inf, 1.0], np.float32)
                out["ranges_valid"] = np.ones(4, np.int8)
            return out

    ihrcf_env.register_fault("nan_tof", lambda: NanFault(), ("ranges",))
    env = make_env(ihrcf_env.HOVER_RAW_ID, camera_model="projected", faults={"nan_tof": True})
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert obs["ranges"].tolist() == [4.0, 1.0, 4.0, 1.0] and obs["ranges_valid"].tolist() == [0, 1, 0, 1]


def test_nan_tag_corners_make_a_non_detection_with_a_reason(registries: Any, make_env: Any) -> None:
    from ihrcf_env.sim.registry import REASON_NOT_FINITE

    ihrcf_env.register_noise_model("nan_corner", lambda size: _Const(nan=3))
    env = make_env(
        ihrcf_env.HOVER_RAW_ID,
        camera_model="projected",
        camera_output="corners",
        measurement_noise={"tag_corners": "nan_corner"},
    )
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert obs["tag_detected"] == 0 and obs["tag_status"] != 0 and np.isfinite(obs["tag_corners"]).all()
    assert info["tag_reason"] == REASON_NOT_FINITE


def test_nan_imu_values_are_refused_naming_the_measurement_and_the_model(
    registries: Any, make_env: Any
) -> None:
    ihrcf_env.register_noise_model("nan_gyro", lambda size: _Const(nan=1))
    env = make_env(
        ihrcf_env.HOVER_RAW_ID, camera_model="projected", measurement_noise={"angular_velocity": "nan_gyro"}
    )
    with pytest.raises(ValueError, match="'angular_velocity' is not finite.*nan_gyro"):
        env.reset(seed=0)


@pytest.mark.parametrize(
    ("factory", "words"),
    [
        (lambda config: None, "factory must return a DeckPoseSource"),
        (lambda config: 3, "factory must return a DeckPoseSource"),
        (lambda config: _Const("other"), "calls itself"),
        (lambda config: _Const("mine", value=False), "update\\(\\) must return a PoseEstimate.*bool"),
        (lambda config: _Const("mine", value={"valid": 1}), "update\\(\\) must return a PoseEstimate.*dict"),
        (lambda config: _NoneUpdate(), "update\\(\\) must return a PoseEstimate.*got None"),
    ],
)
def test_a_bad_user_estimator_is_named(registries: Any, make_env: Any, factory: Any, words: str) -> None:
    ihrcf_env.register_estimator("mine", factory)
    with pytest.raises((TypeError, ValueError), match=rf"estimator 'mine'.*{words}"):
        env = make_env(ihrcf_env.HOVER_ID, camera_model="projected", estimators=("fused", "mine"))
        env.reset(seed=0)


class _NoneUpdate(_Const):
    def __init__(self) -> None:
        super().__init__("mine")

    def update(self, frame: Any) -> Any:
        return None


@pytest.mark.parametrize(
    ("factory", "words"),
    [
        (lambda world: None, "factory must return a Sensor"),
        (lambda world: _Const(value={"other": np.zeros(1)}), "read\\(\\) must return"),
        (lambda world: _Const(value={"level": np.zeros(1), "ranges": np.zeros(4)}), "read\\(\\) must return"),
        (lambda world: _Const(value=[1.0]), "read\\(\\) must return"),
        (lambda world: _Const(value={"level": np.zeros(3)}), "shape"),
        (lambda world: _Const(value={"level": np.array(["a"])}), "real numbers"),
    ],
)
def test_a_bad_user_sensor_is_named(registries: Any, make_env: Any, factory: Any, words: str) -> None:
    ihrcf_env.register_sensor("baro", factory, {"level": registries.SensorOutput((1,), 0.0, 2.0)})
    with pytest.raises((TypeError, ValueError), match=rf"sensor 'baro'.*{words}"):
        env = make_env(ihrcf_env.HOVER_RAW_ID, camera_model="projected", sensors=("baro",))
        env.reset(seed=0)


@pytest.mark.parametrize(
    ("factory", "words"),
    [
        (lambda size: None, "factory must return a NoiseModel"),
        (
            lambda size: _Const(value=None, nan=None) if size < 0 else object(),
            "factory must return a NoiseModel",
        ),
        (lambda size: _Const(value=np.zeros(4)), "must return \\(value, valid\\)"),
        (lambda size: _Const(value=(np.zeros(3), np.ones(4, bool))), "value of 4 values, got 3"),
        (lambda size: _Const(value=(np.zeros(4), np.ones(5, bool))), "valid of 4 values, got 5"),
        (lambda size: _Const(value=(np.array(["x"] * 4), np.ones(4, bool))), "real numbers"),
    ],
)
def test_a_bad_user_noise_model_is_named(registries: Any, make_env: Any, factory: Any, words: str) -> None:
    ihrcf_env.register_noise_model("hail", factory)
    with pytest.raises((TypeError, ValueError), match=rf"noise model 'hail'.*{words}"):
        env = make_env(ihrcf_env.HOVER_RAW_ID, camera_model="projected", measurement_noise={"ranges": "hail"})
        env.reset(seed=0)


@pytest.mark.parametrize(
    ("result", "words"),
    [
        (lambda r: None, "must return the reading's keys"),
        (lambda r: {k: v for k, v in r.items() if k != "ranges_valid"}, "must return the reading's keys"),
        (lambda r: {**r, "extra": np.zeros(1)}, "must return the reading's keys"),
        (lambda r: {**r, "ranges": np.zeros(3)}, "'ranges' must keep its shape"),
        (lambda r: {**r, "ranges": np.array(["a"] * 4)}, "'ranges' must be an array of real numbers"),
    ],
)
def test_a_bad_user_fault_is_named(registries: Any, make_env: Any, result: Any, words: str) -> None:
    class Fault:
        def reset(self, rng: Any) -> None:
            pass

        def apply(self, reading: Any, time: float, dt: float, rng: Any) -> Any:
            return result(dict(reading)) if "ranges" in reading else dict(reading)

    ihrcf_env.register_fault("glare", lambda: Fault(), ("ranges",))
    env = make_env(ihrcf_env.HOVER_RAW_ID, camera_model="projected", faults={"glare": True})
    with pytest.raises((TypeError, ValueError), match=rf"faults\['glare'\].*{words}"):
        env.reset(seed=0)
