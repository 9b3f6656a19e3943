"""Floating-point operation counts of the periodic solver, and this machine's matmul rate.

The lower bound of a solve's wall time is its flop count divided by the rate
the machine reaches on the operation that dominates it: batched dense matrix
products of the sizes the solve uses. :func:`periodic_flops` counts what
:func:`kedfem.solvers.periodic.solve` does for ``n`` time elements of an ``N``-DOF
system (time-varying stiffness; constant or sampled mass and damping), phase
by phase, with the matrix size of each phase; :func:`batched_matmul_rate`
measures the rate; :func:`time_bound` divides the two.

Conventions (Golub & Van Loan): a product of ``m x m`` matrices costs
``2 m**3``, a matrix-vector product ``2 m**2``, an LU factorization
``2/3 m**3``, a pair of triangular solves ``2 m**2`` per right-hand side, a
Cholesky factorization ``1/3 m**3``, an inverse ``2 m**3``, the eigenvalues of
a general matrix ``10 m**3`` and its singular values ``8/3 m**3``.
Elementwise passes (axpy, scaling, norms) are not counted: they are memory
bound, and their cost is part of what the measured time shows above the bound.

Exponentials (Taylor approximant, Paterson-Stockmeyer, the solver's default):
``products`` of :class:`kedfem.solvers.expm.ExpmInfo` plus the square ``B @ B`` that
the power-norm scaling always forms (for a Paterson-Stockmeyer block size of 1
it is not one of the ``products``), plus one product per squaring, each of
the augmented size ``2N + 1`` (zoh) or ``2N + 2`` (foh, magnus2). Pade adds
one LU and an ``m``-column solve per matrix.
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

__all__ = ["FlopCount", "batched_matmul_rate", "expm_flops", "matmul_flops", "periodic_flops",
           "time_bound"]

log = logging.getLogger(__name__)


def matmul_flops(m: int, k: int | None = None, p: int | None = None) -> float:
    """Flops of one product of an ``m x k`` and a ``k x p`` matrix: ``2 m k p``.

    Parameters
    ----------
    m : int
    k, p : int, optional
        Default ``m`` (square).

    Returns
    -------
    float
    """
    k = m if k is None else k
    p = m if p is None else p
    return 2.0 * m * k * p


def _ps_block(p: int) -> int:
    """Paterson-Stockmeyer block size kedfem.solvers.expm uses for Taylor degree ``p``."""
    from ..solvers.expm import _ps_plan
    return _ps_plan(int(p))[0]


def expm_flops(m: int, products: int, squarings, *, approximant: str = "taylor",
               degree: int | None = None) -> float:
    """Flops of a batch of scaling-and-squaring exponentials of ``m x m`` matrices.

    Parameters
    ----------
    m : int
        Matrix order (the augmented size for element transitions).
    products : int
        Products spent on the approximant per matrix
        (:attr:`kedfem.solvers.expm.ExpmInfo.products`).
    squarings : array_like of int
        Squarings per matrix (:attr:`kedfem.solvers.expm.ExpmInfo.squarings`); its
        length is the batch size.
    approximant : {"taylor", "pade"}
    degree : int, optional
        Taylor degree; when its Paterson-Stockmeyer block size is 1 the
        always-formed ``B @ B`` is added.

    Returns
    -------
    float
    """
    if approximant not in ("taylor", "pade"):
        raise InputError(f"unknown approximant {approximant!r}; valid: taylor, pade")
    sq = np.atleast_1d(np.asarray(squarings, dtype=float))
    per = matmul_flops(m) * (products + (1 if (approximant == "taylor" and degree is not None
                                                and _ps_block(degree) == 1) else 0))
    if approximant == "pade":
        per += 2.0 / 3.0 * m ** 3 + 2.0 * m ** 2 * m  # LU of the denominator, m-column solve
    return float(sq.size * per + matmul_flops(m) * sq.sum())


@dataclass(frozen=True)
class FlopCount:
    """Flops of one periodic solve, by phase.

    Attributes
    ----------
    phases : dict
        ``name -> (flops, size)``: ``size`` is the order of the matrices the
        phase multiplies, to look up the matmul rate it can reach.
    n, N : int
        Time elements and DOFs.
    """

    phases: dict = field(default_factory=dict)
    n: int = 0
    N: int = 0

    @property
    def total(self) -> float:
        """Total flops."""
        return float(sum(f for f, _ in self.phases.values()))

    def sizes(self) -> list[int]:
        """Distinct matrix orders of the phases."""
        return sorted({s for _, s in self.phases.values()})


def periodic_flops(n: int, N: int, hold: str = "zoh", *, products: int, squarings,
                   degree: int | None = None, approximant: str = "taylor",
                   mass: str = "constant", damping: str = "constant", passes: int = 1,
                   chunks: int = 1) -> FlopCount:
    """Flops of :func:`kedfem.solvers.periodic.solve` by condensation, time-varying stiffness.

    Parameters
    ----------
    n, N : int
        Time elements, DOFs.
    hold : {"zoh", "foh", "magnus2"}
    products, squarings, degree, approximant
        Of the element exponentials, see :func:`expm_flops` (``squarings`` per
        element, or one number for all).
    mass, damping : {"constant", "sampled"}
        Whether ``M`` and ``C`` are given as one matrix or per node.
    passes : int
        2 when the exponentials are recomputed for the propagation (streaming).
    chunks : int
        Number of element chunks (one monodromy update per chunk).

    Returns
    -------
    FlopCount
    """
    if hold not in ("zoh", "foh", "magnus2"):
        raise InputError(f"unknown hold {hold!r}")
    for name, v in (("mass", mass), ("damping", damping)):
        if v not in ("constant", "sampled"):
            raise InputError(f"{name} must be 'constant' or 'sampled', got {v!r}")
    n, N = int(n), int(N)
    m = 2 * N
    ma = m + (1 if hold == "zoh" else 2)
    nodes = n + (0 if hold == "zoh" else 1)  # magnus2 / foh need node k + 1 too
    sq = np.broadcast_to(np.asarray(squarings, dtype=float), (n,))
    ph = {}
    # M^-1 K, M^-1 C, M^-1 Q (kedfem.solvers.state_space._state_parts) and the mass check
    if mass == "constant":
        st = N ** 3 / 3.0 + 2.0 / 3.0 * N ** 3 + 2.0 * N ** 2 * N * nodes + 2.0 * N ** 2 * nodes
        st += (2.0 * N ** 3) if damping == "constant" else 2.0 * N ** 3 * nodes
    else:
        st = nodes * (N ** 3 / 3.0 + 2.0 * N ** 3 + matmul_flops(N) * 2 + 2.0 * N ** 2)
    ph["state matrices"] = (passes * st, N)
    ph["exponentials"] = (passes * expm_flops(ma, products, sq, approximant=approximant,
                                              degree=degree), ma)
    # tree products of the chunk transfers + monodromy update per chunk
    cond = (n - chunks) * (matmul_flops(m) + 2.0 * m * m) + chunks * (matmul_flops(m) + 2.0 * m * m)
    ph["condensation"] = (cond, m)
    # eigvals(Phi), singular values of I - Phi and its 2-norm, two solves (one refinement)
    ph["floquet"] = (10.0 * m ** 3 + 2 * 8.0 / 3.0 * m ** 3, m)
    ph["solve + propagate"] = (2 * (2.0 / 3.0 * m ** 3 + 2.0 * m * m) + n * 2.0 * m * m, m)
    log.debug("periodic_flops: n=%d N=%d hold=%s total %.3g", n, N, hold,
              sum(f for f, _ in ph.values()))
    return FlopCount(ph, n, N)


def batched_matmul_rate(batch: int, m: int, *, repeats: int = 5, threads: int = 1,
                        min_time: float = 0.02, seed: int = 0) -> float:
    """Best measured rate [flop/s] of ``np.matmul`` on a ``(batch, m, m)`` float64 stack.

    Parameters
    ----------
    batch, m : int
        Stack size and matrix order.
    repeats : int
        Best of this many timings.
    threads : int
        1: one ``np.matmul`` call with numpy's BLAS as configured. ``> 1``: the
        stack split into ``threads`` parts multiplied concurrently in Python
        threads with BLAS limited to one thread each (how kedfem runs its
        element exponentials; without threadpoolctl BLAS keeps its threads).
    min_time : float
        Each timing repeats the product until at least this many seconds pass.
    seed : int

    Returns
    -------
    float
    """
    if batch < 1 or m < 1 or repeats < 1 or threads < 1:
        raise InputError("batch, m, repeats and threads must be positive")
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((batch, m, m))
    B = rng.standard_normal((batch, m, m))
    out = np.empty_like(A)
    if threads == 1:
        def run():
            np.matmul(A, B, out=out)
        ctx = None
    else:
        from ..solvers.threads import one_blas_thread
        edges = np.linspace(0, batch, threads + 1).round().astype(int)
        parts = [slice(int(a), int(b)) for a, b in itertools.pairwise(edges) if b > a]
        pool = ThreadPoolExecutor(max_workers=len(parts))

        def run():
            futs = [pool.submit(np.matmul, A[s], B[s], out=out[s]) for s in parts]
            for f in futs:
                f.result()
        ctx = one_blas_thread()
        ctx.__enter__()
    best = math.inf
    try:
        run()  # warm-up
        for _ in range(repeats):
            reps = 0
            t0 = time.perf_counter()
            while True:
                run()
                reps += 1
                el = time.perf_counter() - t0
                if el >= min_time:
                    break
            best = min(best, el / reps)
    finally:
        if ctx is not None:
            ctx.__exit__(None, None, None)
            pool.shutdown()
    rate = matmul_flops(m) * batch / best
    log.debug("batched_matmul_rate: (%d, %d, %d) threads=%d: %.3g flop/s", batch, m, m, threads, rate)
    return rate


def time_bound(count: FlopCount, rate) -> float:
    """Lower bound of the wall time [s]: each phase's flops over the rate at its size.

    Parameters
    ----------
    count : FlopCount
    rate : callable or float
        ``rate(size) -> flop/s``, or one rate for all phases.

    Returns
    -------
    float
    """
    f = rate if callable(rate) else (lambda _s: float(rate))
    return float(sum(fl / f(s) for fl, s in count.phases.values()))
