"""Image-formation effects of a real camera, applied to a TinyRenderer frame (numpy/OpenCV only).

The realistic camera (:class:`~ihrcf_env.config.sensors.CameraConfig` ``quality="realistic"``)
turns the renderer's clean RGB frame into what a small global-shutter drone camera delivers:

1. **background** -- the ground/sea is the plane z = 0, so its image is exactly a homography of a
   texture (:func:`ground_homography`); a procedural, periodic texture (:func:`make_texture`) is
   warped with ``cv2.warpPerspective`` and composited where the segmentation mask says background;
2. **motion blur** -- the image displacement of the scene during the exposure, from the drone's
   velocity and angular velocity (:func:`image_motion_px`), as a line kernel (:func:`blur_kernel`);
3. **vignetting** (:func:`vignetting_gain`) and the episode's **exposure** error;
4. **sensor noise** -- read noise and signal-dependent shot noise, variance ``read^2 + S/g`` in DN
   (``g`` electrons per DN), added from a bank of unit normals drawn at reset
   (:func:`add_sensor_noise`), then 8-bit quantisation.

The per-episode state (light, exposure and gain, texture placement, noise bank) is drawn by
:meth:`RealisticImager.reset` from the env's generator; per frame only a random offset and sign
into the noise bank are drawn. Same generator state, same images, bit for bit.

Default parameters (:class:`ImagingParams`) are those of the **Sony IMX296** 1/2.9-inch, 1.58 MP,
3.45 um global-shutter sensor of the Raspberry Pi Global Shutter Camera, see the class docstring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ihrcf_env.config.sensors import BACKGROUNDS, ImagingParams

#: The noise bank stores unit normals as int8 in steps of 1 / NOISE_BANK_SCALE (clipped at +-3.97).
NOISE_BANK_SCALE = 32.0


# -- background ------------------------------------------------------------------------------------


def make_texture(kind: str, size: int, seed: int) -> NDArray[np.uint8]:
    """A periodic (tileable) RGB texture (size, size, 3) uint8, by spectral synthesis.

    ``"sea"``: a directional wind-wave spectrum peaked at 9 cycles per period (about 0.33 m waves
    on a 3 m tile), isotropic ripples at ~60 cycles per period (~5 cm) and a weak broadband swell,
    coloured from deep blue-green to light crests, with foam on the highest crests. ``"ground"``: a
    1/f^2.2 fractal field coloured from dark grass to
    dry soil. Deterministic in ``seed``.
    """
    if kind not in BACKGROUNDS:
        raise ValueError(f"texture kind must be one of {BACKGROUNDS}, got {kind!r}")
    rng = np.random.default_rng(seed)
    k = np.fft.fftfreq(size) * size  # integer cycles per period: the field is exactly periodic
    kx, ky = np.meshgrid(k, k)
    kk = np.hypot(kx, ky)
    kk[0, 0] = 1.0
    if kind == "sea":
        k0 = 9.0
        wind = rng.uniform(0.0, math.pi)
        spread = np.cos(np.arctan2(ky, kx) - wind) ** 4
        ripples = 0.015 * np.exp(-(((kk - 60.0) / 25.0) ** 2))  # ~5 cm capillary ripples, any direction
        power = np.exp(-(((kk - k0) / (0.35 * k0)) ** 2)) * spread + ripples + 0.02 * kk**-2.0
    else:
        power = kk**-2.2
    power[0, 0] = 0.0
    spectrum = np.sqrt(power) * (rng.standard_normal((size, size)) + 1j * rng.standard_normal((size, size)))
    h = np.real(np.fft.ifft2(spectrum))
    h = (h - h.mean()) / max(float(h.std()), 1e-12)
    if kind == "sea":
        t = (1.0 / (1.0 + np.exp(-1.2 * h)))[..., None]
        deep, light = np.array([24.0, 66.0, 92.0]), np.array([88.0, 136.0, 158.0])
        rgb = deep + (light - deep) * t
        foam = np.clip((h - 2.0) / 0.8, 0.0, 1.0)[..., None]
        rgb = rgb + (np.array([205.0, 214.0, 220.0]) - rgb) * foam
    else:
        t = np.clip(0.5 + 0.22 * h, 0.0, 1.0)[..., None]
        dark, dry = np.array([58.0, 74.0, 40.0]), np.array([140.0, 128.0, 92.0])
        rgb = dark + (dry - dark) * t
    return np.ascontiguousarray(np.clip(np.rint(rgb), 0, 255).astype(np.uint8))


def ground_homography(
    K: NDArray[np.float64],
    eye: NDArray[np.float64],
    R_wc: NDArray[np.float64],
    texel_m: float,
    origin_xy: tuple[float, float],
    angle: float,
) -> NDArray[np.float64]:
    """Homography from texture pixels to image pixels for a texture lying on the plane z = 0.

    Texture pixel (u, v) (OpenCV pixel centres) is the world point ``origin + Rz(angle) @
    ((u + 0.5) texel_m, (v + 0.5) texel_m)``; the camera (OpenCV frame) is at ``eye`` with rotation
    ``R_wc`` (columns: camera axes in the world) and intrinsics ``K``.
    """
    c, s = math.cos(angle), math.sin(angle)
    A = np.array(
        [
            [texel_m * c, -texel_m * s, origin_xy[0] + 0.5 * texel_m * (c - s)],
            [texel_m * s, texel_m * c, origin_xy[1] + 0.5 * texel_m * (s + c)],
            [0.0, 0.0, 1.0],
        ]
    )
    R_cw = R_wc.T
    M = np.column_stack([R_cw[:, 0], R_cw[:, 1], -R_cw @ eye])  # (X, Y, 1) on z = 0 -> camera frame
    H: NDArray[np.float64] = K @ M @ A
    return H


def sky_mask(
    K: NDArray[np.float64], R_wc: NDArray[np.float64], width: int, height: int
) -> NDArray[np.bool_] | None:
    """Pixels whose ray does not reach the ground plane (at or above the horizon), or None if the
    whole image looks down. The ray's world z is linear in (u, v), so the corners decide."""
    a, b, c = R_wc[2, :] @ np.linalg.inv(K)
    corners = [a * u + b * v + c for u in (0.0, width - 1.0) for v in (0.0, height - 1.0)]
    if max(corners) < -0.02:
        return None
    u = np.arange(width, dtype=np.float64)[None, :]
    v = np.arange(height, dtype=np.float64)[:, None]
    mask: NDArray[np.bool_] = (a * u + b * v + c) >= -0.02
    return mask


