"""One contract for both backends: the JAX vector env's ``reset`` and ``step`` ``info`` has the
PyBullet vector env's keys, dtypes, masks and units, and on a paired seed its values (the truth,
the time, the reward's deterministic terms, the outcome, the reasons before the first frame).

Every landing id runs on both backends (the hover ids have no JAX backend: refused by name). The
keys one backend cannot give are listed in docs/jax-backend.md ("Keys only one backend gives");
the test checks that list against the actual difference. The JAX envs compile for minutes each,
so one env per id is shared by the module's tests (slow).
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

jax = pytest.importorskip("jax")

import ihrcf_env  # noqa: E402

LANDING_IDS = (ihrcf_env.LANDING_V1_ID, ihrcf_env.LANDING_V2_ID)
HOVER_IDS = tuple(i for i in ihrcf_env.ENV_IDS if i not in LANDING_IDS)
N = 2
SEED = 21
#: The PyBullet env in the JAX backend's configuration (its one camera).
PYBULLET = {"camera_model": "projected", "camera_output": "corners"}
DOC = Path(__file__).resolve().parents[2] / "docs" / "jax-backend.md"
#: Descend at full speed (both backends end an episode within a few seconds).
DOWN = np.tile(np.array([0.0, 0.0, -1.0, 0.0]), (N, 1))


def _make(env_id: str, backend: str) -> gym.vector.VectorEnv:
    options: dict[str, Any] = {"backend": "jax"} if backend == "jax" else dict(PYBULLET)
    return gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", **options)


def _run(env: gym.vector.VectorEnv) -> dict[str, Any]:
    """The reset info, the first step's, the step where an env first ended and the next one."""
    out: dict[str, Any] = {}
    _, out["reset"] = env.reset(seed=SEED)
    _, _, _, _, out["step"] = env.step(np.zeros((N, 4)))
    for _ in range(400):
        _, _, term, trunc, info = env.step(DOWN)
        if (term | trunc).any():
            out["ended"], out["ended_rows"] = info, term | trunc
            _, _, _, _, out["after"] = env.step(DOWN)
            break
    # a masked reset and a later full reset (the JAX env: the same compiled reset as the first)
    env.reset(options={"reset_mask": np.array([False, True])})
    env.reset(seed=SEED + 1)
    out["reset_traces"] = getattr(env, "reset_traces", None)
    return out


@pytest.fixture(scope="module", params=LANDING_IDS)
def runs(request: pytest.FixtureRequest) -> dict[str, dict[str, Any]]:
    """Both backends' infos over the same paired seed (one compiled JAX env per id)."""
    out = {}
    for backend in ("pybullet", "jax"):
        env = _make(request.param, backend)
        try:
            out[backend] = _run(env)
        finally:
            env.close()
    return out


def _keys(info: dict[str, Any]) -> set[str]:
    return {k for k in info if not k.startswith("_")}


def _documented() -> dict[str, set[str]]:
    """The keys docs/jax-backend.md lists as given by one backend only (backend -> keys)."""
    text = DOC.read_text()
    section = text.split("### Keys only one backend gives", 1)[1].split("\n#", 1)[0]
    out: dict[str, set[str]] = {"pybullet": set(), "jax": set()}
    for line in section.splitlines():
        m = re.match(r"\|\s*`([^`]+)`\s*\|\s*(pybullet|jax) only\s*\|", line)
        if m:
            out[m.group(2)].add(m.group(1))
    return out


