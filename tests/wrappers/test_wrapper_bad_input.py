"""Bad input to the estimator wrapper and in the calibration file: errors that name what is wrong,
and no PyBullet client left behind by a failed construction."""

from __future__ import annotations

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest
from conftest import calibration_fields

import ihrcf_env  # noqa: F401  (registers the envs)
from ihrcf_env.core.calibration import Calibration, CalibrationError, default_calibration_path
from ihrcf_env.envs import deck_landing
from ihrcf_env.envs.deck_landing import DeckLandingEnv
from ihrcf_env.wrappers.estimates import DeckPoseObservation

HOVER_ID = "ihrcf_env/DeckHover-v0"


@pytest.fixture
def built_envs(monkeypatch: pytest.MonkeyPatch) -> list[DeckLandingEnv]:
    """Every DeckLandingEnv constructed during the test (to check that none is left connected)."""
    envs: list[DeckLandingEnv] = []
    original = deck_landing.DeckLandingEnv.__init__

    def spy(self: DeckLandingEnv, *args: object, **kwargs: object) -> None:
        envs.append(self)
        original(self, *args, **kwargs)

    monkeypatch.setattr(deck_landing.DeckLandingEnv, "__init__", spy)
    return envs


def _assert_all_closed(envs: list[DeckLandingEnv]) -> None:
    for env in envs:
        assert not p.isConnected(physicsClientId=env.world.client), "a failed make left a PyBullet client"


# ------------------------------------------------------------------------------ wrapper options


@pytest.mark.parametrize("bad", ["0.01", True, np.bool_(True), None, [0.01], b"0.01"])
def test_max_residual_of_wrong_type_is_named(bad, built_envs):
    with pytest.raises(TypeError, match="max_residual must be a real number"):
        gym.make(HOVER_ID, max_residual=bad)
    assert built_envs == []  # checked before the env is built


@pytest.mark.parametrize("bad", [0, -0.01, math.nan, math.inf])
def test_max_residual_out_of_range_is_named(bad, built_envs):
    with pytest.raises(ValueError, match="max_residual must be in"):
        gym.make(HOVER_ID, max_residual=bad)
    assert built_envs == []


def test_max_residual_accepts_numpy_and_int_numbers():
    for good in (np.float32(0.02), 1):
        env = gym.make(HOVER_ID, max_residual=good, keep_image=False)
        try:
            assert env.get_wrapper_attr("estimator").config.max_residual == float(good)
        finally:
            env.close()


@pytest.mark.parametrize("bad", [123, 1.5, b"calibration.json", ["calibration.json"], {"K": 1}])
def test_calibration_of_wrong_type_is_named(bad, built_envs):
    with pytest.raises(TypeError, match="calibration must be a Calibration, a path"):
        gym.make(HOVER_ID, calibration=bad)
    assert built_envs == []


@pytest.mark.parametrize("option", ["keep_image", "flatten", "raw"])
@pytest.mark.parametrize("bad", ["yes", "False", 1, 0, None])
def test_bool_options_reject_non_bools(option, bad, built_envs):
    if option == "keep_image" and bad is None:
        return  # None is keep_image's default: keep the image if the env delivers one
    with pytest.raises(TypeError, match=f"{option} must be True or False"):
        gym.make(HOVER_ID, **{option: bad})
    assert built_envs == []


def test_unknown_estimator_name_is_named(built_envs):
    with pytest.raises(ValueError, match="estimators: unknown name 'kalman'"):
        gym.make(HOVER_ID, estimators=("ihrcf", "kalman"))
    with pytest.raises(ValueError, match="reserved"):
        gym.make(HOVER_ID, estimators=("ihrcf", "ground_truth"))
    with pytest.raises(TypeError, match="estimators must be a sequence of names"):
        gym.make(HOVER_ID, estimators="ihrcf")
    assert built_envs == []


def test_wrapper_built_directly_checks_options_and_leaves_the_env_to_its_owner():
    env = DeckLandingEnv(deck_profile="static")
    try:
        with pytest.raises(TypeError, match="calibration"):
            DeckPoseObservation(env, calibration=123)
        with pytest.raises(TypeError, match="flatten"):
            DeckPoseObservation(env, flatten="yes")
        with pytest.raises(TypeError, match="max_residual"):
            DeckPoseObservation(env, max_residual="0.01")
        env.reset(seed=0)  # still usable: the caller made it, the caller closes it
    finally:
        env.close()


# ------------------------------------------------------------------------------ no leak on failure


def test_calibration_is_matched_to_the_camera_before_the_env_is_built(built_envs):
    with pytest.raises(CalibrationError, match="does not match"):
        gym.make(HOVER_ID, camera_fov=math.radians(50.0))
    with pytest.raises(ValueError, match="raw=True"):
        gym.make(HOVER_ID, camera=False)
    assert built_envs == []


def test_bad_calibration_file_is_read_before_the_env_is_built(tmp_path, built_envs):
    bad = _mutated_file(tmp_path, "fov", None)
    with pytest.raises(CalibrationError, match="fov"):
        gym.make(HOVER_ID, calibration=bad)
    assert built_envs == []


# ------------------------------------------------------------------------------ calibration file