# -- optics and motion ------------------------------------------------------------------------------


def vignetting_gain(K: NDArray[np.float64], width: int, height: int, exponent: float) -> NDArray[np.float32]:
    """Relative illumination (H, W) float32: ``cos(theta)^exponent`` of each pixel's field angle."""
    u = (np.arange(width, dtype=np.float64) - K[0, 2]) / K[0, 0]
    v = (np.arange(height, dtype=np.float64) - K[1, 2]) / K[1, 1]
    r2 = u[None, :] ** 2 + v[:, None] ** 2
    return ((1.0 + r2) ** (-exponent / 2.0)).astype(np.float32)  # cos(theta) = 1 / sqrt(1 + r^2)


def image_motion_px(
    K: NDArray[np.float64],
    R_wc: NDArray[np.float64],
    velocity: NDArray[np.float64],
    angular_velocity: NDArray[np.float64],
    depth: float,
    exposure_s: float,
) -> tuple[float, float]:
    """Displacement (du, dv) in px of the scene at the image centre during one exposure.

    ``velocity``: world velocity of the optical centre (m/s); ``angular_velocity``: world (rad/s);
    ``depth``: distance of the scene along the optical axis (m). A static point on the axis moves
    in the camera frame as ``-v_c - w_c x P``, so its normalised image coordinates change at
    ``(-v_x / Z - w_y, -v_y / Z + w_x)``. Rotation about the optical axis (no displacement at the
    centre) and motion along it (radial zoom) are left out.
    """
    v_c = R_wc.T @ np.asarray(velocity, dtype=np.float64)
    w_c = R_wc.T @ np.asarray(angular_velocity, dtype=np.float64)
    z = max(float(depth), 1e-3)
    du = K[0, 0] * (-v_c[0] / z - w_c[1]) * exposure_s
    dv = K[1, 1] * (-v_c[1] / z + w_c[0]) * exposure_s
    return float(du), float(dv)


