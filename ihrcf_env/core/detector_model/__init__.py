"""A statistical model of the tag detector: what
:class:`~ihrcf_env.core.estimators.TagDetector` (``refine="subpix"``) reports on a rendered frame,
from the exact projection of the tag's corners (pure numpy / scipy; no simulator).

The "projected" camera (:class:`ihrcf_env.sim.sensors.tag_camera.ProjectedTagCamera`) renders
nothing: it projects the tag's corners through the true camera and asks this model for the corners
the rendered pipeline would have produced, or for the reason it would have failed; the same model
can corrupt corners projected from logged poses. Modules: ``features`` (the per-frame features),
``params`` (:class:`QualityParams`, one camera quality), ``model`` (:class:`DetectorModel`,
:class:`CornerTrack`, the failure reasons), ``file`` (the JSON file, :class:`DetectorModelError`),
``fit`` (fitting to rendered frames). The model is described in ``docs/detector_model.md``.
"""

from ihrcf_env.core.detector_model.features import (
    BASIS_NAMES,
    N_BASIS,
    QUIET_ZONE_SCALE,
    TagFeatures,
    corner_basis,
    image_margin,
    noise_to_contrast,
    project_points,
    tag_features,
)
from ihrcf_env.core.detector_model.file import (
    FIT_COMMAND,
    FORMAT_NAME,
    FORMAT_VERSION,
    DetectorModelError,
    default_detector_model_path,
    load_model,
    model_from_dict,
    model_to_dict,
    save_model,
)
from ihrcf_env.core.detector_model.fit import (
    NOISE_FIELDS,
    DetectorSamples,
    fit_detector_params,
    fit_quality,
    merge_samples,
)
from ihrcf_env.core.detector_model.model import (
    FIELD_FEATURES,
    QUALITIES,
    REASON_BORDER,
    REASON_MISS,
    REASON_OBLIQUE,
    REASON_OUTSIDE,
    REASON_QUIET_ZONE,
    REASON_SMALL,
    CornerTrack,
    DetectorModel,
)
from ihrcf_env.core.detector_model.params import COEFFICIENT_FIELDS, QualityParams

__all__ = [
    "BASIS_NAMES",
    "COEFFICIENT_FIELDS",
    "FIELD_FEATURES",
    "FIT_COMMAND",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "NOISE_FIELDS",
    "N_BASIS",
    "QUALITIES",
    "QUIET_ZONE_SCALE",
    "REASON_BORDER",
    "REASON_MISS",
    "REASON_OBLIQUE",
    "REASON_OUTSIDE",
    "REASON_QUIET_ZONE",
    "REASON_SMALL",
    "CornerTrack",
    "DetectorModel",
    "DetectorModelError",
    "DetectorSamples",
    "QualityParams",
    "TagFeatures",
    "corner_basis",
    "default_detector_model_path",
    "fit_detector_params",
    "fit_quality",
    "image_margin",
    "load_model",
    "merge_samples",
    "model_from_dict",
    "model_to_dict",
    "noise_to_contrast",
    "project_points",
    "save_model",
    "tag_features",
]
