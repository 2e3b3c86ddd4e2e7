"""The rendered camera's tag corners from a window: render and search only where the tag is.

When the agent does not get the image (``camera_output="corners"`` with the rendered camera), the
camera only has to render the pixels around the tag. :class:`WindowedTagCamera` projects the
tag's true corners, renders that window of the frame alone
(:meth:`~ihrcf_env.sim.sensors.camera.DownCamera.read_window`: an off-axis projection matrix, the
crop of the full frame up to TinyRenderer's rounding), the part of it inside the tag's image from
a private copy of the tag alone (:class:`TagScene`: the deck, legs and base it hides cost
TinyRenderer as much as the tag), and detects the tag there with the full frame's detection
parameters (:meth:`~ihrcf_env.core.estimators.TagDetector.detect` with ``origin`` and
``full_size``). The corners are those of rendering the full frame and detecting in it, at a
fraction of the cost (see :class:`WindowedTagCamera` for the figures).
"""

from __future__ import annotations

import math
import tempfile
import weakref
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.core.estimators.detector import TagDetector
from ihrcf_env.core.frames import matrix_from_quat
from ihrcf_env.core.rig import tag_corners_deck
from ihrcf_env.sim.assets import tag_texture
from ihrcf_env.sim.deck import Deck
from ihrcf_env.sim.sensors.base import TAG_CAMERA, BodyState, tag_reading
from ihrcf_env.sim.sensors.camera import DownCamera, Render, Window, tiny_render

#: Points sampled per tag edge (corners included) to bound its image under lens distortion, where
#: the straight edges of the tag bend.
_EDGE_SAMPLES = 9

#: How far (px) OpenCV's adaptive threshold (23 px window at most) reaches from an edge.
_THRESHOLD_REACH_PX = 12


def _outline(corners: NDArray[np.float64]) -> NDArray[np.float64]:
    """Points along the closed polygon ``corners`` (4, 3), :data:`_EDGE_SAMPLES` - 1 per edge."""
    t = np.linspace(0.0, 1.0, _EDGE_SAMPLES)[:-1, None]
    return np.concatenate([corners[i] + t * (corners[(i + 1) % 4] - corners[i]) for i in range(4)])


#: PyBullet visual geometry types (getVisualShapeData) whose bounding box is known from their
#: dimensions: sphere (radius), box (full extents), cylinder and capsule (length, radius).
_GEOM_SPHERE, _GEOM_BOX, _GEOM_CYLINDER, _GEOM_MESH, _GEOM_CAPSULE = 2, 3, 4, 5, 7


