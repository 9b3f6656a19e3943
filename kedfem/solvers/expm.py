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

Discretization helpers (used by :mod:`kedfem.solvers.periodic`, usable on their own, in
:mod:`kedfem.solvers.vanloan` and importable from here): :func:`affine_exponential` gives ``A =
exp(F dt)`` and the affine part ``b`` of ``z' = F z + g(s)`` with ``g`` constant or linear over
the element from ONE exponential of an augmented matrix (Van Loan 1978);
:func:`second_order_transition` does the same for ``F = [[0, I], [-M^-1 K, -M^-1 C]]`` building
the balanced augmented matrix directly; :func:`exponential_integrals` gives the operators ``A,
Gamma0, Gamma1`` that map a whole sampled forcing at once when ``F`` is time-invariant.

Here are :func:`expm` and :func:`taylor_expm`; the balancing is in
:mod:`kedfem.solvers.balancing`, the degrees, bounds and the scaling-and-squaring core in
:mod:`kedfem.solvers.scaling_squaring`.
"""

from __future__ import annotations

import numpy as np

from ..checks import choice, flag, integer
from ..errors import InputError
from . import scaling_squaring as _core
from .balancing import _inf_norm, balance, second_order_scaling
from .scaling_squaring import (APPROXIMANTS, ExpmInfo, _exp_scaled_core, pade_coefficients, pade_degree,
                               pade_error_bound)
from .vanloan import affine_exponential, exponential_integrals, second_order_transition

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

_balance = balance  # expm's argument ``balance`` shadows the function name there

# read as ``expm._ps_plan`` by kedfem.lab.flops (moved to scaling_squaring by issue 27)
_ps_plan = _core._ps_plan


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
