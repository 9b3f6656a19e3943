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
(:func:`kedfem.solvers.periodic.solve_cyclic`): Floquet multipliers, instability
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
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field
from functools import lru_cache
from types import MappingProxyType
from typing import Mapping

import numpy as np
import scipy.linalg as sla
from numpy.polynomial import Polynomial
from numpy.polynomial import legendre as npleg

from ..errors import InputError
from .periodic import (MAX_CONDITION, MIN_NODES, _check_mass, _run_parallel, _Source, _split,
                       default_workers, solve_cyclic)
from .threads import one_blas_thread

__all__ = ["Tableau", "tableau", "SCHEMES", "solve", "CollocationSolution", "dense", "instants", "residual",
           "stiffly_accurate", "kinematic_defect", "Resolver", "locate", "apply_at_instants"]

log = logging.getLogger(__name__)

#: Collocation schemes: name -> (family, stages).
SCHEMES = {"radau2": ("radau", 2), "radau3": ("radau", 3), "gauss2": ("gauss", 2),
           "gauss3": ("gauss", 3)}


@dataclass(frozen=True)
class Tableau:
    """Butcher tableau of a collocation method.

    Attributes
    ----------
    name : str
    family : {"radau", "gauss"}
    c : ndarray, shape (s,)
        Collocation nodes as fractions of the element.
    A : ndarray, shape (s, s)
        ``A_ij = int_0^{c_i} l_j``, ``l_j`` the Lagrange basis on ``c``.
    b : ndarray, shape (s,)
        ``b_j = int_0^1 l_j``.
    order : int
        Classical order at the element ends (``2s - 1`` Radau IIA, ``2s`` Gauss).
    stage_order : int
        Order of the collocation polynomial between the ends (``s``).
    l_stable : bool
    """

    name: str
    family: str
    c: np.ndarray
    A: np.ndarray
    b: np.ndarray
    order: int
    stage_order: int
    l_stable: bool

    @property
    def s(self) -> int:
        """Number of stages."""
        return int(self.c.size)

    @property
    def A2(self) -> np.ndarray:
        """``A @ A``: the double integral of the stage accelerations."""
        return self.A @ self.A

    @property
    def bA(self) -> np.ndarray:
        """``b @ A``."""
        return self.b @ self.A


@lru_cache(maxsize=None)
def tableau(name: str) -> Tableau:
    """Tableau of a collocation scheme (see :data:`SCHEMES`), computed from its nodes.

    Gauss nodes are the zeros of the shifted Legendre polynomial ``P_s(2x-1)``;
    Radau IIA nodes the zeros of ``P_s(2x-1) - P_{s-1}(2x-1)`` (the last is 1).
    """
    if name not in SCHEMES:
        raise InputError(f"unknown collocation scheme {name!r}; valid: {', '.join(SCHEMES)}")
    family, s = SCHEMES[name]
    coef = np.zeros(s + 1)
    coef[s] = 1.0
    if family == "radau":
        coef[s - 1] = -1.0
    x = np.sort(npleg.legroots(coef).real)
    c = 0.5 * (x + 1.0)
    if family == "radau":
        c[-1] = 1.0
    A = np.empty((s, s))
    b = np.empty(s)
    for j in range(s):
        others = np.delete(c, j)
        lj = Polynomial.fromroots(others) / np.prod(c[j] - others)
        Lj = lj.integ()
        A[:, j] = Lj(c) - Lj(0.0)
        b[j] = Lj(1.0) - Lj(0.0)
    order = 2 * s - 1 if family == "radau" else 2 * s
    return Tableau(name, family, c, A, b, order, s, family == "radau")


def instants(name: str, n: int, period: float, edges=None) -> np.ndarray:
    """Collocation instants ``t_k + c_j h_k`` of ``n`` elements, shape (n, s) [s].

    ``edges`` (n + 1,) [s] gives non-uniform elements (default ``k T / n``).
    For Radau IIA the last instant of the last element is ``period`` itself.
    """
    tab = tableau(name)
    if edges is None:
        h = period / n
        return (np.arange(n)[:, None] + tab.c[None, :]) * h
    e = np.asarray(edges, dtype=float)
    return e[:-1, None] + tab.c[None, :] * np.diff(e)[:, None]


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
                    da = sla.lu_solve(el._lu[(a, b)], rhs, check_finite=False)
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


