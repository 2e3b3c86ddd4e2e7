"""disturbance_force: a disturbance's result is exactly 3 finite real numbers of a sane magnitude,
or the error names the disturbance."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest

from ihrcf_env.config.wind import Disturbance, WindParams
from ihrcf_env.sim.disturbances import MAX_DISTURBANCE_FORCE, ConstantForce, Wind, disturbance_force


class Returns:
    """A disturbance returning a fixed object."""

    def __init__(self, value: object) -> None:
        self.value = value

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def __call__(self, t: float, position: Sequence[float], velocity: Sequence[float]) -> object:
        return self.value

    def __repr__(self) -> str:
        return f"Returns({self.value!r})"


POS, VEL = (0.0, 0.0, 1.0), (0.1, 0.0, 0.0)


def test_good_forces_pass_as_float_tuples() -> None:
    assert disturbance_force(ConstantForce((2.0, 0.0, -1.0)), 0.5, POS, VEL) == (2.0, 0.0, -1.0)
    for value in ([1, 2, 3], np.array([1.0, 2.0, 3.0]), (np.float32(1.5), 0, np.int64(2))):
        f = disturbance_force(Returns(value), 0.0, POS, VEL)  # type: ignore[arg-type]
        assert isinstance(f, tuple) and len(f) == 3 and all(type(v) is float for v in f)
    wind = Wind(WindParams(mean_speed_min=3.0, mean_speed_max=3.0))
    wind.reset(np.random.default_rng(0))
    assert disturbance_force(wind, 1.0, POS, VEL) == wind(1.0, POS, VEL)
    assert isinstance(Returns(None), Disturbance)


@pytest.mark.parametrize(
    ("value", "error", "match"),
    [
        ((1.0, 2.0), TypeError, "3 real numbers"),
        ((1.0, 2.0, 3.0, 4.0), TypeError, "3 real numbers"),
        (np.zeros((3, 1)), TypeError, "3 real numbers"),
        (None, TypeError, "3 real numbers"),
        ("abc", TypeError, "3 real numbers"),
        (5.0, TypeError, "3 real numbers"),
        ((1.0, "2", 3.0), TypeError, "3 real numbers"),
        ((1.0, True, 3.0), TypeError, "3 real numbers"),
        ((1.0, 1j, 3.0), TypeError, "3 real numbers"),
        ((math.nan, 0.0, 0.0), ValueError, "non-finite"),
        ((0.0, -math.inf, 0.0), ValueError, "non-finite"),
        ((1e300, 0.0, 0.0), ValueError, "above"),
        ((0.0, 0.0, 2 * MAX_DISTURBANCE_FORCE), ValueError, "above"),
        ((10**400, 0, 0), ValueError, "non-finite"),
    ],
)
def test_bad_results_name_the_disturbance(value: object, error: type, match: str) -> None:
    d = Returns(value)
    with pytest.raises(error, match=match) as info:
        disturbance_force(d, 1.25, POS, VEL)  # type: ignore[arg-type]
    text = str(info.value)
    assert "Returns" in text and "disturbance" in text and "t = 1.2500 s" in text


def test_a_large_but_sane_force_passes() -> None:
    m = MAX_DISTURBANCE_FORCE / math.sqrt(3.0) * 0.999
    assert disturbance_force(Returns((m, -m, m)), 0.0, POS, VEL) == (m, -m, m)  # type: ignore[arg-type]


def test_the_disturbances_own_error_propagates() -> None:
    class Broken(Returns):
        def __call__(self, t: float, position: Sequence[float], velocity: Sequence[float]) -> object:
            raise ZeroDivisionError("inside")

    with pytest.raises(ZeroDivisionError, match="inside"):
        disturbance_force(Broken(None), 0.0, POS, VEL)  # type: ignore[arg-type]


def test_constant_force_is_bounded() -> None:
    with pytest.raises(ValueError, match="force"):
        ConstantForce((1e300, 0.0, 0.0))
    with pytest.raises(TypeError, match="force"):
        ConstantForce((1.0, 2.0))
