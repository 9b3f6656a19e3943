"""Scattering element terms into q-space through sparse operators (COO -> CSR, built once).

The element DOF index map of a group (``(n_el, m)``) gives one sparse
operator per group; dense batches (over time nodes) are scattered by a 0/1
summing operator per group (CSR), single instants as scipy.sparse CSR matrices.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = ["Scatter", "ACTIVE_WIDTH", "ActiveTerms", "column_patterns"]

#: element matrices at least this wide are scattered by the columns each instant uses (the
#: elements and point masses at a block carry the columns of every node of the member it
#: slides on, of which a handful are not zero at an instant)
ACTIVE_WIDTH = 24


@dataclass(frozen=True)
class ActiveTerms:
    """Element terms of a wide group kept on the columns each instant uses.

    ``parts``: ``(rows (r,), cols (k,), data)`` with ``data`` (r, n_el, k, k) element matrices
    or (r, n_el, k) element vectors at instants ``rows`` of ``nt``, on the group's element
    columns ``cols``; the columns left out are zeros. :meth:`Scatter.scatter_matrix` and
    :meth:`Scatter.scatter_vector` take them as they take dense terms.
    """

    nt: int
    parts: tuple


def column_patterns(active: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Instants alike in the element columns they use: ``[(rows, cols), ...]`` from ``active``
    (nt, m) booleans, patterns without a column left out."""
    patterns, which = np.unique(active, axis=0, return_inverse=True)
    which = np.ravel(which)
    return [(np.flatnonzero(which == k), np.flatnonzero(pat)) for k, pat in enumerate(patterns) if pat.any()]


@dataclass(frozen=True)
class _Plan:
    """How a group's flat element entries sum into global entries.

    ``targets`` (k,) are the global flat entries reached; ``sums`` (k, n_entries) is the 0/1 CSR
    operator whose row ``i`` picks the entries landing on ``targets[i]``, in ascending entry
    order, summed left to right. (It replaced a gather with ``np.add.reduceat``, which adds all
    but the first entry of a segment pairwise: equal sums where at most two entries meet, else
    within round-off, 2e-16 of the mould oscillator's terms. The sums are 3.3x faster at the
    four-bar's sizes, the batched scatter of its solve with the writes 1.9x: 22 -> 11.5 ms.)
    """

    targets: np.ndarray
    sums: sp.csr_matrix

    def add(self, data2d: np.ndarray, out2d: np.ndarray) -> None:
        """``out2d[:, targets] +=`` the sums of ``data2d`` (nt, n_entries) (nt, k)."""
        if self.targets.size:
            out2d[:, self.targets] += (self.sums @ data2d.T).T


def _plan(flat_targets, keep) -> _Plan:
    """The :class:`_Plan` of the kept entries of ``flat_targets`` (n_entries,)."""
    idx = np.flatnonzero(keep)
    tgt = flat_targets[idx]
    order = np.argsort(tgt, kind="stable")  # equal targets adjacent, their entries ascending
    idx, tgt = idx[order], tgt[order]
    starts = np.flatnonzero(np.r_[True, tgt[1:] != tgt[:-1]]) if tgt.size else np.zeros(0, int)
    sums = sp.csr_matrix((np.ones(idx.size), idx, np.r_[starts, idx.size]), shape=(starts.size, flat_targets.size))
    return _Plan(tgt[starts], sums)


def _matrix_plan(colarr, N: int):
    """:func:`_plan` of element matrices with DOF map ``colarr`` (n_el, m) into ``(N, N)``."""
    r, c = colarr[:, :, None], colarr[:, None, :]
    return _plan((r * N + c).reshape(-1), ((r < N) & (c < N)).reshape(-1))