def blur_kernel(du: float, dv: float) -> NDArray[np.float32]:
    """Normalised line kernel for a displacement (du, dv) px centred on the kernel (box profile
    along the segment, bilinearly anti-aliased)."""
    length = math.hypot(du, dv)
    half = int(math.ceil(length / 2.0)) + 1
    size = 2 * half + 1
    n = max(2, int(math.ceil(4.0 * length)) + 1)
    t = np.linspace(-0.5, 0.5, n)
    x, y = half + t * du, half + t * dv
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    k = np.zeros((size, size), np.float64)
    np.add.at(k, (y0, x0), (1 - fx) * (1 - fy))
    np.add.at(k, (y0, x0 + 1), fx * (1 - fy))
    np.add.at(k, (y0 + 1, x0), (1 - fx) * fy)
    np.add.at(k, (y0 + 1, x0 + 1), fx * fy)
    return (k / k.sum()).astype(np.float32)


def motion_blur(image: NDArray[np.uint8], du: float, dv: float, threshold_px: float) -> NDArray[np.uint8]:
    """``image`` blurred along (du, dv) px (unchanged if the displacement is <= ``threshold_px``)."""
    if math.hypot(du, dv) <= threshold_px:
        return image
    out = cv2.filter2D(image, -1, blur_kernel(du, dv), borderType=cv2.BORDER_REPLICATE)
    return np.asarray(out, dtype=np.uint8)


# -- sensor noise -----------------------------------------------------------------------------------


def noise_sigma_lut(
    electrons_per_dn: float, read_noise_e: float, bank_scale: float = 1.0
) -> NDArray[np.float32]:
    """(1, 256) float32: temporal noise s.d. (DN) at each signal level S (DN),
    ``sqrt((read / g)^2 + S / g)``, divided by ``bank_scale`` (the scale of an integer noise bank);
    0 at 255 (a saturated pixel reads full scale)."""
    g = float(electrons_per_dn)
    s = np.arange(256, dtype=np.float64)
    sigma = np.sqrt((read_noise_e / g) ** 2 + s / g) / bank_scale
    sigma[255] = 0.0
    return sigma.astype(np.float32).reshape(1, 256)


def draw_noise_bank(rng: np.random.Generator, height: int, width: int) -> NDArray[np.int8]:
    """(height, width, 3) int8: independent unit normals times :data:`NOISE_BANK_SCALE`, rounded
    and clipped to int8 (s.d. 1.00004 after division; clipping beyond 3.97 s.d. affects 7e-5 of
    the draws). A quarter of a float32 bank's memory, and faster to read."""
    z = rng.standard_normal((height, width, 3), dtype=np.float32)
    z *= NOISE_BANK_SCALE
    np.rint(z, out=z)
    np.clip(z, -127, 127, out=z)
    return z.astype(np.int8)


def add_sensor_noise(
    signal: NDArray[np.uint8],
    sigma_lut: NDArray[np.float32],
    bank: NDArray[np.float32] | NDArray[np.int8],
    offset: tuple[int, int],
    sign: int,
) -> NDArray[np.uint8]:
    """``signal + sigma(signal) * n``, rounded and saturated to uint8.

    ``n`` is the window of the normal ``bank`` (H + m, W + m, C) at ``offset`` (row, col), times
    ``sign`` (+1 or -1): independent normals per pixel and channel (``sigma_lut`` includes the
    bank's scale, see :func:`noise_sigma_lut`): a look-up, a multiply and an add per pixel, much
    cheaper than drawing fresh normals. Successive frames use independent offsets, so a
    pixel's noise is independent from frame to frame unless an offset and sign repeat (1 in
    2 (m + 1)^2).
    """
    h, w = signal.shape[:2]
    oy, ox = offset
    sigma = cv2.LUT(signal, sigma_lut)
    noise = cv2.multiply(sigma, bank[oy : oy + h, ox : ox + w], dtype=cv2.CV_32F)
    op = cv2.add if sign > 0 else cv2.subtract
    return np.asarray(op(signal, noise, dtype=cv2.CV_8U), dtype=np.uint8)


# -- the per-episode state and the pipeline -------------------------------------------------------


