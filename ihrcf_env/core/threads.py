"""BLAS threads of worker processes.

NumPy's BLAS (OpenBLAS in the PyPI wheels) starts one thread per core in every process. Several
processes on the same cores, each stepping small arrays, then spend more time handing work between
their threads than doing it. The worker processes of this package (:class:`WorkerVectorEnv
<ihrcf_env.vector.workers.WorkerVectorEnv>`, the DAgger flyers, the benchmarks) are
started inside :func:`one_blas_thread`, so each runs one BLAS / OpenMP thread: the variables below,
read by those libraries when a process loads them, unless the user has set them.
:func:`limit_blas_threads` does the same for the libraries already loaded in this process.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

#: The environment variables of the thread pools of OpenBLAS, OpenMP and MKL.
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Processes started inside this block run one BLAS / OpenMP thread each (the variables of
    :data:`THREAD_VARIABLES` the user has not set are set to 1 meanwhile, then removed)."""
    added = [v for v in THREAD_VARIABLES if v not in os.environ]
    for v in added:
        os.environ[v] = "1"
    try:
        yield
    finally:
        for v in added:
            os.environ.pop(v, None)


def limit_blas_threads(n: int = 1) -> None:
    """Limit the BLAS / OpenMP libraries loaded in this process to ``n`` threads (for the rest of
    the process)."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=n)


__all__ = [
    "THREAD_VARIABLES",
    "limit_blas_threads",
    "one_blas_thread",
]
