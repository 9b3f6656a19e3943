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

The same equations give the joint forces of an elastic response
(:class:`KnownForces`, used by :mod:`kedfem.analysis.loads`): the flexible
links' end forces are then known from their section forces, their own
balance is dropped, the rigid members and pins move with their elastic
accelerations too, and the remaining forces follow by least squares; the
equations left over (the balance of pins between flexible links) measure
how well the known forces balance.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import KedError
from .kinematics import Motion, slot_direction
from ..model.mechanism import Mechanism

__all__ = ["JointForces", "KnownForces", "kinetostatics", "link_axial_force", "link_axial_force_at"]

log = logging.getLogger(__name__)

#: Weight of a pin's balance against a member's in the least squares of :class:`KnownForces`
PIN_WEIGHT = 1e4


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
        Moment the pin exerts on the member [N m] (non-zero at welded joints,
        and with :class:`KnownForces` where an elastically clamped end passes one).
    drive_torque : ndarray, shape (n, n_drives)
        Torque of each drive on its member [N m].
    frame_reaction : dict
        Joint name -> (n, 2) force of the frame on the pin [N].
    residual : float
        Relative residual of the equations solved (with :class:`KnownForces`:
        the largest imbalance of an equation, relative to the largest force
        or moment term).
    frame_moment : dict
        Joint name -> (n,) moment of the frame on the pin [N m], at the
        ground joints that take one (clamped, or an elastically clamped end).
    contact : dict
        Slot joint name -> (n, 2) force [N] the member ``on`` exerts on the
        block's pin: normal to the line (and along it when the slide is
        locked); the pin exerts the opposite on the member, at the pin.
    contact_moment : dict
        Slot joint name -> (n,) moment [N m] the member exerts on the pin
        of a rotation-locked slot.
    """

    pairs: tuple[tuple[str, str], ...]
    force: np.ndarray
    moment: np.ndarray
    drive_torque: np.ndarray
    frame_reaction: dict
    residual: float
    frame_moment: dict = field(default_factory=dict)
    contact: dict = field(default_factory=dict)
    contact_moment: dict = field(default_factory=dict)

    def on(self, member: str, joint: str) -> np.ndarray:
        """Force (n, 2) [N] the pin at ``joint`` exerts on ``member``."""
        return self.force[:, self.pairs.index((member, joint))]


@dataclass(frozen=True)
class KnownForces:
    """What an elastic response fixes in the joint equilibrium of :func:`kinetostatics`.

    Attributes
    ----------
    force : dict
        ``(member, joint)`` -> (n, 2) force [N] the pin exerts on the member,
        for every attachment of the members whose forces are known (flexible
        links); their own balance equations are dropped.
    moment : dict
        ``(member, joint)`` -> (n,) moment [N m] the pin exerts on such a member
        (an elastically clamped end); the joint then gets a moment balance.
    torque : dict
        Driven member -> (n,) known drive torque [N m].
    moment_pairs : frozenset of (str, str)
        ``(member, joint)`` of members whose forces are unknown that take a
        moment at a joint that is not welded (a rigid member an elastic end
        is clamped to).
    frame_moments : frozenset of str
        Ground joints, not clamped, whose frame takes a moment (an elastic
        end clamped to the frame).
    member_acceleration : ndarray, shape (n, n_members, 2), optional
        Elastic acceleration of each member's centre [m/s^2] (``motion.member_names``).
    member_angular_acceleration : ndarray, shape (n, n_members), optional
        Elastic angular acceleration of each member [rad/s^2].
    joint_acceleration : ndarray, shape (n, n_joints, 2), optional
        Elastic acceleration of each pin [m/s^2] (``motion.joint_names``).
    joint_angular_acceleration : ndarray, shape (n, n_joints), optional
        Elastic angular acceleration at each joint [rad/s^2] (point masses' ``J``).
    """

    force: dict
    moment: dict = field(default_factory=dict)
    torque: dict = field(default_factory=dict)
    moment_pairs: frozenset = frozenset()
    frame_moments: frozenset = frozenset()
    member_acceleration: np.ndarray | None = None
    member_angular_acceleration: np.ndarray | None = None
    joint_acceleration: np.ndarray | None = None
    joint_angular_acceleration: np.ndarray | None = None


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


def _members_of(mech: Mechanism, name: str) -> tuple[str, ...]:
    return mech.links[name].attached if name in mech.links else mech.bodies[name].joints


class _Layout:
    """Unknown columns and equation rows of the joint equilibrium (one layout for all instants).

    Columns: forces of the pairs whose forces are unknown (2 each), their
    moments where they take one, ground reactions (2) and ground moments,
    slider normals, unknown drive torques. Rows: 3 per member whose forces
    are unknown, 2 per joint, 1 per joint passing moments.
    """

    def __init__(self, mech: Mechanism, motion: Motion, known: KnownForces | None):
        kf = known.force if known is not None else {}
        km = known.moment if known is not None else {}
        kt = known.torque if known is not None else {}
        extra_m = known.moment_pairs if known is not None else frozenset()
        extra_g = known.frame_moments if known is not None else frozenset()
        # redundant (kinematic=False) links take no kinetostatic force: their mass goes to their
        # pins, unless their end forces are known (an elastic response)
        self.passive = [m for m in motion.member_names if m in mech.links and not mech.links[m].kinematic
                        and (m, mech.links[m].a) not in kf]
        members = [m for m in motion.member_names if m not in self.passive]
        self.joints = list(motion.joint_names)
        self.pairs = [(m, j) for m in members for j in _members_of(mech, m)]
        given = {m for m in members if all((m, j) in kf for j in _members_of(mech, m))}
        self.members = [m for m in members if m not in given]  # members with balance rows
        col = 0
        self.f_col = {}
        for p in self.pairs:
            if p not in kf:
                self.f_col[p] = col
                col += 2
        self.m_col = {}
        for p in self.pairs:
            if p[0] not in given and (mech.joints[p[1]].welds(p[0]) or p in extra_m or _locked(mech, *p)):
                self.m_col[p] = col
                col += 1
        self.g_col, self.gm_col, self.s_col = {}, {}, {}
        self.c_col, self.cm_col = {}, {}  # slots: normal contact force, and moment when locked
        for j in mech.joints.values():
            if j.kind == "ground":
                self.g_col[j.name] = col
                col += 2
                if j.clamped or j.name in extra_g:
                    self.gm_col[j.name] = col
                    col += 1
            elif j.kind == "slider":
                self.s_col[j.name] = col
                col += 1
                if j.rotation == "locked":  # a crosshead: the guide takes a moment
                    self.gm_col[j.name] = col
                    col += 1
            elif j.kind == "slot":
                self.c_col[j.name] = col
                col += 1 if j.slide == "free" else 2
                if j.rotation == "locked":
                    self.cm_col[j.name] = col
                    col += 1
        self.d_col = []  # None: known, or acting through a clamped ground joint's moment
        for d in mech.drives:
            if d.member in kt or mech.joints[d.ground_joint].clamped:
                self.d_col.append(None)
            else:
                self.d_col.append(col)
                col += 1
        self.n_unk = col
        moment_joints = {p[1] for p in self.m_col} | set(self.gm_col) | {p[1] for p in km} | set(self.cm_col)
        self.moment_joints = [j for j in self.joints if j in moment_joints]
        self.n_eq = 3 * len(self.members) + 2 * len(self.joints) + len(self.moment_joints)


def _locked(mech: Mechanism, member: str, joint: str) -> bool:
    """``member`` is locked in rotation to the member a slot joint slides on."""
    jt = mech.joints[joint]
    return (jt.kind in ("slot", "slider") and jt.rotation == "locked" and member != jt.on)


def _contact_directions(mech, motion, joint):
    """Unit directions (n, k, 2) of the contact force components of a slot: its normal (and its line)."""
    u = slot_direction(mech, motion, joint)[0]
    nrm = np.stack([-u[:, 1], u[:, 0]], axis=-1)
    return nrm[:, None] if mech.joints[joint].slide == "free" else np.stack([nrm, u], axis=1)


def _equations(mech, motion, lay: _Layout, inertia, gravity, joint_loads, member_moments,
               known: KnownForces | None, pair_loads=None):
    """The batched equations ``A x = b``: A (n, n_eq, n_unk), b (n, n_eq)."""
    n = motion.n
    kf = known.force if known is not None else {}
    km = known.moment if known is not None else {}
    kt = known.torque if known is not None else {}
    midx = {m: i for i, m in enumerate(motion.member_names)}
    jidx = {j: i for i, j in enumerate(lay.joints)}
    A = np.zeros((n, lay.n_eq, lay.n_unk))
    b = np.zeros((n, lay.n_eq))
    g = np.asarray(mech.gravity, dtype=float) if gravity else np.zeros(2)

    def elastic(name, i):
        arr = getattr(known, name) if known is not None else None
        return 0.0 if arr is None else arr[:, i]

    # member equations
    for i, mname in enumerate(lay.members):
        mass, J, _origin, _off = _member_mass(mech, mname)
        rc, _vc, ac = member_centre(mech, motion, mname)
        r0 = 3 * i
        for p in lay.pairs:
            if p[0] != mname:
                continue
            c = lay.f_col[p]
            A[:, r0, c] = 1.0
            A[:, r0 + 1, c + 1] = 1.0
            arm = motion.r[:, jidx[p[1]]] - rc
            A[:, r0 + 2, c] = -arm[:, 1]
            A[:, r0 + 2, c + 1] = arm[:, 0]
            if p in lay.m_col:
                A[:, r0 + 2, lay.m_col[p]] = 1.0
        rhs = np.zeros((n, 3))
        for k, d in enumerate(mech.drives):
            if d.member == mname and lay.d_col[k] is not None:
                A[:, r0 + 2, lay.d_col[k]] = 1.0
            elif d.member == mname and d.member in kt:
                rhs[:, 2] -= kt[d.member]
        if inertia:
            rhs[:, :2] += mass * ac
            rhs[:, 2] += J * motion.alpha[:, midx[mname]]
        rhs[:, :2] += mass * elastic("member_acceleration", midx[mname])
        rhs[:, 2] += J * elastic("member_angular_acceleration", midx[mname])
        rhs[:, :2] -= mass * g
        if member_moments is not None:
            rhs[:, 2] -= member_moments[:, midx[mname]]
        b[:, r0:r0 + 3] = rhs
    # pin equations
    r0 = 3 * len(lay.members)
    pm_mass = np.zeros(len(lay.joints))
    pm_J = np.zeros(len(lay.joints))
    for pm in mech.point_masses:
        pm_mass[jidx[pm.joint]] += pm.mass
        pm_J[jidx[pm.joint]] += pm.J
    for name in lay.passive:
        lk = mech.links[name]
        pm_mass[jidx[lk.a]] += 0.5 * lk.mass
        pm_mass[jidx[lk.b]] += 0.5 * lk.mass
    moment_row = {j: r0 + 2 * len(lay.joints) + k for k, j in enumerate(lay.moment_joints)}
    for jn, jname in enumerate(lay.joints):
        jt = mech.joints[jname]
        rr = r0 + 2 * jn
        rhs = np.zeros((n, 2))
        here = [p for p in lay.pairs if p[1] == jname]
        for p in here:
            if p in kf:
                rhs += kf[p]
            else:
                c = lay.f_col[p]
                A[:, rr, c] = -1.0
                A[:, rr + 1, c + 1] = -1.0
        if jname in lay.g_col:
            A[:, rr, lay.g_col[jname]] = 1.0
            A[:, rr + 1, lay.g_col[jname] + 1] = 1.0
        if jname in lay.s_col:
            nrm = np.array([-jt.axis[1], jt.axis[0]])
            A[:, rr, lay.s_col[jname]] = nrm[0]
            A[:, rr + 1, lay.s_col[jname]] = nrm[1]
        if pair_loads and jname in pair_loads:  # a known force inside the pair, along the line
            Fp = pair_loads[jname][:, None] * slot_direction(mech, motion, jname)[0]
            rhs -= Fp
            if jt.on in lay.members:
                r1 = 3 * lay.members.index(jt.on)
                arm = motion.r[:, jn] - member_centre(mech, motion, jt.on)[0]
                b[:, r1:r1 + 2] += Fp
                b[:, r1 + 2] += arm[:, 0] * Fp[:, 1] - arm[:, 1] * Fp[:, 0]
        if jname in lay.c_col:  # the slot's member pushes the pin, the pin the member (at the pin)
            dirs = _contact_directions(mech, motion, jname)
            c0 = lay.c_col[jname]
            A[:, rr:rr + 2, c0:c0 + dirs.shape[1]] = np.swapaxes(dirs, 1, 2)
            if jt.on in lay.members:
                r1 = 3 * lay.members.index(jt.on)
                rc = member_centre(mech, motion, jt.on)[0]
                arm = motion.r[:, jn] - rc
                A[:, r1:r1 + 2, c0:c0 + dirs.shape[1]] = -np.swapaxes(dirs, 1, 2)
                A[:, r1 + 2, c0:c0 + dirs.shape[1]] = -(arm[:, None, 0] * dirs[..., 1]
                                                        - arm[:, None, 1] * dirs[..., 0])
                if jname in lay.cm_col:
                    A[:, r1 + 2, lay.cm_col[jname]] = -1.0
        if inertia:
            rhs += pm_mass[jn] * motion.a[:, jn]
        rhs += pm_mass[jn] * elastic("joint_acceleration", jn)
        rhs -= pm_mass[jn] * g
        if joint_loads is not None:
            rhs -= joint_loads[:, jn]
        b[:, rr:rr + 2] = rhs
        if jname in moment_row:
            wr = moment_row[jname]
            for p in here:
                if p in lay.m_col:
                    A[:, wr, lay.m_col[p]] = -1.0
                elif p in km:
                    b[:, wr] += km[p]
            if jname in lay.gm_col:
                A[:, wr, lay.gm_col[jname]] = 1.0
            if jname in lay.cm_col:
                A[:, wr, lay.cm_col[jname]] = 1.0
            if inertia and here:
                b[:, wr] += pm_J[jn] * motion.alpha[:, midx[here[0][0]]]
            b[:, wr] += pm_J[jn] * elastic("joint_angular_acceleration", jn)
    return A, b


def _solve_square(mech, A, b, n_eq, n_unk):
    """The statically determinate system: its solution and relative residual."""
    if n_unk != n_eq:
        kind = "statically indeterminate" if n_unk > n_eq else "under-constrained"
        raise KedError(f"{mech.name}: kinetostatics has {n_unk} unknown forces for {n_eq} equations "
                       f"({kind}); joint forces, and the axial_stiffening effect, need a statically "
                       "determinate mechanism")
    scale = np.maximum(np.max(np.abs(A), axis=(1, 2)), 1e-300)
    probes = _probes(n_eq)
    try:
        # one batched LU for the solution and two probe vectors: ||A^-1 v|| / ||v|| over random
        # v estimates the smallest singular value's reciprocal (a third of the cost of
        # the inverse, a ninth of a batched SVD)
        X = np.linalg.solve(A, np.concatenate([b[..., None], np.broadcast_to(probes, A.shape[:1] + probes.shape)],
                                              axis=2))
    except np.linalg.LinAlgError:
        raise KedError(f"{mech.name}: kinetostatic equations are singular (toggle position or a "
                       "redundant support); joint forces are not unique") from None
    x = X[..., 0]
    res = np.einsum("nij,nj->ni", A, x) - b
    bscale = np.maximum(np.max(np.abs(b), axis=1), np.max(np.abs(x), axis=1) * scale)
    rel = float(np.max(np.abs(res).max(axis=1) / np.maximum(bscale, 1e-300))) if n_eq else 0.0
    cond = condition_estimate(A, X[..., 1:], probes) if n_eq else np.ones(1)
    if not np.all(np.isfinite(x)) or np.max(cond) > 1e12:
        raise KedError(f"{mech.name}: kinetostatic equations are ill-conditioned (condition "
                       f"{np.max(cond):.3g}); the mechanism passes a toggle position or is "
                       "statically indeterminate")
    return x, rel


def _probes(n: int) -> np.ndarray:
    """Two fixed Gaussian random vectors, shape (n, 2), for :func:`condition_estimate`.

    Gaussian, not random signs: a near-null direction with a few entries of equal size (two
    equations nearly the same, a redundant support) is orthogonal to a sign vector about one
    time in four, and never exactly to a Gaussian one."""
    return np.random.default_rng(20261127).standard_normal((n, 2))


def condition_estimate(A: np.ndarray, Y: np.ndarray, probes: np.ndarray) -> np.ndarray:
    """2-norm condition numbers of a batch of square matrices, estimated from solves with probes.

    For a nearly singular ``A = U S V^T``, ``A^-1 v ~ v_min (u_min . v) / s_min``: over a
    Gaussian vector ``v`` of ``n`` entries, ``|u_min . v|`` is about 1 and ``||v||`` about
    ``sqrt(n)``, so ``sqrt(n) ||A^-1 v|| / ||v||`` is about ``1 / s_min`` (the larger of two
    probes; below it by 100x only where both are, a chance of about 1e-4). Times the Frobenius norm, an upper
    bound of ``s_max``, it is the condition number to within a small factor.

    Parameters
    ----------
    A : ndarray, shape (k, n, n)
    Y : ndarray, shape (k, n, p)
        ``A^-1 probes``.
    probes : ndarray, shape (n, p)

    Returns
    -------
    ndarray, shape (k,)
    """
    n = A.shape[-1]
    inv = math.sqrt(n) * np.max(np.linalg.norm(Y, axis=1) / np.linalg.norm(probes, axis=0), axis=-1)
    return np.linalg.norm(A, axis=(1, 2)) * inv


def _solve_least_squares(mech, motion, lay: _Layout, A, b):
    """Least-squares solution of the over-determined equations with known forces.

    Moment rows are divided by a length of the mechanism and moment columns
    multiplied by it, so that every row is a force [N]. The pins' balances
    (a particle's, exact) weigh :data:`PIN_WEIGHT` times a member's: where a
    pin's forces are unknown they balance it (Newton's third law through a
    massless pin holds), and what the known forces leave over lands in the
    members' balances and in the pins whose forces are all known.
    """
    n = A.shape[0]
    r = motion.r
    length = float(np.max(np.ptp(r.reshape(-1, 2), axis=0))) if r.size else 1.0
    length = length if length > 0 else 1.0
    pin0 = 3 * len(lay.members)
    unit = np.ones(lay.n_eq)  # rows in [N]
    unit[2:pin0:3] = 1.0 / length
    unit[pin0 + 2 * len(lay.joints):] = 1.0 / length
    weight = np.ones(lay.n_eq)
    weight[pin0:] = PIN_WEIGHT
    cols = np.ones(lay.n_unk)  # columns in [N]
    for c in (*lay.m_col.values(), *lay.gm_col.values(), *(c for c in lay.d_col if c is not None)):
        cols[c] = length
    As = A * unit[:, None] * cols[None, :]
    bs = b * unit
    y = np.zeros((n, lay.n_unk))
    if lay.n_unk:
        U, s, Vt = np.linalg.svd(As * weight[:, None], full_matrices=False)
        tiny = s[:, -1] <= 1e-10 * s[:, 0]
        if np.any(tiny) or not np.all(np.isfinite(s)):
            k = int(np.argmax(tiny))
            raise KedError(f"{mech.name}: the forces left unknown by the elastic response are not unique "
                           f"(at crank angle {np.degrees(motion.crank_angle[k]) % 360:.1f} deg): "
                           "a toggle position, or a redundant support of a rigid member")
        y = np.einsum("nji,nj->ni", Vt, np.einsum("nji,nj->ni", U, bs * weight) / s)
    res = np.einsum("nij,nj->ni", As, y) - bs
    size = max(float(np.max(np.abs(bs))) if bs.size else 0.0,
               float(np.max(np.abs(As * y[:, None, :]))) if y.size else 0.0)
    rel = float(np.max(np.abs(res)) / size) if size > 0 else 0.0
    return y * cols, rel


def kinetostatics(mech: Mechanism, motion: Motion, *, inertia: bool = True,
                  gravity: bool = False, joint_loads: np.ndarray | None = None,
                  member_moments: np.ndarray | None = None,
                  known: KnownForces | None = None, pair_loads: dict | None = None) -> JointForces:
    """Joint forces of the rigid mechanism in dynamic equilibrium.

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    motion : Motion
        Its rigid-body motion (``n`` time nodes).
    inertia : bool
        Include the inertia of members and point masses (of the rigid-body
        motion; the elastic accelerations of ``known`` always count).
    gravity : bool
        Include the weight of members and point masses (``mech.gravity``).
    joint_loads : ndarray, shape (n, n_joints, 2), optional
        Applied forces on the joint pins [N] (springs, loads, friction at the
        rigid state), joints in ``motion.joint_names`` order.
    member_moments : ndarray, shape (n, n_members), optional
        Applied moments on the members [N m] (torsional springs), members in
        ``motion.member_names`` order.
    known : KnownForces, optional
        Forces an elastic response fixes (the flexible links' end forces,
        drive torques) and the elastic accelerations; the other forces then
        follow by least squares, and ``residual`` is the imbalance of the
        equations left over.
    pair_loads : dict, optional
        Slot joint -> (n,) known force [N] the member exerts on the block
        along the block's line (a sliding pair's friction); the block exerts
        the opposite on the member, at the block. ``contact`` includes it.

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
    lay = _Layout(mech, motion, known)
    A, b = _equations(mech, motion, lay, inertia, gravity, joint_loads, member_moments, known, pair_loads)
    if known is None:
        x, rel = _solve_square(mech, A, b, lay.n_eq, lay.n_unk)
    else:
        x, rel = _solve_least_squares(mech, motion, lay, A, b)
    kf = known.force if known is not None else {}
    km = known.moment if known is not None else {}
    kt = known.torque if known is not None else {}
    pairs = lay.pairs
    force = np.zeros((n, len(pairs), 2))
    moment = np.zeros((n, len(pairs)))
    for k, p in enumerate(pairs):
        force[:, k] = kf[p] if p in kf else x[:, lay.f_col[p]:lay.f_col[p] + 2]
        if p in lay.m_col:
            moment[:, k] = x[:, lay.m_col[p]]
        elif p in km:
            moment[:, k] = km[p]
    torque = np.zeros((n, len(mech.drives)))
    for k, d in enumerate(mech.drives):
        if d.member in kt:
            torque[:, k] = kt[d.member]
        elif lay.d_col[k] is not None:
            torque[:, k] = x[:, lay.d_col[k]]
        else:
            torque[:, k] = moment[:, pairs.index((d.member, d.ground_joint))]
    frame = {j: x[:, c:c + 2] for j, c in lay.g_col.items()}
    for j, c in lay.s_col.items():
        jt = mech.joints[j]
        frame[j] = x[:, c:c + 1] * np.array([-jt.axis[1], jt.axis[0]])
    frame_moment = {j: x[:, c] for j, c in lay.gm_col.items()}
    contact = {}
    for j, c in lay.c_col.items():
        dirs = _contact_directions(mech, motion, j)
        contact[j] = np.einsum("nk,nkd->nd", x[:, c:c + dirs.shape[1]], dirs)
        if pair_loads and j in pair_loads:
            contact[j] = contact[j] + pair_loads[j][:, None] * slot_direction(mech, motion, j)[0]
    contact_moment = {j: x[:, c] for j, c in lay.cm_col.items()}
    return JointForces(tuple(pairs), force, moment, torque, frame, rel, frame_moment, contact,
                       contact_moment)


