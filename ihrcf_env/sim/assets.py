"""Locating shipped assets and generating tag textures."""

from __future__ import annotations

import importlib.resources
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray


def asset_path(name: str) -> Path:
    """Absolute path of a file shipped in ``assets/`` (works from a non-editable install)."""
    p = Path(str(importlib.resources.files("ihrcf_env.assets") / name))
    if not p.is_file():
        raise FileNotFoundError(f"asset {name!r} not found at {p}; is the package installed completely?")
    return p


def tag_texture(tag_id: int, cell_px: int = 16) -> NDArray[np.uint8]:
    """RGB texture of AprilTag 36h11 ``tag_id`` with a one-cell white quiet zone (10 x 10 cells).

    The black-bordered 8 x 8 cell square is the tag (its edge is the ``tag_size``); the drawing is
    OpenCV's ``generateImageMarker``, whose corner order the detector reports.
    """
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    n_ids = dictionary.bytesList.shape[0]
    if not (0 <= tag_id < n_ids):
        raise ValueError(f"tag_id must be in [0, {n_ids - 1}] for AprilTag 36h11, got {tag_id}")
    marker = cv2.aruco.generateImageMarker(dictionary, tag_id, 8 * cell_px, borderBits=1)
    img = np.full((10 * cell_px, 10 * cell_px), 255, np.uint8)
    img[cell_px:-cell_px, cell_px:-cell_px] = marker
    return np.ascontiguousarray(np.repeat(img[:, :, None], 3, axis=2))
