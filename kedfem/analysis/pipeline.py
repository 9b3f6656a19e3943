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
from ..solvers import defect, schemes
from ..fe.model import FEModel
from ..fe.assembler import Assembler
from ..errors import AccuracyWarning, EffectWarning, InputError
from ..motion.kinematics import Cycle, kinematics
from ..fe.modal_damping import DampingField, PiecewiseDampingField
from ..fe.slots import node_crossings
from ..fe.effects.loads import idle_loads, load_breaks, load_force
from ..motion.profiles import distinct_instants
from ..fe.effects import unsimulated
from ..solvers.nonlinear import PREDICT_FRACTION, PREDICT_MAX_CHANGE
from ..solvers.threads import one_blas_thread
from .plausibility import check_passive_links, check_result
from .problem import STREAM_BYTES, PeriodicProblem, constant_or_sampled, damping_field, snapped_edges
from .results import PeriodicResult, Sampler, Stability, Timings, stability_verdict
from .scene import MAX_STEPS, Scene
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
#: a process load whose harmonics ask for this many times the elements the motion alone asks for
#: is named in a logged warning (:meth:`_Run.resolution`)
LOAD_WARN_FACTOR = 4
START_ELEMENTS = {"radau3": 12, "radau2": 16, "gauss3": 12, "gauss2": 16, "magnus2": 45,
                  "foh": 45, "zoh": 90, "fourier": 17}
#: largest ``omega h`` at which a level counts as resolving a mode (one element per period)
RESOLVE_OMEGA_H = 2.0 * math.pi
#: instants of the cycle where the modal frequency bands are sampled
BAND_INSTANTS = 12
#: modes whose per-cycle decay lies within this of the least damped one's (natural logarithm)
#: must keep their multipliers to rtol (:meth:`_Run.stability_floor`)
STAB_MARGIN = 0.25
#: seconds of forecast remaining work beyond which a solve warns before it goes on
LONG_SOLVE = 60.0
#: the forecast's read-out of a level for the estimate, before one is measured, as a share of
#: the level's solve (the catalogue: 0.1 .. 1)
READ_SHARE = 0.5
#: a spectral radius below this, even raised by the most the numerical damping can have lowered
#: it, is stable beyond doubt: the stability floor is not pursued (:meth:`_Run.stable_beyond_doubt`);
#: the verdict needs a margin to 1, not the radius to rtol (the slider-crank at 0.5 % damping:
#: 0.7565 on 48 elements, at most 0.768 by the damping bound, 0.7654 on 192, which the floor
#: asked for at four times the cost); the stated error of the radius includes the bound
CERTAIN_RHO = 0.9
#: below the stability floor a solve stops on its peaks alone when the spectral radius (raised by
#: the damping bound) is below this; between it and CERTAIN_RHO, or when only the modes' physical
#: decay makes the verdict clear, the histories must meet rtol too
HISTORY_FREE_RHO = 0.5
#: a DOF is stiff for the exact split of the exponential holds when the links' axial
#: stiffness carries at least this share of its diagonal stiffness at every instant
AXIAL_SHARE = 0.9


_constant_or_sampled = constant_or_sampled  # (tests use the old name)


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
        neighbour on a branch: :func:`kedfem.continuation` uses it). Default: the linear
        response.

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


def undamped(scene: Scene) -> bool:
    """The scene dissipates no energy: no damping model (or a zero one) and no friction."""
    from ..fe.effects import ModalDamping, Rayleigh
    d = scene.damping
    if isinstance(d, ModalDamping) and d.zeta > 0:
        return False
    if isinstance(d, Rayleigh) and (d.alpha > 0 or d.beta > 0):
        return False
    if "loads" in scene.effects and scene.mech.frictions:
        return False
    return True


def phase_sample(discrete, t, period: float):
    """A discrete solution read at instants ``t`` of a cycle ``period`` long, at the same fractions
    of its own cycle (velocities rescaled to the new cycle): a response at another speed as a
    start."""
    r = discrete.period / period
    U, V = discrete.at(np.asarray(t, dtype=float) * r)
    return U, V * r