class Scatter:
    """The scatter part of :class:`kedfem.fe.model.FEModel`."""

    # --------------------------------------------------------------- scatter
    def _operators(self, gname: str):
        """The :class:`_Plan` of a group's element matrices and of its element vectors.

        Entries ``(element, i, j)`` that land on the same global entry are summed by
        one row of the plan's operator; the padding column ``N`` (an element DOF with no
        unknown) is dropped.
        """
        if gname in self._scatter_cache:
            return self._scatter_cache[gname]
        colarr = self._static_layout(gname).cols
        N = self.n_dof
        mat = _matrix_plan(colarr, N)
        vec = _plan(colarr.reshape(-1), colarr.reshape(-1) < N)
        self._scatter_cache[gname] = (mat, vec)
        return mat, vec

    def _sub_operator(self, gname: str, cols: np.ndarray):
        """The :class:`_Plan` of a group's element matrices restricted to element columns ``cols``."""
        key = (gname, cols.tobytes())
        if key not in self._scatter_cache:
            self._scatter_cache[key] = _matrix_plan(self._static_layout(gname).cols[:, cols], self.n_dof)
        return self._scatter_cache[key]

    def _sub_vector_operator(self, gname: str, cols: np.ndarray):
        """The :class:`_Plan` of a group's element vectors restricted to element columns ``cols``."""
        key = (gname, cols.tobytes(), "vector")
        if key not in self._scatter_cache:
            c = self._static_layout(gname).cols[:, cols].reshape(-1)
            self._scatter_cache[key] = _plan(c, c < self.n_dof)
        return self._scatter_cache[key]

    def _scatter_parts(self, gname: str, terms: ActiveTerms, out: np.ndarray, matrix: bool) -> np.ndarray:
        """Scatter :class:`ActiveTerms` into ``out`` (nt, N, N) or (nt, N), C-contiguous (the callers
        :meth:`scatter_matrix` and :meth:`scatter_vector` see to it)."""
        flat = out.reshape(terms.nt, -1)
        for rows, cols, data in terms.parts:
            plan = (self._sub_operator if matrix else self._sub_vector_operator)(gname, cols)
            if plan.targets.size:
                flat[rows[:, None], plan.targets[None, :]] += (
                    plan.sums @ np.ascontiguousarray(data).reshape(rows.size, -1).T).T
        return out

    def _scatter_active(self, gname: str, data: np.ndarray, out: np.ndarray) -> None:
        """Scatter of wide element matrices by the columns each instant actually uses.

        The maps of the elements (and point masses) at a block span every node of the member
        it slides on, but at an instant only the element under the block carries entries: a handful of the
        ``m`` columns (the Whitworth's: 12 of 57). Instants with the same active columns are
        scattered together through a plan for those columns alone; the entries left out are
        zeros, so the sums are those of the full scatter.
        """
        nz = data != 0.0
        active = nz.any(axis=(1, 2)) | nz.any(axis=(1, 3))  # (nt, m)
        parts = tuple((rows, cols, data[rows][:, :, cols][:, :, :, cols]) for rows, cols in column_patterns(active))
        self._scatter_parts(gname, ActiveTerms(data.shape[0], parts), out, True)

    def scatter_matrix(self, gname: str, data: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Scatter element matrices ``(nt, n_el, m, m)`` (or :class:`ActiveTerms`) to dense
        ``(nt, N, N)``.

        With ``out`` (nt, N, N), the entries are added to it (in place where it is C-contiguous).
        """
        N = self.n_dof
        if out is not None and not out.flags.c_contiguous:  # the entries must land in out, not a copy
            out += self.scatter_matrix(gname, data)
            return out
        if isinstance(data, ActiveTerms):
            return self._scatter_parts(gname, data, np.zeros((data.nt, N, N)) if out is None else out, True)
        (mat, _vec) = self._operators(gname)
        nt = data.shape[0]
        if out is None:
            out = np.zeros((nt, N, N))
        if data.shape[-1] >= ACTIVE_WIDTH and data.shape[0] > 1:
            self._scatter_active(gname, data, out)
            return out
        mat.add(np.ascontiguousarray(data).reshape(nt, -1), out.reshape(nt, N * N))
        return out

    def scatter_vector(self, gname: str, data: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Scatter element vectors ``(nt, n_el, m)`` (or :class:`ActiveTerms`) to dense ``(nt, N)``
        (added to ``out`` if given)."""
        if out is not None and not out.flags.c_contiguous:
            out += self.scatter_vector(gname, data)
            return out
        if isinstance(data, ActiveTerms):
            return self._scatter_parts(gname, data, np.zeros((data.nt, self.n_dof)) if out is None else out, False)
        (_mat, vec) = self._operators(gname)
        nt = data.shape[0]
        if out is None:
            out = np.zeros((nt, self.n_dof))
        vec.add(np.ascontiguousarray(data).reshape(nt, -1), out)
        return out

    def scatter_sparse(self, gname: str, data: np.ndarray) -> sp.csr_matrix:
        """Scatter element matrices of one time node ``(n_el, m, m)`` to CSR ``(N, N)``."""
        colarr = self._static_layout(gname).cols
        n_el, m = colarr.shape
        r = np.repeat(colarr, m, axis=1).reshape(-1)
        c = np.tile(colarr, (1, m)).reshape(-1)
        keep = (r < self.n_dof) & (c < self.n_dof)
        return sp.coo_matrix((data.reshape(-1)[keep], (r[keep], c[keep])),
                             shape=(self.n_dof, self.n_dof)).tocsr()

