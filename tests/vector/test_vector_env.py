"""The landing tasks' vector env (gym.make_vec): Gymnasium 1.x semantics, equal to single envs."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ihrcf_env
from ihrcf_env.control.policies import ScriptedLanding
from ihrcf_env.vector import DeckLandingVectorEnv

V2 = ihrcf_env.LANDING_V2_ID
OPTIONS: dict[str, Any] = {"camera_model": "projected", "level": "calm"}


@pytest.fixture
def make_vec(closing: Callable[[Any], Any]) -> Callable[..., DeckLandingVectorEnv]:
    """``make_vec(n, **options)``: ``gym.make_vec(v2, num_envs=n)`` closed when the test ends."""
    return lambda n, **o: closing(gym.make_vec(V2, num_envs=n, **{**OPTIONS, **o}))


def test_make_vec_uses_the_native_vector_env(make_vec: Callable[..., Any]) -> None:
    v = make_vec(3)
    assert isinstance(v, DeckLandingVectorEnv) and v.num_envs == 3
    single = v.single_observation_space
    assert v.observation_space.shape == (3, *single.shape) and v.action_space.shape == (3, 4)
    obs, info = v.reset(seed=7)
    assert obs.shape == (3, *single.shape) and obs.dtype == single.dtype
    assert info["_time"].all() and info["time"].shape == (3,)


def test_each_sub_env_reproduces_the_single_env_through_an_autoreset(
    make_vec: Callable[..., Any], make_env: Callable[..., gym.Env]
) -> None:
    """Sub-env i of reset(seed=s) is the single env of seed s + i, step for step, bit for bit, also
    after its episode ends (next-step autoreset: the following step returns the first observation
    of a new episode with reward 0)."""
    n, seed = 2, 100_000
    v = make_vec(n, max_episode_steps=60)
    singles = [make_env(V2, **OPTIONS, max_episode_steps=60) for _ in range(n)]
    policies = [ScriptedLanding.from_env(e) for e in singles]
    obs, _ = v.reset(seed=seed)
    s_obs = [e.reset(seed=seed + i)[0] for i, e in enumerate(singles)]
    for p in policies:
        p.reset()
    ended = [False] * n
    resets = 0
    for _ in range(70):  # beyond the 60-step limit: every env autoresets once
        actions = np.stack([p.act(o) for p, o in zip(policies, s_obs, strict=True)])
        obs, reward, terminated, truncated, info = v.step(actions)
        for i, e in enumerate(singles):
            if ended[i]:  # the vector env reset it; the single env is reset with its own seed stream
                s_obs[i], _ = e.reset()
                policies[i].reset()
                assert reward[i] == 0.0 and not terminated[i] and not truncated[i]
                ended[i] = False
                resets += 1
            else:
                s_obs[i], r, te, tr, _ = e.step(actions[i])
                assert reward[i] == r and terminated[i] == te and truncated[i] == tr
                ended[i] = te or tr
            np.testing.assert_array_equal(obs[i], s_obs[i])
    assert resets >= n  # every env went through an autoreset


def test_the_vector_env_is_deterministic(make_vec: Callable[..., Any]) -> None:
    runs = []
    for _ in range(2):
        v = make_vec(2)
        obs, _ = v.reset(seed=3)
        seq = [obs]
        rng = np.random.default_rng(0)
        for _ in range(10):
            obs, reward, *_ = v.step(rng.uniform(-0.5, 0.5, (2, 4)).astype(np.float32))
            seq += [obs, reward]
        runs.append(seq)
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    ("kwargs", "exc", "name"),
    [
        ({"num_envs": 0}, ValueError, "num_envs"),
        ({"num_envs": 1.5}, TypeError, "num_envs"),
        ({"num_envs": "2"}, TypeError, "num_envs"),
        ({"num_envs": 10**6}, ValueError, "num_envs"),
        ({"num_envs": 2, "render_mode": "rgb_array"}, ValueError, "render_mode"),
        ({"num_envs": 2, "level": "stormy"}, ValueError, "level"),
    ],
)
def test_bad_arguments_are_named(kwargs: dict[str, Any], exc: type, name: str, no_leaks: None) -> None:
    with pytest.raises(exc, match=name):
        DeckLandingVectorEnv(V2, **{**OPTIONS, **kwargs})


def test_bad_actions_and_seeds_are_named(make_vec: Callable[..., Any]) -> None:
    v = make_vec(2)
    with pytest.raises(ValueError, match="seed"):
        v.reset(seed=[1, 2, 3])
    with pytest.raises(TypeError, match="seed"):
        v.reset(seed="1")
    v.reset(seed=[1, None])
    with pytest.raises(ValueError, match="actions"):
        v.step(np.zeros(4, np.float32))  # one action for two envs
    with pytest.raises(ValueError, match="actions"):
        v.step(np.zeros((3, 4), np.float32))
    with pytest.raises(TypeError, match="actions"):
        v.step(np.array([["a"] * 4] * 2))


def test_close_releases_every_client(no_leaks: None) -> None:
    v = gym.make_vec(V2, num_envs=3, **OPTIONS)
    v.reset(seed=0)
    v.close()
    v.close()  # twice is fine
    with pytest.raises(RuntimeError, match="closed"):
        v.step(np.zeros((3, 4), np.float32))


def test_same_step_autoreset_returns_the_next_first_observation(
    make_vec: Callable[..., Any], make_env: Callable[..., gym.Env]
) -> None:
    """autoreset_mode=SAME_STEP: the step that ends an episode returns the next episode's first
    observation, with the last one and its info in final_obs / final_info (SyncVectorEnv's way)."""
    from gymnasium.vector import AutoresetMode

    v = make_vec(2, max_episode_steps=3, autoreset_mode=AutoresetMode.SAME_STEP)
    assert v.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    single = make_env(V2, **OPTIONS, max_episode_steps=3)
    v.reset(seed=5)
    single.reset(seed=5)
    zero = np.zeros((2, 4), np.float32)
    for _ in range(3):
        obs, reward, terminated, truncated, info = v.step(zero)
        s_obs, s_r, _, s_tr, s_info = single.step(zero[0])
    assert truncated.all() and s_tr
    assert info["_final_obs"].all()
    np.testing.assert_array_equal(info["final_obs"][0], s_obs)
    assert info["final_info"]["time"][0] == s_info["time"]
    first, _ = single.reset()
    np.testing.assert_array_equal(obs[0], first)
    obs, reward, terminated, truncated, info = v.step(zero)  # no extra reset step
    assert not truncated.any() and "final_obs" not in info


def test_an_unknown_autoreset_mode_is_refused_by_name(make_vec: Callable[..., Any]) -> None:
    with pytest.raises(ValueError, match="autoreset_mode"):
        make_vec(1, autoreset_mode="whenever")


def test_the_time_limit_comes_from_the_spec_and_no_wrapper_is_stripped(closing: Callable[[Any], Any]) -> None:
    """The sub-envs are what the id's entry point makes (no TimeLimit, OrderEnforcing or checker
    under them); the limit is the spec's unless max_episode_steps overrides it (-1: none)."""
    from ihrcf_env.wrappers.landing_obs import LandingObservation

    spec_limit = gym.spec(V2).max_episode_steps
    v = closing(DeckLandingVectorEnv(V2, 1, **OPTIONS))
    assert v.max_episode_steps == spec_limit and isinstance(v.envs[0], LandingObservation)
    assert closing(gym.make_vec(V2, num_envs=1, **OPTIONS)).max_episode_steps == spec_limit
    assert closing(gym.make_vec(V2, num_envs=1, max_episode_steps=-1, **OPTIONS)).max_episode_steps is None
    v = closing(gym.make_vec(V2, num_envs=1, max_episode_steps=2, **OPTIONS))
    v.reset(seed=0)
    zero = np.zeros((1, 4), np.float32)
    assert not v.step(zero)[3][0] and v.step(zero)[3][0]
    for bad, error in ((0, ValueError), (-2, ValueError), (2.5, TypeError), ("600", TypeError)):
        with pytest.raises(error, match="max_episode_steps"):
            DeckLandingVectorEnv(V2, 1, max_episode_steps=bad, **OPTIONS)


def test_the_vector_entry_points_are_named_by_string() -> None:
    import pickle

    for env_id in ihrcf_env.VECTOR_IDS:
        spec = gym.spec(env_id)
        assert isinstance(spec.vector_entry_point, str) and spec.vector_entry_point.startswith(
            "ihrcf_env.vector:"
        )
        assert pickle.loads(pickle.dumps(spec)).vector_entry_point == spec.vector_entry_point


def test_the_vector_package_reads_no_private_or_stripped_wrapper() -> None:
    """The vector envs build their sub-envs' pieces themselves: no ``env.unwrapped``, no private
    attribute of another object, no Gymnasium wrapper taken apart."""
    import ast
    from pathlib import Path

    import ihrcf_env.vector

    banned = {"unwrapped", "TimeLimit", "OrderEnforcing", "PassiveEnvChecker", "_max_episode_steps"}
    for path in Path(ihrcf_env.vector.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            name = (
                node.attr
                if isinstance(node, ast.Attribute)
                else node.id
                if isinstance(node, ast.Name)
                else ""
            )
            assert name not in banned, f"{path.name}:{node.lineno} uses {name}"
            if (
                isinstance(node, ast.Attribute)
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
            ):
                owner = node.value
                assert isinstance(owner, ast.Name) and owner.id == "self", (
                    f"{path.name}:{node.lineno} reads {node.attr} of another object"
                )


def test_the_removed_physics_option_is_refused_by_name(no_leaks: None) -> None:
    """``physics`` (the numpy batched physics was removed) is a ValueError naming it and the JAX
    backend, before any env is built, by every vector env."""
    removed = r'physics: .*numpy batched physics were removed.*gym\.make_vec\(.*backend="jax"\)'
    with pytest.raises(ValueError, match=removed):
        DeckLandingVectorEnv(V2, 2, camera_model="projected", physics="numpy")
    with pytest.raises(ValueError, match=removed):
        gym.make_vec(V2, num_envs=2, camera_model="projected", physics="numpy")
    with pytest.raises(ValueError, match=removed):
        gym.make_vec(V2, num_envs=2, workers=2, camera_model="projected", physics="numpy")


def test_the_jax_backend_refuses_physics_by_name() -> None:
    pytest.importorskip("jax")
    with pytest.raises(ValueError, match=r"physics: .*numpy batched physics were removed"):
        gym.make_vec(V2, num_envs=2, backend="jax", physics="numpy")
