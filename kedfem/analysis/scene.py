"""Scenes: which mechanism, at what speed, with which effects, solved how."""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field, fields

import numpy as np

from ..fe.effects import DEFAULT_ZETA, ModalDamping, Rayleigh, check_effects, chosen, default_effects
from ..checks import choice, flag
from ..errors import InputError
from ..model.mechanism import Mechanism

__all__ = ["Scene", "HOLDS", "NONLINEAR_METHODS", "ACCURACY_PRESETS", "MAX_STEPS"]

from ..solvers.nonlinear import NONLINEAR_METHODS  # noqa: E402  (one definition each, re-exported here)
from ..solvers.periodic import HOLDS  # noqa: E402
#: Largest number of time elements per cycle a scene may ask for (or a
#: tolerance-driven solve may reach): the cost grows linearly with it, and
#: every shipped mechanism converges to 1e-5 far below it.
MAX_STEPS = 20_000
#: Cycle periods a scene accepts [s]: beyond them the time discretisation's products of
#: stiffness and squared element length leave floating point (speeds of 6e-9 to 6e9 rad/s)
PERIOD_RANGE = (1e-9, 1e9)

#: Knobs of ``Scene(accuracy=...)``: the tolerance ``rtol`` on the peaks, the
#: non-linear tolerance ``eps`` and the exponentials' ``delta`` (``None``:
#: matched to the hold). The solve refines its time elements until the error
#: estimate of every link's peak deflection and stress meets ``rtol``
#: (README "Accuracy versus cost" shows what each costs).
ACCURACY_PRESETS: dict[str, dict] = {
    "fast": dict(rtol=1e-2, eps=1e-4, delta=1e-8),
    "default": dict(rtol=1e-3, eps=1e-6, delta=None),
    "tight": dict(rtol=1e-5, eps=1e-8, delta=None),
}
_KNOBS = ("rtol", "eps", "delta")


def _int(owner, name, v, lo):
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
        raise InputError(f"{owner}: {name} must be an integer >= {lo}, got {v!r}")
    return int(v)