def dense(name: str, Z: np.ndarray, stages: np.ndarray, period: float, t, edges=None) -> np.ndarray:
    """Evaluate the collocation polynomials at instants ``t``.

    Parameters
    ----------
    name : str
        Scheme.
    Z : ndarray, shape (n, m)
        States at the element starts.
    stages : ndarray, shape (n, s, m)
        States at the collocation instants.
    period : float
        [s].
    t : array_like, shape (k,)
        Instants [s], taken modulo ``period``.
    edges : array_like, shape (n + 1,), optional
        Element edges [s] (default uniform).

    Returns
    -------
    ndarray, shape (k, m)
    """
    tab = tableau(name)
    k, theta = locate(t, Z.shape[0], period, edges)
    nodes = np.concatenate([[0.0], tab.c])
    # Lagrange weights on (0, c_1 .. c_s), shape (k, s + 1)
    diff = theta[:, None] - nodes[None, :]
    w = np.empty((theta.size, nodes.size))
    for j in range(nodes.size):
        others = np.delete(np.arange(nodes.size), j)
        w[:, j] = np.prod(diff[:, others], axis=1) / np.prod(nodes[j] - nodes[others])
    return w[:, :1] * Z[k] + np.einsum("ks,ksm->km", w[:, 1:], stages[k])


def locate(t, n: int, period: float, edges=None) -> tuple[np.ndarray, np.ndarray]:
    """Element (k,) of int and fraction in it (k,) of instants ``t`` [s] (taken modulo
    ``period``) on ``n`` elements, uniform or with ``edges`` (n + 1,) [s]."""
    tt = np.mod(np.asarray(t, dtype=float), period)
    if edges is None:
        x = tt * (n / period)
        k = np.minimum(np.floor(x).astype(int), n - 1)
        return k, x - k
    e = np.asarray(edges, dtype=float)
    k = np.clip(np.searchsorted(e, tt, side="right") - 1, 0, n - 1)
    return k, (tt - e[k]) / (e[k + 1] - e[k])


def apply_at_instants(X, Y) -> np.ndarray:
    """``X_t Y_t`` (n_t, N) for matrices ``X`` (n_t, N, N) at the instants, or one (N, N) for all,
    and vectors ``Y`` (n_t, N)."""
    X = np.asarray(X, dtype=float)
    return Y @ X.T if X.ndim == 2 else np.einsum("tij,tj->ti", X, Y)


# --------------------------------------------------------------------------
# Element transitions
# --------------------------------------------------------------------------

