"""The fallback of a level whose Newton iteration does not converge: its response by continuation in
speed (:meth:`Homotopy.homotopy`, a part of :class:`kedfem.analysis.pipeline._Run`), and a response
at another speed read as a start (:func:`phase_sample`)."""

from __future__ import annotations

import dataclasses
import logging
import math
import time
import warnings

import numpy as np

from ..units import RPM_PER_RAD_S
from .progress import Reminder

# the steps of a solve log under the pipeline's name (docs/usage.md: the continuation's warning)
log = logging.getLogger("kedfem.analysis.pipeline")


#: a continuation forecast to take longer than this [s] says so in the log (once)
LONG_CONTINUATION = 10.0
#: ... once it has covered this fraction of its way (its first steps are short while the step
#: control finds the predictor's error: the four-bar preset at 350 rpm was forecast 10 s more
#: after three steps that covered 2 % of the way, and took 2 s)
SAID_AFTER = 0.1
#: ... and again when it has doubled since, at most this many times in all
SAID_TIMES = 3


class ContinuationProgress:
    """What a solve's continuation in speed has done and how long the rest will likely take.

    Called by :func:`kedfem.analysis.branch.reach` after each point: the speed reached, the
    steps taken, and the seconds left at the pace since the start was found (the speed still to
    cover times the seconds per rad/s so far: the step grows on an easy branch, so this errs
    long; it shrinks toward a resonance, so this errs short there). Shown on the solve's
    progress bar; logged from the third step on (steps whose iteration failed count, those
    rejected on their first correction do not) and a tenth of the way (:data:`SAID_AFTER`), when
    above :data:`LONG_CONTINUATION`, and again each time it has doubled since it was last said
    (:data:`SAID_TIMES` in all).

    Parameters
    ----------
    name : str
        The mechanism's name (for the log).
    target : float
        Speed to reach [rad/s].
    n : int
        Time elements of the level.
    bar : tqdm or None
        The solve's progress bar.
    """

    def __init__(self, name: str, target: float, n: int, bar=None):
        self.name, self.target, self.n, self.bar = name, abs(target), n, bar
        self.t_start = None  # when the start was found
        self.left = None     # seconds left, as last forecast
        self._tell = Reminder(LONG_CONTINUATION, SAID_TIMES)

    def __call__(self, lam: float, start: float, steps: int) -> None:
        now = time.perf_counter()
        lam, start = abs(lam), abs(start)
        if self.t_start is None:
            self.t_start = now
        covered, rest = lam - start, self.target - lam
        self.left = (now - self.t_start) * rest / covered if covered > 0 else None
        rpm = RPM_PER_RAD_S
        text = f"{self.n} time elements, continuation in speed {lam * rpm:.4g} of {self.target * rpm:.4g} rpm"
        if self.left is not None and rest > 0:  # before the steps: what a narrow terminal must show
            text += f", about {self.left:.0f} s left"
        if steps:
            text += f", {steps} step{'s' if steps > 1 else ''}"
        if self.bar is not None:
            self.bar.set_postfix_str(text, refresh=True)
        if steps >= 3 and covered >= SAID_AFTER * (self.target - start) and self._tell.due(self.left):
            log.warning("%s: the continuation in speed reached %.4g of %.4g rpm in %d steps (%.0f s): about "
                        "%.0f s more at this pace", self.name, lam * rpm, self.target * rpm, steps,
                        now - self.t_start, self.left)


#: a finer level's run-up starts where its coarser level's passed, this fraction below the lowest
#: fold that one met (near a fold the levels' branches differ most)
COARSE_MARGIN = 0.02


def phase_sample(discrete, t, period: float):
    """A discrete solution read at instants ``t`` of a cycle ``period`` long, at the same fractions
    of its own cycle (velocities rescaled to the new cycle): a response at another speed as a
    start."""
    r = discrete.period / period
    U, V = discrete.at(np.asarray(t, dtype=float) * r)
    return U, V * r