@dataclass(frozen=True)
class Scene:
    """A KED analysis: a mechanism, its speed, the effects to simulate and the solver knobs.

    Parameters
    ----------
    mechanism : Mechanism
        A driven mechanism.
    steps : int, optional
        Number of time elements over one cycle, >= 3 (for experts). Default:
        chosen by the solve, doubling from a coarse start until the error
        estimate of every flexible link's peak deflection and stress meets
        ``rtol``.
    effects : sequence of str, optional
        Effects to assemble (see :data:`kedfem.fe.effects.EFFECTS`); nothing
        else is assembled, and the response is iterated only if one of them
        depends on the elastic state. Default: the linear KED set (inertia,
        coupling, axial_stiffening) and the effects of what the mechanism
        declares (its springs, loads and friction, a gravity set with
        ``set_gravity``; :func:`kedfem.fe.effects.default_effects`), as the
        command line's for a builder file. A declared item the effects leave
        out is named in one :class:`~kedfem.errors.EffectWarning` per item.
    damping : Rayleigh or ModalDamping or None
        Damping model; default 2 % modal damping (as the command line's);
        ``None``: undamped (an undamped system forced near a resonance raises
        :class:`~kedfem.errors.ResonanceError`).
    hold : {"zoh", "foh", "magnus2"}, optional
        Shorthand for ``method=hold``: one of the paper's exponential holds.
    speed : float, optional
        Speed of the first drive [rad/s] (others keep their ratio); default
        the mechanism's own.
    eps : float, optional
        Tolerance of the non-linear iteration (the paper's Eq. 21, as a
        fraction; default: from ``accuracy``). Newton also stops on a last
        change above it whose successor the rate of a coarser level predicts
        below ``eps / 10`` (:func:`kedfem.solvers.nonlinear.newton`; the
        result's ``predicted_change``).
    max_iter : int
        Largest number of linear solves of the non-linear iteration.
    nonlinear_method : {"newton", "fixed-point", "relaxation", "anderson"}
        Iteration for the state-dependent effects. ``"newton"`` (default): Newton's method with a
        line search on the periodic problem (the effects' terms are the consistent tangent), and
        when it does not converge from the linear response, continuation in speed from a speed
        where it does (:func:`kedfem.solve`); ``"fixed-point"``: the paper's plain iteration
        (falling back to Anderson acceleration when it diverges); ``"relaxation"``,
        ``"anderson"``.
    delta : float, optional
        Accuracy asked from each matrix exponential (default: from
        ``accuracy``; the presets' ``None`` matches it to the hold).
    reduction : CraigBampton, optional
        Craig-Bampton reduction of the flexible links (see :mod:`kedfem.fe.reduction`).
    name : str
        Label used in reports.
    accuracy : {"fast", "default", "tight"}
        Preset of ``rtol`` (1e-2, 1e-3, 1e-5), ``eps`` and ``delta`` (see
        :data:`ACCURACY_PRESETS`); a knob given explicitly wins over the
        preset. The resolved values are the scene's attributes, so
        ``dataclasses.replace(scene, accuracy=...)`` keeps them: use
        :meth:`with_accuracy` to switch presets.
    method : str
        Time discretisation (:data:`kedfem.solvers.schemes.SCHEMES`): ``"auto"``
        (Radau IIA collocation, 3 stages), ``"radau3"``, ``"radau2"``,
        ``"gauss3"``, ``"gauss2"``, or the paper's exponential holds
        ``"magnus2"``, ``"foh"``, ``"zoh"`` (for experts).
    rtol : float, optional
        Relative tolerance on every flexible link's peak deflection and peak
        stress (default: from ``accuracy``, 1e-3). With ``steps`` given it is
        only checked: a :class:`~kedfem.errors.AccuracyWarning` says when
        the estimate exceeds it.
    estimate : bool
        Estimate the time-discretisation error (``res.error``). With
        ``steps`` given this costs two coarser solves (about 0.75 of the
        solve); a tolerance-driven solve gets it from its refinement.
    stiff_split : bool
        Exponential holds only: carry the DOFs along which a link's axial
        stiffness acts as static response plus deviation (:mod:`kedfem.solvers.split`,
        an exact change of variables); False is the paper's method literally.
    """

    mechanism: Mechanism
    steps: int | None = None
    effects: tuple[str, ...] | None = None
    damping: Rayleigh | ModalDamping | None = field(default_factory=lambda: ModalDamping(DEFAULT_ZETA))
    hold: str | None = None
    speed: float | None = None
    eps: float | None = None
    max_iter: int = 50
    nonlinear_method: str = "newton"
    delta: float | None = None
    reduction: object = None
    name: str = ""
    accuracy: str = "default"
    method: str = "auto"
    rtol: float | None = None
    estimate: bool = True
    stiff_split: bool = True
    _mech: Mechanism = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        owner = "Scene"
        choice(owner, "accuracy", self.accuracy, tuple(ACCURACY_PRESETS))
        choice(owner, "nonlinear_method", self.nonlinear_method, NONLINEAR_METHODS)
        if not isinstance(self.name, str):
            raise InputError(f"{owner}: name must be a string, got {type(self.name).__name__} {self.name!r:.60}")
        if self.hold is not None:
            choice(owner, "hold", self.hold, HOLDS)
        for k in ("estimate", "stiff_split"):
            flag(owner, k, getattr(self, k))
        for k, v in ACCURACY_PRESETS[self.accuracy].items():
            if getattr(self, k) is None:
                object.__setattr__(self, k, v)
        if not isinstance(self.mechanism, Mechanism):
            raise InputError(f"{owner}: mechanism must be a kedfem.Mechanism, got {type(self.mechanism).__name__}")
        if self.steps is not None:
            _int(owner, "steps", self.steps, 3)
            if self.steps > MAX_STEPS:
                raise InputError(f"{owner}: steps must be at most {MAX_STEPS} time elements, got "
                                 f"{self.steps} (the cost grows linearly with it; a tolerance rtol "
                                 f"picks the number of elements a result needs)")
        from ..solvers import schemes
        if not isinstance(self.method, str) or self.method not in schemes.names():
            raise InputError(f"{owner}: method must be one of {', '.join(schemes.names())}, "
                             f"got {self.method!r}")
        rt = self.rtol
        if isinstance(rt, bool) or not isinstance(rt, (int, float, np.floating)) or not (0 < rt < 1):
            raise InputError(f"{owner}: rtol must be a number in (0, 1), got {rt!r}")
        if not isinstance(self.estimate, (bool, np.bool_)):
            raise InputError(f"{owner}: estimate must be True or False, got {self.estimate!r}")
        if self.effects is None:
            object.__setattr__(self, "effects", default_effects(self.mechanism))
        object.__setattr__(self, "effects", check_effects(self.effects))
        if self.damping is not None and not isinstance(self.damping, (Rayleigh, ModalDamping)):
            raise InputError(f"{owner}: damping must be kf.Rayleigh(...), kf.ModalDamping(...) or None, "
                             f"got {self.damping!r}")
        if self.hold is not None:
            if self.hold not in HOLDS:
                raise InputError(f"{owner}: hold must be one of {', '.join(HOLDS)}, got {self.hold!r}")
            if self.method not in ("auto", self.hold):
                raise InputError(f"{owner}: hold={self.hold!r} is one of the exponential methods; it "
                                 f"contradicts method={self.method!r} (give one of them)")
        if self.nonlinear_method not in NONLINEAR_METHODS:
            raise InputError(f"{owner}: nonlinear_method must be one of {', '.join(NONLINEAR_METHODS)}, "
                             f"got {self.nonlinear_method!r}")
        eps = self.eps
        if isinstance(eps, bool) or not isinstance(eps, (int, float, np.floating)) or not (0 < eps < 1):
            raise InputError(f"{owner}: eps must be a number in (0, 1), got {eps!r}")
        _int(owner, "max_iter", self.max_iter, 1)
        if self.delta is not None and not (isinstance(self.delta, (int, float, np.floating))
                                           and 0 < self.delta < 1):
            raise InputError(f"{owner}: delta must be a number in (0, 1), got {self.delta!r}")
        from ..fe.reduction import CraigBampton
        if self.reduction is not None and not isinstance(self.reduction, CraigBampton):
            raise InputError(f"{owner}: reduction must be kf.CraigBampton(...) or None, got {self.reduction!r}")
        if not self.mechanism.drives:
            raise InputError(f"{owner}: mechanism '{self.mechanism.name}' has no drive; a periodic "
                             "response needs a cycle (use kf.static_response or kf.natural_frequencies "
                             "for a structure)")
        if self.speed is not None:
            sp = self.speed
            if isinstance(sp, bool) or not isinstance(sp, (int, float, np.floating)) or not math.isfinite(sp):
                raise InputError(f"{owner}: speed must be a finite number [rad/s], got {sp!r}")
            if sp == 0.0:
                raise InputError(f"{owner}: speed is zero: a periodic response needs a cycle")
            mech = self.mechanism.with_speed(float(sp))
        else:
            if self.mechanism.drives[0].speed == 0.0:
                raise InputError(f"{owner}: the drive speed of '{self.mechanism.name}' is zero: "
                                 "a periodic response needs a cycle")
            mech = self.mechanism
        T = mech.period
        if not (PERIOD_RANGE[0] <= T <= PERIOD_RANGE[1]):
            raise InputError(f"{owner}: the drive's cycle lasts {T:.3g} s (speed {mech.drives[0].speed:.3g} "
                             f"rad/s), outside [{PERIOD_RANGE[0]:g}, {PERIOD_RANGE[1]:g}] s: check the "
                             "speed's units (rad/s in Python, rev/min in scene files); " +
                             ("a linkage this slow is quasi-static (kf.static_response)" if T > PERIOD_RANGE[1]
                              else "no linkage turns this fast"))
        object.__setattr__(self, "_mech", mech)

    def __repr__(self) -> str:
        # one line: the mechanism by name (its own repr is every joint and link, 2.6 kB for the
        # four-bar, which print(scene) dumped) and the knobs that differ from their defaults
        knobs = [f"{k}={getattr(self, k)!r}" for k, default in _SCENE_DEFAULTS.items() if getattr(self, k) != default]
        return (f"Scene({self.mechanism.name!r}, effects={self.effects!r}, damping={self.damping!r}, "
                f"rtol={self.rtol:g}, eps={self.eps:g}{''.join(', ' + k for k in knobs)})")

    def with_accuracy(self, accuracy: str) -> "Scene":
        """The same scene with the ``rtol``, ``eps`` and ``delta`` of another preset."""
        import dataclasses
        return dataclasses.replace(self, accuracy=accuracy, **{k: None for k in _KNOBS})

    @property
    def scheme(self) -> str:
        """The time discretisation the solve uses (``method`` with ``"auto"`` and ``hold`` resolved)."""
        from ..solvers import schemes
        if self.hold is not None:
            return self.hold
        return schemes.get(self.method).name

    @property
    def mech(self) -> Mechanism:
        """The mechanism at the scene's speed."""
        return self._mech

    @property
    def period(self) -> float:
        """Cycle period [s]."""
        return self._mech.period

    @property
    def state_dependent(self) -> bool:
        """True if a chosen effect depends on the elastic state (the solve iterates)."""
        return any(e.state_dependent(self._mech) for e in chosen(self.effects))


#: the knobs a scene's repr shows where they differ from these defaults (the effects and tolerances it always
#: shows, resolved)
_SCENE_DEFAULTS = {f.name: f.default for f in fields(Scene)
                   if f.default is not MISSING and f.name not in ("effects", "rtol", "eps", "delta", "accuracy")}
