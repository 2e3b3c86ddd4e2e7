"""Calibration props in a :class:`~ihrcf_env.sim.world.World`: the chessboard and the four colour pads.

* The **chessboard** (paper section 2.1) is a textured quad (the UV-mapped ``tag_quad.obj`` of the
  tag, scaled) with ``pattern = (nx, ny)`` inner corners, i.e. ``(nx + 1) x (ny + 1)`` squares of
  side ``square`` (m) inside a one-square white margin. Board frame: origin at the board centre,
  z out of the printed face; the texture's rows run along board -x and its columns along board -y
  (the tag quad's mapping, see ``assets/tag_quad.obj``).
* The **pads** (section 2.2, Fig. 5) are flat visual-only discs (a 128-gon, normal +z) coloured
  :data:`PAD_RGB`; pad i is centred on the touch point of sensor ps_i and lies in the deck's top
  surface (the surface the ToF rays hit; the deck's own visual top is 1 mm lower, so nothing
  z-fights). Pads have no collision shape, so they never change a ToF reading.

The deck's AprilTag quad is parked out of sight (:meth:`CalibrationScene.hide_tag`) for every
frame taken with :meth:`CalibrationScene.render`; the world's own ``update_visuals`` (called by
``World.sensing.render_camera``/``World.reset``) puts it back, as does :meth:`CalibrationScene.restore_tag`.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType

import cv2
import numpy as np
import pybullet as p
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.frames import as_array, quat_from_matrix
from ihrcf_env.core.rig import PAD_COLOURS
from ihrcf_env.sim.assets import asset_path
from ihrcf_env.sim.world import World

#: Pad colours (RGB in [0, 1]) in ps1..ps4 order. With the default light (ambient 0.6, diffuse 0.35)
#: a level pad renders at ~0.925 of its colour. Table 1 then takes a rendered green G (0..1) as
#: green only for 0.41 < G < 0.68 (Cr <= 90 needs G > 0.41; above 0.68, Y >= 103 and Cb <= 95 make
#: it yellow too), so green is (0, 0.6, 0) -> G ~ 0.55; (0, 0.8, 0) renders at G ~ 0.74 and is
#: also "yellow". Blue, yellow and red pass only their own box for any brightness above ~0.5.
#: ``tests/test_calibration_sim.py`` checks this on rendered frames, deck level and tilted 15 deg.
PAD_RGB: Mapping[str, tuple[float, float, float]] = MappingProxyType(
    {"blue": (0.0, 0.0, 1.0), "green": (0.0, 0.6, 0.0), "yellow": (1.0, 1.0, 0.0), "red": (1.0, 0.0, 0.0)}
)

#: Default pad radius (m). Neighbouring touch points are 2 a cos(45 deg) = 0.1414 m apart for the
#: default rig, so the pads leave a 6 cm gap; all four are fully in a 512x512, 60 deg image from a
#: range of about 0.19 m up.
DEFAULT_PAD_RADIUS: float = 0.04

#: Where hidden props are parked (world, m): far beyond any camera's far plane.
PARKING: tuple[float, float, float] = (0.0, 0.0, -100.0)

_IDENTITY_QUAT = (0.0, 0.0, 0.0, 1.0)


def write_disc_obj(path: Path, segments: int = 128) -> Path:
    """Write a unit-radius disc (triangle fan in the XY plane, normal +z, with UVs) as an OBJ file."""
    if segments < 8:
        raise ValueError(f"a disc needs at least 8 segments, got {segments}")
    a = 2.0 * math.pi * np.arange(segments) / segments
    lines = ["# unit disc, normal +z", "v 0 0 0"]
    lines += [f"v {math.cos(t):.12f} {math.sin(t):.12f} 0" for t in a]
    lines += ["vt 0.5 0.5"] + [f"vt {0.5 + 0.5 * math.cos(t):.12f} {0.5 + 0.5 * math.sin(t):.12f}" for t in a]
    lines.append("vn 0 0 1")
    for k in range(segments):
        i, j = 2 + k, 2 + (k + 1) % segments
        lines.append(f"f 1/1/1 {i}/{i}/1 {j}/{j}/1")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def chessboard_texture(
    pattern: tuple[int, int] = (7, 9), square_px: int = 64, margin_squares: int = 1
) -> NDArray[np.uint8]:
    """RGB chessboard image with ``pattern = (nx, ny)`` inner corners and a white margin.

    The image has ``(ny + 1 + 2 m)`` rows and ``(nx + 1 + 2 m)`` columns of ``square_px`` squares
    (``m = margin_squares``); the top-left square of the board proper is black.
    """
    nx, ny = int(pattern[0]), int(pattern[1])
    if nx < 2 or ny < 2:
        raise ValueError(f"pattern must have at least 2 x 2 inner corners, got {pattern}")
    if square_px < 2 or margin_squares < 1:
        raise ValueError("square_px must be >= 2 and margin_squares >= 1")
    rows, cols = ny + 1, nx + 1
    rr, cc = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    board = np.where((rr + cc) % 2 == 0, 0, 255).astype(np.uint8)
    board = np.kron(board, np.ones((square_px, square_px), dtype=np.uint8))
    m = margin_squares * square_px
    img = np.full((board.shape[0] + 2 * m, board.shape[1] + 2 * m), 255, np.uint8)
    img[m:-m, m:-m] = board
    return np.ascontiguousarray(np.repeat(img[:, :, None], 3, axis=2))


class CalibrationScene:
    """Chessboard and colour pads added to a world's PyBullet client (visual-only bodies).

    Args:
        world: the world to decorate (its client, deck and temporary directory are used).
        pad_radius: pad radius (m).
        pattern: chessboard inner corners ``(nx, ny)``.
        square: chessboard square side (m).
        texture_dir: where to write the generated OBJ/PNG files (default: a private temporary
            directory removed by :meth:`close`).
    """

    def __init__(
        self,
        world: World,
        pad_radius: float = DEFAULT_PAD_RADIUS,
        pattern: tuple[int, int] = (7, 9),
        square: float = 0.04,
        texture_dir: Path | None = None,
    ) -> None:
        if not (math.isfinite(pad_radius) and pad_radius > 0):
            raise ValueError(f"pad_radius must be positive (m), got {pad_radius!r}")
        if not (math.isfinite(square) and square > 0):
            raise ValueError(f"square must be positive (m), got {square!r}")
        self.world = world
        self.client = cid = world.client
        self.pad_radius = float(pad_radius)
        self.pattern = (int(pattern[0]), int(pattern[1]))
        self.square = float(square)
        self._tmp = tempfile.TemporaryDirectory(prefix="ihrcf_calib_") if texture_dir is None else None
        tdir = Path(self._tmp.name) if self._tmp is not None else Path(texture_dir)  # type: ignore[arg-type]
        tdir.mkdir(parents=True, exist_ok=True)

        disc = write_disc_obj(tdir / "pad_disc.obj")
        self.pad_bodies: list[int] = []
        for colour in PAD_COLOURS:
            vis = p.createVisualShape(
                p.GEOM_MESH,
                fileName=str(disc),
                meshScale=[self.pad_radius, self.pad_radius, 1.0],
                rgbaColor=[*PAD_RGB[colour], 1.0],
                physicsClientId=cid,
            )
            body = p.createMultiBody(
                baseMass=0, baseVisualShapeIndex=vis, basePosition=PARKING, physicsClientId=cid
            )
            self.pad_bodies.append(body)

        tex = chessboard_texture(self.pattern)
        tex_file = tdir / "chessboard.png"
        cv2.imwrite(str(tex_file), cv2.cvtColor(tex, cv2.COLOR_RGB2BGR))
        nx, ny = self.pattern
        # Texture rows (ny + 3 squares) run along board -x, columns (nx + 3 squares) along board -y.
        self.board_extent = ((ny + 3) * self.square, (nx + 3) * self.square)  # (x, y) in m
        board_vis = p.createVisualShape(
            p.GEOM_MESH,
            fileName=str(asset_path("tag_quad.obj")),
            meshScale=[self.board_extent[0], self.board_extent[1], 1.0],
            physicsClientId=cid,
        )
        self.board_body = p.createMultiBody(
            baseMass=0, baseVisualShapeIndex=board_vis, basePosition=PARKING, physicsClientId=cid
        )
        tex_id = p.loadTexture(str(tex_file), physicsClientId=cid)
        p.changeVisualShape(
            self.board_body, -1, textureUniqueId=tex_id, rgbaColor=[1, 1, 1, 1], physicsClientId=cid
        )
        self._closed = False

    # -- tag --------------------------------------------------------------------------------
    def hide_tag(self) -> None:
        """Park the deck's tag quad out of sight (undone by every ``World.step``/``World.reset``)."""
        p.resetBasePositionAndOrientation(
            self.world.deck.tag_body, PARKING, _IDENTITY_QUAT, physicsClientId=self.client
        )

    def restore_tag(self) -> None:
        """Put the tag back on the deck at the deck's current pose."""
        self.world.deck.update_visuals()

    def render(self) -> NDArray[np.uint8]:
        """The drone camera's RGB image (H, W, 3) uint8 with the tag hidden and the props as placed.

        Deck visuals (legs) are synchronised first, then the tag is parked; ``World.sensing.render_camera``
        is not used because it puts the tag back.
        """
        cam = self.world.camera
        if cam is None:
            raise RuntimeError("calibration needs a camera (WorldConfig.camera is None)")
        self.world.deck.update_visuals()
        self.hide_tag()
        pos, R = self.world.drone_pose()
        return cam.render(pos, R)

    # -- pads -------------------------------------------------------------------------------
    def place_pads(self, centres_world: ArrayLike, R_world_surface: ArrayLike) -> None:
        """Centre pad i (ps1..ps4 order) on ``centres_world[i]`` (4, 3) (world, m), lying in the plane
        whose orientation is ``R_world_surface`` (its z column is the surface normal)."""
        c = as_array(centres_world, (4, 3), "centres_world")
        q = quat_from_matrix(as_array(R_world_surface, (3, 3), "R_world_surface")).tolist()
        for body, centre in zip(self.pad_bodies, c, strict=True):
            p.resetBasePositionAndOrientation(body, centre.tolist(), q, physicsClientId=self.client)

    def hide_pads(self) -> None:
        for body in self.pad_bodies:
            p.resetBasePositionAndOrientation(body, PARKING, _IDENTITY_QUAT, physicsClientId=self.client)

    # -- chessboard -------------------------------------------------------------------------
    def place_board(self, position_world: ArrayLike, R_world_board: ArrayLike) -> None:
        """Put the board's centre at ``position_world`` (m) with orientation ``R_world_board``."""
        pos = as_array(position_world, (3,), "position_world")
        q = quat_from_matrix(as_array(R_world_board, (3, 3), "R_world_board")).tolist()
        p.resetBasePositionAndOrientation(self.board_body, pos.tolist(), q, physicsClientId=self.client)

    def hide_board(self) -> None:
        p.resetBasePositionAndOrientation(
            self.board_body, PARKING, _IDENTITY_QUAT, physicsClientId=self.client
        )

    def board_outline(self) -> NDArray[np.float64]:
        """(4, 3) corners of the whole board (white margin included) in the board frame (m)."""
        hx, hy = self.board_extent[0] / 2, self.board_extent[1] / 2
        return np.array([[hx, hy, 0.0], [hx, -hy, 0.0], [-hx, -hy, 0.0], [-hx, hy, 0.0]])

    # -- lifecycle --------------------------------------------------------------------------
    def close(self) -> None:
        """Remove the props, restore the tag and delete the generated files; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        try:
            for body in [*self.pad_bodies, self.board_body]:
                p.removeBody(body, physicsClientId=self.client)
            self.restore_tag()
        except p.error:  # the world's client is already gone
            pass
        if self._tmp is not None:
            self._tmp.cleanup()

    def __enter__(self) -> CalibrationScene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = [
    "DEFAULT_PAD_RADIUS",
    "PAD_RGB",
    "PARKING",
    "CalibrationScene",
    "chessboard_texture",
    "write_disc_obj",
]
