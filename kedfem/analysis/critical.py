"""Critical speeds: the onset of parametric instability and of buckling, bracketed and refined.

Two questions an engineer asks of a linkage that is to run faster:

* ``kind="parametric"``: from which speed does its periodic response stop being
  stable, the largest Floquet multiplier modulus ``rho`` (``res.stability``)
  crossing 1? Each evaluation is one tolerance-driven periodic solve.
* ``kind="buckling"``: from which speed does a link buckle somewhere in the
  cycle, the lowest eigenvalue ``lambda_1 = (2 pi f_1)^2`` of the modal problem on
  the rigid-body motion (co-moving frame, kinetostatic geometric stiffness and
  centripetal softening) crossing zero? Each evaluation is one modal analysis
  over the cycle (no periodic solve).

:func:`critical_speed` takes a bracket ``[lo, hi]`` whose ends lie on either
side (optionally scanning inside it, upward, for the first change), then
narrows it by the ITP method (:func:`itp_root`: regula falsi, truncated toward
the midpoint and projected so that it never needs more than one step over
bisection) in ``log(speed)``, on ``log rho`` (on ``-lambda_1``, roughly linear in
``speed^2``, for buckling), until the bracket is narrower than ``rtol`` of the
speed. Plain regula falsi, even Illinois, creeps on the spectral radius:
``log rho`` is flat below a tongue of parametric resonance (the damping's decay
per cycle) and rises like a square root inside it, so the interpolation keeps
landing on the flat side (the slider-crank: 14 solves without reaching 5e-3
from a 3x bracket; ITP: 12). A point whose ``rho`` lies within its
estimated error of 1 (``res.stability.verdict == "marginal"``) is solved again
at a tenth of the scene's tolerance before its side is believed.

``rho`` may cross 1 several times: tongues of instability with stable speeds
between them (the four-bar: unstable 592.7-611.9 rpm, stable to 616.7, unstable
above; the slider-crank: unstable 5247-5574 rpm, stable to 6054). The search
finds a crossing of its bracket, the lowest one when the bracket holds a
single one; ``scan`` or a :func:`kedfem.io.design_plots.stability_map` first
tells where they are.

By default the question is asked of the scene as it is: with
``geometric_nonlinearity`` the spectral radius is that of the non-linear orbit
(the linearisation about the converged periodic response, the effect's
consistent tangent included; :func:`kedfem.solve` reaches the orbit by
continuation in speed where Newton's method alone does not), each evaluation
starting from the response at the nearest speed already solved. ``linear=True``
asks it of the linearised KED equations about the rigid-body motion instead:
``geometric_nonlinearity`` is replaced by ``axial_stiffening``
(:func:`kedfem.fe.effects.linear_effects`), as in ``benchmarks/stability.py``.
Where a stable orbit turns back at a fold, :func:`kedfem.continuation` follows the
whole response curve and locates the change of stability there.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..checks import choice, flag
from ..errors import AccuracyWarning, ConvergenceWarning, InputError, UnboundedResponseError
from .buckling import BuckledMode, buckled_mode
from ..fe.effects import linear_effects
from .campbell import RPM_PER_RAD_S, cycle_frequencies, scene_at
from .hooks import hook
from .progress import bar
from .scene import Scene, _int

__all__ = ["Evaluation", "CriticalSpeed", "critical_speed", "KINDS"]

log = logging.getLogger(__name__)

#: What :func:`critical_speed` can look for.
KINDS = ("parametric", "buckling")
#: The quantity followed by each kind.
QUANTITY = {"parametric": "spectral radius [-]", "buckling": "lowest natural frequency over the cycle [Hz]"}
#: log of the spectral radius taken for an overflowing (unbounded) response
LOG_RHO_MAX = math.log(1e300)


@dataclass(frozen=True)
class Evaluation:
    """One solve (or modal analysis) of the search.

    Attributes
    ----------
    speed : float
        [rad/s].
    value : float
        Spectral radius [-] (parametric; ``inf`` for an unbounded response) or
        the lowest natural frequency over the cycle [Hz] (buckling; negative:
        buckled).
    error : float
        Estimated absolute error of ``value`` (``res.stability.error``; 0 if none).
    side : int
        -1 stable (not buckled), +1 unstable (buckled), 0 undecided (``value``
        within ``error`` of the threshold after the tighter solve too).
    elements : int
        Time elements of the solve (0 for a modal analysis).
    """

    speed: float
    value: float
    error: float
    side: int
    elements: int = 0

    @property
    def rpm(self) -> float:
        """``speed`` [rev/min]."""
        return self.speed * RPM_PER_RAD_S


@dataclass(frozen=True)
class CriticalSpeed:
    """A critical speed, with its bracket and how it was found.

    Attributes
    ----------
    kind : {"parametric", "buckling"}
    speed : float
        Critical speed [rad/s]: the root of the regula-falsi line inside ``bracket``.
    bracket : tuple of float
        Speeds [rad/s] of the last evaluations on either side: the critical speed
        lies between them.
    solves : int
        Evaluations used (periodic solves, or modal analyses for buckling).
    rtol : float
        Relative tolerance asked on the speed.
    met : bool
        ``bracket[1] - bracket[0] <= rtol * speed``: the critical speed is within
        ``rtol`` of ``speed``.
    value_lo, value_hi : float
        The followed quantity (:attr:`quantity`) at ``bracket[0]`` and ``bracket[1]``.
    direction : {"onset", "exit"}
        ``"onset"``: stable (not buckled) below, unstable above; ``"exit"``: the reverse.
    evaluations : tuple of Evaluation
        Every evaluation, in the order made.
    effects : tuple of str
        The effects of the scene the question was asked of.
    name : str
        Scene name.
    nonlinear : bool
        The scene's effects depend on the elastic state (``geometric_nonlinearity``, friction):
        the crossing is the loss of stability of its periodic response, whose linearisation
        may be stable where the linear scene's is (``describe`` says so instead of
        "parametric instability").
    buckled : BuckledMode or None
        ``kind="buckling"``: the mode at the buckled end of the bracket and the link that carries
        most of it (:func:`kedfem.analysis.buckling.buckled_mode`).
    """

    kind: str
    speed: float
    bracket: tuple[float, float]
    solves: int
    rtol: float
    met: bool
    value_lo: float
    value_hi: float
    direction: str
    evaluations: tuple[Evaluation, ...]
    effects: tuple[str, ...]
    name: str = ""
    nonlinear: bool = False
    buckled: BuckledMode | None = None

    @property
    def rpm(self) -> float:
        """Critical speed [rev/min]."""
        return self.speed * RPM_PER_RAD_S

    @property
    def bracket_rpm(self) -> tuple[float, float]:
        """:attr:`bracket` [rev/min]."""
        return self.bracket[0] * RPM_PER_RAD_S, self.bracket[1] * RPM_PER_RAD_S

    @property
    def quantity(self) -> str:
        """What ``value_lo`` / ``value_hi`` are, with their unit."""
        return QUANTITY[self.kind]

    def describe(self) -> str:
        """One line: the speed, its bracket, the quantity either side, the cost."""
        what = "parametric instability" if self.kind == "parametric" else "buckling"
        if self.kind == "parametric" and self.nonlinear:  # (a new user read "parametric" where the linear
            what = "instability of the non-linear periodic response"  # scene was stable either side)
        if self.direction == "exit":
            what = f"end of {what}"
        met = "met" if self.met else "NOT met"
        lo, hi = self.bracket_rpm
        # decimals that tell the bracket's ends apart (a new user read "3205.14 .. 3205.14 rpm")
        dec = 2 if hi - lo <= 0 else min(max(2, math.ceil(-math.log10((hi - lo) / 2.0))), 9)
        return (f"{self.name + ': ' if self.name else ''}{what} at {self.rpm:.2f} rpm ({self.speed:.4f} rad/s), "
                f"bracket {lo:.{dec}f} .. {hi:.{dec}f} rpm (rtol {self.rtol:g} {met}); "
                f"{self.quantity.split(' [')[0]} {self.value_lo:.6g} / {self.value_hi:.6g} either side; "
                f"{self.solves} {'solves' if self.kind == 'parametric' else 'modal analyses'}"
                f"{'; ' + self.buckled.describe() if self.buckled is not None else ''}")


# ------------------------------------------------------------ evaluations
def _solve_rho(sc: Scene, start=None):
    """Spectral radius of the scene's periodic solve, its error and its side (and the result)."""
    from .pipeline import solve
    speed = abs(sc.mech.drives[0].speed)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            res = solve(sc, start=start if sc.state_dependent else None)
        except UnboundedResponseError:
            log.info("critical_speed: %.2f rpm: unbounded response (rho > 1e300)", speed * RPM_PER_RAD_S)
            return Evaluation(speed, math.inf, 0.0, 1, 0), None
    for w in caught:  # an unstable scene's response is large and the instability is the question
        important = issubclass(w.category, (AccuracyWarning, ConvergenceWarning))
        log.log(logging.WARNING if important else logging.DEBUG, "critical_speed at %.2f rpm: %s: %s", speed * RPM_PER_RAD_S,
                w.category.__name__, w.message)
    st = res.stability
    if st.note:
        log.info("critical_speed at %.2f rpm: %s", speed * RPM_PER_RAD_S, st.note)
    side = {"stable": -1, "unstable": 1}.get(st.verdict, 0)
    ev = Evaluation(speed, float(st.spectral_radius), float(st.error or 0.0), side, int(st.elements))
    log.info("critical_speed: %.2f rpm: rho %.6g +- %.1e (%s, %d elements)", ev.rpm, ev.value, ev.error,
             st.verdict, ev.elements)
    return ev, res