class _Elements:
    """Transition source of :func:`kedfem.solvers.periodic.solve_cyclic` for a collocation scheme.

    Data are given at the collocation instants, flattened element by element
    (instant ``k s + j`` is stage ``j`` of element ``k``).
    """

    def __init__(self, tab: Tableau, Ms, Cs, Ks, Qs, n, N, period, workers, edges=None, check_mass=True):
        self.tab = tab
        self.check_mass = check_mass
        self.Ms, self.Cs, self.Ks, self.Qs = Ms, Cs, Ks, Qs
        self.n, self.N, self.m = n, N, 2 * N
        self.h = np.full(n, period / n) if edges is None else np.diff(np.asarray(edges, float))
        self.workers = workers
        self.chunk = 1
        self.invariant = Ms.const and Cs.const and Ks.const and edges is None
        self._inv = None
        self._kept: dict[tuple[int, int], np.ndarray] = {}
        self.keep_ops = False
        #: keep each element's LU of ``W`` for other loads (:class:`Resolver`)
        self.keep_lu = False
        self._lu: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}

    def bounds(self):
        for a in range(0, self.n, self.chunk):
            yield a, min(self.n, a + self.chunk)

    def _data(self, a, b):
        s, N = self.tab.s, self.N
        idx = slice(a * s, b * s)
        L = b - a

        def get(src):
            X = src.get(idx, N)
            return X if X.ndim == 2 else X.reshape((L, s) + X.shape[1:])

        Q = self.Qs.get(idx, N).reshape(L, s, N)
        return get(self.Ms), get(self.Cs), get(self.Ks), Q

    def _W(self, M, C, K, h):
        """Stage matrices W, shape (L, sN, sN) (or (sN, sN) for constant data).

        ``h`` (L,) element lengths [s] (a scalar for constant data).
        """
        tab = self.tab
        s, N = tab.s, self.N
        const = M.ndim == 2
        if const:
            M, C, K = (np.broadcast_to(X, (s, N, N))[None] for X in (M, C, K))
        h = np.reshape(np.asarray(h, dtype=float), (-1,))
        L = max(M.shape[0], h.size)
        hA = h[:, None, None] * tab.A          # (L, s, s)
        h2A2 = (h * h)[:, None, None] * tab.A2
        W = np.empty((L, s, N, s, N))
        tmp = np.empty((L, N, N))
        # block (j, l): delta_jl M_j + h A_jl C_j + h^2 (A^2)_jl K_j, filled block by block (the
        # 5-D broadcast formed three (L, sN, sN) temporaries: 1.8x the time at N = 36, s = 3)
        for j in range(s):
            for ell in range(s):
                blk = W[:, j, :, ell, :]
                np.multiply(hA[:, j, ell, None, None], C[:, j], out=blk)
                if j == ell:
                    blk += M[:, j]
                np.multiply(h2A2[:, j, ell, None, None], K[:, j], out=tmp)
                blk += tmp
        W = W.reshape(L, s * N, s * N)
        return W[0] if const else W

    def _R(self, C, K, h):
        """``-R_j = -[K_j, C_j + h c_j K_j]``, shape (L, s, N, 2N) (or (s, N, 2N))."""
        tab = self.tab
        s, N = tab.s, self.N
        if K.ndim == 2:
            K = np.broadcast_to(K, (s, N, N))
            C = np.broadcast_to(C, (s, N, N))
            hc = (float(h) * tab.c)[:, None, None]
        else:
            hc = np.asarray(h, dtype=float)[:, None, None, None] * tab.c[None, :, None, None]
        return self._neg_R_into(C, K, hc, np.empty(K.shape[:-1] + (2 * N,)))

    @staticmethod
    def _neg_R_into(C, K, hc, out):
        """``out[..., :2N] = -[K_j, C_j + h c_j K_j]`` (``hc`` the ``h c_j`` broadcast to ``K``)."""
        N = K.shape[-1]
        np.negative(K, out=out[..., :N])
        right = out[..., N:2 * N]
        np.multiply(hc, K, out=right)
        right += C
        np.negative(right, out=right)
        return out

    def _ops(self, a, b):
        """``X = W^-1 [-R | q]`` per element, shape (L, sN, 2N + 1)."""
        key = (a, b)
        if key in self._kept:
            return self._kept[key]
        tab, N, s = self.tab, self.N, self.tab.s
        M, C, K, Q = self._data(a, b)
        L = b - a
        h = self.h[a:b]
        if self.invariant:
            if self._inv is None:
                _check_mass(M, np.array([0]))
                lu = sla.lu_factor(self._W(M, C, K, h[0]))
                XR = sla.lu_solve(lu, self._R(C, K, h[0]).reshape(s * N, 2 * N))
                self._inv = (lu, XR)
            lu, XR = self._inv
            Xq = sla.lu_solve(lu, Q.reshape(L, s * N).T).T
            X = np.concatenate([np.broadcast_to(XR, (L, s * N, 2 * N)), Xq[:, :, None]], axis=2)
        else:
            if self.check_mass:
                if M.ndim == 2:
                    _check_mass(M, np.array([0]))
                else:
                    _check_mass(M.reshape((L * s, N, N)), np.arange(a * s, b * s))
            X = np.empty((L, s * N, 2 * N + 1))
            Mb, Cb, Kb = (np.broadcast_to(X_, (L, s, N, N)) if X_.ndim == 2 else X_ for X_ in (M, C, K))
            hc = h[:, None, None, None] * tab.c[None, :, None, None]

            keep_lu = self.keep_lu
            if keep_lu:
                lus = np.empty((L, s * N, s * N))
                pivs = np.empty((L, s * N), dtype=np.int32)

            def work(i, lo, hi):
                W = self._W(Mb[lo:hi], Cb[lo:hi], Kb[lo:hi], h[lo:hi])
                rhs = np.empty((hi - lo, s, N, 2 * N + 1))  # [-R | q], written in place
                self._neg_R_into(Cb[lo:hi], Kb[lo:hi], hc[lo:hi], rhs)
                rhs[..., 2 * N] = Q[lo:hi]
                rhs = rhs.reshape(hi - lo, s * N, 2 * N + 1)
                if keep_lu:  # the same LAPACK factorisation as solve's, kept
                    lu, piv = sla.lu_factor(W, overwrite_a=True, check_finite=False)
                    if np.any(np.diagonal(lu, axis1=-2, axis2=-1) == 0.0):
                        raise np.linalg.LinAlgError("Singular matrix")
                    lus[lo:hi], pivs[lo:hi] = lu, piv
                    X[lo:hi] = sla.lu_solve((lu, piv), rhs, check_finite=False)
                else:
                    X[lo:hi] = np.linalg.solve(W, rhs)

            _run_parallel(work, _split(L, self.workers))
            if keep_lu:
                self._lu[key] = (lus, pivs)
        if self.keep_ops:
            self._kept[key] = X
        return X

    def compute(self, a, b):
        """Transitions ``(P (L, 2N, 2N), p (L, 2N))`` of elements ``a..b-1``."""
        tab, N, s = self.tab, self.N, self.tab.s
        h = self.h[a:b]
        X = self._ops(a, b).reshape(b - a, s, N * (2 * N + 1))
        # the stage sums b A a and b a of every element in one batched product
        Y = np.matmul(np.stack([tab.bA, tab.b]), X).reshape(b - a, 2, N, 2 * N + 1)
        du = (h * h)[:, None, None] * Y[:, 0]
        dv = h[:, None, None] * Y[:, 1]
        P = np.concatenate([du[..., :2 * N], dv[..., :2 * N]], axis=1)
        P[:, np.arange(N), np.arange(N)] += 1.0
        P[:, np.arange(N), N + np.arange(N)] += h[:, None]
        P[:, N + np.arange(N), N + np.arange(N)] += 1.0
        p = np.concatenate([du[..., 2 * N], dv[..., 2 * N]], axis=1)
        if self.invariant:
            return P[0], p
        return P, p

    def load(self, a, b, Q):
        """Forced parts ``p`` (L, 2N) of elements ``a..b-1`` for another load ``Q`` (L, s, N)
        at their instants, and ``W^-1 Q`` (L, s N): the kept factorisations, no new one."""
        tab, N, s = self.tab, self.N, self.tab.s
        L = b - a
        q = np.asarray(Q, dtype=float).reshape(L, s * N)
        if self.invariant:
            Xq = sla.lu_solve(self._inv[0], q.T, check_finite=False).T
        else:
            lu, piv = self._lu[(a, b)]
            Xq = sla.lu_solve((lu, piv), q[..., None], check_finite=False)[..., 0]
        h = self.h[a:b]
        Y = np.matmul(np.stack([tab.bA, tab.b]), Xq.reshape(L, s, N))  # (L, 2, N)
        p = np.concatenate([(h * h)[:, None] * Y[:, 0], h[:, None] * Y[:, 1]], axis=1)
        return p, Xq

    def stages(self, a, b, Z, Xq=None):
        """Stage states ``(U_j, V_j)`` of elements ``a..b-1`` from their start states Z (L, 2N)
        (``Xq``: ``W^-1 Q`` of another load, :meth:`load`)."""
        tab, N, s = self.tab, self.N, self.tab.s
        h = self.h[a:b, None, None]
        L = b - a
        X = self._ops(a, b).reshape(L, s, N, 2 * N + 1)
        forced = X[..., 2 * N] if Xq is None else Xq.reshape(L, s, N)
        acc = np.einsum("ljnk,lk->ljn", X[..., :2 * N], Z) + forced
        u0, v0 = Z[:, None, :N], Z[:, None, N:]
        V = v0 + h * np.einsum("jl,kln->kjn", tab.A, acc)
        U = u0 + h * tab.c[None, :, None] * v0 + h * h * np.einsum("jl,kln->kjn", tab.A2, acc)
        return U, V


