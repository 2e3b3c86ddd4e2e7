"""Controller filters."""

from __future__ import annotations

import pytest

from ihrcf_env.control.filters import AlphaBeta


def test_alpha_beta_initialises_then_tracks_a_ramp() -> None:
    f = AlphaBeta(alpha=0.5, beta=0.1)
    f.update(None, 0.1)
    assert f.x is None  # nothing to start from
    f.update(1.0, 0.1)
    assert f.x == 1.0 and f.v == 0.0  # the first measurement initialises, no prediction
    for k in range(1, 400):
        f.update(1.0 + 0.5 * k * 0.1, 0.1)  # x = 1 + 0.5 t
    assert f.v == pytest.approx(0.5, rel=1e-3)
    x = f.x
    assert x is not None
    f.update(None, 0.1)  # no measurement: predicts along the rate
    assert f.x == pytest.approx(x + 0.05)
    f.reset()
    assert f.x is None and f.v == 0.0
