"""Kinetostatics: rigid-body inverse dynamics of the whole mechanism.

Given the rigid-body motion, solve for the forces every joint pin exerts on
every member, the frame reactions, slider normal forces and drive torques,
at all time nodes at once. Every member is a rigid body with its own mass
and rotary inertia (flexible links: ``rho A L`` and ``m L^2 / 12``); every
joint is a pin particle carrying its point mass. Per member: force and
moment balance with its inertia; per pin: force balance with its inertia,
the frame reaction (ground: 2 components, slider: the normal component),
and the applied joint loads (springs, loads, friction at the rigid state).
Welded joints also pass moments.

The forces feed the ``axial_stiffening`` effect: the axial force along
each flexible link follows from the force at its ``a`` end and its
distributed inertia (and weight), so a slider's inertia and its normal
reaction reach the connecting rod together with the rod's end shear.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..errors import KedError
from .kinematics import Motion
from ..model.mechanism import Mechanism

__all__ = ["JointForces", "kinetostatics", "link_axial_force"]

log = logging.getLogger(__name__)


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


@dataclass(frozen=True)
class JointForces:
    """Result of :func:`kinetostatics`.

    Attributes
    ----------
    pairs : tuple of (str, str)
        ``(member, joint)`` attachment pairs, in the order of ``force``.
    force : ndarray, shape (n, n_pairs, 2)
        Force the joint pin exerts on the member [N], global components.
    moment : ndarray, shape (n, n_pairs)
        Moment the pin exerts on the member [N m] (non-zero at welded joints).
    drive_torque : ndarray, shape (n, n_drives)
        Torque of each drive on its member [N m].
    frame_reaction : dict
        Joint name -> (n, 2) force of the frame on the pin [N].
    residual : float
        Relative residual of the equations solved.
    """

    pairs: tuple[tuple[str, str], ...]
    force: np.ndarray
    moment: np.ndarray
    drive_torque: np.ndarray
    frame_reaction: dict
    residual: float

    def on(self, member: str, joint: str) -> np.ndarray:
        """Force (n, 2) [N] the pin at ``joint`` exerts on ``member``."""
        return self.force[:, self.pairs.index((member, joint))]


def _member_mass(mech: Mechanism, name: str):
    if name in mech.links:
        lk = mech.links[name]
        a = np.array(mech.joints[lk.a].at)
        b = np.array(mech.joints[lk.b].at)
        return lk.mass, lk.J, lk.a, 0.5 * (b - a)
    body = mech.bodies[name]
    origin = body.joints[0]
    return body.mass, body.J, origin, np.array(body.cm) - np.array(mech.joints[origin].at)


def member_centre(mech: Mechanism, motion: Motion, name: str):
    """Centre-of-mass motion (r, v, a), each (n, 2), of a member."""
    _m, _J, origin, offset = _member_mass(mech, name)
    return motion.point(name, origin, offset)


def kinetostatics(mech: Mechanism, motion: Motion, *, inertia: bool = True,
                  gravity: bool = False, joint_loads: np.ndarray | None = None,
                  member_moments: np.ndarray | None = None) -> JointForces:
    """Joint forces of the rigid mechanism in dynamic equilibrium.

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    motion : Motion
        Its rigid-body motion (``n`` time nodes).
    inertia : bool
        Include the inertia of members and point masses.
    gravity : bool
        Include the weight of members and point masses (``mech.gravity``).
    joint_loads : ndarray, shape (n, n_joints, 2), optional
        Applied forces on the joint pins [N] (springs, loads, friction at the
        rigid state), joints in ``motion.joint_names`` order.
    member_moments : ndarray, shape (n, n_members), optional
        Applied moments on the members [N m] (torsional springs), members in
        ``motion.member_names`` order.

    Returns
    -------
    JointForces

    Raises
    ------
    KedError
        The mechanism is statically indeterminate or under-constrained, so
        the joint forces are not unique.
    """
    n = motion.n
    # redundant (kinematic=False) links take no kinetostatic force: their mass goes to their pins
    passive = [m for m in motion.member_names if m in mech.links and not mech.links[m].kinematic]
    members = [m for m in motion.member_names if m not in passive]
    joints = list(motion.joint_names)
    midx = {m: i for i, m in enumerate(members)}
    jidx = {j: i for i, j in enumerate(joints)}
    pairs = []
    for mname in members:
        js = mech.links[mname].joints if mname in mech.links else mech.bodies[mname].joints
        pairs.extend((mname, j) for j in js)
    npair = len(pairs)
    # unknown layout: pair forces (2 each), pair moments at welded joints, ground
    # reactions (2), ground moments at clamped joints, slider normals, drive torques
    col = 0
    f_col = {}
    for p in pairs:
        f_col[p] = col
        col += 2
    m_col = {}
    for p in pairs:
        if mech.joints[p[1]].welded:
            m_col[p] = col
            col += 1
    g_col, gm_col, s_col = {}, {}, {}
    for j in mech.joints.values():
        if j.kind == "ground":
            g_col[j.name] = col
            col += 2
            if j.welded:
                gm_col[j.name] = col
                col += 1
        elif j.kind == "slider":
            s_col[j.name] = col
            col += 1
    d_col = []  # None: the drive acts through a clamped ground joint's moment
    for d in mech.drives:
        if mech.joints[d.ground_joint].welded:
            d_col.append(None)
        else:
            d_col.append(col)
            col += 1
    n_unk = col
    n_eq = 3 * len(members) + 2 * len(joints) + sum(1 for j in mech.joints.values() if j.welded)
    A = np.zeros((n, n_eq, n_unk))
    b = np.zeros((n, n_eq))
    g = np.asarray(mech.gravity, dtype=float) if gravity else np.zeros(2)
    # member equations
    for i, mname in enumerate(members):
        mass, J, _origin, _off = _member_mass(mech, mname)
        rc, _vc, ac = member_centre(mech, motion, mname)
        r0 = 3 * i
        for p in pairs:
            if p[0] != mname:
                continue
            c = f_col[p]
            A[:, r0, c] = 1.0
            A[:, r0 + 1, c + 1] = 1.0
            arm = motion.r[:, jidx[p[1]]] - rc
            A[:, r0 + 2, c] = -arm[:, 1]
            A[:, r0 + 2, c + 1] = arm[:, 0]
            if p in m_col:
                A[:, r0 + 2, m_col[p]] = 1.0
        for k, d in enumerate(mech.drives):
            if d.member == mname and d_col[k] is not None:
                A[:, r0 + 2, d_col[k]] = 1.0
        rhs = np.zeros((n, 3))
        if inertia:
            rhs[:, :2] += mass * ac
            rhs[:, 2] += J * motion.alpha[:, midx[mname]]
        rhs[:, :2] -= mass * g
        if member_moments is not None:
            rhs[:, 2] -= member_moments[:, midx[mname]]
        b[:, r0:r0 + 3] = rhs
    # pin equations
    r0 = 3 * len(members)
    pm_mass = np.zeros(len(joints))
    pm_J = np.zeros(len(joints))
    for pm in mech.point_masses:
        pm_mass[jidx[pm.joint]] += pm.mass
        pm_J[jidx[pm.joint]] += pm.J
    for name in passive:
        lk = mech.links[name]
        pm_mass[jidx[lk.a]] += 0.5 * lk.mass
        pm_mass[jidx[lk.b]] += 0.5 * lk.mass
    weld_row = r0 + 2 * len(joints)
    for jn, jname in enumerate(joints):
        jt = mech.joints[jname]
        rr = r0 + 2 * jn
        for p in pairs:
            if p[1] == jname:
                c = f_col[p]
                A[:, rr, c] = -1.0
                A[:, rr + 1, c + 1] = -1.0
        if jname in g_col:
            A[:, rr, g_col[jname]] = 1.0
            A[:, rr + 1, g_col[jname] + 1] = 1.0
        if jname in s_col:
            nrm = np.array([-jt.axis[1], jt.axis[0]])
            A[:, rr, s_col[jname]] = nrm[0]
            A[:, rr + 1, s_col[jname]] = nrm[1]
        rhs = np.zeros((n, 2))
        if inertia:
            rhs += pm_mass[jn] * motion.a[:, jn]
        rhs -= pm_mass[jn] * g
        if joint_loads is not None:
            rhs -= joint_loads[:, jn]
        b[:, rr:rr + 2] = rhs
        if jt.welded:
            for p in pairs:
                if p[1] == jname:
                    A[:, weld_row, m_col[p]] = -1.0
            if jname in gm_col:
                A[:, weld_row, gm_col[jname]] = 1.0
            mem_here = [p[0] for p in pairs if p[1] == jname]
            if inertia and mem_here:
                b[:, weld_row] = pm_J[jn] * motion.alpha[:, midx[mem_here[0]]]
            weld_row += 1
    if n_unk != n_eq:
        kind = "statically indeterminate" if n_unk > n_eq else "under-constrained"
        raise KedError(f"{mech.name}: kinetostatics has {n_unk} unknown forces for {n_eq} equations "
                       f"({kind}); joint forces, and the axial_stiffening effect, need a statically "
                       "determinate mechanism")
    scale = np.maximum(np.max(np.abs(A), axis=(1, 2)), 1e-300)
    try:
        # the inverse gives the solution and a 1-norm condition number (within a factor
        # n_eq of the 2-norm one) at a third of the cost of a batched SVD
        Ainv = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        raise KedError(f"{mech.name}: kinetostatic equations are singular (toggle position or a "
                       "redundant support); joint forces are not unique") from None
    x = np.einsum("nij,nj->ni", Ainv, b)
    res = np.einsum("nij,nj->ni", A, x) - b
    bscale = np.maximum(np.max(np.abs(b), axis=1), np.max(np.abs(x), axis=1) * scale)
    rel = float(np.max(np.abs(res).max(axis=1) / np.maximum(bscale, 1e-300))) if n_eq else 0.0
    cond = (np.abs(A).sum(axis=1).max(axis=1) * np.abs(Ainv).sum(axis=1).max(axis=1)
            if n_eq else np.ones(1))
    if not np.all(np.isfinite(x)) or np.max(cond) > 1e12:
        raise KedError(f"{mech.name}: kinetostatic equations are ill-conditioned (condition "
                       f"{np.max(cond):.3g}); the mechanism passes a toggle position or is "
                       "statically indeterminate")
    force = np.stack([x[:, f_col[p]:f_col[p] + 2] for p in pairs], axis=1) if pairs else np.zeros((n, 0, 2))
    moment = np.zeros((n, npair))
    for k, p in enumerate(pairs):
        if p in m_col:
            moment[:, k] = x[:, m_col[p]]
    torque = np.zeros((n, len(mech.drives)))
    for k, d in enumerate(mech.drives):
        if d_col[k] is not None:
            torque[:, k] = x[:, d_col[k]]
        else:
            torque[:, k] = moment[:, pairs.index((d.member, d.ground_joint))]
    frame = {j: x[:, c:c + 2] for j, c in g_col.items()}
    for j, c in s_col.items():
        jt = mech.joints[j]
        frame[j] = x[:, c:c + 1] * np.array([-jt.axis[1], jt.axis[0]])
    return JointForces(tuple(pairs), force, moment, torque, frame, rel)


def link_axial_force(mech: Mechanism, motion: Motion, forces: JointForces, link: str,
                     s1: np.ndarray, s2: np.ndarray, gravity: bool = False) -> np.ndarray:
    """Mean kinetostatic axial force over segments ``[s1, s2]`` of a link.

    ``N(s) = rhoA (s a_a.e1 - omega^2 s^2 / 2) - F_a.e1 - rhoA s g.e1``
    (tension positive), from the balance of the part ``[0, s]`` of the link
    with the force ``F_a`` the pin at ``a`` exerts on it; averaged over each
    segment in closed form.

    Parameters
    ----------
    s1, s2 : ndarray, shape (n_seg,)
        Segment ends, distances from joint ``a`` [m].

    Returns
    -------
    N : ndarray, shape (n, n_seg)
        Mean axial force per segment [N].
    """
    lk = mech.links[link]
    mi = motion.member_names.index(link)
    th = motion.theta[:, mi]
    e1 = np.stack([np.cos(th), np.sin(th)], axis=-1)
    rhoA = lk.mass / lk.length
    ja = motion.joint_names.index(lk.a)
    aa = np.einsum("nd,nd->n", motion.a[:, ja], e1)
    Fa = np.einsum("nd,nd->n", forces.on(link, lk.a), e1)
    g = np.asarray(mech.gravity) if gravity else np.zeros(2)
    ge = e1 @ g
    w2 = motion.omega[:, mi] ** 2
    sm = 0.5 * (s1 + s2)
    sq = (s1**2 + s1 * s2 + s2**2) / 3.0
    return (rhoA * (aa[:, None] * sm - 0.5 * w2[:, None] * sq) - Fa[:, None]
            - rhoA * ge[:, None] * sm)
