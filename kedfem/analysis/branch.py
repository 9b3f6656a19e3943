"""Following a periodic response along a parameter: the numerical engine of continuation.

A *family* is a scene that depends on a parameter ``lam`` (the drive speed, or a mechanism
parameter through its builder), discretised on a fixed number of time elements. A point of its
branch is ``(x, lam)`` with ``x`` the response at the scheme's instants, packed as
``[U, V T / (2 pi)]`` (the velocities in displacement units of the cycle, so that ``x`` changes
smoothly with the speed).

Pseudo-arclength continuation (Keller): from a point and the branch's unit tangent ``t`` the
predictor steps ``ds`` along ``t``; the corrector solves the periodic problem together with the
arclength condition ``<t, (x, lam) - predictor> = 0`` by Newton's method on the bordered
system. Each Newton step uses the periodic solve of the tangent problem twice (the block-cyclic
structure of the linear solve is kept; the border is eliminated):

* ``a = J^-1 F = x - G(x, lam)``, the Newton correction at fixed ``lam``;
* ``b = J^-1 F_lam = (G(x, lam) - G(x, lam + delta)) / delta`` (exact to first order near the
  branch, where ``F`` is small);

then ``d lam = (-N + <t_x, a>) / (t_lam - <t_x, b>)`` and ``d x = -a - b d lam``. At a fold the
periodic problem alone is singular, the bordered one is not: the branch is followed through it.
The step length adapts to the corrector's work and to the predictor's error; a step whose
corrector fails is halved.

Along the branch each point's Floquet multipliers are those of the tangent periodic problem at
the converged orbit (the linear solve ``G`` there). A change of stability between two points is
classified by the multiplier that crossed the unit circle (through +1: a fold; through -1: a
flip, period doubling; a complex pair: Neimark-Sacker) and located by the secant method on
``|mu| - 1`` of that multiplier along the secant between the two points.
"""

from __future__ import annotations

import logging
import math
import warnings
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from ..errors import InstabilityWarning, KedError, UnboundedResponseError
from ..fe.model import FEModel
from ..fe.modal_damping import DampingField
from ..solvers import monodromy
from ..motion.kinematics import Cycle
from .problem import PeriodicProblem, _relative_change, damping_field

__all__ = ["Family", "Point", "Crossing", "Tracker", "damping_field", "classify", "in_unit", "MAX_POINTS"]

log = logging.getLogger(__name__)

#: most points of one branch
MAX_POINTS = 400
#: most linear solves one continuation to a target may spend (:func:`reach`; the four-bar preset
#: needs 147 at 350 rpm on 48 elements, and with the Rayleigh damping of the exact comparison
#: about 1200 at 425 rpm, where it passes two folds at 399.6 and 398.8 rpm with pseudo-arclength
#: steps of 5-10 solves each; a branch that wanders without end would go on for thousands)
MAX_SOLVES = 3000
#: most linear solves of Newton from the linear response when a continuation looks for its start
START_ITER = 16
#: the speeds tried as a start: the target times 0.75, 0.75 f, 0.75 f^2, ... down to half of it,
#: then halves. A continuation's steps can be no longer than the distance of the response's
#: complex singularities in speed, about the damping ratio times the speed (where a harmonic of
#: the drive meets a mode; the four-bar preset near 220 rpm: the response's differences in speed
#: shrink as (h / 2.5 rpm)^k), so every speed nearer the target saves steps of a few solves
#: each; a start that fails costs START_ITER solves
START_FACTOR = 0.85
#: most linear solves of one natural continuation step (a step that needs more is halved)
STEP_ITER = 16
#: the first Newton correction from the predictor (relative to the response) a natural
#: continuation step aims at: the next step is scaled by ``(PREDICTOR_CHANGE / c0)^(1/p)``
#: (``p`` the predictor's order: 1 from one point, 2 from two)
PREDICTOR_CHANGE = 0.05
#: a first correction above this many times the aim rejects the step before its Newton
#: iteration (the four-bar preset at 350 rpm on 48 elements: the steps whose first correction
#: was 0.12 or more failed after 12-16 linear solves, every one at 0.085 or less converged), except
#: a step onto the target, whose problem may sit on elements snapped to the data's kinks (a
#: first correction that does not shrink with the step: 0.10 on 12 elements of the inverted
#: slider-crank)
PREDICTOR_REJECT = 3.0
#: the least the aim falls to after failed steps (it rises back by 1.25 per step that converges)
AIM_LEAST = 0.005
#: tolerance of the Newton iterations at the speeds on the way (the target's is the caller's):
#: they are the predictor's bases, whose error adds to a predictor error of PREDICTOR_CHANGE
STEP_EPS = 1e-3
#: relative tolerance of the arclength corrector (displacements and parameter)
CORRECTOR_EPS = 1e-8
#: most bordered Newton steps of one correction
CORRECTOR_ITER = 8
#: corrector steps that evaluate the border's column ``b`` afresh (later ones keep the last)
FRESH_BORDER = 3
#: relative finite-difference step of the parameter derivative
DELTA = 1e-6
#: largest relative predictor error accepted (larger: the step may have jumped branches)
PREDICTOR_ERROR = 2.0
#: the predictor error (relative to the step) the step control aims at
PREDICTOR_TARGET = 0.5
#: a multiplier within this of the unit circle is on it (stability changes at crossings only)
ON_CIRCLE = 1e-9
#: a multiplier with an imaginary part below this fraction of its modulus is real (the solvers'
#: instability warning names its kind by the same rule)
REAL_TOL = monodromy.REAL_TOL

