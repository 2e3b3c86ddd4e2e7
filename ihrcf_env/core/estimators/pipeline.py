"""One frame through detection and both estimators."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.estimators.atda import atda_estimate
from ihrcf_env.core.estimators.base import PoseEstimate
from ihrcf_env.core.estimators.detector import TagDetector
from ihrcf_env.core.estimators.ihrcf import TouchPixels, ihrcf_estimate
from ihrcf_env.core.frames import as_array
from ihrcf_env.core.rig import SensorRig, tag_corners_deck


class DeckPoseEstimator:
    """Tag detection + IHRCF + ATDA for one camera frame and one set of ToF ranges.

    Keeps the last valid ATDA rotation (body frame) as the prior for the flip ambiguity
    (:meth:`reset` forgets it).
    """

    def __init__(
        self,
        rig: SensorRig,
        tag_size: float,
        tag_id: int,
        K: ArrayLike,
        dist: ArrayLike | None,
        touch_pixels: TouchPixels,
        refine: str = "subpix",
        max_residual: float = 0.01,
    ) -> None:
        tag_corners_deck(tag_size)  # validates tag_size
        self.rig = rig
        self.tag_size = float(tag_size)
        self.K = as_array(K, (3, 3), "K").copy()
        self.dist = None if dist is None else np.asarray(dist, dtype=np.float64).ravel().copy()
        self.touch_pixels = touch_pixels
        self.max_residual = float(max_residual)
        self.detector = TagDetector(tag_id, refine)
        self._prior: NDArray[np.float64] | None = None

    @property
    def prior_rotation(self) -> NDArray[np.float64] | None:
        """The ATDA prior: last valid ATDA ``R_body_deck`` (3, 3), or None."""
        return None if self._prior is None else self._prior.copy()

    def reset(self) -> None:
        """Forget the ATDA rotation prior."""
        self._prior = None

    def estimate(
        self, image: ArrayLike, ranges: ArrayLike, ranges_valid: ArrayLike
    ) -> tuple[PoseEstimate, PoseEstimate]:
        """(IHRCF, ATDA) estimates from one image and the four ranges (m) of ps1..ps4."""
        corners = self.detector.detect(image)
        if corners is None:
            lost = PoseEstimate.invalid("tag not found")
            return lost, lost
        ihrcf = ihrcf_estimate(
            corners, ranges, ranges_valid, self.touch_pixels, self.rig, self.tag_size, self.max_residual
        )
        atda = atda_estimate(corners, self.K, self.dist, self.tag_size, self.rig, self._prior)
        if atda.valid:
            self._prior = np.array(atda.rotation)
        return ihrcf, atda
