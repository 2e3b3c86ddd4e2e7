"""DAgger's flyers (no PyTorch needed): the vector env flies each seed's episode as a single env
does, bit for bit, the expert's labels included, through partial resets."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import ihrcf_env
from ihrcf_env.control.gru_policy import WEIGHTS, GruPolicy
from ihrcf_env.rl import episodes as ep

V2 = ihrcf_env.LANDING_V2_ID
KW: dict[str, Any] = {"level": "calm", "max_episode_steps": 25}


def _policy(obs_size: int, seed: int = 0) -> GruPolicy:
    rng = np.random.default_rng(seed)
    d, sizes = 6, {"D": 6, "E": 8, "H": 5, "3H": 15, "F": 4, "A": 4}
    w = {k: rng.normal(scale=0.5, size=tuple(sizes[x] for x in dims)) for k, dims in WEIGHTS.items()}
    w["std"] = np.abs(w["std"]) + 0.5
    return GruPolicy(w, list(range(d)), obs_size)


@pytest.fixture
def single() -> Any:
    """This process as a :class:`~ihrcf_env.rl.episodes.Pool` worker (its env closed at the end)."""
    ep.init_worker(V2, KW, 0.1)
    yield ep
    ep._WORKER.pop("env").close()


@pytest.mark.parametrize("pilot", ["expert", "gru"])
def test_the_vector_flyer_gives_the_single_envs_episodes(
    single: Any, closing: Callable[[Any], Any], pilot: str
) -> None:
    """3 seeds on 2 envs: the third starts by a partial reset in the env that ended first; each
    episode's observations, labels and outcome equal the single env's."""
    flyer = closing(ep.VectorFlyer(V2, KW, 2, 1, 0.1))
    size = int(single._WORKER["env"].observation_space.shape[0])
    policy = None if pilot == "expert" else _policy(size)
    seeds = [5, 6, 7]
    got = flyer.fly(seeds, policy, 0.3)
    want = [single.fly(s, policy, 0.3) for s in seeds]
    assert [e.seed for e in got] == seeds
    for a, b in zip(got, want, strict=True):
        assert len(a.obs) == len(b.obs) > 0 and a.outcome == b.outcome and a.success == b.success
        np.testing.assert_array_equal(a.obs, b.obs)
        np.testing.assert_array_equal(a.labels, b.labels)
    again = flyer.fly(seeds[:1], policy, 0.3, label=False)  # the flyer is reusable; unlabelled
    assert again[0].outcome == want[0].outcome and len(again[0].obs) == 0


def test_flights_share_one_queue_and_keep_their_own_pilots(
    single: Any, closing: Callable[[Any], Any]
) -> None:
    """An unlabelled noiseless flight and a labelled noisy one with another pilot, flown as one
    queue on 2 envs: each episode is the single env's for its own flight's pilot."""
    flyer = closing(ep.VectorFlyer(V2, KW, 2, 1, 0.1))
    size = int(single._WORKER["env"].observation_space.shape[0])
    policy = _policy(size, seed=3)
    flights = [ep.Flight.of([8, 9], policy, 0.0, label=False), ep.Flight.of([10], None, 0.0)]
    val, train = flyer.fly_all(flights)
    assert [e.seed for e in val] == [8, 9] and [e.seed for e in train] == [10]
    for got, f in ((val, flights[0]), (train, flights[1])):
        for a in got:
            b = single.fly(a.seed, f.policy, f.noise, f.label)
            assert a.outcome == b.outcome and len(a.obs) == len(b.obs)
            np.testing.assert_array_equal(a.obs, b.obs)
            np.testing.assert_array_equal(a.labels, b.labels)
    assert len(val[0].obs) == 0 and len(train[0].obs) > 0


def test_vector_flyers_in_processes_give_the_single_envs_episodes(
    single: Any, closing: Callable[[Any], Any]
) -> None:
    """2 processes of 1-env vector envs: the queue is dealt out between them and comes back in
    order, each episode the single env's; an env with no seed left pauses while the other flies."""
    flyer = closing(ep.VectorFlyer(V2, KW, 2, 2, 0.1))
    size = int(single._WORKER["env"].observation_space.shape[0])
    policy = _policy(size, seed=4)
    seeds = [11, 12, 13]
    got = flyer.fly(seeds, policy, 0.2)
    assert [e.seed for e in got] == seeds
    for a in got:
        b = single.fly(a.seed, policy, 0.2)
        assert a.outcome == b.outcome and len(a.obs) == len(b.obs) > 0
        np.testing.assert_array_equal(a.obs, b.obs)
        np.testing.assert_array_equal(a.labels, b.labels)


def test_the_vector_flyer_names_bad_sizes() -> None:
    with pytest.raises(ValueError, match="num_envs"):
        ep.VectorFlyer(V2, KW, 0, 1, 0.1)
    with pytest.raises(ValueError, match="workers"):
        ep.VectorFlyer(V2, KW, 2, 3, 0.1)
