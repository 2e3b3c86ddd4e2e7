"""Sensor timing: camera latency (a delay line), ToF and IMU on their own clocks, and the estimator
stage's timestamps. Defaults are unchanged: a default env's observations match values recorded
before the timing options existed."""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from ihrcf_env.config.make import make_config
from ihrcf_env.config.sensors import CameraConfig, IMUConfig, ToFConfig
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.envs.deck_landing import MAX_SENSOR_AGE, DeckLandingEnv
from ihrcf_env.sim.sensors.timing import NO_FRAME_YET, DelayLine, SampleClock

DATA = Path(__file__).parent / "data" / "default_observations.json"
ACTION = np.array([0.1, -0.05, -0.2, 0.0])


def _flat(obs: dict[str, Any]) -> dict[str, list[float]]:
    out = {}
    for k, v in sorted(obs.items()):
        if isinstance(v, dict):
            for k2, v2 in sorted(v.items()):
                out[f"{k}.{k2}"] = np.asarray(v2, np.float64).ravel().tolist()
        else:
            out[k] = np.asarray(v, np.float64).ravel().tolist()
    return out


def _env(
    camera_latency: float = 0.0, tof_hz: float | None = None, imu_hz: float | None = None, **options: Any
):
    """A raw env (projected corners) with the timing options set on its world config."""
    cfg = make_config(task="hover", raw=True, camera_model="projected", camera_output="corners", **options)
    w = cfg.world
    assert w.camera is not None
    world = dataclasses.replace(
        w,
        camera=dataclasses.replace(w.camera, latency=camera_latency),
        tof=dataclasses.replace(w.tof, rate_hz=tof_hz),
        imu=dataclasses.replace(w.imu, rate_hz=imu_hz),
    )
    return DeckLandingEnv(dataclasses.replace(cfg, world=world))


# --------------------------------------------------------------------------------- defaults


def test_default_observations_are_unchanged() -> None:
    """A raw env and the landing task's flat observation (estimators and fused filter included)
    reproduce observations recorded before the timing options existed."""
    recorded = json.loads(DATA.read_text())
    env = gym.make("ihrcf_env/DeckHoverRaw-v0", camera_model="projected", camera_output="corners")
    try:
        obs, _ = env.reset(seed=3)
        seq = [_flat(obs)]
        for _ in range(6):
            seq.append(_flat(env.step(ACTION)[0]))
    finally:
        env.close()
    assert [sorted(o) for o in seq] == [sorted(o) for o in recorded["raw_projected"]]
    for got, want in zip(seq, recorded["raw_projected"], strict=True):
        for key in want:
            np.testing.assert_allclose(got[key], want[key], rtol=1e-6, atol=1e-7, err_msg=key)
    with warnings.catch_warnings():  # gymnasium may point at a newer version of the id
        warnings.simplefilter("ignore", DeprecationWarning)
        env = gym.make("ihrcf_env/DeckLanding-v1", camera_model="projected")
    try:
        slices = env.get_wrapper_attr("obs_slices")
        flat = [np.asarray(env.reset(seed=3)[0], np.float64)]
        for _ in range(40):
            flat.append(np.asarray(env.step(ACTION)[0], np.float64))
    finally:
        env.close()
    got_v1, want_v1 = np.array(flat), np.array(recorded["landing_v1"])
    assert got_v1.shape == want_v1.shape
    solved = np.zeros(got_v1.shape[1], bool)
    for name in ("atda", "fused"):  # PnP's iterative refinement and the filter fed by it
        solved[slices[name]] = True
    # sensors, navigation and IHRCF's closed-form fit: float rounding only
    np.testing.assert_allclose(got_v1[:, ~solved], want_v1[:, ~solved], rtol=1e-6, atol=1e-7)
    # cv2's PnP refinement magnifies one-ulp input differences between x86-64 CPUs into a few
    # micro-units: 2e-5 (m in position, unit-vector components in the normal) is 0.02 mm / 1e-3 deg
    np.testing.assert_allclose(got_v1[:, solved], want_v1[:, solved], rtol=0.0, atol=2e-5)


def test_default_config_has_no_timing() -> None:
    w = WorldConfig()
    assert w.camera is not None and w.camera.latency == 0.0
    assert w.tof.rate_hz is None and w.imu.rate_hz is None
    env = _env()
    try:
        assert not {"camera_frame", "tof_age", "imu_age"} & set(env.observation_space.spaces)
        assert env.world.sensing.camera_pipeline is None and env.world.sensing.clocks == {}
    finally:
        env.close()


