"""Collocation time elements for the periodic steady state of ``M u'' + C u' + K u = Q``.

Each time element ``[t_k, t_k + h]`` is an implicit Runge-Kutta collocation
step (Hairer & Wanner, *Solving ODEs II*, IV.5): the equations of motion hold
exactly at the ``s`` collocation instants ``t_k + c_j h`` with the true
``M, C, K, Q`` of each instant, nothing is held over the element. With the
state ``z = [u; v]`` and the stage accelerations ``a_j = u''(t_k + c_j h)``::

    V_j = v_k + h sum_l A_jl a_l
    U_j = u_k + h c_j v_k + h^2 sum_l (A^2)_jl a_l
    M_j a_j + C_j V_j + K_j U_j = Q_j,          j = 1..s

is one linear system of size ``s N`` per element (no inverse of ``M``):
``W a = q - R z_k`` with blocks ``W_jl = delta_jl M_j + h A_jl C_j + h^2
(A^2)_jl K_j`` and ``R_j = [K_j, C_j + h c_j K_j]``. The element end is
``u_{k+1} = u_k + h v_k + h^2 (b A) a``, ``v_{k+1} = v_k + h b a``, so each
element is an affine map ``z_{k+1} = P_k z_k + p_k`` that goes through the
same block-cyclic condensation as the exponential holds
(:func:`kedfem.solvers.cyclic.solve_cyclic`): Floquet multipliers, instability
fallback and streaming are shared.

Schemes (``s`` stages; order at the element ends / stage order):

``"radau2"``, ``"radau3"``
    Radau IIA, orders 3 and 5 / 2 and 3. L-stable: modes the elements do not
    resolve (the stiff axial couplings of closed loops, ``omega h >> 1``) are
    damped to their quasi-static response at the exact ``K(t)`` of each
    instant instead of ringing. Stiffly accurate (``c_s = 1``).
``"gauss2"``, ``"gauss3"``
    Gauss-Legendre, orders 4 and 6 / 2 and 3. A-stable and symmetric:
    ``|R(iy)| = 1``, so it neither damps nor excites an undamped mode and the
    moduli of its Floquet multipliers do not hide a parametric instability;
    not L-stable, so stiff modes it does not resolve keep multipliers close
    to the unit circle (use Radau IIA for the response).

The response between element ends is the collocation polynomial of degree
``s`` through ``z_k`` and the stage states (:func:`dense`).

Here are the solve (:func:`solve`), its solution and the re-solve for other loads
(:class:`Resolver`); the schemes' tableaux, instants and polynomials are in
:mod:`~kedfem.solvers.tableaux`, the element transitions in
:mod:`~kedfem.solvers.collocation_elements`, the residuals in
:mod:`~kedfem.solvers.collocation_residual` (all importable from here too).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np
import scipy.linalg as sla

from ..errors import InputError
from . import collocation_residual as _residual
from .batched_lu import lu_solve_stack
from .collocation_elements import _Elements
from .collocation_residual import apply_at_instants, kinematic_defect, residual, stiffly_accurate
from .cyclic import solve_cyclic
from .inputs import MIN_NODES, _Source, check_period
from .monodromy import MAX_CONDITION
from .parallel import default_workers
from .tableaux import SCHEMES, Tableau, dense, instants, locate, tableau
from .threads import one_blas_thread

__all__ = ["Tableau", "tableau", "SCHEMES", "solve", "CollocationSolution", "dense", "instants", "residual",
           "stiffly_accurate", "kinematic_defect", "Resolver", "locate", "apply_at_instants"]

log = logging.getLogger(__name__)

# read as ``collocation._stage_accelerations`` by kedfem.solvers.defect (moved by issue 27)
_stage_accelerations = _residual._stage_accelerations


@dataclass(frozen=True)
class CollocationSolution:
    """Periodic steady state of a collocation discretisation.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Element starts [s] (``k T / n`` unless graded).
    U, V : ndarray, shape (n, N)
        Displacements and velocities at the element starts.
    stage_U, stage_V : ndarray, shape (n, s, N)
        The same at the collocation instants (``instants(scheme, n, T)``).
    scheme : str
    floquet_multipliers : ndarray of complex, shape (2N,)
        Eigenvalues of the discrete monodromy matrix, by decreasing modulus.
    stable : bool
    residual : float
        Relative residual of the block-cyclic system.
    monodromy : ndarray, shape (2N, 2N)
    method : str
        ``"condensation"`` or ``"cyclic-lu"``.
    period : float
    condition : float
        Condition estimate of ``I - Phi`` (balanced).
    passes : int
    timings : Mapping[str, float]
    edges : ndarray, shape (n + 1,)
        Element edges [s].
    """

    t: np.ndarray
    U: np.ndarray
    V: np.ndarray
    stage_U: np.ndarray
    stage_V: np.ndarray
    scheme: str
    floquet_multipliers: np.ndarray
    stable: bool
    residual: float
    monodromy: np.ndarray
    method: str
    period: float
    condition: float
    passes: int
    timings: Mapping[str, float] = field(default_factory=dict)
    edges: np.ndarray | None = None
    resolver: "Resolver | None" = field(default=None, repr=False, compare=False)

    @property
    def n(self) -> int:
        """Number of time elements."""
        return int(self.t.shape[0])

    @property
    def hold(self) -> str:
        """The scheme (the name the exponential holds use for theirs)."""
        return self.scheme

    @property
    def spectral_radius(self) -> float:
        """Largest Floquet multiplier modulus."""
        return float(np.abs(self.floquet_multipliers).max()) if self.floquet_multipliers.size else 0.0

    def at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Displacements and velocities at any instants of the cycle (collocation polynomial).

        Parameters
        ----------
        t : array_like of float, shape (k,)
            Instants [s] (taken modulo the period).

        Returns
        -------
        U, V : ndarray, shape (k, N)
        """
        N = self.U.shape[1]
        Z = np.concatenate([self.U, self.V], axis=1)
        S = np.concatenate([self.stage_U, self.stage_V], axis=2)
        out = dense(self.scheme, Z, S, self.period, t, self.edges)
        return out[:, :N], out[:, N:]


    def velocities(self, t) -> np.ndarray:
        """Velocities (k, N) at instants ``t`` (k,) [s] (the collocation polynomial of ``v`` alone)."""
        return dense(self.scheme, self.V, self.stage_V, self.period, t, self.edges)


