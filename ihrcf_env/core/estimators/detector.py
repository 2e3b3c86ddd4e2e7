"""AprilTag 36h11 corner detection with OpenCV's aruco module.

:class:`TagDetector` uses sub-pixel corner refinement (``refine="subpix"``) by default; the
refinement modes' measured corner errors and costs, and the offset of the ``"apriltag"`` mode
(:data:`APRILTAG_CORNER_OFFSET_PX`), are in ``docs/estimators.md`` ("Tag detection").
"""

from __future__ import annotations

import functools

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Offset (px, both axes) of CORNER_REFINE_APRILTAG corners from OpenCV's pixel-centre convention.
APRILTAG_CORNER_OFFSET_PX: float = 0.42


_REFINE_METHODS: dict[str, int] = {
    "none": cv2.aruco.CORNER_REFINE_NONE,
    "subpix": cv2.aruco.CORNER_REFINE_SUBPIX,
    "contour": cv2.aruco.CORNER_REFINE_CONTOUR,
    "apriltag": cv2.aruco.CORNER_REFINE_APRILTAG,
}


@functools.cache
def apriltag_ids() -> int:
    """Number of tags in the AprilTag 36h11 family (valid ``tag_id`` 0 .. n - 1)."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    return int(dictionary.bytesList.shape[0])


class TagDetector:
    """AprilTag 36h11 detector (``cv2.aruco.ArucoDetector``) returning one tag's corners.

    ``refine`` is one of 'none', 'subpix' (default, see the module docstring),
    'contour', 'apriltag'. With 'apriltag' the corners are shifted by ``-apriltag_offset`` px on
    both axes to OpenCV's pixel-centre convention.
    """

    def __init__(
        self, tag_id: int = 0, refine: str = "subpix", apriltag_offset: float = APRILTAG_CORNER_OFFSET_PX
    ) -> None:
        if refine not in _REFINE_METHODS:
            raise ValueError(f"refine must be one of {sorted(_REFINE_METHODS)}, got {refine!r}")
        self.tag_id = int(tag_id)
        self.refine = refine
        self._offset = float(apriltag_offset) if refine == "apriltag" else 0.0
        self._dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
        self._detector = cv2.aruco.ArucoDetector(self._dictionary, self._parameters())
        # windows: a second detector whose size-relative thresholds are set per window size
        self._window_detector: cv2.aruco.ArucoDetector | None = None
        self._window_key: tuple[int, int, bool] = (0, 0, False)

    def _parameters(self) -> cv2.aruco.DetectorParameters:
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = _REFINE_METHODS[self.refine]
        params.cornerRefinementMinAccuracy = 0.01
        params.cornerRefinementMaxIterations = 100
        # The tag's black square, its white quiet zone and the square deck around it are nested,
        # nearly concentric quads. With OpenCV 5's defaults (minMarkerDistanceRate 0.125,
        # minDistanceToBorder 3) the black square was dropped in favour of its neighbours on some
        # frames: measured on 300 random rendered poses (0.45-2.5 m, tilts to 0.2 rad), 255 of the
        # 259 with the tag fully in view were detected; with 0.05 (OpenCV 4's default) and 1 px,
        # 259 of 259, and no false ids in either case.
        params.minMarkerDistanceRate = 0.05
        params.minDistanceToBorder = 1
        return params

    def _window_detector_for(
        self, window_side: int, full_side: int, at_border: bool
    ) -> cv2.aruco.ArucoDetector:
        """The window detector: OpenCV's perimeter limits (fractions of the image's largest side,
        truncated to whole pixels) set to the full image's pixel values; OpenCV's border rule
        (``minDistanceToBorder``) kept only if the window reaches the image's border."""
        key = (window_side, full_side, at_border)
        if self._window_detector is None or key != self._window_key:
            params = self._parameters()
            base = cv2.aruco.DetectorParameters()
            # OpenCV: limit = (unsigned) (rate * max(cols, rows)); half a pixel above the full
            # image's whole-pixel limit truncates back to it on the window
            lo = int(base.minMarkerPerimeterRate * full_side)
            hi = int(base.maxMarkerPerimeterRate * full_side)
            params.minMarkerPerimeterRate = (lo + 0.5) / window_side
            params.maxMarkerPerimeterRate = (hi + 0.5) / window_side
            if not at_border:
                # the window's edges are not the image's: nothing there is near the image border
                params.minDistanceToBorder = 0
            if self._window_detector is None:
                self._window_detector = cv2.aruco.ArucoDetector(self._dictionary, params)
            else:
                self._window_detector.setDetectorParameters(params)
            self._window_key = key
        return self._window_detector

    def detect(
        self,
        image: ArrayLike,
        origin: tuple[int, int] | None = None,
        full_size: tuple[int, int] | None = None,
    ) -> NDArray[np.float64] | None:
        """(4, 2) float64 corners (OpenCV pixel centres, OpenCV order) of tag ``tag_id``, or None.

        ``image``: uint8 grayscale (H, W), RGB (H, W, 3) or RGBA (H, W, 4).

        A window: with ``origin`` = (x0, y0) and ``full_size`` = (W, H) (both or neither),
        ``image`` is the pixel rectangle of a W x H image whose top-left pixel is (x0, y0); the
        corners are returned in the full image's pixels. OpenCV's only parameters relative to the
        image size (``min/maxMarkerPerimeterRate``, fractions of the largest side) are set to the
        full image's pixel values; every other parameter is in pixels or relative to the marker.
        OpenCV drops a group of nested candidates whose largest member has a corner within
        ``minDistanceToBorder`` (1 px) of the image border; a window's edge inside the image is
        no border, so that rule is applied only when the window reaches the image's border.

        Equal to the full image's detection when the window holds the tag's black square with
        12 px or more around it (OpenCV's adaptive threshold looks 11 px away, corner refinement
        6 px) and neither it nor the tag's quiet zone grown by 12 px reaches the image border, or
        when it is the whole image. (Near the border the tag's candidate group can hold large
        thresholded regions that a window would cut into other shapes;
        :class:`~ihrcf_env.sim.sensors.tag_window.WindowedTagCamera` passes the whole image
        there.) ``tests/sim/test_render_window.py`` checks the agreement on rendered frames.
        """
        img = np.asarray(image)
        if img.dtype != np.uint8:
            raise ValueError(f"image must be uint8, got {img.dtype}")
        if img.ndim == 3 and img.shape[2] == 3:
            img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
        elif img.ndim == 3 and img.shape[2] == 4:
            img = cv2.cvtColor(img, cv2.COLOR_RGBA2GRAY)
        elif img.ndim != 2:
            raise ValueError(f"image must have shape (H, W), (H, W, 3) or (H, W, 4), got {img.shape}")
        if (origin is None) != (full_size is None):
            raise ValueError("origin and full_size must be given together (a window) or not at all")
        detector = self._detector
        x0 = y0 = 0
        if origin is not None and full_size is not None:
            x0, y0 = _int_pair("origin", origin, 0)
            width, height = _int_pair("full_size", full_size, 1)
            h, w = img.shape[:2]
            if x0 + w > width or y0 + h > height:
                raise ValueError(
                    f"the {w}x{h} window at origin {(x0, y0)} does not fit in full_size {(width, height)}"
                )
            at_border = x0 == 0 or y0 == 0 or x0 + w == width or y0 + h == height
            detector = self._window_detector_for(max(w, h), max(width, height), at_border)
        corners, ids, _ = detector.detectMarkers(np.ascontiguousarray(img))
        if ids is None:
            return None
        for c, i in zip(corners, ids.ravel(), strict=True):
            if int(i) == self.tag_id:
                out: NDArray[np.float64] = c.reshape(4, 2).astype(np.float64) - self._offset
                if x0 or y0:
                    out += (x0, y0)
                return out
        return None


def _int_pair(name: str, value: object, low: int) -> tuple[int, int]:
    """``value`` as two ints >= ``low`` (TypeError / ValueError naming ``name``)."""
    if not isinstance(value, tuple | list | np.ndarray) or len(value) != 2:
        raise TypeError(f"{name} must be two integers, got {value!r}")
    if not all(isinstance(v, int | np.integer) and not isinstance(v, bool) for v in value):
        raise TypeError(f"{name} must be two integers, got {value!r}")
    a, b = int(value[0]), int(value[1])
    if a < low or b < low:
        raise ValueError(f"{name} must be two integers >= {low}, got {value!r}")
    return a, b


__all__ = [
    "APRILTAG_CORNER_OFFSET_PX",
    "TagDetector",
    "apriltag_ids",
]