class Homotopy:
    """The continuation-in-speed fallback of :class:`kedfem.analysis.pipeline._Run` (a mixin: it sets
    the run's ``path`` and ``highest``, which its failure message reads)."""

    def homotopy(self, prob, failed, eps: float, origin: str = "the linear response"):
        """The level's response by continuation in speed when Newton from ``origin`` (the linear
        response, the coarser level, or the given start) does not converge
        (:func:`kedfem.analysis.branch.reach`).

        Returns the :class:`~kedfem.analysis.problem.Solved` at the scene's speed (the failed
        one when the continuation does not get there; :attr:`path` says what happened). A
        warning is logged when it begins: each of its steps is a Newton solve on the level's
        elements, and tens of them take minutes.
        """
        from .branch import Family, reach
        from ..errors import NonlinearSolveError
        sc = self.scene
        w = sc.mech.drives[0].speed
        log.warning("%s: Newton from %s did not converge at %.4g rpm on %d time elements: continuation in "
                    "speed (each step a Newton solve on %d elements; tens of steps can take minutes%s)",
                    sc.mech.name, origin, abs(w) * RPM_PER_RAD_S, prob.n, prob.n,
                    "" if self.start is not None else
                    "; a result at a nearby speed, kf.solve(scene, start=result), starts there instead")
        if self._bar is not None:
            self._bar.set_postfix_str(f"{prob.n} time elements, continuation in speed", refresh=True)
        fam = Family(lambda s: dataclasses.replace(sc, speed=s), prob.n, self.scheme, in_speed=True)
        fam.pin(w, prob)  # the target on this level's own elements (a continuation of more speeds than
        # the family keeps evicted it, and the level came out on uniform elements where it has kinks)
        t0 = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            given, source = None, None
            coarse = self._coarse_start(w)
            if coarse is not None:
                # a coarser level's run-up: its response below its first fold, where this level's
                # branch runs alike (a drag-link's 96-element level ran up again from 0.75 of the
                # target, 13 s, where its 48-element level had been there)
                w0, d0, n0 = coarse
                source = f"the {n0}-element level's run-up"
            elif self.start is not None and self.start.sampler is not None:
                # continue from the given start's own speed, where it is a response
                w0, d0 = self.start.model.mech.drives[0].speed, self.start.sampler.discrete
                source = "the given start"
            if source is not None:
                p0 = fam.problem(w0)
                given = (w0, fam.pack(*phase_sample(d0, p0.instants, p0.period), w0))
            try:
                r = reach(fam, w, eps=eps, unit=(RPM_PER_RAD_S, "rpm"), start=given,
                          progress=ContinuationProgress(sc.mech.name, w, prob.n, self._bar))
            except NonlinearSolveError as e:
                self.path = (f"Newton's method from {origin} did not converge; " + str(e))
                self.highest = e.highest
                log.info("%s: %s", sc.mech.name, self.path)  # the NonlinearSolveError says it
                return failed
        self._runup = (prob.n, r)
        rpm = RPM_PER_RAD_S
        folds = (f", through folds at {', '.join(f'{abs(f) * rpm:.1f}' for f in r.folds)} rpm" if r.folds else "")
        there = (f" ({source}'s response there)" if given is not None and math.isclose(r.start, abs(given[0]))
                 else "")
        self.path = (f"reached by continuation in speed from {r.start * rpm:.4g} rpm{there} ({r.steps} steps"
                     f"{folds}; Newton from {origin} did not converge at {abs(w) * rpm:.4g} rpm)")
        log.info("%s: %s, %d solves, %.1f s", sc.mech.name, self.path, r.solves, time.perf_counter() - t0)
        d = r.point.discrete
        from .problem import Solved
        if getattr(d, "chord", False):
            # the continuation's last Newton ended on a chord step, whose multipliers are those of a
            # tangent frozen up to CHORD_CHANGE away (a Watt six-bar by a resonance: spectral radius
            # 0.6845 where its response's own is 0.6787): a full Newton step from it on this level
            again = prob.solve(d.instant_states(), eps=eps, max_iter=3)
            if again.converged:
                return dataclasses.replace(again, iterations=failed.iterations + r.solves + again.iterations,
                                           history=failed.history + again.history,
                                           caught=list(caught) + list(again.caught))
        return Solved(d, True, failed.iterations + r.solves, failed.history, "newton", list(caught))

    def _coarse_start(self, target: float):
        """``(speed, discrete, n)``: where a coarser level's run-up to ``target`` passed, the
        response to start this level's from, or None. Its last point at most
        :data:`COARSE_MARGIN` below the lowest fold it met, taken on its way up before its first
        turn; None where it met no fold (the finer level's Newton failed at the target from the
        coarser response: its own fold is likely below, unseen) or that point is not above the
        fresh start (0.75 of the target)."""
        run = self._runup
        if run is None:
            return None
        n0, r = run
        if not r.folds:  # where the finer level fails from the coarser's response without a fold the
            return None  # coarser saw, its own fold lies below (a drag-link at 3270 rpm, the four-bar at 550)
        cutoff = min(abs(f) for f in r.folds) * (1.0 - COARSE_MARGIN)
        best, before = None, 0.0
        for p in r.path:  # in the order of the run-up: up to its first turn
            if abs(p.lam) < before:
                break
            before = abs(p.lam)
            if abs(p.lam) <= cutoff and p.discrete is not None:
                best = p
        if best is None or abs(best.lam) <= 0.75 * abs(target) or math.copysign(1.0, best.lam) != math.copysign(1.0, target):
            return None
        return best.lam, best.discrete, n0
