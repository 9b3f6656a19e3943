"""The rigid-body motion's record, :class:`Motion`, and what follows from one.

A :class:`Motion` holds the joints' positions, velocities and accelerations, the members' angles
and their rates and the sliders' travels at the instants of a cycle (:mod:`kedfem.motion.kinematics`
computes it); :meth:`Motion.point` gives the motion of a point fixed to a member and
:func:`slot_direction` the turning line of a slot joint over a motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..model.mechanism import Mechanism

__all__ = ["Motion", "slot_direction"]

_S = np.array([[0.0, -1.0], [1.0, 0.0]])


def _rot(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


@dataclass(frozen=True)
class Motion:
    """Rigid-body motion of a mechanism at ``n`` time nodes of one cycle.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Time nodes [s], ``t_k = k * period / n``.
    crank_angle : ndarray, shape (n,)
        Angle of the first driven member [rad]; ``crank_angle[0]`` is the
        reference configuration.
    period : float
        Cycle period [s] (``inf`` for a structure without drive).
    r, v, a : ndarray, shape (n, n_joints, 2)
        Joint positions [m], velocities [m/s], accelerations [m/s^2].
    theta, omega, alpha : ndarray, shape (n, n_members)
        Member angles [rad], angular velocities [rad/s], angular
        accelerations [rad/s^2]. A link's angle is that of its ``a -> b``
        line; a body's angle is its rotation from the reference configuration.
    s, sd, sdd : ndarray, shape (n, n_sliders)
        Slider travel [m] from the reference position, its rate and acceleration.
    residual : float
        Largest loop-closure residual over the cycle [m].
    theta_ref : ndarray, shape (n_members,)
        Member angles in the reference configuration [rad].
    """

    mechanism: str
    t: np.ndarray
    crank_angle: np.ndarray
    period: float
    joint_names: tuple[str, ...]
    member_names: tuple[str, ...]
    slider_names: tuple[str, ...]
    r: np.ndarray
    v: np.ndarray
    a: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    s: np.ndarray
    sd: np.ndarray
    sdd: np.ndarray
    residual: float
    theta_ref: np.ndarray


    @property
    def n(self) -> int:
        """Number of time nodes."""
        return int(self.t.size)

    def __repr__(self) -> str:
        return (f"Motion({self.mechanism!r}: {self.n} instants over {self.period:.6g} s, joints "
                f"{', '.join(self.joint_names)}; members {', '.join(self.member_names)}; sliders "
                f"{', '.join(self.slider_names) or 'none'}; loop residual {self.residual:.2g} m)")

    def _j(self, joint: str) -> int:
        try:
            return self.joint_names.index(joint)
        except ValueError:
            raise InputError(f"unknown joint '{joint}' (joints: {', '.join(self.joint_names)})") from None

    def _m(self, member: str) -> int:
        try:
            return self.member_names.index(member)
        except ValueError:
            raise InputError(f"unknown link or body '{member}' "
                             f"(members: {', '.join(self.member_names)})") from None

    def position(self, joint: str) -> np.ndarray:
        """Joint position, shape (n, 2) [m]."""
        return self.r[:, self._j(joint)]

    def velocity(self, joint: str) -> np.ndarray:
        """Joint velocity, shape (n, 2) [m/s]."""
        return self.v[:, self._j(joint)]

    def acceleration(self, joint: str) -> np.ndarray:
        """Joint acceleration, shape (n, 2) [m/s^2]."""
        return self.a[:, self._j(joint)]

    def angle(self, member: str) -> np.ndarray:
        """Member angle, shape (n,) [rad]."""
        return self.theta[:, self._m(member)]

    def angular_velocity(self, member: str) -> np.ndarray:
        """Member angular velocity, shape (n,) [rad/s]."""
        return self.omega[:, self._m(member)]

    def angular_acceleration(self, member: str) -> np.ndarray:
        """Member angular acceleration, shape (n,) [rad/s^2]."""
        return self.alpha[:, self._m(member)]

    def point(self, member: str, origin: str, offset) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Motion of a point fixed to a member.

        Parameters
        ----------
        member : str
            Link or body.
        origin : str
            A joint of the member.
        offset : array_like, shape (..., 2)
            Vector(s) from ``origin`` to the point(s) in the reference
            configuration [m].

        Returns
        -------
        r, v, a : ndarray, shape (n, ..., 2)
            Position [m], velocity [m/s], acceleration [m/s^2].
        """
        i = self._m(member)
        j = self._j(origin)
        rho0 = np.asarray(offset, dtype=float)
        dth = self.theta[:, i] - self.theta_ref[i]
        R = _rot(dth)  # (n, 2, 2)
        extra = (1,) * (rho0.ndim - 1)
        R = R.reshape((self.n,) + extra + (2, 2))
        rho = R @ rho0[..., None]
        rho = rho[..., 0]
        srho = rho @ _S.T
        w = self.omega[:, i].reshape((self.n,) + extra + (1,))
        al = self.alpha[:, i].reshape((self.n,) + extra + (1,))
        r0 = self.r[:, j].reshape((self.n,) + extra + (2,))
        v0 = self.v[:, j].reshape((self.n,) + extra + (2,))
        a0 = self.a[:, j].reshape((self.n,) + extra + (2,))
        return r0 + rho, v0 + w * srho, a0 + al * srho - w**2 * rho


def slot_direction(mech: Mechanism, motion: Motion, joint: str):
    """Direction of a slot joint's line over the motion, turning with its member.

    Returns
    -------
    u, u1, u2 : ndarray, shape (n, 2)
        The unit direction and its first and second time derivatives
        (``u' = w S u``, ``u'' = a S u - w^2 u``, ``w``, ``a`` the member's rates).
    """
    jt = mech.joints[joint]
    i = motion.member_names.index(jt.on)
    th = motion.theta[:, i] - motion.theta_ref[i]
    w, al = motion.omega[:, i, None], motion.alpha[:, i, None]
    _origin, _d, ax = mech.slot_line(joint)
    c, s_ = np.cos(th), np.sin(th)
    u = np.stack([c * ax[0] - s_ * ax[1], s_ * ax[0] + c * ax[1]], axis=-1)
    su = u @ _S.T
    return u, w * su, al * su - w**2 * u
