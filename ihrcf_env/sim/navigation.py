"""The autopilot's navigation estimate: the position and velocity its outer loops are closed on.

Two feedback modes (:class:`NavigationConfig` ``feedback``):

* ``"truth"`` (:class:`TruthNavigation`): the autopilot flies on the true state, as every result of
  this simulator did before this module existed (bit for bit).
* ``"estimated"`` (:class:`GNSSINSNavigation`): the output of an onboard GNSS + IMU (+ barometer)
  EKF, true state plus a coloured error with figures of :class:`NavigationErrors`. Per world axis,
  a velocity error ``e_v`` (first-order Gauss-Markov, std ``sigma_v``, correlation time ``tau_v``)
  integrates into a position error ``e_p`` that the GNSS fixes keep bounded (a leak ``tau_p``):

      de_v = -e_v / tau_v dt + sigma_v sqrt(2 / tau_v) dW
      de_p = (e_v - e_p / tau_p) dt

  so the position error is smooth and its derivative is the velocity error. Its stationary std is
  ``sigma_p`` with ``sigma_p^2 = sigma_v^2 tau_v tau_p^2 / (tau_p + tau_v)``; ``sigma_v`` is
  derived from ``sigma_p``, ``tau_p`` and ``tau_v``. The reported estimate is

      p_hat = p + e_p,    v_hat = v + de_p/dt + w,    w ~ N(0, velocity_noise^2) white.

  Over a time ``T << tau_p`` the position error wanders by about ``sigma_p sqrt(2 T / tau_p)``: a
  drone holding its *estimated* position drifts by that much (tens of centimetres in 30 s).

The error is advanced at every physics step (exact Gauss-Markov update of ``e_v``, exponential
integration of ``e_p``) from a generator seeded at :meth:`GNSSINSNavigation.reset` by one draw
from the env's ``np_random``; it is advanced lazily to the time asked for, so it does not depend on
how often it is read. The attitude loop keeps the true attitude and body rates (a well-filtered
gyro and attitude estimate are not this module's subject; see the IMU's attitude error model for
the attitude the agent observes).
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

import numpy as np

from ihrcf_env.config.vehicle import NavigationConfig, NavigationErrors
from ihrcf_env.core.checks import check_real

Vec3 = tuple[float, ...]


@runtime_checkable
class Navigation(Protocol):
    """The autopilot's navigation solution."""

    #: True when :meth:`estimate` returns the true state unchanged (nothing is drawn).
    ideal: bool

    def reset(self, rng: np.random.Generator) -> None:
        """Start of an episode: draw this episode's errors from ``rng``."""

    def estimate(self, t: float, position: Vec3, velocity: Vec3) -> tuple[Vec3, Vec3]:
        """(position, velocity) estimate (world, m and m/s) at time ``t`` (s) for the true state."""
        ...


class TruthNavigation:
    """The true state: :meth:`estimate` returns its arguments, the same objects."""

    ideal = True

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def estimate(self, t: float, position: Vec3, velocity: Vec3) -> tuple[Vec3, Vec3]:
        return position, velocity


class GNSSINSNavigation:
    """A GNSS/INS estimate with the coloured errors of :class:`NavigationErrors` (see the module
    docstring), advanced in steps of ``dt`` seconds (the physics step)."""

    ideal = False
    _BLOCK = 256  # steps of normal draws made at once

    def __init__(self, errors: NavigationErrors, dt: float) -> None:
        self.errors = errors
        self.dt = check_real("dt", dt, "s", low=1e-5, high=1.0)
        tp, tv = errors.position_time_constant, errors.velocity_time_constant
        self._phi_v = math.exp(-self.dt / tv)
        self._phi_p = math.exp(-self.dt / tp)
        self._gain_p = tp * (1.0 - self._phi_p)
        self._inv_tp = 1.0 / tp
        self._sv = errors.velocity_sigma
        self._q_v = (self._sv * math.sqrt(1.0 - self._phi_v**2)).tolist()
        self._w = errors.velocity_noise
        self._rng = np.random.default_rng(0)
        self._k = 0
        self.position_error = [0.0, 0.0, 0.0]
        self.velocity_error = [0.0, 0.0, 0.0]  # correlated part e_v
        self._white = [0.0, 0.0, 0.0]
        self._block: list[list[float]] = []
        self._i = 0

    def reset(self, rng: np.random.Generator) -> None:
        """Seed this episode's error generator from ``rng`` (one draw) and start the errors from
        their stationary distribution (``e_p`` and ``e_v`` jointly Gaussian, correlated)."""
        self._rng = np.random.default_rng(int(rng.integers(0, 2**63 - 1)))
        self._k = 0
        self._block = []
        self._i = 0
        a = 1.0 / self.errors.position_time_constant
        b = 1.0 / self.errors.velocity_time_constant
        sp, sv = self.errors.position_sigma, self._sv
        z = self._rng.standard_normal((3, 3))
        ev = sv * z[0]
        cov = sv**2 / (a + b)  # E[e_p e_v]
        with np.errstate(invalid="ignore", divide="ignore"):
            gain = np.where(sv > 0, cov / np.maximum(sv**2, 1e-300), 0.0)
        rest = np.sqrt(np.maximum(sp**2 - gain * cov, 0.0))
        self.velocity_error = ev.tolist()
        self.position_error = (gain * ev + rest * z[1]).tolist()
        self._white = (self._w * z[2]).tolist()

    def _step(self) -> None:
        if self._i >= len(self._block):
            self._block = self._rng.standard_normal((self._BLOCK, 6)).tolist()  # floats: fast scalar maths
            self._i = 0
        z = self._block[self._i]
        self._i += 1
        ev, ep, q = self.velocity_error, self.position_error, self._q_v
        phi_v, phi_p, g = self._phi_v, self._phi_p, self._gain_p
        for k in range(3):
            new = phi_v * ev[k] + q[k] * z[k]
            ep[k] = phi_p * ep[k] + g * 0.5 * (ev[k] + new)
            ev[k] = new
        w = self._w
        self._white = [w * z[3], w * z[4], w * z[5]]

    def advance(self, t: float) -> None:
        """Bring the error to time ``t`` (s); a time before the current one only moves the clock."""
        k = int(round(t / self.dt))
        while self._k < k:
            self._step()
            self._k += 1
        self._k = k

    def estimate(self, t: float, position: Vec3, velocity: Vec3) -> tuple[Vec3, Vec3]:
        self.advance(t)
        ep, ev, w, inv = self.position_error, self.velocity_error, self._white, self._inv_tp
        pos = (position[0] + ep[0], position[1] + ep[1], position[2] + ep[2])
        vel = (
            velocity[0] + ev[0] - ep[0] * inv + w[0],
            velocity[1] + ev[1] - ep[1] * inv + w[1],
            velocity[2] + ev[2] - ep[2] * inv + w[2],
        )
        return pos, vel


def make_navigation(config: NavigationConfig, dt: float) -> Navigation:
    """The navigation model for ``config``, advanced in physics steps of ``dt`` seconds."""
    errors = config.errors
    return TruthNavigation() if errors is None else GNSSINSNavigation(errors, dt)


__all__ = [
    "GNSSINSNavigation",
    "Navigation",
    "TruthNavigation",
    "Vec3",
    "make_navigation",
]
