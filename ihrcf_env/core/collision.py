"""The drone's collision shape: the axis-aligned boxes of ``assets/quadrotor.urdf`` (body frame,
FLU, m), as the simulator loads them into PyBullet. Read once; pure (the standard library's XML
parser), shared by the closed-form sensors' rays and the JAX backend's touchdown test."""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.paths import asset_path

__all__ = ["drone_boxes"]


@functools.lru_cache(maxsize=1)
def drone_boxes() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(centres, half_extents)``, each (B, 3) (body frame, m), of the collision boxes of
    ``assets/quadrotor.urdf`` (read-only arrays). Other collision shapes, or rotated boxes, are
    refused (ValueError)."""
    root = ET.parse(asset_path("quadrotor.urdf")).getroot()
    centres, halves = [], []
    for col in root.iter("collision"):
        origin = col.find("origin")
        box = col.find("geometry/box")
        if box is None:
            raise ValueError("quadrotor.urdf: only box collision shapes are supported")
        if origin is not None and origin.get("rpy", "0 0 0").split() != ["0", "0", "0"]:
            raise ValueError("quadrotor.urdf: only unrotated collision boxes are supported")
        xyz = "0 0 0" if origin is None else origin.get("xyz", "0 0 0")
        centres.append([float(v) for v in xyz.split()])
        halves.append([float(v) / 2 for v in box.get("size", "").split()])
    c, h = np.array(centres, dtype=np.float64), np.array(halves, dtype=np.float64)
    c.flags.writeable = h.flags.writeable = False
    return c, h
