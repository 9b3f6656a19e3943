"""Scattering element terms into q-space through sparse operators (COO -> CSR, built once).

The element DOF index map of a group (``(n_el, m)``) gives one sparse
operator per group; dense batches (over time nodes) are scattered with
segment sums, single instants as scipy.sparse CSR matrices.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["Scatter"]


class Scatter:
    """The scatter part of :class:`kedfem.fe.model.FEModel`."""

    # --------------------------------------------------------------- scatter
    def _operators(self, gname: str):
        """Segment sums of a group's element entries: (gather order, segment starts, targets).

        Entries ``(element, i, j)`` that land on the same global entry are
        adjacent after the gather, so one ``np.add.reduceat`` sums them; the
        padding column ``N`` (an element DOF with no unknown) is dropped.
        """
        if gname in self._scatter_cache:
            return self._scatter_cache[gname]
        colarr = self._static_layout(gname)[0]
        N = self.n_dof

        def plan(flat_targets, keep):
            idx = np.flatnonzero(keep)
            tgt = flat_targets[idx]
            order = np.argsort(tgt, kind="stable")
            idx, tgt = idx[order], tgt[order]
            starts = np.flatnonzero(np.r_[True, tgt[1:] != tgt[:-1]]) if tgt.size else np.zeros(0, int)
            return idx, starts, tgt[starts]

        r, c = colarr[:, :, None], colarr[:, None, :]
        mat = plan((r * N + c).reshape(-1), ((r < N) & (c < N)).reshape(-1))
        vec = plan(colarr.reshape(-1), colarr.reshape(-1) < N)
        self._scatter_cache[gname] = (mat, vec)
        return mat, vec

    @staticmethod
    def _segment_add(plan, data2d, out2d):
        idx, starts, targets = plan
        if idx.size:
            out2d[:, targets] += np.add.reduceat(data2d[:, idx], starts, axis=1)

    def scatter_matrix(self, gname: str, data: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Scatter element matrices ``(nt, n_el, m, m)`` to dense ``(nt, N, N)``.

        With ``out`` (nt, N, N), C-contiguous, the entries are added to it.
        """
        (mat, _vec) = self._operators(gname)
        nt = data.shape[0]
        N = self.n_dof
        if out is None:
            out = np.zeros((nt, N, N))
        self._segment_add(mat, np.ascontiguousarray(data).reshape(nt, -1), out.reshape(nt, N * N))
        return out

    def scatter_vector(self, gname: str, data: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Scatter element vectors ``(nt, n_el, m)`` to dense ``(nt, N)`` (added to ``out`` if given)."""
        (_mat, vec) = self._operators(gname)
        nt = data.shape[0]
        if out is None:
            out = np.zeros((nt, self.n_dof))
        self._segment_add(vec, np.ascontiguousarray(data).reshape(nt, -1), out)
        return out

    def scatter_sparse(self, gname: str, data: np.ndarray) -> sp.csr_matrix:
        """Scatter element matrices of one time node ``(n_el, m, m)`` to CSR ``(N, N)``."""
        colarr = self._static_layout(gname)[0]
        n_el, m = colarr.shape
        r = np.repeat(colarr, m, axis=1).reshape(-1)
        c = np.tile(colarr, (1, m)).reshape(-1)
        keep = (r < self.n_dof) & (c < self.n_dof)
        return sp.coo_matrix((data.reshape(-1)[keep], (r[keep], c[keep])),
                             shape=(self.n_dof, self.n_dof)).tocsr()

