"""The loop-closure model of a mechanism (:class:`_LoopModel`), internal to the motion wing.

Every member (link or rigid body) has one unknown angle and every slider one travel along its
line. The joint graph (joints plus the frame) is spanned by a tree grown from the frame; each chord
closes one loop and gives two closure equations, welded joints, clamped ground joints and locked
sliders add angle equations, and drives prescribe the angles of the driven members. The model
evaluates the edge vectors, the residuals and their Jacobian at any configurations (many instants
at once); :mod:`kedfem.motion.kinematics` solves the equations, :mod:`kedfem.motion.rates` the
velocity and acceleration equations.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError, KinematicsError, MobilityError
from ..model.mechanism import GROUND, Mechanism, require_mechanism
from .record import _rot

__all__: list[str] = []  # the motion wing's internals (kinematics and rates import them)


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