_FAILURES = (KedError, np.linalg.LinAlgError, FloatingPointError)


class Family:
    """The periodic problems of a parameter family on ``n`` time elements.

    Parameters
    ----------
    scene_of : callable
        ``scene_of(lam) -> Scene``.
    n : int
        Time elements per period of the problem.
    scheme : kedfem.solvers.schemes.Scheme
    periods : int
        Drive cycles per period of the response (2: period doubled).
    in_speed : bool
        ``lam`` is the drive speed and nothing else changes with it: the modal damping field and
        the assembly branch, which follow the configuration at each phase, are made once and read
        at every speed (:meth:`kedfem.fe.modal_damping.DampingField.at_period`,
        :meth:`kedfem.motion.kinematics.Cycle.at_speed`).
    """

    #: problems kept, the most recently used (besides the pinned ones)
    KEEP = 6

    def __init__(self, scene_of, n: int, scheme, periods: int = 1, in_speed: bool = False):
        self.scene_of, self.n, self.scheme, self.periods = scene_of, int(n), scheme, int(periods)
        self.in_speed = bool(in_speed)
        self._field = None  # (the first trigonometric damping field made, its turning sense) (in_speed)
        self._cycle = None  # (the first cycle made, its turning sense) (in_speed)
        self._cache: OrderedDict = OrderedDict()
        self._pinned: dict = {}
        self.solves = 0

    def pin(self, lam: float, prob: PeriodicProblem) -> None:
        """Use ``prob`` at ``lam`` for the family's lifetime (a caller's own problem there: the
        refinement's level at the scene's speed, on elements snapped to the data's kinks, which a
        problem made here on uniform elements is not). The continuation's predictor carries the
        neighbours' values instant by instant onto its instants (a fraction of an element apart
        where they are snapped: Newton's start, not its answer)."""
        if prob.n != self.n or prob.periods != self.periods:
            raise ValueError(f"pin: a problem on {prob.n} elements over {prob.periods} period(s) in a family of "
                             f"{self.n} over {self.periods}")
        self._pinned[float(lam)] = prob

    def problem(self, lam: float) -> PeriodicProblem:
        """The problem at ``lam`` (pinned, or one of the last :attr:`KEEP` made)."""
        key = float(lam)
        if key in self._pinned:
            return self._pinned[key]
        if key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        sc = self.scene_of(key)
        model = FEModel(sc.mech, reduction=sc.reduction)
        turn = math.copysign(1.0, sc.mech.drives[0].speed)  # (the other way, the phases run backwards)
        if self.in_speed and self._cycle is not None and self._cycle[1] == turn:
            cycle = self._cycle[0].at_speed(sc.mech)  # the assembly branch followed once
        else:
            cycle = Cycle(sc.mech)
            if self.in_speed:
                self._cycle = (cycle, turn)
        ni = self.scheme.instants(self.n, sc.period * self.periods).size
        if self._field is not None and self._field[1] == turn:
            field = self._field[0].at_period(sc.period)
        else:
            field = damping_field(sc, model, cycle, ni)  # where it is cheaper than eigenproblems
            if self.in_speed and isinstance(field, DampingField):  # (no kinks: a block's are set in time)
                self._field = (field, turn)
        prob = PeriodicProblem(sc, model, cycle, self.scheme, self.n, damping_field=field, periods=self.periods)
        self._cache[key] = prob
        while len(self._cache) > self.KEEP:
            self._cache.popitem(last=False)
        return prob

    def vscale(self, lam: float) -> float:
        return self.problem(lam).period / (2 * math.pi)

    def pack(self, U, V, lam: float) -> np.ndarray:
        return np.concatenate([np.asarray(U, float).ravel(), (np.asarray(V, float) * self.vscale(lam)).ravel()])

    def unpack(self, x: np.ndarray, lam: float):
        prob = self.problem(lam)
        m = prob.instants.size * prob.N
        return x[:m].reshape(-1, prob.N), x[m:].reshape(-1, prob.N) / self.vscale(lam)

    def step(self, x: np.ndarray, lam: float):
        """``(discrete, G(x, lam))``: one linear periodic solve of the tangent problem."""
        prob = self.problem(lam)
        self.solves += 1
        with warnings.catch_warnings():  # an unstable orbit's solve warns: its multipliers say it
            warnings.simplefilter("ignore", InstabilityWarning)
            d, U, V = prob.step(*self.unpack(x, lam))
        g = self.pack(U, V, lam)
        if not np.all(np.isfinite(g)):
            raise UnboundedResponseError("the tangent problem's periodic solve is not finite")
        return d, g

    def solve(self, lam: float, x0: np.ndarray | None, eps: float, max_iter: int = 30):
        """Newton's method with a line search at fixed ``lam`` from ``x0`` (None: the linear response).

        Returns
        -------
        (Solved, x) ; x is None when it did not converge.
        """
        prob = self.problem(lam)
        start = None if x0 is None else self.unpack(x0, lam)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", InstabilityWarning)
            out = prob.solve(start, eps=eps, max_iter=max_iter, method="newton")
        self.solves += out.iterations
        if not out.converged:
            return out, None
        return out, self.pack(*out.discrete.instant_states(), lam)