def _lowest_frequency(sc: Scene, nodes: int) -> Evaluation:
    """Lowest signed natural frequency over the cycle (modal analysis on the rigid-body motion)."""
    f = float(cycle_frequencies(sc, 1, nodes)[:, 0].min())
    speed = abs(sc.mech.drives[0].speed)
    log.info("critical_speed: %.2f rpm: lowest frequency over the cycle %.6g Hz", speed * RPM_PER_RAD_S, f)
    return Evaluation(speed, f, 0.0, int(np.sign(-f)), 0)


def _g(kind: str, ev: Evaluation) -> float:
    """The function whose root is sought, positive on the unstable (buckled) side: ``log rho``, or
    ``-lambda_1 / (2 pi)^2`` [Hz^2]."""
    if kind == "parametric":
        return LOG_RHO_MAX if not math.isfinite(ev.value) else math.log(max(ev.value, 1e-300))
    return math.copysign(ev.value * ev.value, -ev.value)


def _number(name: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v) \
            or v <= 0:
        raise InputError(f"critical_speed: {name} must be a finite speed > 0 [rad/s], got {v!r}")
    return float(v)


def _secant(xa, ga, xb, gb) -> float:
    """Root of the line through ``(xa, ga)``, ``(xb, gb)`` (the midpoint if it is not finite)."""
    if not (math.isfinite(ga) and math.isfinite(gb)) or ga == gb:
        return 0.5 * (xa + xb)
    return xa - ga * (xb - xa) / (gb - ga)