class TagScene:
    """A private PyBullet client holding a copy of the deck's tag quad alone: where the tag hides
    everything else, a window renders there at a fraction of the cost, with the world's pixels
    (a :class:`~ihrcf_env.sim.sensors.camera.RegionScene`).

    In the world, a window inside the tag's image is drawn by the tag (1 mm above the deck's
    visual top, so it wins every depth test) over the deck's faces, legs and base, which
    TinyRenderer still rasterises: at the 1 m hover they cost as much as the tag itself. Each
    frame (:meth:`prepare`) the copy is placed at the world tag's pose (the same position and
    quaternion: a full frame of the copy equals the world's on every tag pixel). :meth:`inner`
    offers the largest rectangle of a region whose pixel centres lie 1.5 px inside the tag
    quad's image, if (1) the camera is on the tag's front side and (2) every other visual of the
    world lies behind the tag's plane or outside that rectangle's view pyramid (tested on the
    oriented bounding boxes of all bodies' visuals, refreshed when the world's visual shapes
    change: the drone's own legs, or any body added to the world, are accounted for; a visual of
    unknown extent (a mesh) other than the tag disables the copy). :meth:`render` returns None if
    a pixel missed the tag (a crack along the quad's diagonal), and the world is rendered instead.
    The camera renders the rest of the window (up to four strips) in the world.
    """

    def __init__(self, camera: DownCamera, deck: Deck) -> None:
        self.camera = camera
        self.deck = deck
        self.world = camera.client
        shapes = p.getVisualShapeData(deck.tag_body, physicsClientId=self.world)
        if len(shapes) != 1 or shapes[0][2] != _GEOM_MESH:
            raise ValueError("the deck's tag must be one textured mesh visual")
        _, _, _, scale, mesh_file, local_pos, local_orn, rgba = shapes[0][:8]
        self._tmp = tempfile.TemporaryDirectory(prefix="ihrcf_env_tag_")
        self.client = p.connect(p.DIRECT)
        if self.client < 0:
            raise RuntimeError("could not start a PyBullet client for the tag scene")
        self._finalizer = weakref.finalize(self, _close_scene, self.client, self._tmp)
        cid = self.client
        vis = p.createVisualShape(
            p.GEOM_MESH,
            fileName=mesh_file.decode(),
            meshScale=list(scale),
            visualFramePosition=list(local_pos),
            visualFrameOrientation=list(local_orn),
            physicsClientId=cid,
        )
        self.body = p.createMultiBody(baseMass=0, baseVisualShapeIndex=vis, physicsClientId=cid)
        tex_file = Path(self._tmp.name) / "tag.png"
        cv2.imwrite(str(tex_file), tag_texture(deck.config.tag_id))  # the Deck's texture, same bytes
        tex = p.loadTexture(str(tex_file), physicsClientId=cid)
        p.changeVisualShape(self.body, -1, textureUniqueId=tex, rgbaColor=list(rgba), physicsClientId=cid)
        self._quad_local = _mesh_vertices(mesh_file.decode()) * np.asarray(scale)  # (n, 3) tag frame
        self._visuals: tuple[object, ...] = ()  # the world's visual shapes when _boxes was made
        self._boxes: list[tuple[int, int, NDArray[np.float64]]] | None = []  # (body, link, local corners)
        self._usable = False
        self._polygon = np.zeros((4, 3))  # edge lines a u + b v + c >= 0 inside (px)
        self._front = np.zeros((0, 8, 3))  # camera-frame corners of boxes in front of the tag plane

    def close(self) -> None:
        """Disconnect the private client (also done when the scene is garbage-collected)."""
        self._finalizer()

    def _visual_boxes(self) -> list[tuple[int, int, NDArray[np.float64]]] | None:
        """(body, link, 8 corners in the link frame) of every world visual except the tag; None if
        one has no known extent (a mesh)."""
        out = []
        for i in range(p.getNumBodies(physicsClientId=self.world)):
            body = p.getBodyUniqueId(i, physicsClientId=self.world)
            if body == self.deck.tag_body:
                continue
            for shape in p.getVisualShapeData(body, physicsClientId=self.world):
                geom, dims, pos, orn = shape[2], shape[3], shape[5], shape[6]
                if geom == _GEOM_BOX:
                    half = np.asarray(dims[:3]) / 2.0
                elif geom == _GEOM_SPHERE:
                    half = np.full(3, dims[0])
                elif geom in (_GEOM_CYLINDER, _GEOM_CAPSULE):
                    r = dims[1]
                    half = np.array([r, r, dims[0] / 2.0 + (r if geom == _GEOM_CAPSULE else 0.0)])
                else:
                    return None
                half = half + 1e-5  # float rounding (m); tessellated shapes lie inside their box
                signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
                corners = np.asarray(pos) + (signs * half) @ matrix_from_quat(orn).T
                out.append((body, int(shape[1]), corners))
        return out

    def prepare(self, state: BodyState) -> None:
        """Place the tag copy at the world tag's pose and work out, for the camera of ``state``,
        the tag's image and the visuals in front of its plane. Call after the deck's visuals are
        placed, before rendering."""
        world, cid = self.world, self.client
        pos, quat = p.getBasePositionAndOrientation(self.deck.tag_body, physicsClientId=world)
        p.resetBasePositionAndOrientation(self.body, pos, quat, physicsClientId=cid)
        self._usable = False
        ids = [
            p.getBodyUniqueId(i, physicsClientId=world) for i in range(p.getNumBodies(physicsClientId=world))
        ]
        visuals = tuple(p.getVisualShapeData(b, physicsClientId=world) for b in ids)
        if visuals != self._visuals:
            self._visuals = visuals
            self._boxes = self._visual_boxes()
        if self._boxes is None:
            return  # a visual of unknown extent: never stand in for the world
        cam = self.camera
        c = cam.config
        eye, R_wc = cam.pose(np.asarray(state.position, dtype=np.float64), np.asarray(state.rotation))
        origin, R_tag = np.asarray(pos), matrix_from_quat(quat)
        normal = R_tag[:, 2]
        if float((eye - origin) @ normal) < 0.01:
            return  # camera not clearly on the tag's front side
        quad = (origin + self._quad_local @ R_tag.T - eye) @ R_wc  # camera frame
        if np.any(quad[:, 2] <= c.near):
            return
        K = cam._K
        uv = quad[:, :2] / quad[:, 2:] * (K[0, 0], K[1, 1]) + (K[0, 2], K[1, 2])
        center = uv.mean(axis=0)
        lines = []
        for i in range(len(uv)):
            a, b = uv[i], uv[(i + 1) % len(uv)]
            n = np.array([a[1] - b[1], b[0] - a[0]])
            n /= np.linalg.norm(n)
            line = np.array([n[0], n[1], -float(n @ a)])
            if line[:2] @ center + line[2] < 0:
                line = -line
            lines.append(line)
        self._polygon = np.array(lines)
        front = []
        for body, link, local in self._boxes:
            if link < 0:
                bpos, born = p.getBasePositionAndOrientation(body, physicsClientId=world)
            else:
                ls = p.getLinkState(body, link, physicsClientId=world)
                bpos, born = ls[4], ls[5]
            corners = np.asarray(bpos) + local @ matrix_from_quat(born).T
            if np.all((corners - origin) @ normal < -1e-4):
                continue  # behind the tag's plane: hidden wherever the tag is
            front.append((corners - eye) @ R_wc)
        self._front = np.array(front).reshape(-1, 8, 3)
        self._usable = True

    def inner(self, region: Window) -> Window | None:
        """The largest rectangle found inside ``region`` (pinhole pixels) whose pixel centres lie
        1.5 px inside the tag's image, with no other visual in front of the tag there; None if
        there is none of at least a quarter of the region's area."""
        if not self._usable:
            return None
        x0, y0, w, h = region
        box = [x0, y0, x0 + w - 1, y0 + h - 1]  # inclusive pixel bounds

        def fits(b: list[int]) -> bool:
            pts = np.array([[b[0], b[1], 1.0], [b[2], b[1], 1.0], [b[2], b[3], 1.0], [b[0], b[3], 1.0]])
            return b[0] <= b[2] and b[1] <= b[3] and bool(np.all(pts @ self._polygon.T >= 1.5))

        # uniform inset (monotone: the tag's image is convex), then push each side back out
        lo, hi = 0, (min(w, h) - 1) // 2
        if not fits([box[0] + hi, box[1] + hi, box[2] - hi, box[3] - hi]):
            return None
        while lo < hi:
            mid = (lo + hi) // 2
            if fits([box[0] + mid, box[1] + mid, box[2] - mid, box[3] - mid]):
                hi = mid
            else:
                lo = mid + 1
        d = lo
        b = [box[0] + d, box[1] + d, box[2] - d, box[3] - d]
        for side, step in ((0, -1), (1, -1), (2, 1), (3, 1)):
            lo_e, hi_e = 0, d
            while lo_e < hi_e:
                mid = (lo_e + hi_e + 1) // 2
                trial = list(b)
                trial[side] += step * mid
                if fits(trial):
                    lo_e = mid
                else:
                    hi_e = mid - 1
            b[side] += step * lo_e
        inner = (b[0], b[1], b[2] - b[0] + 1, b[3] - b[1] + 1)
        if inner[2] * inner[3] * 4 < w * h or not self._clear(inner):
            return None
        return inner

    def _clear(self, region: Window) -> bool:
        """No visual in front of the tag's plane reaches into ``region``'s view pyramid."""
        if not len(self._front):
            return True
        x0, y0, w, h = region
        K = self.camera._K
        near = self.camera.config.near
        X, Y, Z = self._front[..., 0], self._front[..., 1], self._front[..., 2]
        u0, u1 = (x0 - 1.0 - K[0, 2]) / K[0, 0], (x0 + w - K[0, 2]) / K[0, 0]
        v0, v1 = (y0 - 1.0 - K[1, 2]) / K[1, 1], (y0 + h - K[1, 2]) / K[1, 1]
        outside = (
            np.all(Z < near, axis=1)
            | np.all(X < u0 * Z, axis=1)
            | np.all(X > u1 * Z, axis=1)
            | np.all(Y < v0 * Z, axis=1)
            | np.all(Y > v1 * Z, axis=1)
        )
        return bool(np.all(outside))

    def render(
        self,
        config: CameraConfig,
        view: object,
        proj: object,
        light: tuple[Sequence[float], float, float] | None,
        segmentation: bool,
        size: tuple[int, int],
    ) -> Render | None:
        """The region rendered with the tag alone (mask: the world's tag id), or None if a pixel
        missed the tag."""
        rgb, depth, mask = tiny_render(self.client, config, view, proj, light, True, size)
        assert mask is not None
        if np.any(mask < 0):
            return None
        mask[:] = self.deck.tag_body
        return rgb, depth, (mask if segmentation else None)


