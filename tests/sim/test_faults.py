"""Sensor faults (ihrcf_env.sim.faults) on readings dicts, their option (registry.check_faults), and
the estimators fed a recorded hover run with a dead ToF sensor."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.sim import registry
from ihrcf_env.sim.faults import (
    REASON_FRAME_LOST,
    REASON_OCCLUDED,
    CameraDropout,
    ImuBiasStep,
    TagOcclusion,
    ToFDead,
    ToFStuck,
)
from ihrcf_env.sim.registry import FAULTS, apply_faults, build_faults, check_faults, register_fault
from ihrcf_env.sim.sensors.base import TAG_STATUS, tag_reading, tag_status_code

DT = 0.05
CORNERS = np.array([[200.0, 200.0], [300.0, 200.0], [300.0, 300.0], [200.0, 300.0]])


def tof(ranges: Any = (1.0, 1.1, 1.2, 1.3), valid: Any = (1, 1, 1, 1)) -> dict[str, np.ndarray]:
    return {"ranges": np.array(ranges, np.float32), "ranges_valid": np.array(valid, np.int8)}


def imu() -> dict[str, np.ndarray]:
    return {
        "quaternion": np.array([0.0, 0.0, 0.0, 1.0]),
        "angular_velocity": np.array([0.1, -0.2, 0.3]),
        "linear_acceleration": np.array([0.0, 0.0, 9.81]),
    }


def run(fault: Any, readings: list[Mapping[str, np.ndarray]], seed: int = 0) -> list[dict[str, np.ndarray]]:
    """The readings (one per control step from t = 0) through ``fault``, reset from its stream."""
    rng = SeedStreams(seed).generator("fault.test")
    fault.reset(rng)
    return [fault.apply(r, i * DT, DT, rng) for i, r in enumerate(readings)]


# -- the option ----------------------------------------------------------------------------------
def test_faults_are_off_by_default() -> None:
    assert check_faults(None) == ()
    assert check_faults({}) == ()
    assert check_faults({"tof_dead": False, "camera_dropout": False}) == ()
    assert {"tof_dead", "tof_stuck", "camera_dropout", "tag_occlusion", "imu_bias_step"} <= set(FAULTS)


def test_option_is_normalised_and_takes_the_world_context() -> None:
    spec = check_faults(
        {"tof_dead": {"sensors": [2]}, "camera_dropout": True}, context={"tof_max_range": 3.0}
    )
    assert spec == (("tof_dead", (("sensors", (2,)), ("tof_max_range", 3.0))), ("camera_dropout", ()))
    hash(spec)  # a frozen WorldConfig field
    built = build_faults(spec)
    assert list(built) == ["tof_dead", "camera_dropout"]
    assert isinstance(built["tof_dead"], ToFDead) and built["tof_dead"].tof_max_range == 3.0
    assert isinstance(built["tof_dead"], registry.Fault)
    # an explicit parameter wins over the context
    assert dict(check_faults({"tof_dead": {"tof_max_range": 2.0}}, context={"tof_max_range": 3.0})[0][1]) == {
        "tof_max_range": 2.0
    }


@pytest.mark.parametrize(
    ("value", "error", "words"),
    [
        ({"tof_broken": True}, ValueError, "unknown fault 'tof_broken'"),
        ({"tof_dead": {"sensor": 1}}, ValueError, "unknown parameter 'sensor'"),
        ({"tof_dead": {"sensors": [4]}}, ValueError, "ToFDead.sensors[0]"),
        ({"tof_dead": {"sensors": [-1]}}, ValueError, "ToFDead.sensors[0]"),
        ({"tof_dead": {"sensors": [1, 1]}}, ValueError, "given twice"),
        ({"tof_dead": {"sensors": [0, 1, 2, 3]}}, ValueError, "all four ToF sensors dead"),
        ({"tof_dead": {"count": 4}}, ValueError, "all four ToF sensors dead"),
        ({"tof_dead": {"sensors": [1, 2], "count": 3}}, ValueError, "sensors or count"),
        ({"tof_dead": {"onset": -1.0}}, ValueError, "ToFDead.onset"),
        ({"tof_stuck": {"onset": (5.0, 2.0)}}, ValueError, "ToFStuck.onset[1]"),
        ({"tof_stuck": {"onset": "soon"}}, TypeError, "ToFStuck.onset"),
        ({"camera_dropout": {"loss_rate": 1.5}}, ValueError, "CameraDropout.loss_rate"),
        ({"camera_dropout": {"loss_rate": -0.1}}, ValueError, "CameraDropout.loss_rate"),
        ({"camera_dropout": {"loss_rate": 0.9, "mean_burst": 2.0}}, ValueError, "cannot be met"),
        ({"camera_dropout": {"mean_burst": 0.5}}, ValueError, "CameraDropout.mean_burst"),
        ({"tag_occlusion": {"rate": math.inf}}, ValueError, "TagOcclusion.rate"),
        ({"tag_occlusion": {"radius": (0.5, 0.1)}}, ValueError, "TagOcclusion.radius[1]"),
        ({"imu_bias_step": {"gyro": 0.0, "accel": 0.0}}, ValueError, "would do nothing"),
        ({"imu_bias_step": {"gyro": 1e300}}, ValueError, "ImuBiasStep.gyro"),
        ({"imu_bias_step": {"accel": (1.0, 2.0)}}, TypeError, "ImuBiasStep.accel"),
        ({"tof_dead": "yes"}, TypeError, "faults['tof_dead']"),
        (["tof_dead"], TypeError, "faults must be a dict"),
        ({"tof_dead": {"sensors": [1]}, "tof_stuck": {"sensors": [1, 3]}}, ValueError, "both dead"),
    ],
)
def test_bad_options_are_refused_naming_them(value: Any, error: type[Exception], words: str) -> None:
    with pytest.raises(error, match=None) as info:
        check_faults(value)
    assert words in str(info.value)


def test_a_fault_on_a_measurement_the_env_lacks_is_refused() -> None:
    with pytest.raises(ValueError, match="camera_dropout.*does not measure"):
        check_faults({"camera_dropout": True}, measurements={"ranges", "ranges_valid"})
    assert check_faults({"camera_dropout": True}, measurements={"image"}) == (("camera_dropout", ()),)
    no_camera = registry.world_measurements(None)
    assert "ranges" in no_camera and "angular_velocity" in no_camera and "tag_corners" not in no_camera
    with pytest.raises(ValueError, match="tag_occlusion"):
        check_faults({"tag_occlusion": True}, measurements=registry.world_measurements("image"))
    assert check_faults({"tag_occlusion": True}, measurements=registry.world_measurements("corners"))


def test_user_faults_register_like_the_built_in_ones() -> None:
    class Spike:
        def __init__(self, size: float = 1.0) -> None:
            self.size = size

        def reset(self, rng: np.random.Generator) -> None:
            pass

        def apply(self, reading: Mapping[str, np.ndarray], time: float, dt: float, rng: Any) -> dict:
            out = dict(reading)
            if "ranges" in out:
                out["ranges"] = out["ranges"] + self.size
            return out

    register_fault("test_spike", Spike, ("ranges",))
    try:
        with pytest.raises(ValueError, match="already registered"):
            register_fault("test_spike", Spike)
        spec = check_faults({"test_spike": {"size": 0.5}})
        faults = build_faults(spec)
        out = apply_faults(faults, tof(), 0.0, DT, lambda name: np.random.default_rng(0))
        np.testing.assert_allclose(out["ranges"], np.array([1.5, 1.6, 1.7, 1.8]), rtol=1e-6)
        with pytest.raises(ValueError, match="unknown parameter 'sigma'"):
            check_faults({"test_spike": {"sigma": 1.0}})
    finally:
        del FAULTS["test_spike"]


# -- each fault ----------------------------------------------------------------------------------
def test_tof_dead_from_the_start() -> None:
    out = run(ToFDead(sensors=2, tof_max_range=4.0), [tof()] * 3)
    for r in out:
        np.testing.assert_array_equal(r["ranges_valid"], [1, 1, 0, 1])
        np.testing.assert_allclose(r["ranges"], [1.0, 1.1, 4.0, 1.3], rtol=1e-6)
        assert r["ranges"].dtype == np.float32 and r["ranges_valid"].dtype == np.int8
    assert run(ToFDead(sensors=2), [imu()])[0].keys() == imu().keys()  # other readings pass


def test_tof_dead_from_a_random_onset_is_deterministic_per_seed() -> None:
    readings = [tof()] * 200  # 10 s

    def dead_from(seed: int) -> tuple[tuple[int, ...], float]:
        fault = ToFDead(count=2, onset=(2.0, 8.0))
        out = run(fault, readings, seed)
        dead = [i for i, r in enumerate(out) if r["ranges_valid"].sum() < 4]
        assert dead == list(range(dead[0], 200))  # stays dead
        assert (out[-1]["ranges_valid"] == 0).sum() == 2
        assert 2.0 <= dead[0] * DT and (dead[0] - 1) * DT < fault.start <= dead[0] * DT <= 8.0 + DT
        return fault.chosen, fault.start

    assert dead_from(1) == dead_from(1)
    draws = {dead_from(seed) for seed in range(8)}
    assert len(draws) == 8
    assert len({chosen for chosen, _ in draws}) > 1


def test_tof_stuck_repeats_its_last_valid_value_flagged_valid() -> None:
    # descending: 2 m -> 0.5 m over 3 s; sensor 1 gets stuck at 1 s, then its readings go invalid
    heights = np.linspace(2.0, 0.5, 60)
    readings = [tof([h] * 4, [1, int(i < 30), 1, 1]) for i, h in enumerate(heights)]
    out = run(ToFStuck(sensors=[1], onset=1.0), readings)
    stuck_at = heights[19]  # the last reading before t = 1 s (i = 20)
    for i, r in enumerate(out):
        if i < 20:
            assert r["ranges"][1] == pytest.approx(heights[i], rel=1e-6)
        else:
            assert r["ranges"][1] == pytest.approx(stuck_at, rel=1e-6)
            assert r["ranges_valid"][1] == 1  # the nasty case: flagged valid
        np.testing.assert_allclose(r["ranges"][[0, 2, 3]], heights[i], rtol=1e-6)


def test_tof_stuck_from_the_start_waits_for_a_first_valid_reading() -> None:
    readings = [tof([3.0] * 4, [1, 0, 1, 1]), tof([2.0] * 4), tof([1.0] * 4), tof([0.5] * 4, [1, 0, 1, 1])]
    out = run(ToFStuck(sensors=1), readings)
    assert [float(r["ranges"][1]) for r in out] == [3.0, 2.0, 2.0, 2.0]
    assert [int(r["ranges_valid"][1]) for r in out] == [0, 1, 1, 1]


def lost(r: Mapping[str, np.ndarray]) -> bool:
    return not bool(r["tag_detected"])


def bursts(flags: list[bool]) -> list[int]:
    out, n = [], 0
    for f in flags:
        if f:
            n += 1
        elif n:
            out.append(n)
            n = 0
    return out + ([n] if n else [])


def test_camera_dropout_has_the_loss_rate_and_burst_length_asked() -> None:
    frames = [tag_reading(CORNERS, "")] * 40000
    out = run(CameraDropout(loss_rate=0.2, mean_burst=4.0), frames, seed=5)
    flags = [lost(r) for r in out]
    assert np.mean(flags) == pytest.approx(0.2, abs=0.02)
    assert np.mean(bursts(flags)) == pytest.approx(4.0, rel=0.1)
    r = next(r for r in out if lost(r))
    assert str(r["tag_reason"]) == REASON_FRAME_LOST
    assert int(r["tag_status"]) == max(1, tag_status_code(REASON_FRAME_LOST))
    np.testing.assert_array_equal(r["tag_corners"], np.zeros((4, 2)))
    kept = next(r for r in out if not lost(r))
    np.testing.assert_array_equal(kept["tag_corners"], CORNERS)
    # deterministic per seed; the rendered image output is blanked
    again = run(CameraDropout(loss_rate=0.2, mean_burst=4.0), frames[:500], seed=5)
    assert [lost(r) for r in again] == flags[:500]
    image = {"image": np.full((4, 4, 3), 200, np.uint8)}
    blank = run(CameraDropout(loss_rate=0.5, mean_burst=50.0), [image] * 200, seed=1)
    assert any(not r["image"].any() for r in blank) and any(r["image"].all() for r in blank)


def test_a_lost_frame_has_its_own_tag_status() -> None:
    out = run(CameraDropout(loss_rate=0.5, mean_burst=50.0), [tag_reading(CORNERS, "")] * 100)
    r = next(r for r in out if lost(r))
    assert TAG_STATUS[int(r["tag_status"])] == REASON_FRAME_LOST


def test_tag_occlusion_loses_the_tag_only_when_a_corner_is_covered() -> None:
    fault = TagOcclusion(rate=0.0)
    fault.reset(np.random.default_rng(0))  # rate 0: never occluded
    assert not fault.active and fault.next_change == math.inf
    frame = tag_reading(CORNERS, "")
    fault.active, fault.next_change = True, math.inf
    fault.centre, fault.disc = np.array([0.0, 0.0]), 0.9  # over the code bits only
    assert not lost(fault.apply(frame, 0.0, DT, np.random.default_rng(0)))
    fault.centre, fault.disc = np.array([1.2, -1.1]), 0.3  # over the corner (1, -1)
    np.testing.assert_array_equal(fault.covered(), [False, False, True, False])
    r = fault.apply(frame, 0.0, DT, np.random.default_rng(0))
    assert lost(r) and str(r["tag_reason"]) == REASON_OCCLUDED
    assert int(r["tag_status"]) == tag_status_code(REASON_OCCLUDED) > 1
    # a tag already missed keeps its own reason
    missed = tag_reading(None, "tag too small in the image")
    assert (
        str(fault.apply(missed, 0.0, DT, np.random.default_rng(0))["tag_reason"])
        == "tag too small in the image"
    )


def test_tag_occlusion_episodes_have_the_rate_and_duration_asked() -> None:
    rate, duration = 0.1, 2.0  # busy 20 / (20 + 100) of the time

    def episodes(seed: int, n: int) -> tuple[list[bool], list[bool]]:
        fault = TagOcclusion(rate=rate, mean_duration=duration, radius=(0.2, 1.5))
        rng = SeedStreams(seed).generator("fault.tag_occlusion")
        fault.reset(rng)
        active, lost_ = [], []
        for i in range(n):
            lost_.append(lost(fault.apply(tag_reading(CORNERS, ""), i * DT, DT, rng)))
            active.append(fault.active)
        return active, lost_

    active, flags = episodes(2, 100000)  # 5000 s
    busy = rate * duration
    assert np.mean(active) == pytest.approx(busy / (1 + busy), abs=0.03)
    assert np.mean(bursts(active)) * DT == pytest.approx(duration, rel=0.15)
    # the tag is lost only during an episode, in some of them (the disc over a corner), not all
    assert not any(f and not a for a, f in zip(active, flags, strict=True))
    assert 0.2 * sum(active) < sum(flags) < 0.9 * sum(active)
    assert episodes(2, 2000) == (active[:2000], flags[:2000])


def test_imu_bias_step_adds_its_step_from_the_onset() -> None:
    fault = ImuBiasStep(gyro=0.02, accel=(0.0, 0.1, 0.0), onset=(1.0, 3.0))
    out = run(fault, [imu()] * 100, seed=4)
    assert 1.0 <= fault.start <= 3.0
    assert np.linalg.norm(fault.gyro_step) == pytest.approx(0.02, rel=1e-9)
    for i, r in enumerate(out):
        on = i * DT >= fault.start
        np.testing.assert_allclose(r["angular_velocity"] - imu()["angular_velocity"], fault.gyro_step * on)
        np.testing.assert_allclose(r["linear_acceleration"] - imu()["linear_acceleration"], [0, 0.1 * on, 0])
        np.testing.assert_array_equal(r["quaternion"], imu()["quaternion"])
    other = ImuBiasStep(gyro=0.02, accel=(0.0, 0.1, 0.0), onset=(1.0, 3.0))
    run(other, [imu()], seed=4)
    assert other.start == fault.start and np.array_equal(other.gyro_step, fault.gyro_step)
    run(other, [imu()], seed=9)
    assert other.start != fault.start and not np.allclose(other.gyro_step, fault.gyro_step)


def test_each_fault_draws_only_from_its_own_stream() -> None:
    """Two runs from the same fault streams agree whatever the other faults are."""
    readings = [{**tof(), **tag_reading(CORNERS, "")} for _ in range(300)]

    def through(option: dict[str, Any]) -> list[dict[str, np.ndarray]]:
        faults = build_faults(check_faults(option))
        streams = SeedStreams(7)
        rngs = {n: streams.generator(f"fault.{n}") for n in faults}
        for n, f in faults.items():
            f.reset(rngs[n])
        return [apply_faults(faults, r, i * DT, DT, rngs.__getitem__) for i, r in enumerate(readings)]

    alone = through({"camera_dropout": {"loss_rate": 0.3}})
    with_tof = through({"tof_dead": {"onset": (0.0, 10.0)}, "camera_dropout": {"loss_rate": 0.3}})
    assert [lost(r) for r in alone] == [lost(r) for r in with_tof]
    assert any(lost(r) for r in alone)


# -- the estimators through a dead ToF -------------------------------------------------------------
class FaultyReadings(gym.ObservationWrapper):  # type: ignore[type-arg]
    """Applies faults to a raw deck env's observation (what World.sensing.read_sensors does)."""

    def __init__(self, env: gym.Env, option: dict[str, Any]) -> None:
        super().__init__(env)
        self.faults = build_faults(check_faults(option, context={"tof_max_range": 4.0}))
        self.steps = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        streams = SeedStreams(0 if seed is None else seed)
        self.rngs = {n: streams.generator(f"fault.{n}") for n in self.faults}
        for n, f in self.faults.items():
            f.reset(self.rngs[n])
        self.steps = 0
        return super().reset(seed=seed, options=options)

    def step(self, action: Any) -> Any:
        self.steps += 1
        return super().step(action)

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        dt = 1.0 / self.env.unwrapped.config.world.control_hz
        return {
            **observation,
            **apply_faults(self.faults, observation, self.steps * dt, dt, self.rngs.__getitem__),
        }


