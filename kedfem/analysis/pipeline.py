"""``kf.solve(scene)``: kinematics -> assembly of the chosen effects -> periodic solve
(-> iteration) on a sequence of time discretisations until the error estimate
meets the scene's tolerance.

One *level* is one periodic solve on ``n`` time elements of the scene's
scheme (:mod:`kedfem.solvers.schemes`): the motion at the scheme's instants, the
effects assembled there, the linear periodic solve, or the non-linear
iteration when a chosen effect depends on the elastic state. A
tolerance-driven solve (``Scene.steps`` not given) starts coarse and refines
until the estimate of every flexible link's peak deflection and stress meets
``Scene.rtol`` (:mod:`kedfem.analysis.accuracy`); with ``steps`` given, two coarser
levels (``steps / 4`` and ``steps / 2``) provide the estimate. The result is
read on output instants (at least 360 per cycle, the element ends among
them) and anywhere else through its dense output (``res.resample``).

The parts of a solve other than its levels are mixins of :class:`_Run` in their own modules:
the resolution floor (:mod:`kedfem.analysis.resolution`), the stability floor and verdict
(:mod:`kedfem.analysis.stability_floor`), the forecast (:mod:`kedfem.analysis.forecast`), the
levels' read-outs and error estimates (:mod:`kedfem.analysis.level_estimates`) and the
continuation in speed where Newton's method fails (:mod:`kedfem.analysis.homotopy`).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import sys
import time
import warnings
from dataclasses import dataclass

import numpy as np

from . import accuracy
from ..solvers import monodromy, schemes
from ..fe.model import FEModel
from ..fe.assembler import Assembler
from ..errors import AccuracyWarning, CostWarning, EffectWarning, InputError, InstabilityWarning, user_stacklevel
from ..motion.kinematics import Cycle, kinematics
from ..fe.modal_damping import DampingField, PiecewiseDampingField
from ..fe.slots import node_crossings
from ..fe.effects.loads import idle_loads, load_breaks
from ..motion.profiles import distinct_instants
from ..fe.effects import unsimulated
from ..solvers.nonlinear import PREDICT_FRACTION
from ..solvers.threads import one_blas_thread
from .forecast import Forecast
from .homotopy import Homotopy, phase_sample
from .level_estimates import LevelEstimates
from .progress import Reminder
from .plausibility import check_passive_links, check_result
from .problem import PeriodicProblem, constant_or_sampled, damping_field, snapped_edges
from .resolution import ResolutionFloor
from .results import PeriodicResult, Sampler, Stability, Timings
from .scene import MAX_STEPS, Scene
from .stability_floor import StabilityFloor, undamped as _undamped
from ..units import RPM_PER_RAD_S

__all__ = ["solve", "assemble_scene", "START_ELEMENTS", "OUTPUT_STEPS"]

log = logging.getLogger(__name__)

#: least number of output instants per cycle (1 degree of crank)
OUTPUT_STEPS = 360
#: tolerance of the non-linear iteration on the levels of a tolerance-driven solve,
#: as a fraction of ``rtol`` (the last level goes on to the scene's ``eps``)
COARSE_EPS = 0.1
#: time elements of the first level of a tolerance-driven solve, per scheme (doubled
#: until the elements resolve the relevant modes, see ``_Run.resolution``)
START_ELEMENTS = {"radau3": 12, "radau2": 16, "gauss3": 12, "gauss2": 16, "magnus2": 45,
                  "foh": 45, "zoh": 90, "fourier": 17}
#: seconds of forecast remaining work beyond which a solve warns before it goes on
LONG_SOLVE = 60.0
#: a DOF is stiff for the exact split of the exponential holds when the links' axial
#: stiffness carries at least this share of its diagonal stiffness at every instant
AXIAL_SHARE = 0.9


_constant_or_sampled = constant_or_sampled  # (tests use the old name)
undamped = _undamped  # (kedfem.analysis.critical reads it here; it lives in stability_floor)


def assemble_scene(scene: Scene, steps: int | None = None):
    """Kinematics, FE model and assembler of a scene at equally spaced nodes (no solve).

    Parameters
    ----------
    scene : Scene
    steps : int, optional
        Nodes ``k T / steps`` (default ``scene.steps``, or 360).

    Returns
    -------
    motion : Motion
    model : FEModel
    assembler : Assembler
    """
    n = steps if steps is not None else (scene.steps or OUTPUT_STEPS)
    motion = kinematics(scene.mech, steps=n)
    model = FEModel(scene.mech, reduction=scene.reduction)
    asm = Assembler(model, motion, scene.effects, damping=scene.damping)
    return motion, model, asm


@dataclass
class _Level:
    """One periodic solve of the refinement sequence."""

    n: int
    discrete: schemes.Discrete
    converged: bool
    iterations: int
    history: tuple
    kinematics: float
    assembly: float
    solve: float
    caught: list
    predicted: float | None = None  # Newton stopped on this predicted next change (see Solved)
    orbit: object = None  # the multipliers about the last iterate on demand (see Solved.orbit)
    problem: object = None  # its PeriodicProblem, kept on the last two levels for the defect estimate


def solve(scene: Scene, progress: bool | None = None, *, start=None) -> PeriodicResult:
    """Periodic steady-state elastic response of a scene, with its error estimate.

    Assembles exactly the scene's effects at the instants the time scheme
    needs, solves the periodic problem, iterates (the paper's Eq. 21
    criterion) only when a chosen effect depends on the elastic state, and
    refines the time elements until the estimated error of every flexible
    link's peak deflection and stress meets ``scene.rtol`` (or, with
    ``scene.steps`` given, solves on that many and estimates the error from
    two coarser solves).

    Parameters
    ----------
    scene : Scene
    progress : bool, optional
        A progress bar on stderr (tqdm) for solves longer than about 2 s: the levels solved, their
        time elements and error estimate. Default: only on a terminal.
    start : PeriodicResult, optional
        A response of the same mechanism (at another speed, on other time elements) the
        non-linear iteration starts from, read at the same fractions of the cycle (a
        neighbour on a branch: :func:`kedfem.continuation` uses it). Where Newton does not
        converge from it, the continuation in speed starts from its speed if that is below the
        scene's (a start above it is only Newton's start: going down in speed, the continuation
        climbs from a fraction of the speed on its own). Default: the linear response.

    Returns
    -------
    PeriodicResult
        With ``res.error`` (:class:`~kedfem.analysis.accuracy.ErrorEstimate`) and ``res.path``
        (how a non-linear response was reached when Newton's method from the linear response
        did not converge).

    Raises
    ------
    NonlinearSolveError
        A non-linear scene whose periodic response was not found (Newton's method and the
        continuation in speed failed): no result, no stability verdict of an iterate.
    KinematicsError, MobilityError
        The linkage cannot run through its cycle.
    ResonanceError
        ``I - Phi`` singular (undamped resonance or a free rigid-body mode).
    SingularMassError
        Massless DOFs.

    Warns
    -----
    AccuracyWarning
        The estimate exceeds ``scene.rtol`` (fixed ``steps``, or the largest
        number of elements reached).
    ConvergenceWarning
        The non-linear iteration of the result did not meet ``scene.eps``.
    InstabilityWarning
        A Floquet multiplier lies outside the unit circle.
    """
    if not isinstance(scene, Scene):
        raise InputError(f"solve: expected a kf.Scene, got {type(scene).__name__}")
    if start is not None:
        if not isinstance(start, PeriodicResult) or start.sampler is None:
            raise InputError(f"solve: start must be a result of kedfem.solve, got {type(start).__name__}")
        if start.model.n_dof != FEModel(scene.mech, reduction=scene.reduction).n_dof:
            raise InputError(f"solve: start has {start.model.n_dof} elastic DOFs, the scene {scene.mech.name!r} "
                             "another number: give a response of the same mechanism")
    # one BLAS thread: the batched small-matrix work (eigh of the modal
    # damping, products, the periodic solve) ran 10-40x slower on OpenBLAS's
    # threads whenever the other core was busy (benchmarks/peers.py)
    with one_blas_thread():
        return _Run(scene, progress, start=start).run()


def _coarser(scheme, n: int) -> int | None:
    """The level whose refinement is ``n`` (None below the scheme's minimum)."""
    for m in range(max(scheme.min_elements, n // 2 - 1), n):
        if scheme.refine(m) == n:
            return m
    return None


class _Run(ResolutionFloor, StabilityFloor, Forecast, LevelEstimates, Homotopy):
    """The levels of one solve and their observables on common output instants.

    (The resolution and stability floors, the forecast, the estimates' read-outs and the
    continuation in speed are its mixins, each in its own module.)
    """

    def __init__(self, scene: Scene, progress: bool | None = None, start=None, runup: bool = True,
                 ladder: bool = False):
        self.t0 = time.perf_counter()
        self.scene = scene
        self.progress = progress
        self._bar = None
        self.cycle = Cycle(scene.mech)
        self.model = FEModel(scene.mech, reduction=scene.reduction)
        check_passive_links(self.model, self.cycle.at(np.arange(72) * (scene.period / 72)))
        self.scheme = schemes.get(scene.scheme)
        self.stiff = None
        if isinstance(self.scheme, (schemes.ExponentialHold, schemes.Fourier)) and scene.stiff_split:
            # the directions a link's axial stiffness holds throughout the cycle
            motion = self.cycle.at(np.arange(72) * (scene.period / 72))
            share = Assembler(self.model, motion, (), damping=None).axial_share()
            self.stiff = share.min(axis=0) >= AXIAL_SHARE
        self.levels: list[_Level] = []
        self._field = None
        self._rate = None  # Newton's rate on the last level that observed one (NewtonRate)
        self._bands = None
        self._stab_need, self._stab_f = 0, 0.0
        self._stab_loss = None  # n -> the most the scheme lowers ln(rho) on n elements
        self._stab_decay = 0.0  # ln of the least damped mode's physical multiplier per cycle
        self._buckled = True  # a mode of negative stiffness somewhere in the cycle (set by resolution)
        self._read: dict = {}  # (level index, output instants) -> (the level, what reading it computed)
        self._continue = None
        self._need = 0       # time elements that resolve the excited modes (set by _run)
        self._failed_problems: dict = {}  # n -> (instants, problem) of a level whose iteration failed
        self.path = ""       # how the non-linear response was reached, when not directly
        self.start = start   # a neighbour's response the first level starts from
        # where Newton fails: continuation in speed (False: the level fails, a mesh check's comparison)
        self.runup = runup
        # steps given: solve the halvings of steps from the coarsest that resolves the excited modes
        # up, each from the one before, as a tolerance-driven solve does (a mesh check's comparison
        # where Newton from the result failed: the way the result's own solve got there)
        self.ladder = ladder
        self._runup = None   # (n, Reached) of the last level reached by continuation in speed
        self.highest = None  # the highest speed the continuation reached, when it failed
        self._grids: dict[int, tuple] = {}
        self._breaks = None  # instants of kinks in the data (see breaks())
        self._obs: dict[tuple[int, int], accuracy.Observables] = {}
        self._corrected: dict = {}  # level index -> its defect-corrected Discrete (None: not available)
        self._obs_corrected: dict[tuple[int, int], accuracy.Observables] = {}
        self._t_read = 0.0   # seconds spent reading levels for the estimate
        self.forecast_s = None  # the whole solve's wall time as forecast after its second level [s]
        self._more_levels = 0   # levels the forecast expects after the last one solved
        self._reminder = Reminder(LONG_SOLVE)  # when a forecast past the second level warns
        self.t_setup = time.perf_counter() - self.t0

    def damping_field(self, n: int, several: bool = True) -> DampingField | PiecewiseDampingField | None:
        """The scene's modal damping over the cycle (built once, when the first level on ``n``
        elements asks, for three levels from ``n`` or, not ``several``, that one; None for
        other damping).

        Where a block crosses the nodes of its link, ``C(t)`` has kinks, which a trigonometric
        interpolant does not settle on before 1024 samples: there it is a Chebyshev interpolant
        between the kinks (:class:`PiecewiseDampingField`, to a thousandth of ``rtol``) when its
        exact matrices, about :data:`kedfem.fe.modal_damping.PIECE_COST` per piece, are fewer than half of those of the
        three levels from ``n`` (``7 s n``), else exact matrices at every instant (the
        oscillating cylinder: 4 pieces against 12/24/48 elements).
        """
        sc = self.scene
        self.breaks()
        if self._field is None:
            field = damping_field(sc, self.model, self.cycle, (7 if several else 1) * self.scheme.stages * n,
                                  kinks=self._node_breaks)
            if isinstance(field, PiecewiseDampingField):
                log.info("%s: modal damping between %d kinks from %d exact matrices (degrees %s, check %.1e)",
                         sc.mech.name, field.degrees.size, field.samples, field.degrees.tolist(), field.error)
            self._field = False if field is None else field  # False: none, or exact matrices at every instant
        return self._field or None

    # ---------------------------------------------------------------- levels
    def level(self, n: int, eps: float | None = None) -> _Level:
        """Solve on ``n`` time elements (warm start from the previous level).

        ``eps``: tolerance of the non-linear iteration on this level (default
        the scene's); :meth:`finish` tightens the last level to the scene's.
        """
        sc, scheme = self.scene, self.scheme
        eps = sc.eps if eps is None else max(eps, sc.eps)
        self._continue = None
        if self._bar is not None:  # the level being solved (the bar said the last one solved)
            self._bar.set_postfix_str(f"solving {n} time elements", refresh=True)
        ti, prob = self.problem(n)
        tc = time.perf_counter()
        a0 = prob.assembly  # the terms are assembled on the first solve: assembly, not solve time
        # warm start from the previous level only if its iteration converged: a coarse
        # level's diverged iterate (|mu| = 585 at 24 elements) sent every finer level
        # off to overflow, where each converges from the linear start
        prev = next((lv for lv in reversed(self.levels) if lv.converged), None)
        x0 = prev.discrete.at(ti) if prob.state and prev is not None else None
        origin = f"the {prev.n}-element level" if x0 is not None else "the linear response"
        if prob.state and x0 is None and self.start is not None:
            x0 = phase_sample(self.start.sampler.discrete, ti, sc.period)
            origin = "the given start"
        out = prob.solve(x0, eps=eps, max_iter=sc.max_iter, method=sc.nonlinear_method, rate=self._rate)
        if out.converged and origin == "the given start" and not self.path:  # (res.path: not from the linear response)
            self.path = (f"Newton from the given start (its response at "
                         f"{abs(self.start.model.mech.drives[0].speed) * RPM_PER_RAD_S:.4g} rpm)")
        if out.converged and out.rate is not None:
            self._rate = out.rate  # the finest level's Newton rate predicts the next level's changes
        if (prob.state and not out.converged and sc.nonlinear_method == "newton" and n >= self._need
                and self.runup):
            # a level that resolves the excited modes: continuation in speed (on a coarser one the
            # branch may turn where the finer ones run on; it is solved again from a finer level)
            out = self.homotopy(prob, out, eps, origin)
        if prob.state and eps > sc.eps:  # what finish() needs to go on to the scene's eps
            self._continue = (prob, out)
        td = time.perf_counter()
        d = out.discrete
        t_solve = td - tc - (prob.assembly - a0)
        lv = _Level(n, d, out.converged, out.iterations, out.history, prob.kinematics, prob.assembly, t_solve,
                    out.caught, out.predicted, out.orbit, prob if self._keeps(prob) else None)
        # only the finest level's multipliers are made exact (its kept factorisations go with it);
        # the problems (their assembled systems) of the last two levels only
        self.levels = [dataclasses.replace(x, orbit=None) if x.orbit is not None else x for x in self.levels]
        for i, x in enumerate(self.levels[:-1]):
            if x.problem is not None:
                x.problem.release()
                self._corrected.pop(i, None)  # its read-out stays in _obs_corrected
        self.levels[:-1] = [dataclasses.replace(x, problem=None) if x.problem is not None else x
                            for x in self.levels[:-1]]
        # (a level below the resolution floor has a spectral radius of its discretisation only: a new
        # user read a coarse level's rho = 433 in this line as the machine's)
        coarse = (f" (below the {self._need} elements that resolve the excited modes)" if n < self._need else
                  f" (lowered by the scheme's numerical damping below {self._stab_need} elements)"
                  if n < self._stab_need else "")
        log.info("%s: level n=%d (%s) %d iteration(s) rho=%.4g%s %.3f s", sc.mech.name, n, scheme.name,
                 out.iterations, d.spectral_radius, coarse, prob.kinematics + prob.assembly + t_solve)
        self.levels.append(lv)
        if not lv.converged and prob.state:
            self._failed_problems[n] = (ti, prob)  # assembled once: backfill() solves it again
        if lv.converged and prob.state:
            self.backfill(eps)
        if self._bar is not None:
            if self._bar.total is not None and self._bar.n >= self._bar.total:
                self._bar.total = self._bar.n + 1  # a level more than the forecast expected
            self._bar.update(1)
            self._bar.set_postfix_str(f"{n} time elements, {prob.kinematics + prob.assembly + t_solve:.1f} s",
                                      refresh=True)
        return lv

    def backfill(self, eps: float) -> None:
        """Coarser levels whose iteration failed, solved again from the finest converged one (the
        error estimate compares levels of the same response)."""
        sc, fine = self.scene, self.levels[-1]
        for i, lv in enumerate(self.levels[:-1]):
            if lv.converged:
                continue
            reused = lv.n in self._failed_problems  # its kinematics and assembly are counted already
            ti, prob = self._failed_problems.pop(lv.n, None) or self.problem(lv.n)
            t0, a0 = time.perf_counter(), prob.assembly
            out = prob.solve(fine.discrete.at(ti), eps=eps, max_iter=sc.max_iter, method=sc.nonlinear_method)
            # this attempt's time, counted whether it converges or not (a later backfill reuses the
            # problem as counted)
            timed = dataclasses.replace(lv, kinematics=lv.kinematics + (0.0 if reused else prob.kinematics),
                                        assembly=lv.assembly + prob.assembly - (a0 if reused else 0.0),
                                        solve=lv.solve + time.perf_counter() - t0 - (prob.assembly - a0))
            if out.converged:
                log.info("%s: level n=%d solved again from level n=%d", sc.mech.name, lv.n, fine.n)
                self.levels[i] = dataclasses.replace(
                    timed, discrete=out.discrete, converged=True, iterations=lv.iterations + out.iterations,
                    history=out.history, caught=out.caught, predicted=None,
                    problem=prob if lv.problem is not None else None)
                self._forget(i)
            else:
                self._failed_problems[lv.n] = (ti, prob)
                self.levels[i] = timed

    def problem(self, n: int):
        """``(instants, PeriodicProblem)`` of the level on ``n`` time elements (modal damping from
        the interpolated field on fine levels)."""
        edges = snapped_edges(n, self.scene.period, self.breaks()) if self.scheme.graded else None
        ti = self.scheme.instants(n, self.scene.period, edges)
        several = self.scene.steps is None or self.scene.estimate
        # modal damping from the cycle's interpolated field where it is cheaper than an eigenproblem
        # per instant (kedfem.fe.modal_damping.field_over_cycle: the slider-crank at rtol 1e-4, 35
        # eigenproblems instead of 252 for levels 12/24/48; one solve on 48 elements, 35 for 144)
        field = self.damping_field(n, several)
        return ti, PeriodicProblem(self.scene, self.model, self.cycle, self.scheme, n, damping_field=field,
                                   stiff=self.stiff, edges=edges, kinks=self.breaks() if edges is not None else None,
                                   chord=True)

    def breaks(self) -> np.ndarray:
        """Instants [s] where the data has a kink or a step in time: a block crossing a node of
        its flexible link (:func:`kedfem.fe.slots.node_crossings`), a process load's profile
        reaching a kink or step of its table (:func:`kedfem.fe.effects.loads.load_breaks`);
        element edges go there."""
        if self._breaks is None:
            sc = self.scene
            nodes = node_crossings(self.model, self.cycle, sc.period)
            loads = (load_breaks(sc.mech, self.cycle, sc.period) if "loads" in sc.effects
                     else np.zeros(0))
            self._node_breaks = nodes
            self._breaks = distinct_instants(np.concatenate([nodes, loads]), sc.period)
            if nodes.size:
                log.info("%s: %d instants where a block crosses a node of its link: element edges there",
                         sc.mech.name, nodes.size)
            if loads.size:
                log.info("%s: %d instants where a process load kinks or steps: element edges there",
                         sc.mech.name, loads.size)
        return self._breaks

    def failure(self, final: _Level):
        """The named error of a non-linear solve that found no periodic response (no result is
        returned: its last iterate is no answer, and neither is a stability verdict from it)."""
        from ..errors import NonlinearSolveError
        sc = self.scene
        rpm = RPM_PER_RAD_S
        w = abs(sc.mech.drives[0].speed)
        if sc.nonlinear_method == "newton":
            tried = (f"Newton's method with a line search from the linear response on {final.n} time elements, "
                     f"then continuation in speed")
            what = self.path or "the continuation did not reach the scene's speed"
        else:
            tried = (f"the {sc.nonlinear_method} iteration on {'/'.join(str(lv.n) for lv in self.levels)} "
                     "time elements (and Anderson acceleration)")
            what = f"it did not converge within max_iter = {sc.max_iter} linear solves"
        # (the continuation's message in the path names the speed it stalled at)
        highest = ("; the response may exist higher (the steps start from a fraction of the scene's speed)"
                   if self.highest is not None else "")
        nxt = ("kf.continuation(scene, lo, hi) (kedfem continuation SCENE --speeds LO:HI) follows the response "
               "over speed and says where it ends or loses its stability")
        if sc.nonlinear_method != "newton":
            nxt = "nonlinear_method='newton' (the default) continues in speed by itself; " + nxt
        else:  # what a new user found cheaper than both: a run-up of their own, result to result
            nxt += ("; or solve at speeds on the way up and start each from the last: kf.solve(scene_at_next_speed, "
                    "start=result)")
        return NonlinearSolveError(
            f"{sc.mech.name}: no periodic response found at {w * rpm:.6g} rpm: {what}{highest}. Tried: {tried}. "
            f"Next: {nxt}", highest=self.highest, tried=tried)

    def _level_eps(self) -> float:
        """The non-linear tolerance of the levels of a tolerance-driven solve: a tenth of rtol
        (their differences are of the order of rtol), at least the scene's ``eps``."""
        sc = self.scene
        return max(sc.eps, COARSE_EPS * sc.rtol) if sc.rtol is not None else sc.eps

    def finish(self) -> None:
        """Iterate the last level on to the scene's ``eps`` if it was solved looser."""
        if self._continue is None:
            return
        sc = self.scene
        prob, out = self._continue
        if out.converged and out.history and (out.history[-1] <= sc.eps or (
                out.predicted is not None and out.predicted <= PREDICT_FRACTION * sc.eps)):
            # its last change already meets the scene's eps: the iteration run at eps would have
            # stopped on the same iterate (a Newton step of 8e-7 then costs no fifth solve)
            self._continue = None
            return
        lv = self.levels[-1]
        t0 = time.perf_counter()
        out = prob.polish(out, eps=sc.eps, max_iter=sc.max_iter, rate=self._rate)
        self.levels[-1] = dataclasses.replace(
            lv, discrete=out.discrete, converged=out.converged, iterations=out.iterations,
            history=out.history, solve=lv.solve + time.perf_counter() - t0, caught=out.caught,
            predicted=out.predicted, orbit=out.orbit)
        self._forget(len(self.levels) - 1)
        self._continue = None

    # ----------------------------------------------------------- output grid
    @staticmethod
    def output_steps(n: int) -> int:
        """Output instants for ``n`` elements: a multiple of ``n``, at least :data:`OUTPUT_STEPS`."""
        return n * max(1, -(-OUTPUT_STEPS // n))

    def _grid(self, n_out: int):
        g = self._grids.get(n_out)
        if g is None:
            t = np.arange(n_out) * (self.scene.period / n_out)
            g = self._grids[n_out] = (t, self.cycle.at(t), {})
        return g

    def result(self, lv: _Level, n_out: int, error=None, shared_cache: bool = True,
               stability: Stability | None = None) -> PeriodicResult:
        """The level read on ``n_out`` equally spaced output instants."""
        t, motion, cache = self._grid(n_out)
        d = lv.discrete
        U, V = d.at(t)
        stable = stability.verdict == "stable" if stability is not None else bool(d.stable)
        res = PeriodicResult(
            self.scene, self.model, motion, motion.t, motion.crank_angle, U, V,
            tuple(self.model.dof_labels), d.floquet_multipliers, stable, lv.converged,
            lv.iterations, lv.history, float(d.residual), Timings(0.0, 0.0, 0.0, 0.0), d.method,
            elements=lv.n, scheme=self.scheme.name, error=error, sampler=Sampler(self.cycle, d),
            stability=stability, predicted_change=lv.predicted)
        for (_i, n), (level, cache_read) in list(self._read.items()):
            if n == n_out and level is lv:  # this level on these instants was read for the estimate
                res._cache.update(cache_read)
        if shared_cache:
            # the constraint maps and the kinetostatic forces depend on the motion only: built once
            # per output grid (PeriodicResult._motion_cache)
            res._cache["grid"] = cache
        return res

    # ------------------------------------------------------------------- run
    def run(self) -> PeriodicResult:
        from tqdm.auto import tqdm
        # no rate or time left by the levels' rate: the levels cost 2-4x each other, a continuation in
        # speed many times more (it puts its own seconds left in the postfix, which needs the width)
        self._bar = tqdm(desc=self.scene.name or self.scene.mech.name, unit="level", file=sys.stderr, delay=2.0,
                         disable=None if self.progress is None else not self.progress, dynamic_ncols=True,
                         leave=False, bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} levels [{elapsed}{postfix}]")
        try:
            return self._run()
        finally:
            self._bar.close()
            self._bar = None

    def buckling_note(self) -> str:
        """``"; ... buckles ..."`` where the scene's linear stiffness has a negative eigenvalue over
        the cycle (the link and where, :func:`kedfem.analysis.buckling.buckled_mode`), else ``""``:
        an instability warning above a buckling speed named neither (a new user's wiper linkage)."""
        if self._bands is None or not self._buckled:
            # the resolution floor found every stiffness eigenvalue positive, or did not look (steps
            # given without an estimate: a stability map's points, which would each pay a modal
            # analysis for a warning they catch)
            return ""
        from .buckling import buckled_mode
        mode = buckled_mode(self.scene.mech, self.scene.effects, model=self.model)
        if mode is None:
            return ""
        return (f"; the stiffness has a negative eigenvalue over part of the cycle: {mode.describe()} "
                "(kf.critical_speed(..., kind='buckling') finds the speed it starts at)")

    def say_refinement(self, est, believed: bool, need: int) -> None:
        """Past the forecast's second level, before each further level: log what drives the
        refinement on (:meth:`refinement_driver`) and the seconds the rest is now forecast to
        take, set the progress bar's levels to it, and warn (:class:`~kedfem.analysis.progress.Reminder`)
        where that exceeds :data:`LONG_SOLVE` (a new user's toggle press ran 8x its forecast with
        its bar at 100 % from the third level on, nothing said about why)."""
        sc, n = self.scene, self.levels[-1].n
        why, target = self.refinement_driver(est, believed)
        left = self.forecast(need, target=target)
        log.info("%s: level n=%d: refining to %d time elements: %s; forecast %.3g s more (up to %d elements)",
                 sc.mech.name, n, self.scheme.refine(n), why, left, target)
        if self._bar is not None:
            self._bar.total = len(self.levels) + max(self._more_levels, 1)
            self._bar.refresh()
        if self._reminder.due(left):
            log.warning("%s: this solve will take about %.0f s more (up to %d time elements per cycle): %s",
                        sc.mech.name, left, target, why)

    def _unsimulated(self) -> None:
        """One :class:`EffectWarning` per declared item the scene's effects leave out (a spring and
        its preload, a load, a friction, a gravity set with ``set_gravity``): it is not simulated."""
        mech, eff = self.scene.mech, set(self.scene.effects)
        if "loads" in eff:
            for msg in idle_loads(mech, self.cycle):
                log.info(msg)
                warnings.warn(msg, EffectWarning, stacklevel=user_stacklevel())
        for msg in unsimulated(mech, self.scene.effects):
            log.info(msg)
            warnings.warn(msg, EffectWarning, stacklevel=user_stacklevel())

    def _run(self) -> PeriodicResult:
        self._unsimulated()
        sc, scheme = self.scene, self.scheme
        est = None
        need, f_res = self.resolution() if (sc.estimate or sc.steps is None or self.ladder) else (0, 0.0)
        need = int(math.ceil(need * scheme.per_period))
        self._need = need
        self._stab_need, self._stab_f = self.stability_floor()
        if sc.steps is not None:
            n = scheme.check_elements(sc.steps)
            plan = []
            if sc.estimate:  # the two coarser levels whose refinements lead to n
                m = n
                for _ in range(2):
                    m = _coarser(scheme, m)
                    if m is None:
                        break
                    plan.insert(0, m)
            elif self.ladder:
                m, floor = n, max(need, START_ELEMENTS.get(scheme.name, 24))
                while (m := _coarser(scheme, m)) is not None and m >= floor:
                    plan.insert(0, m)
                self._need = min(need, plan[0] if plan else n)  # the coarsest may run up, whatever its floor
            for m in plan + [n]:
                lv = self.level(m)
                if self.ladder and not lv.converged:
                    break  # (the failure names the level)
            n_out = self.output_steps(n)
            if sc.estimate:
                est = self.estimate(n_out, need)
                if est is None:
                    msg = (f"{sc.mech.name}: no error estimate: {n} time elements (steps given) have no coarser "
                           f"level of {scheme.name} to compare with (the estimate needs steps >= "
                           f"{scheme.refine(scheme.min_elements)}); leave steps out to meet rtol")
                    warnings.warn(msg, AccuracyWarning, stacklevel=user_stacklevel())
        else:
            # double from a start whose second level resolves the relevant modes; the
            # estimate needs three levels (an observed rate) before it is believed
            n = max(START_ELEMENTS.get(scheme.name, 24), scheme.min_elements)
            while scheme.refine(n) < need and scheme.refine(scheme.refine(n)) <= MAX_STEPS:
                n = scheme.refine(n)
            # the levels' non-linear iteration stops at a tenth of rtol (their differences
            # are of the order of rtol); the last one then goes on to the scene's eps
            eps_level = self._level_eps()
            believed = False
            while True:
                lv = self.level(n, eps=eps_level)
                if len(self.levels) <= 2:  # after the second, a difference to extrapolate: again
                    left = self.forecast(need)
                    self.forecast_s = time.perf_counter() - self.t0 + left
                    log.info("%s: forecast after %d level(s) %.3g s (up to %d time elements)", sc.mech.name,
                             len(self.levels), self.forecast_s, self.forecast_elements(need))
                    if self._bar is not None:  # the levels expected (the bar runs on if more are needed)
                        self._bar.total = len(self.levels) + self._more_levels
                        self._bar.refresh()
                    if len(self.levels) == 1 and self._reminder.due(left):  # (then again only when doubled)
                        why = "a looser rtol or a coarser mesh is faster"
                        if getattr(self, "_friction_reach", 0.0):  # the reversal sets the resolution
                            smooth = min(f.smoothing for f in sc.mech.frictions.values())
                            why = (f"the friction's reversal (smoothing {smooth:g} m/s) sets the elements: a "
                                   f"larger smoothing= costs fewer")
                        log.warning("%s: this solve will take about %.0f s more (%d elastic DOFs, up to %d time "
                                    "elements per cycle: %.2f s per element measured on the first %d); %s",
                                    sc.mech.name, left, self.model.n_dof, self.forecast_elements(need),
                                    (lv.kinematics + lv.assembly + lv.solve) / n, n, why)
                failed = 0
                for prev in reversed(self.levels):
                    if prev.converged:
                        break
                    failed += 1
                if failed and sc.nonlinear_method == "newton" and self.levels[-1].n >= need:
                    break  # Newton and the continuation in speed failed: finer levels will not do better
                if failed >= 3 or (failed >= 2 and self.levels[-2].n >= need):
                    # refining the time discretisation does not make a non-linear iteration
                    # converge: two resolved levels, or three, that fail end the refinement
                    log.warning("%s: the non-linear iteration does not converge on %s time elements; "
                                "not refining further", sc.mech.name,
                                "/".join(str(x.n) for x in self.levels[-failed:]))
                    break
                est = self.estimate(self.output_steps(n), need) if len(self.levels) >= 3 else None
                if est is None or not (est.met and (est.asymptotic or believed or est.settled or est.clear)):
                    # the finest level's defect correction, where it explains the change from the level
                    # before: one or two levels fewer than three levels in the asymptotic range
                    # read on the grid the next level's three-level estimate reads these two levels on
                    # (a coarse level's grid differs, 360 instants for 24 elements, 384 for 48): a
                    # defect estimate that does not stop the refinement then costs no read twice
                    dest = self.defect_estimate(self.output_steps(scheme.refine(n)), need)
                    # and only with the histories within rtol too: over the cycle they carry the
                    # stiff axial forces the correction does not see, on which the bearing loads
                    # ride (the four-bar preset stopped on 48/96 elements with its coupler force
                    # history 12 % off and a bearing force peak 3.4 % off, where 48/96/192 had
                    # 0.6 % and 1.6e-4; the estimate said 16 %, honestly)
                    if dest is not None and dest.met and dest.history <= sc.rtol:
                        est = dest
                if est is not None:
                    if self._bar is not None and est.peak is not None:
                        hist = f", histories {est.history:.1e}" if sc.rtol and est.history > sc.rtol else ""
                        self._bar.set_postfix_str(f"{n} time elements, error {est.peak:.1e}{hist}", refresh=True)
                    # before the asymptotic range the estimate is loose (over): refine on; and
                    # on until the scheme's numerical damping leaves the spectral radius right.
                    # Once a level was in the asymptotic range and met rtol, the finer levels the
                    # stability floor asks for need only meet it: their differences sink toward
                    # the read-out noise (~1e-7), whose rates say nothing (four-bar at rtol 1e-5:
                    # 384 met and asymptotic, 768 at rate 2.49, and on to 1536 for nothing)
                    if est.met and est.asymptotic:
                        believed = True
                    # below the stability floor, where the verdict is clear only by a margin (or by
                    # the modes' physical decay), the histories must meet rtol too: the bearing loads
                    # ride on the axial forces, which the peaks do not see (a four-bar at 5 rpm on 48
                    # elements: peaks 4.7e-4, histories 1.8e-2, bearing forces 13 % off)
                    if est.met and (est.asymptotic or believed or est.settled or est.clear) and (
                            n >= self._stab_need or (self.stable_beyond_doubt() and (
                                est.history <= sc.rtol or self.clearly_stable()))):
                        break
                if scheme.refine(n) > MAX_STEPS:
                    break
                if len(self.levels) >= 3:
                    self.say_refinement(est, believed, need)
                n = scheme.refine(n)
            if self._continue is not None:
                self.finish()
                # the defect estimate stands: the iteration's last change (within a tenth of rtol)
                # moves it by the estimate's relative error times that change
                if len(self.levels) >= 3 and (est is None or est.method != "defect"):
                    est = self.estimate(self.output_steps(self.levels[-1].n), need)
            n_out = self.output_steps(self.levels[-1].n)
            if est is None and len(self.levels) >= 2:
                est = self.estimate(n_out, need)
        final = self.levels[-1]
        if final.orbit is not None:  # ended on a chord step: the multipliers of its own orbit
            t0 = time.perf_counter()
            final = self.levels[-1] = dataclasses.replace(final, discrete=final.orbit(), orbit=None,
                                                          solve=final.solve + time.perf_counter() - t0)
        if not final.converged:
            raise self.failure(final)
        nonlinear = sc.state_dependent
        for w in final.caught:  # warnings of the result's own solve (coarse levels' are dropped)
            if nonlinear and issubclass(w.category, InstabilityWarning):
                continue  # said below, from the result's own multipliers
            msg = w.message
            if issubclass(w.category, InstabilityWarning):
                msg = f"{msg}{self.buckling_note()}"
            warnings.warn_explicit(msg, w.category, w.filename, w.lineno)
        if nonlinear:
            # the orbit's linearisation, as the result holds it: the linear solve of a last chord step
            # warned of its frozen tangent's, a run-up's steps of none, and either called a
            # non-linear orbit's instability "parametric" (a new user read it as the linear machine's)
            mu = np.asarray(final.discrete.floquet_multipliers)
            k = int(np.argmax(np.abs(mu))) if mu.size else -1
            if k >= 0 and abs(mu[k]) > 1.0 + monodromy.INSTABILITY_TOL:
                warnings.warn(f"unstable non-linear periodic response: the largest Floquet multiplier of its "
                              f"linearisation |mu| = {abs(mu[k]):.6g} > 1 ({monodromy.instability_kind(mu[k])}); "
                              f"the periodic response exists but is not attracting{self.buckling_note()}",
                              InstabilityWarning, stacklevel=user_stacklevel())
        if est is not None and sc.rtol is not None and not est.met:
            how = (f"{final.n} time elements (steps given)" if sc.steps is not None
                   else f"{final.n} time elements, the finest level the refinement reaches (another "
                        f"doubling would pass the limit of {MAX_STEPS} per cycle)" if scheme.refine(final.n) > MAX_STEPS
                   else f"{final.n} time elements, where the refinement stopped")
            if est.peak > sc.rtol:
                why = f"estimated error of the peaks {est.peak:.1e} exceeds rtol = {sc.rtol:.0e}"
            elif not est.resolved:
                why = (f"estimated error of the peaks {est.peak:.1e} cannot be trusted: the coarser "
                       f"levels do not resolve the modes up to {f_res:.4g} Hz the drive excites "
                       f"(they need >= {need} time elements)")
                if getattr(self, "_friction_reach", 0.0):
                    smooth = min(f.smoothing for f in sc.mech.frictions.values())
                    why += (f"; the friction's reversal (smoothing {smooth:g} m/s) reaches "
                            f"{self._friction_reach:.4g} Hz: a larger smoothing= costs fewer elements")
            else:
                why = (f"estimated error of the peaks {est.peak:.1e} cannot be trusted: no "
                       f"convergence rate observed over three levels")
            warnings.warn(f"{sc.mech.name}: {why}, with {how}", AccuracyWarning, stacklevel=user_stacklevel())
        cost = self.corner_cost(final.n, max(self._need, scheme.refine(START_ELEMENTS.get(scheme.name, 24))),
                                time.perf_counter() - self.t0)
        if cost is not None:
            log.info("%s", cost)
            warnings.warn(cost, CostWarning, stacklevel=user_stacklevel())
        res = self.result(final, n_out, error=est, stability=self.stability(est))
        object.__setattr__(res, "path", self.path)
        check_result(res)
        total = time.perf_counter() - self.t0
        kin = self.t_setup + sum(lv.kinematics for lv in self.levels)
        asm = sum(lv.assembly for lv in self.levels)
        slv = sum(lv.solve for lv in self.levels)
        object.__setattr__(res, "timings", Timings(kin, asm, slv, total, self.forecast_s))
        log.info("%s: %s, %s levels %s, converged=%s stable=%s %.3f s", sc.mech.name, scheme.name,
                 len(self.levels), [lv.n for lv in self.levels], final.converged,
                 res.stable, total)
        return res