@dataclass
class Point:
    """A converged point of a branch.

    Attributes
    ----------
    lam : float
        Parameter value.
    x : ndarray
        Packed response at the instants.
    multipliers : ndarray of complex
        Floquet multipliers of the orbit (the tangent problem at the converged point).
    s : float
        Arclength from the branch's start (weighted norm).
    tangent : ndarray or None
        Unit tangent ``(t_x, t_lam)`` at the point (weighted), oriented along the branch.
    iterations : int
        Corrector steps.
    discrete : object
        The linear solve at the point (its dense output).
    """

    lam: float
    x: np.ndarray
    multipliers: np.ndarray
    s: float = 0.0
    tangent: np.ndarray | None = None
    iterations: int = 0
    discrete: object = field(default=None, repr=False)

    @property
    def rho(self) -> float:
        return float(np.abs(self.multipliers).max()) if self.multipliers.size else 0.0

    @property
    def stable(self) -> bool:
        return self.rho < 1.0 - ON_CIRCLE


def _indicators(mu: np.ndarray) -> dict:
    """``|mu| - 1`` of the largest multiplier of each kind: real positive, real negative, complex."""
    mu = np.asarray(mu, dtype=complex)
    out = {"fold": -1.0, "flip": -1.0, "neimark-sacker": -1.0}
    if not mu.size:
        return out
    a = np.abs(mu)
    real = np.abs(mu.imag) <= REAL_TOL * np.maximum(a, 1e-300)
    for kind, sel in (("fold", real & (mu.real > 0)), ("flip", real & (mu.real < 0)), ("neimark-sacker", ~real)):
        if sel.any():
            out[kind] = float(a[sel].max()) - 1.0
    return out


def classify(before: np.ndarray, after: np.ndarray) -> str | None:
    """The kind of multiplier that crossed the unit circle between two points (None: none did)."""
    ib, ia = _indicators(before), _indicators(after)
    crossed = [k for k in ib if (ib[k] < 0) != (ia[k] < 0)]
    if not crossed:
        return None
    return max(crossed, key=lambda k: abs(ia[k] - ib[k]))  # the one that moved the most through zero


@dataclass(frozen=True)
class Crossing:
    """A located change of stability (or fold) between two branch points.

    Attributes
    ----------
    kind : {"fold", "flip", "neimark-sacker"}
    lam : float
        Located parameter value.
    bracket : (float, float)
        The parameter values of the last iterates either side.
    multiplier : complex
        The crossing multiplier at the located point.
    point : Point
        The located point.
    """

    kind: str
    lam: float
    bracket: tuple
    multiplier: complex
    point: Point


