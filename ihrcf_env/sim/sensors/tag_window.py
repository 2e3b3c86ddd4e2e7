"""The rendered camera's tag corners from a window: render and search only where the tag is.

When the agent does not get the image (``camera_output="corners"`` with the rendered camera), the
camera only has to render the pixels around the tag. :class:`WindowedTagCamera` projects the
tag's true corners, renders that window of the frame alone
(:meth:`~ihrcf_env.sim.sensors.camera.DownCamera.read_window`: an off-axis projection matrix,
pixel for pixel the crop of the full frame) and detects the tag there with the full frame's
detection parameters (:meth:`~ihrcf_env.core.estimators.TagDetector.detect` with ``origin`` and
``full_size``). The corners are those of rendering the full frame and detecting in it, at a
fraction of the cost (see the class docstring for the figures).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.estimators.detector import TagDetector
from ihrcf_env.core.rig import tag_corners_deck
from ihrcf_env.sim.deck import Deck
from ihrcf_env.sim.sensors.base import TAG_CAMERA, BodyState, tag_reading
from ihrcf_env.sim.sensors.camera import DownCamera, Window

#: Points sampled per tag edge (corners included) to bound its image under lens distortion, where
#: the straight edges of the tag bend.
_EDGE_SAMPLES = 9

#: How far (px) OpenCV's adaptive threshold (23 px window at most) reaches from an edge.
_THRESHOLD_REACH_PX = 12


def _outline(corners: NDArray[np.float64]) -> NDArray[np.float64]:
    """Points along the closed polygon ``corners`` (4, 3), :data:`_EDGE_SAMPLES` - 1 per edge."""
    t = np.linspace(0.0, 1.0, _EDGE_SAMPLES)[:-1, None]
    return np.concatenate([corners[i] + t * (corners[(i + 1) % 4] - corners[i]) for i in range(4)])


class WindowedTagCamera:
    """Tag-corner sensor (:data:`~ihrcf_env.sim.sensors.base.TAG_CAMERA`) of a rendered camera that
    renders only the window around the tag (a :class:`~ihrcf_env.sim.sensors.base.Sensor`).

    Each :meth:`read` places the deck's visuals, projects the true outline of the tag's black
    square (deck pose from ``deck``, corners from :func:`~ihrcf_env.core.rig.tag_corners_deck`,
    the camera's true intrinsics and lens distortion), takes its bounding box grown by ``margin``
    px and clipped to the image, renders that window with ``camera.read_window`` (the realistic
    quality adds its blur margin itself) and detects the tag in it with a
    :class:`~ihrcf_env.core.estimators.TagDetector` (``tag_id``, ``refine``). A tag entirely
    outside the image (or partly behind the camera) is not rendered: ``"tag outside the image"``.
    The generator ``rng`` is drawn from exactly as the full camera's ``read`` draws from it, so
    every other sensor sees the same random stream as with the full image.

    ``margin`` (px, default 14) is what the detector needs around the black square to behave as
    on the full frame: OpenCV's adaptive threshold looks up to 11 px away (23 px window), its
    corner refinement 6 px; plus the projected-vs-detected corner difference (< 1 px).

    Measured against rendering the full 512x512 frame and detecting in it (tests/sim/
    test_render_window.py): the same corners within 1e-3 px over random poses, tags near the
    image border included, ideal and realistic quality. Cost at the paper's 1 m hover (tag
    0.4 m, ~185 px): see the README / ``ihrcf_env.experiments.speed``.
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
        image = self.camera.read_window(state, window, rng)
        c = self.camera.config
        corners = self.detector.detect(image, origin=window[:2], full_size=(c.width, c.height))
        if corners is None:
            return tag_reading(None, "tag not detected" if inside else "tag partly outside the image")
        return tag_reading(corners, "")