def itp_root(f, a: float, b: float, fa: float, fb: float, width: float, more=lambda: True, k1: float = 0.2,
             n0: int = 1) -> tuple[float, float]:
    """Bracket ``[a, b]`` of a root of ``f`` narrowed to ``width`` by the ITP method.

    Interpolate (regula falsi), Truncate (toward the midpoint by ``k1 (b - a)^2 /
    (b0 - a0)``), Project (into the interval that keeps the worst case within
    ``n0`` steps of bisection): superlinear on smooth functions, never more than
    ``ceil(log2((b0 - a0) / width)) + n0`` evaluations on any (Oliveira &
    Takahashi 2020, ACM TOMS 47(1) 5). The onset of a parametric instability is
    such a function: ``log rho`` flat (the damping's decay) up to the tongue's
    boundary, then rising like a square root, where plain regula falsi creeps.

    Parameters
    ----------
    f : callable
        ``f(x) -> float``, negative at ``a``, positive at ``b``.
    a, b : float
        The bracket, ``a < b``.
    fa, fb : float
        ``f(a) < 0 < f(b)``.
    width : float
        Width to reach.
    more : callable
        ``more() -> bool``: may ``f`` be evaluated again (a budget)?
    k1, n0 : float, int
        Truncation factor (relative to the first bracket) and slack over bisection.

    Returns
    -------
    (a, b) : tuple of float
        The final bracket (wider than ``width`` if the budget ran out).
    """
    a0, b0 = a, b
    eps = 0.5 * width
    n_max = max(0, math.ceil(math.log2((b - a) / width))) + n0
    j = 0
    while b - a > width and more():
        mid = 0.5 * (a + b)
        r = eps * 2.0 ** (n_max - j) - 0.5 * (b - a)
        delta = k1 * (b - a) ** 2 / (b0 - a0)
        xf = _secant(a, fa, b, fb)
        sigma = math.copysign(1.0, mid - xf)
        xt = xf + sigma * delta if delta <= abs(mid - xf) else mid
        x = xt if abs(xt - mid) <= r else mid - sigma * r
        y = f(x)
        j += 1
        if y > 0:
            b, fb = x, y
        elif y < 0:
            a, fa = x, y
        else:
            return x, x
    return a, b