class Tracker:
    """Pseudo-arclength continuation of one branch of a :class:`Family` (module docstring).

    Parameters
    ----------
    family : Family
    eps : float
        Relative tolerance of the corrector.
    ds : float
        First step length (weighted arclength: relative change of the response and the parameter).
    ds_min, ds_max : float
        Step length bounds.
    """

    def __init__(self, family: Family, *, eps: float = CORRECTOR_EPS, ds: float = 0.05, ds_min: float = 1e-5,
                 ds_max: float = 0.25):
        self.family = family
        self.eps = eps
        self.ds, self.ds_min, self.ds_max = ds, ds_min, ds_max
        self.wx = 1.0
        self.wl = 1.0
        self._failed = None  # (step length whose corrector failed, accepted steps it still caps)

    # ------------------------------------------------------------------ geometry
    def set_scale(self, x: np.ndarray, lam: float) -> None:
        """Weights of the arclength norm from a point: relative changes of the displacements and
        of ``lam`` (the velocities follow from the displacements; weighting them too let the
        fast phase changes of lightly damped high modes throttle the steps)."""
        m = x.size // 2
        self.mask = np.zeros(x.size)
        self.mask[:m] = 1.0
        self.wx = 1.0 / max(float(np.dot(x[:m], x[:m])), 1e-300)
        self.wl = 1.0 / max(lam * lam, 1e-300)

    def _dot(self, a: np.ndarray, b: np.ndarray) -> float:
        m = a.size // 2
        return float(np.dot(a[:m], b[:m]))

    def norm(self, dx: np.ndarray, dl: float) -> float:
        return math.sqrt(self.wx * self._dot(dx, dx) + self.wl * dl * dl)

    def unit(self, dx: np.ndarray, dl: float) -> np.ndarray:
        r = self.norm(dx, dl)
        return np.concatenate([dx, [dl]]) / r

    def tangent_at(self, x: np.ndarray, lam: float, direction: float = 1.0) -> np.ndarray:
        """The branch's unit tangent at a converged point: ``(x_lam, 1)`` with ``x_lam = -b``."""
        dl = DELTA * max(abs(lam), 1e-12)
        _d1, g1 = self.family.step(x, lam)
        _d2, g2 = self.family.step(x, lam + dl)
        xl = (g2 - g1) / dl
        return direction * self.unit(xl, 1.0)

    # ------------------------------------------------------------------ corrector
    def correct(self, xp: np.ndarray, lp: float, t: np.ndarray):
        """Bordered Newton from the predictor ``(xp, lp)`` on the hyperplane normal to ``t``.

        Returns
        -------
        Point or None
            None when it does not converge within :data:`CORRECTOR_ITER` steps.
        """
        tx, tl = t[:-1], float(t[-1])
        x, lam = xp.copy(), float(lp)
        b = None
        d = None
        for k in range(1, CORRECTOR_ITER + 1):
            try:
                d, g = self.family.step(x, lam)
                a = x - g
                if b is None or k <= FRESH_BORDER:
                    # the border's column again at the first iterates: near a fold its error grows
                    # as |J^-1|^2 |F|, and the predictor's residual F is not small
                    dl = DELTA * max(abs(lam), 1e-12)
                    _d2, g2 = self.family.step(x, lam + dl)
                    b = (g - g2) / dl
            except _FAILURES as e:
                log.debug("corrector: step %d failed at lam=%.6g: %s", k, lam, e)
                return None
            N = self.wx * self._dot(tx, x - xp) + self.wl * tl * (lam - lp)
            den = self.wl * tl - self.wx * self._dot(tx, b)
            if den == 0.0 or not math.isfinite(den):
                return None
            dlam = (-N + self.wx * self._dot(tx, a)) / den
            dx = -a - b * dlam
            x = x + dx
            lam = lam + dlam
            small = (float(np.linalg.norm(dx)) <= self.eps * max(float(np.linalg.norm(x)), 1e-300)
                     and abs(dlam) <= self.eps * max(abs(lam), 1e-300))
            if not (math.isfinite(lam) and np.all(np.isfinite(x))):
                return None
            if small:  # the multipliers of the orbit: the tangent problem at the (converged) last iterate
                return Point(lam, x, np.asarray(d.floquet_multipliers), iterations=k, discrete=d)
        return None

    def fixed(self, x0: np.ndarray, lam: float) -> Point | None:
        """Correct at a fixed parameter value (Newton with a line search) from ``x0``."""
        try:
            out, x = self.family.solve(lam, x0, self.eps)
        except _FAILURES:
            return None
        if x is None:
            return None
        # a Newton that ended on a chord step: the multipliers of the orbit's own tangent, not of the
        # frozen one (0.9 % off on a Watt six-bar by a resonance; a stability change between points
        # is read from them)
        d = out.orbit() if getattr(out, "orbit", None) is not None else out.discrete
        return Point(lam, x, np.asarray(d.floquet_multipliers), iterations=out.iterations, discrete=d)

    # ------------------------------------------------------------------ stepping
    def advance(self, p: Point, t: np.ndarray):
        """One accepted step from ``p`` along ``t``: (new point, its tangent), or None when the
        step length fell below ``ds_min``."""
        while self.ds >= self.ds_min:
            ds = self.ds
            xp = p.x + ds * t[:-1]
            lp = p.lam + ds * t[-1]
            q = self.correct(xp, lp, t)
            if q is not None:
                err = self.norm(q.x - xp, q.lam - lp) / max(ds, 1e-300)
                if err > PREDICTOR_ERROR and ds > 4 * self.ds_min:
                    self.ds = ds * 0.5
                    continue
                q.s = p.s + self.norm(q.x - p.x, q.lam - p.lam)
                # the secant, the branch's direction at the new point (a second-order predictor
                # is not worth its solves: the step control keeps the secant's error small)
                q.tangent = self.unit(q.x - p.x, q.lam - p.lam)
                grow = min(2.0, math.sqrt(PREDICTOR_TARGET / max(err, 1e-12)))
                if q.iterations > 6:
                    grow = min(grow, 0.7)
                cap = self.ds_max
                if self._failed is not None:  # not straight back to a length whose corrector failed
                    cap = min(cap, 0.8 * self._failed[0])
                    self._failed = None if self._failed[1] <= 1 else (self._failed[0], self._failed[1] - 1)
                self.ds = min(cap, max(ds * grow, self.ds_min))
                self.set_scale(q.x, q.lam)
                q.tangent = self.unit(q.tangent[:-1], q.tangent[-1])
                return q
            self._failed = (ds, 4)
            self.ds = ds * 0.5
        return None

    def locate(self, a: Point, b: Point, kind: str, lam_rtol: float = 1e-4, max_iter: int = 24) -> Crossing:
        """The parameter value between ``a`` and ``b`` where the ``kind`` indicator crosses zero
        (secant/Illinois on the fraction along the secant from ``a`` to ``b``)."""
        dx, dl = b.x - a.x, b.lam - a.lam
        t = self.unit(dx, dl)
        ta, tb = 0.0, 1.0
        fa, fb = _indicators(a.multipliers)[kind], _indicators(b.multipliers)[kind]
        lo, hi = a, b
        best = a if abs(fa) < abs(fb) else b
        side = 0
        for _ in range(max_iter):
            fbest = _indicators(best.multipliers)[kind] if best is not a and best is not b else min(abs(fa), abs(fb))
            if abs(hi.lam - lo.lam) <= lam_rtol * max(abs(best.lam), 1e-300) and abs(fbest) <= 1e-3:
                break
            if tb - ta <= 1e-9:
                break
            tau = tb - fb * (tb - ta) / (fb - fa) if fb != fa else 0.5 * (ta + tb)
            tau = min(max(tau, ta + 0.02 * (tb - ta)), tb - 0.02 * (tb - ta))
            q = self.correct(a.x + tau * dx, a.lam + tau * dl, t)
            if q is None:
                tau = 0.5 * (ta + tb)
                q = self.correct(a.x + tau * dx, a.lam + tau * dl, t)
                if q is None:
                    break
            fq = _indicators(q.multipliers)[kind]
            best = q
            if (fq < 0) == (fa < 0):
                ta, fa, lo = tau, fq, q
                if side == -1:
                    fb *= 0.5
                side = -1
            else:
                tb, fb, hi = tau, fq, q
                if side == 1:
                    fa *= 0.5
                side = 1
        mu = best.multipliers
        if mu.size:
            ind = np.abs(np.abs(mu) - 1.0)
            crit = complex(mu[int(np.argmin(ind))])
        else:
            crit = complex(0.0)
        return Crossing(kind, float(best.lam), (float(min(lo.lam, hi.lam)), float(max(lo.lam, hi.lam))), crit, best)

    def fold_between(self, p: Point, q: Point, r: Point) -> Crossing:
        """The fold (extremum of ``lam`` along the branch) among three points p, q, r whose
        ``lam`` turns at q: a parabola of ``lam`` in arclength, its vertex corrected on the branch."""
        s = np.array([p.s, q.s, r.s])
        lam = np.array([p.lam, q.lam, r.lam])
        c = np.polyfit(s - q.s, lam, 2)
        sv = q.s - c[1] / (2 * c[0]) if c[0] != 0 else q.s
        sv = min(max(sv, p.s), r.s)
        # correct at the vertex along the secant of the two points around it
        a, b = (p, q) if sv <= q.s else (q, r)
        tau = (sv - a.s) / max(b.s - a.s, 1e-300)
        dx, dl = b.x - a.x, b.lam - a.lam
        t = self.unit(dx, dl)
        v = self.correct(a.x + tau * dx, a.lam + tau * dl, t)
        if v is None:
            v = q
        mu = v.multipliers
        crit = complex(mu[int(np.argmin(np.abs(mu - 1.0)))]) if mu.size else complex(1.0)
        lam_v = float(np.polyval(c, sv - q.s)) if v is q else v.lam
        return Crossing("fold", lam_v, (float(min(lam)), float(max(lam))), crit, v)


