"""Small state filters for controllers (pure Python and :mod:`ihrcf_env.core`, no simulator)."""

from __future__ import annotations

from ihrcf_env.core.checks import check_real


class AlphaBeta:
    """Alpha-beta tracker of a scalar ``x`` and its rate ``v`` (units of x per second).

    Args:
        alpha: position correction gain, in [0, 1].
        beta: rate correction gain in [0, 2] (dimensionless; the correction is ``beta * residual / dt``).
    """

    def __init__(self, alpha: float, beta: float) -> None:
        self.alpha = check_real("alpha", alpha, low=0.0, high=1.0)
        self.beta = check_real("beta", beta, low=0.0, high=2.0)
        self.x: float | None = None
        self.v = 0.0

    def reset(self) -> None:
        """Forget the state: the next measurement initialises ``x``, the rate restarts at 0."""
        self.x, self.v = None, 0.0

    def update(self, z: float | None, dt: float) -> None:
        """Predict over ``dt`` (s); correct with the measurement ``z`` if there is one.

        The first measurement after a reset initialises ``x`` without prediction.
        """
        if self.x is None:
            self.x = z
            return
        self.x += self.v * dt
        if z is not None:
            r = z - self.x
            self.x += self.alpha * r
            self.v += self.beta * r / dt


__all__ = [
    "AlphaBeta",
]
