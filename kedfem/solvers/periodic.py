"""Closed-form periodic steady state of ``M(t) u'' + C(t) u' + K(t) u = Q(t)``.

State-space method of Wang, Liu & Yuan (DETC2002, sections 1 and 3), corrected and
extended. The period ``T`` is split into ``n`` equal time elements with nodes
``t_k = k T / n``. With the state ``z = [u; u']`` each element is integrated
exactly for its held data::

    z' = F z + g(t),  F = [[0, I], [-M^-1 K, -M^-1 C]],  g = [0; M^-1 Q]
    z_{k+1} = A_k z_k + b_k,  A_k = exp(F dt),  b_k = int exp(F (dt - s)) g ds

Hold schemes (how the sampled data are held over element ``k``):

``"zoh"``
    ``F = F_k`` and ``g = g_k`` constant (the paper). First order when the data
    vary; exact for a time-invariant system under piecewise-constant forcing that
    switches at the nodes.
``"foh"``
    ``F = F_k`` constant, ``g`` linear from ``g_k`` to ``g_{k+1}``. Second order
    for a time-invariant ``F``; first order when ``F`` varies.
``"magnus2"``
    ``F`` from the element-mean data ``(M_k + M_{k+1}) / 2`` and likewise ``C``,
    ``K`` (the element midpoint to second order, indices modulo ``n``), with the
    first-order-hold forcing: second order for time-varying ``F`` too. Averaging
    the data rather than ``M^-1 K`` keeps the frequencies of each element real.

Periodicity ``z_n = z_0`` closes the block-cyclic system (paper Eq. 12). It is
solved by condensation (Eq. 13-16 with the corrected back substitution ``z_{k+1}
= A_k z_k + b_k``): ``Phi = A_{n-1} ... A_0`` (the monodromy matrix, whose
eigenvalues are the Floquet multipliers), ``d = sum_k A_{n-1}..A_{k+1} b_k``,
``(I - Phi) z_0 = d``, then forward propagation. When a multiplier lies outside
the unit circle forward propagation amplifies rounding errors, so the whole
cyclic system is instead solved by a sparse LU with partial pivoting
(``method="cyclic-lu"``) and an :class:`~kedfem.errors.InstabilityWarning` is
issued. If ``I - Phi`` is numerically singular (a multiplier at 1: undamped
resonance, a free rigid-body mode) :class:`~kedfem.errors.ResonanceError` is
raised.

Streaming: ``M``, ``C``, ``K`` and ``Q`` may be callables of the node indices, and
when keeping all ``n`` exponentials would exceed ``memory_budget`` the elements
are processed in chunks and the exponentials recomputed in a second pass, so the
peak memory does not grow with ``n`` beyond the ``O(n N)`` result.
"""

from __future__ import annotations

import logging
import math
import os
import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import InputError, InstabilityWarning, ResonanceError, SingularMassError, UnboundedResponseError
from .expm import balance, exponential_integrals, second_order_transition
from .threads import one_blas_thread

__all__ = ["solve", "solve_cyclic", "CyclicSolution", "PeriodicSolution", "HOLDS", "METHODS", "auto_delta", "MIN_NODES",
           "state_matrix"]

log = logging.getLogger(__name__)

#: Valid hold schemes.
HOLDS = ("zoh", "foh", "magnus2")
#: Valid solution methods (``"auto"`` picks one of the other two).
METHODS = ("auto", "condensation", "cyclic-lu")
#: ``I - Phi`` with a condition above ``max_condition`` is a resonance only if a
#: Floquet multiplier lies within this distance of 1; otherwise the size of the
#: condition number comes from the non-normality of ``Phi`` (stiff, undamped
#: high modes) and the cyclic system is solved by sparse LU instead.
RESONANCE_GAP = 1e-6
#: Minimum number of time elements: a periodic signal needs more than two samples
#: per period to represent even its fundamental harmonic (Nyquist), and the
#: midpoint / linear holds need distinct neighbours ``k - 1, k, k + 1``.
MIN_NODES = 3
#: Default largest acceptable condition number of the balanced ``I - Phi``.
MAX_CONDITION = 1e12
#: Spectral radius above ``1 + INSTABILITY_TOL`` counts as parametric instability.
INSTABILITY_TOL = 1e-6
#: A mass matrix pivot below this fraction of the largest diagonal entry is zero.
MASS_PIVOT_TOL = 1e-13
#: Bytes of work memory per augmented-matrix entry in one batched exponential
#: (the matrix, its even powers, U, V, the LU solve and squaring temporaries).
_WORK_COPIES = 12

