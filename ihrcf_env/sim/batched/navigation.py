"""The GNSS/INS error processes of N worlds over one control step, on arrays: :func:`error_tracks`.

Each :class:`~ihrcf_env.sim.navigation.GNSSINSNavigation` advances its coloured errors one
physics step at a time from its own block of normal draws. Over the ticks of a control step the
steps of all the worlds are taken together here: each process's draws are taken from its own
block in the order its scalar step takes them, and the recursion runs on (N, 3) arrays with the
scalar code's operations in its order, so every row equals the world's own
:meth:`~ihrcf_env.sim.navigation.GNSSINSNavigation.errors_at` bit for bit. A process that would
take more than one step before some tick (its clock jumped) is advanced by its own
``errors_at``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.sim.navigation import GNSSINSNavigation

F64 = NDArray[np.float64]


def error_tracks(navs: Sequence[GNSSINSNavigation], times: F64) -> tuple[F64, F64, F64]:
    """Advance each of ``navs`` through its row of ``times`` ((N, M) s, non-decreasing) and return
    the position error, correlated velocity error and white velocity noise it applies at each,
    each (N, M, 3) (world, m and m/s), as ``errors_at`` would."""
    n, m = times.shape
    out = np.empty((3, n, m, 3))
    if n == 0 or m == 0:
        return out[0], out[1], out[2]
    dts = np.array([nav.dt for nav in navs])
    ks = np.rint(times / dts[:, None]).astype(np.int64)  # round half to even, as round()
    prev = np.concatenate([np.array([[nav._k] for nav in navs], dtype=np.int64), ks[:, :-1]], axis=1)
    counts = np.maximum(ks - prev, 0)
    fast = np.flatnonzero(counts.max(axis=1) <= 1)
    for i in np.flatnonzero(counts.max(axis=1) > 1).tolist():
        out[0, i], out[1, i], out[2, i] = navs[i].errors_at(times[i].tolist())
    if fast.size == 0:
        return out[0], out[1], out[2]
    group = [navs[i] for i in fast.tolist()]
    stepping = counts[fast] == 1  # (R, M)
    z = np.zeros((len(group), m, 6))
    for r, nav in enumerate(group):
        draws = nav.take_draws(int(stepping[r].sum()))
        if draws:
            z[r, stepping[r]] = draws
    phi_v = np.array([[nav._phi_v] for nav in group])
    phi_p = np.array([[nav._phi_p] for nav in group])
    half_gain = np.array([[nav._gain_p] for nav in group]) * 0.5
    q = np.array([nav._q_v for nav in group], dtype=np.float64)
    w = np.array([[nav._w] for nav in group], dtype=np.float64)
    ev = np.array([nav.velocity_error for nav in group], dtype=np.float64)
    ep = np.array([nav.position_error for nav in group], dtype=np.float64)
    white = np.array([nav._white for nav in group], dtype=np.float64)
    for j in range(m):
        zj = z[:, j]
        new = phi_v * ev + q * zj[:, :3]
        ep_new = phi_p * ep + half_gain * (ev + new)
        step = stepping[:, j, None]
        ep = np.where(step, ep_new, ep)
        ev = np.where(step, new, ev)
        white = np.where(step, w * zj[:, 3:], white)
        out[0, fast, j], out[1, fast, j], out[2, fast, j] = ep, ev, white
    for r, nav in enumerate(group):
        nav.position_error, nav.velocity_error, nav._white = ep[r].tolist(), ev[r].tolist(), white[r].tolist()
        nav._k = int(ks[fast[r], -1])
    return out[0], out[1], out[2]


__all__ = [
    "error_tracks",
]
