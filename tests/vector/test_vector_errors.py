"""The vector envs' errors: arguments checked whole before any env steps (the bad rows named), the
workers' options checked in the parent, every worker reply read before an error is raised, the
failing worker named, a vector env usable after an error of its input and closed (saying so)
after a worker stopped."""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import subprocess
import sys
import textwrap
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import ihrcf_env
from ihrcf_env.vector import DeckLandingVectorEnv, WorkerError, WorkerVectorEnv

V2 = ihrcf_env.LANDING_V2_ID
OPTIONS: dict[str, Any] = {"camera_model": "projected", "level": "calm"}
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def one_blas_thread() -> Iterator[None]:
    """This process's BLAS on one thread, as the workers' (the last bits of some BLAS products
    depend on the number of threads)."""
    with threadpool_limits(limits=1):
        yield


def _actions(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.uniform(-0.5, 0.5, (n, 4)).astype(np.float32)


# -- actions checked whole ----------------------------------------------------------------------
def test_a_bad_row_steps_no_env(closing: Callable[[Any], Any], make_env: Callable[..., gym.Env]) -> None:
    """A NaN in row 1 (or inf in rows 0 and 1) is refused naming the rows before any env steps, by
    step and step_masked: afterwards every env still equals its single env, bit for bit."""
    v = closing(gym.make_vec(V2, num_envs=2, **OPTIONS))
    singles = [make_env(V2, **OPTIONS) for _ in range(2)]
    v.reset(seed=3)
    for i, e in enumerate(singles):
        e.reset(seed=3 + i)
    rng = np.random.default_rng(0)
    for k in range(3):
        a = _actions(rng, 2)
        bad = a.copy()
        bad[1, 2] = np.nan
        with pytest.raises(ValueError, match=r"actions: row 1 .*NaN or inf.*no env was stepped"):
            v.step(bad)
        bad[0, 0] = np.inf
        with pytest.raises(ValueError, match=r"actions: rows \[0, 1\]"):
            v.step_masked(bad, np.array([True, False]))
        obs, reward, *_ = v.step(a)
        for i, e in enumerate(singles):
            o, r, *_ = e.step(a[i])
            np.testing.assert_array_equal(obs[i], o)
            assert reward[i] == r, (k, i)


def test_the_worker_env_checks_actions_before_any_worker_steps(
    closing: Callable[[Any], Any], one_blas_thread: None
) -> None:
    w = closing(gym.make_vec(V2, num_envs=3, workers=2, **OPTIONS))
    v = closing(gym.make_vec(V2, num_envs=3, **OPTIONS))
    np.testing.assert_array_equal(w.reset(seed=9)[0], v.reset(seed=9)[0])
    rng = np.random.default_rng(1)
    for _ in range(2):
        a = _actions(rng, 3)
        bad = a.copy()
        bad[2, 0] = np.nan  # a row of worker 1
        with pytest.raises(ValueError, match=r"actions: row 2 "):
            w.step(bad)
        with pytest.raises(ValueError, match=r"actions: row 2 "):
            w.step_masked(bad, np.array([True, False, False]))
        with pytest.raises(TypeError, match="actions"):
            w.step(np.full((3, 4), "x"))
        np.testing.assert_array_equal(w.step(a)[0], v.step(a)[0])


# -- the workers' options checked in the parent --------------------------------------------------
@pytest.mark.parametrize(
    "bad",
    [
        {"camera_model": "pinhole"},
        {"level": "stormy"},
        {"estimators": ("ihrcf", "no_such_estimator")},
        {"max_episode_steps": 0},
        {"autoreset_mode": "whenever"},
        {"batch_estimators": True},  # removed: refused by name
        {"render_mode": "rgb_array"},
    ],
)
def test_worker_options_raise_the_in_process_error_before_any_worker_starts(
    bad: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    options = {**OPTIONS, **bad}
    with pytest.raises((ValueError, TypeError)) as in_process:
        gym.make_vec(V2, num_envs=2, **options)

    def no_start(self: Any) -> None:
        raise AssertionError("a worker was started")

    monkeypatch.setattr(mp.get_context("spawn").Process, "start", no_start)
    with pytest.raises(type(in_process.value)) as workers:
        gym.make_vec(V2, num_envs=2, workers=2, **options)
    assert str(workers.value) == str(in_process.value)


@pytest.mark.parametrize(
    ("num_envs", "workers", "error", "text"),
    [
        (10**9, 2, ValueError, r"num_envs must be an integer in \[1, 2048\].*1000000000"),
        (0, 2, ValueError, "num_envs"),
        (2.0, 2, TypeError, "num_envs"),
        (2, 3, ValueError, r"workers must be an integer in \[1, num_envs = 2\]"),
    ],
)
def test_num_envs_is_named_with_its_own_value(num_envs: Any, workers: int, error: type, text: str) -> None:
    with pytest.raises(error, match=text):
        WorkerVectorEnv(V2, num_envs, workers, **OPTIONS)


# -- worker errors -------------------------------------------------------------------------------
def test_after_workers_fail_every_reply_is_read_and_a_reset_goes_on(
    closing: Callable[[Any], Any], one_blas_thread: None
) -> None:
    """A reset option every env refuses fails in both workers: the error names both (index, pid,
    env rows) with the env's own error as the cause; no reply is left unread, so the next reset
    and steps equal the in-process env's."""
    w = closing(gym.make_vec(V2, num_envs=3, workers=2, **OPTIONS))
    v = closing(gym.make_vec(V2, num_envs=3, **OPTIONS))
    w.reset(seed=1)
    with pytest.raises(WorkerError, match=r"worker 0 \(pid \d+, envs 0-1\) failed.*altitude") as e:
        w.reset(options={"altitude": -1.0})
    assert "worker 1 (pid" in str(e.value) and "env 2) failed" in str(e.value)
    assert "needs a full reset()" in str(e.value)
    assert isinstance(e.value.__cause__, ValueError)
    with pytest.raises(gym.error.ResetNeeded, match="reset"):
        w.step(np.zeros((3, 4), np.float32))
    np.testing.assert_array_equal(w.reset(seed=4)[0], v.reset(seed=4)[0])
    rng = np.random.default_rng(2)
    for _ in range(3):
        a = _actions(rng, 3)
        np.testing.assert_array_equal(w.step(a)[0], v.step(a)[0])


def test_a_killed_worker_is_named_and_the_env_closes_cleanly(closing: Callable[[Any], Any]) -> None:
    w = closing(gym.make_vec(V2, num_envs=3, workers=2, **OPTIONS))
    w.reset(seed=0)
    pid = w.pids[1]
    os.kill(pid, signal.SIGKILL)
    with pytest.raises(
        WorkerError, match=rf"worker 1 \(pid {pid}, env 2\) stopped.*the vector env is closed"
    ):
        w.step(np.zeros((3, 4), np.float32))
    with pytest.raises(RuntimeError, match="closed .*a worker process stopped"):
        w.reset(seed=0)
    w.close()
    w.close()
    assert w.pids == () and mp.active_children() == []


def _run_script(tmp_path: Path, code: str) -> subprocess.CompletedProcess[str]:
    script = tmp_path / "script.py"
    script.write_text(textwrap.dedent(code))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=300, env=env, cwd=tmp_path
    )


TOY = """
    import numpy as np
    import gymnasium as gym
    import ihrcf_env
    from ihrcf_env.core.estimators import PoseEstimate
    from ihrcf_env.vector import WorkerError

    class Toy:
        name = "toy"
        count = 0  # envs of this process

        def __init__(self, config):
            Toy.count += 1
            self.updates = 0

        def reset(self):
            self.updates = 0

        def update(self, frame):
            self.updates += 1
            if Toy.count > 1 and self.updates > 3:  # fails in a process of more than one env
                raise RuntimeError("toy estimator failed")
            return PoseEstimate.from_body_pose(np.eye(3), [0.0, 0.0, -1.0], 0.0)
"""


def test_a_worker_failing_alone_leaves_no_reply_unread(tmp_path: Path) -> None:
    """Worker 0 (two envs) fails at the third step, worker 1 steps: its reply is read before the
    error (naming worker 0 only) is raised, and the next reset returns fresh observations."""
    out = _run_script(
        tmp_path,
        TOY
        + """
    ihrcf_env.register_estimator("toy", Toy)

    if __name__ == "__main__":
        options = dict(camera_model="projected", level="calm", estimators=("ihrcf", "toy"))
        w = gym.make_vec("ihrcf_env/DeckLanding-v2", num_envs=3, workers=2, **options)
        first, _ = w.reset(seed=5)
        try:
            for _ in range(5):
                w.step(np.zeros((3, 4), np.float32))
        except WorkerError as e:
            assert "worker 0 (pid" in str(e) and "envs 0-1) failed" in str(e), str(e)
            assert "worker 1" not in str(e).splitlines()[0], str(e)
            assert "toy estimator failed" in str(e)
        else:
            raise AssertionError("no error")
        again, _ = w.reset(seed=5)
        np.testing.assert_array_equal(again, first)
        w.close()
        print("ok")
    """,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_an_estimator_registered_under_the_main_guard_is_named(tmp_path: Path) -> None:
    out = _run_script(
        tmp_path,
        TOY
        + """
    if __name__ == "__main__":
        ihrcf_env.register_estimator("toy", Toy)  # not run in the workers
        options = dict(camera_model="projected", estimators=("ihrcf", "toy"))
        gym.make_vec("ihrcf_env/DeckLanding-v2", num_envs=2, workers=2, **options)
    """,
    )
    assert out.returncode != 0
    err = out.stderr
    assert "WorkerError" in err and "worker 0 (pid" in err, err
    assert "estimator 'toy' registered in the main process but unknown in the worker processes" in err
    assert 'if __name__ == "__main__":' in err and "Register it at import time of a module" in err


def test_the_in_process_env_is_refused_the_same_bad_rows(closing: Callable[[Any], Any]) -> None:
    v = closing(DeckLandingVectorEnv(V2, 3, **OPTIONS))
    v.reset(seed=0)
    a = np.zeros((3, 4))
    a[[0, 2], 1] = -np.inf
    with pytest.raises(ValueError, match=r"rows \[0, 2\]"):
        v.step(a)


@pytest.mark.parametrize("n", [1, 3])
def test_a_seed_list_has_the_single_seeds_cap(n: int) -> None:
    """Every env's seed is at most MAX_SEED, given as one int (``s + i``) or as a list."""
    from ihrcf_env.vector.checks import MAX_SEED, env_seeds

    assert env_seeds(MAX_SEED + 1 - n, n)[-1] == MAX_SEED
    assert env_seeds([MAX_SEED] * n, n) == [MAX_SEED] * n
    with pytest.raises(ValueError, match="seed"):
        env_seeds(MAX_SEED + 2 - n, n)
    with pytest.raises(ValueError, match=r"seed\[0\]"):
        env_seeds([2**70] + [None] * (n - 1), n)
    with pytest.raises(ValueError, match=rf"seed\[{n - 1}\]"):
        env_seeds([0] * (n - 1) + [MAX_SEED + 1], n)
