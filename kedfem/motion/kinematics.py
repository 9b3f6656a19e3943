"""Rigid-body kinematics of planar linkages by loop closure.

Every member (link or rigid body) is a rigid body with one unknown angle;
every slider has one unknown travel along its line. The joint graph (joints
plus the frame) is spanned by a tree grown from the frame; each chord (an
edge not in the tree) closes one independent loop and gives two loop
closure equations ``sum of member vectors around the loop = 0``. Welded
joints and clamped ground joints add angle equations. Drives prescribe the
angles of driven members, ``theta = theta_0 + speed * t``.

Positions come from Newton's method with continuation from time node to
time node (a second-order Taylor predictor, step halving on failure);
velocities and accelerations from the linear velocity and acceleration
equations (no finite differences), solved for all time nodes at once.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, KinematicsError, MobilityError
from ..model.materials import real
from ..model.mechanism import GROUND, Mechanism, require_mechanism

__all__ = ["Motion", "Cycle", "kinematics", "kinematics_at", "static_motion", "slot_direction"]

log = logging.getLogger(__name__)

_S = np.array([[0.0, -1.0], [1.0, 0.0]])
#: Most instants of one kinematics call (a 0.005 degree crank step; the solver's own limit is far below)
MAX_NODES = 100_000


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


class _LoopModel:
    """Compiled loop-closure model of a mechanism (internal)."""

    def __init__(self, mech: Mechanism):
        require_mechanism(mech, "kinematics")
        mech.validate()
        self.mech = mech
        self.joint_names = tuple(mech.joints)
        self.jindex = {j: i for i, j in enumerate(self.joint_names)}
        self.passive = tuple(n for n, lk in mech.links.items() if not lk.kinematic)
        self.member_names = tuple([n for n in mech.links if n not in self.passive] + list(mech.bodies))
        self.mindex = {m: i for i, m in enumerate(self.member_names)}
        self.slider_names = tuple(j.name for j in mech.joints.values()
                                  if j.kind == "slider" or (j.kind == "slot" and j.slide == "free"))
        nm = len(self.member_names)
        # member reference data: reference joint, reference angle, local vectors
        theta0 = np.zeros(nm)
        edges = []  # (u, v, kind, member_or_slider_index, local vector)
        for i, name in enumerate(self.member_names):
            if name in mech.links:
                lk = mech.links[name]
                pa, pb = np.array(mech.joints[lk.a].at), np.array(mech.joints[lk.b].at)
                theta0[i] = math.atan2(pb[1] - pa[1], pb[0] - pa[0])
                edges.append((lk.a, lk.b, "member", i, np.array([lk.length, 0.0])))
                for t, x in zip(lk.through, lk.through_at):  # joints on the link's line
                    edges.append((lk.a, t, "member", i, np.array([x, 0.0])))
            else:
                b = mech.bodies[name]
                p0 = np.array(mech.joints[b.joints[0]].at)
                for j in b.joints[1:]:
                    edges.append((b.joints[0], j, "member", i, np.array(mech.joints[j].at) - p0))
        axes = {}
        for j in mech.joints.values():
            if j.kind == "ground":
                edges.append((GROUND, j.name, "ground", -1, np.array(j.at)))
            elif j.kind == "slider":
                edges.append((GROUND, j.name, "slider", self.slider_names.index(j.name), np.array(j.at)))
                axes[j.name] = np.array(j.axis)
            elif j.kind == "slot":
                # a line fixed in member i: w = R(theta_i) (d + s a), d and a in the member's frame
                i = self.mindex[j.on]
                origin, d, ax = mech.slot_line(j.name)
                back = _rot(-theta0[i])
                if j.slide == "free":
                    k = self.slider_names.index(j.name)
                    edges.append((origin, j.name, "slot", (i, k), back @ d))
                    axes[j.name] = back @ ax
                else:
                    edges.append((origin, j.name, "member", i, back @ d))
        self.slot_axis = axes
        self.theta0 = theta0
        self.edges = edges
        self._build_tree()
        self._build_welds()
        self._build_drives()

    # -- topology -----------------------------------------------------------
    def _build_tree(self):
        nodes = [GROUND] + list(self.joint_names)
        nidx = {n: i for i, n in enumerate(nodes)}
        adj = {n: [] for n in nodes}
        for e, (u, v, *_rest) in enumerate(self.edges):
            adj[u].append((e, v, +1))
            adj[v].append((e, u, -1))
        # BFS from the frame, or from the first joint for a floating structure
        root = GROUND if adj[GROUND] else self.joint_names[0]
        parent = {root: None}
        order = [root]
        tree = set()
        queue = [root]
        while queue:
            x = queue.pop(0)
            for e, y, sgn in adj[x]:
                if y not in parent:
                    parent[y] = (e, x, sgn)
                    tree.add(e)
                    order.append(y)
                    queue.append(y)
        missing = [n for n in nodes if n not in parent and n != GROUND]
        if missing:
            raise InputError(f"{self.mech.name}: joints {', '.join(missing)} are not connected to the rest")
        ne = len(self.edges)
        # path incidence: r_node = sum_e P[node, e] w_e
        P = np.zeros((len(nodes), ne))
        for n in order[1:]:
            e, x, sgn = parent[n]
            P[nidx[n]] = P[nidx[x]]
            P[nidx[n], e] += sgn
        self.root = root
        self.P = P[[nidx[j] for j in self.joint_names]]  # (nj, ne)
        self._P_all = P
        self._nidx = nidx
        self._parent = parent
        chords = [e for e in range(ne) if e not in tree]
        D = np.zeros((len(chords), ne))
        loops = []
        for c, e in enumerate(chords):
            u, v = self.edges[e][0], self.edges[e][1]
            D[c] = P[nidx[v]] - P[nidx[u]]
            D[c, e] -= 1.0
            loops.append(self._loop_name(u, v))
        self.chords = chords
        self.D = D
        self.loop_names = loops

    def _path(self, n):
        out = [n]
        while self._parent[n] is not None:
            n = self._parent[n][1]
            out.append(n)
        return out

    def _loop_name(self, u, v):
        pu, pv = self._path(u), self._path(v)
        common = next(x for x in pu if x in pv)
        loop = pu[: pu.index(common) + 1] + list(reversed(pv[: pv.index(common)]))
        return "-".join("frame" if x == GROUND else x for x in loop)

    def _build_welds(self):
        rows = []  # (i, j, const, description): theta_i - theta_j = const (j = -1: frame)
        mech = self.mech
        for j in mech.joints.values():
            if not j.welded:
                continue
            mem = [m for m in mech.members_at(j.name) if m in self.mindex and j.welds(m)]
            idx = [self.mindex[m] for m in mem]
            if j.clamped:
                for i in idx:
                    if mech.driven(self.member_names[i]) is None:
                        rows.append((i, -1, 0.0, f"clamped ground joint '{j.name}'"))
            else:
                for i in idx[1:]:
                    rows.append((i, idx[0], 0.0, f"welded joint '{j.name}'"))
        for j in mech.joints.values():
            if j.kind == "slider" and j.rotation == "locked":  # a crosshead: no member turns
                for m in mech.members_at(j.name):
                    if m in self.mindex and mech.driven(m) is None:
                        rows.append((self.mindex[m], -1, 0.0, f"locked slider '{j.name}'"))
            if j.kind == "slot" and j.rotation == "locked":
                k = self.mindex[j.on]
                for m in mech.members_at(j.name):
                    if m in self.mindex and m != j.on:
                        rows.append((self.mindex[m], k, 0.0, f"locked slider '{j.name}' on '{j.on}'"))
        self.welds = rows

    def _build_drives(self):
        mech = self.mech
        self.drive_idx = np.array([self.mindex[d.member] for d in mech.drives], dtype=int)
        self.drive_speed = np.array([d.speed for d in mech.drives], dtype=float)
        nm = len(self.member_names)
        driven = np.zeros(nm, bool)
        driven[self.drive_idx] = True
        self.free_members = np.flatnonzero(~driven)
        self.n_unknown = self.free_members.size + len(self.slider_names)
        self.n_eq = 2 * len(self.chords) + len(self.welds)
        # member index of each edge (-1 if not a member edge) and local vectors
        self.edge_member = np.array([e[3] if e[2] == "member" else e[3][0] if e[2] == "slot" else -1
                                     for e in self.edges])
        self.edge_slider = np.array([e[3] if e[2] == "slider" else e[3][1] if e[2] == "slot" else -1
                                     for e in self.edges])
        self._slot_edges = np.array([e for e, ed in enumerate(self.edges) if ed[2] == "slot"], dtype=int)
        self.edge_vec0 = np.array([e[4] for e in self.edges])
        self._mem_edges = np.flatnonzero(self.edge_member >= 0)
        self._slider_edges = np.flatnonzero(self.edge_slider >= 0)
        nm = len(self.member_names)
        A = np.zeros((len(self.edges), nm))
        A[self._mem_edges, self.edge_member[self._mem_edges]] = 1.0
        self._Dm = self.D[:, :, None] * A[None]  # (nc, ne, nm)
        # slider axes: global for a fixed line, in the member's frame for a slot
        self.slider_axis = np.array([self.slot_axis[name] for name in self.slider_names]).reshape(-1, 2)
        self._fixed_slider_edges = np.array([e for e, ed in enumerate(self.edges) if ed[2] == "slider"],
                                            dtype=int)

    def check_mobility(self):
        n_total = len(self.member_names) + len(self.slider_names)
        dof = n_total - self.n_eq
        nd = len(self.mech.drives)
        if dof != nd:
            raise MobilityError(
                f"{self.mech.name}: mobility {dof} (members + sliders: {n_total}, loop and weld "
                f"equations: {self.n_eq}, loops: {', '.join(self.loop_names) or 'none'}) does not "
                f"match its {nd} drive(s)")

    # -- geometry -----------------------------------------------------------
    def edge_vectors(self, theta, s):
        """Edge vectors w_e, shape (..., ne, 2) for theta (..., nm), s (..., ns).

        Link edges are ``R(theta) (L, 0)``; body edges ``R(theta) d0`` with
        ``d0`` the reference-configuration vector (bodies have angle 0 there).
        """
        lead = theta.shape[:-1]
        w = np.empty(lead + self.edge_vec0.shape)
        w[...] = self.edge_vec0
        mem = self._mem_edges
        if mem.size:
            th = theta[..., self.edge_member[mem]]
            c, sn = np.cos(th), np.sin(th)
            v = self.edge_vec0[mem]
            w[..., mem, 0] = c * v[:, 0] - sn * v[:, 1]
            w[..., mem, 1] = sn * v[:, 0] + c * v[:, 1]
        sl = self._fixed_slider_edges
        if sl.size:
            k = self.edge_slider[sl]
            w[..., sl, :] += s[..., k, None] * self.slider_axis[k]
        sl = self._slot_edges
        if sl.size:
            w[..., sl, :] += s[..., self.edge_slider[sl], None] * self.slot_directions(theta, sl)
        return w

    def slot_directions(self, theta, edges=None):
        """Unit directions of the slot lines ``R(theta_i) a``, shape (..., n_slot_edges, 2)."""
        sl = self._slot_edges if edges is None else edges
        th = theta[..., self.edge_member[sl]]
        a = self.slider_axis[self.edge_slider[sl]]
        c, sn = np.cos(th), np.sin(th)
        return np.stack([c * a[:, 0] - sn * a[:, 1], sn * a[:, 0] + c * a[:, 1]], axis=-1)

    def residual(self, theta, s, w=None):
        """Loop-closure and weld residuals, shape (..., n_eq) (``w``: the edge vectors, when known)."""
        w = self.edge_vectors(theta, s) if w is None else w
        loop = np.matmul(self.D, w).reshape(theta.shape[:-1] + (-1,))
        if self.welds:
            wv = np.stack([theta[..., i] - (theta[..., j] if j >= 0 else 0.0)
                           - (self.theta0[i] - (self.theta0[j] if j >= 0 else 0.0))
                           for i, j, _c, _d in self.welds], axis=-1)
            loop = np.concatenate([loop, wv], axis=-1)
        return loop

    def jacobian(self, theta, s, w=None):
        """d residual / d (all members' angles, sliders), shape (..., n_eq, nm + ns) (``w``: the edge
        vectors, when known)."""
        w = self.edge_vectors(theta, s) if w is None else w
        lead = theta.shape[:-1]
        nm, ns = len(self.member_names), len(self.slider_names)
        nc = len(self.chords)
        J = np.zeros(lead + (2 * nc + len(self.welds), nm + ns))
        sw = np.empty_like(w)  # d w_e / d theta_member = S w_e
        sw[..., 0] = -w[..., 1]
        sw[..., 1] = w[..., 0]
        if sw.size > 64 * sw.shape[-2] * 2:  # many instants: one BLAS product (an einsum below)
            Jt = np.moveaxis(np.tensordot(sw, self._Dm, axes=([sw.ndim - 2], [1])), -3, -2)
        else:
            Jt = np.einsum("cem,...ed->...cdm", self._Dm, sw)
        J[..., : 2 * nc, :nm] = Jt.reshape(lead + (2 * nc, nm))
        for e in self._fixed_slider_edges:
            k = self.edge_slider[e]
            J[..., : 2 * nc, nm + k] += (self.D[:, e, None] * self.slider_axis[k]).reshape(-1)
        if self._slot_edges.size:
            u = self.slot_directions(theta)  # (..., n_slot, 2)
            for c, e in enumerate(self._slot_edges):
                k = self.edge_slider[e]
                J[..., : 2 * nc, nm + k] += (self.D[:, e, None] * u[..., c, None, :]).reshape(lead + (-1,))
        for r, (i, j, _c, _d) in enumerate(self.welds):
            J[..., 2 * nc + r, i] = 1.0
            if j >= 0:
                J[..., 2 * nc + r, j] = -1.0
        return J

    def check_slots(self, s, crank):
        """Raise :class:`KinematicsError` when a block runs off the end of its link.

        ``s`` (n, n_sliders) travels [m], ``crank`` (n,) the crank angle [rad].
        """
        for e in self._slot_edges:
            name = self.edges[e][1]
            lk = self.mech.links.get(self.mech.joints[name].on)
            if lk is None:
                continue
            k = self.edge_slider[e]
            xi = self.edge_vec0[e][0] + s[:, k] * self.slider_axis[k][0]
            tol = 1e-9 * lk.length
            out = np.flatnonzero((xi < -tol) | (xi > lk.length + tol))
            if out.size:
                i = int(out[0])
                near = " or shorten the stroke" if xi[i] > 0 else (
                    "; or, if the block passes close to the line's origin at joint "
                    f"'{lk.a}' (the member's angle turns fast there), the motion jumped to another assembly "
                    "branch near that toggle: move the pivot away from the block's path")
                raise KinematicsError(
                    f"{self.mech.name}: the block of slider '{name}' runs off link '{lk.name}' at crank "
                    f"angle {math.degrees(float(crank[i])):.3f} deg: its abscissa {xi[i]:.6g} m is outside "
                    f"the link (0 to {lk.length:.6g} m); lengthen '{lk.name}'{near}")

    def unknown_columns(self):
        nm = len(self.member_names)
        return np.concatenate([self.free_members, nm + np.arange(len(self.slider_names))])

    def drive_angles(self, t):
        return self.theta0[self.drive_idx] + np.multiply.outer(t, self.drive_speed)

    def scale(self):
        return max(1.0, float(np.max(np.abs(self.edge_vec0)))) if len(self.edges) else 1.0


def _split(model: _LoopModel, y, th_drive):
    nm = len(model.member_names)
    lead = y.shape[:-1]
    theta = np.zeros(lead + (nm,))
    theta[..., model.free_members] = y[..., : model.free_members.size]
    theta[..., model.drive_idx] = th_drive
    s = y[..., model.free_members.size:]
    return theta, s


def _newton(model, y, th_drive, cols, tol, max_iter=12):
    """Newton on the loop equations at one time node; returns (y, ok, resnorm, cond)."""
    res_norm = np.inf
    for _ in range(max_iter):
        theta, s = _split(model, y, th_drive)
        w = model.edge_vectors(theta, s)
        res = model.residual(theta, s, w)
        res_norm = float(np.max(np.abs(res))) if res.size else 0.0
        J = model.jacobian(theta, s, w)[:, cols]
        if res_norm <= tol:
            return y, True, res_norm, J
        try:
            dy = np.linalg.solve(J, -res)
        except np.linalg.LinAlgError:
            return y, False, res_norm, None
        y = y + dy
    return y, False, res_norm, None


def _rates(model, theta, s, th_drive_rate, cols):
    """Velocities and accelerations of the unknowns for all nodes at once."""
    n = theta.shape[0]
    w = model.edge_vectors(theta, s)
    J = model.jacobian(theta, s, w)  # (n, neq, nm+ns)
    Ju = J[:, :, cols]
    Jd = J[:, :, model.drive_idx]
    rhs_v = -np.matmul(Jd, th_drive_rate[..., None])[..., 0]
    yd = np.linalg.solve(Ju, rhs_v[..., None])[..., 0]
    omega, sd = _split(model, yd, th_drive_rate)
    # acceleration: J [alpha; s''] = sum_loops D omega_e^2 w_e  (constant drive speed)
    mem = model.edge_member >= 0
    om_e = np.zeros((n, len(model.edges)))
    om_e[:, mem] = omega[:, model.edge_member[mem]]
    quad = np.matmul(model.D, (om_e**2)[..., None] * w)
    sl = model._slot_edges
    if sl.size:  # Coriolis: the slot turns while the block slides, 2 omega s' S u
        cor = np.zeros_like(w)
        cor[:, sl] = 2.0 * (om_e[:, sl] * sd[:, model.edge_slider[sl]])[..., None] \
            * (model.slot_directions(theta) @ _S.T)
        quad = quad - np.matmul(model.D, cor)
    quad = quad.reshape(n, -1)
    rhs_a = np.concatenate([quad, np.zeros((n, len(model.welds)))], axis=1)
    ydd = np.linalg.solve(Ju, rhs_a[..., None])[..., 0]
    alpha, sdd = _split(model, ydd, np.zeros_like(th_drive_rate))
    return omega, sd, alpha, sdd


def _joint_states(model, theta, s, omega, sd, alpha, sdd):
    w = model.edge_vectors(theta, s)
    n = theta.shape[0]
    mem = model.edge_member >= 0
    om_e = np.zeros((n, len(model.edges)))
    al_e = np.zeros((n, len(model.edges)))
    om_e[:, mem] = omega[:, model.edge_member[mem]]
    al_e[:, mem] = alpha[:, model.edge_member[mem]]
    sw = w @ _S.T
    wd = om_e[..., None] * sw
    wdd = al_e[..., None] * sw - (om_e**2)[..., None] * w
    sl = model._fixed_slider_edges
    if sl.size:
        k = model.edge_slider[sl]
        wd[:, sl] = sd[:, k, None] * model.slider_axis[k]
        wdd[:, sl] = sdd[:, k, None] * model.slider_axis[k]
    sl = model._slot_edges
    if sl.size:
        u = model.slot_directions(theta)
        k = model.edge_slider[sl]
        wd[:, sl] += sd[:, k, None] * u
        wdd[:, sl] += sdd[:, k, None] * u + 2.0 * (om_e[:, sl] * sd[:, k])[..., None] * (u @ _S.T)
    r = np.matmul(model.P, w)
    v = np.matmul(model.P, wd)
    a = np.matmul(model.P, wdd)
    return r, v, a


class Cycle:
    """Rigid-body motion of a driven mechanism at any instants of its cycle.

    The assembly branch is followed once, by continuation on a coarse grid
    (36 steps, about 10 degrees of crank, with step halving); positions at
    any instants then start from a cubic Hermite interpolation of the coarse
    solution and its exact rates and are corrected by Newton's method for
    all instants at once. Build one and call :meth:`at` as often as needed
    (the time discretisations of a solve, its output grid).

    Parameters
    ----------
    mechanism : Mechanism
        A driven single-degree-of-freedom linkage.

    Raises
    ------
    MobilityError, KinematicsError
        As :func:`kinematics`.
    """

    #: steps of the coarse continuation grid
    COARSE = 36
    #: the continuation marches through every STRIDE-th instant of the coarse grid; the others
    #: are solved together from the marched ones (:func:`_coarse_march`)
    STRIDE = 3

    def __init__(self, mechanism: Mechanism):
        model = _LoopModel(mechanism)
        if not mechanism.drives:
            raise InputError(f"{mechanism.name}: has no drive, so it has no cycle; "
                             "use static_motion() for a structure")
        self.mechanism = mechanism
        self.model = model
        self.period = period = mechanism.period
        model.check_mobility()
        self.tol = tol = 1e-14 * model.scale()
        _check_reference(model, tol)
        self.y0 = y0 = np.concatenate([model.theta0[model.free_members],
                                       np.zeros(len(model.slider_names))])
        cols = model.unknown_columns()
        n_c = self.COARSE
        self.h = h = period / n_c
        self.tc = tc = np.arange(n_c + 1) * h
        yc = _coarse_march(model, tc, y0, tol, cols, self.STRIDE)
        self.yc = yc
        if cols.size:
            theta, sl = _split(model, yc, model.drive_angles(tc))
            model.check_slots(sl, model.drive_angles(tc)[:, 0])
            self.ydc = _unknown_rates(model, theta, sl, cols)
        else:
            self.ydc = np.zeros_like(yc)
        # close the cycle: continuing to t = T must return to the reference configuration
        if not _closes(model, y0, yc[-1]):
            raise KinematicsError(f"{mechanism.name}: the motion does not return to the reference "
                                  "configuration after one cycle (the linkage switched assembly branch)")

    def positions(self, t: np.ndarray) -> np.ndarray:
        """Unknown coordinates (free angles, slider travels) at instants ``t`` in ``[0, T]``."""
        model, tol, y0 = self.model, self.tol, self.y0
        cols = model.unknown_columns()
        n = t.size
        if cols.size == 0:
            return np.broadcast_to(y0, (n, y0.size)).copy()
        k = np.clip((t / self.h).astype(int), 0, self.COARSE - 1)
        guess = _hermite(self.tc, self.yc, self.ydc, k, t)
        thd = model.drive_angles(t)
        y, ok = _newton_all(model, guess, thd, cols, tol)
        if ok and np.max(np.abs(y - guess)) < 1e-3:
            J = model.jacobian(*_split(model, y, thd))[:, :, cols]
            cond = np.linalg.cond(J)
            bad = np.flatnonzero(~np.isfinite(cond) | (cond > 1e10))
            if bad.size:
                _fail(model, y[bad[0]], thd[bad[0]], t[bad[0]], 0.0, toggle=True)
            return y
        log.debug("kinematics: batched Newton did not settle; marching through all %d instants", n)
        order = np.argsort(t, kind="stable")
        ys = np.empty((n, y0.size))
        ys[order] = _march(model, t[order], y0, tol)
        return ys

    def at(self, times) -> Motion:
        """Motion at instants ``times`` [s] in ``[0, T]`` (``T`` is the reference again).

        Parameters
        ----------
        times : array_like of float, shape (n,)

        Returns
        -------
        Motion
        """
        period = self.period
        try:
            t = np.asarray(times, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"kinematics: times must be an array of instants [s], got {times!r:.80}") from None
        if t.size > MAX_NODES:
            raise InputError(f"kinematics: at most {MAX_NODES} instants, got {t.size}")
        if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)) \
                or t.min() < 0.0 or t.max() > period * (1 + 1e-12):
            raise InputError(f"kinematics: times must be a non-empty 1-D array of instants in "
                             f"[0, {period:.6g}] s (one cycle), got {np.asarray(times)!r:.80}")
        end = t >= period
        y = self.positions(np.where(end, 0.0, t))
        y[end] = self.yc[-1]  # the end of the cycle (angles continued, not wrapped)
        crank = self.model.drive_angles(t)[:, 0]
        return _motion(self.model, t, crank, y, period)


def _unknown_rates(model, theta, s, cols):
    """Rates (n, n_unknowns) of the unknown coordinates at configurations ``theta``, ``s`` (n, ...)."""
    omega, sd, _al, _sdd = _rates(model, theta, s, np.broadcast_to(
        model.drive_speed, (theta.shape[0], model.drive_idx.size)), cols)
    return np.concatenate([omega[:, model.free_members], sd], axis=1)


def _hermite(tk, yk, ydk, k, t):
    """Cubic Hermite interpolant (n, n_unknowns) at instants ``t`` (n,) of positions ``yk`` and
    rates ``ydk`` on the equally spaced instants ``tk``, ``t`` in the interval ``k`` (n,)."""
    h = tk[1] - tk[0]
    u = ((t - tk[k]) / h)[:, None]
    return ((2 * u**3 - 3 * u**2 + 1) * yk[k] + (u**3 - 2 * u**2 + u) * h * ydk[k]
            + (-2 * u**3 + 3 * u**2) * yk[k + 1] + (u**3 - u**2) * h * ydk[k + 1])


def _newton_all(model, y, thd, cols, tol, max_iter: int = 8):
    """Newton's method on the loop equations at all instants at once from ``y`` (n, n_unknowns).

    Returns the positions and whether every residual met ``tol`` (False also when a Jacobian
    is singular).
    """
    for _ in range(max_iter):
        theta, s = _split(model, y, thd)
        w = model.edge_vectors(theta, s)
        res = model.residual(theta, s, w)
        if np.max(np.abs(res)) <= tol:
            return y, True
        J = model.jacobian(theta, s, w)[:, :, cols]
        try:
            y = y + np.linalg.solve(J, -res[..., None])[..., 0]
        except np.linalg.LinAlgError:
            return y, False
    return y, False


def _closes(model, y0, yT) -> bool:
    """The positions ``yT`` after a cycle are the reference ``y0`` (free angles up to whole turns)."""
    nfree = model.free_members.size
    wrap = yT.copy()
    wrap[:nfree] = y0[:nfree] + np.round((yT[:nfree] - y0[:nfree]) / (2 * math.pi)) * 2 * math.pi
    return bool(np.max(np.abs(yT - wrap), initial=0.0) <= 1e-8)


def _coarse_march(model, tc, y0, tol, cols, stride):
    """Positions (n_c + 1, n_unknowns) on the coarse grid ``tc`` (``tc[0] = 0`` at ``y0``).

    The continuation (:func:`_march`, with its step halving and its guards against toggles and
    branch jumps) goes through every ``stride``-th instant; the instants between are solved
    together by Newton's method from the cubic Hermite interpolant of the marched positions and
    their exact rates. Where that does not settle to the tolerance close to the interpolant
    (within the branch-jump guard of a continuation step), at a well-conditioned configuration,
    the continuation goes through every instant instead.
    """
    n_c = tc.size - 1

    def full():
        return np.vstack([y0[None], _march(model, tc[1:], y0, tol)])

    if stride <= 1 or not cols.size or n_c % stride:
        return full()
    tm = tc[::stride]
    try:  # longer steps near a toggle may jump branch (or fail) where the full march does not
        ym = np.vstack([y0[None], _march(model, tm[1:], y0, tol)])
    except KinematicsError:
        return full()
    ydm = _unknown_rates(model, *_split(model, ym, model.drive_angles(tm)), cols)
    # the instants between: cubic Hermite guesses from the marched interval they are in
    j = np.arange(1, n_c)
    j = j[j % stride != 0]
    k = j // stride
    guess = _hermite(tm, ym, ydm, k, tc[j])
    thd = model.drive_angles(tc[j])
    y, ok = _newton_all(model, guess, thd, cols, tol)
    yc = np.empty((n_c + 1, y0.size))
    yc[::stride] = ym
    if ok:
        yc[j] = y
        nf = model.free_members.size
        step = np.max(np.abs(ym[k + 1, :nf] - ym[k, :nf]), axis=1, initial=0.0)
        jump = np.max(np.abs(y - guess), axis=1)
        J = model.jacobian(*_split(model, yc, model.drive_angles(tc)))[:, :, cols]
        cond = np.linalg.cond(J)
        # one assembly branch all through the cycle: the Jacobian's determinant keeps its sign
        # (the branches meet where it vanishes, at a toggle); a march that jumped branch near a
        # toggle and back at another closes the cycle with a wrong motion between
        sign = np.sign(np.linalg.det(J))
        ok = bool(np.all(jump <= 0.05 + 0.5 * step) and np.all(np.isfinite(cond)) and np.all(cond <= 1e10)
                  and np.all(sign == sign[0]) and sign[0] != 0 and _closes(model, y0, yc[-1]))
    if not ok:
        log.debug("kinematics: the coarse grid from the marched instants is not one settled branch; "
                  "marching through all of it")
        return full()
    return yc


def _march(model, targets_t, y0, tol, max_depth=8):
    """Continuation of the positions through the times ``targets_t``."""
    cols = model.unknown_columns()
    ys = np.empty((targets_t.size, y0.size))
    y = y0.copy()
    t_prev = 0.0
    yd_prev = None
    for k, t in enumerate(targets_t):
        y, t_prev, yd_prev = _advance(model, y, t_prev, t, yd_prev, cols, tol, max_depth)
        ys[k] = y
    return ys


def _advance(model, y, t0, t1, yd0, cols, tol, max_depth):
    """Advance the solution from t0 to t1 with a Taylor predictor and step halving."""
    if t1 == t0:
        thd = model.drive_angles(np.array(t1))
        y2, ok, res, J = _newton(model, y, thd, cols, tol)
        if not ok:
            _fail(model, y, thd, t1, res)
        return y2, t1, yd0
    stack = [(t0, t1, 0)]
    cur_t, cur_y = t0, y
    while stack:
        a, b, depth = stack.pop()
        thd = model.drive_angles(np.array(b))
        pred = cur_y
        if model.drive_idx.size and cols.size:
            theta, s = _split(model, cur_y, model.drive_angles(np.array(a)))
            omega, sd, alpha, sdd = _rates(model, theta[None], s[None], model.drive_speed[None], cols)
            vel = np.concatenate([omega[0, model.free_members], sd[0]])
            acc = np.concatenate([alpha[0, model.free_members], sdd[0]])
            h = b - a
            pred = cur_y + vel * h + 0.5 * acc * h * h
        y2, ok, res, J = _newton(model, pred, thd, cols, tol)
        if ok:
            # guard against branch jumps: the correction must be small against the step
            step = np.max(np.abs(y2[: model.free_members.size] - cur_y[: model.free_members.size]),
                          initial=0.0)
            jump = np.max(np.abs(y2 - pred), initial=0.0)
            if jump > 0.05 + 0.5 * step and depth < max_depth:
                ok = False
        if ok:
            cond = np.linalg.cond(J) if J is not None and J.size else 1.0
            if not np.isfinite(cond) or cond > 1e10:
                ok = False
                if depth >= max_depth:
                    _fail(model, y2, thd, b, res, toggle=True)
        if ok:
            cur_t, cur_y = b, y2
            continue
        if depth >= max_depth:
            _fail(model, cur_y, thd, b, res)
        mid = 0.5 * (a + b)
        stack.append((mid, b, depth + 1))
        stack.append((a, mid, depth + 1))
    return cur_y, cur_t, None


def _fail(model, y, thd, t, res, toggle=False):
    theta, s = _split(model, y, thd)
    r = model.residual(theta, s)
    nc = len(model.chords)
    worst = ""
    if nc:
        per_loop = np.abs(r[: 2 * nc]).reshape(nc, 2).max(axis=1)
        worst = model.loop_names[int(np.argmax(per_loop))]
    crank = None
    if model.drive_idx.size:
        crank = math.degrees(float(model.drive_angles(np.array(t))[0]))
    where = f" at crank angle {crank:.3f} deg" if crank is not None else ""
    what = ("reaches a toggle (dead-centre or limit) position" if toggle
            else "cannot be assembled")
    raise KinematicsError(
        f"{model.mech.name}: the linkage {what}{where}: loop {worst or '(none)'} does not close "
        f"(residual {res:.3g} m); a crank of a non-Grashof linkage cannot rotate fully, "
        "and a linkage through a toggle position has no unique motion")


def _check_reference(model, tol):
    """Positions of the reference configuration must satisfy the loops."""
    theta = model.theta0.copy()
    s = np.zeros(len(model.slider_names))
    res = model.residual(theta, s)
    scale = model.scale()
    bad = np.flatnonzero(np.abs(res) > 1e-9 * scale)
    if bad.size:
        nc = len(model.chords)
        i = int(bad[0])
        if i < 2 * nc:
            where = f"loop {model.loop_names[i // 2]}"
        else:
            where = model.welds[i - 2 * nc][3]
        raise KinematicsError(f"{model.mech.name}: the reference configuration (the at= positions) "
                              f"does not close {where} (residual {abs(res[i]):.3g})")
    J = model.jacobian(theta, s)[:, model.unknown_columns()]
    if J.size:
        sv = np.linalg.svd(J, compute_uv=False)
        if sv[-1] < 1e-10 * max(sv[0], 1.0):
            raise MobilityError(f"{model.mech.name}: the loop equations are singular in the reference "
                                "configuration (a redundant constraint, a free member, or a toggle position)")


def _motion(model: _LoopModel, t, crank, y, period):
    th_drive = model.drive_angles(t)
    theta, s = _split(model, y, th_drive)
    cols = model.unknown_columns()
    n = t.size
    if cols.size:
        omega, sd, alpha, sdd = _rates(model, theta, s, np.broadcast_to(model.drive_speed, (n, model.drive_idx.size)), cols)
    else:
        omega = np.zeros_like(theta)
        omega[:, model.drive_idx] = model.drive_speed
        alpha = np.zeros_like(theta)
        sd = sdd = np.zeros_like(s)
    res = model.residual(theta, s)
    resid = float(np.max(np.abs(res))) if res.size else 0.0
    model.check_slots(s, crank)
    r, v, a = _joint_states(model, theta, s, omega, sd, alpha, sdd)
    names, theta, omega, alpha, ref = _with_passive(model, r, v, a, theta, omega, alpha)
    return Motion(model.mech.name, t, crank, period, model.joint_names, names,
                  model.slider_names, r, v, a, theta, omega, alpha, s, sd, sdd, resid, ref)


def _with_passive(model, r, v, a, theta, omega, alpha):
    """Append the chord angle, its rate and acceleration of every passive link."""
    if not model.passive:
        return model.member_names, theta, omega, alpha, model.theta0.copy()
    th, om, al, ref = [], [], [], []
    for name in model.passive:
        lk = model.mech.links[name]
        ia, ib = model.jindex[lk.a], model.jindex[lk.b]
        d, dd, ddd = r[:, ib] - r[:, ia], v[:, ib] - v[:, ia], a[:, ib] - a[:, ia]
        n2 = np.einsum("nd,nd->n", d, d)
        cross1 = d[:, 0] * dd[:, 1] - d[:, 1] * dd[:, 0]
        cross2 = d[:, 0] * ddd[:, 1] - d[:, 1] * ddd[:, 0]
        dot1 = np.einsum("nd,nd->n", d, dd)
        th.append(np.arctan2(d[:, 1], d[:, 0]))
        om.append(cross1 / n2)
        al.append(cross2 / n2 - 2.0 * dot1 * cross1 / n2**2)
        pa, pb = np.array(model.mech.joints[lk.a].at), np.array(model.mech.joints[lk.b].at)
        ref.append(math.atan2(pb[1] - pa[1], pb[0] - pa[0]))
    cat = lambda x, y: np.concatenate([x, np.stack(y, axis=1)], axis=1)  # noqa: E731
    return (model.member_names + model.passive, cat(theta, th), cat(omega, om), cat(alpha, al),
            np.concatenate([model.theta0, ref]))


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


def kinematics(mechanism: Mechanism, steps: int = 360, *, times=None) -> Motion:
    """Rigid-body motion over one cycle of the first drive.

    Parameters
    ----------
    mechanism : Mechanism
        A single-degree-of-freedom linkage (one drive, or several
        synchronised drives matching its mobility).
    steps : int
        Number of time nodes ``n`` (>= 3); ``t_k = k T / n``, ``k = 0..n-1``.
    times : array_like of float, shape (n,), optional
        Instead of ``steps``: any instants of the cycle [s], in ``[0, T]``
        (the collocation instants of a time discretisation, a fine output
        grid); ``T`` itself is the reference configuration again. For many
        calls on one mechanism build a :class:`Cycle` once.

    Returns
    -------
    Motion
        Positions, velocities and accelerations of all joints and members.

    Raises
    ------
    MobilityError
        The mobility does not match the drives.
    KinematicsError
        The linkage cannot complete the cycle (names the loop and crank angle).
    """
    if times is None:
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 3 <= steps <= MAX_NODES:
            raise InputError(f"kinematics: steps must be an integer in 3 .. {MAX_NODES}, got {steps!r}")
    cyc = Cycle(mechanism)
    if times is None:
        times = np.arange(steps) * (cyc.period / steps)
    mo = cyc.at(times)
    log.debug("kinematics of %s: %d instants, residual %.3g m", mechanism.name, mo.n, mo.residual)
    return mo


def kinematics_at(mechanism: Mechanism, crank_angle: float) -> Motion:
    """Rigid-body state at one crank angle (continuation from the reference).

    Parameters
    ----------
    mechanism : Mechanism
        A driven linkage.
    crank_angle : float
        Absolute angle of the first driven member [rad]; the branch is the
        one reached by turning the crank from the reference configuration in
        its direction of rotation.

    Returns
    -------
    Motion
        With a single time node.
    """
    model = _LoopModel(mechanism)
    crank_angle = real("kinematics_at", "crank_angle [rad]", crank_angle)
    if not mechanism.drives:
        return static_motion(mechanism)
    model.check_mobility()
    tol = 1e-14 * model.scale()
    _check_reference(model, tol)
    w = mechanism.drives[0].speed
    if w == 0.0:
        raise InputError(f"{mechanism.name}: the first drive's speed is zero")
    period = mechanism.period
    dth = (float(crank_angle) - model.theta0[model.drive_idx[0]]) * np.sign(w)
    dth = dth % (2 * math.pi)
    t_target = dth / abs(w)
    n_sub = max(1, int(math.ceil(dth / math.radians(5.0))))
    ts = np.linspace(0.0, t_target, n_sub + 1)[1:]
    y0 = np.concatenate([model.theta0[model.free_members], np.zeros(len(model.slider_names))])
    y = _march(model, ts, y0, tol)[-1:] if ts.size else y0[None]
    t = np.array([t_target])
    crank = model.drive_angles(t)[:, 0]
    return _motion(model, t, crank, y, period)


def static_motion(mechanism: Mechanism) -> Motion:
    """The reference configuration at rest (a structure, or a linkage stopped).

    Returns
    -------
    Motion
        One time node, all velocities and accelerations zero.
    """
    model = _LoopModel(mechanism)
    theta = model.theta0[None].copy()
    s = np.zeros((1, len(model.slider_names)))
    z = np.zeros_like(theta)
    zs = np.zeros_like(s)
    r = np.array([[mechanism.joints[j].at for j in model.joint_names]])
    zero = np.zeros_like(r)
    crank = theta[:, model.drive_idx[0]] if model.drive_idx.size else np.zeros(1)
    names, theta, z, z2, ref = _with_passive(model, r, zero, zero, theta, z, z.copy())
    return Motion(mechanism.name, np.zeros(1), crank, math.inf, model.joint_names, names,
                  model.slider_names, r, zero, zero.copy(), theta, z, z2, s, zs, zs.copy(), 0.0, ref)
