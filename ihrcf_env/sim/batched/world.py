"""A world whose drone the numpy integrator flies (``WorldConfig(physics="numpy")``).

``World(config)`` returns this class when ``config.physics == "numpy"``: the scene, sensors and
contacts are the world's own; one control period is advanced by
:func:`ihrcf_env.sim.batched.loop.advance` (the same function a vector env calls for all its worlds
at once) instead of PyBullet's rigid-body solver.
"""

from __future__ import annotations

from ihrcf_env.sim.batched.loop import advance
from ihrcf_env.sim.world import Touchdown, World

__all__ = ["NumpyPhysicsWorld"]


class NumpyPhysicsWorld(World):
    """A :class:`~ihrcf_env.sim.world.World` flown by the numpy integrator."""

    def step(self) -> Touchdown | None:
        """Advance one control period with the numpy integrator; return the first contact, if any."""
        self._check_open()
        return advance([self])[0]