# ---------------------------------------------------------------------- homotopy
@dataclass(frozen=True)
class Reached:
    """The periodic response at a target parameter value, reached by continuation.

    Attributes
    ----------
    point : Point
        The converged point at the target.
    start : float
        Parameter value where the continuation started (Newton converged from the linear response).
    steps : int
        Continuation steps.
    folds : tuple of float
        Parameter values of the folds passed on the way.
    solves : int
        Linear periodic solves spent.
    path : tuple of Point
        The points on the way (the start first, the target last; those between solved to
        :data:`STEP_EPS`, or the corrector's tolerance through folds, not to ``eps``).
    """

    point: Point
    start: float
    steps: int
    folds: tuple
    solves: int
    path: tuple = ()


def _extrapolate(pts: list, lam: float) -> np.ndarray:
    """Linear extrapolation in the parameter from the last two points (the last one alone)."""
    if len(pts) < 2:
        return pts[-1].x
    a, b = pts[-2], pts[-1]
    return b.x + (b.x - a.x) * ((lam - b.lam) / (b.lam - a.lam))


def _first_correction(family: Family, xp: np.ndarray, lam: float) -> tuple[np.ndarray, float]:
    """Newton's first full step from the predicted ``xp`` at ``lam``: the new iterate (packed)
    and the relative change of its displacements (the predictor's error, as Newton's iteration
    measures its changes)."""
    _d, g = family.step(xp, lam)
    return g, _relative_change(family.unpack(xp, lam)[0], family.unpack(g, lam)[0])