def _axial_parts(mech: Mechanism, motion: Motion, forces: JointForces, link: str, gravity: bool):
    """The terms of a link's kinetostatic axial force ``N(s)`` (tension positive):
    ``N(s) = c1 s - w2 s^2 / 2 - Fa + sum_k f_k [s > xi_k]`` with ``c1 = rhoA (a_a.e1 - g.e1)``,
    ``w2 = rhoA omega^2``, each shape (n,), and the steps ``(xi_k, f_k)`` of the pins on it."""
    lk = mech.links[link]
    mi = motion.member_names.index(link)
    th = motion.theta[:, mi]
    e1 = np.stack([np.cos(th), np.sin(th)], axis=-1)
    rhoA = lk.mass / lk.length
    ja = motion.joint_names.index(lk.a)
    aa = np.einsum("nd,nd->n", motion.a[:, ja], e1)
    Fa = np.einsum("nd,nd->n", forces.on(link, lk.a), e1)
    g = np.asarray(mech.gravity) if gravity else np.zeros(2)
    steps = []
    for j, F in forces.contact.items():  # a block on the link pushes it along its axis (locked, friction)
        jt = mech.joints[j]
        if jt.on != link:
            continue
        _o, d, _ax = mech.slot_line(j)
        e0 = (np.array(mech.joints[lk.b].at) - np.array(mech.joints[lk.a].at)) / lk.length
        steps.append((float(d @ e0), np.einsum("nd,nd->n", F, e1)))  # the pin's force on the link is -F
    for j, xi in zip(lk.through, lk.through_at):  # a pin the link passes through: its force beyond it
        steps.append((xi, -np.einsum("nd,nd->n", forces.on(link, j), e1)))
    return rhoA * (aa - e1 @ g), rhoA * motion.omega[:, mi] ** 2, Fa, steps


