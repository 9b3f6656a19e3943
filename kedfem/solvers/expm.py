"""Batched matrix exponential and the exact discretization of one time element.

The matrix exponential follows the paper's variable scaling-and-squaring method
(Wang, Liu & Yuan, DETC2002, section 2; Golub & Van Loan alg. 11.3.1): scale ``A``
by ``2**-j``, evaluate the diagonal Pade approximant of degree ``q`` chosen from
the accuracy ``delta`` (paper Table 1), square ``j`` times. Three refinements make
it robust on the matrices the paper's algorithm fails on:

* **balancing**: a diagonal similarity by powers of two (exact, undone exactly)
  so that a stiff state matrix is scaled by its spectral size ``omega_max dt``
  rather than by ``||M^-1 K|| dt ~ omega_max**2 dt``;
* **power norms**: ``j`` is computed from ``min(||A^2||^(1/2), max(||A^4||^(1/4),
  ||A^6||^(1/6)))`` (Al-Mohy & Higham 2009) instead of ``||A||``, which avoids
  overscaling of nearly triangular / non-normal matrices. The powers are the ones
  the Pade evaluation needs anyway, so this costs nothing;
* **exact bound**: the Golub & Van Loan backward-error bound is evaluated at the
  actual scaled norm, so the requested ``delta`` truly holds (the paper's
  ``j = 1 + floor(log2 ||A||)`` leaves ``||A/2^j||`` up to 1, outside the bound's
  hypothesis ``<= 1/2``), and for triangular matrices the diagonal and first
  superdiagonal are recomputed exactly during squaring.

Everything works on a stack ``(..., m, m)`` at once; matrices needing different
numbers of squarings are sorted so that each squaring step is one batched matmul
on a contiguous prefix of the stack. ``approximant="taylor"`` replaces the Pade
approximant by a truncated Taylor series evaluated by Paterson-Stockmeyer under
the same scaling rule and backward-error target: no linear solve, which in a
batch is the expensive part (the periodic solver's default; ``docs/solver.md``).

Discretization helpers (used by :mod:`kedfem.solvers.periodic`, usable on their own):
:func:`affine_exponential` gives ``A = exp(F dt)`` and the affine part ``b`` of
``z' = F z + g(s)`` with ``g`` constant or linear over the element from ONE
exponential of an augmented matrix (Van Loan 1978); :func:`second_order_transition`
does the same for ``F = [[0, I], [-M^-1 K, -M^-1 C]]`` building the balanced
augmented matrix directly; :func:`exponential_integrals` gives the operators ``A,
Gamma0, Gamma1`` that map a whole sampled forcing at once when ``F`` is
time-invariant.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

import numpy as np
from scipy.linalg.blas import daxpy as _daxpy

from ..checks import choice, flag, integer, real
from ..errors import InputError

__all__ = [
    "expm",
    "taylor_expm",
    "pade_degree",
    "pade_error_bound",
    "pade_coefficients",
    "balance",
    "second_order_scaling",
    "affine_exponential",
    "second_order_transition",
    "exponential_integrals",
    "ExpmInfo",
    "APPROXIMANTS",
]

log = logging.getLogger(__name__)

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
# Balancing
# --------------------------------------------------------------------------

def _inf_norm(X: np.ndarray) -> np.ndarray:
    return np.abs(X).sum(axis=-1).max(axis=-1)


def balance(A: np.ndarray, max_iter: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Diagonal balancing by powers of two, batched over leading axes.

    Finds ``d`` (powers of two) such that ``B = D^-1 A D`` (``D = diag(d)``) has
    comparable off-diagonal row and column norms (Osborne / LAPACK ``gebal``
    scaling, without permutations). All indices are updated simultaneously,
    with step halving where a step does not reduce the off-diagonal norm, so the
    whole stack is processed by vectorized numpy operations. Because ``d`` holds
    powers of two, ``B`` is exact and ``exp(A) = D exp(B) D^-1`` is undone
    exactly. Per matrix, the balancing is kept only if it reduces ``||A||_inf``.

    Parameters
    ----------
    A : ndarray, shape (..., m, m)
    max_iter : int
        Maximum number of simultaneous sweeps.

    Returns
    -------
    B : ndarray, shape (..., m, m)
    d : ndarray, shape (..., m)
        Real powers of two.
    """
    A = np.asarray(A)
    m = A.shape[-1]
    batch = A.shape[:-2]
    absA = np.abs(A).reshape((-1, m, m)).astype(float)
    nb = absA.shape[0]
    idx = np.arange(m)
    absA[:, idx, idx] = 0.0
    # entries below 1e-150 of the largest do not steer the scaling (a subnormal
    # entry would ask for factors 2^+-537 whose ratios overflow)
    big = absA.reshape(nb, -1).max(axis=1)
    absA[absA < (1e-150 * big)[:, None, None]] = 0.0
    x = np.zeros((nb, m))  # log2 of d

    def offnorm(xx):
        # sum_ij |a_ij| 2^(x_j - x_i)
        w = np.exp2(xx)
        return np.einsum("bij,bj,bi->b", absA, w, 1.0 / w)

    cur = offnorm(x)
    active = np.ones(nb, dtype=bool)
    for _ in range(max_iter):
        if not active.any():
            break
        w = np.exp2(x)
        Bm = absA * (w[:, None, :] / w[:, :, None])
        r = Bm.sum(axis=2)  # row sums
        c = Bm.sum(axis=1)  # column sums
        ok = (r > 0) & (c > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(ok, np.round(0.5 * (np.log2(np.where(ok, r, 1.0)) - np.log2(np.where(ok, c, 1.0)))),
                            0.0)
        step[~active] = 0.0
        if not np.any(step):
            break
        improved = np.zeros(nb, dtype=bool)
        trial_step = step
        for _half in range(6):
            xt = x + trial_step
            val = offnorm(xt)
            better = (val < cur * (1 - 1e-12)) & ~improved & active & np.any(trial_step != 0, axis=1)
            x[better] = xt[better]
            cur[better] = val[better]
            improved |= better
            if improved[active].all():
                break
            trial_step = np.trunc(trial_step / 2.0)
            if not np.any(trial_step):
                break
        active &= improved
    d = np.exp2(x)
    B = A.reshape((-1, m, m)) * (d[:, None, :] / d[:, :, None])
    # keep the balancing only where it reduces the inf-norm
    keep = _inf_norm(B) < _inf_norm(A.reshape((-1, m, m)))
    d[~keep] = 1.0
    B[~keep] = A.reshape((-1, m, m))[~keep]
    return B.reshape(A.shape), d.reshape(batch + (m,))


_balance = balance  # expm's argument ``balance`` shadows the function name there


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


def _as_stack(A: np.ndarray, name: str = "A") -> tuple[np.ndarray, tuple]:
    try:
        A = np.asarray(A)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a numeric array of shape (..., m, m)") from None
    if A.ndim < 2 or A.shape[-1] != A.shape[-2]:
        raise InputError(f"{name} must have shape (..., m, m), got {A.shape}")
    if not np.issubdtype(A.dtype, np.number) or np.issubdtype(A.dtype, np.bool_):
        raise InputError(f"{name} must be numeric, got dtype {A.dtype}")
    if np.issubdtype(A.dtype, np.integer):
        A = A.astype(float)
    bad = ~np.isfinite(A)
    if bad.any():
        first = tuple(int(i) for i in np.argwhere(bad)[0])
        raise InputError(f"{name} has a non-finite entry at index {first}")
    m = A.shape[-1]
    return A.reshape((-1, m, m)), A.shape


def expm(A: np.ndarray, delta: float = 1e-15, balance: bool = True, *,
         degree: int | str | None = None, approximant: str = "pade",
         return_info: bool = False):
    """Matrix exponential of one matrix or of a stack, by scaling and squaring.

    Parameters
    ----------
    A : array_like, shape (m, m) or (..., m, m)
        Real or complex. A stack is processed at once (no Python loop over it).
    delta : float
        Requested relative backward error: the result is ``exp(A + E)`` with
        ``||E|| <~ delta ||A||`` (Golub & Van Loan bound at the actual scaled
        norm). Default 1e-15.
    balance : bool
        Apply power-of-two diagonal balancing (:func:`balance`) first.
    degree : int or "auto" or None
        Degree of the approximant. ``None`` (default): for Pade the paper's
        :func:`pade_degree` of ``delta``, for Taylor ``"auto"``. ``"auto"``: the
        cheapest degree (products plus squarings) meeting ``delta`` (for Pade
        among the odd degrees ``>= pade_degree(delta)``).
    approximant : {"pade", "taylor"}
        Diagonal Pade approximant (the paper; needs one linear solve) or a
        truncated Taylor series evaluated by Paterson-Stockmeyer (no solve). Both
        use the same scaling rule and meet the same backward-error bound.
    return_info : bool
        Also return an :class:`ExpmInfo`.

    Returns
    -------
    E : ndarray, same shape as ``A``
    info : ExpmInfo, only if ``return_info``

    Notes
    -----
    Scaling exponent per matrix: ``j = max(0, 1 + floor(log2(eta / theta)))``,
    the paper's formula with ``||A||_inf`` replaced by the power-norm size
    ``eta`` of the balanced matrix and measured in units of ``theta``, the
    largest scaled size for which the approximant's backward-error bound is
    ``<= delta``. Triangular matrices get their diagonal and first superdiagonal
    recomputed exactly at every squaring.
    """
    A_st, shape = _as_stack(A)
    return_info = flag("expm", "return_info", return_info)
    choice("expm", "approximant", approximant, APPROXIMANTS)
    balance = flag("expm", "balance", balance)
    if degree is None:
        degree = pade_degree(delta) if approximant == "pade" else "auto"
    elif not (isinstance(degree, str) and degree == "auto"):
        degree = integer("expm", "degree", degree, 1, 30)
    pade_degree(delta)  # validates delta
    if balance and A_st.shape[-1] > 1:
        Bst, d = _balance(A_st)
    else:
        Bst, d = A_st, None
    E, info = _exp_scaled_core(Bst, float(delta), degree, approximant=approximant)
    if d is not None:
        E = E * (d[:, :, None] / d[:, None, :])
    E = E.reshape(shape)
    return (E, info) if return_info else E


def taylor_expm(A: np.ndarray, tol: float = 1e-16, max_terms: int = 500) -> np.ndarray:
    """The paper's literal truncated Taylor series ``sum_k A^k / k!`` (Eq. 6, 9).

    No scaling, no balancing: kept for comparison. It is accurate only for small
    ``||A||``; for large norms the terms grow to ``||A||^k / k!`` before
    decaying and cancellation destroys the result, or the terms overflow (the
    result is then ``inf``/``nan``; no warning is raised). Batched.

    Parameters
    ----------
    A : array_like, shape (m, m) or (..., m, m)
    tol : float
        Stop when ``||term||_inf <= tol * ||sum||_inf`` for every matrix.
    max_terms : int
        Hard limit on the number of terms.

    Returns
    -------
    ndarray, same shape as ``A``
    """
    A_st, shape = _as_stack(A)
    m = A_st.shape[-1]
    S = np.broadcast_to(np.eye(m, dtype=np.result_type(A_st.dtype, float)), A_st.shape).copy()
    T = S.copy()
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(1, max_terms + 1):
            T = (T @ A_st) / k
            S += T
            tn = _inf_norm(T)
            sn = _inf_norm(S)
            if np.all((tn <= tol * sn) | ~np.isfinite(sn)):
                break
    return S.reshape(shape)


# --------------------------------------------------------------------------
# Discretization of one time element (Van Loan augmented exponentials)
# --------------------------------------------------------------------------

def _pow2(x: np.ndarray) -> np.ndarray:
    """Nearest power of two (elementwise), 1 where x is 0 or not finite."""
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x) & (x > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.where(ok, np.round(np.log2(np.where(ok, x, 1.0))), 0.0)
    return np.exp2(np.clip(e, -300, 300))


def second_order_scaling(Fd: np.ndarray) -> np.ndarray:
    """Diagonal scaling ``d`` (powers of two) balancing a second-order state matrix.

    For ``Fd = [[0, dt I], [-S dt, -D dt]]`` (``S = M^-1 K``, ``D = M^-1 C``) the
    displacement components are scaled so that the off-diagonal row and column
    norms of each displacement index agree: ``sigma_i = 2**round(log2(sqrt(r_i /
    c_i)))`` with ``r_i`` the row norm and ``c_i`` the column norm of index ``i``.
    Since the displacement-displacement block is zero this single Osborne sweep is
    already the balanced point for those indices; it turns ``||Fd|| ~ omega_max**2
    dt`` into ``~ omega_max dt``. Velocities keep scale 1.

    Parameters
    ----------
    Fd : ndarray, shape (..., 2N, 2N)

    Returns
    -------
    d : ndarray, shape (..., 2N)
        ``B = D^-1 Fd D`` with ``D = diag(d)`` is the balanced matrix.
    """
    m = Fd.shape[-1]
    N = m // 2
    absF = np.abs(Fd)
    r = absF[..., :N, :].sum(axis=-1) - np.abs(np.diagonal(Fd, axis1=-2, axis2=-1)[..., :N])
    c = absF[..., :, :N].sum(axis=-2) - np.abs(np.diagonal(Fd, axis1=-2, axis2=-1)[..., :N])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where((r > 0) & (c > 0), r / np.where(c > 0, c, 1.0), 1.0)
    sigma = _pow2(np.sqrt(ratio))
    ones = np.ones(Fd.shape[:-2] + (m - N,))
    return np.concatenate([sigma, ones], axis=-1)


def _state_scaling(Fd: np.ndarray, scaling) -> np.ndarray | None:
    if scaling is None or scaling is False:
        return None
    if isinstance(scaling, str):
        if scaling == "second-order":
            if Fd.shape[-1] % 2:
                raise InputError("scaling='second-order' needs an even state dimension")
            return second_order_scaling(Fd)
        if scaling in ("general", "auto"):
            return balance(Fd)[1]
        raise InputError(f"unknown scaling {scaling!r}; valid: None, 'general', 'second-order'")
    d = np.asarray(scaling, dtype=float)
    if d.shape[-1] != Fd.shape[-1]:
        raise InputError(f"scaling must have length {Fd.shape[-1]}, got shape {d.shape}")
    return _pow2(d)  # force powers of two so that the similarity is exact


def affine_exponential(F: np.ndarray, dt: float, g0: np.ndarray, g1: np.ndarray | None = None,
                       *, delta: float = 1e-15, scaling="general", degree="auto",
                       approximant: str = "taylor", return_info: bool = False):
    """Exact transition of ``z' = F z + g(s)`` over one element ``0 <= s <= dt``.

    ``g`` is constant (``g1 is None``: zero-order hold) or linear from ``g0`` at
    ``s = 0`` to ``g1`` at ``s = dt`` (first-order hold). Then ``z(dt) = A z(0) +
    b`` with ``A = exp(F dt)`` and ``b = int_0^dt exp(F (dt - s)) g(s) ds``, both
    taken from ONE exponential of the augmented matrix (Van Loan 1978)::

        [[F dt, (g1 - g0) dt, g0 dt],      exp ->  [[A, *, b],
         [0,    0,            1    ],               [0, 1, 1],
         [0,    0,            0    ]]               [0, 0, 1]]

    The forcing columns are rescaled by powers of two to the size of ``F dt``
    (exact by linearity) so that a large load does not force extra squarings.
    Batched over leading axes.

    Parameters
    ----------
    F : ndarray, shape (..., m, m)
        State matrix, 1/s.
    dt : float
        Element length, s.
    g0, g1 : ndarray, shape (..., m)
        Forcing at the start and end of the element (state units / s).
    delta : float
        Requested relative backward error of the exponential.
    scaling : None, "general", "second-order" or ndarray (..., m)
        State balancing: none, :func:`balance`, :func:`second_order_scaling`
        (for ``F = [[0, I], [-M^-1 K, -M^-1 C]]``), or explicit powers of two.
    degree : int or "auto"
        Degree of the approximant, see :func:`expm`.
    approximant : {"taylor", "pade"}
        See :func:`expm`. Default Taylor: in a batch the Pade solve costs more
        than the products it saves (see ``docs/solver.md``).
    return_info : bool
        Also return the :class:`ExpmInfo`.

    Returns
    -------
    A : ndarray, shape (..., m, m)
    b : ndarray, shape (..., m)
    info : ExpmInfo, only if ``return_info``
    """
    F = np.asarray(F)
    m = F.shape[-1]
    batch = np.broadcast_shapes(F.shape[:-2], np.shape(g0)[:-1],
                                np.shape(g1)[:-1] if g1 is not None else ())
    dtype = np.result_type(F.dtype, np.asarray(g0).dtype, float)
    Fd = np.broadcast_to(F * dt, batch + (m, m)).reshape((-1, m, m)).astype(dtype, copy=False)
    nb = Fd.shape[0]
    g0d = np.broadcast_to(np.asarray(g0) * dt, batch + (m,)).reshape((nb, m))
    dgd = None
    if g1 is not None:
        dgd = np.broadcast_to((np.asarray(g1) - np.asarray(g0)) * dt, batch + (m,)).reshape((nb, m))
    d = _state_scaling(Fd, scaling)
    if d is not None:
        d = np.broadcast_to(d, (nb, m))
        B = Fd * (d[:, None, :] / d[:, :, None])
        g0d = g0d / d
        if dgd is not None:
            dgd = dgd / d
    else:
        B = Fd
    tau = np.maximum(_inf_norm(B), 2.0 ** -20)
    gmax0 = np.abs(g0d).max(axis=-1) if m else np.zeros(nb)
    beta = _pow2(np.where(gmax0 > 0, tau / np.where(gmax0 > 0, gmax0, 1.0), 1.0))
    ma = m + (1 if dgd is None else 2)
    X = np.zeros((nb, ma, ma), dtype=dtype)
    X[:, :m, :m] = B
    if dgd is None:
        X[:, :m, m] = g0d * beta[:, None]
    else:
        gmax1 = np.abs(dgd).max(axis=-1)
        alpha = np.where(gmax1 > 0, _pow2(tau / np.where(gmax1 > 0, gmax1, 1.0)), beta)
        # keep the coupling entry beta/alpha <= max(1, tau): a vanishing g0 next to
        # a finite slope must not create a huge entry (that would cost squarings)
        beta = np.minimum(beta, alpha * _pow2(np.maximum(1.0, tau)))
        X[:, :m, m] = dgd * alpha[:, None]
        X[:, :m, m + 1] = g0d * beta[:, None]
        X[:, m, m + 1] = beta / alpha
    E, info = _exp_scaled_core(X, float(delta), degree, triangular=False,
                               approximant=approximant)
    A = E[:, :m, :m]
    b = E[:, :m, ma - 1] / beta[:, None]
    if d is not None:
        A = A * (d[:, :, None] / d[:, None, :])
        b = b * d
    A = A.reshape(batch + (m, m))
    b = b.reshape(batch + (m,))
    return (A, b, info) if return_info else (A, b)


def exponential_integrals(F: np.ndarray, G: np.ndarray, dt: float, *, delta: float = 1e-15,
                          scaling="general", degree="auto", approximant: str = "taylor",
                          return_info: bool = False):
    """Operators of the exact element transition for a time-invariant ``F``.

    For ``z' = F z + G q(s)`` with ``q`` linear over the element (``q_k`` at
    ``s = 0``, ``q_{k+1}`` at ``s = dt``)::

        z_{k+1} = A z_k + Gamma0 q_k + Gamma1 (q_{k+1} - q_k)

    with ``A = exp(F dt)``, ``Gamma0 = int_0^dt exp(F (dt-s)) ds G`` and ``Gamma1 =
    int_0^dt exp(F (dt-s)) (s/dt) ds G``; zero-order hold uses ``Gamma0`` only.
    All three come from one exponential of ``[[F dt, G dt, 0], [0, 0, I], [0, 0,
    0]]`` of size ``m + 2p``; afterwards a whole sampled forcing is mapped at once
    by two matrix products.

    Parameters
    ----------
    F : ndarray, shape (m, m)
        State matrix, 1/s.
    G : ndarray, shape (m, p)
        Input matrix.
    dt : float
        Element length, s.
    delta, scaling, degree, approximant, return_info
        As in :func:`affine_exponential`.

    Returns
    -------
    A : ndarray, shape (m, m)
    Gamma0, Gamma1 : ndarray, shape (m, p)
    info : ExpmInfo, only if ``return_info``
    """
    F = np.asarray(F)
    G = np.asarray(G)
    m = F.shape[-1]
    p = G.shape[-1]
    dtype = np.result_type(F.dtype, G.dtype, float)
    Fd = (F * dt).astype(dtype)
    Gd = (G * dt).astype(dtype)
    d = _state_scaling(Fd[None], scaling)
    if d is not None:
        d = d[0]
        B = Fd * (d[None, :] / d[:, None])
        Gd = Gd / d[:, None]
    else:
        B = Fd
    tau = max(float(_inf_norm(B)), 2.0 ** -20)
    gn = float(np.abs(Gd).sum(axis=-1).max()) if Gd.size else 0.0
    alpha = float(_pow2(tau / gn)) if gn > 0 else 1.0
    ma = m + 2 * p
    X = np.zeros((1, ma, ma), dtype=dtype)
    X[0, :m, :m] = B
    X[0, :m, m:m + p] = Gd * alpha
    X[0, m:m + p, m + p:] = np.eye(p)
    E, info = _exp_scaled_core(X, float(delta), degree, triangular=False,
                               approximant=approximant)
    E = E[0]
    A = E[:m, :m]
    G0 = E[:m, m:m + p] / alpha
    G1 = E[:m, m + p:] / alpha
    if d is not None:
        A = A * (d[:, None] / d[None, :])
        G0 = G0 * d[:, None]
        G1 = G1 * d[:, None]
    return (A, G0, G1, info) if return_info else (A, G0, G1)


def second_order_transition(S: np.ndarray, D: np.ndarray, dt: float, f0: np.ndarray,
                            f1: np.ndarray | None = None, *, delta: float = 1e-15,
                            degree="auto", approximant: str = "taylor",
                            return_info: bool = False):
    """Element transitions of a second-order system, built in balanced form.

    Same result as :func:`affine_exponential` with ``F = [[0, I], [-S, -D]]``,
    ``g = [0; f]`` and ``scaling="second-order"``, but the balanced augmented
    matrix is written directly from ``S = M^-1 K`` and ``D = M^-1 C`` (the
    identity block is diagonal, the scaling is a column scaling of ``S``), which
    saves several passes over the ``(L, 2N+2, 2N+2)`` stack; this matters because
    batched elementwise passes cost about half a matrix product at ``N ~ 40``.

    Parameters
    ----------
    S, D : ndarray, shape (L, N, N)
        ``M^-1 K`` [1/s^2] and ``M^-1 C`` [1/s] held over each element (``D`` may
        be ``(N, N)``).
    dt : float
        Element length, s.
    f0, f1 : ndarray, shape (L, N)
        ``M^-1 Q`` at the start and end of the element (``f1=None``: held constant).
    delta, degree, approximant, return_info
        As in :func:`affine_exponential`.

    Returns
    -------
    A : ndarray, shape (L, 2N, 2N)
    b : ndarray, shape (L, 2N)
    info : ExpmInfo, only if ``return_info``
    """
    L, N, _ = S.shape
    m = 2 * N
    ma = m + (1 if f1 is None else 2)
    absS = np.abs(S)
    col = absS.sum(axis=-2)  # column sums of |S|
    sigma = _pow2(np.where(col > 0, 1.0 / np.sqrt(np.where(col > 0, col, 1.0)), 1.0))
    X = np.zeros((L, ma, ma))
    iu = np.arange(N)
    X[:, iu, N + iu] = dt / sigma
    np.multiply(S, (-dt) * sigma[:, None, :], out=X[:, N:m, :N])
    np.multiply(D, -dt, out=X[:, N:m, N:m])
    # upper bound of ||B||_inf (no extra pass over the whole stack)
    rows_v = np.einsum("lij,lj->li", absS, sigma) * dt + np.abs(D).sum(axis=-1) * dt
    tau = np.maximum(np.maximum((dt / sigma).max(axis=-1), rows_v.max(axis=-1)), 2.0 ** -20)
    g0d = f0 * dt
    gmax0 = np.abs(g0d).max(axis=-1)
    beta = _pow2(np.where(gmax0 > 0, tau / np.where(gmax0 > 0, gmax0, 1.0), 1.0))
    if f1 is None:
        X[:, N:m, m] = g0d * beta[:, None]
        extra = np.abs(X[:, N:m, m]).max(axis=-1)
    else:
        dgd = (f1 - f0) * dt
        gmax1 = np.abs(dgd).max(axis=-1)
        alpha = np.where(gmax1 > 0, _pow2(tau / np.where(gmax1 > 0, gmax1, 1.0)), beta)
        beta = np.minimum(beta, alpha * _pow2(np.maximum(1.0, tau)))  # see affine_exponential
        X[:, N:m, m] = dgd * alpha[:, None]
        X[:, N:m, m + 1] = g0d * beta[:, None]
        X[:, m, m + 1] = beta / alpha
        extra = np.abs(X[:, N:m, m]).max(axis=-1) + np.abs(X[:, N:m, m + 1]).max(axis=-1)
        extra = np.maximum(extra, beta / alpha)
    bound = tau + extra
    E, info = _exp_scaled_core(X, float(delta), degree, triangular=False,
                               approximant=approximant, copy=False, norm_bound=bound)
    A = E[:, :m, :m]
    A[:, :N, :] *= sigma[:, :, None]
    A[:, :, :N] /= sigma[:, None, :]
    b = E[:, :m, ma - 1] / beta[:, None]
    b[:, :N] *= sigma
    return (A, b, info) if return_info else (A, b)