def stiffly_accurate(name: str) -> bool:
    """The scheme's last stage is the element end (``c_s = 1``: Radau IIA), so the stage states
    alone determine the discrete solution and its residual (:func:`residual`)."""
    return bool(tableau(name).c[-1] == 1.0)


def residual(M, C, K, Q, U, V, period: float, scheme: str = "radau3", edges=None) -> np.ndarray:
    """Residual of the collocation equations at given stage states (a stiffly accurate scheme).

    The element start state is the last stage of the element before (periodically), the stage
    accelerations follow from the stage velocities, ``a = A^-1 (V - v_k) / h``, and the residual
    is ``M_j a_j + C_j V_j + K_j U_j - Q_j`` at every stage. Stage states from a periodic solve,
    and any linear combination of such states, satisfy the kinematic rows
    ``U_j = u_k + h sum_l A_jl V_l`` exactly, so this is the whole residual along Newton steps.
    Zero (to round-off) at the solution of :func:`solve` with the same data.

    Parameters
    ----------
    M, C, K : ndarray, shape (n s, N, N) or (N, N)
        At the collocation instants (element by element), or constant.
    Q : ndarray, shape (n s, N)
    U, V : ndarray, shape (n s, N)
        Stage displacements and velocities.
    period : float
        [s].
    scheme : str
        A stiffly accurate scheme (``"radau2"``, ``"radau3"``).
    edges : array_like, shape (n + 1,), optional
        Element edges [s] (default uniform).

    Returns
    -------
    ndarray, shape (n s, N)
        Force residual [N] (moments [N m] on rotational DOFs).
    """
    tab = tableau(scheme)
    if tab.c[-1] != 1.0:
        raise InputError(f"residual: scheme {scheme!r} is not stiffly accurate (its last stage is not the "
                         "element end)")
    U = np.asarray(U, dtype=float)
    V = np.asarray(V, dtype=float)
    _h, acc = _stage_accelerations(V, period, scheme, edges)
    acc = acc.reshape(U.shape)
    return (apply_at_instants(M, acc) + apply_at_instants(C, V) + apply_at_instants(K, U)
            - np.asarray(Q, dtype=float))