@dataclass(frozen=True)
class PeriodicSolution:
    """Periodic steady state at the time nodes.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Time nodes ``k T / n``, s.
    U, V : ndarray, shape (n, N)
        Displacement and velocity at the nodes (units of the DOFs, per s for V).
    floquet_multipliers : ndarray of complex, shape (2N,)
        Eigenvalues of ``monodromy``, sorted by decreasing modulus.
    stable : bool
        All multipliers strictly inside the unit circle.
    residual : float
        Normwise relative residual ``||r|| / (||Acyc|| ||z|| + ||c||)`` (Frobenius
        / 2-norms) of the block-cyclic system actually solved.
    monodromy : ndarray, shape (2N, 2N)
        ``Phi = A_{n-1} ... A_0`` of the discrete system.
    method : str
        ``"condensation"`` or ``"cyclic-lu"``.
    hold : str
        Hold scheme used.
    period : float
        Period, s.
    delta : float
        Accuracy requested from the matrix exponentials (the smallest used).
    approximant : str
        ``"taylor"`` or ``"pade"``: the approximant inside the scaling and squaring.
    degree : int
        Degree of that approximant in the (last) batch of exponentials.
    max_squarings : int
        Largest number of squarings of any exponential.
    n_exponentials : int
        Number of (augmented) matrix exponentials computed, recomputations included.
    condition : float
        Condition estimate ``(1 + ||Phi||_2) / sigma_min(I - Phi)`` in balanced
        coordinates (relative to the data ``I`` and ``Phi`` it is formed from).
    passes : int
        1 when all ``A_k`` were kept, 2 when they were recomputed (streaming).
    timings : Mapping[str, float]
        Wall-clock seconds per phase.
    """

    t: np.ndarray
    U: np.ndarray
    V: np.ndarray
    floquet_multipliers: np.ndarray
    stable: bool
    residual: float
    monodromy: np.ndarray
    method: str
    hold: str
    period: float
    delta: float
    approximant: str
    degree: int
    max_squarings: int
    n_exponentials: int
    condition: float
    passes: int
    timings: Mapping[str, float] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of time elements."""
        return self.t.shape[0]

    @property
    def dt(self) -> float:
        """Element length, s."""
        return self.period / self.n

    @property
    def Z(self) -> np.ndarray:
        """State ``[U, V]`` at the nodes, shape (n, 2N)."""
        return np.concatenate([self.U, self.V], axis=1)

    @property
    def spectral_radius(self) -> float:
        """Largest Floquet multiplier modulus."""
        return float(np.abs(self.floquet_multipliers).max()) if self.floquet_multipliers.size else 0.0


# --------------------------------------------------------------------------
# Input sources
# --------------------------------------------------------------------------

class _Source:
    """A coefficient given as constant (N,N), sampled (n,...) or callable."""

    def __init__(self, name: str, value, matrix: bool):
        self.name = name
        self.matrix = matrix
        self.callable = callable(value)
        self.value = value
        self.const = False
        if not self.callable:
            arr = np.asarray(value)
            if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
                raise InputError(f"{name} must be a real numeric array or a callable, "
                                 f"got dtype {arr.dtype}")
            arr = arr.astype(float, copy=False)
            if matrix:
                if arr.ndim == 2:
                    self.const = True
                elif arr.ndim != 3:
                    raise InputError(f"{name} must have shape (N, N) or (n, N, N), got {arr.shape}")
                if arr.shape[-1] != arr.shape[-2]:
                    raise InputError(f"{name} must be square in its last two axes, got {arr.shape}")
            elif arr.ndim != 2:
                raise InputError(f"{name} must have shape (n, N), got {arr.shape}")
            _check_finite(name, arr)
            self.value = arr

    @property
    def n(self) -> int | None:
        if self.callable or self.const:
            return None
        return self.value.shape[0]

    @property
    def N(self) -> int | None:
        if self.callable:
            return None
        return self.value.shape[-1]

    def get(self, idx: np.ndarray | slice, N: int) -> np.ndarray:
        """Values at node indices ``idx`` (an array, or a slice of consecutive nodes: a view of
        sampled data, not a copy): (len, N, N) / (len, N), or (N, N) if constant."""
        if self.const:
            return self.value
        if not self.callable:
            return self.value[idx]
        if isinstance(idx, slice):
            idx = np.arange(idx.start, idx.stop)
        out = np.asarray(self.value(idx), dtype=float)
        want = (len(idx), N, N) if self.matrix else (len(idx), N)
        if out.shape != want:
            raise InputError(f"{self.name}(idx) must return shape {want} for {len(idx)} indices, "
                             f"got {out.shape}")
        bad = ~np.isfinite(out)
        if bad.any():
            pos = np.argwhere(bad)[0]
            node = int(idx[pos[0]])
            raise InputError(f"{self.name} has a non-finite value at time node {node} "
                             f"(entry {tuple(int(i) for i in pos[1:])})")
        return out


def _check_finite(name: str, arr: np.ndarray) -> None:
    bad = ~np.isfinite(arr)
    if bad.any():
        first = tuple(int(i) for i in np.argwhere(bad)[0])
        raise InputError(f"{name} has a non-finite value at index {first}")


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


# --------------------------------------------------------------------------
# Mass matrix check and state matrices
# --------------------------------------------------------------------------

def _mass_error(M: np.ndarray, nodes: np.ndarray) -> SingularMassError:
    Ms = 0.5 * (M + np.swapaxes(M, -1, -2))
    d = np.abs(np.diagonal(Ms, axis1=-2, axis2=-1))
    # Jacobi scaling (each DOF's own mass 1; a DOF without mass keeps the heaviest one's scale)
    s = 1.0 / np.sqrt(np.where(d <= 0, d.max(axis=-1, keepdims=True), d))
    Ms = s[:, :, None] * Ms * s[:, None, :]
    w, v = np.linalg.eigh(Ms)
    scale = np.maximum(np.abs(w).max(axis=-1), np.finfo(float).tiny)
    bad = w <= MASS_PIVOT_TOL * scale[:, None]
    k = int(np.nonzero(bad.any(axis=-1))[0][0]) if bad.any() else int(np.argmin(w[:, 0] / scale))
    vecs = v[k][:, bad[k]] if bad[k].any() else v[k][:, :1]
    weight = np.abs(vecs).max(axis=1)
    dofs = [int(i) for i in np.nonzero(weight >= 0.3 * weight.max())[0]]
    kind = "indefinite" if w[k, 0] < -MASS_PIVOT_TOL * scale[k] else "singular"
    return SingularMassError(
        f"mass matrix M at time node {int(nodes[k])} is {kind} (smallest eigenvalue of its "
        f"symmetric part {w[k, 0]:.3g}, largest {w[k, -1]:.3g}); massless or negative-mass "
        f"DOFs: {dofs}. The state-space method needs M positive definite; give those DOFs "
        f"mass or condense them out before calling the solver.")


def _check_mass(M: np.ndarray, nodes: np.ndarray) -> None:
    """Raise SingularMassError unless every M (symmetric part) is positive definite."""
    Mb = M if M.ndim == 3 else M[None]
    Ms = 0.5 * (Mb + np.swapaxes(Mb, -1, -2))
    try:
        L = np.linalg.cholesky(Ms)
    except np.linalg.LinAlgError:
        raise _mass_error(Mb, nodes) from None
    # each pivot against its own DOF's mass: a heavy DOF beside light ones (a 1e12 kg press ram on
    # a 1e-6 kg m^2 rotary inertia of a beam node) is not a massless one; a DOF without mass, or
    # one whose mass its neighbours' coupling cancels, is
    piv = np.diagonal(L, axis1=-2, axis2=-1) ** 2
    diag = np.diagonal(Ms, axis1=-2, axis2=-1)
    if np.any(piv <= MASS_PIVOT_TOL * diag):
        raise _mass_error(Mb, nodes)


def _state_parts(M, C, K, Q, nodes, inverse=False):
    """S = M^-1 K, D = M^-1 C, f = M^-1 Q for the given nodes (constants broadcast).

    A sampled ``M`` is inverted once per node (batched LU with partial
    pivoting, ``np.linalg.inv``) and the inverses applied by batched matrix
    products: numpy's stacked ``solve`` runs LAPACK node by node with a copy of
    every right-hand side and is several times slower for these small blocks
    (measured 4.9 against 3.0 ms for 91 nodes of 33 DOFs), and the inverse is
    reused for the linearised terms of the non-linear iteration. The fourth
    item is the inverses (for a constant ``M`` the one inverse, always formed).
    """
    N = Q.shape[-1]
    _check_mass(M, nodes if M.ndim == 3 else nodes[:1])
    if M.ndim == 2:
        # one inverse, applied by (batched) matrix products: faster than
        # triangular solves with L*N right-hand sides (0.1 s of 0.8 s at N = 100)
        Minv = sla.lu_solve(sla.lu_factor(M), np.eye(N))
        S, D = Minv @ K, Minv @ C
        f = Q @ Minv.T
    else:  # the inverses are needed for S, D, f anyway
        Minv = np.linalg.inv(M)
        S = Minv @ K
        D = Minv @ C
        f = (Minv @ Q[:, :, None])[..., 0]
    return S, D, f, Minv


def state_matrix(S, D, dtype=float):
    """State matrix ``F = [[0, I], [-S, -D]]``, (..., 2N, 2N), of ``S = M^-1 K`` [1/s^2] and
    ``D = M^-1 C`` [1/s], each a stack (L, N, N) or a single (N, N)."""
    N = S.shape[-1]
    shape = np.broadcast_shapes(S.shape, D.shape)
    F = np.zeros(shape[:-2] + (2 * N, 2 * N), dtype=dtype)
    F[..., :N, N:] = np.eye(N)
    F[..., N:, :N] = -S
    F[..., N:, N:] = -D
    return F


# --------------------------------------------------------------------------
# Element transitions
# --------------------------------------------------------------------------

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


def _split(L: int, workers: int, min_part: int = 8) -> list[tuple[int, int]]:
    w = max(1, min(workers, L // min_part))
    edges = np.linspace(0, L, w + 1).round().astype(int)
    return [(int(edges[i]), int(edges[i + 1])) for i in range(w)]


_POOL = None


def check_period(period) -> float:
    """``period`` [s] as a positive finite float, or an :class:`InputError`."""
    try:
        period = float(period)
    except (TypeError, ValueError):
        raise InputError(f"period must be a positive finite number, got {period!r}") from None
    if not (math.isfinite(period) and period > 0):
        raise InputError(f"period must be a positive finite number, got {period!r}")
    return period


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


# --------------------------------------------------------------------------
# Sequential products
# --------------------------------------------------------------------------

def _scan_invariant(A, bvec, z0):
    """States of z_{k+1} = A z_k + b_k (constant A) by sqrt-blocking.

    The elements are split into ``nb`` blocks of ``blk ~ sqrt(L)``; the partial
    sums inside all blocks advance together (``blk`` products ``A @ (m, nb)``),
    the block start states follow by ``nb`` products with ``A**blk``, and the
    states by ``blk`` more products: ``O(sqrt(L))`` Python steps instead of ``L``.

    Returns
    -------
    Z : ndarray, shape (L, m)
        States at the element starts (``Z[0] = z0``).
    z_end : ndarray, shape (m,)
        State after the last element.
    """
    L, m = bvec.shape
    blk = max(1, int(math.isqrt(L)))
    nb = -(-L // blk)
    pad = nb * blk - L
    B = np.concatenate([bvec, np.zeros((pad, m))]).reshape(nb, blk, m)
    P = np.empty((blk + 1, m, nb))
    P[0] = 0.0
    for i in range(blk):
        P[i + 1] = A @ P[i] + B[:, i, :].T
    Ablk = np.linalg.matrix_power(A, blk)
    S = np.empty((nb + 1, m))
    S[0] = z0
    for j in range(nb):
        S[j + 1] = Ablk @ S[j] + P[blk][:, j]
    Y = S[:nb].T.copy()
    Z = np.empty((nb, blk, m))
    for i in range(blk):
        Z[:, i, :] = (Y + P[i]).T
        Y = A @ Y
    Zf = Z.reshape(nb * blk, m)
    z_end = Zf[L] if pad else S[nb]
    return Zf[:L], z_end


def _propagate(A, bvec, z0, out):
    """z_{k+1} = A_k z_k + b_k for the chunk; out[k] = z_k; returns the state after."""
    if A.ndim == 2:
        Zc, z_end = _scan_invariant(A, bvec, z0)
        out[:] = Zc
        return z_end
    z = z0
    for k in range(bvec.shape[0]):
        out[k] = z
        z = A[k] @ z + bvec[k]
    return z


# --------------------------------------------------------------------------
# Entry point
# --------------------------------------------------------------------------

def _resolve_shapes(Ms, Cs, Ks, Qs, n):
    ns = {s.name: s.n for s in (Ms, Cs, Ks, Qs) if s.n is not None}
    if n is not None:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
            raise InputError(f"n must be an integer, got {n!r}")
        ns["n"] = int(n)
    if not ns:
        raise InputError("cannot infer the number of time elements: all of M, C, K, Q are "
                         "constant or callables; pass n=...")
    if len(set(ns.values())) > 1:
        raise InputError("inconsistent numbers of time nodes: "
                         + ", ".join(f"{k} has {v}" for k, v in ns.items()))
    n_ = next(iter(ns.values()))
    if n_ < MIN_NODES:
        raise InputError(f"need at least {MIN_NODES} time elements per period (a periodic "
                         f"signal needs more than two samples per period), got n = {n_}")
    Ns = {s.name: s.N for s in (Ms, Cs, Ks, Qs) if s.N is not None}
    if not Ns:
        probe = Qs if Qs.callable else Ms
        out = np.asarray(probe.value(np.array([0])))
        if out.ndim < 2:
            raise InputError(f"{probe.name}(idx) must return a 2-D or 3-D array, got {out.shape}")
        Ns[probe.name] = out.shape[-1]
    if len(set(Ns.values())) > 1:
        raise InputError("inconsistent numbers of DOFs: "
                         + ", ".join(f"{k} has {v}" for k, v in Ns.items()))
    N_ = next(iter(Ns.values()))
    if N_ < 1:
        raise InputError("need at least one DOF")
    return n_, N_


def solve(M, C, K, Q, period: float, hold: str = "zoh", *, n: int | None = None,
          delta: float | None = None, method: str = "auto", approximant: str = "taylor",
          memory_budget: float = 256e6, max_condition: float = MAX_CONDITION,
          workers: int | None = None, Kz=None, Qz=None, Cz=None) -> PeriodicSolution:
    """Periodic steady state of ``M u'' + C u' + K u = Q`` by the state-space method.

    Parameters
    ----------
    M, C, K : ndarray, shape (n, N, N) or (N, N), or callable
        Mass [kg], damping [N s/m] and stiffness [N/m] (or consistent units),
        sampled at ``t_k = k * period / n``, or constant. A callable
        ``f(idx) -> ndarray (len(idx), N, N)`` is evaluated on chunks of node
        indices ``idx`` (int array, values in ``0..n-1``) so that huge ``n`` can be
        streamed without materialising ``(n, N, N)`` arrays. ``M`` must be
        positive definite (its symmetric part is checked); massless DOFs raise
        :class:`~kedfem.errors.SingularMassError`.
    Q : ndarray, shape (n, N), or callable
        Load [N] at the nodes; a callable ``q(idx) -> ndarray (len(idx), N)``.
    period : float
        Period ``T`` > 0, s.
    hold : {"zoh", "foh", "magnus2"}
        Hold scheme, see the module docstring.
    n : int, optional
        Number of time elements; needed only if no argument is a sampled array.
    delta : float, optional
        Relative backward error asked from each matrix exponential. ``None``
        (default): :func:`auto_delta`, matched to the hold's discretization error,
        clipped to ``[1e-15, 1e-10]`` and divided by ``max(1, omega_max dt)``.
    method : {"auto", "condensation", "cyclic-lu"}
        ``"auto"``: condensation unless a Floquet multiplier lies outside the unit
        circle (then cyclic LU, with an ``InstabilityWarning``).
    approximant : {"taylor", "pade"}
        Approximant inside the scaling and squaring (see
        :func:`kedfem.solvers.expm.expm`). Default Taylor/Paterson-Stockmeyer: same
        backward-error bound and scaling rule as Pade, no batched linear solve,
        measured 1.3-2x faster per exponential (``docs/solver.md``).
    memory_budget : float
        Bytes. If keeping all ``A_k`` (``n (2N)**2 8`` bytes) exceeds half of it,
        exponentials are computed in chunks and recomputed in a second pass.
    max_condition : float
        Largest acceptable condition estimate ``(1 + ||Phi||) / sigma_min(I - Phi)``
        (balanced coordinates, 2-norms); above it
        :class:`~kedfem.errors.ResonanceError` is raised. The default ``1e12``
        keeps the rounding error of ``z_0`` below about ``1e-4`` relative; a
        lightly damped resonance (``zeta = 1e-6``) has a condition of about
        ``1 / (2 pi zeta)`` per period and is solved.
    workers : int, optional
        Threads for the element exponentials (default: usable CPUs, at most 8);
        while they run BLAS is limited to one thread per worker (threadpoolctl).
        Callables are always evaluated from the calling thread.

    Kz, Qz, Cz : ndarray, shape (n, N, N), (n, N) and (n, N, N), optional
        Stiffness, load and damping of a linearisation about each time node,
        held constant over the element that starts at the node whatever the
        hold (``K_k + Kz_k``, ``C_k + Cz_k`` and ``Q(t) + Qz_k`` on
        ``[t_k, t_k+1]``). The non-linear
        iteration passes its state-dependent terms here: the tangent stiffness
        and the load ``-f_nl + K_nl x`` linearised at node ``k`` then cancel
        exactly at the node, so that a fixed point solves the non-linear
        equations and the iteration converges as Newton's method would, while
        the error of the linearisation over the element stays ``O(dt^2)``.

    Returns
    -------
    PeriodicSolution

    Raises
    ------
    InputError
        Bad shapes, ``n < 3``, bad period or hold, non-finite values (named, with
        the first bad index), before any numerical work for array inputs.
    SingularMassError
        ``M`` singular or indefinite at some node (names node and DOFs).
    ResonanceError
        ``I - Phi`` numerically singular (condition above ``max_condition``).

    Notes
    -----
    All linear algebra runs on one BLAS thread per kedfem worker
    (:func:`kedfem.solvers.threads.one_blas_thread`): the matrices are small
    (2N up to a few hundred) and OpenBLAS's own threading of them was 2-60x
    slower than one thread whenever the other cores were busy (measured on a
    shared 2-core machine, ``benchmarks/peers.py``).

    The steps: check the options (:func:`_check_options`), build the
    transitions (:func:`_element_transitions`), solve the block-cyclic system
    and its Floquet analysis (:func:`solve_cyclic`).
    """
    with one_blas_thread():
        timings: dict[str, float] = {}
        t_start = time.perf_counter()
        period, delta = _check_options(period, hold, method, approximant, delta, memory_budget)
        elems = _element_transitions(M, C, K, Q, period, hold, n, delta, approximant, workers,
                                     Kz, Qz, Cz)
        cyc = solve_cyclic(elems, _element_bytes(elems), method=method,
                           memory_budget=memory_budget, max_condition=max_condition,
                           timings=timings, t_start=t_start)
        return _periodic_solution(elems, cyc, timings)


def _check_options(period, hold, method, approximant, delta,
                   memory_budget) -> tuple[float, float | None]:
    """Validate the scalar options of :func:`solve` before any work.

    Parameters
    ----------
    period : float
        Period, s.
    hold, method, approximant : str
        Names, checked against :data:`HOLDS`, :data:`METHODS` and the approximants.
    delta : float or None
        Requested exponential accuracy, in (0, 1), or ``None`` (automatic).
    memory_budget : float
        Bytes, > 0.

    Returns
    -------
    period : float
        Period as a float, s.
    delta : float or None
        ``delta`` as a float (or ``None``).

    Raises
    ------
    InputError
        The first invalid option, named.
    """
    if hold not in HOLDS:
        raise InputError(f"unknown hold {hold!r}; valid holds: {', '.join(HOLDS)}")
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; valid methods: {', '.join(METHODS)}")
    if approximant not in ("taylor", "pade"):
        raise InputError(f"unknown approximant {approximant!r}; valid: taylor, pade")
    period = check_period(period)
    if delta is not None:
        delta = float(delta)
        if not (math.isfinite(delta) and 0 < delta < 1):
            raise InputError(f"delta must lie in (0, 1), got {delta!r}")
    if not (isinstance(memory_budget, (int, float, np.integer, np.floating))
            and memory_budget > 0):
        raise InputError(f"memory_budget must be a positive number of bytes, got {memory_budget!r}")
    return period, delta


def _linearisation_source(name: str, value, matrix: bool, n: int, N: int) -> _Source:
    """``Kz``, ``Cz`` (``matrix``: shape (n, N, N)) or ``Qz`` (shape (n, N)), checked sampled."""
    src = _Source(name, value, matrix)
    if src.n != n or src.N != N:  # constant or callable: n is None
        want = f"be sampled with shape ({n}, {N}, {N})" if matrix else f"have shape ({n}, {N})"
        raise InputError(f"{name} must {want}")
    return src


def _element_transitions(M, C, K, Q, period: float, hold: str, n, delta, approximant: str,
                         workers, Kz=None, Qz=None, Cz=None) -> _Elements:
    """Build the transitions: the source of ``(A_k, b_k)`` of the ``n`` time elements.

    Wraps the inputs, infers and checks ``n`` and ``N``, and resolves ``workers``;
    no exponential is computed here (see :meth:`_Elements.compute`).

    Parameters
    ----------
    M, C, K, Q, n, Kz, Qz, Cz
        As in :func:`solve`: (n, N, N) / (N, N) / callable matrices in kg, N s/m,
        N/m; (n, N) loads in N.
    period : float
        Period, s (checked).
    hold, approximant : str
        Checked names.
    delta : float or None
        Checked exponential accuracy.
    workers : int or None
        Threads for the exponentials; ``None``: :func:`default_workers`.

    Returns
    -------
    _Elements
        State size ``m = 2 N``; ``invariant`` when one ``A`` serves all elements.

    Raises
    ------
    InputError
        Bad shapes or values, in the order: ``M, C, K, Q``, ``n``, ``Cz, Kz, Qz``, ``workers``.
    """
    Ms = _Source("M", M, True)
    Cs = _Source("C", C, True)
    Ks = _Source("K", K, True)
    Qs = _Source("Q", Q, False)
    n, N = _resolve_shapes(Ms, Cs, Ks, Qs, n)
    Czs = None if Cz is None else _linearisation_source("Cz", Cz, True, n, N)
    Kzs = None if Kz is None else _linearisation_source("Kz", Kz, True, n, N)
    Qzs = None if Qz is None else _linearisation_source("Qz", Qz, False, n, N)
    if workers is None:
        workers = default_workers()
    elif not (isinstance(workers, (int, np.integer)) and workers >= 1):
        raise InputError(f"workers must be a positive integer or None, got {workers!r}")
    return _Elements(Ms, Cs, Ks, Qs, n, N, period, hold, delta, 1, approximant, int(workers),
                     Kzs, Qzs, Czs)


def _element_bytes(elems: _Elements) -> int:
    """Work memory per element of :meth:`_Elements.compute`, bytes (sets the chunk size).

    The batched exponential of the augmented ``(2N + 1)`` (zoh) or ``(2N + 2)``
    square matrices needs :data:`_WORK_COPIES` of them; with one ``A`` for all
    elements only ``O(m)`` per element remains (``b_k`` and the scan's partial sums).
    """
    m = elems.m
    ma = m + (1 if elems.hold == "zoh" else 2)
    return 8 * m * 8 if elems.invariant else 2 * _WORK_COPIES * ma * ma * 8


def _periodic_solution(elems: _Elements, cyc: CyclicSolution, timings: dict) -> PeriodicSolution:
    """The :class:`PeriodicSolution` of the states ``cyc.Z`` (n, 2N) and the exponentials' record."""
    n, N, period = elems.n, elems.N, elems.period
    return PeriodicSolution(
        t=np.arange(n) * (period / n), U=cyc.Z[:, :N].copy(), V=cyc.Z[:, N:].copy(),
        floquet_multipliers=cyc.multipliers, stable=cyc.stable, residual=cyc.residual,
        monodromy=cyc.monodromy, method=cyc.method, hold=elems.hold, period=period,
        delta=float(elems.delta_used), approximant=elems.approximant, degree=int(elems.degree),
        max_squarings=int(elems.max_squarings), n_exponentials=int(elems.n_exponentials),
        condition=cyc.condition, passes=cyc.passes, timings=MappingProxyType(timings))


@dataclass(frozen=True)
class CyclicSolution:
    """Outcome of :func:`solve_cyclic` (see :class:`PeriodicSolution` for the fields)."""

    Z: np.ndarray
    multipliers: np.ndarray
    stable: bool
    residual: float
    monodromy: np.ndarray
    method: str
    condition: float
    passes: int
    factors: "CyclicFactors | None" = None


@dataclass(frozen=True)
class CyclicFactors:
    """The condensed transitions of a solved block-cyclic system, kept for other loads.

    ``z_{k+1} = A_k z_k + b'_k``, ``z_n = z_0`` with the same ``A_k`` and new ``b'_k``: one march
    from zero gives the particular part, ``I - Phi`` (balanced, as the first solve) gives ``z_0``,
    and a second march the states: ``2 n`` products ``A_k z`` instead of the transitions'
    computation and condensation.

    Attributes
    ----------
    bounds : tuple of (int, int)
        The chunks ``(a, b)`` of elements.
    A : tuple of ndarray
        Per chunk, its ``A_k`` (L, m, m), or the one ``A`` (m, m) when invariant.
    ImP, Bal, dsc : ndarray
        ``I - Phi`` and its balanced form and scaling (:func:`_balanced_condition`).
    a_norm2 : float
        ``sum_k ||A_k||_F**2``.
    """

    bounds: tuple
    A: tuple
    ImP: np.ndarray
    Bal: np.ndarray
    dsc: np.ndarray
    a_norm2: float

    def solve(self, b: list) -> tuple[np.ndarray, float]:
        """Periodic states for the forced parts ``b`` (per chunk, (L, m)).

        Returns
        -------
        Z : ndarray, shape (n, m)
            States at the element starts.
        residual : float
            Normwise relative residual of the cyclic system (as :func:`solve_cyclic`).
        """
        n, m = self.bounds[-1][1], self.ImP.shape[0]
        Z = np.empty((n, m))
        chunks = [(a, e, A, bb) for (a, e), A, bb in zip(self.bounds, self.A, b)]
        d = _march(chunks, np.zeros(m), Z)
        z0 = _solve_z0(self.ImP, self.Bal, self.dsc, d)
        z_end = _march(chunks, z0, Z)
        rnorm = float(np.linalg.norm(z_end - Z[0]))
        bnorm2 = sum(float(np.sum(bb * bb)) for bb in b)
        denom = math.sqrt(self.a_norm2 + n * m) * float(np.linalg.norm(Z)) + math.sqrt(bnorm2)
        return Z, (rnorm / denom if denom > 0 else 0.0)


def solve_cyclic(elems, per_element: float, *, method: str = "auto", memory_budget: float = 256e6,
                 max_condition: float = MAX_CONDITION, timings: dict | None = None,
                 t_start: float | None = None, factors: bool = False) -> CyclicSolution:
    """Periodic states of ``z_{k+1} = A_k z_k + b_k``, ``z_n = z_0``, and its Floquet analysis.

    The block-cyclic system of any one-step time discretisation (the
    exponential holds of this module, the collocation schemes of
    :mod:`kedfem.solvers.collocation`): condensation (paper Eq. 13-16) or, when a
    multiplier lies outside the unit circle or ``I - Phi`` is non-normal and
    ill-conditioned, a sparse LU of the whole cyclic system.

    Parameters
    ----------
    elems : transition source
        Object with attributes ``n`` (elements), ``m`` (state size),
        ``invariant`` (one ``A`` for all elements), ``chunk`` (set here),
        ``workers``, and methods ``bounds()`` (chunks ``(a, b)``) and
        ``compute(a, b) -> (A (b-a, m, m) or (m, m), b (b-a, m))``.
    per_element : float
        Work memory of ``compute`` per element [bytes] (sets the chunk size).
    method, memory_budget, max_condition
        As in :func:`solve`.
    timings : dict, optional
        Filled with the wall time of the phases [s].
    factors : bool
        Keep the condensed transitions for other loads (:class:`CyclicFactors`), where the
        system was condensed with its transitions kept (not by the sparse LU, not streamed).

    Returns
    -------
    CyclicSolution
        States ``Z`` (n, m) at the element starts and the Floquet analysis.

    Notes
    -----
    The steps: plan the chunks (:func:`_plan_chunks`); condense the cyclic
    system into ``Phi`` and ``d`` (:func:`_condense`); the Floquet multipliers,
    the condition of ``I - Phi`` and the choice of method
    (:func:`_floquet_multipliers`, :func:`_balanced_condition`,
    :func:`_check_resonance`, :func:`_choose_method`); then either solve for
    ``z_0`` (:func:`_solve_z0`) and march the states (:func:`_march`), or solve
    the cyclic system by sparse LU (:func:`_solve_by_cyclic_lu`); last the
    normwise residual (:func:`_relative_residual`).
    """
    timings = {} if timings is None else timings
    t_start = time.perf_counter() if t_start is None else t_start
    n, m = elems.n, elems.m
    keep, seg = _plan_chunks(elems, per_element, memory_budget)

    t0 = time.perf_counter()
    pass1 = _condense(elems, keep, seg)
    timings["exponentials"] = pass1.t_exp
    timings["condensation"] = time.perf_counter() - t0 - pass1.t_exp

    t0 = time.perf_counter()
    _check_bounded(pass1, n)
    mult = _floquet_multipliers(pass1.Phi)
    rho = float(np.abs(mult).max())
    ImP = np.eye(m) - pass1.Phi
    Bal, dsc, condition = _balanced_condition(ImP)
    ill_conditioned = _check_resonance(mult, condition, max_condition)
    method = _choose_method(method, rho, ill_conditioned)
    timings["floquet"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    Z = np.empty((n, m))
    if method == "condensation":
        z0 = _solve_z0(ImP, Bal, dsc, pass1.d)
        z_end = _march(_second_pass(elems, pass1, keep), z0, Z)
        rnorm = float(np.linalg.norm(z_end - Z[0]))  # only the closing row is not exact
    else:
        rnorm = _solve_by_cyclic_lu(elems, pass1, keep, seg, Z)
    residual = _relative_residual(rnorm, pass1, Z)
    timings["solve"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    log.info("periodic: n=%d m=%d method=%s rho=%.6g cond=%.3g residual=%.2e (%.3f s)",
             n, m, method, rho, condition, residual, timings["total"])
    kept = None
    if factors and keep and method == "condensation":
        kept = CyclicFactors(tuple(elems.bounds()), tuple(pass1.kept_A), ImP, Bal, dsc, pass1.a_norm2)
    return CyclicSolution(Z, mult, bool(rho < 1.0), float(residual), pass1.Phi, method,
                          float(condition), 1 if keep else 2, kept)


# --------------------------------------------------------------------------
# Steps of solve_cyclic
# --------------------------------------------------------------------------

def _plan_chunks(elems, per_element: float, memory_budget: float) -> tuple[bool, int]:
    """Chunk size (set on ``elems.chunk``), whether to keep the ``A_k``, and the LU segment.

    Parameters
    ----------
    elems : transition source
        As in :func:`solve_cyclic`, with ``n`` elements of state size ``m``.
    per_element : float
        Work memory of ``elems.compute`` per element, bytes.
    memory_budget : float
        Bytes. A chunk's work fits the budget; the ``A_k`` (``n m**2 8`` bytes)
        are kept when they fit half of it.

    Returns
    -------
    keep : bool
        Keep every chunk's ``A_k`` for the second pass (always when invariant);
        otherwise they are recomputed.
    seg : int
        Elements per segment of the cyclic system solved by sparse LU: 1 (the
        whole system) unless its LU would not fit the budget. Time-varying
        segments lie inside one chunk or span whole chunks.
    """
    n, m, invariant = elems.n, elems.m, elems.invariant
    chunk = max(1, min(n, int(memory_budget // per_element)))
    keep = invariant or n * m * m * 8 <= memory_budget / 2
    s_max = max(1, int(memory_budget // (48 * m * m)))
    seg = -(-n // s_max)
    if not invariant:
        if seg <= chunk:
            chunk = max(seg, (chunk // seg) * seg)
        else:
            seg = -(-seg // chunk) * chunk
    elems.chunk = chunk
    log.debug("solve_cyclic: n=%d m=%d chunk=%d keep=%s segment=%d", n, m, chunk, keep, seg)
    return keep, seg


@dataclass
class _Condensed:
    """The block-cyclic system condensed by the first pass (:func:`_condense`).

    State units: those of the DOFs for the first ``m / 2`` entries, per second
    for the rest.

    Attributes
    ----------
    Phi : ndarray, shape (m, m)
        Monodromy matrix ``A_{n-1} ... A_0``.
    d : ndarray, shape (m,)
        Particular part ``sum_k A_{n-1} ... A_{k+1} b_k``, the state after one
        period from ``z_0 = 0``.
    kept_A : list of ndarray
        Per chunk, its ``A_k`` (L, m, m), or the one ``A`` (m, m) when
        invariant; empty when not kept.
    kept_b : list of ndarray, shape (L, m)
        Per chunk, its ``b_k`` (always kept: ``O(n m)``).
    seg_A, seg_b : list of ndarray, shapes (S, m, m) and (S, m)
        Transfers of the sparse-LU segments (time-varying transitions only).
    a_norm2 : float
        ``sum_k ||A_k||_F**2``.
    t_exp : float
        Wall time of ``elems.compute``, s.
    """

    Phi: np.ndarray
    d: np.ndarray
    kept_A: list
    kept_b: list
    seg_A: list
    seg_b: list
    a_norm2: float
    t_exp: float


class _Segments:
    """Transfers of consecutive segments of ``seg`` elements, collected chunk by chunk.

    For time-varying transitions: a segment lies inside one chunk (all of them
    when ``seg`` does not exceed the chunk) or spans whole chunks, whose
    transfers are then composed until the segment is complete.
    """

    def __init__(self, seg: int, n: int, workers: int):
        self.seg, self.n, self.workers = seg, n, workers
        self.A: list[np.ndarray] = []
        self.b: list[np.ndarray] = []
        self._open_A = self._open_b = None
        self._open_len = 0

    def add(self, A: np.ndarray, bvec: np.ndarray, end: int) -> tuple[np.ndarray, np.ndarray]:
        """Record the segments of a chunk and return the chunk's transfer.

        Parameters
        ----------
        A : ndarray, shape (L, m, m)
            Transitions of the chunk's elements.
        bvec : ndarray, shape (L, m)
            Their forced parts.
        end : int
            Index one past the chunk's last element.

        Returns
        -------
        P : ndarray, shape (m, m)
            ``A_{L-1} ... A_0``.
        d : ndarray, shape (m,)
            State after the chunk from a zero state.
        """
        L, seg = bvec.shape[0], self.seg
        if seg == 1:
            sA, sb = A, bvec
        elif seg <= L:
            sA, sb = _tree_groups(A, bvec, seg)
        else:
            sA, sb = None, None
        Pc, dc = (_tree_parallel(A, bvec, self.workers) if sA is None
                  else _tree_parallel(sA, sb, self.workers))
        Pc, dc = Pc[0], dc[0]
        if sA is not None:
            self.A.append(sA)
            self.b.append(sb)
            return Pc, dc
        if self._open_A is None:  # segment spans several chunks
            self._open_A, self._open_b = Pc, dc
        else:
            with np.errstate(over="ignore", invalid="ignore"):
                self._open_A, self._open_b = Pc @ self._open_A, Pc @ self._open_b + dc
        self._open_len += L
        if self._open_len >= seg or end == self.n:
            self.A.append(self._open_A[None])
            self.b.append(self._open_b[None])
            self._open_A, self._open_b, self._open_len = None, None, 0
        return Pc, dc


def _condense(elems, keep: bool, seg: int) -> _Condensed:
    """First pass: compute every chunk's transitions and condense the cyclic system.

    Composes ``Phi = A_{n-1} ... A_0`` and ``d`` chunk by chunk (constant
    ``A``: powers by :func:`_chain_invariant`; time-varying: pairwise products
    in worker threads), collects the segment transfers for a sparse LU and
    keeps what the second pass needs.

    Parameters
    ----------
    elems : transition source
        As in :func:`solve_cyclic` (``elems.chunk`` already planned).
    keep : bool
        Keep the ``A_k``.
    seg : int
        Elements per sparse-LU segment.

    Returns
    -------
    _Condensed
    """
    m = elems.m
    Phi, dvec = np.eye(m), np.zeros(m)
    kept_A, kept_b = [], []
    segments = _Segments(seg, elems.n, elems.workers)
    a_norm2 = 0.0
    t_exp = 0.0
    for a, b in elems.bounds():
        te = time.perf_counter()
        A, bvec = elems.compute(a, b)
        t_exp += time.perf_counter() - te
        if A.ndim == 2:
            Pc, dc = _chain_invariant(A, bvec)
        else:
            a_norm2 += float(np.einsum("kij,kij->", A, A))
            Pc, dc = segments.add(A, bvec, b)
        with np.errstate(over="ignore", invalid="ignore"):  # see _check_bounded
            Phi, dvec = Pc @ Phi, Pc @ dvec + dc
        if keep:
            kept_A.append(A)
        kept_b.append(bvec)
    if elems.invariant:
        a_norm2 = elems.n * float(np.sum(kept_A[0] * kept_A[0]))
    return _Condensed(Phi, dvec, kept_A, kept_b, segments.A, segments.b, a_norm2, t_exp)


def _check_bounded(pass1: _Condensed, n: int) -> None:
    """Raise :class:`~kedfem.errors.UnboundedResponseError` if ``Phi`` or ``d`` overflowed.

    Parameters
    ----------
    pass1 : _Condensed
        The condensed system.
    n : int
        Number of time elements (for the message).
    """
    if not (np.all(np.isfinite(pass1.Phi)) and np.all(np.isfinite(pass1.d))):
        raise UnboundedResponseError(
            f"response unbounded: the transition over one cycle ({n} time elements) overflows "
            "floating point, so the largest Floquet multiplier exceeds about 1e300 -- a violent "
            "parametric instability or buckling at this speed, negative damping, or a diverging "
            "non-linear iterate; no periodic response is returned", elements=n)


def _floquet_multipliers(Phi: np.ndarray) -> np.ndarray:
    """Eigenvalues of the monodromy ``Phi`` (m, m), shape (m,) complex, by decreasing modulus."""
    mult = np.linalg.eigvals(Phi)
    return mult[np.argsort(-np.abs(mult), kind="stable")]


def _balanced_condition(ImP: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Balance ``I - Phi`` and estimate its condition relative to the data ``I`` and ``Phi``.

    The condition is ``(1 + ||Phi||_2) / sigma_min(I - Phi)`` in balanced
    coordinates. Scale-free measures such as ``sigma_max / sigma_min`` miss
    ``I - Phi ~ 0`` (all multipliers 1).

    Parameters
    ----------
    ImP : ndarray, shape (m, m)
        ``I - Phi``.

    Returns
    -------
    Bal : ndarray, shape (m, m)
        ``D^-1 (I - Phi) D``.
    dsc : ndarray, shape (m,)
        The diagonal of ``D``.
    condition : float
        Condition estimate (``inf`` when singular).
    """
    Bal, dsc = balance(ImP)
    try:
        smin = float(np.linalg.svd(Bal, compute_uv=False)[-1])
        pnorm = float(np.linalg.norm(np.eye(ImP.shape[0]) - Bal, 2))
        condition = (1.0 + pnorm) / smin if smin > 0 else math.inf
    except np.linalg.LinAlgError:
        condition = math.inf
    return Bal, dsc, condition


def _check_resonance(mult: np.ndarray, condition: float, max_condition: float) -> bool:
    """Whether ``I - Phi`` is ill-conditioned but not singular; a ResonanceError if singular.

    A condition above ``max_condition`` with every multiplier farther than
    :data:`RESONANCE_GAP` from 1 is not singularity: it comes from ``Phi``'s
    non-normality (stiff modes with ``omega dt >> 1`` that no diagonal scaling
    balances together). Condensation would lose digits in ``z_0``; the sparse LU
    of the whole cyclic system is backward stable.

    Parameters
    ----------
    mult : ndarray, shape (m,)
        Floquet multipliers.
    condition : float
        Condition estimate of ``I - Phi`` (:func:`_balanced_condition`).
    max_condition : float
        Largest acceptable condition.

    Returns
    -------
    bool
        ``True`` when ``I - Phi`` is ill-conditioned but not singular.

    Raises
    ------
    ResonanceError
        Condition infinite, or above ``max_condition`` with a multiplier within
        :data:`RESONANCE_GAP` of 1.
    """
    near = mult[np.argmin(np.abs(mult - 1.0))]
    if math.isfinite(condition) and condition > max_condition and abs(near - 1.0) > RESONANCE_GAP:
        log.info("I - Phi has condition %.3g but no Floquet multiplier near 1 (nearest at |mu - 1| = %.3g): "
                 "solving the whole cyclic system by sparse LU", condition, abs(near - 1.0))
        return True
    if not math.isfinite(condition) or condition > max_condition:
        raise ResonanceError(
            f"I - Phi is numerically singular (condition number {condition:.3g} > {max_condition:.3g}): "
            f"Floquet multiplier {near.real:.15g}{near.imag:+.3g}j lies at |mu - 1| = "
            f"{abs(near - 1):.3g} from 1. The system has no unique periodic response: undamped "
            f"forcing at resonance, a free rigid-body mode (K singular with no damping), or an "
            f"incompletely constrained mechanism.", multiplier=complex(near), condition=condition)
    return False


def _choose_method(method: str, rho: float, ill_conditioned: bool) -> str:
    """``"condensation"`` or ``"cyclic-lu"``; warns of a parametric instability.

    Parameters
    ----------
    method : str
        Requested method; ``"auto"`` picks cyclic LU when the spectral radius
        ``rho`` exceeds ``1 + INSTABILITY_TOL`` or ``ill_conditioned``.
    rho : float
        Largest Floquet multiplier modulus.
    ill_conditioned : bool
        From :func:`_check_resonance`.

    Returns
    -------
    str
    """
    unstable = rho > 1.0 + INSTABILITY_TOL
    if method == "auto":
        method = "cyclic-lu" if (unstable or ill_conditioned) else "condensation"
    if unstable:  # stacklevel: the caller of solve_cyclic
        warnings.warn(f"parametric instability: largest Floquet multiplier |mu| = {rho:.6g} > 1; "
                      f"the periodic solution exists but is not attracting (solved by {method})",
                      InstabilityWarning, stacklevel=3)
    return method


def _solve_z0(ImP: np.ndarray, Bal: np.ndarray, dsc: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Solve ``(I - Phi) z_0 = d`` in balanced coordinates with one step of iterative refinement.

    Parameters
    ----------
    ImP : ndarray, shape (m, m)
        ``I - Phi``.
    Bal, dsc : ndarray, shapes (m, m) and (m,)
        Its balanced form and scaling (:func:`_balanced_condition`).
    d : ndarray, shape (m,)
        Particular part.

    Returns
    -------
    ndarray, shape (m,)
        The periodic state at ``t = 0`` (DOF units, per s for velocities).
    """
    z0 = dsc * np.linalg.solve(Bal, d / dsc)
    r = d - ImP @ z0
    return z0 + dsc * np.linalg.solve(Bal, r / dsc)


def _second_pass(elems, pass1: _Condensed, keep: bool):
    """Chunks again, as ``(a, b, A, bvec)``: the kept transitions, or recomputed (streaming)."""
    for ci, (a, b) in enumerate(elems.bounds()):
        A, bvec = (pass1.kept_A[ci], pass1.kept_b[ci]) if keep else elems.compute(a, b)
        yield a, b, A, bvec


def _march(chunks, z0: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """March the states ``z_{k+1} = A_k z_k + b_k`` from ``z0`` over all chunks.

    Parameters
    ----------
    chunks : iterable of (a, b, A, bvec)
        From :func:`_second_pass`.
    z0 : ndarray, shape (m,)
        Initial state.
    Z : ndarray, shape (n, m)
        Filled with the states at the element starts.

    Returns
    -------
    ndarray, shape (m,)
        The state after the last element (``z_n``, equal to ``z_0`` up to the residual).
    """
    z = z0
    for a, b, A, bvec in chunks:
        z = _propagate(A, bvec, z, Z[a:b])
    return z


def _solve_by_cyclic_lu(elems, pass1: _Condensed, keep: bool, seg: int, Z: np.ndarray) -> float:
    """Solve the block-cyclic system by sparse LU, on segments of ``seg`` elements.

    With ``seg > 1`` the LU gives the states at the segment starts and the
    states inside the segments are marched from them.

    Parameters
    ----------
    elems : transition source
    pass1 : _Condensed
    keep : bool
    seg : int
        Elements per segment.
    Z : ndarray, shape (n, m)
        Filled with the states.

    Returns
    -------
    float
        2-norm of the residual of the block-cyclic system.
    """
    if elems.invariant:
        A0 = pass1.kept_A[0]
        ball = np.concatenate(pass1.kept_b, axis=0)
        if seg == 1:
            sA, sb = np.broadcast_to(A0, (elems.n, elems.m, elems.m)), ball
        else:
            sA, sb = _segments_invariant(A0, ball, seg)
    else:
        sA, sb = np.concatenate(pass1.seg_A, axis=0), np.concatenate(pass1.seg_b, axis=0)
    Zs, rnorm = _cyclic_lu(sA, sb)
    if seg == 1:
        Z[:] = Zs
        return rnorm
    return _march_segments(_second_pass(elems, pass1, keep), Zs, seg, Z, rnorm)


def _march_segments(chunks, Zs: np.ndarray, seg: int, Z: np.ndarray, rnorm: float) -> float:
    """March the states inside the segments from their starts ``Zs``; add the closing residuals.

    Parameters
    ----------
    chunks : iterable of (a, b, A, bvec)
        From :func:`_second_pass`.
    Zs : ndarray, shape (S, m)
        States at the segment starts (elements ``0, seg, 2 seg, ...``).
    seg : int
        Elements per segment.
    Z : ndarray, shape (n, m)
        Filled with the states.
    rnorm : float
        Residual 2-norm of the segment system.

    Returns
    -------
    float
        Residual 2-norm including the mismatch of each segment's end with the next start.
    """
    n = Z.shape[0]
    S = Zs.shape[0]
    rn2 = rnorm ** 2
    z_carry = None  # state carried across chunk boundaries inside a segment
    for a, b, A, bvec in chunks:
        for s0 in range(a, b, seg):
            s1 = min(s0 + seg, b)
            k = s0 // seg
            Ak = A if A.ndim == 2 else A[s0 - a:s1 - a]
            if a <= k * seg and s1 == min((k + 1) * seg, n):
                z_end = _propagate(Ak, bvec[s0 - a:s1 - a], Zs[k], Z[s0:s1])
                rn2 += float(np.sum((z_end - Zs[(k + 1) % S]) ** 2))
            else:  # segment spanning chunks: continue from the stored state
                zs = Zs[k] if s0 == k * seg else z_carry
                z_carry = _propagate(Ak, bvec[s0 - a:s1 - a], zs, Z[s0:s1])
                if s1 == min((k + 1) * seg, n):
                    rn2 += float(np.sum((z_carry - Zs[(k + 1) % S]) ** 2))
    return math.sqrt(rn2)


def _relative_residual(rnorm: float, pass1: _Condensed, Z: np.ndarray) -> float:
    """Normwise relative residual ``||r|| / (||Acyc||_F ||z|| + ||c||)`` of the cyclic system.

    Parameters
    ----------
    rnorm : float
        ``||r||_2``.
    pass1 : _Condensed
        For ``sum ||A_k||_F**2`` and the ``b_k``.
    Z : ndarray, shape (n, m)
        The states.

    Returns
    -------
    float
    """
    n, m = Z.shape
    bnorm2 = sum(float(np.sum(bb * bb)) for bb in pass1.kept_b)
    denom = math.sqrt(pass1.a_norm2 + n * m) * float(np.linalg.norm(Z)) + math.sqrt(bnorm2)
    return rnorm / denom if denom > 0 else 0.0


def _overflow_is_checked(fn):
    """Run ``fn`` with numpy's overflow warnings off: an overflowing product of
    transitions means an unbounded response, which :func:`solve_cyclic` reports
    as :class:`~kedfem.errors.UnboundedResponseError` (errstate is per thread,
    so the products in worker threads need it too)."""
    import functools

    @functools.wraps(fn)
    def wrapped(*args, **kwargs):
        with np.errstate(over="ignore", invalid="ignore"):
            return fn(*args, **kwargs)
    return wrapped

@_overflow_is_checked
def _tree_parallel(A, b, workers):
    """``_tree_groups(A, b, len(A))`` with the parts composed in parallel worker threads.

    Each worker multiplies with one BLAS thread: OpenBLAS's own threads on these
    small products wait for a time slice on every call when the machine is shared
    (measured 10-40x slower condensation at N = 100 under load).
    """
    parts = _split(A.shape[0], workers, min_part=16)
    res = [None] * len(parts)

    def work(i, lo, hi):
        res[i] = _tree_groups(A[lo:hi], b[lo:hi], hi - lo)

    _run_parallel(work, parts)
    P, d = res[0]
    for Pi, di in res[1:]:
        P, d = Pi @ P, np.einsum("gij,gj->gi", Pi, d) + di
    return P, d


@_overflow_is_checked
def _tree_groups(A, b, g):
    """Compose consecutive groups of ``g`` affine maps ``z -> A_k z + b_k``.

    Returns the group transfers ``(A_{g-1} ... A_0, sum ...)`` for every group
    (the last group may be shorter), by pairwise (tree) products: each level is one
    batched matmul over all groups, so ``log2(g)`` numpy calls instead of ``g``.
    """
    L = A.shape[0]
    full = (L // g) * g
    outA, outb = [], []
    if full:
        GA = A[:full].reshape((full // g, g) + A.shape[1:])
        Gb = b[:full].reshape((full // g, g) + b.shape[1:])
        while GA.shape[1] > 1:
            h = GA.shape[1]
            e, o = slice(0, h - 1, 2), slice(1, h, 2)
            nA = GA[:, o] @ GA[:, e]
            nb = np.einsum("gkij,gkj->gki", GA[:, o], Gb[:, e]) + Gb[:, o]
            if h % 2:
                nA = np.concatenate([nA, GA[:, -1:]], axis=1)
                nb = np.concatenate([nb, Gb[:, -1:]], axis=1)
            GA, Gb = nA, nb
        outA.append(GA[:, 0])
        outb.append(Gb[:, 0])
    if full < L:
        rA, rb = _tree_groups(A[full:], b[full:], L - full)
        outA.append(rA)
        outb.append(rb)
    if len(outA) == 1:
        return outA[0], outb[0]
    return np.concatenate(outA), np.concatenate(outb)


@_overflow_is_checked
def _chain_invariant(A, bvec):
    """Transfer of a chunk of elements with constant A: (A**L, d)."""
    _, dseg = _scan_invariant(A, bvec, np.zeros(A.shape[0]))
    return np.linalg.matrix_power(A, len(bvec)), dseg


def _segments_invariant(A, bvec, seg):
    """Transfers of consecutive segments of ``seg`` elements (constant A)."""
    n, m = bvec.shape
    S = -(-n // seg)
    pad = S * seg - n
    B = np.concatenate([bvec, np.zeros((pad, m))]).reshape(S, seg, m)
    lens = np.full(S, seg)
    lens[-1] = seg - pad
    P = np.zeros((m, S))
    for i in range(seg):
        live = i < lens
        P[:, live] = A @ P[:, live] + B[live, i, :].T
    As = np.broadcast_to(np.linalg.matrix_power(A, seg), (S, m, m)).copy()
    if pad:
        As[-1] = np.linalg.matrix_power(A, int(lens[-1]))
    return As, P.T


def _cyclic_lu(blocks, rhs_b):
    """Backward-stable sparse LU (partial pivoting) of the cyclic system.

    Unknowns ``z_0 .. z_{S-1}``; block rows ``A_s z_s - z_{s+1} = -b_s`` with
    ``z_S = z_0``. Returns the states and the 2-norm of the residual after one
    step of iterative refinement.
    """
    S, m, _ = blocks.shape
    ii = np.arange(S * m).reshape(S, m)
    rows = np.concatenate([np.repeat(ii, m, axis=1).ravel(), ii.ravel()])
    cols = np.concatenate([np.tile(ii, (1, m)).ravel(), np.roll(ii, -1, axis=0).ravel()])
    vals = np.concatenate([np.ascontiguousarray(blocks).reshape(-1), -np.ones(S * m)])
    Acyc = sp.csc_matrix((vals, (rows, cols)), shape=(S * m, S * m))
    c = -np.ascontiguousarray(rhs_b).reshape(-1)
    lu = spla.splu(Acyc, diag_pivot_thresh=1.0)
    x = lu.solve(c)
    x = x + lu.solve(c - Acyc @ x)  # one step of iterative refinement
    rnorm = float(np.linalg.norm(Acyc @ x - c))
    return x.reshape(S, m), rnorm