class Resolver:
    """Another load on a solved collocation system: the same ``M, C, K`` and elements.

    Keeps the elements' LU factorisations of their stage matrices and the condensed cyclic
    system of a :func:`solve` (``factors=True``). A new load costs one triangular solve per
    element and two marches of the element transitions (``O(n (sN)^2)``), instead of the
    factorisations and products of a solve (``O(n (sN)^3)``): the correction of a chord
    (simplified Newton) step with a frozen tangent, a second right-hand side.
    """

    def __init__(self, elems: "_Elements", cyclic, base: "CollocationSolution"):
        self._elems = elems
        self._cyclic = cyclic
        self._base = base

    def solve(self, Q) -> "CollocationSolution":
        """The periodic response to the load ``Q`` (n s, N) [N] at the collocation instants.

        Returns
        -------
        CollocationSolution
            Multipliers, condition and method are those of the factorised system.
        """
        t0 = time.perf_counter()
        el, base = self._elems, self._base
        n, s, N = el.n, el.tab.s, el.N
        Q = np.asarray(Q, dtype=float).reshape(n, s, N)
        with one_blas_thread():
            parts = [el.load(a, b, Q[a:b]) for a, b in el.bounds()]
            Z, residual = self._cyclic.solve([p for p, _ in parts])
            SU = np.empty((n, s, N))
            SV = np.empty((n, s, N))
            for (a, b), (_p, Xq) in zip(el.bounds(), parts):
                SU[a:b], SV[a:b] = el.stages(a, b, Z[a:b], Xq)
        timings = MappingProxyType({"total": time.perf_counter() - t0})
        return dataclasses.replace(base, U=Z[:, :N].copy(), V=Z[:, N:].copy(), stage_U=SU, stage_V=SV,
                                   residual=float(residual), passes=0, timings=timings, resolver=self)

    def multipliers(self, dC=None, dK=None, lead: int = 4) -> np.ndarray:
        """Floquet multipliers of the system with ``C + dC``, ``K + dK``, to first order in them.

        The leading ``lead`` multipliers ``mu`` of the factorised monodromy ``Phi`` move by
        ``w^H dPhi v / w^H v`` (``v``, ``w`` its right and left eigenvectors), with
        ``dPhi v = sum_k P_{n-1}..P_{k+1} dP_k P_{k-1}..P_0 v`` and each element's ``dP_k`` from
        ``W^-1 (d(-R) z - dW a)``: a march of ``v`` forward and of ``w`` backward through the
        kept transitions, and a triangular solve per element. The others are returned as they
        were. For a tangent frozen at an iterate near the solution (a chord step): the
        multipliers of the orbit's own tangent, with an error of the order of the square of the
        change.

        Parameters
        ----------
        dC, dK : ndarray, shape (n s, N, N), optional
            Changes of ``C`` [N s/m] and ``K`` [N/m] at the collocation instants.
        lead : int
            Multipliers corrected (by decreasing modulus).

        Returns
        -------
        ndarray of complex, shape (2N,)
            By decreasing modulus.
        """
        el, base = self._elems, self._base
        tab, n, N = el.tab, el.n, el.N
        s, m = tab.s, 2 * N
        mu0 = base.floquet_multipliers
        if dC is None and dK is None:
            return mu0
        lam, wl, vr = sla.eig(base.monodromy, left=True, right=True)
        order = np.argsort(-np.abs(lam), kind="stable")
        q = min(lead, m)
        mod = np.abs(lam[order])
        while q < m and mod[q] >= mod[q - 1] * (1.0 - 1e-9):  # not half of a conjugate pair
            q += 1
        top = order[:q]
        lam, v, w = lam[top], vr[:, top], wl[:, top]
        # complex vectors as real pairs of columns [re | im]: every operator here is real
        v2 = np.concatenate([v.real, v.imag], axis=1)
        w2 = np.concatenate([w.real, w.imag], axis=1)
        with one_blas_thread():
            # forward r_k = P_{k-1}..P_0 v and backward l_k^H = w^H P_{n-1}..P_{k+1}
            R = np.empty((n, m, 2 * q))
            Lt = np.empty((n, m, 2 * q))
            P = [(a, b, A) for (a, b), A in zip(self._cyclic.bounds, self._cyclic.A)]
            r = v2
            for a, b, A in P:
                for k in range(a, b):
                    R[k] = r
                    r = (A if A.ndim == 2 else A[k - a]) @ r
            lk = w2
            for a, b, A in reversed(P):
                for k in range(b - 1, a - 1, -1):
                    Lt[k] = lk
                    lk = (A if A.ndim == 2 else A[k - a]).T @ lk
            dlam = np.zeros(q, dtype=complex)
            for a, b in el.bounds():
                L = b - a
                h = el.h[a:b]
                X = el._ops(a, b)[..., :m]  # W^-1 (-R), (L, sN, 2N)
                acc = (X @ R[a:b]).reshape(L, s, N, 2 * q)
                Ua = h[:, None, None, None] * np.einsum("jl,klnq->kjnq", tab.A, acc)
                Uaa = (h * h)[:, None, None, None] * np.einsum("jl,klnq->kjnq", tab.A2, acc)
                u, vv = R[a:b, None, :N], R[a:b, None, N:]
                hc = h[:, None, None, None] * tab.c[None, :, None, None]
                # d(-R) z - dW a: the stage forces of the changed C, K at the stage states
                rhs = np.zeros((L, s, N, 2 * q))
                if dK is not None:
                    rhs -= dK[a * s:b * s].reshape(L, s, N, N) @ (u + hc * vv + Uaa)
                if dC is not None:
                    rhs -= dC[a * s:b * s].reshape(L, s, N, N) @ (vv + Ua)
                rhs = rhs.reshape(L, s * N, 2 * q)
                if el.invariant:
                    da = sla.lu_solve(el._inv[0], rhs.transpose(1, 0, 2).reshape(s * N, -1),
                                      check_finite=False).reshape(s * N, L, 2 * q).transpose(1, 0, 2)
                else:
                    da = lu_solve_stack(el._lu[(a, b)], rhs)
                da = da.reshape(L, s, N, 2 * q)
                du = (h * h)[:, None, None] * np.einsum("j,kjnq->knq", tab.bA, da)
                dv = h[:, None, None] * np.einsum("j,kjnq->knq", tab.b, da)
                dPr = np.concatenate([du, dv], axis=1)  # (L, 2N, 2q)
                # l^H dP r with l = lr + i li, dP r = xr + i xi
                lr, li, xr, xi = Lt[a:b, :, :q], Lt[a:b, :, q:], dPr[..., :q], dPr[..., q:]
                dlam += (np.einsum("kmq,kmq->q", lr, xr) + np.einsum("kmq,kmq->q", li, xi)
                         + 1j * (np.einsum("kmq,kmq->q", lr, xi) - np.einsum("kmq,kmq->q", li, xr)))
        wv = np.einsum("mq,mq->q", w.conj(), v)
        out = mu0.copy()
        new = lam + dlam / wv
        # the corrected ones in place of the leading ones, sorted again by modulus
        out[:q] = new
        return out[np.argsort(-np.abs(out), kind="stable")]


