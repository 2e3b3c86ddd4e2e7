"""The drone's collision boxes (ihrcf_env.core.collision) read from its URDF."""

from __future__ import annotations

import numpy as np
import pytest

from ihrcf_env.core.collision import drone_boxes


def test_the_five_boxes_of_the_urdf() -> None:
    centres, halves = drone_boxes()
    assert centres.shape == halves.shape == (5, 3)  # the body and four landing legs
    assert (centres[:, 2] - halves[:, 2]).min() == pytest.approx(-0.0625 - 0.0375)  # the legs' feet
    assert np.abs(centres[:, 0] + np.sign(centres[:, 0]) * halves[:, 0]).max() == pytest.approx(0.126)
    assert (halves > 0).all()


def test_read_once_and_read_only() -> None:
    a, b = drone_boxes(), drone_boxes()
    assert a[0] is b[0] and a[1] is b[1]
    with pytest.raises(ValueError):
        a[0][0, 0] = 1.0
