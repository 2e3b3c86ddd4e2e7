"""Locating shipped assets and generating tag textures."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.paths import asset_path

__all__ = ["asset_path", "tag_texture"]


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