@dataclass(frozen=True)
class EpisodeImaging:
    """What :meth:`RealisticImager.reset` drew for one episode."""

    light_direction: tuple[float, float, float]  # world, towards the light (unit)
    ambient: float
    diffuse: float
    exposure_s: float
    gain: float  # analog gain (1 = 0 dB)
    brightness: float  # mean-level factor left by the auto-exposure (1 = on target)
    texture_origin: tuple[float, float]  # m, world
    texture_angle: float  # rad
    drift: tuple[float, float]  # m/s, world

    @property
    def gain_db(self) -> float:
        return 20.0 * math.log10(self.gain)


def draw_episode(params: ImagingParams, rng: np.random.Generator) -> EpisodeImaging:
    """Draw one episode's light, exposure/gain and texture placement (see :class:`ImagingParams`)."""
    az = rng.uniform(0.0, 2.0 * math.pi)
    el = math.radians(rng.uniform(*params.light_elevation_deg))
    light = (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el))
    ambient = float(rng.uniform(*params.ambient))
    diffuse = float(rng.uniform(*params.diffuse))
    lo, hi = params.scene_exposure_s
    needed = math.exp(rng.uniform(math.log(lo), math.log(hi)))  # exposure the scene needs at 0 dB
    exposure = min(needed, params.max_exposure_s)
    gain = min(needed / exposure, params.max_gain)
    brightness = exposure * gain / needed * math.exp(params.ae_error * rng.standard_normal())
    origin = (float(rng.uniform(0.0, params.texture_tile_m)), float(rng.uniform(0.0, params.texture_tile_m)))
    angle = float(rng.uniform(0.0, 2.0 * math.pi))
    speed, heading = rng.uniform(0.0, params.drift_speed), rng.uniform(0.0, 2.0 * math.pi)
    return EpisodeImaging(
        light_direction=light,
        ambient=ambient,
        diffuse=diffuse,
        exposure_s=float(exposure),
        gain=float(gain),
        brightness=float(brightness),
        texture_origin=origin,
        texture_angle=angle,
        drift=(float(speed * math.cos(heading)), float(speed * math.sin(heading))),
    )


