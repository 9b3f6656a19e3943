"""kedfem.analysis.branch.reach on scalar families with known solutions: the step control by the
predictor's error, the folds, a target whose first correction does not shrink with the step."""

import math
import types
import warnings

import numpy as np
import pytest

from kedfem.analysis import branch
from kedfem.errors import NonlinearSolveError
from kedfem.solvers import nonlinear


class Curve:
    """``x + a sin x = lam`` as a family (``reach``'s protocol): the Newton map as its tangent
    solve; folds where ``1 + a cos x = 0`` (``a > 1``). ``offset``: the equation at ``lam == at``
    is ``x + a sin x = lam + offset`` (a problem discretised otherwise there, as a pinned level
    on elements snapped to the data's kinks: the first correction from the neighbours' predictor
    does not shrink with the step)."""

    def __init__(self, a, offset=0.0, at=None):
        self.a, self.offset, self.at = a, offset, at
        self.solves = 0
        self.solved_at = []
        self.stepped_at = []  # first corrections and arclength steps

    def F(self, x, lam):
        return x + self.a * math.sin(x) - lam - (self.offset if lam == self.at else 0.0)

    def G(self, x, lam):
        return x - self.F(x, lam) / (1.0 + self.a * math.cos(x))

    def unpack(self, x, lam):
        return x[:1].reshape(1, 1), x[1:].reshape(1, 1)

    def step(self, x, lam):
        self.solves += 1
        self.stepped_at.append(lam)
        return types.SimpleNamespace(floquet_multipliers=np.array([0.5])), np.array([self.G(x[0], lam), 0.0])

    def solve(self, lam, x0, eps, max_iter=30):
        self.solved_at.append(lam)
        start = (np.array([[lam if x0 is None else x0[0]]]), np.zeros((1, 1)))

        def G(U, V, it):
            Un = np.array([[self.G(U[0, 0], lam)]])
            return Un, Un, np.zeros((1, 1))

        def merit(U, V):
            return abs(self.F(U[0, 0], lam))

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = nonlinear.newton(G, 1, 1, 2 * math.pi, eps=eps, max_iter=max_iter, x0=start, merit=merit)
        self.solves += len(out.history)
        o = types.SimpleNamespace(iterations=len(out.history),
                                  discrete=types.SimpleNamespace(floquet_multipliers=np.array([0.5])))
        return o, (np.array([out.solution[0, 0], 0.0]) if out.converged else None)


class FarStart(Curve):
    """Newton from the linear response (``x0`` None) converges only up to ``lam = 3``."""

    def solve(self, lam, x0, eps, max_iter=30):
        if x0 is None and lam > 3.0:
            self.solved_at.append(lam)
            return types.SimpleNamespace(iterations=max_iter), None
        return super().solve(lam, x0, eps, max_iter)


def test_reach_steps_by_the_predictors_error_to_the_target():
    c = FarStart(0.5)
    r = branch.reach(c, 30.0, eps=1e-10)
    assert r.point.lam == 30.0 and abs(c.F(r.point.x[0], 30.0)) < 1e-8
    assert r.folds == ()
    # every counted step solved (a step rejected on its first correction is not a step), and
    # the speeds on the way to STEP_EPS, the target to eps
    after = c.solved_at[c.solved_at.index(r.start) + 1:]  # after the start was found
    assert after[-1] == 30.0 and r.steps == len(after)
    assert c.solves > len(c.solved_at)  # first corrections and rejected steps cost solves too
    assert r.solves == c.solves


def test_reach_follows_a_response_curve_through_its_folds():
    c = FarStart(1.2)  # folds near lam = 9.35 / 9.50, 15.68 / 15.78, 21.9 / 22.0, ...
    r = branch.reach(c, 30.0, eps=1e-10)
    assert r.point.lam == 30.0 and abs(c.F(r.point.x[0], 30.0)) < 1e-8
    assert len(r.folds) >= 2
    for f in r.folds:  # each a fold of the curve: 1 + a cos x = 0 there, lam = x + a sin x
        x = [xx for xx in (math.acos(-1 / 1.2) + 2 * math.pi * k * s for k in range(6) for s in (1, -1))]
        lams = [xx + 1.2 * math.sin(xx) for xx in x] + [-xx + 1.2 * math.sin(-xx) for xx in x]
        assert min(abs(f - v) for v in lams) < 0.05, (f, r.folds)


