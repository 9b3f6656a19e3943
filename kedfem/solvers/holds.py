"""Element transitions of the exponential holds ``"zoh"``, ``"foh"`` and ``"magnus2"``.

:class:`_Elements` computes ``(A_k, b_k)`` for a chunk of time elements (one ``A`` for all of
them when ``M``, ``C`` and ``K`` are constant), the numerical work split over worker threads;
:func:`auto_delta` matches the exponentials' accuracy to what the hold can deliver, and
:func:`_element_bytes` is the work memory per element that sets the chunk size. The hold
schemes are described in :mod:`kedfem.solvers.periodic`.
"""

from __future__ import annotations

import math
import threading

import numpy as np
import scipy.linalg as sla

from .parallel import _run_parallel, _split
from .state_space import _check_mass, _state_parts, state_matrix
from .vanloan import exponential_integrals, second_order_transition

#: Bytes of work memory per augmented-matrix entry in one batched exponential
#: (the matrix, its even powers, U, V, the LU solve and squaring temporaries).
_WORK_COPIES = 12


def auto_delta(n: int, hold: str, omega_dt: float = 0.0) -> float:
    """Exponential accuracy matched to what the time discretization can deliver.

    A non-constant periodic forcing has at least its fundamental harmonic, so the
    hold's relative discretization error is at least about ``(2 pi / n)**p / 12``
    (``p = 1`` for zoh, 2 for foh / magnus2). The exponentials are asked for a
    thousand times less, clipped to ``[1e-15, 1e-10]``; the upper clip keeps the
    Floquet multipliers and the discrete solution itself about ten digits
    accurate even when the discretization error is much larger. The bound is
    relative to ``||F dt||`` (balanced), about ``omega_max dt``; dividing by
    ``max(1, omega_max dt)`` keeps the absolute perturbation of each element's
    exponent below that level for stiff elements too, whose lightly damped high
    modes would otherwise accumulate it over the period.

    Parameters
    ----------
    n : int
        Number of time elements.
    hold : str
        Hold scheme.
    omega_dt : float
        Largest ``omega dt`` of the elements (an upper estimate is fine).

    Returns
    -------
    float
    """
    p = 1 if hold == "zoh" else 2
    base = float(np.clip(1e-3 * (2 * math.pi / n) ** p / 12.0, 1e-15, 1e-10))
    return max(1e-15, base / max(1.0, float(omega_dt)))


def _omega_dt(S, dt) -> float:
    """Upper estimate of omega_max dt: sqrt of the largest column sum of |M^-1 K|."""
    return math.sqrt(float(np.abs(S).sum(axis=-2).max())) * dt if S.size else 0.0


