"""What a :class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv` shows: the offscreen chase view
(``render_mode="rgb_array"``) and the PyBullet GUI's camera (``render_mode="human"``).

PyBullet allows one GUI connection per process, and its GUI needs a display: :class:`EnvRenderer`
checks both before the env connects (:meth:`EnvRenderer.claim_gui`) and gives the GUI back when
the env closes.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.envs.display import require_gui_display
from ihrcf_env.sim.world import World

__all__ = ["CHASE_FOV", "EnvRenderer"]

#: Vertical field of view (deg) of the chase view.
CHASE_FOV = 50.0


class EnvRenderer:
    """The renderer of one env: ``render_mode`` (None, ``"human"`` or ``"rgb_array"``) and the
    chase view's ``chase_size`` (width, height) in pixels. With ``"human"`` it claims the process's
    one GUI at once (RuntimeError if another open env holds it, or without a display); the env
    hands it its :class:`~ihrcf_env.sim.world.World` with :meth:`attach` and calls :meth:`release`
    when it closes."""

    _gui_owner: ClassVar[EnvRenderer | None] = None

    def __init__(self, render_mode: str | None, chase_size: tuple[int, int]) -> None:
        self.render_mode = render_mode
        self.chase_size = chase_size
        self.world: World | None = None
        self.released = False
        if render_mode == "human":
            self.claim_gui()

    def claim_gui(self) -> None:
        """PyBullet allows one GUI per process, and its GUI needs a display: check both first."""
        owner = EnvRenderer._gui_owner
        if owner is not None and not owner.released:
            raise RuntimeError(
                'only one render_mode="human" env can be open per process (PyBullet allows one GUI '
                'connection): close the other one, or use render_mode="rgb_array"'
            )
        require_gui_display()
        EnvRenderer._gui_owner = self

    def attach(self, world: World) -> None:
        """Render ``world`` from now on."""
        self.world = world

    def release(self) -> None:
        """Give the GUI back (if this renderer holds it) and drop the world; safe to call twice."""
        self.released = True
        self.world = None
        if EnvRenderer._gui_owner is self:
            EnvRenderer._gui_owner = None

    def render(self) -> NDArray[np.uint8] | None:
        """The Gymnasium ``render()``: the chase view (``"rgb_array"``), else None."""
        if self.render_mode == "rgb_array":
            return self.chase_view()
        return None

    def follow(self) -> None:
        """After a reset or step: point the GUI's camera at the drone (``"human"`` only)."""
        if self.render_mode == "human":
            world = self._world()
            world.deck.update_visuals()
            pos, _ = world.drone_pose()
            p.resetDebugVisualizerCamera(2.5, 30.0, -25.0, pos.tolist(), physicsClientId=world.client)

    def chase_view(self) -> NDArray[np.uint8]:
        """RGB image (H, W, 3) uint8 from behind and beside the drone (along its heading), looking
        at the point between drone and deck."""
        from ihrcf_env.sim.sensors import render_rgb

        w = self._world()
        w.deck.update_visuals()
        pos, R = w.drone_pose()
        deck_pos, _ = w.deck.pose()
        target = 0.5 * (pos + deck_pos) - np.array([0.0, 0.0, 0.35])
        yaw = math.atan2(R[1, 0], R[0, 0])
        back = np.array([-math.cos(yaw), -math.sin(yaw), 0.0])
        side = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
        eye = target + 2.5 * back + 0.8 * side + np.array([0.0, 0.0, 1.0])
        cid = w.client
        view = p.computeViewMatrix(eye.tolist(), target.tolist(), [0, 0, 1], physicsClientId=cid)
        width, height = self.chase_size
        proj = p.computeProjectionMatrixFOV(CHASE_FOV, width / height, 0.05, 30.0, physicsClientId=cid)
        cfg = CameraConfig(width=width, height=height)
        return render_rgb(cid, cfg, view, proj)

    def _world(self) -> World:
        if self.world is None:
            raise RuntimeError("the renderer has no world (its env is closed or not built yet)")
        return self.world
