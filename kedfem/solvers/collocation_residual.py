"""Residuals of the collocation equations at given stage states (stiffly accurate schemes).

:func:`residual` is the force residual ``M_j a_j + C_j V_j + K_j U_j - Q_j`` at every stage,
:func:`kinematic_defect` how far stage states are from satisfying the kinematic rows, and
:func:`stiffly_accurate` tells the schemes for which the stage states alone determine both;
:func:`apply_at_instants` applies matrices at the instants to vectors at the instants.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..errors import InputError
from .tableaux import tableau


def apply_at_instants(X, Y) -> np.ndarray:
    """``X_t Y_t`` (n_t, N) for matrices ``X`` (n_t, N, N) at the instants, or one (N, N) for all,
    and vectors ``Y`` (n_t, N)."""
    X = np.asarray(X, dtype=float)
    return Y @ X.T if X.ndim == 2 else np.einsum("tij,tj->ti", X, Y)


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
