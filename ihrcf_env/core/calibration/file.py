"""The versioned calibration file (deterministic JSON): chessboard intrinsics and the
range -> pixel tables, with the camera and rig they were made for.

Pixel convention everywhere: OpenCV pixel centres, ``u`` = column, ``v`` = row, pixel ``(r, c)``
has its centre at ``(u, v) = (c, r)``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env._version import __version__
from ihrcf_env.core.calibration._checks import check_real_array
from ihrcf_env.core.calibration.bounds import (
    LENS_DISTORTION_LIMIT,
    MAX_CHESSBOARD_RMS,
    MAX_IMAGE_SIZE,
    MAX_SEED,
    check_camera_matrix,
    check_distortion,
    check_fov,
    check_rig,
    check_table_pixels,
)
from ihrcf_env.core.calibration.tables import RangePixelTable
from ihrcf_env.core.checks import check_int, check_non_negative, describe, is_int
from ihrcf_env.core.jsonfile import read_json
from ihrcf_env.core.paths import assets_dir
from ihrcf_env.core.rig import SensorRig

#: Version of the calibration file format written by :meth:`Calibration.save`.
FORMAT_VERSION: int = 1


class CalibrationError(ValueError):
    """A calibration file is missing, unreadable, malformed, or made for another camera/rig."""


def default_calibration_path() -> Path:
    """The calibration file shipped with the package (``assets/calibration_default.json``)."""
    return assets_dir() / "calibration_default.json"


def _json_default(o: Any) -> Any:
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


_REQUIRED_KEYS = (
    "image_width",
    "image_height",
    "fov",
    "rig",
    "tables",
    "K",
    "dist",
    "chessboard_rms",
    "seed",
    "created_with",
    "report",
)
_OPTIONAL_KEYS = ("format_version", "lens_distortion")


@dataclass(eq=False)
class Calibration:
    """Versioned calibration file of one camera configuration and rig.

    Every field is type- and range-checked on construction (TypeError for the wrong kind,
    ValueError out of its physical bounds, both naming the field); the bounds are those of
    :mod:`ihrcf_env.core.calibration.bounds`, in brief:

    Attributes:
        image_width, image_height: image size (px) the file was made for, 1 .. 32768.
        fov: vertical field of view (rad) the file was made for, in (0, pi).
        rig: :meth:`ihrcf_env.core.rig.SensorRig.to_dict` of the rig (a ``SensorRig`` is converted):
            ``a`` in (0, 1] m, ``theta`` in (0, pi/2) rad, ``camera_position`` within +-1 m.
        tables: the range -> pixel tables ps1..ps4 (ranges in (0, 100] m, touch pixels within one
            image size around the image).
        K: (3, 3) intrinsics from the chessboard stage (section 2.1; used by ATDA): ``fx``, ``fy``
            in [0.01, 100] x the larger image side, ``|skew| <= 0.1 fx``, the principal point inside
            the image, last row ``0 0 1``.
        dist: (5,) distortion (k1, k2, p1, p2, k3), within +-(2, 10, 0.2, 0.2, 50), and its radial
            part must not fold the image (``r (1 + k1 r^2 + k2 r^4 + k3 r^6)`` increasing out to
            the image corners).
        chessboard_rms: reprojection RMS (px) of the chessboard calibration, in [0, 100]; None if
            skipped.
        seed: RNG seed of the calibration run, in [0, 2^128] (None if unseeded).
        created_with: producer string, e.g. ``"ihrcf_env 0.1.0"``.
        report: free JSON-serialisable dict (stages used/skipped, measurements).
        lens_distortion: (k1, k2) radial distortion of the simulated camera the file was made for,
            each in [-1, 1] (the camera's property, like ``fov``; ``dist`` is what the chessboard
            estimated).
        format_version: file format version (:data:`FORMAT_VERSION`).
        source: file this was loaded from (not serialised).
    """

    image_width: int
    image_height: int
    fov: float
    rig: dict[str, Any]
    tables: RangePixelTable
    K: NDArray[np.float64]
    dist: NDArray[np.float64]
    chessboard_rms: float | None = None
    seed: int | None = None
    created_with: str = f"ihrcf_env {__version__}"
    report: dict[str, Any] = field(default_factory=dict)
    lens_distortion: tuple[float, float] = (0.0, 0.0)
    format_version: int = FORMAT_VERSION
    source: str | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        """Type- and value-check every field (see the class docstring for units): TypeError for a
        value of the wrong kind (ints must be ints, not floats or bools; numbers not null, bool or
        strings; arrays of numbers), ValueError for a bad value, both naming the field."""
        self.image_width = check_int("image_width", self.image_width, low=1, high=MAX_IMAGE_SIZE)
        self.image_height = check_int("image_height", self.image_height, low=1, high=MAX_IMAGE_SIZE)
        self.fov = check_fov(self.fov)
        lim = LENS_DISTORTION_LIMIT
        k = check_real_array("lens_distortion", self.lens_distortion, (2,), low=-lim, high=lim)
        self.lens_distortion = (float(k[0]), float(k[1]))
        if not isinstance(self.tables, RangePixelTable):
            raise TypeError(f"tables must be a RangePixelTable, got {describe(self.tables)}")
        self.K = check_camera_matrix(self.K, self.image_width, self.image_height)
        self.dist = check_distortion(self.dist, self.K, self.image_width, self.image_height)
        check_table_pixels(self.tables, self.image_width, self.image_height)
        if self.chessboard_rms is not None:
            self.chessboard_rms = check_non_negative(
                "chessboard_rms", self.chessboard_rms, "px", high=MAX_CHESSBOARD_RMS
            )
        if self.seed is not None:
            self.seed = check_int("seed", self.seed, low=0, high=MAX_SEED)
        if not isinstance(self.created_with, str):
            raise TypeError(f"created_with must be a string, got {describe(self.created_with)}")
        if not isinstance(self.report, Mapping):
            raise TypeError(f"report must be an object, got {describe(self.report)}")
        self.report = dict(self.report)
        self.format_version = check_int(
            "format_version", self.format_version, low=FORMAT_VERSION, high=FORMAT_VERSION
        )
        self.rig = check_rig(self.rig)

    def to_dict(self) -> dict[str, Any]:
        return {
            "format_version": self.format_version,
            "image_width": self.image_width,
            "image_height": self.image_height,
            "fov": self.fov,
            "lens_distortion": list(self.lens_distortion),
            "rig": self.rig,
            "tables": self.tables.to_dict(),
            "K": self.K.tolist(),
            "dist": self.dist.tolist(),
            "chessboard_rms": self.chessboard_rms,
            "seed": self.seed,
            "created_with": self.created_with,
            "report": self.report,
        }

    def __eq__(self, other: object) -> bool:
        """Equal contents (every field, arrays element-wise): a copy equals its original."""
        if not isinstance(other, Calibration):
            return NotImplemented
        return self is other or self.to_json() == other.to_json()

    __hash__ = None  # type: ignore[assignment]  # mutable contents

    def to_json(self) -> str:
        """Deterministic JSON: sorted keys, floats by ``repr`` (exact round trip), no NaN/inf."""
        try:
            return (
                json.dumps(self.to_dict(), sort_keys=True, indent=1, allow_nan=False, default=_json_default)
                + "\n"
            )
        except ValueError as e:
            raise ValueError(f"calibration contains a non-finite number (report?): {e}") from e

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the calibration file; the same contents always give byte-identical files."""
        p = Path(path)
        text = self.to_json()
        if p.parent != Path(""):
            p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_name(p.name + ".tmp")
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, p)
        return p

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], source: str = "<dict>") -> Calibration:
        """Validate and build; raises :class:`CalibrationError` naming ``source`` and the field.

        Every field is type-checked (see :meth:`__post_init__`); unknown keys are rejected (a
        misspelt optional key would otherwise be silently replaced by its default)."""
        if not isinstance(d, Mapping):
            raise CalibrationError(f"{source}: expected a JSON object, got {describe(d)}")
        if "format_version" not in d:
            raise CalibrationError(f"{source}: missing 'format_version' (not an ihrcf_env calibration file?)")
        version = d["format_version"]
        if not is_int(version) or version != FORMAT_VERSION:
            raise CalibrationError(
                f"{source}: unsupported format_version {describe(version)} (this ihrcf_env reads "
                f"{FORMAT_VERSION}); re-create it with python -m ihrcf_env.calibrate"
            )
        missing = [k for k in _REQUIRED_KEYS if k not in d]
        if missing:
            raise CalibrationError(f"{source}: missing key(s) {missing}")
        unknown = sorted(str(k) for k in d if k not in _REQUIRED_KEYS + _OPTIONAL_KEYS)
        if unknown:
            raise CalibrationError(
                f"{source}: unknown key(s) {unknown}; known: {sorted(_REQUIRED_KEYS + _OPTIONAL_KEYS)}"
            )
        try:
            tables = RangePixelTable.from_dict(d["tables"])
        except (ValueError, TypeError, OverflowError) as e:
            raise CalibrationError(f"{source}: bad 'tables': {e}") from e
        try:
            return cls(
                image_width=d["image_width"],
                image_height=d["image_height"],
                fov=d["fov"],
                rig=d["rig"],
                tables=tables,
                K=d["K"],
                dist=d["dist"],
                chessboard_rms=d["chessboard_rms"],
                seed=d["seed"],
                created_with=d["created_with"],
                report=d["report"],
                lens_distortion=d.get("lens_distortion", (0.0, 0.0)),
                format_version=version,
                source=source,
            )
        except (ValueError, TypeError, OverflowError) as e:
            raise CalibrationError(f"{source}: {e}") from e

    @classmethod
    def load(cls, path: str | os.PathLike[str] | Traversable) -> Calibration:
        """Read and validate a calibration file; :class:`CalibrationError` naming the file otherwise."""
        name = str(path)
        data = read_json(path, CalibrationError, "calibration JSON file", "create one with ihrcf-calibrate")
        return cls.from_dict(data, source=name)

    def matches(
        self,
        width: int,
        height: int,
        fov: float,
        rig: SensorRig | Mapping[str, Any],
        distortion: tuple[float, float] = (0.0, 0.0),
    ) -> list[str]:
        """Human-readable differences between this file and a camera config / rig (empty if none)."""
        rd = dict(rig.to_dict() if isinstance(rig, SensorRig) else rig)
        diffs = []
        if not np.allclose(
            np.asarray(distortion, dtype=np.float64), self.lens_distortion, rtol=0.0, atol=1e-12
        ):
            theirs = tuple(float(x) for x in distortion)
            diffs.append(f"lens distortion (k1, k2) {self.lens_distortion} in the file vs {theirs}")
        if (int(width), int(height)) != (self.image_width, self.image_height):
            diffs.append(f"image size {self.image_width}x{self.image_height} in the file vs {width}x{height}")
        if not math.isclose(float(fov), self.fov, rel_tol=0.0, abs_tol=1e-8):
            diffs.append(f"fov {math.degrees(self.fov):.10g} deg in the file vs {math.degrees(fov):.10g} deg")
        for key in ("a", "theta"):
            if not math.isclose(float(rd[key]), self.rig[key], rel_tol=0.0, abs_tol=1e-9):
                diffs.append(f"rig {key} {self.rig[key]!r} in the file vs {float(rd[key])!r}")
        cp = np.asarray(rd["camera_position"], dtype=np.float64)
        if cp.shape != (3,) or not np.allclose(cp, self.rig["camera_position"], rtol=0.0, atol=1e-9):
            diffs.append(f"rig camera_position {self.rig['camera_position']} in the file vs {cp.tolist()}")
        return diffs

    def check_matches(
        self,
        width: int,
        height: int,
        fov: float,
        rig: SensorRig | Mapping[str, Any],
        output: str | os.PathLike[str] | None = None,
        distortion: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """Raise :class:`CalibrationError` if the file was made for another camera config (px, rad) or rig.

        The message gives the command that produces a matching file; ``output`` is the path to
        suggest in it (default ``calibration_<W>x<H>_fov<F>.json``).
        """
        diffs = self.matches(width, height, fov, rig, distortion)
        if not diffs:
            return
        fov_deg = f"{math.degrees(fov):.10g}"
        out = str(output) if output is not None else f"calibration_{width}x{height}_fov{fov_deg}.json"
        k1, k2 = (float(x) for x in distortion)
        lens = f" --k1 {k1:.10g} --k2 {k2:.10g}" if (k1, k2) != (0.0, 0.0) else ""
        cmd = (
            f"python -m ihrcf_env.calibrate --width {width} --height {height} --fov-deg {fov_deg}{lens} "
            f"--output {out}"
        )
        rig_note = " (with the same rig settings)" if any(s.startswith("rig") for s in diffs) else ""
        raise CalibrationError(
            f"calibration file {self.source or '<in memory>'} does not match the requested configuration: "
            + "; ".join(diffs)
            + f". Produce a matching file with:\n    {cmd}{rig_note}"
        )


__all__ = [
    "FORMAT_VERSION",
    "Calibration",
    "CalibrationError",
    "default_calibration_path",
]
