"""The error estimate of a solve from its levels: each level read on common output instants
(its observables, and those of its defect-corrected solution), and the three-level and defect
estimates made from them (:class:`LevelEstimates`, a part of
:class:`kedfem.analysis.pipeline._Run`)."""

from __future__ import annotations

import dataclasses
import logging
import time

from . import accuracy
from ..solvers import defect, schemes
from .problem import STREAM_BYTES

# the steps of a solve log under the pipeline's name (docs/usage.md)
log = logging.getLogger("kedfem.analysis.pipeline")


class LevelEstimates:
    """The estimate's read-outs of the levels of :class:`kedfem.analysis.pipeline._Run` (a mixin: it
    reads the levels through the run's :meth:`~kedfem.analysis.pipeline._Run.result`)."""

    def observe(self, i: int, n_out: int) -> accuracy.Observables:
        key = (i, n_out)
        if key not in self._obs:
            t0 = time.perf_counter()
            res = self.result(self.levels[i], n_out)
            self._obs[key] = res.observables(refined=False)  # the grid alike for every level
            self._t_read += time.perf_counter() - t0
            self._read[key] = (self.levels[i], res._cache)  # its peaks, forces... for the result
        return self._obs[key]

    def _keeps(self, prob) -> bool:
        """Keep a level's problem for the defect estimate: a tolerance-driven solve (``steps``
        not given) with a scheme the estimate reads (:func:`kedfem.solvers.defect.offered`) whose
        assembled system is held whole (not streamed)."""
        return bool(self.scene.steps is None and defect.offered(self.scheme.name)
                    and 3 * prob.instants.size * prob.N ** 2 * 8 <= STREAM_BYTES)

    def _forget(self, i: int) -> None:
        """Level ``i`` was solved again: what was read from it goes."""
        self._obs = {k: v for k, v in self._obs.items() if k[0] != i}
        self._obs_corrected = {k: v for k, v in self._obs_corrected.items() if k[0] != i}
        self._corrected.pop(i, None)

    def corrected(self, i: int):
        """Level ``i``'s defect-corrected solution (:meth:`PeriodicProblem.corrected`), or None."""
        if i not in self._corrected:
            lv = self.levels[i]
            t0 = time.perf_counter()
            self._corrected[i] = (lv.problem.corrected(lv.discrete)
                                  if lv.problem is not None and lv.converged else None)
            self._t_read += time.perf_counter() - t0
        return self._corrected[i]

    def observe_corrected(self, i: int, n_out: int) -> accuracy.Observables | None:
        """:meth:`observe` of level ``i``'s defect-corrected solution (None where there is none)."""
        key = (i, n_out)
        if key not in self._obs_corrected:
            y = self.corrected(i)
            if y is None:
                self._obs_corrected[key] = None
            else:
                t0 = time.perf_counter()
                lv = dataclasses.replace(self.levels[i], discrete=y)
                self._obs_corrected[key] = self.result(lv, n_out).observables(refined=False)
                self._t_read += time.perf_counter() - t0
        return self._obs_corrected[key]

    def defect_estimate(self, n_out: int, need: int = 0) -> accuracy.ErrorEstimate | None:
        """Estimate of the finest level from its defect correction, believed where the level
        before it, corrected by its own, explains their difference
        (:func:`kedfem.analysis.accuracy.defect_estimate`); None where it does not apply (a
        scheme without it, fewer than two converged levels, a coarser level that
        does not resolve the excited modes (``need``), levels not one refinement apart, or peaks
        that changed too much for the finer level to meet the tolerance:
        :func:`kedfem.analysis.accuracy.promising`)."""
        sc = self.scene
        if len(self.levels) < 2:
            return None
        ia, ib = len(self.levels) - 2, len(self.levels) - 1
        a, b = self.levels[ia], self.levels[ib]
        if not (a.converged and b.converged) or a.n < need or self.scheme.refine(a.n) != b.n \
                or a.problem is None or b.problem is None:
            return None  # (a coarser level that does not resolve the excited modes does not explain the change)
        oa, ob = self.observe(ia, n_out), self.observe(ib, n_out)
        # (the histories too: the refinement stops on a defect estimate only with them within rtol)
        assumed = accuracy.ASSUMED_RATE.get(self.scheme.name, 1.0)
        if not accuracy.promising(oa, ob, ratio=b.n / a.n, order=self.scheme.dense_order, rtol=sc.rtol,
                                  assumed=assumed):
            return None
        oya = self.observe_corrected(ia, n_out)
        if oya is None:
            return None
        ok, left = accuracy.explained(oa, ob, oya)
        if not ok:  # the finer level's correction is not worth making
            log.debug("%s: the %d-element level's defect correction leaves %.2g of the change to %d elements",
                      sc.mech.name, a.n, left, b.n)
            return None
        oyb = self.observe_corrected(ib, n_out)
        if oyb is None:
            return None
        return accuracy.defect_estimate((a.n, b.n), oa, ob, oya, oyb, assumed=assumed,
                                        order=self.scheme.dense_order, rtol=sc.rtol)

    def estimate(self, n_out: int, need: int = 0) -> accuracy.ErrorEstimate | None:
        """Estimate of the finest level from the last two or three converged ones (``need``:
        resolution floor)."""
        ok = [i for i, lv in enumerate(self.levels) if lv.converged]
        if len(ok) < 2 or ok[-1] != len(self.levels) - 1:
            return None
        idx = ok[-3:]
        obs = [self.observe(i, n_out) for i in idx]
        est = accuracy.estimate([self.levels[i].n for i in idx], obs,
                                assumed=accuracy.ASSUMED_RATE.get(self.scheme.name, 1.0),
                                order=self.scheme.dense_order, rtol=self.scene.rtol)
        # the exponential holds integrate frozen data exactly (no numerical damping or aliasing)
        resolved = isinstance(self.scheme, schemes.ExponentialHold) or self.levels[idx[-2]].n >= need
        return dataclasses.replace(est, resolved=bool(resolved))
