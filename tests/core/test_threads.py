"""Worker processes get one BLAS thread each unless the user chose otherwise."""

from __future__ import annotations

import multiprocessing as mp
import os

import pytest

from ihrcf_env.core.threads import THREAD_VARIABLES, limit_blas_threads, one_blas_thread


def _report(queue: mp.Queue) -> None:  # type: ignore[type-arg]
    queue.put({v: os.environ.get(v) for v in THREAD_VARIABLES})


def test_processes_started_inside_run_one_thread_and_the_variables_are_restored(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    for v in THREAD_VARIABLES:
        monkeypatch.delenv(v, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")  # the user's choice is kept
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=_report, args=(queue,))
    with one_blas_thread():
        assert os.environ["OPENBLAS_NUM_THREADS"] == "1"
        proc.start()
    seen = queue.get(timeout=60)
    proc.join(timeout=60)
    assert seen == {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "3"}
    assert "OPENBLAS_NUM_THREADS" not in os.environ and "OMP_NUM_THREADS" not in os.environ
    assert os.environ["MKL_NUM_THREADS"] == "3"


def test_the_variables_are_removed_after_an_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    with pytest.raises(RuntimeError), one_blas_thread():
        raise RuntimeError("boom")
    assert "OPENBLAS_NUM_THREADS" not in os.environ


def test_limit_blas_threads_limits_the_loaded_libraries() -> None:
    from threadpoolctl import threadpool_info, threadpool_limits

    with threadpool_limits(limits=None):  # restored at the end
        limit_blas_threads(1)
        assert threadpool_info() and all(p["num_threads"] == 1 for p in threadpool_info())
