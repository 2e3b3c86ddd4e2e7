"""The start curriculum's episode transform: the task's own start at scale 1, bit for bit; nearer
the deck below it."""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from ihrcf_env.fast.episode import start_towards_deck  # noqa: E402
from ihrcf_env.vector.jax_make import make_functional  # noqa: E402


def test_scale_one_is_the_task_start_and_zero_the_lowest_above_the_tag() -> None:
    fenv = make_functional("ihrcf_env/DeckLanding-v2", "float64", level="moderate")
    ep = fenv.draw(jax.random.PRNGKey(3), ())
    same = start_towards_deck(ep, 1.0, 0.6)
    assert np.asarray(same.altitude).tobytes() == np.asarray(ep.altitude).tobytes()
    assert np.asarray(same.offset).tobytes() == np.asarray(ep.offset).tobytes()
    low = start_towards_deck(ep, 0.0, 0.6)
    assert float(low.altitude) == pytest.approx(min(0.6, float(ep.altitude)))
    np.testing.assert_array_equal(np.asarray(low.offset), 0.0)
    half = start_towards_deck(ep, 0.5, 0.6)
    assert 0.6 < float(half.altitude) < float(ep.altitude)
    np.testing.assert_allclose(np.asarray(half.offset), 0.5 * np.asarray(ep.offset))
    for other in ("yaw", "deck_time", "wind_u", "gusts"):  # nothing else changes
        assert np.asarray(getattr(half, other)).tobytes() == np.asarray(getattr(ep, other)).tobytes()
