"""Exceptions and warnings raised by kedfem.

Every error a user can trigger derives from :class:`KedError`, so that
``except kf.KedError`` catches all of them. Input errors also derive from
:class:`ValueError` so that generic callers see a familiar type.
"""

from __future__ import annotations


class KedError(Exception):
    """Base class of every error raised by kedfem."""


class InputError(KedError, ValueError):
    """Bad user input: the message names the argument, link, joint or key."""


class KinematicsError(KedError):
    """The linkage cannot be assembled or cannot complete its cycle."""


class MobilityError(KinematicsError):
    """The linkage's mobility does not match its drives."""


class ResonanceError(KedError):
    """``I - Phi`` is (numerically) singular: a Floquet multiplier sits at 1.

    Raised by the periodic solver for an undamped system forced at
    resonance, a free rigid-body mode, or a mechanism that is not fully
    constrained. Attributes ``multiplier`` (complex) and ``condition``
    (float, condition estimate of ``I - Phi``) describe the offending mode.
    """

    def __init__(self, message: str, multiplier: complex | None = None,
                 condition: float | None = None):
        super().__init__(message)
        self.multiplier = multiplier
        self.condition = condition


class UnboundedResponseError(KedError):
    """The response grows without bound: the one-cycle transition overflows floating point.

    The largest Floquet multiplier exceeds about 1e300 (a violent parametric
    instability, buckling, negative damping, or a diverging non-linear
    iterate). Attribute ``elements``: the time elements of the solve.
    """

    def __init__(self, message: str, elements: int | None = None):
        super().__init__(message)
        self.elements = elements


class NonlinearSolveError(KedError):
    """No periodic response of a non-linear scene was found: neither Newton's method from the linear
    response nor a continuation from a speed where it converges reached the scene.

    No result is returned (a diverged iterate is no answer). Attributes: ``highest`` (float or
    None), the highest parameter value [rad/s for speed] this attempt's continuation reached
    (the response may exist beyond it: :func:`kedfem.continuation` says where it ends);
    ``tried`` (str), what was tried.
    """

    def __init__(self, message: str, highest: float | None = None, tried: str = ""):
        super().__init__(message)
        self.highest = highest
        self.tried = tried


class SingularMassError(KedError):
    """The mass matrix is singular or indefinite (massless or negative-mass DOFs)."""


class InstabilityWarning(UserWarning):
    """A Floquet multiplier lies outside the unit circle (parametric instability)."""


class ConvergenceWarning(UserWarning):
    """A non-linear iteration stopped before meeting its tolerance."""


class OptionalDependencyError(KedError, ImportError):
    """An optional library needed for this output is not installed."""


class LengthWarning(UserWarning):
    """A link's joint coordinates give it another length than the one stated (``link(..., length=)``)."""


class PlausibilityWarning(UserWarning):
    """A result leaves the model's theory: deflections beyond small, stresses beyond yield."""


class EffectWarning(UserWarning):
    """The mechanism declares components whose effect the scene leaves out (so they do nothing)."""


class AccuracyWarning(UserWarning):
    """A result's estimated time-discretisation error exceeds the scene's tolerance."""


class CostWarning(UserWarning):
    """A modelling choice multiplies a solve's cost where another would not (a process load that
    steps, ringing modes far above the drive's harmonics)."""


def did_you_mean(word, choices) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``choices`` to ``word``, or ``""``."""
    import difflib
    m = difflib.get_close_matches(str(word), [str(c) for c in choices], n=1, cutoff=0.6)
    return f" (did you mean '{m[0]}'?)" if m else ""


def user_stacklevel() -> int:
    """``stacklevel`` for the ``warnings.warn`` call it is an argument of: the first frame outside
    kedfem, so that the warning names the user's line however deep in a solve it is raised (a new
    user's ``PlausibilityWarning`` pointed at ``kedfem/analysis/pipeline.py:485``)."""
    import os
    import sys
    pkg = os.path.dirname(os.path.abspath(__file__)) + os.sep
    frame, level = sys._getframe(1), 1  # the frame that calls warnings.warn
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(pkg):
        frame, level = frame.f_back, level + 1
    return level