def _resolve(name, Ms, Cs, Ks, Qs, n, s):
    counts = {src.name: src.n for src in (Ms, Cs, Ks, Qs) if src.n is not None}
    if n is not None:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
            raise InputError(f"n must be an integer, got {n!r}")
        counts["n * s"] = int(n) * s
    if not counts:
        raise InputError("cannot infer the number of time elements: pass n=...")
    if len(set(counts.values())) > 1:
        raise InputError("inconsistent numbers of collocation instants: "
                         + ", ".join(f"{k} has {v}" for k, v in counts.items()))
    total = next(iter(counts.values()))
    if total % s:
        raise InputError(f"{name} has {s} instants per element: the data must have a multiple "
                         f"of {s} rows (element k at rows k*{s}..k*{s}+{s - 1}), got {total}")
    n_ = total // s
    if n_ < MIN_NODES:
        raise InputError(f"need at least {MIN_NODES} time elements per period, got n = {n_}")
    Ns = {src.name: src.N for src in (Ms, Cs, Ks, Qs) if src.N is not None}
    if not Ns:
        out = np.asarray(Qs.value(np.array([0])))
        Ns[Qs.name] = out.shape[-1]
    if len(set(Ns.values())) > 1:
        raise InputError("inconsistent numbers of DOFs: " + ", ".join(f"{k} has {v}" for k, v in Ns.items()))
    return n_, next(iter(Ns.values()))