class _Elements:
    """Computes (A_k, b_k) for chunks of elements of one discretized period."""

    def __init__(self, Ms, Cs, Ks, Qs, n, N, period, hold, delta, chunk, approximant, workers,
                 Kzs=None, Qzs=None, Czs=None):
        self.Ms, self.Cs, self.Ks, self.Qs = Ms, Cs, Ks, Qs
        self.Kzs, self.Qzs, self.Czs = Kzs, Qzs, Czs
        self.n, self.N, self.m = n, N, 2 * N
        self.period, self.dt, self.hold = period, period / n, hold
        self.delta = delta
        self.delta_used = delta if delta is not None else 1.0
        self._lock = threading.Lock()
        self.approximant = approximant
        self.workers = workers
        self.chunk = chunk
        self.invariant = Ms.const and Cs.const and Ks.const and Kzs is None and Czs is None
        self.n_exponentials = 0
        self.degree = 0
        self.max_squarings = 0
        self._ops = None

    def _delta(self, S):
        """The requested delta, or the automatic one for these state matrices."""
        if self.delta is not None:
            return self.delta
        d = auto_delta(self.n, self.hold, _omega_dt(S, self.dt))
        with self._lock:
            self.delta_used = min(self.delta_used, d)
        return d

    def bounds(self):
        for a in range(0, self.n, self.chunk):
            yield a, min(self.n, a + self.chunk)

    def _record(self, info, count):
        self.n_exponentials += count
        self.degree = info.degree
        if info.squarings.size:
            self.max_squarings = max(self.max_squarings, int(info.squarings.max()))

    def _invariant_ops(self):
        if self._ops is None:
            N = self.N
            M, C, K = self.Ms.value, self.Cs.value, self.Ks.value
            _check_mass(M, np.array([0]))
            lu = sla.lu_factor(M)
            S = sla.lu_solve(lu, K)
            D = sla.lu_solve(lu, C)
            Minv = sla.lu_solve(lu, np.eye(N))
            F = state_matrix(S, D)
            G = np.vstack([np.zeros((N, N)), Minv])
            A, G0, G1, info = exponential_integrals(F, G, self.dt, delta=self._delta(S),
                                                    scaling="second-order",
                                                    approximant=self.approximant,
                                                    return_info=True)
            self._record(info, 1)
            self._ops = (A, G0, G1)
        return self._ops

    def compute(self, a: int, b: int):
        """Return (A, bvec) for elements a..b-1: A (L, m, m) or (m, m) if invariant.

        Inputs are evaluated here (callables are called from this thread only);
        the numerical work on the chunk is split over ``workers`` threads, each on
        a contiguous part with BLAS limited to one thread.
        """
        n, N, m = self.n, self.N, self.m
        L = b - a
        nodes = np.arange(a, b + 1) % n  # element k needs nodes k and k+1
        Q = self.Qs.get(nodes, N)
        if self.invariant:
            A, G0, G1 = self._invariant_ops()
            Qa = Q[:-1] if self.Qzs is None else Q[:-1] + self.Qzs.get(nodes[:-1], N)
            bvec = Qa @ G0.T
            if self.hold != "zoh":
                bvec = bvec + (Q[1:] - Q[:-1]) @ G1.T
            return A, bvec
        need_next = self.hold in ("foh", "magnus2")
        sel = nodes if need_next else nodes[:-1]
        Mk = self.Ms.get(sel, N)
        Ck = self.Cs.get(sel, N)
        Kk = self.Ks.get(sel, N)
        Qk = Q if need_next else Q[:-1]
        Kz = self.Kzs.get(nodes[:-1], N) if self.Kzs is not None else None
        Qz = self.Qzs.get(nodes[:-1], N) if self.Qzs is not None else None
        Cz = self.Czs.get(nodes[:-1], N) if self.Czs is not None else None
        A = np.empty((L, m, m))
        bvec = np.empty((L, m))
        parts = _split(L, self.workers)
        infos = [None] * len(parts)

        def work(i, lo, hi):
            hi_n = hi + 1 if need_next else hi  # nodes needed by elements lo..hi-1
            part = [X if X.ndim == 2 else X[lo:hi_n] for X in (Mk, Ck, Kk)]
            linearised = Kz is not None or Qz is not None or Cz is not None
            if self.hold == "magnus2":
                # midpoint data: average M, C and K first, then form M^-1 K.
                # M^-1 K of a symmetric positive definite M and a symmetric K
                # has real eigenvalues; the average of two such products (at
                # nodes k and k + 1) does not, and with stiff, rotating joint
                # couplings (omega dt >> 1) its complex eigenvalues made the
                # discrete system spuriously unstable (a six-bar: |mu| 1e17).
                avg = [X if X.ndim == 2 else 0.5 * (X[:-1] + X[1:]) for X in part]
                Qe = Qk[lo:hi_n]
                S, D, f0, Minv = _state_parts(*avg, Qe[:hi - lo], sel[lo:hi], inverse=True)
                Mlo = Mhi = Minv  # the same (element-mean) M^-1 at both ends
                f1 = Qe[1:] @ Minv.T if Minv.ndim == 2 else (Minv @ Qe[1:, :, None])[..., 0]
            else:
                S, D, f, Minv = _state_parts(*part, Qk[lo:hi_n], sel[lo:hi_n], inverse=linearised)
                if need_next:
                    S = S[:-1] if S.ndim == 3 else S
                    D = D[:-1] if D.ndim == 3 else D
                f0 = f[:hi - lo]
                f1 = f[1:hi - lo + 1] if need_next else None
                if linearised:
                    Mlo = Minv if Minv.ndim == 2 else Minv[:hi - lo]       # M^-1 at node k
                    Mhi = Minv if Minv.ndim == 2 else Minv[1:hi - lo + 1]  # M^-1 at node k + 1
            S = np.broadcast_to(S, (hi - lo, N, N))
            if linearised:
                # terms linearised about node k, held over element k (see solve)
                if Kz is not None:
                    S = S + Mlo @ Kz[lo:hi]
                if Cz is not None:
                    D = D + Mlo @ Cz[lo:hi]
                if Qz is not None:
                    qz = Qz[lo:hi, :, None]
                    f0 = f0 + (Mlo @ qz)[..., 0]
                    if f1 is not None:
                        f1 = f1 + (Mhi @ qz)[..., 0]
            delta = self._delta(S)
            Ak, bk, infos[i] = second_order_transition(
                S, D, self.dt, f0, f1, delta=delta, approximant=self.approximant,
                return_info=True)
            A[lo:hi] = Ak
            bvec[lo:hi] = bk

        _run_parallel(work, parts)
        for info, (lo, hi) in zip(infos, parts):
            self._record(info, hi - lo)
        return A, bvec


def _element_bytes(elems: _Elements) -> int:
    """Work memory per element of :meth:`_Elements.compute`, bytes (sets the chunk size).

    The batched exponential of the augmented ``(2N + 1)`` (zoh) or ``(2N + 2)``
    square matrices needs :data:`_WORK_COPIES` of them; with one ``A`` for all
    elements only ``O(m)`` per element remains (``b_k`` and the scan's partial sums).
    """
    m = elems.m
    ma = m + (1 if elems.hold == "zoh" else 2)
    return 8 * m * 8 if elems.invariant else 2 * _WORK_COPIES * ma * ma * 8