def critical_speed(scene, lo: float, hi: float, *, rtol: float = 5e-3, kind: str = "parametric",
                   linear: bool = False, scan: int = 0, max_solves: int = 14, nodes: int = 72,
                   trust=None, progress: bool | None = None) -> CriticalSpeed:
    """Speed at which a linkage becomes parametrically unstable (or buckles), to a relative tolerance.

    Parameters
    ----------
    scene : Scene, mapping, Mechanism or callable
        The scene (its speed is replaced at each evaluation), a scene dictionary
        in the TOML layout (``{"mechanism": {"name": "four_bar"}}``), a mechanism
        (linear effects, 2 % modal damping), or a builder ``f(speed [rad/s]) ->
        Scene | Mechanism``.
    lo, hi : float
        Bracket [rad/s], ``0 < lo < hi``, with ``lo`` and ``hi`` on either side
        of the critical speed.
    rtol : float
        Relative tolerance on the speed, in (0, 0.5): the search stops when the
        bracket is narrower than ``rtol * speed``.
    kind : {"parametric", "buckling"}
        The spectral radius crossing 1, or the lowest modal eigenvalue over the
        cycle crossing 0.
    linear : bool
        Ask it of the linearised equations: ``geometric_nonlinearity`` replaced
        by ``axial_stiffening`` (module docstring). Default False: the scene's
        own effects (the stability of the non-linear orbit). The buckling
        question is always linear.
    scan : int
        Bracketing: evaluate up to ``scan`` speeds evenly spaced in ``log(speed)``
        inside ``(lo, hi)``, upward, and refine between the last one on ``lo``'s side
        and the first one past it (``hi`` is then not solved). ``rho`` may cross 1
        several times (instability tongues with stable speeds between them): the
        refinement finds *a* crossing of its bracket, so to get the lowest one the
        scan's step ``(hi / lo)^(1 / (scan + 1))`` must be finer than the tongues
        and the windows between them (a :func:`~kedfem.io.design_plots.stability_map`
        shows them).
    max_solves : int
        Most evaluations, the ends and the scan included.
    nodes : int
        Crank positions per cycle of the buckling kind's modal analysis.
    trust : kedfem.trust.Trust, bool or targets, optional
        Code a scene dictionary may name besides catalogue mechanisms (:mod:`kedfem.trust`).
    progress : bool, optional
        A progress bar on stderr, one step per evaluation, with the speed and the value
        (default: on a terminal, after 2 s).

    Returns
    -------
    CriticalSpeed
        ``met`` False when ``max_solves`` ran out first (the bracket is still right).

    Raises
    ------
    InputError
        ``lo >= hi``, a bad tolerance or kind, an undamped scene (parametric:
        its multipliers lie on the unit circle), or no sign change in the bracket
        (the message gives the spectral radius or frequency at both ends).
    KedError
        A solve fails, or its non-linear iteration does not converge.
    """
    choice("critical_speed", "kind", kind, KINDS)
    linear = flag("critical_speed", "linear", linear)
    lo, hi = _number("lo", lo), _number("hi", hi)
    if lo >= hi:
        raise InputError(f"critical_speed: lo must be < hi, got lo = {lo:.6g} rad/s ({lo * RPM_PER_RAD_S:.6g} rpm) and "
                         f"hi = {hi:.6g} rad/s ({hi * RPM_PER_RAD_S:.6g} rpm)")
    if isinstance(rtol, bool) or not isinstance(rtol, (int, float, np.floating)) or not 0 < rtol < 0.5:
        raise InputError(f"critical_speed: rtol must be a number in (0, 0.5), got {rtol!r}")
    scan = _int("critical_speed", "scan", scan, 0)
    max_solves = _int("critical_speed", "max_solves", max_solves, 3)
    if scan + 3 > max_solves:
        raise InputError(f"critical_speed: scan = {scan} speeds and the two ends leave no solve of max_solves = "
                         f"{max_solves} for the refinement (give max_solves >= scan + 3)")
    nodes = _int("critical_speed", "nodes", nodes, 3)
    if isinstance(scene, Mapping):
        scene = hook("scene_from_dict")(scene, trust=trust)
    base = scene_at(scene, lo, owner="critical_speed")
    effects = linear_effects(base.effects) if (linear or kind == "buckling") else base.effects
    if kind == "parametric":
        from .pipeline import undamped
        if undamped(base):
            raise InputError("critical_speed: the scene is undamped: its Floquet multipliers lie on the unit circle "
                             "up to a parametric resonance, so rho = 1 marks no onset; give it damping "
                             "(kf.ModalDamping(0.02)) or use kind='buckling'")
    evals: list[Evaluation] = []
    solved: dict = {}  # speed -> result: the nearest one starts a non-linear solve

    def nearest(speed: float):
        if not solved:
            return None
        return solved[min(solved, key=lambda s: abs(math.log(s / speed)))]

    def evaluate(speed: float) -> Evaluation:
        sc = scene_at(scene, speed, effects=effects, owner="critical_speed")
        if kind == "buckling":
            ev = _lowest_frequency(sc, nodes)
        else:
            ev, res = _solve_rho(sc, nearest(speed))
            if res is not None:
                solved[speed] = res
            if ev.side == 0 and len(evals) + 1 < max_solves:  # within its error of 1: solve tighter
                evals.append(ev)
                ev, _res = _solve_rho(dataclasses.replace(sc, rtol=sc.rtol / 10), nearest(speed))
                if ev.side == 0:
                    log.warning("critical_speed at %.2f rpm: rho %.6g +- %.1e stays within its error of 1; its "
                                "side is taken from rho", ev.rpm, ev.value, ev.error)
        evals.append(ev)
        pbar.update(1)
        pbar.set_postfix_str(f"{ev.rpm:.5g} rpm: {ev.value:.4g}", refresh=False)
        return ev

    def side(ev: Evaluation) -> int:
        return ev.side or (1 if _g(kind, ev) > 0 else -1)

    what = "spectral radius" if kind == "parametric" else "lowest natural frequency over the cycle [Hz]"

    def definite(ev: Evaluation, name: str) -> Evaluation:
        if ev.side == 0:
            raise InputError(f"critical_speed: the {what} at {name} = {ev.rpm:.6g} rpm is {ev.value:.6g} +- "
                             f"{ev.error:.1e}, within its error of the threshold: move {name} away from it")
        return ev

    with bar("critical speed", "solve" if kind == "parametric" else "speed", max_solves, progress) as pbar:
        res = _search(evaluate, definite, side, lo, hi, scan, kind, what, rtol, evals, max_solves, effects, base)
    buckled = [ev for ev in res.evaluations if ev.value < 0] if kind == "buckling" else []
    if buckled:  # the link that buckles, at the buckled speed nearest the critical one
        at = min(buckled, key=lambda ev: abs(ev.speed - res.speed)).speed
        sc = scene_at(scene, at, effects=effects, owner="critical_speed")
        res = dataclasses.replace(res, buckled=buckled_mode(sc.mech, sc.effects, nodes))
    (log.info if res.met else log.warning)("%s", res.describe())
    return res


