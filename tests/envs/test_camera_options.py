"""Camera options of the env: ``camera_model``, ``camera_output``, ``camera_hz``, ``detector_model``.

What the options deliver (image vs tag corners), the held frames between camera frames with their
age, bitwise determinism per mode, and bad input (errors naming the option, before any client)."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import ihrcf_env  # noqa: F401  (registers the envs)
from ihrcf_env.config.make import make_config

RAW = "ihrcf_env/DeckHoverRaw-v0"
WRAPPED = "ihrcf_env/DeckHover-v0"


def _rollout(env: gym.Env, steps: int, seed: int = 3) -> tuple[list, list]:
    obs, info = env.reset(seed=seed)
    out, infos = [obs], [info]
    rng = np.random.default_rng(1)
    for _ in range(steps):
        obs, _, term, trunc, info = env.step(rng.uniform(-0.3, 0.3, 4))
        out.append(obs)
        infos.append(info)
        if term or trunc:
            break
    return out, infos


# -- what each mode delivers -----------------------------------------------------------------------
@pytest.mark.parametrize("model", ["rendered", "projected"])
def test_corner_output_replaces_the_image(make_env, model):
    env = make_env(RAW, camera_model=model, camera_output="corners", deck_profile="static")
    assert "image" not in env.observation_space.spaces
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert obs["tag_detected"] == 1 and info["tag_reason"] == ""
    c = obs["tag_corners"]
    assert c.shape == (4, 2) and np.all((c > 0) & (c < 512))


def test_projected_defaults_to_corners_and_the_wrapper_drops_the_image(make_env):
    env = make_env(WRAPPED, camera_model="projected", deck_profile="static")
    obs, info = env.reset(seed=0)
    assert "image" not in obs and obs["tag_detected"] == 1
    assert obs["ihrcf"]["valid"] == 1
    assert {"ihrcf_age", "atda_age", "fused_age", "camera_time", "camera_age"} <= set(info)


def test_keep_image_false_renders_the_tag_window(make_env):
    env = make_env(WRAPPED, keep_image=False, deck_profile="static")
    assert env.unwrapped.config.world.camera_output == "corners"
    obs, _ = env.reset(seed=0)
    assert "image" not in obs and obs["ihrcf"]["valid"] == 1
    kept = make_env(WRAPPED, keep_image=False, camera_output="image", deck_profile="static")
    assert kept.unwrapped.config.world.camera_output == "image"  # an explicit camera_output wins


# -- camera_hz: frames held, ages reported ---------------------------------------------------------
def test_camera_hz_holds_frames_and_reports_their_age(make_env):
    env = make_env(WRAPPED, camera_model="projected", camera_hz=5, deck_profile="paper")
    obs, infos = _rollout(env, 9)
    for k, info in enumerate(infos):
        t = info["time"]
        assert info["camera_time"] == pytest.approx(0.2 * (k // 4))
        assert info["camera_age"] == pytest.approx(t - info["camera_time"])
        for name in ("ihrcf", "atda", "fused"):
            assert info[f"{name}_age"] == pytest.approx(info["camera_age"])
    # estimates change only on camera frames; the sensors' ranges every step
    for k in range(1, len(obs)):
        same = np.array_equal(obs[k]["ihrcf"]["position"], obs[k - 1]["ihrcf"]["position"])
        assert same == (k % 4 != 0), k
    assert not np.array_equal(obs[1]["ranges"], obs[2]["ranges"])


def test_held_image_is_a_fresh_array_each_step(make_env):
    env = make_env(RAW, camera_hz=10, deck_profile="static")
    o0, _ = env.reset(seed=0)
    o1, *_ = env.step(np.zeros(4))
    assert np.array_equal(o0["image"], o1["image"]) and o0["image"] is not o1["image"]


# -- determinism -----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs",
    [
        {"camera_model": "projected"},
        {"camera_model": "projected", "sensor_preset": "realistic", "camera_hz": 10},
        {"keep_image": False, "sensor_preset": "realistic"},
    ],
    ids=["projected", "projected-realistic-10hz", "window-realistic"],
)
def test_same_seed_same_actions_bitwise_equal(make_env, kwargs):
    runs = []
    for _ in range(2):
        env = make_env(WRAPPED, flatten=True, **kwargs)
        runs.append(np.stack(_rollout(env, 12)[0]))
    assert runs[0].tobytes() == runs[1].tobytes()


# -- bad input -------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "error", "names"),
    [
        ({"camera_model": "fast"}, ValueError, "camera_model"),
        ({"camera_model": 1}, TypeError, "camera_model"),
        ({"camera_output": "pixels"}, ValueError, "camera_output"),
        ({"camera_model": "projected", "camera_output": "image"}, ValueError, "camera_output"),
        ({"camera_hz": 7}, ValueError, "camera_hz"),
        ({"camera_hz": 0}, ValueError, "camera_hz"),
        ({"camera_hz": 10.0}, TypeError, "camera_hz"),
        ({"camera_hz": True}, TypeError, "camera_hz"),
        ({"camera": False, "camera_hz": 10}, ValueError, "camera_hz"),
        ({"camera": False, "camera_model": "projected"}, ValueError, "camera_model"),
        ({"detector_model": 3, "camera_model": "projected"}, TypeError, "detector_model"),
        ({"detector_model": "x.json"}, ValueError, "detector_model"),  # rendered: unused
    ],
)
def test_bad_camera_options_name_the_option(kwargs, error, names):
    with pytest.raises(error, match=names):
        make_config(**kwargs)


def test_projected_with_keep_image_is_rejected():
    with pytest.raises(ValueError, match="keep_image=True"):
        gym.make(WRAPPED, camera_model="projected", keep_image=True)


@pytest.mark.parametrize("content", [None, "{not json", json.dumps({"version": 1})])
def test_missing_or_corrupt_detector_model_names_the_file_and_the_fit_command(tmp_path, content):
    path = tmp_path / "model.json"
    if content is not None:
        path.write_text(content)
    with pytest.raises(Exception, match="fit[-_]detector") as err:
        make_config(camera_model="projected", detector_model=str(path))
    assert str(path) in str(err.value)
