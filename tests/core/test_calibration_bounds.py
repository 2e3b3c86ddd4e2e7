"""Calibration files with absurd contents: physical bounds on every field, integers too large for a
float, JSON nested too deeply; each raises CalibrationError naming the file and the field."""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import calibration_fields

from ihrcf_env.core.calibration import Calibration, CalibrationError, default_calibration_path
from ihrcf_env.core.calibration._checks import check_keys, check_real_array

HUGE = 10**400  # json.loads reads it as an int; float(HUGE) raises OverflowError


def shipped() -> dict[str, Any]:
    data: dict[str, Any] = json.loads(Path(str(default_calibration_path())).read_text(encoding="utf-8"))
    return data


def load_mutated(tmp_path: Path, mutate: Callable[[dict[str, Any]], None]) -> Calibration:
    d = copy.deepcopy(shipped())
    mutate(d)
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(d), encoding="utf-8")
    return Calibration.load(path)


def _set(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    """A mutation setting ``path`` ("K.0.0", "tables.ps2.pixels.3.1") to ``value``."""
    keys = [int(k) if k.isdigit() else k for k in path.split(".")]

    def mutate(d: dict[str, Any]) -> None:
        node: Any = d
        for k in keys[:-1]:
            node = node[k]
        node[keys[-1]] = value

    return mutate


def test_the_shipped_file_passes_the_bounds() -> None:
    cal = Calibration.load(default_calibration_path())
    assert cal.image_width == 512 and cal.K[0, 0] > 0


# the field as the error names it, and where it is in the file
HUGE_FIELDS = [
    ("image_width", "image_width"),
    ("image_height", "image_height"),
    ("fov", "fov"),
    ("chessboard_rms", "chessboard_rms"),
    ("seed", "seed"),
    ("format_version", "format_version"),
    ("lens_distortion.1", r"lens_distortion\[1\]"),
    ("K.0.0", r"K\[0, 0\]"),
    ("K.1.2", r"K\[1, 2\]"),
    ("dist.0", r"dist\[0\]"),
    ("dist.4", r"dist\[4\]"),
    ("rig.a", "rig.a"),
    ("rig.theta", "rig.theta"),
    ("rig.camera_position.2", r"rig.camera_position\[2\]"),
    ("tables.ps1.ranges.5", r"tables.ps1.ranges\[5\]"),
    ("tables.ps3.pixels.7.1", r"tables.ps3.pixels\[7, 1\]"),
]


@pytest.mark.parametrize(("where", "name"), HUGE_FIELDS)
@pytest.mark.parametrize("sign", [1, -1])
def test_a_400_digit_integer_names_the_field(tmp_path: Path, where: str, name: str, sign: int) -> None:
    # Before: OverflowError (float(int)) escaped from the load, naming nothing.
    with pytest.raises(CalibrationError, match=name) as e:
        load_mutated(tmp_path, _set(where, sign * HUGE))
    assert "cal.json" in str(e.value)


def test_json_nested_too_deeply(tmp_path: Path) -> None:
    # Before: RecursionError from json.loads.
    path = tmp_path / "deep.json"
    depth = 200_000
    path.write_text('{"format_version": 1, "report": ' + "[" * depth + "]" * depth + "}", encoding="utf-8")
    with pytest.raises(CalibrationError, match="nested too deeply") as e:
        Calibration.load(path)
    assert str(path) in str(e.value)


@pytest.mark.parametrize(
    ("where", "value", "name"),
    [
        ("dist.0", -1e6, r"dist\[0\] \(k1\)"),  # before: accepted, ATDA then 9-10 m off at 1 m
        ("dist.1", 1e3, r"dist\[1\] \(k2\)"),
        ("dist.2", 0.5, r"dist\[2\] \(p1\)"),
        ("dist.4", -1e4, r"dist\[4\] \(k3\)"),
        ("dist.0", -1.5, "folds the image"),  # within +-2, but no lens maps two angles to one radius
        ("K.0.0", 1e9, "K"),
        ("K.1.1", 0.5, r"K\[1, 1\] \(fy\)"),
        ("K.0.1", 200.0, "skew"),
        ("K.0.2", 600.0, r"K\[0, 2\] \(cx\)"),
        ("K.1.2", -40.0, r"K\[1, 2\] \(cy\)"),
        ("lens_distortion.0", -3.0, r"lens_distortion\[0\]"),
        ("chessboard_rms", 1e5, "chessboard_rms"),
        ("image_width", 10**6, "image_width"),
        ("rig.a", 5.0, "rig.a"),
        ("rig.camera_position.0", 10.0, r"rig.camera_position\[0\]"),
        ("tables.ps2.ranges.10", 1e5, r"tables.ps2.ranges\[10\]"),
        ("tables.ps4.pixels.3.0", 1e7, r"tables.ps4.pixels\[3, 0\]"),
        ("tables.ps4.pixels.3.0", 5000.0, r"tables.ps4.pixels\[\d+, 0\] \(u\)"),  # > 2 W
    ],
)
def test_physical_bounds_name_the_field(tmp_path: Path, where: str, value: float, name: str) -> None:
    with pytest.raises(CalibrationError, match=name):
        load_mutated(tmp_path, _set(where, value))


def test_bounds_hold_in_the_constructor_too() -> None:
    cal = Calibration.load(default_calibration_path())
    kw = calibration_fields(cal)
    dist = cal.dist.copy()
    dist[0] = -1e6
    with pytest.raises(ValueError, match=r"dist\[0\]"):
        Calibration(**{**kw, "dist": dist})
    with pytest.raises(ValueError, match=r"K\[0, 2\] \(cx\)"):
        Calibration(**{**kw, "image_width": 100, "image_height": 100})  # cx = 256 outside a 100 px image
    assert Calibration(**kw).dist.tolist() == cal.dist.tolist()


def test_a_distortion_that_folds_only_beyond_the_image_is_accepted() -> None:
    # k1 = -0.3 folds at r = 1 / sqrt(0.9) = 1.05, beyond the corners of the shipped 60 deg camera
    # (r = 0.82): a strong but real barrel distortion.
    cal = Calibration.load(default_calibration_path())
    kw = dict(image_width=512, image_height=512, fov=cal.fov, rig=cal.rig, tables=cal.tables, K=cal.K)
    assert Calibration(**kw, dist=np.array([-0.3, 0.0, 0.0, 0.0, 0.0])).dist[0] == -0.3
    with pytest.raises(ValueError, match="folds the image"):
        Calibration(**kw, dist=np.array([-0.6, 0.0, 0.0, 0.0, 0.0]))


def test_array_and_key_helpers_take_the_name_first() -> None:
    a = check_real_array("x", [[1, 2.5]], (None, 2), "m", low=0.0, high=3.0)
    assert a.dtype == np.float64 and a.tolist() == [[1.0, 2.5]]
    with pytest.raises(ValueError, match=r"x\[0, 1\] must be in \[0, 2\] \(m\)"):
        check_real_array("x", [[1, 2.5]], (None, 2), "m", low=0.0, high=2.0)
    with pytest.raises(ValueError, match=r"x\[0, 0\]"):
        check_real_array("x", [[HUGE, 1]], (1, 2))
    with pytest.raises(ValueError, match="nested too deeply"):
        check_real_array("x", [[[[[[[[[[[1.0]]]]]]]]]]], (1,))
    with pytest.raises(TypeError, match="x must contain only numbers"):
        check_real_array("x", [1, True], (2,))
    assert check_keys("o", {"a": 1}, ("a",), ("b",)) == {"a": 1}
    with pytest.raises(ValueError, match=r"o: unknown key\(s\) \['c'\]"):
        check_keys("o", {"a": 1, "c": 2}, ("a",), ("b",))
    assert math.isfinite(float(a.sum()))
