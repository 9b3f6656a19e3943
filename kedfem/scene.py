"""Scenes: which mechanism, at what speed, with which effects, solved how."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .effects import EFFECTS, ModalDamping, Rayleigh, check_effects
from .errors import InputError
from .mechanism import Mechanism

__all__ = ["Scene", "HOLDS", "NONLINEAR_METHODS", "ACCURACY_PRESETS"]

HOLDS = ("zoh", "foh", "magnus2")
NONLINEAR_METHODS = ("fixed-point", "relaxation", "anderson")

#: Knobs of ``Scene(accuracy=...)``: ``steps``, ``hold``, ``eps`` and ``delta``
#: (``None``: matched to the hold). Chosen from the accuracy-versus-cost study
#: (``benchmarks/accuracy_cost.py``, README "Accuracy versus cost"), which
#: measures what each preset delivers on the slider-crank, the four-bar and the
#: mould oscillator.
ACCURACY_PRESETS: dict[str, dict] = {
    "fast": dict(steps=90, hold="magnus2", eps=1e-4, delta=1e-8),
    "default": dict(steps=360, hold="magnus2", eps=1e-6, delta=None),
    "tight": dict(steps=1440, hold="magnus2", eps=1e-8, delta=None),
}
_KNOBS = ("steps", "hold", "eps", "delta")


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
        Number of time nodes (= time elements) over one cycle, >= 3 (default:
        from ``accuracy``).
    effects : sequence of str
        Effects to assemble (see :data:`kedfem.effects.EFFECTS`); nothing
        else is assembled, and the response is iterated only if one of them
        depends on the elastic state.
    damping : Rayleigh or ModalDamping, optional
        Damping model (``None``: undamped; an undamped system forced near a
        resonance raises :class:`~kedfem.errors.ResonanceError`).
    hold : {"zoh", "foh", "magnus2"}, optional
        Hold scheme of the state-space discretisation (default: from ``accuracy``).
    speed : float, optional
        Speed of the first drive [rad/s] (others keep their ratio); default
        the mechanism's own.
    eps : float, optional
        Tolerance of the non-linear iteration (the paper's Eq. 21, as a
        fraction; default: from ``accuracy``).
    max_iter : int
        Largest number of linear solves of the non-linear iteration.
    nonlinear_method : {"fixed-point", "relaxation", "anderson"}
        Iteration scheme (the paper's plain fixed point, under-relaxation, or
        Anderson acceleration).
    delta : float, optional
        Accuracy asked from each matrix exponential (default: from
        ``accuracy``; the presets' ``None`` matches it to the hold).
    reduction : CraigBampton, optional
        Craig-Bampton reduction of the flexible links (see :mod:`kedfem.reduction`).
    name : str
        Label used in reports.
    accuracy : {"fast", "default", "tight"}
        Preset of ``steps``, ``hold``, ``eps`` and ``delta`` (see
        :data:`ACCURACY_PRESETS`); a knob given explicitly wins over the
        preset. The resolved values are the scene's attributes, so
        ``dataclasses.replace(scene, accuracy=...)`` keeps them: use
        :meth:`with_accuracy` to switch presets.
    """

    mechanism: Mechanism
    steps: int | None = None
    effects: tuple[str, ...] = ("inertia", "coupling")
    damping: Rayleigh | ModalDamping | None = None
    hold: str | None = None
    speed: float | None = None
    eps: float | None = None
    max_iter: int = 50
    nonlinear_method: str = "fixed-point"
    delta: float | None = None
    reduction: object = None
    name: str = ""
    accuracy: str = "default"
    _mech: Mechanism = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        owner = "Scene"
        if self.accuracy not in ACCURACY_PRESETS:
            raise InputError(f"{owner}: accuracy must be one of {', '.join(ACCURACY_PRESETS)}, "
                             f"got {self.accuracy!r}")
        for k, v in ACCURACY_PRESETS[self.accuracy].items():
            if getattr(self, k) is None:
                object.__setattr__(self, k, v)
        if not isinstance(self.mechanism, Mechanism):
            raise InputError(f"{owner}: mechanism must be a kedfem.Mechanism, got {type(self.mechanism).__name__}")
        _int(owner, "steps", self.steps, 3)
        object.__setattr__(self, "effects", check_effects(self.effects))
        if self.damping is not None and not isinstance(self.damping, (Rayleigh, ModalDamping)):
            raise InputError(f"{owner}: damping must be kf.Rayleigh(...), kf.ModalDamping(...) or None, "
                             f"got {self.damping!r}")
        if self.hold not in HOLDS:
            raise InputError(f"{owner}: hold must be one of {', '.join(HOLDS)}, got {self.hold!r}")
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
        from .reduction import CraigBampton
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
        object.__setattr__(self, "_mech", mech)

    def with_accuracy(self, accuracy: str) -> "Scene":
        """The same scene with the ``steps``, ``hold``, ``eps`` and ``delta`` of another preset."""
        import dataclasses
        return dataclasses.replace(self, accuracy=accuracy, **{k: None for k in _KNOBS})

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
        return any(EFFECTS[e].state_dependent(self._mech) for e in self.effects)