def solve(M, C, K, Q, period: float, scheme: str = "radau3", *, n: int | None = None,
          edges=None, method: str = "auto", memory_budget: float = 256e6,
          max_condition: float = MAX_CONDITION, workers: int | None = None,
          check_mass: bool = True, factors: bool = False) -> CollocationSolution:
    """Periodic steady state of ``M u'' + C u' + K u = Q`` by collocation time elements.

    Parameters
    ----------
    M, C, K : ndarray, shape (n s, N, N) or (N, N), or callable
        Mass [kg], damping [N s/m], stiffness [N/m] at the collocation
        instants :func:`instants` ``(scheme, n, period).ravel()`` (element by
        element), or constant; a callable ``f(idx)`` of instant indices.
    Q : ndarray, shape (n s, N), or callable
        Load [N] at the same instants.
    period : float
        Period ``T`` [s].
    scheme : {"radau2", "radau3", "gauss2", "gauss3"}
    n : int, optional
        Number of time elements (needed only when nothing is sampled).
    edges : array_like, shape (n + 1,), optional
        Element edges [s], increasing from 0 to ``period`` (graded
        elements; default ``k T / n``).
    method, memory_budget, max_condition, workers
        As in :func:`kedfem.solvers.periodic.solve`.
    check_mass : bool
        Check that ``M`` is positive definite at every instant (a Cholesky factorisation each);
        False for a caller that solved with the same ``M`` before (the iterations of a
        non-linear solve).
    factors : bool
        Keep the factorisations for other loads on the same system (the solution's
        :attr:`~CollocationSolution.resolver`, a :class:`Resolver`), where they fit a quarter
        of ``memory_budget`` and the system is condensed (not solved by the sparse LU of an
        unstable or ill-conditioned cycle); otherwise ``resolver`` is None.

    Returns
    -------
    CollocationSolution

    Raises
    ------
    InputError, SingularMassError, ResonanceError
        As :func:`kedfem.solvers.periodic.solve`.
    """
    t_start = time.perf_counter()
    tab = tableau(scheme)
    period = check_period(period)
    if not (isinstance(memory_budget, (int, float, np.integer, np.floating)) and memory_budget > 0):
        raise InputError(f"memory_budget must be a positive number of bytes, got {memory_budget!r}")
    Ms, Cs, Ks, Qs = (_Source("M", M, True), _Source("C", C, True), _Source("K", K, True),
                      _Source("Q", Q, False))
    n, N = _resolve(scheme, Ms, Cs, Ks, Qs, n, tab.s)
    if workers is None:
        workers = default_workers()
    elif not (isinstance(workers, (int, np.integer)) and workers >= 1):
        raise InputError(f"workers must be a positive integer or None, got {workers!r}")
    s = tab.s
    if edges is not None:
        edges = np.asarray(edges, dtype=float)
        if edges.shape != (n + 1,) or not np.all(np.diff(edges) > 0) \
                or abs(edges[0]) > 1e-12 * period or abs(edges[-1] - period) > 1e-12 * period:
            raise InputError(f"edges must be {n + 1} increasing instants from 0 to the period "
                             f"{period:.6g} s, got shape {edges.shape}")
    elems = _Elements(tab, Ms, Cs, Ks, Qs, n, N, period, int(workers), edges, check_mass=bool(check_mass))
    ops_bytes = n * s * N * (2 * N + 1) * 8
    elems.keep_ops = ops_bytes <= memory_budget / 4
    elems.keep_lu = bool(factors) and elems.keep_ops and n * (s * N) ** 2 * 8 <= memory_budget / 4
    per_element = 8.0 * (3 * (s * N) ** 2 + 4 * s * N * (2 * N + 1) + 3 * s * N * N)
    timings: dict[str, float] = {}
    with one_blas_thread():
        cyc = solve_cyclic(elems, per_element, method=method, memory_budget=memory_budget,
                           max_condition=max_condition, timings=timings, t_start=t_start,
                           factors=elems.keep_lu)
        t0 = time.perf_counter()
        SU = np.empty((n, s, N))
        SV = np.empty((n, s, N))
        for a, b in elems.bounds():
            SU[a:b], SV[a:b] = elems.stages(a, b, cyc.Z[a:b])
    timings["stages"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    log.debug("collocation.solve(%s): n=%d N=%d rho=%.4g %.3f s", scheme, n, N,
             float(np.abs(cyc.multipliers).max()) if cyc.multipliers.size else 0.0, timings["total"])
    sol = CollocationSolution(
        t=np.arange(n) * (period / n) if edges is None else edges[:-1].copy(),
        U=cyc.Z[:, :N].copy(), V=cyc.Z[:, N:].copy(),
        stage_U=SU, stage_V=SV, scheme=scheme, floquet_multipliers=cyc.multipliers,
        stable=cyc.stable, residual=cyc.residual, monodromy=cyc.monodromy, method=cyc.method,
        period=period, condition=cyc.condition, passes=cyc.passes + (0 if elems.keep_ops else 1),
        timings=MappingProxyType(timings), edges=edges)
    if cyc.factors is not None:
        sol = dataclasses.replace(sol, resolver=Resolver(elems, cyc.factors, sol))
    return sol