def hover_with(
    option: dict[str, Any], steps: int = 80, seed: int = 3, preset: str = "ideal"
) -> list[tuple[dict, dict]]:
    from ihrcf_env.config.make import make_config
    from ihrcf_env.envs.deck_landing import DeckLandingEnv
    from ihrcf_env.wrappers.estimates import DeckPoseObservation

    raw = DeckLandingEnv(make_config(task="hover", camera_model="projected", sensor_preset=preset))
    env = DeckPoseObservation(FaultyReadings(raw, option), estimators=("ihrcf", "atda", "fused"))
    try:
        obs, info = env.reset(seed=seed)
        out = []
        for _ in range(steps):
            obs, _, term, trunc, info = env.step(np.zeros(env.action_space.shape, np.float32))
            assert not (term or trunc)
            out.append((obs, info))
        return out
    finally:
        env.close()


def test_ihrcf_works_from_three_ranges_and_says_why_not_from_two() -> None:
    for obs, info in hover_with({"tof_dead": {"sensors": [2]}}, steps=20):
        assert list(obs["ranges_valid"]) == [1, 1, 0, 1]
        assert obs["ihrcf"]["valid"] == 1, info["ihrcf_reason"]
        err = np.linalg.norm(obs["ihrcf"]["position"] - obs["ground_truth"]["position"])
        assert err < 0.02
    for obs, info in hover_with({"tof_dead": {"sensors": [0, 3]}}, steps=5):
        assert obs["ihrcf"]["valid"] == 0
        assert info["ihrcf_reason"] == "fewer than 3 valid ranges"


def test_fused_estimate_stays_valid_through_a_tof_dying() -> None:
    """ps3 dies 2 s into a 5 s hover with the realistic sensors: the fused estimate, valid before,
    stays valid and accurate."""
    run_ = hover_with({"tof_dead": {"sensors": [2], "onset": 2.0}}, steps=100, preset="realistic")
    ps3 = [int(obs["ranges_valid"][2]) for obs, _ in run_]
    assert sum(ps3[:39]) >= 35 and not any(ps3[39:])  # dead from t = 40 * 0.05 s = 2 s
    converged = next(i for i, (obs, _) in enumerate(run_) if obs["fused"]["valid"] == 1)
    assert converged < 30
    for obs, info in run_[converged:]:
        assert obs["fused"]["valid"] == 1, info["fused_reason"]
        err = np.linalg.norm(obs["fused"]["position"] - obs["ground_truth"]["position"])
        assert err < 0.03
