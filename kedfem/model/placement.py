"""Joint positions from link lengths: the circle intersections of assembling a linkage.

A linkage is usually specified by its link lengths, a crank angle and an
assembly branch; a :class:`~kedfem.model.mechanism.Mechanism` wants joint
coordinates. The functions here compute them (pure geometry, SI units,
angles in radians counter-clockwise from +x); :class:`Mechanism` wraps them as
``m.at_angle``, ``m.at_lengths`` and ``m.at_length_on_line``, which name
joints instead of points::

    m.ground("O2", at=(0.0, 0.0))
    m.ground("O4", at=m.at_angle("O2", 0.254, 0.0))
    m.joint("A", at=m.at_angle("O2", 0.108, crank_angle))
    m.joint("B", at=m.at_lengths(("A", 0.2794, "coupler"), ("O4", 0.2705, "rocker"), branch="open"))

Branches
--------
The two circles about ``P`` (radius ``a``) and ``Q`` (radius ``b``) meet in
two points, mirror images about the line ``P Q``:

* ``"left"`` / ``"right"``: the point on the left / right of the directed
  line from ``P`` to ``Q`` (left: counter-clockwise from ``P -> Q``).
* ``"open"`` / ``"crossed"``: the two circuits of a four-bar in Norton's
  closed-form solution (R. L. Norton, Design of Machinery, section 4.5), for
  a dyad that closes on a ground pivot: one of ``P``, ``Q`` is a ground joint
  (the output rocker's pivot ``O4``), the other the moving joint ``A`` at the
  end of the input crank. ``"open"`` is the point on the left of the
  directed line ``A -> O4``, ``"crossed"`` on the right, whatever the order
  in which ``P`` and ``Q`` are given. This is Norton's convention in his
  frame (x from the input pivot to the output pivot, angles
  counter-clockwise), which rotating the frame does not change; a circuit
  is kept over the whole cycle of a crank-rocker, so ``"open"`` names the
  assembly mode, not "the links do not overlap at this angle" (for crank
  angles between 180 and 360 deg the open circuit's coupler crosses the
  ground line). A mirror-image drawing of a linkage is the other circuit.

On a slider's line (``at_length_on_line``) the two points lie along the
axis: ``"open"`` (alias ``"ahead"``) is the one further along ``axis``, as in
Norton's slider-crank (section 4.6: ``theta_3 = asin((a sin theta_2 - c) / b)``
with the slider ahead of the crank pin), ``"crossed"`` (``"behind"``) the other.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError, LengthWarning
from ..checks import real
from .materials import MAX_LENGTH

__all__ = ["BRANCHES", "LINE_BRANCHES", "at_angle", "circle_intersection",
           "line_intersection"]

#: Branches of :func:`circle_intersection`.
BRANCHES = ("open", "crossed", "left", "right")
#: Branches of :func:`line_intersection`.
LINE_BRANCHES = ("open", "crossed", "ahead", "behind")
#: Relative slack in the reach tests: a tangent pair of circles (a toggle) still assembles
_SLACK = 1e-12


def _point(owner: str, name: str, value) -> np.ndarray:
    try:
        p = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        p = np.zeros(0)
    if p.shape != (2,) or not np.all(np.isfinite(p)):
        raise InputError(f"{owner}: {name} must be two finite numbers (x, y) [m], got {value!r}")
    return p


def _length(owner: str, name: str, value) -> float:
    return real(owner, name, value, positive=True, limit=MAX_LENGTH, unit=" m")


def at_angle(origin, length: float, angle: float) -> tuple[float, float]:
    """The point at ``length`` from ``origin`` in the direction ``angle``.

    Parameters
    ----------
    origin : (float, float)
        [m].
    length : float
        [m], > 0.
    angle : float
        [rad], counter-clockwise from +x (a crank angle).

    Returns
    -------
    (float, float)
        [m].
    """
    o = _point("at_angle", "origin", origin)
    r = _length("at_angle", "length", length)
    th = real("at_angle", "angle [rad]", angle)
    return (float(o[0] + r * math.cos(th)), float(o[1] + r * math.sin(th)))


def _side(branch: str, allowed, owner: str) -> str:
    if not isinstance(branch, str) or branch not in allowed:
        raise InputError(f"{owner}: branch must be one of {', '.join(repr(b) for b in allowed)}, got {branch!r:.60}")
    return branch


def circle_intersection(p, a: float, q, b: float, branch: str = "left", *, names=("P", "Q"),
                        labels=(None, None)) -> tuple[float, float]:
    """The point at distance ``a`` from ``p`` and ``b`` from ``q``.

    Parameters
    ----------
    p, q : (float, float)
        Centres [m].
    a, b : float
        Distances [m], > 0 (link lengths).
    branch : {"left", "right"}
        Side of the directed line ``p -> q`` (``"open"`` / ``"crossed"`` are
        resolved to these by :meth:`Mechanism.at_lengths`, which knows which
        joint is the ground pivot).
    names : (str, str)
        Names of ``p`` and ``q`` for the messages (joint names).
    labels : (str or None, str or None)
        Names of the lengths for the messages (link names).

    Returns
    -------
    (float, float)
        The point of the chosen branch [m].

    Raises
    ------
    InputError
        The circles do not meet: ``a + b`` is shorter than ``|p q|`` or
        ``|a - b|`` longer (the message names the joints and lengths), or
        ``p`` and ``q`` coincide.
    """
    owner = f"a joint at lengths from '{names[0]}' and '{names[1]}'"
    p = _point(owner, f"the position of '{names[0]}'", p)
    q = _point(owner, f"the position of '{names[1]}'", q)
    a = _length(owner, f"the length from '{names[0]}'", a)
    b = _length(owner, f"the length from '{names[1]}'", b)
    _side(branch, ("left", "right"), owner)
    la = labels[0] or f"{a:.6g} m from '{names[0]}'"
    lb = labels[1] or f"{b:.6g} m from '{names[1]}'"
    dv = q - p
    d = float(math.hypot(dv[0], dv[1]))
    if d == 0.0:
        raise InputError(f"{owner}: joints '{names[0]}' and '{names[1]}' coincide, so the point is not defined")
    if a + b < d * (1.0 - _SLACK):
        raise InputError(f"{owner}: {la} + {lb} = {a + b:.6g} m < distance |{names[0]}-{names[1]}| = {d:.6g} m; "
                         "the links cannot reach each other (the linkage does not assemble here)")
    if abs(a - b) > d * (1.0 + _SLACK):
        longer, shorter = (la, lb) if a > b else (lb, la)
        raise InputError(f"{owner}: {longer} - {shorter} = {abs(a - b):.6g} m > distance "
                         f"|{names[0]}-{names[1]}| = {d:.6g} m; one circle lies inside the other "
                         "(the linkage does not assemble here)")
    e = dv / d
    x = 0.5 * (d + (a - b) * (a + b) / d)       # along p -> q, law of cosines
    h = math.sqrt(max((a - x) * (a + x), 0.0))  # off the line, 0 at a toggle
    sign = 1.0 if branch == "left" else -1.0
    pt = p + x * e + sign * h * np.array([-e[1], e[0]])
    return (float(pt[0]), float(pt[1]))


def line_intersection(p, a: float, through, axis, branch: str = "open", *, name: str = "P",
                      label: str | None = None) -> tuple[float, float]:
    """The point on the line through ``through`` along ``axis`` at distance ``a`` from ``p``.

    Parameters
    ----------
    p : (float, float)
        Centre [m] (the crank pin of a slider-crank).
    a : float
        Distance [m], > 0 (the connecting rod's length).
    through : (float, float)
        A point of the line [m].
    axis : (float, float)
        Its direction (normalised here).
    branch : {"open", "ahead", "crossed", "behind"}
        ``"open"`` / ``"ahead"``: the point further along ``axis``;
        ``"crossed"`` / ``"behind"``: the other.
    name, label : str
        Names of ``p`` and of the length for the messages.

    Returns
    -------
    (float, float)
        The slider's position on the line [m].

    Raises
    ------
    InputError
        The line is further from ``p`` than ``a``.
    """
    owner = f"a slider at a length from '{name}'"
    p = _point(owner, f"the position of '{name}'", p)
    c = _point(owner, "through", through)
    u = _point(owner, "axis", axis)
    a = _length(owner, f"the length from '{name}'", a)
    _side(branch, LINE_BRANCHES, owner)
    big = float(np.max(np.abs(u)))
    if big == 0.0:
        raise InputError(f"{owner}: axis must be a non-zero vector")
    u = u / big
    u = u / math.hypot(u[0], u[1])
    foot = c + float(u @ (p - c)) * u             # the point of the line nearest p
    off = float(math.hypot(*(p - foot)))
    if off > a * (1.0 + _SLACK):
        what = label or f"{a:.6g} m"
        raise InputError(f"{owner}: {what} from '{name}' cannot reach the slider's line, which is "
                         f"{off:.6g} m from '{name}' (the linkage does not assemble here)")
    s = math.sqrt(max((a - off) * (a + off), 0.0))
    sign = 1.0 if branch in ("open", "ahead") else -1.0
    pt = foot + sign * s * u
    return (float(pt[0]), float(pt[1]))
