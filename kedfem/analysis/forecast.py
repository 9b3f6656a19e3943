"""The forecast of a tolerance-driven solve: the time elements its refinement is likely to end on
and the seconds the remaining levels are likely to take, from a cost model through the levels
solved so far (:class:`Forecast`, a part of :class:`kedfem.analysis.pipeline._Run`)."""

from __future__ import annotations

import math
import time

import numpy as np

from ..solvers.nonlinear import PREDICT_FRACTION, PREDICT_MAX_CHANGE
from .accuracy import ASSUMED_RATE
from .scene import MAX_STEPS

#: the forecast's read-out of a level for the estimate, before one is measured, as a share of
#: the level's solve (the catalogue: 0.1 .. 1)
READ_SHARE = 0.5


class Forecast:
    """The forecast of :class:`kedfem.analysis.pipeline._Run` (a mixin: it reads the run's levels,
    their times and read-outs, and asks its stability floor whether the verdict will need it)."""

    def forecast_elements(self, need: int) -> int:
        """The time elements the refinement is likely to end on (see :meth:`forecast`).

        Three levels (as many doublings past the last as make three), at least ``need`` (the excited modes), and
        the stability floor unless the verdict will not need it: the last level's spectral
        radius, raised by the most the scheme's numerical damping can lower it on the elements
        the response needs, below :data:`CERTAIN_RHO` (:meth:`stable_beyond_doubt`; the floor's
        thousands of elements made the forecast of a 1 rpm linkage 100-250x too long). Below the
        floor, a verdict not clear by :data:`HISTORY_FREE_RHO` makes the histories meet rtol too,
        which takes a level more (the four-bar at 5 rpm: five levels, forecast 0.46x without it).
        """
        lv = self.levels[-1]
        target = lv.n
        for _ in range(3 - len(self.levels)):
            target = self.scheme.refine(target)
        target = max(target, need)
        if len(self.levels) == 2:
            target = max(target, self._elements_for_rtol())
        if self._stab_need > target and not self._doubt_cleared(target):
            target = self._stab_need
        elif self._stab_need > target and not self._clear_at(target):
            target = self.scheme.refine(target)
        return min(target, MAX_STEPS)

    def _elements_for_rtol(self) -> int:
        """The finest level the tolerance is likely to need, from the first two levels.

        Their largest relative difference of displacements over the cycle, as Richardson's
        argument at the scheme's order between element ends makes it an error, extrapolated at
        that order until it is below ``rtol``; a rough guide for the forecast only (the peaks'
        stresses and the asymptotic range decide the refinement, often a level later, which
        :meth:`forecast` allows for).
        """
        a, b = self.levels[-2], self.levels[-1]
        sc, scheme = self.scene, self.scheme
        if sc.rtol is None or not (a.converged and b.converged):
            return b.n
        t = np.arange(64) * (sc.period / 64)
        X, Y = a.discrete.at(t)[0], b.discrete.at(t)[0]
        scale = float(np.abs(Y).max())
        if not (scale > 0 and np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
            return b.n
        diff = float(np.abs(Y - X).max()) / scale
        ratio = b.n / a.n
        order, n = max(float(scheme.dense_order), 1.0), scheme.refine(b.n)
        err = diff / (ratio ** order - 1.0)
        while err * (b.n / n) ** order > sc.rtol and n < MAX_STEPS:
            n = scheme.refine(n)
        return n

    def refinement_driver(self, est, believed: bool) -> tuple[str, int]:
        """What makes the refinement go on past the last level, and the time elements it is
        likely to end on, from the last level's estimate ``est``
        (:class:`kedfem.analysis.accuracy.ErrorEstimate`, or None).

        The reasons are the stopping rule's in :meth:`kedfem.analysis.pipeline._Run._run`, in its
        order: an estimate that cannot be believed (coarser levels that do not resolve the excited
        modes), peaks beyond ``rtol``, a rate short of the asymptotic range, histories beyond
        ``rtol`` below the stability floor, the floor itself. The levels a quantity needs are its
        estimate extrapolated at its observed rate (before the asymptotic range at least the scheme's
        assumed rate, :data:`kedfem.analysis.accuracy.ASSUMED_RATE`) until below ``rtol``: a rough guide
        for the forecast and the progress bar (a toggle press whose histories converged at rate
        1 after a process load's release took 7 levels where the second level's forecast said 4).

        Returns
        -------
        why : str
            The reason, naming the link and the quantity.
        target : int
            Time elements the refinement is likely to end on (at most the finest level it can
            reach without passing :data:`MAX_STEPS`).
        """
        sc, scheme, n = self.scene, self.scheme, self.levels[-1].n
        rtol = sc.rtol if sc.rtol is not None else math.inf
        ratio = scheme.refine(n) / n

        # before the asymptotic range an observed rate is on its way up to the scheme's: credited
        # the assumed one at least (the toggle press's peaks at rate 1.3 on 48 elements
        # extrapolated to 12288 elements, 41 s; they met rtol on 96)
        assumed = ASSUMED_RATE.get(scheme.name, 1.0)

        top = n  # the finest level the refinement can reach (it stops before passing MAX_STEPS)
        while scheme.refine(top) <= MAX_STEPS:
            top = scheme.refine(top)

        def after(err: float, rate: float) -> int:  # elements that bring err below rtol
            rate = max(rate, 1.0) if est.asymptotic else max(rate, assumed)
            m = scheme.refine(n)
            while err * (n / m) ** rate > rtol and m < top:
                m = scheme.refine(m)
            return m

        def worst(attr: str):
            e = max(est.links, key=lambda x: getattr(x, attr), default=None)
            return (e.link, getattr(e, attr)) if e is not None else ("(none)", 0.0)

        below = n < self._stab_need
        if est is None or not est.observed:
            why, target = "the estimate needs three levels", scheme.refine(n)
        elif not est.resolved:
            why = (f"the coarser levels do not resolve the modes the drive excites (they need >= "
                   f"{self._need} time elements), so their agreement cannot be believed")
            target = scheme.refine(n)
            while target / ratio < self._need and target < top:
                target = scheme.refine(target)
        elif est.peak > rtol:
            link, d = worst("deflection")
            link_s, s = worst("stress")
            what, link, err = ("deflection", link, d) if d >= s else ("stress", link_s, s)
            why = (f"the peak {what} of '{link}' is estimated {err:.1e} off, above rtol {rtol:.0e} "
                   f"(observed rate {est.rate:.1f})")
            target = after(err, est.rate)
        elif not (est.asymptotic or believed or est.settled or est.clear):
            why = (f"the peaks meet rtol ({est.peak:.1e}) but their observed rate {est.rate:.1f} is short "
                   f"of the asymptotic range (order {scheme.dense_order}): the estimate is not believed yet")
            target = scheme.refine(n)
        elif below and self.stable_beyond_doubt() and est.history > rtol and not self.clearly_stable():
            link, h = worst("history")
            why = (f"the peaks meet rtol but the histories over the cycle do not ('{link}' {h:.1e} off, "
                   f"observed rate {est.history_rate:.1f}); below the stability floor ({self._stab_need} "
                   f"elements) they must, the bearing loads ride on them")
            target = after(h, est.history_rate)
        else:
            why = (f"the stability verdict needs {self._stab_need} time elements (the scheme's numerical "
                   f"damping may hide a multiplier near 1 on fewer)")
            target = max(self._stab_need, scheme.refine(n))
        return why, min(max(target, scheme.refine(n)), top)

    def forecast(self, need: int, target: int | None = None) -> float:
        """Seconds the remaining levels are likely to take.

        The refinement doubles until three levels agree and the finest resolves the modes the drive
        excites (``need`` elements) and, unless the verdict is beyond doubt, the stability floor.
        A level on ``n`` elements costs its kinematics and assembly, ``a + b n``, and its linear
        solves, as many as :meth:`_next_iterations` expects at ``c + d n`` each, both through the
        last two levels (:meth:`_cost_model`; the Whitworth with geometric non-linearity took
        3, 2, 1, 1 solves on its levels, and a forecast per level was 2.9x long), plus the
        read-out of its peaks for the estimate, as measured or, before any, :data:`READ_SHARE`
        of the last level. The whole solve's time is the geometric mean of ending there and of
        ending a level later. ``target``: the time elements the refinement is expected to end on,
        when known better than :meth:`forecast_elements` says (:meth:`refinement_driver`).
        """
        lv = self.levels[-1]
        last = self.levels[-2:]
        setup = self._cost_model([x.kinematics + x.assembly for x in last], [x.n for x in last])
        one = self._cost_model([x.solve / max(x.iterations, 1) for x in last], [x.n for x in last])
        its = self._next_iterations()
        read = (self._t_read / len(self._obs)) if self._obs else READ_SHARE * (
            last[0].kinematics + last[0].assembly + last[0].solve)
        fixed, per = setup[0] + its * one[0], setup[1] + its * one[1]
        if target is None:
            target = self.forecast_elements(need)
        left, n, more = 0.0, lv.n, 0
        while n < target:
            n = self.scheme.refine(n)
            left += fixed + per * n + read
            more += 1
        self._more_levels = more
        # the estimate reads every level once: those solved so far that it has not read yet
        left += read * max(0, len(self.levels) - len(self._obs))
        n = self.scheme.refine(max(target, lv.n))
        if n <= MAX_STEPS:  # (a level more than the finest the refinement can reach is no outcome)
            # the refinement often takes one level more than the differences suggest (a quantity
            # before its asymptotic range, the histories below the stability floor): the geometric
            # mean of the two outcomes is within 2x of either
            spent = time.perf_counter() - self.t0
            left = math.sqrt((spent + left) * (spent + left + fixed + per * n + read)) - spent
        return left

    @staticmethod
    def _cost_model(cost, n) -> tuple[float, float]:
        """``(a, b)`` of a cost ``a + b n`` through the last two levels' ``cost`` at ``n`` elements
        (``b n`` alone from one level, which errs long: a few elements also carry costs that do
        not grow with ``n``)."""
        if len(cost) == 2 and n[0] < n[1]:
            per = max((cost[1] - cost[0]) / (n[1] - n[0]), 0.0)
            return max(cost[1] - per * n[1], 0.0), per
        return 0.0, cost[-1] / n[-1]

    def _next_iterations(self) -> int:
        """Linear solves a finer level is likely to take: 1 for a linear scene; for Newton, 1 when
        the rate observed so far predicts the change after its first below the stopping level
        (:func:`kedfem.solvers.nonlinear.newton`), the first taken as half of the last level's
        (the difference between levels shrinks 2-20x per doubling), else 2; for the fixed-point
        iterations, as many as the last level took."""
        lv = self.levels[-1]
        if lv.iterations <= 1 and not lv.history:
            return 1
        sc = self.scene
        if sc.nonlinear_method != "newton":
            return max(lv.iterations, 1)
        eps = self._level_eps()
        first = 0.5 * lv.history[0] if lv.history and len(self.levels) > 1 else math.inf
        if self._rate is not None and first <= PREDICT_MAX_CHANGE and \
                self._rate.predict(first) <= PREDICT_FRACTION * eps:
            return 1
        return 2
