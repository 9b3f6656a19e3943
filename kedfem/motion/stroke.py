"""Stroke and time ratio of a reciprocating joint (a quick-return's ram, a slider-crank's piston)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from ..errors import InputError, KinematicsError
from ..checks import floats, name
from ..model.mechanism import Mechanism, require_mechanism
from .kinematics import Cycle

__all__ = ["Stroke", "stroke"]

#: Instants of the scan for the dead centres (refined by root finding)
SCAN = 720


@dataclass(frozen=True)
class Stroke:
    """The two dead centres of a joint's motion along an axis over one cycle.

    Attributes
    ----------
    joint : str
    axis : ndarray, shape (2,)
        Unit direction the position is measured along.
    length : float
        Stroke: distance between the dead centres along ``axis`` [m].
    times : ndarray, shape (2,)
        Instants of the rear (smallest position) and front dead centre [s].
    crank_angles : ndarray, shape (2,)
        Absolute crank angles at those instants [rad], in ``[0, 2 pi)`` (as
        :attr:`PeriodicResult.crank_angle`; a ``Profile.crank_angle`` table counts from the drawing).
    forward_time, return_time : float
        Time from rear to front dead centre (motion along +axis), and back [s].
    """

    joint: str
    axis: np.ndarray
    length: float
    times: np.ndarray
    crank_angles: np.ndarray
    forward_time: float
    return_time: float

    @property
    def time_ratio(self) -> float:
        """Slow stroke over quick stroke (>= 1): the quick-return ratio."""
        return max(self.forward_time, self.return_time) / min(self.forward_time, self.return_time)


def stroke(mechanism: Mechanism, joint: str, axis=None) -> Stroke:
    """Dead centres, stroke and time ratio of ``joint`` along ``axis``.

    Parameters
    ----------
    mechanism : Mechanism
        A driven linkage.
    joint : str
        The reciprocating joint.
    axis : (float, float), optional
        Direction of the stroke; default the joint's slider axis.

    Returns
    -------
    Stroke

    Raises
    ------
    InputError
        Unknown joint, or no axis for a joint that is not on a fixed slider.
    KinematicsError
        The joint does not reverse exactly twice per cycle along ``axis``.
    """
    require_mechanism(mechanism, "stroke")
    name("stroke", "joint", joint, mechanism.joints)
    jt = mechanism.joints[joint]
    if axis is None:
        if jt.kind != "slider":
            raise InputError(f"stroke: joint '{joint}' is not on a fixed slider; give the axis=")
        axis = jt.axis
    ax = floats("stroke", "axis", axis).reshape(-1)
    if ax.shape != (2,) or not np.all(np.isfinite(ax)) or not np.hypot(*ax) > 0:
        raise InputError(f"stroke: axis must be a non-zero pair of numbers, got {axis!r}")
    ax = ax / np.hypot(*ax)
    cyc = Cycle(mechanism)
    T = cyc.period
    t = np.arange(SCAN) * (T / SCAN)
    mo = cyc.at(t)
    v = mo.velocity(joint) @ ax
    sign = np.sign(np.where(np.abs(v) <= 1e-12 * np.max(np.abs(v)), 0.0, v))
    for k in np.flatnonzero(sign == 0)[::-1]:  # a dead centre on a sample: the sign of the next one
        sign[k] = sign[(k + 1) % sign.size] if sign[(k + 1) % sign.size] else 1.0
    flips = np.flatnonzero(sign != np.roll(sign, -1))
    if flips.size != 2:
        raise KinematicsError(f"stroke: joint '{joint}' of {mechanism.name} reverses {flips.size} times per "
                              "cycle along the axis; a stroke has two dead centres")

    def speed(time):
        return float(cyc.at(np.array([time])).velocity(joint)[0] @ ax)

    dead = []
    for k in flips:
        a, b = t[k], min(t[k] + T / SCAN, T)
        fa, fb = speed(a), speed(b)
        if fa * fb > 0.0:  # a dead centre on a sample, the signs there rounding noise
            dead.append(a if abs(fa) < abs(fb) else b)
        else:
            dead.append(brentq(speed, a, b, xtol=1e-15 * T, rtol=4 * np.finfo(float).eps))
    dead = np.mod(np.array(dead), T)
    dead = np.where(T - dead <= 1e-12 * T, 0.0, dead)  # the end of the cycle is its start
    pos = np.array([cyc.at(np.array([d])).position(joint)[0] @ ax for d in dead])
    order = np.argsort(pos)
    dead, pos = dead[order], pos[order]
    fwd = (dead[1] - dead[0]) % T
    crank = np.mod(cyc.model.drive_angles(dead)[:, 0], 2 * np.pi)
    return Stroke(joint, ax, float(pos[1] - pos[0]), dead, crank, float(fwd), float(T - fwd))


