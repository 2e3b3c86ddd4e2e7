"""The start curriculum (``ihrcf_env.rl.curriculum``, no torch): starts between the easy and the
task's distribution by level, the env's own start at level 1, seeded, and bad input rejected."""

from __future__ import annotations

import numpy as np
import pytest

from ihrcf_env.rl.curriculum import StartCurriculum
from ihrcf_env.rl.envs import input_indices, make_env, name_value, policy_inputs


@pytest.fixture(scope="module")
def env():
    e = StartCurriculum(make_env("ihrcf_env/DeckLanding-v1", "projected"), full_fraction=0.0)
    yield e
    e.close()


def _start(e: StartCurriculum, seed: int) -> tuple[float, float]:
    e.reset(seed=seed)
    s = e.unwrapped.world.sensing.snapshot()
    return float(s.drone_position[2] - s.deck_position[2]), e.unwrapped.tag_offset(s)


def test_level_interpolates_the_start_between_easy_and_the_task(env: StartCurriculum) -> None:
    for level, (lo, hi), radius in ((0.0, (0.4, 0.8), 0.1), (0.5, (0.95, 1.9), 0.55)):
        env.set_curriculum_level(level)
        starts = [_start(env, seed) for seed in range(12)]
        alts = [a for a, _ in starts]
        assert all(lo - 0.02 <= a <= hi + 0.02 for a in alts), (level, alts)
        assert max(alts) - min(alts) > 0.3 * (hi - lo)  # spread over the interval, not one point
        assert all(off <= radius + 0.02 for _, off in starts), (level, starts)
    env.set_curriculum_level(0.0)
    assert _start(env, 7) == _start(env, 7)  # seeded


def test_level_one_is_the_task_start_bitwise(closing, env: StartCurriculum) -> None:
    env.set_curriculum_level(1.0)
    plain = closing(make_env("ihrcf_env/DeckLanding-v1", "projected"))
    for seed in (0, 5):
        obs, info = env.reset(seed=seed)
        ref, _ = plain.reset(seed=seed)
        assert np.array_equal(obs, ref) and info["curriculum_level"] == 1.0


def test_full_fraction_and_explicit_options_keep_the_task_start(closing) -> None:
    plain = closing(make_env("ihrcf_env/DeckLanding-v1", "projected"))
    always = closing(StartCurriculum(make_env("ihrcf_env/DeckLanding-v1", "projected"), full_fraction=1.0))
    assert np.array_equal(always.reset(seed=3)[0], plain.reset(seed=3)[0])
    always.full_fraction = 0.0
    opts = {"altitude": 2.0, "offset": (0.1, 0.0)}
    assert np.array_equal(always.reset(seed=4, options=opts)[0], plain.reset(seed=4, options=opts)[0])


def test_bad_input_names_the_parameter(closing) -> None:
    e = closing(make_env("ihrcf_env/DeckLanding-v1", "projected"))
    with pytest.raises(ValueError, match="easy_altitude"):
        StartCurriculum(e, easy_altitude=(0.1, 0.5))
    with pytest.raises(ValueError, match="easy_altitude"):
        StartCurriculum(e, easy_altitude=(1.0, 0.5))
    with pytest.raises(TypeError, match="easy_altitude"):
        StartCurriculum(e, easy_altitude="low")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="easy_offset"):
        StartCurriculum(e, easy_offset="near")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="full_fraction"):
        StartCurriculum(e, full_fraction=None)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="easy_offset"):
        StartCurriculum(e, easy_offset=2.0)
    with pytest.raises(ValueError, match="full_fraction"):
        StartCurriculum(e, full_fraction=1.5)
    with pytest.raises(ValueError, match="level"):
        StartCurriculum(e).set_curriculum_level(1.2)
    v0 = closing(make_env("ihrcf_env/DeckHover-v0", "projected"))
    with pytest.raises(TypeError, match="DeckLanding-v1"):
        StartCurriculum(v0)


def test_name_value_parses_command_line_weights() -> None:
    assert name_value("time=2") == ("time", 2.0) and name_value("crash=1e2") == ("crash", 100.0)
    for bad in ("time", "=2", "time=x", "time=nan", "time=inf"):
        with pytest.raises(ValueError, match="NAME=NUMBER"):
            name_value(bad)


def test_input_indices_drop_named_fields(env: StartCurriculum) -> None:
    slices = env.get_wrapper_attr("obs_slices")
    n = slices["all"].stop
    keep = input_indices(slices, ["ihrcf", "atda"])
    assert len(keep) == n - 20 and keep == sorted(keep)
    dropped = set(range(n)) - set(keep)
    assert dropped == set(range(n)[slices["ihrcf"]]) | set(range(n)[slices["atda"]])
    assert input_indices(slices, []) == list(range(n))
    assert policy_inputs(lambda: make_env("ihrcf_env/DeckLanding-v1", "projected"), ["ihrcf", "atda"]) == keep
    assert policy_inputs(lambda: make_env("ihrcf_env/DeckLanding-v1", "projected"), []) is None
    for bad in (["imu"], ["all"], ["fused", "nonsense"]):
        with pytest.raises(ValueError, match="unknown observation field"):
            input_indices(slices, bad)
    with pytest.raises(ValueError, match="leaves no observation"):
        input_indices({"all": slice(0, 2), "a": slice(0, 2)}, ["a"])


def test_frame_stack_gives_the_last_observations_and_stacked_inputs(closing) -> None:
    plain = closing(make_env("ihrcf_env/DeckLanding-v1", "projected"))
    stacked = closing(make_env("ihrcf_env/DeckLanding-v1", "projected", frame_stack=3))
    n = plain.observation_space.shape[0]
    assert stacked.observation_space.shape == (3, n)
    first, _ = stacked.reset(seed=4)
    flat, _ = plain.reset(seed=4)
    np.testing.assert_array_equal(first, np.stack([flat] * 3))  # the first observation repeated
    action = np.array([0.0, 0.0, -0.3, 0.0], dtype=np.float32)
    seen = [flat] * 3
    for _ in range(4):
        obs, *_ = stacked.step(action)
        seen.append(plain.step(action)[0])
        np.testing.assert_array_equal(obs, np.stack(seen[-3:]))  # oldest first, newest last
    keep = input_indices(plain.get_wrapper_attr("obs_slices"), ["ihrcf"])
    made = policy_inputs(lambda: make_env("ihrcf_env/DeckLanding-v1", "projected", 2), ["ihrcf"])
    assert made == keep + [n + i for i in keep]
    for bad in (0, 65, 2.0, True):
        with pytest.raises(ValueError, match="frame_stack"):
            make_env("ihrcf_env/DeckLanding-v1", "projected", frame_stack=bad)
