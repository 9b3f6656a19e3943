"""A process load's factor over the cycle, and the instants where it kinks or steps.

:class:`~kedfem.model.profiles.Profile` holds the table; here it is read on a
:class:`~kedfem.motion.kinematics.Motion` (:func:`factor`), and the instants where the motion
reaches a kink or a step of it are found (:func:`breaks`, to round-off: Newton on the quantity
from the bracket of a search grid), for the solve to end time elements there.
"""

from __future__ import annotations

import numpy as np

from ..model.profiles import Profile
from .kinematics import Motion

__all__ = ["factor", "quantity", "breaks", "distinct_instants", "SEARCH_SAMPLES"]

#: Instants of the grid on which crossings are bracketed
SEARCH_SAMPLES = 2048
#: Newton steps that refine a bracketed crossing (each halves the bracket when it leaves it)
REFINE_STEPS = 40
#: a factor below this fraction of the table's largest is zero (no step at a dead centre there)
ZERO_FACTOR = 1e-9
#: a level crossing this close to a dead centre (fraction of the cycle) is at the dead centre
SNAP = 1e-5


def distinct_instants(t, period: float) -> np.ndarray:
    """Instants [s] (k,) sorted, each once (those within 1e-12 of the period of the one before
    merged)."""
    t = np.sort(np.asarray(t, dtype=float))
    return t[np.concatenate([[True], np.diff(t) > 1e-12 * period])] if t.size else t


def quantity(profile: Profile, motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """The profile's quantity (n,) at the motion's instants, and its rate (n,).

    Crank angle turned from the drawing [deg] and [deg/s]; a joint's position along the axis
    [m] and its velocity [m/s]; its velocity [m/s] and acceleration [m/s^2].
    """
    if profile.of == "crank_angle":
        rate = 360.0 / motion.period
        return np.mod(np.asarray(motion.t, float) * rate, 360.0), np.full(motion.n, rate)
    ax = np.asarray(profile.axis)
    j = motion.joint_names.index(profile.joint)
    if profile.of == "position":
        return motion.r[:, j] @ ax, motion.v[:, j] @ ax
    return motion.v[:, j] @ ax, motion.a[:, j] @ ax


def factor(profile: Profile, motion: Motion) -> np.ndarray:
    """The profile's factor [-] (n,) at the motion's instants: zero on a stroke it leaves out,
    half the table's at a dead centre itself (the mean of the two strokes' values: the loads of
    a press's down- and up-stroke that meet there add up to the value they meet at)."""
    q, rate = quantity(profile, motion)
    out = profile.table(q)
    if profile.stroke == "forward":
        out = out * (0.5 * (1.0 + np.sign(rate)))
    elif profile.stroke == "return":
        out = out * (0.5 * (1.0 - np.sign(rate)))
    return out


def breaks(profile: Profile, cycle, period: float) -> np.ndarray:
    """Instants [s] in ``[0, period)`` where the factor kinks or steps, sorted.

    The motion reaches a table entry where the slopes change (:attr:`Profile.levels`; on the
    stroke the profile keeps), or a dead centre (the position's rate changes sign) where the
    factor is not zero. A quantity that touches a level and turns back between two instants of
    the search grid is not found (the factor then hardly kinks).

    Parameters
    ----------
    profile : Profile
    cycle : kedfem.motion.kinematics.Cycle
    period : float
        [s].

    Returns
    -------
    ndarray, shape (k,)
    """
    levels = profile.levels
    if profile.of == "crank_angle":
        return np.sort(np.mod(levels / 360.0 * period, period))
    t = np.arange(SEARCH_SAMPLES) * (period / SEARCH_SAMPLES)
    q, rate = quantity(profile, cycle.at(t))
    found = [_crossings(profile, cycle, period, t, q, rate, float(x)) for x in levels]

    def velocity(mo):
        ax = np.asarray(profile.axis)
        j = mo.joint_names.index(profile.joint)
        return mo.v[:, j] @ ax, mo.a[:, j] @ ax

    # dead centres: the rate (the velocity along the axis) changes sign
    dc = _roots(velocity, cycle, period, t, rate, 0.0) if (profile.stroke != "both" or profile.of == "position") \
        else np.zeros(0)
    if profile.of == "position" and dc.size:
        # a level the position reaches at a dead centre is a double root there, found only to about
        # the square root of round-off (2e-7 of the cycle either side): it is the dead centre
        found = [_snap(x, dc, period) for x in found]
    if profile.stroke != "both":
        if dc.size:
            # a dead centre where the table's factor is zero to round-off does not step it (the
            # position there is round-off away from the table's zero: 5e-44 or 0 by the digit)
            pos, _ = quantity(profile, cycle.at(dc))
            dc = dc[np.abs(profile.table(pos)) > ZERO_FACTOR * max(np.abs(profile.y), default=0.0)]
        found.append(dc)
    if not found:
        return np.zeros(0)
    out = np.sort(np.concatenate(found))
    return out


def _snap(x: np.ndarray, centres: np.ndarray, period: float) -> np.ndarray:
    """Instants ``x`` within :data:`SNAP` of the cycle of one of ``centres``, moved onto it."""
    if not x.size:
        return x
    d = np.mod(x[:, None] - centres[None, :] + 0.5 * period, period) - 0.5 * period
    k = np.argmin(np.abs(d), axis=1)
    near = np.abs(d[np.arange(x.size), k]) <= SNAP * period
    return np.where(near, centres[k], x)


def _crossings(profile, cycle, period, t, q, rate, level) -> np.ndarray:
    """Instants where the quantity crosses ``level`` on the stroke the profile keeps."""
    out = _roots(lambda mo: quantity(profile, mo), cycle, period, t, q, level)
    if out.size and profile.stroke != "both":
        _q, r = quantity(profile, cycle.at(out))
        out = out[(r > 0.0) if profile.stroke == "forward" else (r < 0.0)]
    return out


def _roots(fn, cycle, period, t, g, level) -> np.ndarray:
    """Instants where ``fn(motion)[0]`` (its rate ``fn(motion)[1]``) crosses ``level``.

    ``g`` (samples,) its values on the search grid ``t``; periodic.
    """
    f = np.append(g, g[0]) - level
    i = np.flatnonzero((f[:-1] == 0.0) | (np.sign(f[:-1]) * np.sign(f[1:]) < 0))
    if not i.size:
        return np.zeros(0)
    h = period / t.size
    lo, hi = t[i], t[i] + h
    flo = f[i]
    x = np.where(flo == 0.0, lo, 0.5 * (lo + hi))
    for _ in range(REFINE_STEPS):
        val, dval = fn(cycle.at(np.mod(x, period)))
        r = val - level
        if np.all(np.abs(r) <= 1e-13 * max(1.0, float(np.max(np.abs(g))))):
            break
        # keep the bracket: the side whose sign matches the low end moves
        same = np.sign(r) == np.sign(flo)
        lo = np.where(same, x, lo)
        hi = np.where(same, hi, x)
        flo = np.where(same, r, flo)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = x - r / dval
        inside = np.isfinite(step) & (step > lo) & (step < hi)
        x = np.where(inside, step, 0.5 * (lo + hi))
    return np.unique(np.mod(x, period))
