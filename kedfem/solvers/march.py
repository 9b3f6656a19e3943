"""Marching the element transitions ``z_{k+1} = A_k z_k + b_k`` from a start state.

:func:`_propagate` marches one chunk of elements (one constant ``A``: by sqrt-blocking,
:func:`_scan_invariant`), :func:`_march` all chunks of a period.
"""

from __future__ import annotations

import math

import numpy as np


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