def link_axial_force(mech: Mechanism, motion: Motion, forces: JointForces, link: str,
                     s1: np.ndarray, s2: np.ndarray, gravity: bool = False) -> np.ndarray:
    """Mean kinetostatic axial force over segments ``[s1, s2]`` of a link.

    ``N(s) = rhoA (s a_a.e1 - omega^2 s^2 / 2) - F_a.e1 - rhoA s g.e1``
    (tension positive), from the balance of the part ``[0, s]`` of the link
    with the force ``F_a`` the pin at ``a`` exerts on it; averaged over each
    segment in closed form. A pin on the link (a slot with a locked slide, or
    a joint the link passes through) adds the axial part of its force beyond
    its abscissa.

    Parameters
    ----------
    s1, s2 : ndarray, shape (n_seg,)
        Segment ends, distances from joint ``a`` [m].

    Returns
    -------
    N : ndarray, shape (n, n_seg)
        Mean axial force per segment [N].
    """
    c1, w2, Fa, steps = _axial_parts(mech, motion, forces, link, gravity)
    sm = 0.5 * (s1 + s2)
    sq = (s1**2 + s1 * s2 + s2**2) / 3.0
    N = c1[:, None] * sm - 0.5 * w2[:, None] * sq - Fa[:, None]
    for xi, f in steps:
        beyond = np.clip((s2 - xi) / np.maximum(s2 - s1, 1e-300), 0.0, 1.0)  # share of the segment past xi
        N = N + f[:, None] * beyond
    return N