def kinematic_defect(U, V, period: float, scheme: str = "radau3", edges=None) -> float:
    """How far stage states are from satisfying the kinematic rows of a stiffly accurate scheme.

    With the element start the last stage of the element before and the stage accelerations
    ``a = A^-1 (V - v_k) / h``, the rows ``U_j = u_k + h c_j v_k + h^2 sum_l (A^2)_jl a_l``
    hold to round-off for the states of a :func:`solve` and their linear combinations, which
    :func:`residual` then measures whole; a state interpolated from other elements, or a
    relaxed step from one, does not satisfy them.

    Returns
    -------
    float
        ``max |U_j - (u_k + h c_j v_k + h^2 (A^2 a)_j)| / max |U|`` (0 for a zero state).
    """
    tab = tableau(scheme)
    U = np.asarray(U, dtype=float)
    V = np.asarray(V, dtype=float)
    h, acc = _stage_accelerations(V, period, scheme, edges)
    Ue = U.reshape(acc.shape)
    u0 = np.roll(Ue[:, -1], 1, axis=0)
    v0 = np.roll(V.reshape(acc.shape)[:, -1], 1, axis=0)
    pred = (u0[:, None] + (h[:, None, None] * tab.c[None, :, None]) * v0[:, None]
            + (h * h)[:, None, None] * np.einsum("jl,kln->kjn", tab.A2, acc))
    scale = float(np.abs(U).max()) if U.size else 0.0
    return float(np.abs(Ue - pred).max()) / scale if scale > 0 else 0.0


def _stage_accelerations(V, period: float, scheme: str, edges=None):
    """Element lengths ``h`` (n,) [s] and stage accelerations ``a = A^-1 (V_j - v_k) / h``
    (n, s, N) of stage velocities ``V`` (n s, N), the element start the last stage of the
    element before (a stiffly accurate scheme, periodic)."""
    s = tableau(scheme).s
    n = V.shape[0] // s
    h = np.full(n, period / n) if edges is None else np.diff(np.asarray(edges, dtype=float))
    Ve = V.reshape(n, s, -1)
    v0 = np.roll(Ve[:, -1], 1, axis=0)
    return h, np.einsum("jl,kln->kjn", _inverse_A(scheme), Ve - v0[:, None]) / h[:, None, None]


@lru_cache(maxsize=None)
def _inverse_A(name: str) -> np.ndarray:
    return np.linalg.inv(tableau(name).A)


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
    from .periodic import check_period
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
    log.info("collocation.solve(%s): n=%d N=%d rho=%.4g %.3f s", scheme, n, N,
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