def _close_scene(client: int, tmp: tempfile.TemporaryDirectory[str]) -> None:
    try:
        p.disconnect(physicsClientId=client)
    except p.error:
        pass
    tmp.cleanup()


def _mesh_vertices(path: str) -> NDArray[np.float64]:
    """The ``v x y z`` vertices of an OBJ file (the tag quad's 4 corners), in file order."""
    rows = []
    for line in Path(path).read_text().splitlines():
        parts = line.split()
        if parts and parts[0] == "v":
            rows.append([float(x) for x in parts[1:4]])
    return np.array(rows, dtype=np.float64)


class WindowedTagCamera:
    """Tag-corner sensor (:data:`~ihrcf_env.sim.sensors.base.TAG_CAMERA`) of a rendered camera that
    renders only the window around the tag (a :class:`~ihrcf_env.sim.sensors.base.Sensor`).

    Each :meth:`read` places the deck's visuals, projects the true outline of the tag's black
    square (deck pose from ``deck``, corners from :func:`~ihrcf_env.core.rig.tag_corners_deck`,
    the camera's true intrinsics and lens distortion), takes its bounding box grown by ``margin``
    px (:meth:`tag_window`; the whole image near the image border), renders that window with
    ``camera.read_window`` (the realistic quality adds its blur margin itself; with ``tag_scene``
    the part inside the tag's image comes from a :class:`TagScene`) and detects the tag in it with
    a :class:`~ihrcf_env.core.estimators.TagDetector` (``tag_id``, ``refine``). A tag entirely
    outside the image (or partly behind the camera) is not rendered: ``"tag outside the image"``.
    The generator ``rng`` is drawn from exactly as the full camera's ``read`` draws from it, so
    every other sensor sees the same random stream as with the full image. :meth:`close`
    releases the tag scene's private PyBullet client (garbage collection does too).

    ``margin`` (px, default 14) is what the detector needs around the black square to behave as
    on the full frame: OpenCV's adaptive threshold looks up to 11 px away (23 px window), its
    corner refinement 6 px; plus the projected-vs-detected corner difference (< 1 px).

    The windowed detections equal the full frame's (``tests/sim/test_render_window.py``); its
    speed is in the generated results (``docs/results.md``).
    """

    name = TAG_CAMERA

    def __init__(
        self,
        camera: DownCamera,
        deck: Deck,
        tag_size: float,
        tag_id: int,
        margin: int = 14,
        refine: str = "subpix",
        tag_scene: bool = True,
    ) -> None:
        if not isinstance(camera, DownCamera):
            raise TypeError(f"camera must be a DownCamera, got {camera!r}")
        if not isinstance(deck, Deck):
            raise TypeError(f"deck must be a Deck, got {deck!r}")
        if isinstance(margin, bool) or not isinstance(margin, int | np.integer) or margin < 0:
            raise ValueError(f"margin must be a non-negative integer (px), got {margin!r}")
        self.camera = camera
        self.deck = deck
        self.margin = int(margin)
        self.detector = TagDetector(tag_id, refine)
        self._outline_deck = _outline(tag_corners_deck(tag_size))  # (checks tag_size)
        # the white quiet zone: one cell of the 8-cell marker around it (as on the Deck's quad)
        self._zone_deck = _outline(tag_corners_deck(tag_size * 10 / 8))
        self._K = camera.config.intrinsics
        self.window: Window | None = None  # the last read's window (None: nothing rendered)
        self.scene = TagScene(camera, deck) if tag_scene else None

    def close(self) -> None:
        """Release the private client of :attr:`scene` (also done at garbage collection)."""
        if self.scene is not None:
            self.scene.close()

    def reset(self, rng: np.random.Generator) -> None:
        """Start of an episode: the camera's :meth:`~DownCamera.reset` (realistic episode draws)."""
        self.camera.reset(rng)

    def tag_window(self, state: BodyState) -> tuple[Window | None, bool]:
        """The window (x0, y0, w, h) to render for the drone state ``state`` and whether the tag's
        black square is entirely inside the image; (None, False) when no part of it is in view or
        part of it is behind the camera. Uses the deck's current pose.

        The black square's bounding box grown by :attr:`margin`, when that window and the tag's
        white quiet zone grown by 14 px (OpenCV's threshold reach + 2) stay off the image border.
        Otherwise the whole image: OpenCV groups the tag with nested candidates (its quiet zone's
        outline, threshold bands around it) and drops the group if the group's largest member
        has a corner within 1 px of the image border; near the border those candidates can be
        large connected regions that a window would cut into different shapes, so only the full
        frame gives the full frame's answer there.
        """
        c = self.camera.config
        box = self._bounding_box(state, self._outline_deck)
        if box is None:
            return None, False
        u0, v0, u1, v1 = box
        if u1 < 0.0 or v1 < 0.0 or u0 > c.width - 1.0 or v0 > c.height - 1.0:
            return None, False
        inside = u0 >= 0.0 and v0 >= 0.0 and u1 <= c.width - 1.0 and v1 <= c.height - 1.0
        full: Window = (0, 0, c.width, c.height)
        if not inside:
            return full, False
        win = self._grown(box, self.margin)
        zone = self._bounding_box(state, self._zone_deck)
        if zone is None:
            return full, inside
        reach = _THRESHOLD_REACH_PX + 2
        zone_clear = (
            zone[0] - reach >= 0.0
            and zone[1] - reach >= 0.0
            and zone[2] + reach <= c.width - 1.0
            and zone[3] + reach <= c.height - 1.0
        )
        x0, y0, w, h = win
        off_border = x0 > 0 and y0 > 0 and x0 + w < c.width and y0 + h < c.height
        return (win if zone_clear and off_border else full), inside

    def _bounding_box(
        self, state: BodyState, outline_deck: NDArray[np.float64]
    ) -> tuple[float, float, float, float] | None:
        """(u_min, v_min, u_max, v_max) px of the deck-frame outline in the (distorted) image, or
        None if part of it is behind the camera."""
        cam = self.camera
        c = cam.config
        deck_pos, R_wd = self.deck.pose()
        eye, R_wc = cam.pose(np.asarray(state.position, dtype=np.float64), np.asarray(state.rotation))
        pts = (deck_pos + outline_deck @ R_wd.T - eye) @ R_wc  # camera frame (OpenCV)
        z = pts[:, 2]
        if np.any(z <= c.near):
            return None
        x, y = pts[:, 0] / z, pts[:, 1] / z
        k1, k2 = c.distortion
        if k1 or k2:
            r2 = x * x + y * y
            s = 1.0 + k1 * r2 + k2 * r2 * r2
            x, y = x * s, y * s
        K = self._K
        u, v = K[0, 0] * x + K[0, 2], K[1, 1] * y + K[1, 2]
        return float(u.min()), float(v.min()), float(u.max()), float(v.max())

    def _grown(self, box: tuple[float, float, float, float], margin: int) -> Window:
        """The pixel window of ``box`` grown by ``margin`` px, clipped to the image."""
        c = self.camera.config
        x0 = min(max(math.floor(box[0]) - margin, 0), c.width - 1)
        y0 = min(max(math.floor(box[1]) - margin, 0), c.height - 1)
        x1 = max(min(math.ceil(box[2]) + margin, c.width - 1), x0)
        y1 = max(min(math.ceil(box[3]) + margin, c.height - 1), y0)
        return (x0, y0, x1 - x0 + 1, y1 - y0 + 1)

    def read(self, state: BodyState, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        """:func:`~ihrcf_env.sim.sensors.base.tag_reading` of this frame: the tag's corners in the
        full image's pixels, or None with the reason (``"tag outside the image"``, ``"tag partly
        outside the image"``, ``"tag not detected"``)."""
        self.deck.update_visuals()
        window, inside = self.tag_window(state)
        self.window = window
        if window is None:
            self.camera.skip_frame(rng)
            return tag_reading(None, "tag outside the image")
        scene = self.scene
        if scene is not None and window != (0, 0, self.camera.config.width, self.camera.config.height):
            scene.prepare(state)
        else:
            scene = None
        image = self.camera.read_window(state, window, rng, scene)
        c = self.camera.config
        corners = self.detector.detect(image, origin=window[:2], full_size=(c.width, c.height))
        if corners is None:
            return tag_reading(None, "tag not detected" if inside else "tag partly outside the image")
        return tag_reading(corners, "")


__all__ = [
    "TagScene",
    "WindowedTagCamera",
]
