"""What the estimator wrappers observe: :class:`ObservationConfig`, resolved once by
:func:`resolve_observation` (options checked, the calibration loaded and matched to the camera, the
fused filter's parameters chosen for the ToF model and the task).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass

from ihrcf_env.config.sensors import VL53L1X
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.calibration import Calibration, default_calibration_path
from ihrcf_env.core.checks import check_bool, check_positive, describe
from ihrcf_env.core.estimators import DEFAULT_ESTIMATORS, FusedParams, check_estimator_names
from ihrcf_env.core.forecast import ForecastOptions, forecast_options

__all__ = [
    "check_fused_params",
    "MAX_RESIDUAL",
    "ObservationConfig",
    "fused_params_for_tof",
    "check_deck_forecast",
    "check_observation_options",
    "load_calibration",
    "resolve_checked",
    "resolve_observation",
]

#: Largest IHRCF rigid-fit residual threshold (m).
MAX_RESIDUAL = 1.0


def fused_params_for_tof(model: VL53L1X | None, task: str = "") -> FusedParams:
    """The fused filter's parameters for the env's ToF model: with the VL53L1X model (per-sensor
    constant offsets of sigma ``offset_sigma``) a common-mode range-offset state of prior sigma
    ``offset_sigma / 2`` (the mean of four independent offsets); the ideal ToF (None): none. On
    ``task="landing-v2"`` (a ship deck, Froude-scaled: full-scale accelerations at a few times the
    frequency) the position also restarts at agreeing measurements (``reseed_agreeing``)."""
    offset = 0.0 if model is None or model.offset_sigma <= 0 else model.offset_sigma / 2
    return FusedParams(range_offset_sigma=offset, reseed_agreeing=task == "landing-v2")


@dataclass(frozen=True)
class ObservationConfig:
    """What the estimator wrappers observe (:mod:`ihrcf_env.wrappers`), resolved.

    ``raw``: no wrapper (the raw env's Dict observation); ``calibration``: the loaded calibration
    (None when raw), matched to the camera; ``keep_image`` / ``flatten``: the hover task's wrapper
    options; ``max_residual`` (m): IHRCF's rigid-fit threshold; ``estimators``: registered names, in
    order; ``fused_params``: the fused filter's parameters (given, or :func:`fused_params_for_tof`
    of the ToF model and the task; None when raw); ``privileged`` / ``deck_motion``: the landing
    task's flat observation options; ``deck_forecast``: the options of the deck-motion forecast the
    landing task's flat observation appends (None: off)."""

    raw: bool = False
    calibration: Calibration | None = None
    keep_image: bool | None = None
    flatten: bool = False
    max_residual: float = 0.01
    estimators: tuple[str, ...] = DEFAULT_ESTIMATORS
    fused_params: FusedParams | None = None
    privileged: bool = False
    deck_motion: bool = False
    deck_forecast: ForecastOptions | None = None


def check_deck_forecast(value: object) -> ForecastOptions | None:
    """``deck_forecast``: False or None (off), True (the default :class:`ForecastOptions`), a
    ForecastOptions or a dict of some of its fields (errors name ``deck_forecast`` and the field)."""
    if value is None or value is False:
        return None
    if value is True:
        return ForecastOptions()
    if isinstance(value, ForecastOptions):
        return value
    if not isinstance(value, dict):
        raise TypeError(
            "deck_forecast must be a bool, an ihrcf_env.core.forecast.ForecastOptions or a dict of its "
            f"fields, got {describe(value)}"
        )
    try:
        return forecast_options(value)
    except (TypeError, ValueError) as e:
        raise type(e)(f"deck_forecast: {e}") from None


def _check_calibration_kind(calibration: object) -> None:
    if calibration is not None and not isinstance(calibration, Calibration | str | os.PathLike):
        raise TypeError(
            "calibration must be a Calibration, a path (str or os.PathLike) to a calibration file, or "
            f"None for the shipped file; got {describe(calibration)}"
        )


def load_calibration(calibration: object) -> Calibration:
    """The calibration itself, the file at a path, or the shipped file for None (TypeError naming
    ``calibration`` for anything else; the file's CalibrationError for a bad file)."""
    _check_calibration_kind(calibration)
    if isinstance(calibration, Calibration):
        return calibration
    if calibration is None:
        return Calibration.load(default_calibration_path())
    assert isinstance(calibration, str | os.PathLike)
    return Calibration.load(calibration)


