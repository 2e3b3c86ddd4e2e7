"""The detector model file: versioned JSON (``assets/detector_model.json``, a few kB), re-made with
``python -m ihrcf_env.fit_detector``.

An object with ``format`` (:data:`FORMAT_NAME`), ``format_version`` (:data:`FORMAT_VERSION`),
``fit_command``, ``qualities`` (camera quality -> the fields of
:class:`~ihrcf_env.core.detector_model.params.QualityParams`, each range-checked there) and ``fit``
(the fit's free record). Every defect of a file (missing, unreadable, not JSON, nested too deeply,
a field of the wrong kind or out of range, an integer too large for a float) raises
:class:`DetectorModelError` naming the file, the field and the command that re-makes it.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ihrcf_env.core.checks import describe, is_int
from ihrcf_env.core.detector_model.model import DetectorModel
from ihrcf_env.core.detector_model.params import QualityParams
from ihrcf_env.core.jsonfile import read_json
from ihrcf_env.core.paths import assets_dir

#: The command that (re)makes the detector model file.
FIT_COMMAND = "ihrcf-fit-detector"
#: File format tag and version of :func:`save_model`.
FORMAT_NAME = "ihrcf_env detector model"
FORMAT_VERSION = 1


class DetectorModelError(ValueError):
    """A detector model file is missing, unreadable or malformed (the message names the file and
    the command that re-makes it)."""


def default_detector_model_path() -> Path:
    """The detector model shipped with the package (``assets/detector_model.json``)."""
    return assets_dir() / "detector_model.json"


def model_to_dict(model: DetectorModel) -> dict[str, Any]:
    """The JSON object of ``model``'s file."""
    return {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "fit_command": FIT_COMMAND,
        "qualities": {q: p.to_dict() for q, p in model.qualities.items()},
        "fit": dict(model.fit),
    }


def model_from_dict(data: Mapping[str, Any], source: str | None = None) -> DetectorModel:
    """The model of a :func:`model_to_dict` mapping; ValueError / TypeError naming what is wrong."""
    if not isinstance(data, Mapping):
        raise TypeError(f"a detector model must be a JSON object, got {describe(data)}")
    if data.get("format") != FORMAT_NAME:
        raise ValueError(f"'format' must be {FORMAT_NAME!r}, got {describe(data.get('format'))}")
    version = data.get("format_version")
    if not is_int(version) or version != FORMAT_VERSION:
        raise ValueError(f"'format_version' must be {FORMAT_VERSION}, got {describe(version)}")
    qualities = data.get("qualities")
    if not isinstance(qualities, Mapping):
        raise TypeError(f"'qualities' must be an object, got {describe(qualities)}")
    params = {}
    for q, p in qualities.items():
        try:
            params[str(q)] = QualityParams.from_dict(p)
        except (TypeError, ValueError) as e:
            raise type(e)(f"qualities[{q!r}]: {e}") from None
    fit = data.get("fit", {})
    return DetectorModel(qualities=params, fit=fit if isinstance(fit, Mapping) else {}, source=source)


def save_model(model: DetectorModel, path: str | os.PathLike[str]) -> Path:
    """Write ``model`` as JSON to ``path`` (its folder created); returns the path."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(model_to_dict(model), indent=1, allow_nan=False) + "\n", encoding="utf-8")
    return out


def load_model(path: str | os.PathLike[str] | None = None) -> DetectorModel:
    """Read a model file (default: the shipped one). :class:`DetectorModelError` naming the file and
    the fit command when it is missing, unreadable or malformed."""
    p = Path(path) if path is not None else default_detector_model_path()
    redo = f"re-create it with {FIT_COMMAND} --out {p}"
    data = read_json(
        p, DetectorModelError, "detector model file", f"create it with {FIT_COMMAND} --out {p}", redo
    )
    try:
        return model_from_dict(data, source=str(p))
    except (ValueError, TypeError) as e:
        raise DetectorModelError(f"{p}: not a valid detector model file ({e}); {redo}") from None


def _reject_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name} in JSON")


__all__ = [
    "FIT_COMMAND",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "DetectorModelError",
    "default_detector_model_path",
    "load_model",
    "model_from_dict",
    "model_to_dict",
    "save_model",
]
