"""The block-cyclic system solved whole, by a sparse LU with partial pivoting.

When a Floquet multiplier lies outside the unit circle (marching from ``z_0`` would amplify
rounding errors) or ``I - Phi`` is non-normal and ill-conditioned, :func:`_solve_by_cyclic_lu`
solves ``A_s z_s - z_{s+1} = -b_s``, ``z_S = z_0`` by :func:`_cyclic_lu` (backward stable), on
segments of elements when the whole system would not fit the memory budget; the states inside
the segments are then marched from their starts (:func:`_march_segments`).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .condensation import _Condensed, _second_pass
from .march import _propagate


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
