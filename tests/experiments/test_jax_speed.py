"""The JAX speed harness on a small functional env (the landing step's figures come from the command)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from functional_toy import Drop  # noqa: E402

from ihrcf_env.experiments.jax_speed import (  # noqa: E402
    SpeedRow,
    cost_per_env_step,
    functional_rate,
    gpu_estimate,
    rollout_fn,
    table,
)


def test_rollout_resets_the_envs_that_ended() -> None:
    fenv = Drop()
    total, ended, check = rollout_fn(fenv, 4, 60, max_steps=100)(jax.random.PRNGKey(0))
    # falling from 1-2 m at g = 1 with random thrust in [-1, 1] - g: every env lands in 60 steps
    assert int(ended) >= 4 and np.isfinite(float(total)) and np.isfinite(float(check))


class Doubled(Drop):
    """Drop with every observation doubled (the same dynamics, draws and rewards)."""

    def reset_from(self, episode: Any, key: Any, params: Any) -> tuple[Any, Any]:
        obs, state = super().reset_from(episode, key, params)
        return 2.0 * obs, state

    def step(self, key: Any, state: Any, action: Any, params: Any) -> Any:
        obs, *rest = super().step(key, state, action, params)
        return (2.0 * obs, *rest)


def test_rollout_result_depends_on_every_observation() -> None:
    # a timed rollout must compute the observations (XLA drops what no result depends on)
    key = jax.random.PRNGKey(3)
    total, ended, check = rollout_fn(Drop(), 3, 40)(key)
    total2, ended2, check2 = rollout_fn(Doubled(), 3, 40)(key)
    assert float(total2) == pytest.approx(float(total)) and int(ended2) == int(ended)
    assert abs(float(check)) > 1.0
    assert float(check2) == pytest.approx(2.0 * float(check), rel=1e-5)


def test_rates_costs_and_table() -> None:
    row = functional_rate(Drop(), 8, 20, "float32")
    assert row.kind == "functional" and row.num_envs == 8 and row.steps_per_s > 0
    flops, nbytes = cost_per_env_step(Drop(), "float32")
    assert flops > 0 and nbytes > 0
    assert gpu_estimate(flops, nbytes, "float32") > 0
    text = table(
        [
            row,
            SpeedRow("front", 8, "float64", 1.0, 500.0),
            SpeedRow("functional", 8, "float32", 9.0, 900.0, 2, 1.5, 700),
        ],
        reference=100.0,
    )
    assert "| front | 8 | float64 | 1 | 1.0 |  |  | 500 | 5.0 | 5.0 |" in text
    assert "| functional | 8 | float32 | 2 | 9.0 | 1.5 | 700 | 900 | 9.0 | 4.5 |" in text


def test_a_step_limit_ends_episodes() -> None:
    class Hover(Drop):  # never lands: only the step limit ends its episodes
        def step(self, key: Any, state: Any, action: Any, params: Any) -> Any:
            obs, new, reward, done, info = super().step(key, state, action, params)
            return obs, {**new, "h": state["h"], "v": 0.0 * new["v"]}, reward, done & False, info

    total, ended, _ = rollout_fn(Hover(), 2, 25, max_steps=10)(jax.random.PRNGKey(0))
    assert int(ended) == 4  # two episodes of each env ended at 10 and 20 steps


def test_the_measurements_may_use_every_core_after_the_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    """The PyBullet reference runs pinned to one core; the processes measuring the JAX step
    are started with the cores the command was given (a 2-core row would refuse otherwise)."""
    import os

    from ihrcf_env.experiments import jax_speed

    usable = os.sched_getaffinity(0)
    seen: dict[str, set[int]] = {}

    def reference(*args: object) -> float:
        seen["reference"] = os.sched_getaffinity(0)
        return 100.0

    def measure(env_id: str, level: str, n: int, steps: int, dtype: str, cores: int, cache: str) -> object:
        seen["measure"] = os.sched_getaffinity(0)
        raise SystemExit(0)  # stop before anything compiles

    monkeypatch.setattr(jax_speed, "pybullet_rate", reference)
    monkeypatch.setattr(jax_speed, "measure_in_process", measure)
    with pytest.raises(SystemExit):
        jax_speed.main(["--nums", "32", "--cores", "1", "--dtypes", "float32", "--no-front"])
    assert len(seen["reference"]) == 1
    assert seen["measure"] == usable == os.sched_getaffinity(0)