def _mutated_file(tmp_path: Path, key: str, value: object) -> Path:
    """The shipped calibration file with ``d[key] = value`` (dots: nested keys), written to tmp_path."""
    d = json.loads(default_calibration_path().read_text())
    *parents, last = key.split(".")
    node = d
    for k in parents:
        node = node[k]
    node[last] = value
    path = tmp_path / "mutated_calibration.json"
    path.write_text(json.dumps(d))
    return path


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("fov", None, "fov must be a real number"),
        ("lens_distortion", 5, "lens_distortion must be an array of numbers"),
        ("image_width", 512.7, "image_width must be an integer"),
    ],
)
def test_calibration_file_issue_cases_name_file_and_field(tmp_path, key, value, match):
    bad = _mutated_file(tmp_path, key, value)
    with pytest.raises(CalibrationError, match=match) as ei:
        gym.make(HOVER_ID, calibration=bad)
    assert str(bad) in str(ei.value)


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("image_width", 512.0, "image_width must be an integer"),
        ("image_height", True, "image_height must be an integer, got a bool"),
        ("image_height", "512", "image_height must be an integer, got a str"),
        ("image_width", 0, r"image_width must be an integer in \[1, 32768\]"),
        ("fov", "1.047", "fov must be a real number"),
        ("fov", False, "fov must be a real number"),
        ("fov", 4.0, r"fov must be in \(0, pi\)"),
        ("lens_distortion", [0.0], r"lens_distortion must have shape \(2,\)"),
        ("lens_distortion", [0.0, None], "lens_distortion must contain only numbers"),
        ("lens_distortion", [0.0, True], "lens_distortion must contain only numbers"),
        ("K", [[1, 0], [0, 1]], r"K must have shape \(3, 3\)"),
        ("K", "eye", "K must be an array of numbers"),
        ("K", [[443, 0, 256], [0, 443, 256], [0, 0, 2]], "K must be a camera matrix"),
        ("dist", [0, 0, 0, 0], r"dist must have shape \(5,\)"),
        ("dist", [0, 0, 0, 0, "0"], "dist must contain only numbers"),
        ("dist", [[0, 0], [0, 0, 0]], "dist must be an array with shape"),
        ("chessboard_rms", "0.2", "chessboard_rms must be a real number"),
        ("chessboard_rms", -0.1, r"chessboard_rms must be in \[0, 100\]"),
        ("seed", 1.5, "seed must be an integer"),
        ("seed", -1, r"seed must be an integer in \[0, "),
        ("created_with", 3, "created_with must be a string"),
        ("report", [], "report must be an object"),
        ("format_version", True, "unsupported format_version"),
        ("format_version", 1.0, "unsupported format_version"),
        ("rig", [0.1, 0.78], "rig must be an object"),
        ("rig.a", None, "rig.a must be a real number"),
        ("rig.theta", "0.78", "rig.theta must be a real number"),
        ("rig.camera_position", [0, 0], r"rig.camera_position must have shape \(3,\)"),
        ("rig.camera_position", [0, 0, None], "rig.camera_position must contain only numbers"),
        ("rig.height", 0.1, r"rig: unknown key\(s\) \['height'\]"),
        ("rig.a", -0.1, "rig: a must be a positive distance"),
        ("lens_distorsion", [0, 0], r"unknown key\(s\) \['lens_distorsion'\]"),
        ("tables", [], "tables must be an object"),
        ("tables.ps5", {}, r"tables: unknown key\(s\) \['ps5'\]"),
        ("tables.ps2", None, "tables.ps2 must be an object"),
        ("tables.ps2.ranges", "1.0", r"tables.ps2.ranges must be an array of numbers with shape \(N,\)"),
        ("tables.ps3.pixels", [[1, None]] * 4, "tables.ps3.pixels must contain only numbers"),
        ("tables.ps3.pixels", [[1, 2, 3]] * 4, r"tables.ps3.pixels must have shape \(N, 2\)"),
        ("tables.ps4.name", 4, "tables.ps4.name must be a string"),
        ("tables.ps1.ranges", [0.0, 0.5, 1.0, 1.5], "tables.ps1.ranges must be positive"),
    ],
)
def test_every_calibration_field_is_type_checked(tmp_path, key, value, match):
    bad = _mutated_file(tmp_path, key, value)
    with pytest.raises(CalibrationError, match=match) as ei:
        Calibration.load(bad)
    assert str(bad) in str(ei.value)


def test_numbers_of_either_json_kind_are_accepted_where_a_float_belongs(tmp_path):
    d = json.loads(default_calibration_path().read_text())
    d["chessboard_rms"] = 0  # an integer in a float field is a number
    d["rig"]["camera_position"] = [0, 0, -0.03]
    path = tmp_path / "ints.json"
    path.write_text(json.dumps(d))
    cal = Calibration.load(path)
    assert cal.chessboard_rms == 0.0 and isinstance(cal.chessboard_rms, float)
    assert cal.rig["camera_position"] == [0.0, 0.0, -0.03]
    assert isinstance(cal.image_width, int) and cal.image_width == 512


def test_calibration_constructor_checks_types_too():
    cal = Calibration.load(default_calibration_path())
    kw = calibration_fields(cal)
    assert Calibration(**{**kw, "image_width": np.int64(512)}).image_width == 512
    with pytest.raises(TypeError, match="image_width must be an integer"):
        Calibration(**{**kw, "image_width": 512.7})
    with pytest.raises(TypeError, match="tables must be a RangePixelTable"):
        Calibration(**{**kw, "tables": cal.tables.to_dict()})
    with pytest.raises(TypeError, match="K must be an array of numbers"):
        Calibration(**{**kw, "K": np.eye(3, dtype=bool)})
    with pytest.raises(ValueError, match="K must be finite"):
        Calibration(**{**kw, "K": np.full((3, 3), np.nan)})