def _search(evaluate, definite, side, lo, hi, scan, kind, what, rtol, evals, max_solves, effects, base):
    """The bracketing and the ITP refinement of :func:`critical_speed`."""
    a = first = definite(evaluate(lo), "lo")
    side_lo = first.side
    b = None
    # bracketing: the scanned speeds upward, up to the first one on the other side
    for x in np.geomspace(lo, hi, scan + 2)[1:-1]:
        ev = evaluate(float(x))
        if side(ev) != side_lo:
            b = ev
            break
        a = ev
    if b is None:
        b = definite(evaluate(hi), "hi")
    if b.side == side_lo:
        state = {("parametric", -1): "stable", ("parametric", 1): "unstable", ("buckling", -1): "not buckled",
                 ("buckling", 1): "buckled"}[(kind, side_lo)]
        scanned = f" and at the {scan} speeds scanned between them" if scan else ""
        raise InputError(f"critical_speed: no sign change in the bracket: {what} {first.value:.6g} +- "
                         f"{first.error:.1e} at lo = {first.rpm:.6g} rpm and {b.value:.6g} +- {b.error:.1e} at hi = "
                         f"{b.rpm:.6g} rpm, {state} at both ends{scanned}; widen the bracket (a scan, "
                         "kedfem.io.design_plots.stability_map, shows where the boundary lies)")
    lo, hi = a.speed, b.speed

    def g_of(u: float) -> float:
        nonlocal a, b
        ev = evaluate(math.exp(u))
        if side(ev) == side_lo:
            a = ev
        else:
            b = ev
        g = _g(kind, ev)
        return g if side_lo < 0 else -g

    sign = 1.0 if side_lo < 0 else -1.0
    ua, ub = itp_root(g_of, math.log(lo), math.log(hi), sign * _g(kind, a), sign * _g(kind, b),
                      math.log1p(rtol), lambda: len(evals) < max_solves)
    xa, xb = math.exp(ua), math.exp(ub)
    x_hat = math.exp(_secant(ua, _g(kind, a), ub, _g(kind, b)))
    speed = min(max(x_hat, xa), xb)
    met = bool(xb - xa <= rtol * speed)
    nonlinear = kind == "parametric" and dataclasses.replace(base, effects=effects).state_dependent
    res = CriticalSpeed(kind, speed, (xa, xb), len(evals), float(rtol), met, a.value, b.value,
                        "onset" if side_lo < 0 else "exit", tuple(evals), effects, base.name or base.mech.name,
                        nonlinear)
    return res