def in_unit(value: float, unit: tuple = (1.0, ""), digits: int = 6) -> str:
    """``value`` stated in ``unit`` = (factor, name): ``in_unit(41.8, (60 / (2 pi), "rpm"))`` ->
    ``"399.2 rpm"`` (the magnitude: a negative speed runs the other way)."""
    return f"{abs(value) * unit[0]:.{digits}g}" + (f" {unit[1]}" if unit[1] else "")


def reach(family: Family, target: float, *, eps: float, lowest: float | None = None,
          max_steps: int = MAX_POINTS, unit: tuple = (1.0, ""), max_solves: int = MAX_SOLVES,
          start: tuple | None = None, progress=None) -> Reached:
    """The response at ``target`` by continuation from a parameter value where Newton's method
    converges from the linear response, or from a given start.

    The start is the given one where Newton converges from it, else the largest of
    ``0.75 target``, 0.64, 0.54, 0.46 of it, then its halves, not below ``lowest`` (default
    ``target / 64``), where it converges (:data:`START_FACTOR`); from there natural continuation
    (a linear predictor in the parameter, Newton with a line search as corrector) steps toward
    ``target``. Newton's first correction from the predictor measures the predictor's error: a
    step on the way whose first correction exceeds :data:`PREDICTOR_REJECT` times the aim
    (:data:`PREDICTOR_CHANGE`, lowered below the first correction of a step whose iteration
    failed, down to :data:`AIM_LEAST`, and raised back by 1.25 per step that converges) is
    shortened before its iteration and not counted as a step, and each step is scaled so that the
    next one's comes near the aim; the speeds on the way are solved to :data:`STEP_EPS`, the
    target to ``eps``. When the step cannot be shortened further a fold
    is likely: pseudo-arclength continuation (:class:`Tracker`) then follows the branch through
    it (and through the fold that may turn it forward again) until it crosses ``target``.

    Parameters
    ----------
    family : Family
    target : float
        Parameter value to reach (for the speed: > 0 [rad/s]).
    eps : float
        Tolerance of the Newton iterations.
    lowest : float, optional
        Smallest parameter value tried as a start.
    max_steps : int
        Most continuation steps.
    max_solves : int
        Most linear solves (the continuation stops, with the error below, when they are spent).
    unit : (float, str)
        Factor and name of the unit the messages state parameter values in (for the speed:
        ``(60 / (2 pi), "rpm")``).
    start : (float, ndarray), optional
        A parameter value below ``target`` and a packed response there (:meth:`Family.pack`),
        e.g. a result the user passed as a start: tried first.
    progress : callable, optional
        ``progress(lam, start, steps)``, called when the continuation has found its start
        (``lam = start``) and after each point it reaches on its way (``lam``: the parameter
        value reached, ``start``: where it started, ``steps``: the steps taken so far).

    Returns
    -------
    Reached

    Raises
    ------
    NonlinearSolveError
        No start found, or the continuation stalls before ``target`` (``highest``: the largest
        parameter value reached).
    """
    from ..errors import NonlinearSolveError
    sign = 1.0 if target > 0 else -1.0

    def fmt(v: float) -> str:
        return in_unit(v, unit)

    lowest = abs(target) / 64 if lowest is None else abs(lowest)
    solves0 = family.solves

    def spent() -> bool:
        return family.solves - solves0 >= max_solves

    given, start = start, None
    if given is not None and 0.0 < abs(given[0]) < abs(target) * (1 - 1e-12):
        try:
            out, x = family.solve(sign * abs(given[0]), given[1], eps, max_iter=START_ITER)
        except _FAILURES:
            x = None
        if x is not None:
            start = Point(sign * abs(given[0]), x, np.asarray(out.discrete.floquet_multipliers),
                          discrete=out.discrete)
    lam = 0.75 * abs(target)
    tried = lam
    while start is None and lam >= lowest * (1 - 1e-12):
        tried = lam
        try:
            out, x = family.solve(sign * lam, None, eps, max_iter=START_ITER)
        except _FAILURES:
            x = None
        if x is not None:
            start = Point(sign * lam, x, np.asarray(out.discrete.floquet_multipliers), discrete=out.discrete)
            break
        lam *= START_FACTOR if lam > 0.5 * abs(target) else 0.5
    if start is None:
        raise NonlinearSolveError(
            f"no periodic response found from the linear response at any of {fmt(0.75 * target)} .. "
            f"{fmt(tried)} (below the target): the non-linear iteration does not converge even far below "
            "the target", highest=None,
            tried="Newton from the linear response at 0.75, 0.64, 0.54, 0.46 of the target and its halves below")
    pts = [start]
    step = 0.1 * abs(start.lam)
    folds: list[float] = []
    steps = 0
    if progress is not None:
        progress(start.lam, start.lam, steps)
    aim = PREDICTOR_CHANGE
    lost = ""  # why pseudo-arclength did not get through a fold
    while abs(pts[-1].lam) < abs(target) * (1 - 1e-12) and steps < max_steps and not spent():
        new = sign * min(abs(target), abs(pts[-1].lam) + step)
        on_way = abs(new) < abs(target) * (1 - 1e-12)
        order = 1 if len(pts) < 2 else 2  # the predictor's: constant from one point, linear from two
        x, counted = None, False
        try:
            first, c0 = _first_correction(family, _extrapolate(pts, new), new)
            if c0 <= PREDICTOR_REJECT * aim or not on_way:
                # Newton goes on from its first full step (the linear solve is not made twice)
                steps, counted = steps + 1, True  # (a step rejected on its first correction is not counted)
                out, x = family.solve(new, first, max(eps, STEP_EPS) if on_way else eps, max_iter=STEP_ITER - 1)
                if x is None and on_way:  # a first correction this large did not converge here: aim lower
                    aim = max(min(aim, 0.7 * c0), AIM_LEAST)
        except _FAILURES:
            steps += 0 if counted else 1
            c0 = math.inf
        if x is not None:
            pts.append(Point(new, x, np.asarray(out.discrete.floquet_multipliers), discrete=out.discrete))
            grow = (aim / c0) ** (1.0 / order) if c0 > 0 else 2.0
            solves = out.iterations + 1  # with the first correction
            step *= min(2.0, max(0.5, grow), 1.5 if solves <= 8 else (1.0 if solves <= 12 else 0.7))
            aim = min(PREDICTOR_CHANGE, 1.25 * aim)  # back toward the aim after a failure lowered it
            if progress is not None:
                progress(new, start.lam, steps)
            continue
        # rejected on its first correction (shorter by what the predictor's order says it needs),
        # or its Newton iteration failed
        step *= min(0.5, max(0.25, (aim / c0) ** (1.0 / order))) if math.isfinite(c0) and c0 > 0 else 0.5
        if step >= 1e-3 * abs(pts[-1].lam):
            continue
        # the natural step cannot be shortened further: a fold; follow the branch through it
        if len(pts) < 2:
            break
        found = _through_folds(family, pts, target, eps, folds, max_steps - steps, spent,
                               None if progress is None else (lambda lam: progress(lam, start.lam, steps)))
        if isinstance(found, str):  # why it did not get there
            lost = found
            if found == "spent" and not spent():  # its points took the steps left
                steps = max_steps
            break
        pts.extend(found)
        step = 0.02 * abs(pts[-1].lam)
        aim = PREDICTOR_CHANGE  # a new stretch of the branch
        if progress is not None:
            progress(pts[-1].lam, start.lam, steps)
    last = pts[-1]
    if abs(last.lam - target) > 1e-12 * abs(target):
        reason = (f"its budget of {max_solves} linear solves spent" if spent() else
                  f"its {max_steps} steps taken" if steps >= max_steps else
                  {"lost": "the steps could not be shortened further: a fold, which pseudo-arclength did not follow",
                   "target": "pseudo-arclength crossed it, and Newton at it did not converge from there"}.get(lost, ""))
        if reason and folds:
            reason += f", through folds at {', '.join(fmt(f) for f in folds)}"
        why = f" ({reason})" if reason else ""
        raise NonlinearSolveError(
            f"the continuation from {fmt(start.lam)} stalled at {fmt(last.lam)} before the target "
            f"{fmt(target)}{why}", highest=abs(last.lam),
            tried=f"Newton from the linear response, then continuation from {fmt(start.lam)}")
    return Reached(last, abs(start.lam), steps, tuple(folds), family.solves, tuple(pts))


