"""The batched scaling-and-squaring core of :func:`kedfem.solvers.expm.expm`.

The degree and backward-error bound of the approximants (diagonal Pade: the paper's Table 1;
truncated Taylor evaluated by Paterson-Stockmeyer), the degree and number of squarings that
cost least (:func:`_select`), and :func:`_exp_scaled_core`, the exponential of a balanced stack
with the exact diagonal and superdiagonal of triangular matrices (:func:`_fix_triangular`). The
method is described in :mod:`kedfem.solvers.expm`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

import numpy as np
from scipy.linalg.blas import daxpy as _daxpy

from ..checks import real
from ..errors import InputError
from .balancing import _inf_norm

# the records keep the logger they had before the split (issue 27): a filter on it still works
log = logging.getLogger("kedfem.solvers.expm")

#: Odd Pade degrees the cost-optimal ("auto") choice picks from. An odd degree
#: ``q`` costs ``(q + 1) // 2`` matrix products, the same as ``q - 1``.
_AUTO_DEGREES = (3, 5, 7, 9, 11, 13)
#: Pre-scaling cap: the powers A^2..A^14 of a matrix of norm <= 2**_PRESCALE_LOG2
#: cannot overflow.
_PRESCALE_LOG2 = 32


# --------------------------------------------------------------------------
# Pade degree, bound and coefficients
# --------------------------------------------------------------------------

def pade_error_bound(q: int) -> float:
    """Golub & Van Loan backward-error bound of the diagonal Pade approximant.

    ``eps(q) = 2**(3 - 2q) (q!)**2 / ((2q)! (2q+1)!)``: if ``||A|| <= 1/2`` then
    ``R_qq(A) = exp(A + E)`` with ``||E|| <= eps(q) ||A||``.

    Parameters
    ----------
    q : int
        Degree of numerator and denominator, ``q >= 0``.

    Returns
    -------
    float
    """
    q = int(q)
    if q < 0:
        raise InputError(f"pade_error_bound: q must be >= 0, got {q}")
    f = math.factorial
    return float(Fraction(2) ** (3 - 2 * q) * Fraction(f(q) ** 2, f(2 * q) * f(2 * q + 1)))


def pade_degree(delta: float) -> int:
    """Diagonal Pade degree for accuracy ``delta`` (the paper's step 2, Table 1).

    The paper's rule is "the least ``q`` with ``eps(q) <= delta``" where ``eps`` is
    :func:`pade_error_bound`; its Table 1 lists ``eps(q)`` rounded down to its
    decade (``eps(1) = 0.17 -> 1e-1``, ``eps(2) = 6.9e-4 -> 1e-4``, ...,
    ``eps(6) = 3.4e-16 -> 1e-16``). This function reads the rule at that same
    decade resolution, so Table 1 holds exactly: ``q = 1..6`` for ``delta = 1e-1,
    1e-4, 1e-6, 1e-9, 1e-13, 1e-16``. The remaining factor (< 10) is not lost:
    :func:`expm` chooses the scaling so that the bound at the actual scaled norm
    is ``<= delta``.

    Parameters
    ----------
    delta : float
        Requested relative backward error, ``0 < delta``.

    Returns
    -------
    int
        ``q >= 1``.
    """
    delta = real("expm", "delta", delta, positive=True)
    target = math.log10(delta) + 1e-12
    for q in range(1, 40):
        if math.floor(math.log10(pade_error_bound(q))) <= target:
            return q
    return 40


@lru_cache(maxsize=None)
def pade_coefficients(q: int) -> tuple[float, ...]:
    """Numerator coefficients ``c_k = (2q-k)! q! / ((2q)! k! (q-k)!)``, k = 0..q.

    The denominator is the numerator evaluated at ``-A``.
    """
    f = math.factorial
    return tuple(float(Fraction(f(2 * q - k) * f(q), f(2 * q) * f(k) * f(q - k)))
                 for k in range(q + 1))


def _theta_max(q: int, delta: float) -> float:
    """Largest scaled size ``theta`` for which the backward error is <= delta.

    The relative backward error of ``R_qq`` behaves as ``c_q theta**(2q)``; the
    Golub & Van Loan bound is this with a safety factor 8 at ``theta = 1/2``:
    ``eps(q) = 8 c_q (1/2)**(2q)``. Hence ``theta = (1/2) (delta/eps(q))**(1/2q)``.
    """
    return 0.5 * (delta / pade_error_bound(q)) ** (1.0 / (2 * q))


def _n_products(q: int) -> int:
    """Matrix products to evaluate R_qq by the even/odd split: A^2..A^(2p) and A*()."""
    return q // 2 + (1 if q >= 3 else 0)


# --------------------------------------------------------------------------
# Core scaling and squaring
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class ExpmInfo:
    """Diagnostics of one batched exponential.

    Attributes
    ----------
    approximant : str
        ``"pade"`` (diagonal Pade) or ``"taylor"`` (truncated Taylor series).
    degree : int
        Degree of the approximant used for the batch.
    squarings : ndarray of int, shape (batch,)
        Number of squarings per matrix (including any pre-scaling).
    products : int
        Matrix products per matrix spent evaluating the approximant (the Pade
        approximant needs one linear solve on top).
    """

    approximant: str
    degree: int
    squarings: np.ndarray
    products: int


#: Taylor degrees that are optimal for Paterson-Stockmeyer evaluation.
_TAYLOR_DEGREES = (2, 4, 6, 9, 12, 16, 20, 25, 30)
APPROXIMANTS = ("pade", "taylor")


def _ps_plan(p: int) -> tuple[int, int]:
    """Paterson-Stockmeyer block size ``s`` and product count for degree ``p``."""
    best = None
    for s in range(1, 9):
        r = p // s
        cost = (s - 1) + r - (1 if p % s == 0 else 0)
        if best is None or cost < best[1]:
            best = (s, cost)
    return best


def _ps_axpys(p: int) -> int:
    """Elementwise passes (axpy) of the Paterson-Stockmeyer evaluation of degree p."""
    s, _ = _ps_plan(p)
    return sum(1 for k in range(p + 1) if k % s != 0) + 1


def _taylor_theta(p: int, delta: float) -> float:
    """Largest scaled size with relative backward error ``theta**p/(p+1)! <= delta/2``."""
    return (math.factorial(p + 1) * delta / 2.0) ** (1.0 / p)


def _squarings(alpha: np.ndarray, theta: float) -> np.ndarray:
    """The paper's ``j = max(0, 1 + floor(log2(size)))`` with size in units of theta."""
    with np.errstate(divide="ignore"):
        j = 1.0 + np.floor(np.log2(np.maximum(alpha, 1e-300) / theta))
    return np.maximum(0, j).astype(int)


def _select(alpha, delta, degree, approximant, m=100):
    """(degree, theta, products) minimizing the estimated work.

    Work in units of one matrix product: products + squarings of the most demanding
    matrix of the batch, plus for the
    Taylor form its elementwise passes, each costing about ``min(0.35,
    2/sqrt(m))`` of a product for ``m x m`` matrices (measured, numpy/OpenBLAS).
    """
    if approximant == "pade":
        if degree != "auto":
            q = int(degree)
            return q, _theta_max(q, delta), _n_products(q)
        qmin = pade_degree(delta)
        cands = [q for q in _AUTO_DEGREES if q >= qmin] or [qmin]
        table = [(q, _theta_max(q, delta), _n_products(q)) for q in cands]
    else:
        if degree != "auto":
            p = int(degree)
            return p, _taylor_theta(p, delta), _ps_plan(p)[1]
        w = min(0.35, 2.0 / math.sqrt(max(m, 1)))
        table = [(p, _taylor_theta(p, delta), _ps_plan(p)[1], w * _ps_axpys(p))
                 for p in _TAYLOR_DEGREES]
    if approximant == "pade":
        table = [t + (0.0,) for t in table]
    best, best_cost = None, math.inf
    for deg, th, prod, extra in table:
        # the most demanding matrix decides: fewer squarings also mean less rounding
        # growth in the squaring phase, and a batch of similar matrices loses nothing
        cost = prod + extra + (float(np.max(_squarings(alpha, th))) if alpha.size else 0.0)
        if cost < best_cost - 1e-9:
            best, best_cost = (deg, th, prod), cost
    return best


def _axpy(a: float, x: np.ndarray, y: np.ndarray) -> None:
    """y += a x in place, one pass and no temporary (BLAS axpy for contiguous float64)."""
    if (y.dtype == np.float64 and x.dtype == np.float64 and y.flags.c_contiguous
            and x.flags.c_contiguous):
        _daxpy(x.reshape(-1), y.reshape(-1), a=a)
    else:
        y += a * x


def _add_diag(X: np.ndarray, c) -> None:
    """X[..., i, i] += c in place (c scalar or per-matrix (b,))."""
    m = X.shape[-1]
    v = X.reshape(X.shape[0], m * m)[:, ::m + 1]
    v += np.asarray(c)[:, None] if np.ndim(c) else c


def _exp_scaled_core(B: np.ndarray, delta: float, degree: int | str = "auto",
                     triangular: bool = True, approximant: str = "pade", *,
                     copy: bool = True, norm_bound: np.ndarray | None = None
                     ) -> tuple[np.ndarray, ExpmInfo]:
    """exp of a stack (b, m, m) already balanced. Returns (E, info).

    Scaling: ``j = max(0, 1 + floor(log2(alpha / theta)))`` per matrix where
    ``alpha = min(||B||, ||B^2||^(1/2))`` (for the Pade degrees >= 6 also
    ``max(||B^4||^(1/4), ||B^6||^(1/6))``) bounds the relative backward error
    ``sum_k |h_k| ||B^k|| / ||B|| <= sum_k |h_k| alpha^(k-1)`` (Al-Mohy & Higham
    2009, Thm 4.2, with the odd powers handled by one factor ``||B||``), and
    ``theta`` is the largest size for which the approximant's backward error is
    ``<= delta``. ``copy=False`` lets the core overwrite ``B``; ``norm_bound``
    (an upper bound of ``||B||_inf`` per matrix) saves computing the norm.
    """
    if approximant not in APPROXIMANTS:
        raise InputError(f"unknown approximant {approximant!r}; valid: {', '.join(APPROXIMANTS)}")
    nb, m, _ = B.shape
    if nb == 0 or m == 0:
        deg = pade_degree(delta) if degree == "auto" else int(degree)
        return B.copy(), ExpmInfo(approximant, deg, np.zeros(nb, dtype=int), 0)
    dtype = np.result_type(B.dtype, np.float64)
    B = B.astype(dtype, copy=copy)
    nrm = _inf_norm(B) if norm_bound is None else np.asarray(norm_bound, dtype=float)
    # pre-scaling so that the powers cannot overflow
    with np.errstate(divide="ignore"):
        s0 = np.maximum(0, np.ceil(np.log2(np.maximum(nrm, 1e-300))) - _PRESCALE_LOG2).astype(int)
    if np.any(s0):
        B *= np.exp2(-s0)[:, None, None]
        nrm = nrm * np.exp2(-s0)
    B_unscaled = B.copy() if triangular else None
    X2 = B @ B
    alpha = np.minimum(nrm, np.sqrt(_inf_norm(X2)))
    deg, theta, products = _select(alpha, delta, degree, approximant, m)

    if approximant == "pade":
        q = deg
        c = pade_coefficients(q)
        p = q // 2  # even powers B^2 .. B^(2p)
        P = np.empty((max(p, 1), nb, m, m), dtype=dtype)
        if p >= 1:
            P[0] = X2
        for i in range(1, p):
            np.matmul(P[i - 1], X2, out=P[i])
        if p >= 3:
            d46 = np.maximum(_inf_norm(P[1]) ** 0.25, _inf_norm(P[2]) ** (1.0 / 6.0))
            alpha = np.minimum(alpha, d46)
        j = _squarings(alpha, theta)
        sc = np.exp2(-j.astype(float))
        if np.any(j):
            for i in range(p):
                P[i] *= (sc ** (2 * i + 2))[:, None, None]
            B *= sc[:, None, None]
        # V = sum_even c_k A^k, U = A sum_odd c_k A^(k-1), accumulated in place
        V = np.zeros_like(B)
        inner = np.zeros_like(B)
        for i in range(p):
            _axpy(c[2 * i + 2], P[i], V)
            if 2 * i + 3 <= q:
                _axpy(c[2 * i + 3], P[i], inner)
        _add_diag(V, c[0])
        _add_diag(inner, c[1] if q >= 1 else 0.0)
        del P
        U = B @ inner if q >= 1 else np.zeros_like(B)
        del inner
        Dn = V - U
        V += U
        del U
        E = np.linalg.solve(Dn, V)
        del Dn, V
    else:
        pdeg = deg
        j = _squarings(alpha, theta)
        sc = np.exp2(-j.astype(float))
        if np.any(j):
            B *= sc[:, None, None]
            X2 *= (sc * sc)[:, None, None]
        s, _ = _ps_plan(pdeg)
        r = pdeg // s
        P = [B, X2][:s]  # powers B^1 .. B^s of the scaled matrix
        for _ in range(2, s):
            P.append(P[-1] @ B)
        coef = [1.0 / math.factorial(k) for k in range(pdeg + 1)]

        def add_block(T, i):
            """T += sum_{l=1}^{s-1} coef[i s + l] B^l + coef[i s] I (in place)."""
            for l in range(1, s):
                if i * s + l <= pdeg:
                    _axpy(coef[i * s + l], P[l - 1], T)
            _add_diag(T, coef[i * s])

        Xs = P[s - 1]
        T = np.empty_like(B)
        if pdeg % s == 0 and r >= 1:  # top block is coef[p] I: no product needed
            np.multiply(Xs, coef[pdeg], out=T)
            add_block(T, r - 1)
            start = r - 2
        else:
            T.fill(0.0)
            add_block(T, r)
            start = r - 1
        buf = np.empty_like(T)
        for i in range(start, -1, -1):
            np.matmul(T, Xs, out=buf)
            add_block(buf, i)
            T, buf = buf, T
        E = T
        del P, buf, X2

    # total squarings: j for the scaling plus s0 for the pre-scaling
    J = j + s0
    # triangular matrices: exact diagonal / superdiagonal during squaring
    # (Al-Mohy & Higham 2009, sec. 2), computed from the unscaled matrix
    tri = None
    if triangular and m > 1:
        low = np.tril_indices(m, -1)
        tri = ~np.any(B_unscaled[:, low[0], low[1]] != 0, axis=1)
        if tri.any():
            Bt = B_unscaled * np.exp2(s0.astype(float))[:, None, None]  # undo the pre-scaling
            _fix_triangular(E, Bt, tri, J, 0)
        else:
            tri = None
    jmax = int(J.max())
    if jmax > 0:
        if tri is None and np.all(J == jmax):
            buf = np.empty_like(E)
            for _ in range(jmax):
                np.matmul(E, E, out=buf)
                E, buf = buf, E
        else:
            order = np.argsort(-J, kind="stable")
            inv = np.empty_like(order)
            inv[order] = np.arange(nb)
            Es = E[order]
            Js = J[order]
            Bs = Bt[order] if tri is not None else None
            tris = tri[order] if tri is not None else None
            for it in range(jmax):
                cnt = int(np.count_nonzero(Js > it))
                Es[:cnt] = Es[:cnt] @ Es[:cnt]
                if tris is not None:
                    _fix_triangular(Es[:cnt], Bs[:cnt], tris[:cnt], Js[:cnt], it + 1)
            E = Es[inv]
    log.debug("expm core: %d matrices of order %d, %s degree %d, squarings %d..%d",
              nb, m, approximant, deg, int(J.min()), int(J.max()))
    return E, ExpmInfo(approximant, int(deg), J, int(products))


def _sinhc(x: np.ndarray) -> np.ndarray:
    small = np.abs(x) < 1e-7
    xs = np.where(small, 1.0, x)
    return np.where(small, 1.0 + x * x / 6.0, np.sinh(xs) / xs)


def _fix_triangular(E, B, tri, j, step):
    """Recompute diag and first superdiagonal of exp(B 2^(step - j)) exactly."""
    sel = np.nonzero(tri)[0]
    if sel.size == 0:
        return
    m = B.shape[-1]
    scale = np.exp2((step - j[sel]).astype(float))[:, None]
    diag = B[sel][:, np.arange(m), np.arange(m)] * scale
    with np.errstate(over="ignore", invalid="ignore"):
        ed = np.exp(diag)
        a, c = diag[:, :-1], diag[:, 1:]
        sup = B[sel][:, np.arange(m - 1), np.arange(1, m)] * scale
        far = np.abs(a - c) >= 1.0
        dd = np.where(far, a - c, 1.0)
        esup = sup * np.where(far, (np.exp(a) - np.exp(c)) / dd,
                              np.exp(0.5 * (a + c)) * _sinhc(0.5 * (a - c)))
    sub = E[sel]
    sub[:, np.arange(m), np.arange(m)] = ed
    sub[:, np.arange(m - 1), np.arange(1, m)] = esup
    E[sel] = sub