def test_timing_options_are_checked() -> None:
    with pytest.raises(ValueError, match="camera_latency"):
        CameraConfig(latency=-0.01)
    with pytest.raises(ValueError, match="camera_latency"):
        CameraConfig(latency=5.0)
    with pytest.raises(TypeError, match="camera_latency"):
        CameraConfig(latency="0.05")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="tof_hz"):
        ToFConfig(rate_hz=0.0)
    with pytest.raises(ValueError, match="tof_hz"):
        ToFConfig(rate_hz=math.nan)
    with pytest.raises(ValueError, match="imu_hz"):
        IMUConfig(rate_hz=1e6)
    with pytest.raises(ValueError, match="imu_hz"):
        WorldConfig(physics_hz=240, imu=IMUConfig(rate_hz=1000.0))


# ------------------------------------------------------------------------------ the clocks


def test_sample_clock_ticks() -> None:
    clock = SampleClock(33.0, 240)
    ticks = [clock.tick_of(k) for k in range(10)]
    assert ticks[0] == 0
    for k, tick in enumerate(ticks):  # the first physics tick at or after k / 33 s
        assert tick / 240 >= k / 33 - 1e-12 and (tick - 1) / 240 < k / 33
    assert clock.pending(1, 12) == [t for t in ticks if 1 <= t <= 12]
    clock.taken(8)
    assert clock.pending(1, 12) == [t for t in ticks if 8 < t <= 12]
    assert SampleClock(30.0, 240).pending(0, 24) == [0, 8, 16, 24]
    with pytest.raises(ValueError):
        SampleClock(500.0, 240)


def test_delay_line_delivers_at_the_first_tick_at_or_after_exposure_plus_latency() -> None:
    line = DelayLine(0.06, 240)  # 14.4 ticks
    line.push(0, {"x": np.array(0)})
    assert line.deliver(14) == []
    assert [t for t, _ in line.deliver(15)] == [0]
    line.push(12, {"x": np.array(1)})
    line.push(24, {"x": np.array(2)})
    assert [t for t, _ in line.deliver(48)] == [12, 24]  # both due: oldest first
    exact = DelayLine(0.05, 240)  # exactly 12 ticks
    exact.push(0, {})
    assert len(exact.deliver(12)) == 1


# ------------------------------------------------------------------------------ camera latency


@pytest.mark.parametrize(
    ("latency", "camera_hz", "age"), [(0.06, None, 0.1), (0.05, None, 0.05), (0.06, 10, 0.1)]
)
def test_camera_latency_delays_each_frame(latency: float, camera_hz: int | None, age: float) -> None:
    """Frames arrive at the first control step at or after exposure + latency: the corners are the
    ones a camera without latency showed at the exposure step, ``camera_age`` is the exposure's age
    and ``camera_frame`` counts them; before the first, no corners and the largest age."""
    late = _env(latency, camera_hz=camera_hz)
    now = _env(0.0, camera_hz=camera_hz)
    try:
        assert "camera_frame" in late.observation_space.spaces
        o_late, info = late.reset(seed=5)
        o_now, _ = now.reset(seed=5)
        assert late.observation_space.contains(o_late)
        assert o_late["tag_detected"] == 0 and o_late["camera_frame"][0] == 0
        assert info["tag_reason"] == NO_FRAME_YET
        assert o_late["camera_age"][0] == pytest.approx(MAX_SENSOR_AGE)
        shown = [o_now]
        delay = round(age * 20)  # control steps
        for k in range(1, 12):
            o_late, *_, info = late.step(np.zeros(4))
            shown.append(now.step(np.zeros(4))[0])
            assert late.observation_space.contains(o_late)
            if k < delay:
                assert o_late["camera_frame"][0] == 0 and o_late["tag_detected"] == 0
                continue
            exposed = info["camera_time"]
            assert info["time"] - exposed >= latency - 1e-9
            step = round(exposed * 20)
            np.testing.assert_array_equal(o_late["tag_corners"], shown[step]["tag_corners"])
            assert o_late["camera_age"][0] == pytest.approx(info["time"] - exposed, abs=1e-6)
            every = 1 if camera_hz is None else 20 // camera_hz
            assert o_late["camera_frame"][0] == step // every + 1
            if (k - delay) % every == 0:  # a frame arrived at this step
                assert o_late["camera_age"][0] == pytest.approx(age, abs=1e-6)
    finally:
        late.close()
        now.close()