def _dtypes(info: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out = {}
    for key, value in info.items():
        if isinstance(value, dict):
            out.update(_dtypes(value, f"{prefix}{key}."))
        else:
            out[prefix + key] = (np.asarray(value).dtype, np.asarray(value).shape)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("stage", ["reset", "step", "ended", "after"])
def test_the_same_keys_as_documented(runs: dict[str, dict[str, Any]], stage: str) -> None:
    pb, jx = runs["pybullet"][stage], runs["jax"][stage]
    documented = _documented()
    assert _keys(pb) - _keys(jx) == documented["pybullet"] & _keys(pb)
    assert _keys(jx) - _keys(pb) == documented["jax"] & _keys(jx)
    if stage == "reset":
        assert len(_keys(pb)) >= 27


@pytest.mark.slow
@pytest.mark.parametrize("stage", ["reset", "step", "ended", "after"])
def test_the_same_dtypes_shapes_and_masks(runs: dict[str, dict[str, Any]], stage: str) -> None:
    pb, jx = _dtypes(runs["pybullet"][stage]), _dtypes(runs["jax"][stage])
    for key in set(pb) & set(jx):
        assert pb[key] == jx[key], key
    if stage in ("reset", "step"):  # the masks (which envs have a key) agree while no env ended
        for key in set(pb) & set(jx):
            if key.split(".")[-1].startswith("_"):
                np.testing.assert_array_equal(
                    runs["pybullet"][stage][key] if "." not in key else _nested(runs["pybullet"][stage], key),
                    runs["jax"][stage][key] if "." not in key else _nested(runs["jax"][stage], key),
                    err_msg=key,
                )


def _nested(info: dict[str, Any], dotted: str) -> Any:
    for part in dotted.split("."):
        info = info[part]
    return info


@pytest.mark.slow
def test_the_outcome_is_a_string_on_both(runs: dict[str, dict[str, Any]]) -> None:
    for backend in ("pybullet", "jax"):
        info = runs[backend]["ended"]
        rows = runs[backend]["ended_rows"]
        assert info["outcome"].dtype == object
        assert set(info["outcome"][rows]) <= {"success", "crash"}
        np.testing.assert_array_equal(info["is_success"][rows], info["outcome"][rows] == "success")
        crashed = rows & (info["outcome"] == "crash")
        assert all(isinstance(t, str) and t for t in info["crash_reason"][crashed])
        # the row that ended shows its next episode's reset info in the following step
        after = runs[backend]["after"]
        assert after["_time"][rows].all() and not after["_outcome"][rows].any()
        assert (after["time"][rows] == 0.0).all()


#: Values equal on a paired seed (same start, deck motion and wind; the sensor noise differs):
#: key -> absolute tolerance at the reset and after one step (m, rad, m/s, s).
PAIRED = {
    "time": (0.0, 1e-12),
    "drone_position_world": (1e-6, 2e-3),
    "drone_quaternion_world": (1e-6, 2e-3),
    "deck_position_world": (1e-6, 1e-6),
    "deck_quaternion_world": (1e-6, 1e-6),
    "deck_position_body": (1e-6, 1e-2),
    "deck_euler_body": (1e-6, 5e-3),
    "deck_rotation_body": (1e-6, 5e-3),
    "leg_lengths": (1e-6, 1e-6),
    "wind_velocity": (1e-6, 1e-6),
    "relative_velocity": (1e-4, 5e-2),
    "tag_offset": (1e-6, 2e-3),
    "contact_deck": (0, 0),
    "contact_ground": (0, 0),
    "is_success": (0, 0),
    "reward_time": (None, 1e-12),
    "reward_action": (None, 1e-12),
    "reward_progress": (None, 2e-2),
    "reward_terminal": (None, 0.0),
    "outcome": (None, 0),
    "crash_reason": (None, 0),
}


@pytest.mark.slow
@pytest.mark.parametrize("stage", ["reset", "step"])
def test_paired_values(runs: dict[str, dict[str, Any]], stage: str) -> None:
    pb, jx = runs["pybullet"][stage], runs["jax"][stage]
    wrong = []
    for key, tolerances in PAIRED.items():
        tol = tolerances[0 if stage == "reset" else 1]
        if tol is None:
            continue
        a, b = pb[key], jx[key]
        if a.dtype.kind == "f":
            gap = float(np.max(np.abs(b - a)))
            if not gap <= tol:
                wrong.append(f"{key}: {gap:.3g} > {tol:g}")
        elif not np.array_equal(b, a):
            wrong.append(f"{key}: {b.tolist()} != {a.tolist()}")
    assert not wrong, wrong
    if stage == "reset":  # no frame yet on either (or the same reading of the first)
        for key in [k for k in pb if k.endswith("_reason") and not k.startswith("_")]:
            np.testing.assert_array_equal(jx[key], pb[key], err_msg=key)
        np.testing.assert_allclose(jx["camera_time"], pb["camera_time"], atol=1e-12, err_msg="camera_time")


@pytest.mark.parametrize("env_id", HOVER_IDS)
def test_the_hover_ids_have_no_jax_backend(env_id: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the deprecated aliases warn
        with pytest.raises(gym.error.Error, match="vector entry point"):
            gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", backend="jax")


@pytest.mark.slow
def test_every_reset_of_the_jax_env_compiles_once(runs: dict[str, dict[str, Any]]) -> None:
    """The first reset, an autoreset, a masked reset and a full reset: one traced (compiled) reset."""
    assert runs["jax"]["reset_traces"] == 1


@pytest.mark.parametrize(
    ("env_id", "dtype"), [(i, "float64") for i in LANDING_IDS] + [(ihrcf_env.LANDING_V2_ID, "float32")]
)
def test_the_info_keys_and_dtypes_without_compiling(env_id: str, dtype: str) -> None:
    """The JAX env's info columns from the traced shapes of its reset and step (nothing compiled):
    the PyBullet env's keys and dtypes at a reset and at a step without touchdown, in either
    ``dtype`` of the computation."""
    from ihrcf_env.vector.jax_env import _scatter_info

    env = _make(env_id, "pybullet")
    try:
        _, pb_reset = env.reset(seed=SEED)
        pb_step = env.step(np.zeros((N, 4)))[4]
    finally:
        env.close()
    jenv = gym.make_vec(
        env_id, num_envs=N, vectorization_mode="vector_entry_point", backend="jax", dtype=dtype
    )
    fenv = jenv.fenv  # type: ignore[attr-defined]
    with jax.enable_x64(dtype == "float64"):
        episode = fenv.draw_host(np.random.default_rng(0))[1]
        key = jax.random.PRNGKey(0)
        shapes = jax.eval_shape(lambda e: fenv.reset_from_info(e, key, ()), episode)
        step = jax.eval_shape(lambda s: fenv.step(key, s, jax.numpy.zeros(4), ()), shapes[1])
    rows = np.arange(N)

    def columns(info: Any) -> dict[str, Any]:
        zeros = jax.tree_util.tree_map(lambda a: np.zeros((N, *a.shape), a.dtype), info)
        return _scatter_info(N, (rows, fenv.host_info(zeros)))

    documented = _documented()
    for pb, jx in ((pb_reset, columns(shapes[2])), (pb_step, columns(step[4]))):
        assert _keys(pb) - _keys(jx) == documented["pybullet"] & _keys(pb)
        assert _keys(jx) - _keys(pb) == documented["jax"] & _keys(jx)
        a, b = _dtypes(pb), _dtypes(jx)
        assert {k: a[k] for k in set(a) & set(b)} == {k: b[k] for k in set(a) & set(b)}