def _coarser(scheme, n: int) -> int | None:
    """The level whose refinement is ``n`` (None below the scheme's minimum)."""
    for m in range(max(scheme.min_elements, n // 2 - 1), n):
        if scheme.refine(m) == n:
            return m
    return None


def _harmonic_reach(X: np.ndarray, period: float, level: float, f_low: float = 0.0) -> float:
    """Highest frequency [Hz] of the harmonics of the periodic samples ``X`` (samples, k) above
    ``level`` of each column's largest (the columns below 1e-9 of the largest left out), those
    above ``f_low`` [Hz] weighted by ``(f_low / f)^2`` (0: none); 0 when none is above it."""
    F = np.abs(np.fft.rfft(X - X.mean(axis=0), axis=0))[1:]
    amp = F.max(axis=0)
    keep = amp > 1e-9 * amp.max() if amp.size and amp.max() > 0 else np.zeros(amp.shape, bool)
    if not keep.any():
        return 0.0
    env = (F[:, keep] / amp[keep]).max(axis=1)
    f = np.arange(1, env.size + 1) / period
    if f_low > 0.0:
        env = env * np.minimum(1.0, (f_low / f) ** 2)
    over = np.flatnonzero(env > level)
    return float(f[over.max()]) if over.size else 0.0


class _Run:
    """The levels of one solve and their observables on common output instants."""

    def __init__(self, scene: Scene, progress: bool | None = None, start=None):
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
        self.highest = None  # the highest speed the continuation reached, when it failed
        self._grids: dict[int, tuple] = {}
        self._breaks = None  # instants of kinks in the data (see breaks())
        self._obs: dict[tuple[int, int], accuracy.Observables] = {}
        self._corrected: dict = {}  # level index -> its defect-corrected Discrete (None: not available)
        self._obs_corrected: dict[tuple[int, int], accuracy.Observables] = {}
        self._t_read = 0.0   # seconds spent reading levels for the estimate
        self.forecast_s = None  # the whole solve's wall time as forecast after its second level [s]
        self._more_levels = 0   # levels the forecast expects after the last one solved
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
        if out.converged and out.rate is not None:
            self._rate = out.rate  # the finest level's Newton rate predicts the next level's changes
        if prob.state and not out.converged and sc.nonlinear_method == "newton" and n >= self._need:
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
        log.info("%s: level n=%d (%s) %d iteration(s) rho=%.4g %.3f s", sc.mech.name, n, scheme.name,
                 out.iterations, d.spectral_radius, prob.kinematics + prob.assembly + t_solve)
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
                    "speed (each step a Newton solve on %d elements; tens of steps can take minutes)",
                    sc.mech.name, origin, abs(w) * RPM_PER_RAD_S, prob.n, prob.n)
        if self._bar is not None:
            self._bar.set_postfix_str(f"{prob.n} time elements, continuation in speed", refresh=True)
        fam = Family(lambda s: dataclasses.replace(sc, speed=s), prob.n, self.scheme)
        fam.pin(w, prob)  # the target on this level's own elements (a continuation of more speeds than
        # the family keeps evicted it, and the level came out on uniform elements where it has kinks)
        t0 = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            given = None
            if self.start is not None and self.start.sampler is not None:
                # continue from the given start's own speed, where it is a response
                w0 = self.start.model.mech.drives[0].speed
                p0 = fam.problem(w0)
                given = (w0, fam.pack(*phase_sample(self.start.sampler.discrete, p0.instants, p0.period), w0))
            try:
                r = reach(fam, w, eps=eps, unit=(RPM_PER_RAD_S, "rpm"), start=given)
            except NonlinearSolveError as e:
                self.path = (f"Newton's method from {origin} did not converge; " + str(e))
                self.highest = e.highest
                log.info("%s: %s", sc.mech.name, self.path)  # the NonlinearSolveError says it
                return failed
        rpm = RPM_PER_RAD_S
        folds = (f", through folds at {', '.join(f'{abs(f) * rpm:.1f}' for f in r.folds)} rpm" if r.folds else "")
        self.path = (f"reached by continuation in speed from {r.start * rpm:.4g} rpm ({r.steps} steps{folds}; "
                     f"Newton from {origin} did not converge at {abs(w) * rpm:.4g} rpm)")
        log.info("%s: %s, %d solves, %.1f s", sc.mech.name, self.path, r.solves, time.perf_counter() - t0)
        d = r.point.discrete
        from .problem import Solved
        return Solved(d, True, failed.iterations + r.solves, failed.history, "newton", list(caught))

    def failure(self, final: _Level):
        """The named error of a non-linear solve that found no periodic response (no result is
        returned: its last iterate is no answer, and neither is a stability verdict from it)."""
        from ..errors import NonlinearSolveError
        sc = self.scene
        rpm = 60.0 / (2 * math.pi)
        w = abs(sc.mech.drives[0].speed)
        if sc.nonlinear_method == "newton":
            tried = (f"Newton's method with a line search from the linear response on {final.n} time elements, "
                     f"then continuation in speed")
            what = self.path or "the continuation did not reach the scene's speed"
        else:
            tried = (f"the {sc.nonlinear_method} iteration on {'/'.join(str(lv.n) for lv in self.levels)} "
                     "time elements (and Anderson acceleration)")
            what = f"it did not converge within max_iter = {sc.max_iter} linear solves"
        highest = (f"; this attempt's continuation got as far as {self.highest * rpm:.6g} rpm (the response may "
                   "exist higher: the steps start from a fraction of the scene's speed)"
                   if self.highest is not None else "")
        nxt = ("kf.continuation(scene, lo, hi) (kedfem continuation SCENE --speeds LO:HI) follows the response "
               "over speed and says where it ends or loses its stability")
        if sc.nonlinear_method != "newton":
            nxt = "nonlinear_method='newton' (the default) continues in speed by itself; " + nxt
        return NonlinearSolveError(
            f"{sc.mech.name}: no periodic response found at {w * rpm:.6g} rpm: {what}{highest}. Tried: {tried}. "
            f"Next: {nxt}", highest=self.highest, tried=tried)

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

    def _clear_at(self, n: int) -> bool:
        """The last level's verdict would be clear on ``n`` elements (:meth:`clearly_stable`)."""
        return self._raised_at(n) < HISTORY_FREE_RHO

    def _raised_at(self, n: int) -> float:
        """The last level's spectral radius raised by the most the numerical damping of ``n``
        elements can lower it (inf when not finite or not bounded)."""
        rho = self.levels[-1].discrete.spectral_radius
        loss = self._stab_loss(n) if self._stab_loss is not None else math.inf
        return rho * math.exp(loss) if (np.isfinite(rho) and loss < 700.0) else math.inf

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

    def _doubt_cleared(self, n: int) -> bool:
        """The last level's verdict would be beyond doubt on ``n`` elements (see
        :meth:`stable_beyond_doubt`)."""
        rho = self.levels[-1].discrete.spectral_radius
        if not np.isfinite(rho):
            return False
        if self.quasi_static_decay() and rho < CERTAIN_RHO:
            return True
        return self._raised_at(n) < CERTAIN_RHO

    def forecast(self, need: int) -> float:
        """Seconds the remaining levels are likely to take.

        The refinement doubles until three levels agree and the finest resolves the modes the drive
        excites (``need`` elements) and, unless the verdict is beyond doubt, the stability floor.
        A level on ``n`` elements costs its kinematics and assembly, ``a + b n``, and its linear
        solves, as many as :meth:`_next_iterations` expects at ``c + d n`` each, both through the
        last two levels (:meth:`_cost_model`; the Whitworth with geometric non-linearity took
        3, 2, 1, 1 solves on its levels, and a forecast per level was 2.9x long), plus the
        read-out of its peaks for the estimate, as measured or, before any, :data:`READ_SHARE`
        of the last level. The whole solve's time is the geometric mean of ending there and of
        ending a level later.
        """
        lv = self.levels[-1]
        last = self.levels[-2:]
        setup = self._cost_model([x.kinematics + x.assembly for x in last], [x.n for x in last])
        one = self._cost_model([x.solve / max(x.iterations, 1) for x in last], [x.n for x in last])
        its = self._next_iterations()
        read = (self._t_read / len(self._obs)) if self._obs else READ_SHARE * (
            last[0].kinematics + last[0].assembly + last[0].solve)
        fixed, per = setup[0] + its * one[0], setup[1] + its * one[1]
        target = self.forecast_elements(need)
        left, n, more = 0.0, lv.n, 0
        while n < target:
            n = self.scheme.refine(n)
            left += fixed + per * n + read
            more += 1
        self._more_levels = more
        # the estimate reads every level once: those solved so far that it has not read yet
        left += read * max(0, len(self.levels) - len(self._obs))
        if target < MAX_STEPS:
            # the refinement often takes one level more than the differences suggest (a quantity
            # before its asymptotic range, the histories below the stability floor): the geometric
            # mean of the two outcomes is within 2x of either
            n = self.scheme.refine(max(target, lv.n))
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

    def _level_eps(self) -> float:
        """The non-linear tolerance of the levels of a tolerance-driven solve: a tenth of rtol
        (their differences are of the order of rtol), at least the scene's ``eps``."""
        sc = self.scene
        return max(sc.eps, COARSE_EPS * sc.rtol) if sc.rtol is not None else sc.eps

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

    def resolution(self) -> tuple[int, float]:
        """Fewest time elements that resolve the modes the drive can excite.

        An L-stable scheme damps the resonant response and the free vibration
        of modes its elements do not resolve, alike at every coarse level, so
        two such levels can agree while both are wrong: the coarser levels of
        an error estimate must resolve (``omega h <= RESOLVE_OMEGA_H``) every
        mode the drive excites. The excitation reaches (a) the highest
        harmonic of the rigid-body motion above ``rtol / 1000`` of its
        largest (the inertia loads and the time variation of ``M, C, K``),
        (b) ``1 / (pi tau)`` of the fastest friction reversal (a regularised
        step of time scale ``tau``), (c) the highest harmonic of the process
        loads (declared loads with a profile) above ``rtol / 1000`` of their
        largest: a kink or a step of a load rings modes far above the
        drive's harmonics (a press's forming force, kinked where the tool
        meets and leaves the part: a 74 nm rod deflection 17 % off on 384
        elements whose three levels agreed to 1e-5). A mode is excited when its frequency
        band (over the cycle) starts within that reach, or within the reach
        of the time variation around an excited mode (its band's top plus
        (a)). Bands come from the co-moving-frame system (the scene's
        effects, no state terms) at :data:`BAND_INSTANTS` instants.

        Returns
        -------
        n : int
            Fewest time elements.
        f : float
            Highest frequency to resolve [Hz].
        """
        from .modal import eig_frequencies
        sc = self.scene
        T = sc.period
        t = np.arange(BAND_INSTANTS) * (T / BAND_INSTANTS)
        asm = Assembler(self.model, self.cycle.at(t), sc.effects, damping=None, frame=True)
        S = asm.system()
        f = eig_frequencies(S.M, S.K, name=sc.mech.name, labels=self.model.dof_labels)
        self._buckled = bool(np.any(f <= 0.0))  # a negative stiffness: growth, not a decaying mode
        f = np.sort(np.abs(f), axis=1)  # (instants, modes), Hz
        lo, hi = f.min(axis=0), f.max(axis=0)
        self._bands = (lo, hi)
        f_kin = self._motion_band(level=1e-3 * sc.rtol)
        f_fr = self._friction_band()
        self._friction_reach = f_fr if f_fr > f_kin else 0.0
        f_ld = self._load_band(level=1e-3 * sc.rtol, f_low=float(lo.min()) if lo.size else 0.0)
        reach = max(f_kin, f_fr, f_ld)

        def elements(reach: float) -> tuple[int, float] | None:
            """Elements and highest frequency [Hz] to resolve for an excitation up to ``reach``
            (None: no mode within it)."""
            excited = lo <= reach
            if not excited.any():
                return None
            excited |= lo <= float(hi[excited].max()) + f_kin  # the time variation mixes an excited
            f_res = float(hi[excited].max())                   # mode into its neighbours
            return int(math.ceil(2.0 * math.pi * f_res * T / RESOLVE_OMEGA_H)), f_res

        found = elements(reach)
        if found is None:
            log.info("%s: no mode within the excitation (%.4g Hz): quasi-static", sc.mech.name, reach)
            return 1, 0.0
        n, f_res = found
        log.info("%s: excitation reaches %.4g Hz, modes to resolve up to %.4g Hz: >= %d elements",
                 sc.mech.name, reach, f_res, n)
        base = max(f_kin, f_fr)
        if f_ld > base and self._load_steps():
            # a process load whose profile steps or kinks rings modes far above the drive's
            # harmonics: say so where it multiplies the elements (a new user's one-stroke forming
            # load dropped to zero at the dead centre: 6144 elements and 12 s where 768 did)
            n0 = (elements(base) or (1, 0.0))[0]
            if n >= LOAD_WARN_FACTOR * n0:
                log.warning("%s: a process load steps (a one-stroke load ending at a dead centre, or a table "
                            "without smooth=True): its harmonics reach %.4g Hz, which asks for >= %d time "
                            "elements where the motion alone asks for %d; a smooth end (a second load for the "
                            "other stroke, as examples/press.py) costs fewer", sc.mech.name, f_ld, n, n0)
        return n, f_res

    def _motion_band(self, samples: int = 512, level: float = 1e-6) -> float:
        """Highest frequency [Hz] of the rigid-body motion's harmonics above ``level``."""
        mo = self._band_motion(samples)
        X = np.concatenate([x.reshape(samples, -1) for x in (mo.a, mo.alpha, mo.omega ** 2, mo.sdd)
                            if x.size], axis=1)
        return _harmonic_reach(X, self.scene.period, level)

    def _load_band(self, level: float, f_low: float = 0.0, samples: int = 16384) -> float:
        """Highest frequency [Hz] of the process loads' harmonics above ``level`` of their largest
        (0 without a process load among the scene's effects), a harmonic above the lowest mode
        ``f_low`` [Hz] weighted by ``(f_low / f)^2``: it drives the stiffer modes there, whose
        response to it is smaller by their stiffness (a pump's smooth stroke load reached 1.9 kHz
        unweighted, 3072 time elements where 384 met the tolerance to 1e-5)."""
        at = self._joint_loads(samples)
        if not at:
            return 0.0
        X = np.concatenate(list(at.values()), axis=1)  # (samples, 2 per joint)
        return _harmonic_reach(X, self.scene.period, level, f_low)

    def _joint_loads(self, samples: int) -> dict[str, np.ndarray]:
        """The process loads (declared with a profile) on each joint together [N] (samples, 2), at
        ``samples`` equally spaced instants (two one-stroke loads on a joint meet); empty without
        one or without ``loads`` among the scene's effects."""
        loads = [ld for ld in self.scene.mech.loads.values() if ld.profile is not None]
        if not loads or "loads" not in self.scene.effects:
            return {}
        mo = self._band_motion(samples)
        at: dict[str, np.ndarray] = {}
        for ld in loads:
            at[ld.joint] = at.get(ld.joint, 0.0) + load_force(mo, ld)
        return at

    def _load_steps(self, samples: int = 16384, jump: float = 0.2) -> bool:
        """A process load on some joint changes by more than ``jump`` of its largest between two of
        ``samples`` instants per cycle: it steps (a one-stroke load at a dead centre, a table
        without smoothing), where a smooth one, however steep, changes by a sliver per sample."""
        for F in self._joint_loads(samples).values():
            big = float(np.abs(F).max())
            if big > 0 and float(np.abs(np.diff(F, axis=0, append=F[:1])).max()) > jump * big:
                return True
        return False

    def _band_motion(self, samples: int):
        """The rigid-body motion at ``samples`` equally spaced instants (computed once)."""
        cache = self.__dict__.setdefault("_band_cache", {})
        if samples not in cache:
            cache[samples] = self.cycle.at(np.arange(samples) * (self.scene.period / samples))
        return cache[samples]

    def _friction_band(self, samples: int = 512) -> float:
        """``1 / (pi tau)`` [Hz] of the fastest reversal of the mechanism's friction forces.

        A force ``-F tanh((v . axis - v_ref) / s)`` reverses where the
        rigid-body velocity crosses ``v_ref``, over ``tau = s / |a . axis|``
        (``a`` the larger of its values at the two samples around the
        crossing: the acceleration is smooth on the scale of a sample).
        """
        mech = self.scene.mech
        if not mech.frictions or "loads" not in self.scene.effects:
            return 0.0
        mo = self._band_motion(samples)
        out = 0.0
        for fr in mech.frictions.values():
            if fr.axis is None:  # a sliding pair: the block's speed on its member
                k = mo.slider_names.index(fr.joint)
                v, a = mo.sd[:, k] - fr.reference_speed, np.abs(mo.sdd[:, k])
            else:
                ax = np.asarray(fr.axis, dtype=float)
                ax = ax / np.linalg.norm(ax)
                j = mo.joint_names.index(fr.joint)
                v = mo.v[:, j] @ ax - fr.reference_speed
                a = np.abs(mo.a[:, j] @ ax)
            cross = np.flatnonzero(np.sign(v) != np.sign(np.roll(v, -1)))
            if cross.size:
                a_c = np.maximum(a[cross], np.roll(a, -1)[cross])
                out = max(out, float(a_c.max()) / (math.pi * fr.smoothing))
        return out

    def stability_floor(self) -> tuple[int, float]:
        """Fewest time elements whose numerical damping leaves the spectral radius within ``rtol``.

        An L-stable scheme damps every mode a little per element (Radau IIA:
        ``-ln|R(i y)| ~ y^6 / 7200`` at ``y = omega h``), so a mode with many
        periods per cycle loses ``n (omega T / n)^6 / 7200`` of its multiplier's
        modulus on ``n`` elements even when the response is resolved (a
        105 Hz mode of a linkage at 300 rpm on 48 elements: a factor 5). The
        scheme only lowers multipliers, so the spectral radius is right to
        ``rtol`` when the modes that set it lose less than that: the modes
        whose physical decay per cycle ``exp(-zeta omega T)`` lies within
        :data:`STAB_MARGIN` (in its logarithm) of the least damped one, with
        ``zeta`` from the scene's damping (modal ratio; Rayleigh ``alpha /
        (2 omega) + beta omega / 2``). Returns the elements and the highest such
        frequency [Hz]; ``(0, 0)`` for schemes without numerical damping and for
        undamped scenes (whose verdict is ``marginal`` by structure).
        """
        from ..fe.effects import ModalDamping, Rayleigh
        sc, scheme = self.scene, self.scheme
        if not scheme.l_stable or self._bands is None or undamped(sc):
            return 0, 0.0
        lo, hi = self._bands
        T = sc.period
        w_lo, w_hi = 2.0 * math.pi * lo, 2.0 * math.pi * hi
        d = sc.damping
        if isinstance(d, ModalDamping):
            zeta = np.full(lo.shape, float(d.zeta))
        elif isinstance(d, Rayleigh):
            zeta = d.alpha / (2.0 * np.maximum(w_lo, 1e-300)) + d.beta * w_lo / 2.0
        else:
            zeta = np.zeros(lo.shape)
        decay = -zeta * w_lo * T  # ln of the physical multiplier modulus per cycle
        self._stab_decay = float(decay[w_lo > 0].max()) if (w_lo > 0).any() else 0.0
        keep = (w_lo > 0) & (decay >= decay.max() - STAB_MARGIN)
        if not keep.any():
            return 0, 0.0
        theta = w_hi[keep] * T
        tol = sc.rtol if sc.rtol is not None else 1e-3
        tab = scheme.tableau

        def loss(n):
            y = theta / n
            z = 1j * y[:, None, None]
            s_ = tab.A.shape[0]
            stage = np.linalg.solve(np.eye(s_)[None] - z * tab.A[None], np.ones((y.size, s_, 1)))[..., 0]
            Rz = 1.0 + z[:, 0, 0] * (stage @ tab.b)
            return float(np.max(-n * np.log(np.abs(Rz))))

        self._stab_loss = loss
        lo_n, n = 1, max(scheme.min_elements, 8)
        while loss(n) > tol and n < MAX_STEPS:
            lo_n, n = n, 2 * n
        while n - lo_n > 1:  # the fewest: bisection (the loss falls monotonically with n)
            mid = (lo_n + n) // 2
            lo_n, n = (lo_n, mid) if loss(mid) <= tol else (mid, n)
        return n, float(hi[keep].max())

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

    def damping_bound(self) -> float:
        """Bound [-] on how much the finest level's numerical damping lowers the spectral radius:
        the true one is at most ``rho (1 + bound)`` (0 once the stability floor is met)."""
        n = self.levels[-1].n
        if not self._stab_need or n >= self._stab_need or self._stab_loss is None:
            return 0.0
        loss = self._stab_loss(n)
        return math.expm1(loss) if loss < 700.0 else math.inf  # a very slow crank: no bound

    def stable_beyond_doubt(self) -> bool:
        """The finest level's spectral radius, raised by the most its numerical damping can have
        lowered it, is still below :data:`CERTAIN_RHO`: more elements would sharpen a number
        whose verdict is not in doubt (a linkage at rho 0.01 refined to 768 elements for it)."""
        rho = self.levels[-1].discrete.spectral_radius
        if not np.isfinite(rho):
            return False
        return self._raised_rho() < CERTAIN_RHO or (self.quasi_static_decay() and rho < CERTAIN_RHO)

    def _raised_rho(self) -> float:
        """The finest level's spectral radius raised by the most its numerical damping can have
        lowered it (inf when that is not bounded)."""
        rho, bound = self.levels[-1].discrete.spectral_radius, self.damping_bound()
        return rho * (1.0 + bound) if (np.isfinite(rho) and math.isfinite(bound)) else math.inf

    def clearly_stable(self) -> bool:
        """The finest level's spectral radius, raised by the most the numerical damping can have
        lowered it, is below :data:`HISTORY_FREE_RHO`: a verdict so clear that the solve stops on
        its peaks alone below the stability floor."""
        return self._raised_rho() < HISTORY_FREE_RHO

    def quasi_static_decay(self) -> bool:
        """No mode within the drive's excitation (:meth:`resolution` said quasi-static) and every
        mode's physical decay over a cycle below :data:`CERTAIN_RHO`: the multipliers are those
        decays (a slowly varying system), and a parametric resonance, which would need a mode
        within the motion's harmonics, cannot raise them to 1. The damping bound says nothing
        here: at 1 rpm the modes decay by ``e^-1500`` per cycle and the scheme's damping
        underflows the computed radius to 0 (the floor asked for 32768 elements)."""
        return (self._need <= 1 and not self._buckled and self._stab_decay < 0.0
                and self._stab_decay < math.log(CERTAIN_RHO) - STAB_MARGIN)

    def stability(self, error=None) -> Stability:
        """Spectral radius of the finest level, its error from the coarser ones, the verdict."""
        rho = [lv.discrete.spectral_radius for lv in self.levels[-3:]]
        err = None
        if len(rho) >= 2 and error is not None:
            ratio = self.levels[-1].n / self.levels[-2].n
            err = abs(rho[-1] - rho[-2]) / (ratio ** error.rate - 1.0)
        bound = self.damping_bound()
        if bound and self.stable_beyond_doubt():
            # the stability floor was not needed for the verdict: the error is what the damping
            # may hide (with fewer elements given than a clear verdict needs, the note says it)
            hidden = rho[-1] * bound if math.isfinite(bound) else math.inf
            if self.quasi_static_decay():  # the modes' own decay bounds the radius
                hidden = min(hidden, math.exp(self._stab_decay + STAB_MARGIN))
            err = max(err or 0.0, hidden)
        verdict = stability_verdict(rho[-1], err)
        if (verdict == "marginal" and len(rho) >= 2 and rho[-1] > 1.0 + 1e-9
                and (min(rho[-2:]) > 1.0 + 1e-9 or rho[-1] >= rho[-2])
                and self.scheme.name.startswith("radau")):
            # Radau's numerical damping lowers the multipliers, the less the finer the level:
            # growth on the two finest levels, or growth that rises with refinement, is real
            # (a buckling rod: 1e51 on 48 elements, its change from 24 as large)
            verdict = "unstable"
        note = ""
        if undamped(self.scene) and verdict != "unstable":
            verdict = "marginal"
            note = ("undamped: the multipliers of a conservative scene lie on the unit circle unless a "
                    "parametric resonance makes them grow; the scheme's numerical damping can hide a weak one")
        elif self._stab_need and self.levels[-1].n < self._stab_need:
            why = ("in its error; not needed for a verdict this clear" if self.stable_beyond_doubt()
                   else "not in its error: give more elements")
            by = (f"by at most {100.0 * bound:.2g} %" if math.isfinite(bound) and bound < 1.0
                  else f"by at most a factor {1.0 + bound:.2g}" if math.isfinite(bound) and bound < 9.0
                  else "by orders of magnitude")
            note = (f"{self.levels[-1].n} time elements damp the modes up to {self._stab_f:.4g} Hz numerically "
                    f"by more than {self.scene.rtol or 1e-3:.0e} per cycle: the spectral radius is too low, "
                    f"{by} ({why}; a resolved radius needs about {self._stab_need} elements: "
                    f"Scene(steps={self._stab_need}) or more)")
        return Stability(rho[-1], err, verdict, self.scheme.name, self.levels[-1].n, note,
                         conservative=bool(undamped(self.scene) and verdict == "marginal"))

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
            # the constraint maps depend on the motion only: built once per output grid
            if "beam_map" in cache:
                res._cache["beam_map"] = cache["beam_map"]
            else:
                cache["beam_map"] = res._beam_map()
        return res

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

    # ------------------------------------------------------------------- run
    def run(self) -> PeriodicResult:
        from tqdm.auto import tqdm
        self._bar = tqdm(desc=self.scene.name or self.scene.mech.name, unit="level", file=sys.stderr, delay=2.0,
                         disable=None if self.progress is None else not self.progress, dynamic_ncols=True,
                         leave=False)
        try:
            return self._run()
        finally:
            self._bar.close()
            self._bar = None

    def _unsimulated(self) -> None:
        """One :class:`EffectWarning` per declared item the scene's effects leave out (a spring and
        its preload, a load, a friction, a gravity set with ``set_gravity``): it is not simulated."""
        mech, eff = self.scene.mech, set(self.scene.effects)
        if "loads" in eff:
            for msg in idle_loads(mech, self.cycle):
                log.info(msg)
                warnings.warn(msg, EffectWarning, stacklevel=4)
        for msg in unsimulated(mech, self.scene.effects):
            log.info(msg)
            warnings.warn(msg, EffectWarning, stacklevel=4)

    def _run(self) -> PeriodicResult:
        self._unsimulated()
        sc, scheme = self.scene, self.scheme
        est = None
        need, f_res = self.resolution() if (sc.estimate or sc.steps is None) else (0, 0.0)
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
            for m in plan + [n]:
                self.level(m)
            n_out = self.output_steps(n)
            if sc.estimate:
                est = self.estimate(n_out, need)
                if est is None:
                    msg = (f"{sc.mech.name}: no error estimate: {n} time elements (steps given) have no coarser "
                           f"level of {scheme.name} to compare with (the estimate needs steps >= "
                           f"{scheme.refine(scheme.min_elements)}); leave steps out to meet rtol")
                    warnings.warn(msg, AccuracyWarning, stacklevel=3)
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
                    if len(self.levels) == 1 and left > LONG_SOLVE:
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
                        self._bar.set_postfix_str(f"{n} time elements, error {est.peak:.1e}", refresh=True)
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
        for w in final.caught:  # warnings of the result's own solve (coarse levels' are dropped)
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        if est is not None and sc.rtol is not None and not est.met:
            how = (f"{final.n} time elements (steps given)" if sc.steps is not None
                   else f"the largest number of time elements ({final.n}, limit {MAX_STEPS})")
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
            warnings.warn(f"{sc.mech.name}: {why}, with {how}", AccuracyWarning, stacklevel=3)
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
