"""Disturbances acting on the drone: the force hook of :class:`~ihrcf_env.sim.world.World`.

A disturbance is called at every physics step with the simulated time and the drone's world
position and velocity and returns a world-frame force (N) applied at the centre of mass, like
PyFlyt's wind ``__call__(t, pos)``. Randomness (gust sequences) is drawn in :meth:`reset` from the
env's generator so that a seeded episode is reproducible.

:class:`Wind` is the landing task's wind (``ihrcf_env/DeckLanding-v1``): a mean wind drawn per
episode plus Dryden gusts (:class:`WindParams`), pushing the drone through a rotor-drag +
parasitic-drag model of a 1-2 kg quadrotor (:class:`DragModel`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.config.wind import Disturbance, WindParams
from ihrcf_env.core.checks import check_reals, describe, is_real
from ihrcf_env.tasks.episode import draw_wind

#: Largest force (N) a disturbance may return: far beyond any wind or contact on a drone, far below
#: where the physics loses its precision.
MAX_DISTURBANCE_FORCE = 1e4


def _describe_disturbance(d: object) -> str:
    text = repr(d)
    return f"disturbance {type(d).__name__} ({text if len(text) <= 80 else text[:77] + '...'})"


def disturbance_force(
    d: Disturbance, t: float, position: Sequence[float], velocity: Sequence[float]
) -> tuple[float, float, float]:
    """``d(t, position, velocity)`` checked: exactly 3 finite real numbers (N, world frame) of
    magnitude at most :data:`MAX_DISTURBANCE_FORCE`. Raises TypeError (not a sequence of 3 real
    numbers) or ValueError (non-finite, too large) naming the disturbance's type and repr; an
    exception raised by the disturbance itself propagates unchanged."""
    f = d(t, position, velocity)
    if type(f) is tuple and len(f) == 3:  # the common case (the wind's force): three floats
        x, y, z = f
        if type(x) is float and type(y) is float and type(z) is float:
            return _checked_values(d, t, x, y, z, f)
    if isinstance(f, np.ndarray):
        items: list[object] | None = f.tolist() if f.ndim == 1 else None
    elif isinstance(f, Sequence) and not isinstance(f, str | bytes):
        items = list(f)
    else:
        items = None
    if items is None or len(items) != 3 or not all(is_real(v) for v in items):
        raise TypeError(
            f"{_describe_disturbance(d)} must return a force of 3 real numbers (N, world frame), "
            f"got {describe(f)}{'' if items is None else ': ' + repr(f)[:80]} at t = {t:.4f} s"
        )
    try:
        x, y, z = (float(v) for v in items)  # type: ignore[arg-type]
    except OverflowError:  # an int too large for a float
        x = y = z = math.inf
    return _checked_values(d, t, x, y, z, tuple(items))


def _checked_values(
    d: Disturbance, t: float, x: float, y: float, z: float, shown: tuple[object, ...]
) -> tuple[float, float, float]:
    """``(x, y, z)`` if finite and at most :data:`MAX_DISTURBANCE_FORCE` in magnitude, else
    ValueError (``shown``: the force as the disturbance returned it)."""
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise ValueError(
            f"{_describe_disturbance(d)} returned a non-finite force {repr(shown)[:80]} (N) at t = {t:.4f} s"
        )
    if x * x + y * y + z * z > MAX_DISTURBANCE_FORCE**2:
        raise ValueError(
            f"{_describe_disturbance(d)} returned a force of {math.sqrt(x * x + y * y + z * z):.4g} N at "
            f"t = {t:.4f} s, above the {MAX_DISTURBANCE_FORCE:g} N a disturbance may apply"
        )
    return (x, y, z)


class ConstantForce:
    """A steady world-frame force (N), e.g. to test position hold or model a steady side load."""

    def __init__(self, force: Sequence[float] | NDArray[np.float64]) -> None:
        m = MAX_DISTURBANCE_FORCE / math.sqrt(3.0)
        fx, fy, fz = check_reals("ConstantForce force", force, 3, "N", low=-m, high=m)
        self.force = (fx, fy, fz)

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def __call__(
        self, t: float, position: Sequence[float], velocity: Sequence[float]
    ) -> tuple[float, float, float]:
        return self.force


# -- wind ------------------------------------------------------------------------------------------
FT = 0.3048  # m per foot (the Dryden formulas are written in feet)


def dryden_low_altitude(height: float) -> tuple[float, float, float, float]:
    """Dryden turbulence below 1000 ft (MIL-F-8785C / MIL-HDBK-1797, as in MathWorks' "Dryden Wind
    Turbulence Model" blocks) at ``height`` (m) above the surface, for a wind of 1 m/s at 20 ft:
    ``(sigma_horizontal, sigma_vertical, L_horizontal, L_vertical)``, intensities per m/s of wind
    (dimensionless) and scale lengths (m)::

        sigma_w = 0.1 W20,  sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4
        L_w = h,            L_u = L_v = h / (0.177 + 0.000823 h)^1.2         (h in ft)
    """
    h = max(float(height), 0.5) / FT
    k = 0.177 + 0.000823 * h
    return 0.1 / k**0.4, 0.1, h / k**1.2 * FT, h * FT


class Wind:
    """Seeded wind on the drone: a mean wind plus Dryden gusts (see :class:`WindParams`), turned
    into a world force by :class:`DragModel` from the drone's velocity through the air.

    As a :class:`Disturbance` it returns the force the wind *adds* to the drone's own still-air drag
    (the quadrotor model's linear ``QuadParams.drag``): ``drag.force(v - w) - drag.force(v)``, zero
    in calm air. :meth:`velocity` gives the wind itself (world, m/s) at a time; the state drawn at
    :meth:`reset` is ``mean_speed`` (m/s), ``direction`` (rad) and the gust sequence (from one draw
    of the env's generator, generated lazily in 10 s blocks, so it does not depend on how often the
    wind is read). Before the first :meth:`reset` the air is calm.
    """

    BLOCK = 200  # gust samples generated at a time

    def __init__(self, params: WindParams | None = None, **overrides: object) -> None:
        base = params if params is not None else WindParams()
        self.params = dataclasses.replace(base, **overrides) if overrides else base  # type: ignore[arg-type]
        self.mean_speed = 0.0
        self.direction = 0.0
        self.mean = (0.0, 0.0, 0.0)
        self.sigma = (0.0, 0.0, 0.0)  # gust std along (mean wind, cross wind, vertical), m/s
        self.tau = (1.0, 1.0, 1.0)  # s, their correlation times
        self._rng: np.random.Generator | None = None
        self._samples: list[tuple[float, float, float]] = []  # gusts in the world frame
        self._state = np.zeros(3)
        self._drag = self.params.drag

    def reset(self, rng: np.random.Generator) -> None:
        """Draw this episode's mean wind and gust sequence from ``rng``."""
        p = self.params
        draw = draw_wind(rng)  # the draws the JAX backend pairs (ihrcf_env.tasks.episode)
        self.mean_speed = float(p.mean_speed_min + (p.mean_speed_max - p.mean_speed_min) * draw.u_speed)
        self.direction = float(2.0 * math.pi * draw.u_direction)
        c, s = math.cos(self.direction), math.sin(self.direction)
        self.mean = (self.mean_speed * c, self.mean_speed * s, 0.0)
        s_h, s_w, l_h, l_w = dryden_low_altitude(p.height)
        k = p.turbulence * self.mean_speed
        self.sigma = (k * s_h, k * s_h, k * s_w)
        v_adv = max(self.mean_speed, p.min_advection)
        self.tau = (l_h / v_adv, l_h / v_adv, l_w / v_adv)
        self._rng = np.random.default_rng(draw.gust_seed)
        self._samples = []
        self._state = np.asarray(self.sigma) * self._rng.standard_normal(3)  # stationary start

    def _extend(self) -> None:
        """Append one block of gust samples (exact Gauss-Markov steps of ``sample_dt``)."""
        assert self._rng is not None
        dt, n = self.params.sample_dt, self.BLOCK
        a = np.exp(-dt / np.asarray(self.tau))
        q = np.asarray(self.sigma) * np.sqrt(1.0 - a * a)
        noise = self._rng.standard_normal((n, 3)) * q
        out = np.empty((n, 3))
        x = self._state
        for i in range(n):
            out[i] = x
            x = a * x + noise[i]
        self._state = x
        c, s = math.cos(self.direction), math.sin(self.direction)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # (along, cross, up) -> world
        self._samples.extend(tuple(r) for r in (out @ rot.T).tolist())

    def gust(self, t: float) -> tuple[float, float, float]:
        """The turbulent part of the wind (world, m/s) at time ``t`` (s, >= 0)."""
        if self._rng is None or self.params.turbulence == 0 or self.mean_speed == 0:
            return (0.0, 0.0, 0.0)
        u = max(float(t), 0.0) / self.params.sample_dt
        k = int(u)
        while k + 1 >= len(self._samples):
            self._extend()
        f = u - k
        (ax, ay, az), (bx, by, bz) = self._samples[k], self._samples[k + 1]
        return (ax + f * (bx - ax), ay + f * (by - ay), az + f * (bz - az))

    def velocity(self, t: float) -> NDArray[np.float64]:
        """Wind velocity (world, m/s) at time ``t`` (s): mean plus gusts."""
        g = self.gust(t)
        return np.array([self.mean[0] + g[0], self.mean[1] + g[1], self.mean[2] + g[2]])

    def velocity_at(self, times: Sequence[float]) -> NDArray[np.float64]:
        """Wind velocity (len(times), 3) (world, m/s) at each of ``times`` (s), as the force
        (:meth:`__call__`) sees it."""
        t = np.asarray(times, dtype=np.float64).reshape(-1)
        gust = np.zeros((t.size, 3))
        if t.size and not (self._rng is None or self.params.turbulence == 0 or self.mean_speed == 0):
            u = np.maximum(t, 0.0) / self.params.sample_dt  # as gust(t), on arrays
            k = u.astype(np.int64)
            while int(k.max()) + 1 >= len(self._samples):
                self._extend()
            k0 = int(k.min())
            samples = np.array(self._samples[k0 : int(k.max()) + 2])
            a, b = samples[k - k0], samples[k + 1 - k0]
            gust = a + (u - k)[:, None] * (b - a)
        return np.asarray(self.mean, dtype=np.float64) + gust

    def __call__(
        self, t: float, position: Sequence[float], velocity: Sequence[float]
    ) -> tuple[float, float, float]:
        gx, gy, gz = self.gust(t)
        wx, wy, wz = self.mean[0] + gx, self.mean[1] + gy, self.mean[2] + gz
        if wx == 0.0 and wy == 0.0 and wz == 0.0:
            return (0.0, 0.0, 0.0)
        vx, vy, vz = velocity
        fa = self._drag.force((vx - wx, vy - wy, vz - wz))
        f0 = self._drag.force((vx, vy, vz))
        return (fa[0] - f0[0], fa[1] - f0[1], fa[2] - f0[2])


__all__ = [
    "FT",
    "MAX_DISTURBANCE_FORCE",
    "ConstantForce",
    "Wind",
    "disturbance_force",
    "dryden_low_altitude",
]
