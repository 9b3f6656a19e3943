"""Element transitions of the collocation schemes.

:class:`_Elements` is the transition source of :func:`kedfem.solvers.cyclic.solve_cyclic` for a
collocation scheme: for a chunk of elements it solves the stage systems ``W a = q - R z_k``
(factorisations kept for other loads on request) and gives the affine maps ``z_{k+1} = P_k z_k
+ p_k`` (:meth:`~_Elements.compute`), the stage states (:meth:`~_Elements.stages`) and the
forced parts of another load (:meth:`~_Elements.load`). The equations are in
:mod:`kedfem.solvers.collocation`.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .batched_lu import lu_factor_stack, lu_solve_stack
from .parallel import _run_parallel, _split
from .state_space import _check_mass
from .tableaux import Tableau


class _Elements:
    """Transition source of :func:`kedfem.solvers.cyclic.solve_cyclic` for a collocation scheme.

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
                    lu, piv = lu_factor_stack(W)
                    lus[lo:hi], pivs[lo:hi] = lu, piv
                    X[lo:hi] = lu_solve_stack((lu, piv), rhs)
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
            Xq = lu_solve_stack(self._lu[(a, b)], q[..., None])[..., 0]
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
