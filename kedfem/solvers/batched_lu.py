"""LU factorisations of a stack of small matrices, one LAPACK call each.

:func:`scipy.linalg.lu_factor` and :func:`scipy.linalg.lu_solve` take stacks too, but through a
Python wrapper per matrix that checks and dispatches again each time; for the collocation
elements' stage matrices (``s N`` = 72 .. 150, a few hundred per level) that wrapper cost a
sixth of the factorisation. Here the LAPACK routines are looked up once per stack and called
directly (the same ``getrf`` / ``getrs``: the results are the same to the bit).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

__all__ = ["lu_factor_stack", "lu_solve_stack"]


def lu_factor_stack(W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pivoted LU factorisations of the matrices of a stack.

    Parameters
    ----------
    W : ndarray, shape (L, n, n)
        Real matrices.

    Returns
    -------
    lu : ndarray, shape (L, n, n)
        The factors of each, stored transposed (``lu[i].T`` is LAPACK's column-major array).
    piv : ndarray of int32, shape (L, n)
        LAPACK's pivot indices (0-based).

    Raises
    ------
    numpy.linalg.LinAlgError
        A matrix is exactly singular (a zero pivot).
    """
    L, n = W.shape[0], W.shape[-1]
    getrf, = lapack.get_lapack_funcs(("getrf",), (W,))
    lu = np.empty((L, n, n), dtype=W.dtype)
    piv = np.empty((L, n), dtype=np.int32)
    for i in range(L):
        f, p, info = getrf(W[i])
        if info > 0:
            raise np.linalg.LinAlgError("Singular matrix")
        lu[i] = f.T  # f is column-major: its transpose is the row-major copy of the same memory
        piv[i] = p
    return lu, piv


def lu_solve_stack(factors: tuple[np.ndarray, np.ndarray], B: np.ndarray) -> np.ndarray:
    """Solve ``W_i x_i = b_i`` from :func:`lu_factor_stack`'s factors.

    Parameters
    ----------
    factors : tuple
        ``(lu, piv)`` of :func:`lu_factor_stack`, shapes (L, n, n) and (L, n).
    B : ndarray, shape (L, n, k)
        Right-hand sides.

    Returns
    -------
    ndarray, shape (L, n, k)

    Notes
    -----
    SciPy's ``getrs`` wrapper shifts the pivot array in place while it runs: two threads must
    not solve with the same factors at once (each worker of a collocation solve factorises and
    solves its own elements; later solves run on one thread).
    """
    lu, piv = factors
    getrs, = lapack.get_lapack_funcs(("getrs",), (lu, B))
    X = np.empty(B.shape, dtype=np.result_type(lu, B))
    for i in range(lu.shape[0]):
        X[i], _info = getrs(lu[i].T, piv[i], B[i])
    return X
