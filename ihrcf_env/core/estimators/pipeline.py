"""One frame through tag detection (once) and every registered estimator, in order."""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.checks import describe
from ihrcf_env.core.estimators.atda import ATDAEstimator
from ihrcf_env.core.estimators.base import DeckPoseSource, ImuSample, PoseEstimate, SensorFrame
from ihrcf_env.core.estimators.detector import TagDetector
from ihrcf_env.core.estimators.fused import FusedParams
from ihrcf_env.core.estimators.ihrcf import TouchPixels
from ihrcf_env.core.estimators.registry import DEFAULT_ESTIMATORS, EstimatorConfig, build_estimators
from ihrcf_env.core.frames import as_array
from ihrcf_env.core.rig import SensorRig, tag_corners_deck


class DeckPoseEstimator:
    """Tag detection + the registered estimators (default IHRCF, ATDA and the fused filter) for one
    camera frame, one set of ToF ranges and one IMU sample.

    :meth:`frame` detects the tag once and packs a :class:`SensorFrame`; :meth:`update` feeds it to
    every estimator of :attr:`sources` (an ordered mapping name -> :class:`DeckPoseSource`) and
    returns name -> :class:`PoseEstimate`. :meth:`reset` resets every estimator (e.g. ATDA's flip prior).

    Args:
        rig, tag_size (m), K (3, 3), dist, touch_pixels, max_residual (m): see
            :class:`~ihrcf_env.core.estimators.registry.EstimatorConfig`.
        tag_id: AprilTag 36h11 id to detect. refine: the detector's corner refinement.
        estimators: registered names, in order (default ``("ihrcf", "atda", "fused")``).
        fused: parameters of the fused estimator (None: the defaults).
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
        estimators: Iterable[str] = DEFAULT_ESTIMATORS,
        fused: FusedParams | None = None,
    ) -> None:
        tag_corners_deck(tag_size)  # validates tag_size
        self.config = EstimatorConfig(
            rig=rig,
            tag_size=float(tag_size),
            K=as_array(K, (3, 3), "K").copy(),
            dist=None if dist is None else np.asarray(dist, dtype=np.float64).ravel().copy(),
            touch_pixels=touch_pixels,
            max_residual=float(max_residual),
            fused=fused,
        )
        self.detector = TagDetector(tag_id, refine)
        self.sources: dict[str, DeckPoseSource] = build_estimators(self.config, estimators)

    @property
    def names(self) -> tuple[str, ...]:
        """The estimators' names (observation keys), in order."""
        return tuple(self.sources)

    @property
    def prior_rotation(self) -> NDArray[np.float64] | None:
        """The ATDA prior: last valid ATDA ``R_body_deck`` (3, 3), or None (also without ATDA)."""
        atda = self.sources.get("atda")
        return atda.prior_rotation if isinstance(atda, ATDAEstimator) else None

    def reset(self) -> None:
        """Reset every estimator (forgets ATDA's rotation prior and any filter state)."""
        for source in self.sources.values():
            source.reset()

    def frame(
        self,
        image: ArrayLike,
        ranges: ArrayLike,
        ranges_valid: ArrayLike,
        time: float = math.nan,
        imu: ImuSample | None = None,
    ) -> SensorFrame:
        """Detect the tag in ``image`` (uint8) once and pack the frame: ``ranges`` (4,) m of
        ps1..ps4, ``ranges_valid`` (4,) bool, ``time`` s (NaN: unknown), ``imu`` sample or None."""
        img = np.asarray(image)
        corners = self.detector.detect(img)
        return SensorFrame(
            time=time,
            corners=corners,
            ranges=np.asarray(ranges, dtype=np.float64),
            ranges_valid=np.asarray(ranges_valid, dtype=bool),
            imu=imu,
            image=img,
        )

    def update(self, frame: SensorFrame) -> dict[str, PoseEstimate]:
        """Feed ``frame`` to every estimator, in order: name -> estimate (TypeError naming an
        estimator whose ``update`` returns anything but a PoseEstimate)."""
        out: dict[str, PoseEstimate] = {}
        for name, source in self.sources.items():
            est = source.update(frame)
            if not isinstance(est, PoseEstimate):
                raise TypeError(
                    f"estimator {name!r}: update() must return a PoseEstimate "
                    f"(PoseEstimate.invalid(reason) when there is none), got {describe(est)}"
                )
            out[name] = est
        return out


__all__ = [
    "DeckPoseEstimator",
]
