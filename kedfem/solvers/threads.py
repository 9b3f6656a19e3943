"""BLAS thread policy of kedfem, in one place.

kedfem's linear algebra works on many small matrices (state size ``2N`` up to
a few hundred): batched exponentials, products of transitions, small solves.
OpenBLAS's own threads do not pay on such matrices and, on a shared machine,
wait for a time slice on every call: measured 2-60x slower than one thread
whenever the other cores were busy (``benchmarks/peers.py``). kedfem therefore
runs its solvers with BLAS limited to one thread and gets its parallelism from
its own worker threads, one BLAS thread each (see
:func:`kedfem.solvers.periodic.solve`'s ``workers``).

The limit is set with threadpoolctl. Without it (an optional dependency here)
the contexts do nothing and BLAS keeps its configured threads.

Examples
--------
>>> from kedfem.solvers.threads import one_blas_thread
>>> with one_blas_thread():
...     pass  # numpy / scipy calls here run BLAS on one thread
"""

from __future__ import annotations

import contextlib
import logging
import os
from typing import Iterator

__all__ = ["one_blas_thread", "blas_threads", "pin_process", "thread_count"]

#: threadpoolctl's controller of the loaded BLAS libraries, made on first use
#: (it inspects the process's shared libraries, about a millisecond);
#: ``False`` when threadpoolctl cannot be imported.
_CONTROLLER = None

log = logging.getLogger(__name__)


def _controller():
    """The cached ``threadpoolctl.ThreadpoolController``, or ``False`` without threadpoolctl."""
    global _CONTROLLER
    if _CONTROLLER is None:
        try:
            from threadpoolctl import ThreadpoolController
            _CONTROLLER = ThreadpoolController()
        except Exception:  # pragma: no cover - optional dependency
            _CONTROLLER = False
    return _CONTROLLER


@contextlib.contextmanager
def blas_threads(n: int) -> Iterator[None]:
    """Context in which the BLAS libraries of the process use at most ``n`` threads.

    The limit applies to the whole process (BLAS thread pools are global), is
    set on entering the ``with`` block and the previous limits are restored on
    leaving it, also on an exception. Nested contexts restore in turn. A no-op
    when threadpoolctl is not installed.

    Parameters
    ----------
    n : int
        Largest number of BLAS threads, >= 1.

    Yields
    ------
    None
    """
    controller = _controller()
    if controller is False:
        yield
        return
    limiter = controller.limit(limits=n, user_api="blas")
    try:
        yield
    finally:
        limiter.restore_original_limits()


def one_blas_thread() -> contextlib.AbstractContextManager[None]:
    """Context in which BLAS runs on one thread: kedfem's policy for its solvers.

    ``with one_blas_thread(): ...`` is ``blas_threads(1)``; see the module
    docstring for why, and :func:`blas_threads` for the semantics.

    Returns
    -------
    context manager
    """
    return blas_threads(1)


# ------------------------------------------------ worker processes (sweeps)
_BLAS_ENV = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
             "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
_PINNED: list = []


def pin_process() -> None:
    """Limit this process's BLAS/OpenMP thread pools to one thread (idempotent).

    Sets the usual environment variables (inherited by any process started
    later) and, since the libraries are already loaded, limits them at run
    time with threadpoolctl when it is installed.
    """
    if _PINNED:
        return
    for k in _BLAS_ENV:
        os.environ[k] = "1"
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        log.warning("threadpoolctl is not installed: BLAS threads of an already loaded library stay unpinned")
        _PINNED.append(None)
        return
    _PINNED.append(threadpool_limits(limits=1))  # kept alive: the limits hold until restored


def thread_count() -> int:
    """Largest thread count of the BLAS/OpenMP pools loaded in this process (threadpoolctl)."""
    try:
        from threadpoolctl import threadpool_info
    except ImportError:  # pragma: no cover
        return -1
    return max((int(i.get("num_threads", 1)) for i in threadpool_info()), default=1)
