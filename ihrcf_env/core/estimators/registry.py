"""The estimator registry: the one place where a deck-pose estimator is added.

Each entry of :data:`ESTIMATORS` maps an observation key to a factory building a
:class:`~ihrcf_env.core.estimators.base.DeckPoseSource` from an :class:`EstimatorConfig`. Everything
downstream (:class:`~ihrcf_env.core.estimators.pipeline.DeckPoseEstimator`, the observation wrapper's
spaces, ``obs`` keys, ``info[f"{name}_reason"]`` and the flat layout) loops over the names, so a new
estimator is one class implementing the protocol plus one :func:`register_estimator` call, from
the package or from user code (if it needs more than the rig, the tag and the calibration, a field
of :class:`EstimatorConfig` with a default).
:data:`DEFAULT_ESTIMATORS` is what ``ihrcf_env/DeckHover-v0`` shows; others are opted in by name.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.checks import describe
from ihrcf_env.core.estimators.atda import ATDAEstimator
from ihrcf_env.core.estimators.base import DeckPoseSource
from ihrcf_env.core.estimators.fused import FusedEstimator, FusedParams
from ihrcf_env.core.estimators.ihrcf import IHRCFEstimator, TouchPixels
from ihrcf_env.core.keys import estimator_name_reason, reserved_estimator_names
from ihrcf_env.core.rig import SensorRig


@dataclass(frozen=True, eq=False)
class EstimatorConfig:
    """What the registered estimators are built from.

    Attributes:
        rig: sensor geometry (ToF layout and camera position in the body frame, m).
        tag_size: side of the tag's black square, m.
        K: (3, 3) camera matrix from the chessboard stage (px), for image-based estimators (ATDA).
        dist: OpenCV distortion coefficients (k1, k2, p1, p2, k3), or None for none.
        touch_pixels: the range -> touch-pixel table (IHRCF).
        max_residual: IHRCF rigid-fit RMS above which the estimate is invalid, m.
        fused: parameters of the fused estimator (None: :class:`FusedParams` defaults).
    """

    rig: SensorRig
    tag_size: float
    K: NDArray[np.float64]
    dist: NDArray[np.float64] | None
    touch_pixels: TouchPixels
    max_residual: float = 0.01
    fused: FusedParams | None = None


EstimatorFactory = Callable[[EstimatorConfig], DeckPoseSource]

#: Observation key -> factory, in the observation's order. Add new estimators here.
ESTIMATORS: dict[str, EstimatorFactory] = {
    "ihrcf": lambda c: IHRCFEstimator(c.touch_pixels, c.rig, c.tag_size, c.max_residual, name="ihrcf"),
    "atda": lambda c: ATDAEstimator(c.K, c.dist, c.tag_size, c.rig, name="atda"),
    "fused": lambda c: FusedEstimator(
        c.touch_pixels, c.rig, c.tag_size, c.K, c.dist, c.max_residual, params=c.fused, name="fused"
    ),
}


#: The built-in estimators' factories (a name re-registered by user code no longer maps to its own).
BUILTIN_ESTIMATORS: dict[str, EstimatorFactory] = dict(ESTIMATORS)


def register_estimator(name: str, factory: EstimatorFactory, *, replace: bool = False) -> None:
    """Add the estimator ``name`` (an observation key) built by ``factory(config: EstimatorConfig)
    -> DeckPoseSource`` (whose ``name`` must be ``name``). Registering a taken name raises
    ValueError unless ``replace``; reserved names and non-callables raise."""
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(
            f"estimator name must be an identifier (it becomes an observation key), got {name!r}"
        )
    reason = estimator_name_reason(name)
    if reason is not None:
        raise ValueError(f"register_estimator: the name {name!r} is reserved ({reason})")
    if not callable(factory):
        raise TypeError(f"factory must be callable (EstimatorConfig -> DeckPoseSource), got {factory!r}")
    if name in ESTIMATORS and not replace:
        raise ValueError(f"an estimator {name!r} is already registered (replace=True to replace it)")
    ESTIMATORS[name] = factory


def unregister_estimator(name: str) -> None:
    """Remove a user-registered estimator (the built-in ones stay)."""
    if name in DEFAULT_ESTIMATORS:
        raise ValueError(f"{name!r} is a built-in estimator")
    ESTIMATORS.pop(name, None)


#: The estimators of ``ihrcf_env/DeckHover-v0`` (its observation layout), in order.
DEFAULT_ESTIMATORS: tuple[str, ...] = ("ihrcf", "atda", "fused")

#: Names an estimator may not take: the env's own observation and info keys, and the names whose
#: info keys (``f"{name}_reason"``, ...) would be one of them (:mod:`ihrcf_env.core.keys`).
RESERVED_NAMES: frozenset[str] = reserved_estimator_names()


def check_estimator_names(names: Iterable[str]) -> tuple[str, ...]:
    """``names`` as a tuple after checking each is a registered name, given once; TypeError or
    ValueError naming ``estimators`` otherwise."""
    if isinstance(names, str) or not isinstance(names, Iterable):
        raise TypeError(f"estimators must be a sequence of names, got {type(names).__name__}")
    out = tuple(names)
    for n in out:
        if not isinstance(n, str):
            raise TypeError(f"estimators must contain names (str), got {type(n).__name__}")
        reason = estimator_name_reason(n)
        if reason is not None:
            raise ValueError(f"estimators: the name {n!r} is reserved ({reason})")
        if n not in ESTIMATORS:
            raise ValueError(f"estimators: unknown name {n!r}; registered: {sorted(ESTIMATORS)}")
    if len(set(out)) != len(out):
        raise ValueError(f"estimators: a name is given twice in {list(out)}")
    if not out:
        raise ValueError("estimators must name at least one estimator")
    return out


def check_source(name: str, source: object) -> None:
    """TypeError / ValueError naming the estimator ``name`` unless its factory's result ``source``
    is a :class:`~ihrcf_env.core.estimators.base.DeckPoseSource` called ``name``."""
    for method in ("reset", "update"):
        if not callable(getattr(source, method, None)):
            raise TypeError(
                f"estimator {name!r}: its factory must return a DeckPoseSource (name, reset(), "
                f"update(frame)), got {describe(source)} without {method}()"
            )
    own = getattr(source, "name", None)
    if own != name:
        called = repr(own) if isinstance(own, str) else describe(own)
        raise ValueError(f"estimator {name!r}: it calls itself {called}; its name must be {name!r}")


def build_estimators(
    config: EstimatorConfig, names: Iterable[str] = DEFAULT_ESTIMATORS
) -> dict[str, DeckPoseSource]:
    """An ordered mapping name -> new estimator for the registered ``names``."""
    if not (math.isfinite(config.max_residual) and config.max_residual > 0):
        raise ValueError(f"max_residual must be positive (m), got {config.max_residual!r}")
    out: dict[str, DeckPoseSource] = {}
    for n in check_estimator_names(names):
        source = ESTIMATORS[n](config)
        check_source(n, source)
        out[n] = source
    return out


__all__ = [
    "BUILTIN_ESTIMATORS",
    "DEFAULT_ESTIMATORS",
    "ESTIMATORS",
    "RESERVED_NAMES",
    "EstimatorConfig",
    "EstimatorFactory",
    "build_estimators",
    "check_estimator_names",
    "register_estimator",
    "unregister_estimator",
]
