"""The backend-neutral config package: make_config's parts, the task and level it records, the
observation resolved once, and the checks of the resolved config."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import pytest

import ihrcf_env
from ihrcf_env.config import (
    DeckLandingConfig,
    ObservationConfig,
    fused_params_for_tof,
    make_config,
    resolve_observation,
)
from ihrcf_env.config.make import TASK_DEFAULTS
from ihrcf_env.config.sensors import VL53L1X
from ihrcf_env.core.calibration import Calibration, default_calibration_path
from ihrcf_env.core.estimators import FusedParams


@pytest.mark.parametrize(
    ("task", "level", "recorded"),
    [
        ("hover", None, None),
        ("landing-v1", None, None),
        ("landing-v2", None, "moderate"),
        ("landing-v2", "rough", "rough"),
    ],
)
def test_the_config_records_its_task_and_level(task: str, level: str | None, recorded: str | None) -> None:
    cfg = make_config(task=task, level=level, camera_model="projected")
    assert cfg.task_name == task
    assert cfg.level == recorded


def test_the_package_root_make_config_is_the_config_package_s() -> None:
    a = ihrcf_env.make_config(task="landing-v2", camera_model="projected")
    b = make_config(task="landing-v2", camera_model="projected")
    assert a == b


def test_a_level_shapes_the_world_and_the_task() -> None:
    calm = make_config(task="landing-v2", level="calm", camera_model="projected")
    rough = make_config(task="landing-v2", level="rough", camera_model="projected")
    assert calm.world.faults == ()
    assert {name for name, _ in rough.world.faults} == {"camera_dropout", "tof_dead"}
    assert calm.wind is not None and rough.wind is not None
    assert calm.wind.mean_speed_max < rough.wind.mean_speed_min
    assert calm.task.deck.profile == rough.task.deck.profile == "ship"
    assert calm.task.deck.ship != rough.task.deck.ship


def test_the_resolved_config_checks_its_task_name_and_level() -> None:
    cfg = make_config(task="landing-v2", camera_model="projected")
    with pytest.raises(ValueError, match="task_name"):
        dataclasses.replace(cfg, task_name="landing-v9")
    with pytest.raises(ValueError, match="level"):
        dataclasses.replace(cfg, level="stormy")
    with pytest.raises(ValueError, match="level"):
        make_config(task="hover", level="calm")


@pytest.mark.parametrize("task", sorted(TASK_DEFAULTS))
def test_the_observation_part_is_resolved_for_the_task(task: str) -> None:
    cfg = make_config(task=task, camera_model="projected")
    obs = cfg.observation
    assert isinstance(obs.calibration, Calibration)
    assert obs.fused_params == fused_params_for_tof(cfg.world.tof.model, task)
    assert obs.fused_params is not None and obs.fused_params.reseed_agreeing == (task == "landing-v2")


def test_a_raw_config_has_no_observation_to_resolve() -> None:
    cfg = make_config(task="landing-v2", camera_model="projected", raw=True)
    assert cfg.observation == ObservationConfig(raw=True)


def test_given_fused_params_are_kept() -> None:
    mine = FusedParams(range_offset_sigma=0.004)
    cfg = make_config(task="landing-v2", camera_model="projected", fused_params=mine)
    assert cfg.observation.fused_params is mine


def test_resolve_observation_matches_make_config_and_reads_a_given_calibration_as_is() -> None:
    cfg = make_config(task="landing-v1", camera_model="projected", deck_motion=True)
    cal = Calibration.load(default_calibration_path())
    obs = resolve_observation(cfg.world, "landing-v1", calibration=cal, deck_motion=True)
    assert obs == cfg.observation
    assert obs.calibration is cal


def test_resolve_observation_names_a_bad_option_and_needs_a_camera() -> None:
    cfg = make_config(task="landing-v1", camera_model="projected")
    with pytest.raises(ValueError, match="max_residual"):
        resolve_observation(cfg.world, "landing-v1", max_residual=-1.0)
    with pytest.raises(TypeError, match="calibration"):
        resolve_observation(cfg.world, "landing-v1", calibration=3)
    no_camera = dataclasses.replace(cfg.world, camera=None)
    with pytest.raises(ValueError, match="camera=False"):
        resolve_observation(no_camera, "landing-v1")


def test_fused_params_follow_the_tof_model_and_the_task() -> None:
    assert fused_params_for_tof(None).range_offset_sigma == 0.0
    model = VL53L1X(offset_sigma=0.004)
    assert fused_params_for_tof(model).range_offset_sigma == pytest.approx(0.002)
    assert not fused_params_for_tof(model, "landing-v1").reseed_agreeing
    assert fused_params_for_tof(model, "landing-v2").reseed_agreeing


def test_importing_the_config_package_loads_no_simulator() -> None:
    code = (
        "import sys, ihrcf_env.config as c\n"
        "print('pybullet' in sys.modules, 'ihrcf_env.sim' in sys.modules, 'ihrcf_env.envs' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False", "False"]


def test_the_config_is_a_frozen_value() -> None:
    cfg = make_config(task="hover", camera_model="projected")
    assert isinstance(cfg, DeckLandingConfig)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.task_name = "landing-v1"  # type: ignore[misc]


#: The refusal of the removed ``physics`` option: it names the option and the batched path.
PHYSICS_REMOVED = r'physics: .*numpy batched physics were removed.*gym\.make_vec\(.*backend="jax"\)'


@pytest.mark.parametrize("value", ["numpy", "pybullet", None, 1])
@pytest.mark.parametrize("task", ["hover", "landing-v1", "landing-v2"])
def test_the_removed_physics_option_is_refused_by_name(task: str, value: object) -> None:
    """Any value of ``physics`` is a ValueError naming it and the JAX backend."""
    with pytest.raises(ValueError, match=PHYSICS_REMOVED):
        make_config(task=task, physics=value)
    assert not any(f.name == "physics" for f in dataclasses.fields(make_config(task=task).world))