# --------------------------------------------------------------------------- own clocks


def test_tof_and_imu_at_the_control_rate_match_the_default() -> None:
    """On their own clock at the control rate, ToF and (ideal) IMU samples are the default ones."""
    a, b = _env(tof_hz=20.0, imu_hz=20.0), _env()
    try:
        oa, ob = a.reset(seed=2)[0], b.reset(seed=2)[0]
        for _ in range(5):
            np.testing.assert_array_equal(oa["ranges"], ob["ranges"])
            for key in ob["imu"]:
                np.testing.assert_allclose(oa["imu"][key], ob["imu"][key], rtol=1e-12, atol=1e-12)
            assert oa["tof_age"][0] == 0.0 and oa["imu_age"][0] == 0.0
            oa, ob = a.step(ACTION)[0], b.step(ACTION)[0]
    finally:
        a.close()
        b.close()


def test_tof_samples_at_its_own_instants() -> None:
    """At 30 Hz with 20 Hz control, the ToF shows the sample taken mid control step: the ranges a
    60 Hz-controlled env (same physics) read at that instant, with its age."""
    own = _env(tof_hz=30.0)
    fine = _env(control_hz=60)
    try:
        own.reset(seed=4)
        fine.reset(seed=4)
        fine_ranges = {0: fine._get_obs()["ranges"]}
        for k in range(1, 13):
            fine_ranges[4 * k] = fine.step(np.zeros(4))[0]["ranges"]
        for _ in range(4):
            obs, *_, info = own.step(np.zeros(4))
            sample = own.world.sensing.sample_times["tof"]
            tick = round(sample * 240)
            assert tick % 8 == 0 and 0 <= info["time"] - sample < 1 / 30
            assert obs["tof_age"][0] == pytest.approx(info["time"] - sample, abs=1e-6)
            np.testing.assert_array_equal(obs["ranges"], fine_ranges[tick])
        assert {round(own.world.sensing.sample_times["tof"] * 240)} <= {8 * k for k in range(10)}
    finally:
        own.close()
        fine.close()


def test_imu_faster_than_control_shows_its_latest_sample() -> None:
    env = _env(imu_hz=200.0)
    try:
        env.reset(seed=0)
        for _ in range(4):
            obs, *_, info = env.step(ACTION)
            assert 0.0 <= obs["imu_age"][0] < 1 / 200 + 1e-6
            assert env.observation_space.contains(obs)
    finally:
        env.close()


# --------------------------------------------------------------------------- estimator stage


@pytest.mark.parametrize("compensate", [True, False])
def test_estimator_stage_stamps_frames_with_their_exposure(compensate: bool) -> None:
    """With a camera latency the stage estimates each delivered frame once (by ``camera_frame``),
    stamps it with its exposure (compensating: also its arrival, the IMU of the exposure's step and
    the ranges nearest to it), and each estimate's age is the exposure's age."""
    from ihrcf_env.wrappers.landing_obs import LandingObservation

    env = LandingObservation(_env(0.06, tof_hz=30.0))
    stage = env.stage
    stage.compensate_latency = compensate
    try:
        env.reset(seed=1)
        assert stage.last_frame is not None and stage.last_frame.corners is None
        assert stage.last_frame.corners_reason == NO_FRAME_YET
        assert all(math.isnan(a) for a in stage.ages.values())
        frames = []
        for _ in range(10):
            _, _, _, _, info = env.step(np.zeros(4))
            frame = stage.last_frame
            assert frame is not None
            if math.isnan(info["camera_time"]):  # no frame has arrived yet
                assert frame.corners is None and math.isnan(stage.ages["fused"])
                continue
            if frame not in frames:
                frames.append(frame)
            assert stage.ages["fused"] == pytest.approx(info["camera_age"], abs=1e-9)
            assert info["fused_age"] >= 0.06
            if not compensate:  # stamped with the arrival, as without latency
                assert frame.time == pytest.approx(info["time"], abs=1e-12)
                assert math.isnan(frame.arrival_time)
                continue
            assert frame.time == pytest.approx(info["camera_time"], abs=1e-12)
            assert frame.arrival_time == pytest.approx(info["time"], abs=1e-12)
            assert abs(frame.ranges_time - frame.time) <= 1 / 60 + 1e-9
        assert len(frames) == 9  # one per delivered frame (the first arrives at the second step)
        assert stage.last_estimates is not None and stage.last_estimates["ihrcf"].valid
    finally:
        env.close()
