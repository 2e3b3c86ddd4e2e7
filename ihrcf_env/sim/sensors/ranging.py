"""The ToF sensors ps1..ps4 of N drones at once, by closed-form ray casting (:mod:`.rays`): the
rays of a :class:`~ihrcf_env.sim.sensors.tof.ToFArray` given its world's deck, and the numpy
reference of the JAX backend's :mod:`ihrcf_env.fast.rays` and :mod:`ihrcf_env.fast.tof`.

:class:`ClosedFormToF` gives what :class:`~ihrcf_env.sim.sensors.tof.ToFArray` ``true_ranges``,
``cone_returns`` and ``cone_ranges`` give (noise-free), for stacks of drone and deck poses, with the
same arithmetic on the rays' hits. Row-independent: a drone's readings never depend on the other rows.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.sim.sensors.rays import RayHits, RayScene, cast_rays, nearest, self_hits, to_world

if TYPE_CHECKING:
    from ihrcf_env.config.sensors import VL53L1X


class ClosedFormToF:
    """Four ToF sensors at ``positions_body`` (4, 3; body frame, m) reading up to ``max_range`` (m)
    in ``scene``; ``model`` the realistic cone model (None: one ray per sensor along body -z)."""

    def __init__(
        self, positions_body: NDArray[np.float64], max_range: float, scene: RayScene, model: VL53L1X | None
    ) -> None:
        self.positions_body = np.array(positions_body, dtype=np.float64).reshape(4, 3)
        self.max_range = float(max_range)
        self.scene = scene
        self.model = model
        axis = np.tile([0.0, 0.0, -1.0], (4, 1))
        self._axis = self._mount(self.positions_body, axis)
        if model is not None:
            dirs = model.directions()  # sensor frame, +z along the beam = body -z
            dirs_body = np.column_stack([dirs[:, 0], dirs[:, 1], -dirs[:, 2]])
            n = model.rays
            self._cone = self._mount(np.repeat(self.positions_body, n, axis=0), np.tile(dirs_body, (4, 1)))
            self._gain = model.flat_gain

    def _mount(
        self, starts: NDArray[np.float64], dirs: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Rays fixed in the body frame: (starts, directions, own-box fraction, own-box normal)."""
        f, n = self_hits(starts, dirs, self.max_range)
        return starts, dirs, f, n

    def cone_hits(
        self,
        position: NDArray[np.float64],
        rotation: NDArray[np.float64],
        deck_position: NDArray[np.float64],
        deck_rotation: NDArray[np.float64],
    ) -> tuple[RayHits, NDArray[np.float64], NDArray[np.float64]]:
        """Realistic model only: the hits (N, 4 rays) of the cones' rays (sensor by sensor), their
        world starts and directions (N, 4 rays, 3)."""
        if self.model is None:
            raise RuntimeError("cone_hits needs the realistic ToF model (tof_noise='realistic')")
        h, dirs = self._cast(self._cone, position, rotation, deck_position, deck_rotation)
        starts = to_world(np.broadcast_to(self._cone[0], dirs.shape), rotation) + position[:, None, :]
        return h, starts, dirs

    def _cast(
        self,
        rays: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
        position: NDArray[np.float64],
        rotation: NDArray[np.float64],
        deck_position: NDArray[np.float64],
        deck_rotation: NDArray[np.float64],
    ) -> tuple[RayHits, NDArray[np.float64]]:
        """Hits of body-fixed ``rays`` for drones at ``position`` (N, 3), ``rotation`` (N, 3, 3), and
        the rays' world directions (N, R, 3)."""
        s_b, d_b, f_self, n_self = rays
        n = len(position)
        starts = to_world(np.broadcast_to(s_b, (n, *s_b.shape)), rotation) + position[:, None, :]
        dirs = to_world(np.broadcast_to(d_b, (n, *d_b.shape)), rotation)
        h = cast_rays(starts, dirs, self.max_range, deck_position, deck_rotation, self.scene)
        if np.isfinite(f_self).any():  # a sensor sees part of its own drone (a rig-dependent constant)
            own = to_world(np.broadcast_to(n_self, (n, *n_self.shape)), rotation)
            fr = np.stack(
                [np.where(h.hit, h.fraction, np.inf), np.broadcast_to(f_self, h.fraction.shape)], -1
            )
            h = nearest(fr, np.stack([h.normal, own], axis=-2))
        return h, dirs

    def true_ranges(
        self,
        position: NDArray[np.float64],
        rotation: NDArray[np.float64],
        deck_position: NDArray[np.float64],
        deck_rotation: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """(ranges (N, 4) m, hit flags (N, 4)) of the four beam axes; misses read ``max_range``."""
        h, _ = self._cast(self._axis, position, rotation, deck_position, deck_rotation)
        return np.where(h.hit, h.fraction * self.max_range, self.max_range), h.hit

    def cone_returns(
        self,
        position: NDArray[np.float64],
        rotation: NDArray[np.float64],
        deck_position: NDArray[np.float64],
        deck_rotation: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Realistic model only: ``(lengths, signals)``, each (N, 4, rays), as ``ToFArray.cone_returns``."""
        if self.model is None:
            raise RuntimeError("cone_returns needs the realistic ToF model (tof_noise='realistic')")
        h, dirs = self._cast(self._cone, position, rotation, deck_position, deck_rotation)
        r = np.where(h.hit, np.maximum(h.fraction * self.max_range, 1e-4), 1.0)
        cos_i = np.abs(
            h.normal[..., 0] * dirs[..., 0]
            + h.normal[..., 1] * dirs[..., 1]
            + h.normal[..., 2] * dirs[..., 2]
        )
        signal = np.where(h.hit, self.model.reflectance * cos_i / r**2, 0.0)
        shape = (len(position), 4, self.model.rays)
        return np.where(h.hit, r, np.nan).reshape(shape), signal.reshape(shape)

    def cone_ranges(
        self,
        position: NDArray[np.float64],
        rotation: NDArray[np.float64],
        deck_position: NDArray[np.float64],
        deck_rotation: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Realistic model only: noise-free readings (N, 4) (m; ``nan`` where nothing is hit) and
        total signals (N, 4), as ``ToFArray.cone_ranges``."""
        r, s = self.cone_returns(position, rotation, deck_position, deck_rotation)
        total = s.sum(axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.nansum(s * r, axis=-1) / total / self._gain
        return np.where(total > 0, mean, np.nan), total / r.shape[-1]


__all__ = [
    "ClosedFormToF",
]