def check_fused_params(value: object) -> FusedParams | None:
    """The ``fused_params`` option: a :class:`~ihrcf_env.core.estimators.FusedParams`, a dict of
    some of its fields (the others default; the form a spec saved as JSON gives back) or None."""
    if value is None or isinstance(value, FusedParams):
        return value
    if isinstance(value, Mapping):
        fields = [f.name for f in dataclasses.fields(FusedParams)]
        unknown = [k for k in value if k not in fields]
        if unknown:
            raise ValueError(f"fused_params: unknown parameter {unknown[0]!r}; parameters: {fields}")
        try:
            return FusedParams(**value)
        except (TypeError, ValueError) as e:
            raise type(e)(f"fused_params: {e}") from None
    raise TypeError(
        "fused_params must be an ihrcf_env.core.estimators.FusedParams, a dict of its fields or None, "
        f"got {describe(value)}"
    )


def check_observation_options(
    *,
    raw: object = False,
    calibration: object = None,
    keep_image: object = None,
    flatten: object = False,
    max_residual: object = 0.01,
    estimators: object = DEFAULT_ESTIMATORS,
    fused_params: object = None,
    privileged: object = False,
    deck_motion: object = False,
    deck_forecast: object = None,
) -> ObservationConfig:
    """The wrapper options' type and range checks (no file read): an :class:`ObservationConfig`
    without its calibration, ``fused_params`` None when not given."""
    is_raw = check_bool("raw", raw)
    _check_calibration_kind(calibration)
    keep = None if keep_image is None else check_bool("keep_image", keep_image)
    flat = check_bool("flatten", flatten)
    residual = check_positive("max_residual", max_residual, "m", high=MAX_RESIDUAL)
    names = check_estimator_names(estimators)  # type: ignore[arg-type]
    fused_params = check_fused_params(fused_params)
    priv = check_bool("privileged", privileged)
    motion = check_bool("deck_motion", deck_motion)
    if motion and "fused" not in names:
        raise ValueError(
            f"deck_motion needs the fused estimator (estimators must include 'fused'), got {names}"
        )
    forecast = check_deck_forecast(deck_forecast)
    if forecast is not None and "fused" not in names:
        raise ValueError(
            f"deck_forecast needs the fused estimator (estimators must include 'fused'), got {names}"
        )
    if forecast is not None and flat:
        raise ValueError(
            "deck_forecast: the hover task's flat observation (flatten=True) has no forecast fields; "
            "use its Dict observation (flatten=False), where the forecast is obs['forecast']"
        )
    if is_raw:
        given = [
            n
            for n, v, d in (
                ("keep_image", keep, None),
                ("flatten", flat, False),
                ("privileged", priv, False),
                ("deck_motion", motion, False),
                ("deck_forecast", forecast, None),
                ("calibration", calibration, None),
                ("fused_params", fused_params, None),
            )
            if v != d
        ]
        if given:
            raise ValueError(f"{', '.join(given)}: observation-wrapper options have no effect with raw=True")
    return ObservationConfig(
        raw=is_raw,
        keep_image=keep,
        flatten=flat,
        max_residual=residual,
        estimators=names,
        fused_params=fused_params,
        privileged=priv,
        deck_motion=motion,
        deck_forecast=forecast,
    )


def resolve_observation(world: WorldConfig, task: str, **options: object) -> ObservationConfig:
    """The resolved :class:`ObservationConfig` of the wrapper ``options`` (the keywords of
    :func:`check_observation_options`) for an env of ``world`` and ``task`` (a key of
    :data:`~ihrcf_env.config.make.TASK_DEFAULTS`): options checked, then :func:`resolve_checked`."""
    return resolve_checked(world, task, check_observation_options(**options), options.get("calibration"))


def resolve_checked(
    world: WorldConfig, task: str, checked: ObservationConfig, calibration: object
) -> ObservationConfig:
    """``checked`` (from :func:`check_observation_options`) resolved for an env of ``world`` and
    ``task``: the ``calibration`` (as given: a Calibration, a path or None for the shipped file) read
    once and matched to the camera, the fused parameters :func:`fused_params_for_tof` of the ToF
    model and the task unless given. ValueError without a camera (unless raw)."""
    if checked.raw:
        return checked
    cam = world.camera
    if cam is None:
        raise ValueError(
            "camera=False leaves IHRCF and ATDA without an image: use camera=True, or raw=True for a "
            "camera-less simulation"
        )
    cal = load_calibration(calibration)
    cal.check_matches(cam.width, cam.height, cam.fov, world.rig, distortion=cam.distortion)
    fused = checked.fused_params
    if fused is None:
        fused = fused_params_for_tof(world.tof.model, task)
    return dataclasses.replace(checked, calibration=cal, fused_params=fused)