class RealisticImager:
    """The realistic image pipeline of one camera (see the module docstring).

    Built once per camera: the texture (from ``params.texture_seed``) and the vignetting map.
    :meth:`reset` draws an episode (:class:`EpisodeImaging`) and the noise bank; :meth:`process`
    turns a pinhole render into the camera's image. ``distortion_maps`` (for ``cv2.remap``) apply
    the lens distortion after the background and blur, before vignetting and noise.
    """

    def __init__(
        self,
        params: ImagingParams,
        K: NDArray[np.float64],
        width: int,
        height: int,
        distortion_maps: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
    ) -> None:
        self.params = params
        self.K = np.asarray(K, dtype=np.float64)
        self.width, self.height = int(width), int(height)
        self.maps = distortion_maps
        self.texture = make_texture(params.background, params.texture_px, params.texture_seed)
        self.texel_m = params.texture_tile_m / params.texture_px
        self.vignetting = vignetting_gain(self.K, self.width, self.height, params.vignetting_exponent)
        # the background is warped at half resolution (the texture is magnified ~3x at 1-2 m) and
        # upsampled: pixel centre x of the half image is 2x + 0.5 of the full one
        self._half = (max(1, self.width // 2), max(1, self.height // 2))
        sx, sy = self._half[0] / self.width, self._half[1] / self.height
        self._to_half = np.array([[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, 0.5 * sy - 0.5], [0.0, 0.0, 1.0]])
        self.episode: EpisodeImaging | None = None
        self._texture_lit: NDArray[np.uint8] = self.texture
        self._sky = np.zeros(3, np.uint8)
        vig = np.rint(self.vignetting * 255.0).astype(np.uint8)
        self._vignetting_u8 = np.ascontiguousarray(np.repeat(vig[..., None], 3, axis=2))
        self._sigma_lut: NDArray[np.float32] = np.empty(0, np.float32)
        self._bank: NDArray[np.int8] = np.empty(0, np.int8)

    def reset(self, rng: np.random.Generator, episode: EpisodeImaging | None = None) -> EpisodeImaging:
        """Draw the episode's imaging state (unless ``episode`` fixes it) and noise bank from ``rng``."""
        p = self.params
        ep = draw_episode(p, rng) if episode is None else episode
        m = p.noise_margin_px
        self._bank = draw_noise_bank(rng, self.height + m, self.width + m)
        # the plane z = 0 under the same light as the renderer's: ambient + diffuse * cos(incidence)
        shade = min(1.0, ep.ambient + ep.diffuse * max(0.0, ep.light_direction[2]))
        self._texture_lit = np.asarray(cv2.convertScaleAbs(self.texture, alpha=shade), dtype=np.uint8)
        self._sky = np.clip(
            np.rint(np.array([200.0, 214.0, 228.0]) * min(1.0, ep.ambient + ep.diffuse)), 0, 255
        ).astype(np.uint8)
        self._sigma_lut = noise_sigma_lut(p.electrons_per_dn(ep.gain), p.read_noise_e, NOISE_BANK_SCALE)
        self.episode = ep
        return ep

    def background(
        self, eye: NDArray[np.float64], R_wc: NDArray[np.float64], time: float
    ) -> NDArray[np.uint8]:
        """The ground/sea plane as the camera sees it (H, W, 3) uint8 (sky above the horizon)."""
        ep = self.episode
        assert ep is not None
        origin = (ep.texture_origin[0] + ep.drift[0] * time, ep.texture_origin[1] + ep.drift[1] * time)
        H = self._to_half @ ground_homography(self.K, eye, R_wc, self.texel_m, origin, ep.texture_angle)
        half = cv2.warpPerspective(
            self._texture_lit, H, self._half, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP
        )
        bg = np.asarray(cv2.resize(half, (self.width, self.height), interpolation=cv2.INTER_LINEAR), np.uint8)
        sky = sky_mask(self.K, R_wc, self.width, self.height)
        if sky is not None:
            bg[sky] = self._sky
        return bg

    def process(
        self,
        rgb: NDArray[np.uint8],
        seg: NDArray[np.int32],
        eye: NDArray[np.float64],
        R_wc: NDArray[np.float64],
        velocity: NDArray[np.float64],
        angular_velocity: NDArray[np.float64],
        depth: float,
        time: float,
        rng: np.random.Generator,
    ) -> NDArray[np.uint8]:
        """The camera image (H, W, 3) uint8 of a pinhole render ``rgb`` with segmentation ``seg``
        (-1: background), for the optical centre at ``eye`` moving at ``velocity`` (world, m/s),
        ``R_wc``, the body's ``angular_velocity`` (world, rad/s), the scene ``depth`` (m) on the
        optical axis and the simulated ``time`` (s). Draws the noise offset and sign from ``rng``."""
        if self.episode is None:
            self.reset(rng)
        ep = self.episode
        assert ep is not None
        img = np.ascontiguousarray(rgb)
        mask = (seg == -1).view(np.uint8)
        cv2.copyTo(self.background(eye, R_wc, time), mask, img)
        du, dv = image_motion_px(self.K, R_wc, velocity, angular_velocity, depth, ep.exposure_s)
        img = motion_blur(img, du, dv, self.params.blur_threshold_px)
        if self.maps is not None:
            img = np.asarray(
                cv2.remap(img, self.maps[0], self.maps[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE),
                np.uint8,
            )
        # vignetting (8-bit map) and the exposure error in one rounded, saturated multiply
        signal = np.asarray(cv2.multiply(img, self._vignetting_u8, scale=ep.brightness / 255.0), np.uint8)
        m = self.params.noise_margin_px
        oy, ox = (int(x) for x in rng.integers(0, m + 1, 2))
        sign = 1 if rng.random() < 0.5 else -1
        return add_sensor_noise(signal, self._sigma_lut, self._bank, (oy, ox), sign)


__all__ = [
    "NOISE_BANK_SCALE",
    "EpisodeImaging",
    "RealisticImager",
    "add_sensor_noise",
    "blur_kernel",
    "draw_episode",
    "draw_noise_bank",
    "ground_homography",
    "image_motion_px",
    "make_texture",
    "motion_blur",
    "noise_sigma_lut",
    "sky_mask",
    "vignetting_gain",
]