def link_axial_force_at(mech: Mechanism, motion: Motion, forces: JointForces, link: str,
                        s: np.ndarray, gravity: bool = False, side: np.ndarray | None = None) -> np.ndarray:
    """Kinetostatic axial force at abscissae ``s`` of a link (the function
    :func:`link_axial_force` averages; a pin's step counts beyond its abscissa).

    Parameters
    ----------
    s : ndarray, shape (...)
        Distances from joint ``a`` [m].
    side : ndarray, optional
        Broadcastable to ``s``: for a point on a pin (within 1e-12 of the link's length), an
        abscissa on the side it belongs to (an element's midpoint: the element beyond the pin
        takes the pin's force from its first point on).

    Returns
    -------
    N : ndarray, shape (n, ...)
        Axial force [N], tension positive.
    """
    c1, w2, Fa, steps = _axial_parts(mech, motion, forces, link, gravity)
    s = np.asarray(s, dtype=float)
    ex = (slice(None),) + (None,) * s.ndim
    N = c1[ex] * s - 0.5 * w2[ex] * s**2 - Fa[ex]
    tol = 1e-12 * mech.links[link].length
    for xi, f in steps:
        beyond = s > xi + tol
        if side is not None:
            beyond = beyond | ((np.abs(s - xi) <= tol) & (side > xi))
        N = N + f[ex] * beyond
    return N
