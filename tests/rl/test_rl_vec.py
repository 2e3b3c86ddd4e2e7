"""The stable-baselines3 adapter of the vector env (``rl`` marker): SB3's reset/step convention
(the next episode's first observation, ``terminal_observation``, ``TimeLimit.truncated``), the seeds
of ``gym.make``, the sub-env attribute calls and a short PPO run on it."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.rl

ID = "ihrcf_env/DeckLanding-v1"
CAMERA = "projected"


def test_unbatch_info_keeps_each_envs_keys_and_nested_dicts() -> None:
    pytest.importorskip("stable_baselines3")
    from ihrcf_env.rl.vec import unbatch_info

    infos = {
        "a": np.array([1.0, 2.0]),
        "_a": np.array([True, False]),
        "d": {"x": np.array([3, 4]), "_x": np.array([False, True])},
        "_d": np.array([True, True]),
    }
    assert unbatch_info(infos, 0) == {"a": 1.0, "d": {}}
    assert unbatch_info(infos, 1) == {"d": {"x": 4}}
    assert type(unbatch_info(infos, 0)["a"]) is float


def test_sb3_vec_env_follows_sb3s_autoreset_and_gym_makes_seeds(closing) -> None:
    pytest.importorskip("stable_baselines3")
    from ihrcf_env.rl.envs import make_env
    from ihrcf_env.rl.vec import Sb3VectorEnv, make_sb3_vec_env

    n, seed, limit = 2, 7, 3
    venv = closing(make_sb3_vec_env(ID, n, seed, max_episode_steps=limit))
    assert isinstance(venv, Sb3VectorEnv) and venv.num_envs == n
    singles = [closing(make_env(ID, CAMERA, max_episode_steps=limit)) for _ in range(n)]
    assert venv.observation_space == singles[0].observation_space
    assert venv.action_space == singles[0].action_space
    obs = venv.reset()
    assert obs.shape == (n, *venv.observation_space.shape) and obs.dtype == np.float32
    for i, env in enumerate(singles):
        np.testing.assert_array_equal(obs[i], env.reset(seed=seed + i)[0])  # env i: seed + i
    assert all("time" in info for info in venv.reset_infos)
    rng = np.random.default_rng(0)
    for _ in range(limit):
        actions = rng.uniform(-1, 1, size=(n, 4)).astype(np.float32)
        obs, rewards, dones, infos = venv.step(actions)
        assert rewards.shape == (n,) and rewards.dtype == np.float32 and len(infos) == n
        expected = [env.step(a) for env, a in zip(singles, actions, strict=True)]
        for i, (o, r, term, trunc, _) in enumerate(expected):
            assert bool(dones[i]) == (term or trunc)
            assert rewards[i] == pytest.approx(float(r), rel=1e-6, abs=1e-6)
            assert infos[i]["TimeLimit.truncated"] == (trunc and not term)
            if dones[i]:
                np.testing.assert_array_equal(infos[i]["terminal_observation"], o)
                assert "is_success" in infos[i] and "final_obs" not in infos[i]
                assert not np.array_equal(obs[i], o)  # the next episode's first observation
            else:
                assert "terminal_observation" not in infos[i]
                np.testing.assert_array_equal(obs[i], o)
    assert dones.all()  # the time limit ends both at step 3
    assert all("time" in info and "final_info" not in info for info in venv.reset_infos)


def test_sb3_vec_env_refuses_next_step_autoreset_and_reaches_the_sub_envs(closing) -> None:
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    from stable_baselines3.common.vec_env import VecEnv

    from ihrcf_env.rl.vec import Sb3VectorEnv, make_sb3_vec_env

    native = closing(gym.make_vec(ID, num_envs=1, camera_model=CAMERA))  # next-step autoreset
    with pytest.raises(ValueError, match="autoreset"):
        Sb3VectorEnv(native)
    with pytest.raises(TypeError, match="vector_env"):
        Sb3VectorEnv(native.envs[0])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="n_envs"):
        make_sb3_vec_env(ID, 0)
    venv = closing(make_sb3_vec_env(ID, 2, 0))
    assert isinstance(venv, VecEnv)
    assert [s.id for s in venv.get_attr("spec")] == [ID, ID]
    # the native vector env keeps the step limit itself: its envs carry no TimeLimit
    assert venv.env_is_wrapped(gym.wrappers.TimeLimit) == [False, False]
    venv.set_attr("probe_value", 3.5, indices=[1])
    assert venv.get_attr("probe_value", indices=1) == [3.5]
    assert venv.env_method("get_wrapper_attr", "probe_value", indices=[1]) == [3.5]
    venv.set_options({"altitude": 1.0})
    venv.reset()
    assert venv.get_images() == [None, None]


def test_ppo_learns_a_few_hundred_steps_on_the_adapter(closing) -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor

    from ihrcf_env.rl.vec import make_sb3_vec_env

    venv = closing(
        VecMonitor(make_sb3_vec_env(ID, 4, 0, max_episode_steps=20), info_keywords=("is_success",))
    )
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(256)
    assert model.num_timesteps == 256
    episodes = list(model.ep_info_buffer)
    assert len(episodes) >= 4 * 3  # 4 envs x 64 steps, episodes of 20 steps
    assert all(ep["l"] == 20 and "is_success" in ep for ep in episodes)
