"""``kf.continuation``: the periodic response followed over a parameter, its stability and bifurcations.

The response of a scene is followed from ``lo`` to ``hi`` of a parameter (the drive speed, or
any scene or mechanism parameter of a scene dictionary, as in sweeps) by pseudo-arclength
continuation on a fixed number of time elements (:mod:`kedfem.analysis.branch`): folds of the
response curve are passed, so the whole curve comes out, its unstable parts included. Each
point of the branch is a converged periodic response with

* the Floquet multipliers of the orbit (the linearisation about it, the state-dependent
  effects' consistent tangent included) and the verdict stable / unstable;
* every flexible link's peaks, with their estimated time-discretisation error (a
  :func:`kedfem.solve` of the point on ``n/4, n/2, n`` elements, started from it).

Where the stability changes the crossing is located (secant on the crossing multiplier's
``|mu| - 1``, to ``1e-4`` of the parameter) and classified: a real multiplier through +1 (a
fold of the response curve), through -1 (a flip: period doubling), a complex pair (Neimark-
Sacker). Past a flip the period-2 response is computed too (the same problem over two drive
cycles, started from the period-1 orbit plus its flip mode) and followed to ``hi``.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..checks import flag, integer, real
from ..errors import InputError, KedError, NonlinearSolveError
from ..solvers import schemes
from .branch import Family, Point, Tracker, classify, in_unit
from .progress import Reminder
from .results import PeriodicResult
from .scene import Scene
from ..units import RPM_PER_RAD_S

__all__ = ["continuation", "Branch", "BranchPoint", "Bifurcation", "RPM_PER_RAD_S"]

log = logging.getLogger(__name__)

#: relative tolerance of a located bifurcation's parameter value
LOCATE_RTOL = 1e-4
#: a branch whose rest is forecast longer than this [s] says so in a logged warning (again when
#: that has doubled: :class:`kedfem.analysis.progress.Reminder`)
LONG_BRANCH = 60.0


class _Pace:
    """How long the rest of a branch will likely take: the parameter still to cover times the
    seconds per unit of it so far (the farthest value reached, so a branch turning back at a fold
    does not make the rest look shorter). Shown on the bar; logged as a warning from the third
    point on and a tenth of the range, when above :data:`LONG_BRANCH`, and again each time it has
    doubled since (three times at most; a new user's branch ran 28 minutes with nothing said)."""

    def __init__(self, lo: float, hi: float, n: int, unit: tuple, t0: float, errors: bool = False):
        self.lo, self.hi, self.n, self.unit, self.t0, self.errors = lo, hi, n, unit, t0, errors
        self.far = lo
        self.left = None
        self._tell = Reminder(LONG_BRANCH)

    def __call__(self, lam: float, points: int) -> str:
        now = time.perf_counter()
        up = self.hi > self.lo
        self.far = max(self.far, lam) if up else min(self.far, lam)
        covered, span = abs(self.far - self.lo), abs(self.hi - self.lo)
        self.left = (now - self.t0) * max(span - covered, 0.0) / covered if covered > 0 else None
        if points >= 3 and covered >= 0.1 * span and self._tell.due(self.left):
            log.warning("continuation: %s of %s reached in %d points (%.0f s): about %.0f s more at this pace, "
                        "%d time elements a cycle%s (fewer time elements or a narrower range is faster%s; Ctrl-C "
                        "ends the branch where it has got and returns it)", in_unit(self.far, self.unit, 5),
                        in_unit(self.hi, self.unit, 5), points, now - self.t0, self.left, self.n,
                        ", then each point's error estimate (two coarser solves a point)" if self.errors else "",
                        ", and no error estimates" if self.errors else "")
        return "" if self.left is None else f", about {self.left:.0f} s left"


@dataclass(frozen=True)
class BranchPoint:
    """One converged periodic response of a branch.

    Attributes
    ----------
    value : float
        Parameter value (for the speed [rad/s]; a scene key in its own unit).
    peaks : tuple of LinkPeaks
        Every flexible link's peak deflection and stress (:meth:`kedfem.PeriodicResult.peaks`).
    errors : tuple of LinkError
        Their estimated relative time-discretisation errors (empty when not estimated).
    multipliers : ndarray of complex, shape (2 N,)
        Floquet multipliers of the orbit.
    spectral_radius : float
        Largest ``|multiplier|``.
    stable : bool
        Every multiplier inside the unit circle.
    periods : int
        Drive cycles per period of the response (1 or 2).
    result : PeriodicResult or None
        The response (None when its read-out failed).
    """

    value: float
    peaks: tuple
    errors: tuple
    multipliers: np.ndarray = field(repr=False)
    spectral_radius: float
    stable: bool
    periods: int = 1
    result: PeriodicResult | None = field(default=None, repr=False, compare=False)

    def peak(self, link: str, quantity: str = "stress") -> float:
        """A link's peak ``"stress"`` [Pa] or ``"deflection"`` [m]."""
        for p in self.peaks:
            if p.link == link:
                return float(getattr(p, quantity))
        raise InputError(f"branch point: no flexible link {link!r} (links: {', '.join(p.link for p in self.peaks)})")


@dataclass(frozen=True)
class Bifurcation:
    """A located loss or gain of stability (or a fold) of a branch.

    Attributes
    ----------
    kind : {"fold", "flip", "neimark-sacker"}
        The crossing multiplier: real through +1, real through -1, a complex pair.
    value : float
        Located parameter value.
    bracket : (float, float)
        Parameter values of the last iterates either side (its resolution).
    multiplier : complex
        The crossing multiplier at the located point.
    stable_before, stable_after : bool
        Stability of the branch before and after (along the branch).
    """

    kind: str
    value: float
    bracket: tuple
    multiplier: complex
    stable_before: bool
    stable_after: bool

    def describe(self, unit: str = "rpm", scale: float = RPM_PER_RAD_S) -> str:
        what = {"fold": "fold (a multiplier through +1: the response curve turns)",
                "flip": "flip (a multiplier through -1: period doubling)",
                "neimark-sacker": "Neimark-Sacker (a complex pair through the unit circle: a torus)"}[self.kind]
        change = ("loses stability" if self.stable_before and not self.stable_after else
                  "gains stability" if self.stable_after and not self.stable_before else "stability unchanged")
        return (f"{what} at {self.value * scale:.6g} {unit} (bracket {self.bracket[0] * scale:.6g} .. "
                f"{self.bracket[1] * scale:.6g}); the branch {change}; multiplier {self.multiplier:.4f}")


@dataclass(frozen=True)
class Branch:
    """The periodic response followed over a parameter (see the module docstring).

    Attributes
    ----------
    parameter : str
        ``"speed"`` or the dotted scene key.
    unit : str
        The parameter's unit (``"rad/s"`` for the speed).
    points : tuple of BranchPoint
        In the order of the branch (the parameter may turn back at folds).
    bifurcations : tuple of Bifurcation
        Every located fold, flip and Neimark-Sacker point, in the order of the branch.
    elements : int
        Time elements per drive cycle of the branch.
    scheme : str
    periods : int
        1; 2 for a period-doubled branch.
    subharmonic : Branch or None
        The period-2 branch that starts at the first flip (None: no flip, or not computed).
    end : str
        Why the branch ends (``"reached hi"``, ``"stalled at ..."``, ``"interrupted at ..."``: a
        Ctrl-C while it was followed, which returns the points so far without their errors and
        without the period-2 branch).
    wall_time : float
        [s].
    solves : int
        Linear periodic solves spent.
    """

    parameter: str
    unit: str
    points: tuple
    bifurcations: tuple
    elements: int
    scheme: str
    periods: int = 1
    subharmonic: "Branch | None" = None
    end: str = ""
    wall_time: float = float("nan")
    solves: int = 0

    @property
    def values(self) -> np.ndarray:
        """Parameter values of the points, shape (n_points,)."""
        return np.array([p.value for p in self.points])

    @property
    def stable(self) -> np.ndarray:
        """Stability of the points, shape (n_points,) of bool."""
        return np.array([p.stable for p in self.points], dtype=bool)

    @property
    def stability_changes(self) -> tuple:
        """The bifurcations where the branch's stability changes."""
        return tuple(b for b in self.bifurcations if b.stable_before != b.stable_after)

    @property
    def first_loss_of_stability(self) -> Bifurcation | None:
        """The first point along the branch where a stable response becomes unstable (None: none)."""
        for b in self.bifurcations:
            if b.stable_before and not b.stable_after:
                return b
        return None

    @property
    def links(self) -> tuple:
        return tuple(p.link for p in self.points[0].peaks) if self.points else ()

    def _scale(self):
        return (RPM_PER_RAD_S, "rpm") if self.parameter == "speed" else (1.0, self.unit)

    def describe(self) -> str:
        """A few lines: the range followed, the stable parts, the bifurcations, why it ends."""
        s, u = self._scale()
        v = self.values * s
        L = [f"{'period-2 ' if self.periods == 2 else ''}branch over {self.parameter} ({u}): {len(self.points)} "
             f"points from {v[0]:.6g} to {v[-1]:.6g} ({v.min():.6g} .. {v.max():.6g})"
             + (f", {self.elements} {self.scheme} time elements per cycle, {self.solves} linear solves, "
                f"{self.wall_time:.1f} s" if self.elements else "")]
        for b in self.bifurcations:
            L.append("  " + b.describe(u, s))
        if not self.bifurcations:
            L.append(f"  no change of stability: {'stable' if self.stable.all() else 'unstable' if not self.stable.any() else 'mixed'} throughout")
        first = self.first_loss_of_stability
        if first is not None:
            L.append(f"  first loss of stability: {first.kind} at {first.value * s:.6g} {u}")
        L.append(f"  end: {self.end}")
        if self.subharmonic is not None:
            L.extend("  " + line for line in self.subharmonic.describe().splitlines())
        return "\n".join(L)

    def table(self) -> tuple:
        """Rows ``(point, value, link, peak_deflection_m, deflection_error, peak_stress_Pa,
        stress_error, spectral_radius, stable, periods)`` (one per point and flexible link)."""
        rows = []
        for i, p in enumerate(self.points):
            errs = {e.link: e for e in p.errors}
            for lp in p.peaks:
                e = errs.get(lp.link)
                rows.append((i, p.value, lp.link, lp.deflection, e.deflection if e else float("nan"), lp.stress,
                             e.stress if e else float("nan"), p.spectral_radius, p.stable, p.periods))
        return tuple(rows)


# ---------------------------------------------------------------------- the family
def _family_of(scene, parameter: str):
    """``scene_of(value) -> Scene`` and the parameter's unit."""
    if parameter == "speed":
        if not isinstance(scene, Scene):
            raise InputError(f"continuation: scene must be a kf.Scene (its speed is the parameter), got "
                             f"{type(scene).__name__}")
        return (lambda w: dataclasses.replace(scene, speed=float(w))), "rad/s"
    if isinstance(scene, Scene) or not callable(scene):
        raise InputError(f"continuation: parameter {parameter!r} is not the speed: give the scene as a function "
                         "of its value, f(value) -> Scene (kf.scene_family(base, key) makes one from a scene "
                         "dictionary, as for sweeps)")

    def scene_of(v):
        sc = scene(float(v))
        if not isinstance(sc, Scene):
            raise InputError(f"continuation: the scene function returned {type(sc).__name__}, not a kf.Scene")
        return sc

    return scene_of, ""


def _elements(scene_of, lo, hi, steps, scheme) -> int:
    """Time elements of the branch: what the tolerance needs at ``lo`` and the excitation at
    ``hi`` (the highest parameter value usually excites the most modes)."""
    from .pipeline import _Run, solve
    if steps is not None:
        return scheme.check_elements(integer("continuation", "steps", steps, 3))
    need = 0
    for v in (lo, hi):
        run = _Run(scene_of(v))
        n, _f = run.resolution()
        need = max(need, int(math.ceil(n * scheme.per_period)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            n_lo = solve(scene_of(lo)).elements
        except KedError:
            n_lo = 0
    n = max(need, n_lo, scheme.min_elements)
    m = max(scheme.min_elements, 12)
    while m < n:
        m = scheme.refine(m)
    return m


def _read(scene_of, point: Point, n: int, errors: bool, periods: int) -> BranchPoint:
    """A branch point as a result: :func:`kedfem.solve` on ``n`` elements started from it."""
    from .pipeline import solve
    mu = np.asarray(point.multipliers)
    rho = float(np.abs(mu).max()) if mu.size else 0.0
    res = None
    if periods == 1 and errors:  # without errors the point's own discretisation is the answer
        sc = dataclasses.replace(scene_of(point.lam), steps=n, estimate=bool(errors))
        start = _as_result(sc, point)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                res = solve(sc, progress=False, start=start)
            except KedError as e:
                log.info("continuation: the point at %.6g could not be read out: %s", point.lam, e)
                res = None
    if res is not None and res.converged:
        errs = tuple(res.error.links) if res.error is not None else ()
        return BranchPoint(point.lam, tuple(res.peaks()), errs, mu, rho, rho < 1.0, periods, res)
    peaks, res = _peaks_of(scene_of, point, periods)
    return BranchPoint(point.lam, peaks, (), mu, rho, rho < 1.0, periods, res)


def _as_result(scene, point: Point) -> PeriodicResult:
    """A minimal result holding a branch point's dense output (a start for :func:`solve`)."""
    from ..fe.model import FEModel
    from ..motion.kinematics import Cycle
    from .results import Sampler
    d = point.discrete
    model = FEModel(scene.mech, reduction=scene.reduction)
    cyc = Cycle(scene.mech)
    t = np.array([0.0])
    U, V = d.at(t)
    res = PeriodicResult(scene, model, cyc.at(t), t, cyc.at(t).crank_angle, U, V, tuple(model.dof_labels),
                         np.asarray(d.floquet_multipliers), True, True, 0, (), 0.0, None,
                         sampler=Sampler(cyc, d))
    return res


def _peaks_of(scene_of, point: Point, periods: int) -> tuple:
    """Peaks of a point read from its own discretisation (no error estimate: a point without
    errors, a period-2 point, or one whose :func:`solve` failed), and the result they are read
    from: ``(peaks, PeriodicResult or None)``."""
    from .pipeline import _Run
    sc = scene_of(point.lam)
    run = _Run(sc)
    n_out = 360 * periods
    t = np.arange(n_out) * (sc.period * periods / n_out)
    motion = run.cycle.at(np.mod(t, sc.period))
    U, V = point.discrete.at(t)
    from .results import Sampler, Timings
    res = PeriodicResult(sc, run.model, motion, t, motion.crank_angle, U, V, tuple(run.model.dof_labels),
                         np.asarray(point.multipliers), bool(np.abs(point.multipliers).max() < 1.0), True, 0, (), 0.0,
                         Timings(0.0, 0.0, 0.0, 0.0), elements=point.discrete.n, periods=periods,
                         sampler=Sampler(run.cycle, point.discrete) if periods == 1 else None)
    try:
        return tuple(res.peaks()), res
    except KedError:
        return (), None


# ---------------------------------------------------------------------- tracking
def _same_fold(found: list, c) -> bool:
    """The last listed bifurcation is a fold within 1e-3 of the fold ``c`` (one fold seen twice:
    as the turn of the parameter and as the multiplier's crossing of +1)."""
    return bool(found) and found[-1][0].kind == "fold" and abs(found[-1][0].lam - c.lam) <= 1e-3 * abs(c.lam)


def _track(family: Family, p0: Point, p1: Point, lo: float, hi: float, max_points: int, eps: float, bar,
           unit: tuple = (1.0, ""), pace: _Pace | None = None):
    """Pseudo-arclength from two points until the parameter leaves ``[lo, hi]``; the points and
    the located bifurcations (as ``(Crossing, stable_before, stable_after)``). Interrupted
    (Ctrl-C), the branch ends at its last point, ``end`` saying so."""
    tr = Tracker(family, eps=eps)
    tr.set_scale(p1.x, p1.lam)
    t = tr.unit(p1.x - p0.x, p1.lam - p0.lam)
    p1.tangent = t
    p1.s = tr.norm(p1.x - p0.x, p1.lam - p0.lam)
    pts = [p0, p1]
    found = []
    end = "reached the end of the range"
    up = hi > lo
    while len(pts) < max_points:
        p = pts[-1]
        try:
            q = tr.advance(p, p.tangent)
            kind = None if q is None else classify(p.multipliers, q.multipliers)
            c = None if kind is None else tr.locate(p, q, kind, lam_rtol=LOCATE_RTOL)
        except KeyboardInterrupt:
            end = f"interrupted at {in_unit(p.lam, unit, 6)} (Ctrl-C)"
            log.warning("continuation: %s: the branch so far is returned (%d points)", end, len(pts))
            break
        if q is None:
            end = f"stalled at {p.lam:.6g} (the step length fell below its minimum)"
            break
        if kind is not None:
            if kind == "fold" and _same_fold(found, c) and found[-1][1] == found[-1][2]:
                found.pop()  # the turn seen a step earlier is this fold: the multiplier's crossing locates it
            found.append((c, p.stable, q.stable))
        elif len(pts) >= 2 and math.copysign(1.0, p.tangent[-1]) != math.copysign(1.0, q.tangent[-1]):
            c = tr.fold_between(pts[-2], p, q)  # a fold where the stability does not change
            if not _same_fold(found, c):  # (the crossing of the step before was this fold already)
                found.append((c, p.stable, q.stable))
        pts.append(q)
        left = pace(q.lam, len(pts)) if pace is not None else ""
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(f"{in_unit(q.lam, unit, 5)}, rho {q.rho:.3g}{left}", refresh=False)
        if (q.lam > hi if up else q.lam < hi) or (q.lam < lo if up else q.lam > lo):
            # the branch left the range: end it on the boundary
            bound = hi if (q.lam > hi if up else q.lam < hi) else lo
            tau = (bound - p.lam) / (q.lam - p.lam)
            last = tr.fixed(p.x + tau * (q.x - p.x), bound)
            pts[-1] = last if last is not None else q
            end = "reached hi" if bound == hi else "returned below lo (the branch turned back)"
            break
    else:
        end = f"stopped after {max_points} points"
    return pts, found, end


def continuation(scene, lo: float, hi: float, *, parameter: str = "speed", steps: int | None = None,
                 errors: bool = True, period2: bool = True, max_points: int = 300,
                 progress: bool | None = None) -> Branch:
    """Follow the periodic response of a scene over a parameter, through folds; its stability
    and bifurcations (see the module docstring).

    Parameters
    ----------
    scene : Scene or callable
        The scene (its speed is the parameter), or for another parameter a function of its value
        ``f(value) -> Scene`` (:func:`kedfem.io.scenefile.scene_family` makes one from a scene
        dictionary and a dotted key, as for sweeps).
    lo, hi : float
        The range [rad/s for the speed; the key's unit otherwise]; the branch starts at ``lo``.
    parameter : str
        ``"speed"`` (default), or the name of the parameter ``scene`` is a function of
        (``"mechanism.coupler_EI"``), used in tables and plots.
    steps : int, optional
        Time elements per cycle (default: what the tolerance needs at ``lo`` and the excitation
        at ``hi``).
    errors : bool
        Estimate each point's time-discretisation error (two coarser solves per point).
    period2 : bool
        Past a flip, compute and follow the period-2 response.
    max_points : int
        Most points of the branch.
    progress : bool, optional
        A progress bar on stderr (default: on a terminal), with the seconds left at the pace so
        far; a rest forecast above :data:`LONG_BRANCH` is also said in a logged warning (again
        each time it has doubled, three times at most).

    Returns
    -------
    Branch
        Interrupted (Ctrl-C) while it is followed, the branch as far as it got (``end``
        ``"interrupted at ..."``), its points without their errors, no period-2 branch; while its
        error estimates are made, every point, those not reached without theirs (``end`` says
        so). The interrupt ends the call, not the caller: a script looping over branches goes
        on with the next one.

    Raises
    ------
    InputError
        Bad arguments.
    NonlinearSolveError
        No periodic response at ``lo``.
    """
    t0 = time.perf_counter()
    lo = real("continuation", "lo", lo)
    hi = real("continuation", "hi", hi)
    if lo == hi:
        raise InputError("continuation: lo and hi must differ")
    if parameter == "speed" and (lo <= 0 or hi <= 0):
        raise InputError(f"continuation: speeds must be > 0 [rad/s], got lo = {lo:g}, hi = {hi:g}")
    errors = flag("continuation", "errors", errors)
    period2 = flag("continuation", "period2", period2)
    max_points = integer("continuation", "max_points", max_points, 3, 5000)
    if not isinstance(parameter, str) or not parameter:
        raise InputError(f"continuation: parameter must be 'speed' or a dotted scene key, got {parameter!r}")
    scene_of, unit = _family_of(scene, parameter)
    sc0 = scene_of(lo)
    scheme = schemes.get(sc0.scheme)
    if not isinstance(scheme, schemes.Collocation):
        raise InputError(f"continuation: needs a collocation scheme (radau3, radau2, gauss3, gauss2), the scene "
                         f"uses {scheme.name}")
    n = _elements(scene_of, lo, hi, steps, scheme)
    eps = min(sc0.eps, 1e-6)
    family = Family(scene_of, n, scheme, in_speed=parameter == "speed")
    shown_unit = (RPM_PER_RAD_S, "rpm") if parameter == "speed" else (1.0, unit)
    log.info("continuation: %s from %s to %s on %d time elements a cycle, at most %d points%s",
             parameter, in_unit(lo, shown_unit, 6), in_unit(hi, shown_unit, 6), n, max_points,
             ", each point's error from two coarser solves" if errors else "")
    from tqdm.auto import tqdm
    import sys
    bar = tqdm(desc="continuation", unit="point", file=sys.stderr, delay=2.0, leave=False,
               disable=None if progress is None else not progress)
    try:
        # the start: the response at lo (continuation in speed if Newton alone does not get there),
        # and a second point a small step on
        p0 = _start(family, lo, eps)
        d = 0.01 * (hi - lo)
        p1 = None
        for _ in range(6):
            out, x = family.solve(lo + d, p0.x, eps)
            if x is not None:
                p1 = Point(lo + d, x, np.asarray(out.discrete.floquet_multipliers), discrete=out.discrete)
                break
            d *= 0.5
        if p1 is None:
            raise NonlinearSolveError(f"continuation: no second point near lo = {lo:.6g}", highest=lo)
        pts, found, end = _track(family, p0, p1, lo, hi, max_points, eps, bar, shown_unit,
                                 _Pace(lo, hi, n, shown_unit, time.perf_counter(), errors))
    finally:
        bar.close()
    if end.startswith("interrupted"):  # what the user stopped: the points as they are, quickly
        errors = period2 = False
    bifs = tuple(Bifurcation(c.kind, c.lam, c.bracket, c.multiplier, bool(sb), bool(sa)) for c, sb, sa in found)
    disable = None if progress is None else not progress
    read = []
    with tqdm(pts, desc="continuation: peaks and errors" if errors else "continuation: peaks", unit="point",
              file=sys.stderr, delay=2.0, leave=False, disable=disable) as it:
        try:
            for p in it:
                read.append(_read(scene_of, p, n, errors, 1))
        except KeyboardInterrupt:  # the estimates stopped: the rest of the points without theirs
            end += f"; error estimates interrupted after {len(read)} of {len(pts)} points (Ctrl-C)"
            log.warning("continuation: %s", end)
            read += [_read(scene_of, p, n, False, 1) for p in pts[len(read):]]
            period2 = False
    points = tuple(read)
    sub = None
    if period2:
        flip = next((c for c, sb, sa in found if c.kind == "flip"), None)
        if flip is not None:
            try:
                with tqdm(desc="continuation: period 2", unit="point", file=sys.stderr, delay=2.0, leave=False,
                          disable=disable) as bar2:
                    sub = _period2(scene_of, scheme, n, flip, hi, eps, max_points, errors, t0, bar2)
            except KedError as e:
                log.warning("continuation: the period-2 response past the flip at %s was not found: %s",
                            in_unit(flip.lam, shown_unit), e)
    return Branch(parameter, unit, points, bifs, n, scheme.name, 1, sub, end, time.perf_counter() - t0,
                  family.solves)


def _start(family: Family, lam: float, eps: float) -> Point:
    """The converged point at ``lam`` (Newton from the linear response, else continuation)."""
    from .branch import reach
    out, x = family.solve(lam, None, eps)
    if x is not None:
        return Point(lam, x, np.asarray(out.discrete.floquet_multipliers), discrete=out.discrete)
    return reach(family, lam, eps=eps).point


def _period2(scene_of, scheme, n, flip, hi, eps, max_points, errors, t0, bar=None) -> Branch:
    """The period-2 branch born at a flip: the problem over two cycles, started from the period-1
    orbit plus its flip mode, just past the flip, and followed to ``hi``."""
    fam1 = Family(scene_of, n, scheme)
    fam2 = Family(scene_of, 2 * n, scheme, periods=2)
    p = flip.point
    side = 1.0 if hi > p.lam else -1.0
    x2 = None
    for past in (0.002, 0.005, 0.01, 0.02):
        lam = p.lam * (1.0 + side * past) if p.lam != 0 else side * past
        out1, x1 = fam1.solve(lam, p.x, eps)
        if x1 is None:
            continue
        base = _doubled(fam1, fam2, x1, lam, out1.discrete)
        psi = _flip_mode(fam2, base, lam)
        if psi is None:
            continue
        for sign in (1.0, -1.0):
            for amp in (0.05, 0.2):
                out2, y = fam2.solve(lam, base + sign * amp * psi, eps)
                if y is not None and _doubling(y, fam2, lam) > 1e-4:
                    x2 = Point(lam, y, np.asarray(out2.discrete.floquet_multipliers), discrete=out2.discrete)
                    break
            if x2 is not None:
                break
        if x2 is not None:
            break
    if x2 is None:
        raise NonlinearSolveError("no period-2 response distinct from the period-1 one found past the flip",
                                  highest=None)
    d = 0.01 * (hi - x2.lam)
    out, y = fam2.solve(x2.lam + d, x2.x, eps)
    if y is None:
        raise NonlinearSolveError("the period-2 response could not be continued", highest=x2.lam)
    x3 = Point(x2.lam + d, y, np.asarray(out.discrete.floquet_multipliers), discrete=out.discrete)
    pts, found, end = _track(fam2, x2, x3, x2.lam, hi, max_points, eps, bar,
                             (RPM_PER_RAD_S, "rpm"))
    bifs = tuple(Bifurcation(c.kind, c.lam, c.bracket, c.multiplier, bool(sb), bool(sa)) for c, sb, sa in found)
    points = tuple(_read(scene_of, q, 2 * n, errors, 2) for q in pts)
    return Branch("speed", "rad/s", points, bifs, n, scheme.name, 2, None, end, time.perf_counter() - t0,
                  fam2.solves)


def _doubled(fam1: Family, fam2: Family, x1, lam, d1):
    """The period-1 response ``x1`` as a point of the two-cycle problem."""
    prob2 = fam2.problem(lam)
    U, V = d1.at(np.mod(prob2.instants, d1.period))
    return fam2.pack(U, V, lam)


def _flip_mode(fam2: Family, base, lam):
    """The antiperiodic direction of the two-cycle problem about the period-1 orbit: its tangent
    problem, nearly singular along the flip mode just past the flip, answers a generic load with
    that mode; the part that changes sign from one cycle to the next, normalised."""
    prob2 = fam2.problem(lam)
    U, V = fam2.unpack(base, lam)
    terms = prob2.terms
    dC, dK, _dQ = prob2.assembler.state_terms(U, V)
    rng = np.random.default_rng(7)
    Q = rng.standard_normal(terms.Q.shape) * np.abs(terms.Q).max()
    try:
        d = prob2.scheme.solve(terms.M, terms.C, terms.K, Q, prob2.period, prob2.n, dC=dC, dK=dK, **prob2.options)
    except KedError:
        return None
    Ur, Vr = d.instant_states()
    T1 = prob2.period / 2
    Ua, Va = d.at(np.mod(prob2.instants + T1, prob2.period))
    psi = fam2.pack(0.5 * (Ur - Ua), 0.5 * (Vr - Va), lam)
    m = psi.size // 2
    nb, npsi = np.linalg.norm(base[:m]), np.linalg.norm(psi[:m])
    if npsi == 0 or not np.isfinite(npsi):
        return None
    return psi * (nb / npsi)


def _doubling(y, fam2: Family, lam) -> float:
    """How far a two-cycle response is from being 1-periodic: ``|x(t) - x(t + T)| / |x|``."""
    prob2 = fam2.problem(lam)
    U, _V = fam2.unpack(y, lam)
    ni = prob2.instants.size
    half = U[: ni // 2], U[ni // 2:]
    return float(np.linalg.norm(half[0] - half[1]) / max(np.linalg.norm(U), 1e-300))
