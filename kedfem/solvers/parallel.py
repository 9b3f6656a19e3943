"""Parallel runs over the time elements: contiguous parts in kedfem's worker threads.

:func:`_split` cuts ``L`` elements into contiguous parts, one per worker; :func:`_run_parallel`
runs a function on every part in a shared thread pool, with BLAS limited to one thread meanwhile
(:mod:`kedfem.solvers.threads`); :func:`default_workers` is the default number of workers.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .threads import one_blas_thread


def _split(L: int, workers: int, min_part: int = 8) -> list[tuple[int, int]]:
    w = max(1, min(workers, L // min_part))
    edges = np.linspace(0, L, w + 1).round().astype(int)
    return [(int(edges[i]), int(edges[i + 1])) for i in range(w)]


_POOL = None


def _run_parallel(work, parts):
    """Run work(i, lo, hi) for every part; in threads when there are several."""
    global _POOL
    if len(parts) == 1:
        work(0, *parts[0])
        return
    if _POOL is None or _POOL._max_workers < len(parts):
        _POOL = ThreadPoolExecutor(max_workers=len(parts), thread_name_prefix="kedfem")
    with one_blas_thread():
        futures = [_POOL.submit(work, i, lo, hi) for i, (lo, hi) in enumerate(parts)]
        for fut in futures:
            fut.result()


def default_workers() -> int:
    """Number of threads for the element computations (usable CPUs, at most 8)."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        cpus = os.cpu_count() or 1
    return max(1, min(8, cpus))
