"""The vector env with the numpy physics: its worlds advance together, each as the single env."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ihrcf_env
from ihrcf_env.control.policies import ScriptedLanding

V2 = ihrcf_env.LANDING_V2_ID
OPTIONS: dict[str, Any] = {"camera_model": "projected", "level": "moderate", "physics": "numpy"}


def test_sub_envs_reproduce_the_single_numpy_env_through_touchdowns(
    closing: Callable[[Any], Any], make_env: Callable[..., gym.Env]
) -> None:
    """Worlds advanced together (and their ToF rays cast together) equal worlds advanced alone,
    bit for bit, through landings (the contacts in closed form) and autoresets; the controller sees
    the same observations (each env's own estimators: bitwise)."""
    n, seed = 3, 200
    v = closing(gym.make_vec(V2, num_envs=n, **OPTIONS))
    singles = [make_env(V2, **OPTIONS) for _ in range(n)]
    policies = [ScriptedLanding.from_env(e) for e in singles]
    obs, _ = v.reset(seed=seed)
    s_obs = [e.reset(seed=seed + i)[0] for i, e in enumerate(singles)]
    for p in policies:
        p.reset()
    np.testing.assert_array_equal(obs, np.stack(s_obs))
    ended = [False] * n
    touchdowns = 0
    for _ in range(700):
        actions = np.stack([p.act(o) for p, o in zip(policies, s_obs, strict=True)])
        obs, reward, terminated, truncated, info = v.step(actions)
        for i, e in enumerate(singles):
            if ended[i]:
                s_obs[i], _ = e.reset()
                policies[i].reset()
                ended[i] = False
            else:
                s_obs[i], r, te, tr, s_info = e.step(actions[i])
                assert reward[i] == r and terminated[i] == te and truncated[i] == tr
                touchdowns += "touchdown" in s_info
                ended[i] = te or tr
            np.testing.assert_array_equal(obs[i], s_obs[i])
        if touchdowns >= n:
            break
    assert touchdowns >= n


@pytest.mark.parametrize("bad", [{"physics": "bullet"}, {"physics": 1}])
def test_the_physics_option_is_checked_by_name(bad: dict[str, Any], make_env: Callable[..., gym.Env]) -> None:
    with pytest.raises((TypeError, ValueError), match="physics"):
        make_env(V2, camera_model="projected", **bad)


def test_cameras_read_together_as_alone(
    closing: Callable[[Any], Any], make_env: Callable[..., gym.Env]
) -> None:
    """With the ideal projected camera the numpy worlds' tag cameras are read in one batched call
    (each from its own generator and corner track): the frames equal each world's own, bit for bit,
    through the camera's latency line and lost frames."""
    from ihrcf_env.sim.sensors import tag_camera

    options = {**OPTIONS, "camera_quality": "ideal", "max_episode_steps": 80}
    n = 3
    v = closing(gym.make_vec(V2, num_envs=n, **options))
    singles = [make_env(V2, **options) for _ in range(n)]
    taken: list[bool] = []
    read = tag_camera.ProjectedTagCamera._read_closed_form

    def spy(self: Any, state: Any, rng: Any) -> Any:
        taken.append(self.prefetched is not None)
        return read(self, state, rng)

    tag_camera.ProjectedTagCamera._read_closed_form = spy  # type: ignore[method-assign]
    try:
        obs, _ = v.reset(seed=40)
        s_obs = [e.reset(seed=40 + i)[0] for i, e in enumerate(singles)]
        rng = np.random.default_rng(2)
        ended = [False] * n
        for _ in range(100):
            a = (rng.uniform(-1, 1, (n, 4)) * [0.3, 0.3, 0.3, 0.2] + [0.0, 0.0, -0.2, 0.0]).astype(np.float32)
            obs, *_ = v.step(a)
            for i, e in enumerate(singles):
                if ended[i]:
                    s_obs[i], _ = e.reset()
                    ended[i] = False
                else:
                    s_obs[i], _, te, tr, _ = e.step(a[i])
                    ended[i] = te or tr
                np.testing.assert_array_equal(obs[i], s_obs[i])
    finally:
        tag_camera.ProjectedTagCamera._read_closed_form = read  # type: ignore[method-assign]
    assert sum(taken) > 100 and not all(taken)  # the vector env's reads ahead, the singles' own
