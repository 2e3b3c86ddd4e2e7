"""What acts on N drones from outside their rigid-body step, over one control step: the
autopilot's navigation errors and the disturbance forces, as :func:`~ihrcf_env.sim.batched.loop.advance`
needs them at each physics tick.

Both are the worlds' own objects. The part of them that does not depend on the drone's state is
taken from each object once per control step for all its ticks (the GNSS/INS error processes, all
worlds' on arrays, :func:`~ihrcf_env.sim.batched.navigation.error_tracks`; the
wind's velocity, :meth:`Wind.velocity_at <ihrcf_env.sim.disturbances.Wind.velocity_at>`); what
does depend on it is evaluated on arrays at each tick with the scalar code's operations in its
order, so every row equals the world's own calls bit for bit. Other disturbances (user classes)
are called per world and tick, their forces checked as the scalar loop checks them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.sim.batched.navigation import error_tracks
from ihrcf_env.sim.disturbances import ConstantForce, Wind, disturbance_force
from ihrcf_env.sim.navigation import GNSSINSNavigation

if TYPE_CHECKING:
    from ihrcf_env.sim.world import World

F64 = NDArray[np.float64]


class ExternalInputs:
    """The navigation errors and disturbances of ``worlds`` over the ticks ``ticks0 + j`` (``j`` in
    ``range(steps)``, physics period ``dt`` s) of one control step (module docstring)."""

    def __init__(self, worlds: Sequence[World], ticks0: NDArray[np.int64], steps: int, dt: float) -> None:
        n = len(worlds)
        self.worlds = worlds
        times = [[float(t) for t in (ticks0[i] + np.arange(steps)) * dt] for i in range(n)]
        self.times = times
        # navigation: rows with GNSS/INS errors; the others fly on the truth
        nav = [i for i, w in enumerate(worlds) if not w.navigation.ideal]
        gnss = [i for i in nav if isinstance(worlds[i].navigation, GNSSINSNavigation)]
        self._nav_rows = np.array(gnss, dtype=np.intp)  # errors taken ahead, applied on arrays
        self._nav_other = [i for i in nav if i not in gnss]  # other models: called per tick
        if gnss:
            navs: list[GNSSINSNavigation] = [worlds[i].navigation for i in gnss]  # type: ignore[misc]
            track_times = ((ticks0[self._nav_rows, None] + np.arange(steps)) * dt).astype(np.float64)
            self._ep, self._ev, self._w = error_tracks(navs, track_times)  # (rows, steps, 3)
            self._inv = np.array([worlds[i].navigation._inv_tp for i in self._nav_rows])[:, None]
        # disturbances: k-th disturbance of each row, batched where it is the simulator's own
        self.any_disturbance = any(w.disturbances for w in worlds)
        depth = max((len(w.disturbances) for w in worlds), default=0)
        self._layers: list[_Layer] = [_Layer(worlds, k, times, steps) for k in range(depth)]

    @property
    def navigating(self) -> bool:
        """True when some world's autopilot flies on a navigation estimate."""
        return bool(self._nav_rows.size or self._nav_other)

    def navigation(self, j: int, pos: F64, vel: F64) -> tuple[F64, F64]:
        """The autopilot's (position, velocity) estimates (N, 3) at tick ``j`` for the true state."""
        pos_c, vel_c = pos.copy(), vel.copy()
        r = self._nav_rows
        if r.size:
            ep = self._ep[:, j]
            pos_c[r] = pos[r] + ep
            vel_c[r] = vel[r] + self._ev[:, j] - ep * self._inv + self._w[:, j]
        for i in self._nav_other:
            est_p, est_v = self.worlds[i].navigation.estimate(
                self.times[i][j], tuple(pos[i].tolist()), tuple(vel[i].tolist())
            )
            pos_c[i], vel_c[i] = est_p, est_v
        return pos_c, vel_c

    def forces(self, j: int, pos: F64, vel: F64) -> F64 | None:
        """The disturbance forces (N, 3) N, world frame, at tick ``j`` (None: no disturbances)."""
        if not self.any_disturbance:
            return None
        total = np.zeros((len(self.worlds), 3))
        for layer in self._layers:
            layer.add(total, j, pos, vel)
        return total


class _Layer:
    """The ``k``-th disturbance of each world that has one: Wind and ConstantForce rows on arrays,
    other classes called per row."""

    def __init__(self, worlds: Sequence[World], k: int, times: list[list[float]], steps: int) -> None:
        self.worlds, self.k, self.times = worlds, k, times
        rows = [i for i, w in enumerate(worlds) if len(w.disturbances) > k]
        wind = [i for i in rows if type(worlds[i].disturbances[k]) is Wind]
        const = [i for i in rows if type(worlds[i].disturbances[k]) is ConstantForce]
        self.other = [i for i in rows if i not in wind and i not in const]
        self.rows = np.array(rows, dtype=np.intp)
        self.wind = np.array(wind, dtype=np.intp)
        self.const = np.array(const, dtype=np.intp)
        consts: list[ConstantForce] = [worlds[i].disturbances[k] for i in const]  # type: ignore[misc]
        self._const_force = np.array([d.force for d in consts]).reshape(-1, 3)
        if wind:
            winds: list[Wind] = [worlds[i].disturbances[k] for i in wind]  # type: ignore[misc]
            self._air = np.stack([d.velocity_at(times[i]) for d, i in zip(winds, wind, strict=True)])
            self._calm = np.all(self._air == 0.0, axis=2)  # (rows, steps)
            drags = [d.params.drag for d in winds]
            # the scalar formula's constant prefix, m * 0.5 * rho / bcoef, and the linear terms
            self._q0 = np.array([g.mass * 0.5 * g.rho / g.bcoef for g in drags])
            self._lin = np.array([[g.mass * g.mcoef_xy] * 2 + [g.mass * g.mcoef_z] for g in drags])

    def add(self, total: F64, j: int, pos: F64, vel: F64) -> None:
        """Add this layer's forces at tick ``j`` to ``total`` (N, 3), row by row as the scalar loop
        sums a world's disturbances (``0.0 + f1 + f2 ...``)."""
        force = np.zeros_like(total)
        if self.wind.size:
            v = vel[self.wind]
            fa = self._drag(v - self._air[:, j])
            f = np.where(self._calm[:, j, None], 0.0, fa - self._drag(v))
            force[self.wind] = f
        if self.const.size:
            force[self.const] = self._const_force
        for i in self.other:
            ti, pi, vi = self.times[i][j], tuple(pos[i].tolist()), tuple(vel[i].tolist())
            force[i] = disturbance_force(self.worlds[i].disturbances[self.k], ti, pi, vi)
        total[self.rows] = total[self.rows] + force[self.rows]

    def _drag(self, va: F64) -> F64:
        """:meth:`DragModel.force` per row, the same operations in the same order."""
        vx, vy, vz = va[:, 0], va[:, 1], va[:, 2]
        q = self._q0 * np.sqrt(vx * vx + vy * vy + vz * vz)
        return -(self._lin + q[:, None]) * va


__all__ = [
    "ExternalInputs",
]
