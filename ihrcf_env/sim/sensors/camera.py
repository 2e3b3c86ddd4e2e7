"""The drone's downward camera, rendered by PyBullet's TinyRenderer.

Two qualities (:attr:`CameraConfig.quality`): ``"ideal"`` (a clean render on a blank background,
fixed light, no noise or blur) and ``"realistic"`` (a textured sea/ground background, per-episode
light and exposure, motion blur, vignetting, read and shot noise of a real global-shutter sensor:
:mod:`ihrcf_env.sim.sensors.imaging`). What the realistic model costs per frame and the README's
example frame: :mod:`ihrcf_env.experiments.camera_realism`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol

import cv2
import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.sim.sensors.base import BodyState
from ihrcf_env.sim.sensors.imaging import (
    EpisodeImaging,
    RealisticImager,
    add_sensor_noise,
    blur_kernel,
    ground_homography,
    image_motion_px,
    motion_blur,
)

#: A pixel rectangle of the image, ``(x0, y0, width, height)``: columns ``x0 .. x0 + width - 1``,
#: rows ``y0 .. y0 + height - 1`` (OpenCV convention: x right, y down, (0, 0) the top-left pixel).
Window = tuple[int, int, int, int]

#: What :func:`tiny_render` returns: RGB (H, W, 3), z-buffer (H, W), segmentation mask (H, W) or None.
Render = tuple[NDArray[np.uint8], NDArray[np.float32], NDArray[np.int32] | None]


class RegionScene(Protocol):
    """A cheaper stand-in for the world when rendering part of a pixel region of the current frame
    (e.g. :class:`~ihrcf_env.sim.sensors.tag_window.TagScene`: the tag alone, where it hides
    everything else). :meth:`DownCamera.read_window` asks :meth:`inner` for the part of the pinhole
    region it needs that may be rendered here, renders that part with :meth:`render` (None: the
    result would differ from the world's, the world is rendered instead) and the rest of the
    region in the world."""

    def inner(self, region: Window) -> Window | None:
        """The largest rectangle inside ``region`` (pinhole pixels) this scene renders exactly as
        the world this frame, or None."""
        ...

    def render(
        self,
        config: CameraConfig,
        view: object,
        proj: object,
        light: tuple[Sequence[float], float, float] | None,
        segmentation: bool,
        size: tuple[int, int],
    ) -> Render | None:
        """:func:`tiny_render` of a region in this scene (world body ids in the mask), or None."""
        ...


class DownCamera:
    """Renders what the drone's downward camera sees with ``ER_TINY_RENDERER`` (a :class:`Sensor`)."""

    name = "camera"

    def __init__(self, client: int, config: CameraConfig, rig: SensorRig) -> None:
        self.client = client
        self.config = config
        self._cam_offset = np.asarray(rig.camera_position, dtype=np.float64)
        self._proj = p.computeProjectionMatrixFOV(
            fov=math.degrees(config.fov),
            aspect=config.width / config.height,
            nearVal=config.near,
            farVal=config.far,
            physicsClientId=client,
        )
        self._maps = _distortion_maps(config) if any(config.distortion) else None
        self.imager: RealisticImager | None = None
        if config.quality == "realistic":
            self.imager = RealisticImager(
                config.imaging, config.intrinsics, config.width, config.height, self._maps
            )
        K = config.intrinsics
        self._K = K
        self._principal_pixel = (int(round(K[0, 2])), int(round(K[1, 2])))  # (column, row)
        # realistic windows: blur margin (px) rendered around the window, from the last frame
        self._blur_margin = _BLUR_MARGIN_MIN

    @property
    def episode(self) -> EpisodeImaging | None:
        """The realistic camera's current episode (light, exposure, gain); None when ideal or
        before the first reset."""
        return None if self.imager is None else self.imager.episode

    def pose(
        self, pos: NDArray[np.float64], R_wb: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World pose (optical centre, R_world_cam) of the camera for a body pose."""
        return pos + R_wb @ self._cam_offset, R_wb @ R_BODY_CAM

    def reset(self, rng: np.random.Generator) -> None:
        """Realistic quality: draw the episode's light, exposure/gain, background placement and
        noise bank from ``rng``. Ideal quality: nothing (draws nothing from ``rng``). Either way
        the windows' blur margin starts afresh, so an episode's windows do not depend on the
        previous episode's."""
        self._blur_margin = _BLUR_MARGIN_MIN
        if self.imager is not None:
            self.imager.reset(rng)

    def read(self, state: BodyState, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        """``image``: (H, W, 3) uint8. The world places the deck's visuals before reading.

        Realistic quality: the frame's noise is drawn from ``rng`` (and the episode too, if
        :meth:`reset` was not called yet)."""
        if self.imager is None:
            return {"image": self.render(state.position, state.rotation)}
        return {"image": self.render_realistic(state, rng)}

    def _view(self, eye: NDArray[np.float64], R_wc: NDArray[np.float64]) -> Any:
        return p.computeViewMatrix(
            cameraEyePosition=eye.tolist(),
            cameraTargetPosition=(eye + R_wc[:, 2]).tolist(),
            cameraUpVector=(-R_wc[:, 1]).tolist(),
            physicsClientId=self.client,
        )

    def render_realistic(self, state: BodyState, rng: np.random.Generator) -> NDArray[np.uint8]:
        """The realistic camera's image (H, W, 3) uint8 for the drone state ``state``."""
        imager = self.imager
        if imager is None:
            raise RuntimeError("render_realistic needs a camera with quality='realistic'")
        if imager.episode is None:
            imager.reset(rng)
        ep = imager.episode
        assert ep is not None
        R_wb = np.asarray(state.rotation, dtype=np.float64)
        eye, R_wc = self.pose(np.asarray(state.position, dtype=np.float64), R_wb)
        c = self.config
        light = (tuple(ep.light_direction), ep.ambient, ep.diffuse)
        rgb, depth, seg_a = tiny_render(self.client, c, self._view(eye, R_wc), self._proj, light, True)
        assert seg_a is not None
        omega = np.asarray(state.angular_velocity, dtype=np.float64)
        v_eye = np.asarray(state.velocity, dtype=np.float64) + np.cross(omega, R_wb @ self._cam_offset)
        z_axis = self._axis_depth(np.asarray(depth).reshape(c.height, c.width), eye, R_wc)
        return imager.process(rgb, seg_a, eye, R_wc, v_eye, omega, z_axis, float(state.time), rng)

    def _axis_depth(self, depth: NDArray[Any], eye: NDArray[np.float64], R_wc: NDArray[np.float64]) -> float:
        """Distance (m) along the optical axis to the scene at the principal point: the z-buffer
        there, or the ground plane z = 0 if the renderer saw background."""
        col, row = self._principal_pixel
        return self._axis_distance(float(depth[row, col]), eye, R_wc)

    def _axis_distance(self, d: float, eye: NDArray[np.float64], R_wc: NDArray[np.float64]) -> float:
        """:meth:`_axis_depth` from the z-buffer value ``d`` at the principal pixel."""
        c = self.config
        if d < 1.0:
            return c.far * c.near / (c.far - (c.far - c.near) * d)
        down = -float(R_wc[2, 2])
        return float(eye[2]) / down if down > 1e-3 else c.far

    def render(self, pos: NDArray[np.float64], R_wb: NDArray[np.float64]) -> NDArray[np.uint8]:
        """Ideal-quality RGB image (H, W, 3) uint8 for the body pose (world position ``pos``,
        rotation ``R_wb``), whatever :attr:`CameraConfig.quality` (calibration scenes use it)."""
        eye, R_wc = self.pose(pos, R_wb)
        view = self._view(eye, R_wc)
        img = render_rgb(self.client, self.config, view, self._proj)
        if self._maps is None:
            return img
        out = cv2.remap(img, self._maps[0], self._maps[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return np.asarray(out, dtype=np.uint8)

    # -- windows: render only a pixel rectangle of the frame ---------------------------------
    def render_window(
        self,
        pos: NDArray[np.float64],
        R_wb: NDArray[np.float64],
        window: Window,
        scene: RegionScene | None = None,
    ) -> NDArray[np.uint8]:
        """Ideal-quality ``window`` = (x0, y0, w, h) of :meth:`render`'s image, (h, w, 3) uint8,
        rendering only the pixels it needs (:func:`window_projection`): the pixels of
        ``render(pos, R_wb)[y0:y0 + h, x0:x0 + w]`` (up to TinyRenderer's rounding, see
        :func:`window_projection`). With lens distortion the window's pixels come from a (larger)
        window of the pinhole render, where the distortion maps sample; that one is rendered and
        remapped. ``scene``: a :class:`RegionScene` that may stand in for the world for part of
        the region (the same pixels, fewer bodies to draw)."""
        c = self.config
        win = check_window(window, c.width, c.height)
        eye, R_wc = self.pose(np.asarray(pos, dtype=np.float64), np.asarray(R_wb, dtype=np.float64))
        src = self._source_region(win)
        img = self._render_region(self._view(eye, R_wc), src, scene=scene)[0]
        return self._distort_region(img, src, win)

    def read_window(
        self, state: BodyState, window: Window, rng: np.random.Generator, scene: RegionScene | None = None
    ) -> NDArray[np.uint8]:
        """``window`` = (x0, y0, w, h) of the image :meth:`read` returns, (h, w, 3) uint8, rendering
        and processing only what that window needs. Draws from ``rng`` exactly what :meth:`read`
        draws, so the generator's stream does not depend on the window.

        Ideal quality: :meth:`render_window` (the crop of :meth:`read`'s image).
        Realistic quality: the window of the pinhole render the window needs, grown by the motion
        blur's kernel radius (clipped to the image), is rendered with its segmentation mask and
        goes through the realistic pipeline of
        :class:`~ihrcf_env.sim.sensors.imaging.RealisticImager` on that region (background
        composite, blur, distortion remap, vignetting, the noise bank at the window's offset): the
        post-processing is exact on the region (same bytes as the full frame's); what differs
        is the render's own rounding (:func:`window_projection`), plus two rarer cases, +-1 DN
        on a few pixels: a blur streak longer than 8 px (a kernel of 13 x 13 px or more, which
        OpenCV's ``filter2D`` convolves by DFT, image-size dependent), and a frame whose z-buffer
        value at the principal point differs from the full render's by one float ulp (the blur
        length depends on it).

        ``scene``: a :class:`RegionScene` that may stand in for the world for part of the region."""
        c = self.config
        win = check_window(window, c.width, c.height)
        if self.imager is None:
            return self.render_window(state.position, state.rotation, win, scene)
        return self._realistic_window(state, win, rng, scene)

    def skip_frame(self, rng: np.random.Generator) -> None:
        """Draw from ``rng`` what one :meth:`read` would draw, rendering nothing (a windowed
        sensor that needs no pixels this frame keeps the generator's stream aligned with
        :meth:`read`'s). Ideal quality: draws nothing."""
        imager = self.imager
        if imager is None:
            return
        if imager.episode is None:
            imager.reset(rng)
        _noise_draw(imager, rng)

    def _render_region(
        self,
        view: object,
        region: Window,
        light: tuple[Sequence[float], float, float] | None = None,
        segmentation: bool = False,
        scene: RegionScene | None = None,
    ) -> Render:
        """:func:`tiny_render` of the pinhole frame's ``region`` only; with a ``scene``, the part of
        it the scene offers is rendered there and the rest (up to four strips) in the world."""
        c = self.config
        if scene is not None:
            inner = scene.inner(region)
            if inner is not None:
                out = self._composite(view, region, inner, light, segmentation, scene)
                if out is not None:
                    return out
        if region == (0, 0, c.width, c.height):
            return tiny_render(self.client, c, view, self._proj, light, segmentation)
        proj = window_projection(self._proj, c.width, c.height, region)
        return tiny_render(self.client, c, view, proj, light, segmentation, size=(region[2], region[3]))

    def _composite(
        self,
        view: object,
        region: Window,
        inner: Window,
        light: tuple[Sequence[float], float, float] | None,
        segmentation: bool,
        scene: RegionScene,
    ) -> Render | None:
        """``region`` from ``inner`` rendered in ``scene`` and the strips around it in the world
        (every part is a window render, equal to the same pixels of the full frame), or None if the
        scene declined."""
        c = self.config
        x0, y0, w, h = region
        ix, iy, iw, ih = inner
        proj = window_projection(self._proj, c.width, c.height, inner)
        part = scene.render(c, view, proj, light, segmentation, (iw, ih))
        if part is None or inner == region:
            return part
        rgb = np.empty((h, w, 3), np.uint8)
        depth = np.empty((h, w), np.float32)
        mask = np.empty((h, w), np.int32) if segmentation else None
        strips = [
            (x0, y0, w, iy - y0),  # top
            (x0, iy + ih, w, y0 + h - iy - ih),  # bottom
            (x0, iy, ix - x0, ih),  # left
            (ix + iw, iy, x0 + w - ix - iw, ih),  # right
        ]
        for sub, out in [(inner, part)] + [
            (s, self._render_region(view, s, light, segmentation)) for s in strips if s[2] > 0 and s[3] > 0
        ]:
            r0, c0 = sub[1] - y0, sub[0] - x0
            rows, cols = slice(r0, r0 + sub[3]), slice(c0, c0 + sub[2])
            rgb[rows, cols] = out[0]
            depth[rows, cols] = out[1]
            if mask is not None and out[2] is not None:
                mask[rows, cols] = out[2]
        return rgb, depth, mask

    def _source_region(self, win: Window) -> Window:
        """The region of the pinhole render that ``win`` of the (distorted) image samples: ``win``
        itself without distortion; else the bounding box of the distortion maps over ``win``
        grown by the bilinear taps (1 px before, 2 after the floor), clipped to the image."""
        if self._maps is None:
            return win
        c = self.config
        x0, y0, w, h = win
        mx = self._maps[0][y0 : y0 + h, x0 : x0 + w]
        my = self._maps[1][y0 : y0 + h, x0 : x0 + w]
        ax0 = min(max(math.floor(float(mx.min())) - 1, 0), c.width - 1)
        ax1 = min(max(math.floor(float(mx.max())) + 2, 0), c.width - 1)
        ay0 = min(max(math.floor(float(my.min())) - 1, 0), c.height - 1)
        ay1 = min(max(math.floor(float(my.max())) + 2, 0), c.height - 1)
        return (ax0, ay0, ax1 - ax0 + 1, ay1 - ay0 + 1)

    def _distort_region(self, img: NDArray[np.uint8], src: Window, win: Window) -> NDArray[np.uint8]:
        """The (distorted) window ``win`` from ``img``, the pinhole render of region ``src``."""
        if self._maps is None:
            return img
        x0, y0, w, h = win
        # an integer shift of the float32 maps is exact, so the remap samples the same points
        mx = self._maps[0][y0 : y0 + h, x0 : x0 + w] - np.float32(src[0])
        my = self._maps[1][y0 : y0 + h, x0 : x0 + w] - np.float32(src[1])
        out = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return np.asarray(out, dtype=np.uint8)

    def _realistic_window(
        self, state: BodyState, win: Window, rng: np.random.Generator, scene: RegionScene | None
    ) -> NDArray[np.uint8]:
        """:meth:`read_window` for the realistic quality (mirrors :meth:`render_realistic` and
        ``RealisticImager.process`` on a region)."""
        imager = self.imager
        assert imager is not None
        if imager.episode is None:
            imager.reset(rng)
        ep = imager.episode
        assert ep is not None
        c = self.config
        R_wb = np.asarray(state.rotation, dtype=np.float64)
        eye, R_wc = self.pose(np.asarray(state.position, dtype=np.float64), R_wb)
        view = self._view(eye, R_wc)
        light = (tuple(ep.light_direction), ep.ambient, ep.diffuse)
        src = self._source_region(win)
        omega = np.asarray(state.angular_velocity, dtype=np.float64)
        v_eye = np.asarray(state.velocity, dtype=np.float64) + np.cross(omega, R_wb @ self._cam_offset)
        # the blur length needs the depth at the principal point, the region needs the blur length:
        # render with last frame's margin, re-render in the rare frame that needs more
        margin = self._blur_margin
        ext = grow_window(src, margin, c.width, c.height)
        rgb, depth, seg = self._render_region(view, ext, light, True, scene)
        col, row = self._principal_pixel
        if ext[0] <= col < ext[0] + ext[2] and ext[1] <= row < ext[1] + ext[3]:
            d = float(depth[row - ext[1], col - ext[0]])
        else:
            d = float(self._render_region(view, (col, row, 1, 1), light)[1][0, 0])
        z_axis = self._axis_distance(d, eye, R_wc)
        du, dv = image_motion_px(imager.K, R_wc, v_eye, omega, z_axis, ep.exposure_s)
        threshold = imager.params.blur_threshold_px
        need = blur_kernel(du, dv).shape[0] // 2 if math.hypot(du, dv) > threshold else 0
        if need > margin:
            ext = grow_window(src, need, c.width, c.height)
            rgb, _, seg = self._render_region(view, ext, light, True, scene)
        self._blur_margin = max(need + 1, _BLUR_MARGIN_MIN)
        assert seg is not None
        img = np.ascontiguousarray(rgb)
        mask = (seg == -1).view(np.uint8)
        if mask.any():
            cv2.copyTo(_background_region(imager, eye, R_wc, float(state.time), ext), mask, img)
        img = motion_blur(img, du, dv, threshold)
        sx, sy = src[0] - ext[0], src[1] - ext[1]
        img = np.ascontiguousarray(img[sy : sy + src[3], sx : sx + src[2]])
        img = self._distort_region(img, src, win)
        x0, y0, w, h = win
        vignetting = imager._vignetting_u8[y0 : y0 + h, x0 : x0 + w]
        signal = np.asarray(cv2.multiply(img, vignetting, scale=ep.brightness / 255.0), np.uint8)
        oy, ox, sign = _noise_draw(imager, rng)
        return add_sensor_noise(signal, imager._sigma_lut, imager._bank, (oy + y0, ox + x0), sign)


#: Smallest blur margin (px) a realistic window is rendered with (a blurred frame's kernel radius is
#: at least 2 px; one more absorbs the frame-to-frame jitter of the blur length).
_BLUR_MARGIN_MIN = 3


def check_window(window: object, width: int, height: int) -> Window:
    """``window`` as a :data:`Window` of ints, checked to lie inside a ``width`` x ``height`` image
    (TypeError or ValueError naming ``window``)."""
    if not isinstance(window, tuple | list | np.ndarray) or len(window) != 4:
        raise TypeError(f"window must be 4 integers (x0, y0, width, height), got {window!r}")
    if not all(isinstance(v, int | np.integer) and not isinstance(v, bool) for v in window):
        raise TypeError(f"window must be 4 integers (x0, y0, width, height), got {window!r}")
    x0, y0, w, h = (int(v) for v in window)
    if w < 1 or h < 1 or x0 < 0 or y0 < 0 or x0 + w > width or y0 + h > height:
        raise ValueError(
            f"window (x0, y0, width, height) must be non-empty and inside the {width}x{height} image, "
            f"got {tuple(window)!r}"
        )
    return (x0, y0, w, h)


def grow_window(window: Window, margin: int, width: int, height: int) -> Window:
    """``window`` grown by ``margin`` px on every side, clipped to a ``width`` x ``height`` image."""
    x0, y0, w, h = window
    ax0, ay0 = max(x0 - margin, 0), max(y0 - margin, 0)
    ax1, ay1 = min(x0 + w + margin, width), min(y0 + h + margin, height)
    return (ax0, ay0, ax1 - ax0, ay1 - ay0)


def window_projection(proj: Sequence[float], width: int, height: int, window: Window) -> tuple[float, ...]:
    """Off-axis (asymmetric frustum) projection matrix that renders only ``window`` = (x0, y0, w, h)
    of a ``width`` x ``height`` frame rendered with ``proj`` (PyBullet's 16 floats, a column-major
    OpenGL matrix); returned in the same form, for a ``w`` x ``h`` render.

    TinyRenderer maps normalised device coordinates to screen points with the viewport
    (0, 0, w, h) and samples pixel (column i, row j) at screen point (i, h - 1 - j) (rows
    bottom-up: hence the principal point (W/2, H/2 - 1), see :attr:`CameraConfig.intrinsics`).
    The window's screen points are the full frame's shifted by (x0, H - h - y0), so the matrix is
    ``A @ proj`` with ``A`` the affine map x' = (W x + W - 2 x0 - w) / w,
    y' = (H y + H - 2 b - h) / h, b = H - h - y0 (applied in clip coordinates).

    Equal to the crop of the full render up to TinyRenderer's float32 arithmetic, which computes
    every pixel's barycentric coordinates from the (differently rounded) screen coordinates of
    the window: rarely a texture lookup lands on the other side of a texel edge (a black/white
    flip inside the tag), and a flip at a corner of the tag's black square moves that detected
    corner (figures in ``docs/camera-models.md``; see
    :class:`~ihrcf_env.sim.sensors.tag_window.WindowedTagCamera`).
    """
    x0, y0, w, h = window
    b = height - h - y0
    A = np.eye(4)
    A[0, 0], A[0, 3] = width / w, (width - 2.0 * x0 - w) / w
    A[1, 1], A[1, 3] = height / h, (height - 2.0 * b - h) / h
    P = np.asarray(proj, dtype=np.float64).reshape(4, 4).T  # row-major maths from column-major storage
    return tuple((A @ P).T.ravel().tolist())


def _noise_draw(imager: RealisticImager, rng: np.random.Generator) -> tuple[int, int, int]:
    """The per-frame draws of ``RealisticImager.process``: noise-bank offset (row, col) and sign,
    in its order."""
    m = imager.params.noise_margin_px
    oy, ox = (int(x) for x in rng.integers(0, m + 1, 2))
    sign = 1 if rng.random() < 0.5 else -1
    return oy, ox, sign


def _background_region(
    imager: RealisticImager, eye: NDArray[np.float64], R_wc: NDArray[np.float64], time: float, region: Window
) -> NDArray[np.uint8]:
    """``imager.background(eye, R_wc, time)`` on ``region`` only, pixel for pixel: the half-resolution
    warp is the same (a warp of part of it is not bit-exact), the upsampling and the sky mask are
    computed on the region alone."""
    ep = imager.episode
    assert ep is not None
    origin = (ep.texture_origin[0] + ep.drift[0] * time, ep.texture_origin[1] + ep.drift[1] * time)
    H = imager._to_half @ ground_homography(imager.K, eye, R_wc, imager.texel_m, origin, ep.texture_angle)
    half = cv2.warpPerspective(
        imager._texture_lit, H, imager._half, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP
    )
    bg = _upsample_region(np.asarray(half, np.uint8), imager.width, imager.height, region)
    sky = _sky_mask_region(imager.K, R_wc, imager.width, imager.height, region)
    if sky is not None:
        bg[sky] = imager._sky
    return bg


def _upsample_region(half: NDArray[np.uint8], width: int, height: int, region: Window) -> NDArray[np.uint8]:
    """``cv2.resize(half, (width, height), INTER_LINEAR)[region]`` without resizing the rest.

    On an axis where the full size is exactly twice the half size, OpenCV's source coordinate
    (x + 1/2) / 2 - 1/2 is exact and shift-invariant by whole half pixels, so resizing the half
    pixels around the region (one spare on each side) and cropping gives the same bytes. Any
    other ratio: the whole axis is resized (correct, not faster)."""
    x0, y0, w, h = region
    hh, hw = half.shape[:2]

    def span(a0: int, n: int, full: int, hn: int) -> tuple[int, int]:
        if 2 * hn != full:
            return 0, hn
        return max(a0 // 2 - 1, 0), min((a0 + n - 1) // 2 + 2, hn)

    kx0, kx1 = span(x0, w, width, hw)
    ky0, ky1 = span(y0, h, height, hh)
    part = np.ascontiguousarray(half[ky0:ky1, kx0:kx1])
    up = cv2.resize(part, None, fx=width / hw, fy=height / hh, interpolation=cv2.INTER_LINEAR)
    ox = x0 - (2 * kx0 if 2 * hw == width else 0)
    oy = y0 - (2 * ky0 if 2 * hh == height else 0)
    return np.ascontiguousarray(up[oy : oy + h, ox : ox + w])


def _sky_mask_region(
    K: NDArray[np.float64], R_wc: NDArray[np.float64], width: int, height: int, region: Window
) -> NDArray[np.bool_] | None:
    """``imaging.sky_mask(K, R_wc, width, height)[region]`` (None when the whole image looks down),
    with the same element-wise arithmetic."""
    a, b, c = R_wc[2, :] @ np.linalg.inv(K)
    corners = [a * u + b * v + c for u in (0.0, width - 1.0) for v in (0.0, height - 1.0)]
    if max(corners) < -0.02:
        return None
    x0, y0, w, h = region
    u = np.arange(width, dtype=np.float64)[None, x0 : x0 + w]
    v = np.arange(height, dtype=np.float64)[y0 : y0 + h, None]
    mask: NDArray[np.bool_] = (a * u + b * v + c) >= -0.02
    return mask


def _distortion_maps(config: CameraConfig) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """For every pixel of the distorted image, where to sample the ideal (pinhole) render.

    A distorted pixel with normalised coordinates x_d shows the ray whose ideal normalised
    coordinates x satisfy ``x_d = x (1 + k1 r^2 + k2 r^4)``, r = |x| (solved by fixed-point
    iteration). Pixels whose ray falls outside the render repeat its border (negligible for mild
    distortion).
    """
    K = config.intrinsics
    k1, k2 = config.distortion
    u, v = np.meshgrid(np.arange(config.width, dtype=np.float64), np.arange(config.height, dtype=np.float64))
    xd, yd = (u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1]
    x, y = xd.copy(), yd.copy()
    for _ in range(30):
        r2 = x * x + y * y
        s = 1.0 + k1 * r2 + k2 * r2 * r2
        x, y = xd / s, yd / s
    mx = (x * K[0, 0] + K[0, 2]).astype(np.float32)
    my = (y * K[1, 1] + K[1, 2]).astype(np.float32)
    return mx, my


def tiny_render(
    client: int,
    config: CameraConfig,
    view: object,
    proj: object,
    light: tuple[Sequence[float], float, float] | None = None,
    segmentation: bool = False,
    size: tuple[int, int] | None = None,
) -> Render:
    """One TinyRenderer frame: RGB (H, W, 3) uint8, the z-buffer (H, W) and, with ``segmentation``,
    the segmentation mask (H, W) int32 (-1 = background). ``light`` = (direction, ambient, diffuse)
    overrides the config's light (the realistic camera's per-episode light). ``size`` = (W, H)
    overrides the config's image size (a window rendered with :func:`window_projection`)."""
    c = config
    direction, ambient, diffuse = light if light is not None else (c.light_direction, c.ambient, c.diffuse)
    width, height = size if size is not None else (c.width, c.height)
    _, _, rgba, depth, seg = p.getCameraImage(
        width,
        height,
        viewMatrix=view,
        projectionMatrix=proj,
        shadow=0,
        lightDirection=list(direction),
        lightAmbientCoeff=ambient,
        lightDiffuseCoeff=diffuse,
        lightSpecularCoeff=c.specular,
        renderer=p.ER_TINY_RENDERER,
        flags=0 if segmentation else p.ER_NO_SEGMENTATION_MASK,
        physicsClientId=client,
    )
    img = np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)
    z = np.asarray(depth, dtype=np.float32).reshape(height, width)
    mask = np.asarray(seg, dtype=np.int32).reshape(height, width) if segmentation else None
    return np.ascontiguousarray(img[:, :, :3]), z, mask


def render_rgb(client: int, config: CameraConfig, view: object, proj: object) -> NDArray[np.uint8]:
    """One TinyRenderer frame as an (H, W, 3) uint8 array, with the config's light."""
    return tiny_render(client, config, view, proj)[0]


__all__ = [
    "DownCamera",
    "RegionScene",
    "Render",
    "Window",
    "check_window",
    "grow_window",
    "render_rgb",
    "tiny_render",
    "window_projection",
]
