"""Condensation of the block-cyclic system into ``Phi = A_{n-1} ... A_0`` and ``d`` (paper Eq. 13-16).

The first pass (:func:`_condense`) computes every chunk's transitions and composes them, by
pairwise (tree) products in worker threads or, for one constant ``A``, by powers; it collects
the segment transfers that a sparse LU of the cyclic system needs (:class:`_Segments`) and
keeps what the second pass needs (:func:`_second_pass`: the chunks again, kept or recomputed).
A product that overflows means an unbounded response (:func:`_check_bounded`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import UnboundedResponseError
from .march import _scan_invariant
from .parallel import _run_parallel, _split


@dataclass
class _Condensed:
    """The block-cyclic system condensed by the first pass (:func:`_condense`).

    State units: those of the DOFs for the first ``m / 2`` entries, per second
    for the rest.

    Attributes
    ----------
    Phi : ndarray, shape (m, m)
        Monodromy matrix ``A_{n-1} ... A_0``.
    d : ndarray, shape (m,)
        Particular part ``sum_k A_{n-1} ... A_{k+1} b_k``, the state after one
        period from ``z_0 = 0``.
    kept_A : list of ndarray
        Per chunk, its ``A_k`` (L, m, m), or the one ``A`` (m, m) when
        invariant; empty when not kept.
    kept_b : list of ndarray, shape (L, m)
        Per chunk, its ``b_k`` (always kept: ``O(n m)``).
    seg_A, seg_b : list of ndarray, shapes (S, m, m) and (S, m)
        Transfers of the sparse-LU segments (time-varying transitions only).
    a_norm2 : float
        ``sum_k ||A_k||_F**2``.
    t_exp : float
        Wall time of ``elems.compute``, s.
    """

    Phi: np.ndarray
    d: np.ndarray
    kept_A: list
    kept_b: list
    seg_A: list
    seg_b: list
    a_norm2: float
    t_exp: float


class _Segments:
    """Transfers of consecutive segments of ``seg`` elements, collected chunk by chunk.

    For time-varying transitions: a segment lies inside one chunk (all of them
    when ``seg`` does not exceed the chunk) or spans whole chunks, whose
    transfers are then composed until the segment is complete.
    """

    def __init__(self, seg: int, n: int, workers: int):
        self.seg, self.n, self.workers = seg, n, workers
        self.A: list[np.ndarray] = []
        self.b: list[np.ndarray] = []
        self._open_A = self._open_b = None
        self._open_len = 0

    def add(self, A: np.ndarray, bvec: np.ndarray, end: int) -> tuple[np.ndarray, np.ndarray]:
        """Record the segments of a chunk and return the chunk's transfer.

        Parameters
        ----------
        A : ndarray, shape (L, m, m)
            Transitions of the chunk's elements.
        bvec : ndarray, shape (L, m)
            Their forced parts.
        end : int
            Index one past the chunk's last element.

        Returns
        -------
        P : ndarray, shape (m, m)
            ``A_{L-1} ... A_0``.
        d : ndarray, shape (m,)
            State after the chunk from a zero state.
        """
        L, seg = bvec.shape[0], self.seg
        if seg == 1:
            sA, sb = A, bvec
        elif seg <= L:
            sA, sb = _tree_groups(A, bvec, seg)
        else:
            sA, sb = None, None
        Pc, dc = (_tree_parallel(A, bvec, self.workers) if sA is None
                  else _tree_parallel(sA, sb, self.workers))
        Pc, dc = Pc[0], dc[0]
        if sA is not None:
            self.A.append(sA)
            self.b.append(sb)
            return Pc, dc
        if self._open_A is None:  # segment spans several chunks
            self._open_A, self._open_b = Pc, dc
        else:
            with np.errstate(over="ignore", invalid="ignore"):
                self._open_A, self._open_b = Pc @ self._open_A, Pc @ self._open_b + dc
        self._open_len += L
        if self._open_len >= seg or end == self.n:
            self.A.append(self._open_A[None])
            self.b.append(self._open_b[None])
            self._open_A, self._open_b, self._open_len = None, None, 0
        return Pc, dc


def _condense(elems, keep: bool, seg: int) -> _Condensed:
    """First pass: compute every chunk's transitions and condense the cyclic system.

    Composes ``Phi = A_{n-1} ... A_0`` and ``d`` chunk by chunk (constant
    ``A``: powers by :func:`_chain_invariant`; time-varying: pairwise products
    in worker threads), collects the segment transfers for a sparse LU and
    keeps what the second pass needs.

    Parameters
    ----------
    elems : transition source
        As in :func:`solve_cyclic` (``elems.chunk`` already planned).
    keep : bool
        Keep the ``A_k``.
    seg : int
        Elements per sparse-LU segment.

    Returns
    -------
    _Condensed
    """
    m = elems.m
    Phi, dvec = np.eye(m), np.zeros(m)
    kept_A, kept_b = [], []
    segments = _Segments(seg, elems.n, elems.workers)
    a_norm2 = 0.0
    t_exp = 0.0
    for a, b in elems.bounds():
        te = time.perf_counter()
        A, bvec = elems.compute(a, b)
        t_exp += time.perf_counter() - te
        if A.ndim == 2:
            Pc, dc = _chain_invariant(A, bvec)
        else:
            a_norm2 += float(np.einsum("kij,kij->", A, A))
            Pc, dc = segments.add(A, bvec, b)
        with np.errstate(over="ignore", invalid="ignore"):  # see _check_bounded
            Phi, dvec = Pc @ Phi, Pc @ dvec + dc
        if keep:
            kept_A.append(A)
        kept_b.append(bvec)
    if elems.invariant:
        a_norm2 = elems.n * float(np.sum(kept_A[0] * kept_A[0]))
    return _Condensed(Phi, dvec, kept_A, kept_b, segments.A, segments.b, a_norm2, t_exp)


def _check_bounded(pass1: _Condensed, n: int) -> None:
    """Raise :class:`~kedfem.errors.UnboundedResponseError` if ``Phi`` or ``d`` overflowed.

    Parameters
    ----------
    pass1 : _Condensed
        The condensed system.
    n : int
        Number of time elements (for the message).
    """
    if not (np.all(np.isfinite(pass1.Phi)) and np.all(np.isfinite(pass1.d))):
        raise UnboundedResponseError(
            f"response unbounded: the transition over one cycle ({n} time elements) overflows "
            "floating point, so the largest Floquet multiplier exceeds about 1e300 -- a violent "
            "parametric instability or buckling at this speed, negative damping, or a diverging "
            "non-linear iterate; no periodic response is returned", elements=n)


def _second_pass(elems, pass1: _Condensed, keep: bool):
    """Chunks again, as ``(a, b, A, bvec)``: the kept transitions, or recomputed (streaming)."""
    for ci, (a, b) in enumerate(elems.bounds()):
        A, bvec = (pass1.kept_A[ci], pass1.kept_b[ci]) if keep else elems.compute(a, b)
        yield a, b, A, bvec


def _overflow_is_checked(fn):
    """Run ``fn`` with numpy's overflow warnings off: an overflowing product of
    transitions means an unbounded response, which :func:`solve_cyclic` reports
    as :class:`~kedfem.errors.UnboundedResponseError` (errstate is per thread,
    so the products in worker threads need it too)."""
    import functools

    @functools.wraps(fn)
    def wrapped(*args, **kwargs):
        with np.errstate(over="ignore", invalid="ignore"):
            return fn(*args, **kwargs)
    return wrapped

@_overflow_is_checked
def _tree_parallel(A, b, workers):
    """``_tree_groups(A, b, len(A))`` with the parts composed in parallel worker threads.

    Each worker multiplies with one BLAS thread: OpenBLAS's own threads on these
    small products wait for a time slice on every call when the machine is shared
    (measured 10-40x slower condensation at N = 100 under load).
    """
    parts = _split(A.shape[0], workers, min_part=16)
    res = [None] * len(parts)

    def work(i, lo, hi):
        res[i] = _tree_groups(A[lo:hi], b[lo:hi], hi - lo)

    _run_parallel(work, parts)
    P, d = res[0]
    for Pi, di in res[1:]:
        P, d = Pi @ P, np.einsum("gij,gj->gi", Pi, d) + di
    return P, d


@_overflow_is_checked
def _tree_groups(A, b, g):
    """Compose consecutive groups of ``g`` affine maps ``z -> A_k z + b_k``.

    Returns the group transfers ``(A_{g-1} ... A_0, sum ...)`` for every group
    (the last group may be shorter), by pairwise (tree) products: each level is one
    batched matmul over all groups, so ``log2(g)`` numpy calls instead of ``g``.
    """
    L = A.shape[0]
    full = (L // g) * g
    outA, outb = [], []
    if full:
        GA = A[:full].reshape((full // g, g) + A.shape[1:])
        Gb = b[:full].reshape((full // g, g) + b.shape[1:])
        while GA.shape[1] > 1:
            h = GA.shape[1]
            e, o = slice(0, h - 1, 2), slice(1, h, 2)
            nA = GA[:, o] @ GA[:, e]
            nb = np.einsum("gkij,gkj->gki", GA[:, o], Gb[:, e]) + Gb[:, o]
            if h % 2:
                nA = np.concatenate([nA, GA[:, -1:]], axis=1)
                nb = np.concatenate([nb, Gb[:, -1:]], axis=1)
            GA, Gb = nA, nb
        outA.append(GA[:, 0])
        outb.append(Gb[:, 0])
    if full < L:
        rA, rb = _tree_groups(A[full:], b[full:], L - full)
        outA.append(rA)
        outb.append(rb)
    if len(outA) == 1:
        return outA[0], outb[0]
    return np.concatenate(outA), np.concatenate(outb)


@_overflow_is_checked
def _chain_invariant(A, bvec):
    """Transfer of a chunk of elements with constant A: (A**L, d)."""
    _, dseg = _scan_invariant(A, bvec, np.zeros(A.shape[0]))
    return np.linalg.matrix_power(A, len(bvec)), dseg
