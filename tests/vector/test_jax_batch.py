"""map_envs: the vmapped function computed in chunks of envs."""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from functional_toy import Drop  # noqa: E402

from ihrcf_env.vector.jax_batch import map_envs  # noqa: E402


@pytest.mark.parametrize("n, chunk", [(5, 8), (16, 4), (19, 4)])
def test_chunks_give_the_vmapped_result(n: int, chunk: int) -> None:
    fenv = Drop()
    keys = jax.random.split(jax.random.PRNGKey(3), n)
    _, state = jax.vmap(lambda k: fenv.reset_from(fenv.draw(k, fenv.params), k, fenv.params))(keys)
    actions = jax.numpy.linspace(-1.0, 1.0, n)[:, None]
    step = lambda k, s, a: fenv.step(k, s, a, fenv.params)  # noqa: E731
    want = jax.vmap(step)(keys, state, actions)
    got = map_envs(step, keys, state, actions, chunk=chunk)
    for a, b in zip(jax.tree_util.tree_leaves(want), jax.tree_util.tree_leaves(got), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_bad_chunk_is_refused() -> None:
    with pytest.raises(ValueError, match="chunk"):
        map_envs(lambda x: x, jax.numpy.zeros(3), chunk=0)