def _through_folds(family: Family, pts: list, target: float, eps: float, folds: list, budget: int,
                   spent=lambda: False, progress=None):
    """Pseudo-arclength from the last two points until the branch crosses ``target`` again:
    the points on the way, the last one at ``target`` (Newton at fixed parameter from the
    interpolation); else why not: ``"lost"`` (the arclength step fell below its least), ``"target"``
    (Newton at the target from the interpolation failed), ``"spent"`` (solves or steps spent).
    ``progress(lam)``, if given, after each point (a bar that froze for 8-25 s through a fold, a
    new user found)."""
    tr = Tracker(family, eps=max(eps, CORRECTOR_EPS))
    a, b = pts[-2], pts[-1]
    tr.set_scale(b.x, b.lam)
    t = tr.unit(b.x - a.x, b.lam - a.lam)
    p = b
    start_dir = prev_dir = math.copysign(1.0, t[-1])
    turns = 0
    out = []
    sign = math.copysign(1.0, target)
    for _ in range(max(budget, 1)):
        if spent():
            return "spent"
        q = tr.advance(p, t)
        if q is None:
            return "lost"
        if progress is not None:
            progress(q.lam)
        t = q.tangent
        d = math.copysign(1.0, t[-1])
        if d != prev_dir:
            folds.append(p.lam)
            prev_dir = d
            turns += 1
        if (abs(p.lam) - abs(target)) * (abs(q.lam) - abs(target)) <= 0 and d * sign > 0 \
                and abs(q.lam) >= abs(target):
            tau = (target - p.lam) / (q.lam - p.lam)
            end = tr.fixed(p.x + tau * (q.x - p.x), target)
            return "target" if end is None else out + [end]
        if turns >= 2 and d == start_dir and len(out) >= 2 and abs(q.lam) > abs(out[-1].lam):
            # through the folds and forward again: natural continuation goes on from here
            out.append(q)
            return out
        out.append(q)
        p = q
    return "spent"