def test_a_step_onto_the_target_is_not_rejected_on_its_first_correction():
    """The target's problem may differ from those on the way (a level's elements snapped to the
    data's kinks): its first correction then has a floor that no shorter step lowers. The step
    onto it goes to Newton's iteration whatever its first correction."""
    c = FarStart(0.5, offset=10.0, at=20.0)  # a first correction of about 0.27 from any neighbour
    r = branch.reach(c, 20.0, eps=1e-10)
    assert r.point.lam == 20.0 and abs(c.F(r.point.x[0], 20.0)) < 1e-8
    # one first correction there and one iteration (rejected, it was tried 7-8 times and reached
    # by the arclength corrector's Newton at last)
    assert c.stepped_at.count(20.0) == 1 and c.solved_at.count(20.0) == 1


@pytest.mark.parametrize("a, target", [(2.0, 40.0), (2.0, -40.0), (1.2, -30.0)])
def test_reach_a_response_curve_that_turns_often_either_way(a, target):
    """``x + 2 sin x`` turns at eight folds on the way to 40 (a limit of four failed it); a
    negative target (a drive turning the other way) goes through its folds as well (the target's
    crossing was looked for in the positive direction only: -30 failed, beyond it)."""
    c = FarStart(a)

    def solve(lam, x0, eps, max_iter=30):  # the linear response converges only near zero
        if x0 is None and abs(lam) > 3.0:
            c.solved_at.append(lam)
            return types.SimpleNamespace(iterations=max_iter), None
        return Curve.solve(c, lam, x0, eps, max_iter)

    c.solve = solve
    r = branch.reach(c, target, eps=1e-10)
    assert r.point.lam == target and abs(c.F(r.point.x[0], target)) < 1e-8
    assert len(r.folds) >= (6 if a == 2.0 else 2)


def test_a_continuation_out_of_solves_says_so():
    c = FarStart(1.2)
    with pytest.raises(NonlinearSolveError, match=r"its budget of 40 linear solves spent"):
        branch.reach(c, 30.0, eps=1e-10, max_solves=40)


def test_a_finer_level_runs_up_from_where_its_coarser_level_passed_below_its_first_fold():
    """``Homotopy._coarse_start``: the coarser level's run-up point at most COARSE_MARGIN below the
    lowest fold it met, taken on its way up before its first turn, and only where it met a fold
    and that point is above the fresh start (0.75 of the target)."""
    from types import SimpleNamespace as NS
    from kedfem.analysis.branch import Reached
    from kedfem.analysis.homotopy import COARSE_MARGIN, Homotopy

    def run(lams, folds):
        pts = tuple(NS(lam=v, discrete=f"d{v}") for v in lams)
        return NS(_runup=(48, Reached(pts[-1], lams[0], len(lams), tuple(folds), 99, pts)))

    # up to a fold at 95, back to 94, forward past it to the target 100
    r = run([70, 80, 88, 92, 93, 94.5, 94, 96, 100], [94.8, 93.9])
    lam, d, n = Homotopy._coarse_start(r, 100.0)
    assert (lam, d, n) == (92, "d92", 48) and lam <= 94.8 * (1 - COARSE_MARGIN)
    # the branch back from the fold passes below the cutoff again: not a point of the way up
    assert Homotopy._coarse_start(run([70, 88, 94.5, 90, 93.5, 100], [94.6]), 100.0)[0] == 88  # (a turn not listed)
    assert Homotopy._coarse_start(run([70, 80, 90, 97, 99, 100], []), 100.0) is None  # no fold seen: not a guide
    assert Homotopy._coarse_start(run([70, 72, 74, 76], [75.5]), 100.0) is None         # not above 0.75 of the target
    assert Homotopy._coarse_start(run([-70, -80, -90, -96, -98, -97, -100], [-98.2, -96.9]), -100.0)[0] == -90  # the other way
    assert Homotopy._coarse_start(NS(_runup=None), 100.0) is None
