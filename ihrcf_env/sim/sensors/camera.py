"""The drone's downward camera, rendered by PyBullet's TinyRenderer."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig, intrinsics_from_fov
from ihrcf_env.sim.sensors.base import BodyState


@dataclass(frozen=True)
class CameraConfig:
    """Downward camera. ``fov`` is the vertical field of view (rad); square pixels.

    ``light_direction`` (world, pointing from the scene to the light) and the ambient/diffuse
    coefficients set TinyRenderer's single light. ``distortion = (k1, k2)`` applies Brown-Conrady
    radial lens distortion to the rendered image (0, 0: an ideal pinhole camera).
    """

    width: int = 512
    height: int = 512
    fov: float = math.radians(60.0)
    near: float = 0.01
    far: float = 10.0
    light_direction: tuple[float, float, float] = (0.3, 0.2, 1.0)
    ambient: float = 0.6
    diffuse: float = 0.35
    specular: float = 0.0
    distortion: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        if not (isinstance(self.width, int | np.integer) and self.width > 0):
            raise ValueError(f"camera width must be a positive integer, got {self.width!r}")
        if not (isinstance(self.height, int | np.integer) and self.height > 0):
            raise ValueError(f"camera height must be a positive integer, got {self.height!r}")
        if not (math.isfinite(self.fov) and 0.0 < self.fov < math.radians(170.0)):
            raise ValueError(f"camera fov must be in (0, 170 deg) in radians, got {self.fov!r}")
        if not (0.0 < self.near < self.far):
            raise ValueError(f"camera near/far must satisfy 0 < near < far, got {self.near}, {self.far}")
        k = np.asarray(self.distortion, dtype=np.float64)
        if k.shape != (2,) or not np.all(np.isfinite(k)) or np.any(np.abs(k) > 1.0):
            raise ValueError(
                f"camera distortion must be two finite numbers (k1, k2) in [-1, 1], got {self.distortion!r}"
            )

    @property
    def distortion_coefficients(self) -> NDArray[np.float64]:
        """True OpenCV distortion vector (k1, k2, p1, p2, k3) of the image."""
        return np.array([self.distortion[0], self.distortion[1], 0.0, 0.0, 0.0])

    @property
    def intrinsics(self) -> NDArray[np.float64]:
        """True pinhole K of the rendered image (OpenCV convention). Estimators must not read this:
        ATDA uses the chessboard calibration, IHRCF the range-to-pixel table.

        TinyRenderer samples pixel (column i, row j) at screen point (i, H - 1 - j) of its
        viewport, so in OpenCV's pixel-centre convention the principal point is (W/2, H/2 - 1),
        not the image centre ((W - 1)/2, (H - 1)/2); checked against rendered tag corners.
        """
        K = intrinsics_from_fov(self.width, self.height, self.fov)
        K[0, 2] = self.width / 2.0
        K[1, 2] = self.height / 2.0 - 1.0
        return K


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

    def pose(
        self, pos: NDArray[np.float64], R_wb: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World pose (optical centre, R_world_cam) of the camera for a body pose."""
        return pos + R_wb @ self._cam_offset, R_wb @ R_BODY_CAM

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def read(self, state: BodyState, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        """``image``: (H, W, 3) uint8. The world places the deck's visuals before reading."""
        return {"image": self.render(state.position, state.rotation)}

    def render(self, pos: NDArray[np.float64], R_wb: NDArray[np.float64]) -> NDArray[np.uint8]:
        """RGB image (H, W, 3) uint8 for the body pose (world position ``pos``, rotation ``R_wb``)."""
        eye, R_wc = self.pose(pos, R_wb)
        view = p.computeViewMatrix(
            cameraEyePosition=eye.tolist(),
            cameraTargetPosition=(eye + R_wc[:, 2]).tolist(),
            cameraUpVector=(-R_wc[:, 1]).tolist(),
            physicsClientId=self.client,
        )
        img = render_rgb(self.client, self.config, view, self._proj)
        if self._maps is None:
            return img
        out = cv2.remap(img, self._maps[0], self._maps[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return np.asarray(out, dtype=np.uint8)


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


def render_rgb(client: int, config: CameraConfig, view: object, proj: object) -> NDArray[np.uint8]:
    """One TinyRenderer frame as an (H, W, 3) uint8 array."""
    c = config
    _, _, rgba, _, _ = p.getCameraImage(
        c.width,
        c.height,
        viewMatrix=view,
        projectionMatrix=proj,
        shadow=0,
        lightDirection=list(c.light_direction),
        lightAmbientCoeff=c.ambient,
        lightDiffuseCoeff=c.diffuse,
        lightSpecularCoeff=c.specular,
        renderer=p.ER_TINY_RENDERER,
        flags=p.ER_NO_SEGMENTATION_MASK,
        physicsClientId=client,
    )
    img = np.asarray(rgba, dtype=np.uint8).reshape(c.height, c.width, 4)
    return np.ascontiguousarray(img[:, :, :3])
