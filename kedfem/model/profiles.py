"""Process loads: how a declared load varies over the cycle.

A :class:`Profile` is a table of a dimensionless factor against one quantity of the rigid-body
motion; the load's force vector (``Mechanism.load(..., profile=...)``) is multiplied by it at
every instant. The quantity is

``"crank_angle"``
    the angle the first drive has turned from the drawn configuration [deg], ``0 .. 360``, in
    its own sense of rotation (``|omega| t``); the table is periodic (linear from its last
    entry to its first plus 360 deg);
``"position"``
    a joint's coordinate along a unit ``axis`` [m]: its position vector (from the drawing's
    origin) projected on the axis; outside the table the end values hold;
``"velocity"``
    the joint's velocity along the axis [m/s]; outside the table the end values hold.

Between entries the factor is linear, or with ``smooth=True`` an S-curve (the quintic
``6u^5 - 15u^4 + 10u^3`` of the fraction ``u`` of the segment: zero slope and curvature at every
entry, so the factor has no kinks); an abscissa given twice is a step (the factor jumps there,
as a press's force when the tool meets the part). ``stroke`` limits a position table
to the joint moving along ``+axis`` (``"forward"``) or ``-axis`` (``"return"``): the factor
is zero on the other stroke, so it steps at the dead centres where it is not zero.

Steps and kinks are not smoothed: the instants where the motion reaches them are found
(:func:`kedfem.motion.profiles.breaks`) and the solve puts time-element ends there, so every
element sees smooth data and the scheme keeps its order (docs/loads.md). A kink or a step still
rings the machine's modes, far above the drive's harmonics, and the solve resolves every mode
the load's harmonics reach (:meth:`kedfem.analysis.pipeline` ``resolution``): a linear table
costs thousands of time elements where ``smooth=True`` costs tens.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..checks import direction
from ..errors import InputError

__all__ = ["Profile", "PROFILE_QUANTITIES", "STROKES", "MAX_TABLE"]

PROFILE_QUANTITIES = ("crank_angle", "position", "velocity")
STROKES = ("both", "forward", "return")
#: Most entries in a profile's table
MAX_TABLE = 10_000


@dataclass(frozen=True)
class Profile:
    """A load's factor [-] over the cycle from a table (see the module docstring).

    Build it with :meth:`crank_angle`, :meth:`position` or :meth:`velocity`.

    Attributes
    ----------
    of : {"crank_angle", "position", "velocity"}
    x : tuple of float
        Abscissae, non-decreasing; each at most twice (a step) [deg, m or m/s].
    y : tuple of float
        Factors [-] (the load's force is multiplied by them).
    joint : str or None
        The joint whose position or velocity is read.
    axis : (float, float) or None
        Unit direction of the position or velocity read.
    stroke : {"both", "forward", "return"}
    smooth : bool
        S-curves between the entries instead of straight lines (no kinks).
    """

    of: str
    x: tuple[float, ...]
    y: tuple[float, ...]
    joint: str | None = None
    axis: tuple[float, float] | None = None
    stroke: str = "both"
    smooth: bool = False

    def __post_init__(self):
        what = "load profile"
        if self.of not in PROFILE_QUANTITIES:
            raise InputError(f"{what}: 'of' must be one of {', '.join(PROFILE_QUANTITIES)}, got {self.of!r}")
        x, y = _table(what, self.x, self.y)
        if self.of == "crank_angle":
            if x[0] < 0.0 or x[-1] > 360.0:
                raise InputError(f"{what}: crank angles must lie in 0 .. 360 deg, got {x[0]:g} .. {x[-1]:g}")
            if x[-1] <= 2.0 * math.pi * (1.0 + 1e-9) and x[-1] - x[0] > 0.5:
                warnings.warn(f"{what}: the crank angles {x[0]:g} .. {x[-1]:g} are in degrees and all lie "
                              "within 2 pi: were they meant as radians? (np.degrees converts them)",
                              UserWarning, stacklevel=4)
            if self.joint is not None or self.axis is not None:
                raise InputError(f"{what}: a crank-angle table reads no joint or axis")
        else:
            if not isinstance(self.joint, str) or not self.joint:
                raise InputError(f"{what}: a {self.of} table needs the joint whose {self.of} it reads")
            if self.axis is None:
                raise InputError(f"{what}: a {self.of} table needs the axis along which joint "
                                 f"'{self.joint}' is read")
            object.__setattr__(self, "axis", direction(what, "axis", self.axis))
        if self.stroke not in STROKES:
            raise InputError(f"{what}: stroke must be one of {', '.join(STROKES)}, got {self.stroke!r}")
        if not isinstance(self.smooth, (bool, np.bool_)):
            raise InputError(f"{what}: smooth must be True or False, got {self.smooth!r}")
        object.__setattr__(self, "smooth", bool(self.smooth))
        if self.stroke != "both" and self.of != "position":
            raise InputError(f"{what}: stroke= limits a position table to one stroke; a {self.of} table "
                             "has the direction in itself")
        object.__setattr__(self, "x", tuple(float(v) for v in x))
        object.__setattr__(self, "y", tuple(float(v) for v in y))

    # ------------------------------------------------------------------ builders
    @classmethod
    def crank_angle(cls, degrees, factors, smooth: bool = False) -> "Profile":
        """Factor against the angle the drive has turned from the drawing [deg], periodic.

        The table's 0 is the crank as drawn, not the absolute crank angle that results,
        :func:`kedfem.static_response` and ``Stroke`` use (a crank drawn at 90 deg from +x reaches
        the table's 100 deg at an absolute 190 deg).

        Parameters
        ----------
        degrees : array_like, shape (k,)
            Non-decreasing, within ``0 .. 360``.
        factors : array_like, shape (k,)
        smooth : bool
            S-curves between the entries (no kinks).
        """
        return cls("crank_angle", tuple(np.ravel(degrees)), tuple(np.ravel(factors)), smooth=smooth)

    @classmethod
    def position(cls, joint: str, axis, positions, factors, stroke: str = "both",
                 smooth: bool = False) -> "Profile":
        """Factor against joint ``joint``'s coordinate along ``axis`` [m].

        Parameters
        ----------
        joint : str
        axis : (float, float)
            Direction (normalised here).
        positions : array_like, shape (k,)
            Coordinates ``r . axis`` [m], non-decreasing (one given twice: a step).
        factors : array_like, shape (k,)
        stroke : {"both", "forward", "return"}
            Only while the joint moves along ``+axis`` / ``-axis`` (zero on the other stroke).
        smooth : bool
            S-curves between the entries (no kinks).
        """
        return cls("position", tuple(np.ravel(positions)), tuple(np.ravel(factors)), joint,
                   tuple(np.ravel(axis)) if axis is not None else None, stroke, smooth)

    @classmethod
    def velocity(cls, joint: str, axis, speeds, factors, smooth: bool = False) -> "Profile":
        """Factor against joint ``joint``'s velocity along ``axis`` [m/s].

        Parameters
        ----------
        joint : str
        axis : (float, float)
        speeds : array_like, shape (k,)
            Velocities ``v . axis`` [m/s], non-decreasing.
        factors : array_like, shape (k,)
        smooth : bool
            S-curves between the entries (no kinks).
        """
        return cls("velocity", tuple(np.ravel(speeds)), tuple(np.ravel(factors)), joint,
                   tuple(np.ravel(axis)) if axis is not None else None, smooth=smooth)

    # ------------------------------------------------------------------ reading
    def table(self, q: np.ndarray) -> np.ndarray:
        """The table's factor (k,) at values ``q`` (k,) of its quantity (before ``stroke``).

        A step's abscissa takes the factor after it (in increasing ``q``).
        """
        x, y = np.asarray(self.x), np.asarray(self.y)
        q = np.asarray(q, dtype=float)
        if self.of == "crank_angle":
            x = np.concatenate([x - 360.0, x, x + 360.0])
            y = np.tile(y, 3)
            q = np.mod(q, 360.0)
        # np.interp takes the last of equal abscissae on the right of a step: the factor after it
        out = np.interp(q, x, y)
        if self.smooth:  # the same segment, along an S-curve of its fraction
            k = np.clip(np.searchsorted(x, q, side="right") - 1, 0, x.size - 2)
            w = x[k + 1] - x[k]
            with np.errstate(divide="ignore", invalid="ignore"):
                u = np.clip(np.where(w > 0, (q - x[k]) / w, 1.0), 0.0, 1.0)
            out = y[k] + (y[k + 1] - y[k]) * (u**3 * (10.0 - 15.0 * u + 6.0 * u * u))
        steps = np.flatnonzero(np.diff(x) == 0.0)
        for i in steps:
            out = np.where(q == x[i], y[i + 1], out)
        return out

    @property
    def levels(self) -> np.ndarray:
        """Abscissae where the factor kinks or steps (k,) [deg, m or m/s]: every table entry whose
        neighbouring slopes differ (the ends too, where the end value holds beyond them); with
        ``smooth`` the steps only."""
        x, y = np.asarray(self.x), np.asarray(self.y)
        if self.smooth:
            i = np.flatnonzero((np.diff(x) == 0.0) & (np.diff(y) != 0.0))
            out = np.unique(x[i])
            return np.mod(out, 360.0) if self.of == "crank_angle" else out
        if self.of == "crank_angle":
            xs = np.concatenate([x[-1:] - 360.0, x, x[:1] + 360.0])
            ys = np.concatenate([y[-1:], y, y[:1]])
        else:
            xs = np.concatenate([[x[0] - 1.0], x, [x[-1] + 1.0]])
            ys = np.concatenate([[y[0]], y, [y[-1]]])
        out = []
        for i in range(1, xs.size - 1):
            left = _slope(xs[i - 1], xs[i], ys[i - 1], ys[i])
            right = _slope(xs[i], xs[i + 1], ys[i], ys[i + 1])
            if left != right:
                out.append(xs[i])
        out = np.unique(np.asarray(out, dtype=float))
        return np.mod(out, 360.0) if self.of == "crank_angle" else out


def _slope(x0, x1, y0, y1):
    """A segment's slope, ``inf``-signed for a step (equal abscissae, different factors)."""
    if x1 == x0:
        return math.copysign(math.inf, y1 - y0) if y1 != y0 else 0.0
    return (y1 - y0) / (x1 - x0)


def _table(what, x, y):
    try:
        x = np.asarray(x, dtype=float).ravel()
        y = np.asarray(y, dtype=float).ravel()
    except (TypeError, ValueError):
        raise InputError(f"{what}: the table's abscissae and factors must be numbers") from None
    if x.size != y.size or x.size < 2:
        raise InputError(f"{what}: the table needs as many factors as abscissae, at least two "
                         f"(got {x.size} and {y.size})")
    if x.size > MAX_TABLE:
        raise InputError(f"{what}: at most {MAX_TABLE} table entries, got {x.size}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise InputError(f"{what}: the table has a value that is not finite")
    d = np.diff(x)
    if np.any(d < 0):
        i = int(np.flatnonzero(d < 0)[0])
        raise InputError(f"{what}: abscissae must not decrease (entry {i + 1}: {x[i + 1]:g} after {x[i]:g})")
    if np.any((d[:-1] == 0) & (d[1:] == 0)):
        raise InputError(f"{what}: an abscissa is given three times (a step needs it twice)")
    return x, y
