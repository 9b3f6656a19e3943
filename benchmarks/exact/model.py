"""Assembled multibody model: ANCF cable links, rigid bodies, joints as constraints.

Coordinates ``q``:

* every joint of the mechanism has a *joint point* (2 DOFs, its position);
  the end nodes of the flexible links meeting there share it (a revolute
  joint: each link keeps its own slope vector, so the rotations are free);
* every flexible link has nodes ``0..ne``; the end nodes add their slope
  vectors (2 DOFs each), interior nodes their position and slope (4 DOFs);
* every rigid body (and rigid link) has ``(X, Y, phi)``: the centre of mass
  and the rotation from the reference configuration.

Constraints ``g(q, t) = 0`` (Lagrange multipliers):

* ``Fixed``: a joint point on the frame (ground pivot);
* ``Slider``: a joint point on a fixed line (one equation);
* ``SlopeDrive``: a link end's slope parallel to ``(cos th, sin th)``,
  ``th = th0 + w t`` (a link clamped to its drive, or to the frame with w = 0):
  ``-sin(th) x' + cos(th) y' = 0``; the slope's magnitude stays free;
* ``BodyPin``: a joint point fixed to a rigid body,
  ``p - X - R(phi) d = 0``;
* ``BodyAngle``: a driven body, ``phi - w t = 0``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .ancf import ElementSet, hermite

__all__ = ["Builder", "Model", "FlexLink", "State", "Fixed", "Slider", "SlopeDrive", "BodyPin",
           "BodyAngle", "from_mechanism"]

_S = np.array([[0.0, -1.0], [1.0, 0.0]])


def _rot(phi):
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[c, -s], [s, c]])


# ------------------------------------------------------------------ constraints
class Constraint:
    """Base: ``rows`` equations on DOFs ``cols`` (a fixed sparsity pattern)."""

    rows = 0
    linear = True

    def pattern(self):
        """(local row, global col) pairs of the Jacobian's non-zeros."""
        raise NotImplementedError

    def eval(self, q, t):
        """``g`` (rows,) and the Jacobian values in :meth:`pattern` order."""
        raise NotImplementedError

    def hessian(self, q, t, lam):
        """``d(G^T lam)/dq`` entries: (rows, cols, vals) global; empty for linear ones."""
        return (), (), ()


@dataclass
class Fixed(Constraint):
    dofs: np.ndarray
    values: np.ndarray

    @property
    def rows(self):
        return len(self.dofs)

    def pattern(self):
        return [(i, int(d)) for i, d in enumerate(self.dofs)]

    def eval(self, q, t):
        return q[self.dofs] - self.values, np.ones(len(self.dofs))


@dataclass
class Slider(Constraint):
    dofs: np.ndarray          # joint point (x, y)
    point: np.ndarray
    axis: np.ndarray
    rows = 1

    def pattern(self):
        return [(0, int(self.dofs[0])), (0, int(self.dofs[1]))]

    def eval(self, q, t):
        nrm = np.array([-self.axis[1], self.axis[0]])
        return np.array([nrm @ (q[self.dofs] - self.point)]), nrm.copy()


@dataclass
class SlopeDrive(Constraint):
    dofs: np.ndarray          # slope (x', y')
    th0: float
    w: float
    rows = 1

    def pattern(self):
        return [(0, int(self.dofs[0])), (0, int(self.dofs[1]))]

    def eval(self, q, t):
        th = self.th0 + self.w * t
        vals = np.array([-math.sin(th), math.cos(th)])
        return np.array([vals @ q[self.dofs]]), vals


@dataclass
class BodyPin(Constraint):
    point: np.ndarray         # joint point dofs (2)
    body: np.ndarray          # body dofs (X, Y, phi)
    d: np.ndarray             # cm -> joint in the reference configuration
    rows = 2
    linear = False

    def pattern(self):
        p, b = self.point, self.body
        return [(0, int(p[0])), (1, int(p[1])), (0, int(b[0])), (1, int(b[1])), (0, int(b[2])), (1, int(b[2]))]

    def eval(self, q, t):
        X = q[self.body[:2]]
        R = _rot(q[self.body[2]])
        Rd = R @ self.d
        g = q[self.point] - X - Rd
        dphi = -(_S @ Rd)
        return g, np.array([1.0, 1.0, -1.0, -1.0, dphi[0], dphi[1]])

    def hessian(self, q, t, lam):
        Rd = _rot(q[self.body[2]]) @ self.d
        i = int(self.body[2])
        return (i,), (i,), (float(lam @ Rd),)


@dataclass
class BodyAngle(Constraint):
    dof: int
    w: float
    rows = 1

    def pattern(self):
        return [(0, int(self.dof))]

    def eval(self, q, t):
        return np.array([q[self.dof] - self.w * t]), np.ones(1)


# ---------------------------------------------------------------------- parts
@dataclass
class FlexLink:
    """A flexible link meshed into ANCF elements."""

    name: str
    a: str
    b: str
    length: float
    n_el: int
    EA: float
    EI: float
    rhoA: float
    nodes: np.ndarray = None  # (n_el + 1, 4) global DOFs (x, y, x', y') of each node
    elements: np.ndarray = None  # indices into the model's element set
    inner: dict = field(default_factory=dict)  # interior node -> joint pinned there (shares its point)

    @property
    def s_nodes(self):
        return np.linspace(0.0, self.length, self.n_el + 1)


@dataclass
class RigidBody:
    name: str
    mass: float
    J: float
    cm: np.ndarray
    dofs: np.ndarray = None
    attach: dict = field(default_factory=dict)   # joint -> d (cm -> joint, reference)


@dataclass
class State:
    """Generalised-alpha state: q, q_dot, q_ddot (true), a (algorithmic), multipliers."""

    t: float
    q: np.ndarray
    v: np.ndarray
    vd: np.ndarray
    a: np.ndarray
    lam: np.ndarray
    prev: tuple | None = None      # (q_dd, lam) of the step before (predictor only)

    def copy(self):
        return State(self.t, self.q.copy(), self.v.copy(), self.vd.copy(), self.a.copy(), self.lam.copy())


class Builder:
    """Collect joint points, flexible links, bodies and constraints, then :meth:`build`."""

    def __init__(self):
        self.points: dict[str, np.ndarray] = {}       # joint -> reference position
        self.point_mass: dict[str, float] = {}
        self.links: dict[str, FlexLink] = {}
        self.bodies: dict[str, RigidBody] = {}
        self.cons_spec: list = []

    def point(self, name, at, mass=0.0):
        self.points[name] = np.asarray(at, float)
        self.point_mass[name] = self.point_mass.get(name, 0.0) + float(mass)

    def add_mass(self, name, mass):
        self.point_mass[name] += float(mass)

    def flexible(self, name, a, b, n_el, EA, EI, rhoA, inner=None):
        """A flexible link of ``n_el`` equal elements; ``inner`` {node: joint}: interior nodes that
        are joint points (a pin inside the link: the node's position is the joint's)."""
        L = float(np.hypot(*(self.points[b] - self.points[a])))
        self.links[name] = FlexLink(name, a, b, L, int(n_el), float(EA), float(EI), float(rhoA),
                                    inner=dict(inner or {}))

    def force(self, joint, F):
        """A constant force [N] on a joint point."""
        self.cons_spec.append(("force", joint, np.asarray(F, float)))

    def body(self, name, mass, J, cm, joints):
        cm = np.asarray(cm, float)
        self.bodies[name] = RigidBody(name, float(mass), float(J), cm,
                                      attach={j: self.points[j] - cm for j in joints})

    def fix(self, joint, at=None):
        self.cons_spec.append(("fix", joint, at))

    def slider(self, joint, axis):
        self.cons_spec.append(("slider", joint, np.asarray(axis, float)))

    def slope(self, link, end, th0, w=0.0):
        self.cons_spec.append(("slope", link, end, float(th0), float(w)))

    def body_angle(self, body, w):
        self.cons_spec.append(("angle", body, float(w)))

    def build(self, *, beta=0.0, alpha=0.0, gravity=None, ngauss=5) -> "Model":
        return Model(self, beta=beta, alpha=alpha, gravity=gravity, ngauss=ngauss)


class Model:
    """The assembled model (see the module docstring)."""

    def __init__(self, b: Builder, *, beta=0.0, alpha=0.0, gravity=None, ngauss=5):
        self.beta = float(beta)
        self.alpha = float(alpha)
        self.ngauss = int(ngauss)
        self.points = dict(b.points)
        n = 0
        self.pdofs = {}
        for j in b.points:
            self.pdofs[j] = np.array([n, n + 1])
            n += 2
        self.links = {}
        el_L, el_EA, el_EI, el_rhoA, edofs = [], [], [], [], []
        for name, lk0 in b.links.items():
            lk = FlexLink(lk0.name, lk0.a, lk0.b, lk0.length, lk0.n_el, lk0.EA, lk0.EI, lk0.rhoA,
                          inner=dict(lk0.inner))
            nodes = np.zeros((lk.n_el + 1, 4), dtype=int)
            for k in range(lk.n_el + 1):
                if k == 0:
                    nodes[k, :2] = self.pdofs[lk.a]
                    nodes[k, 2:] = [n, n + 1]
                    n += 2
                elif k == lk.n_el:
                    nodes[k, :2] = self.pdofs[lk.b]
                    nodes[k, 2:] = [n, n + 1]
                    n += 2
                elif k in lk.inner:  # a pin inside the link: the joint's point, the link's own slope
                    nodes[k, :2] = self.pdofs[lk.inner[k]]
                    nodes[k, 2:] = [n, n + 1]
                    n += 2
                else:
                    nodes[k] = np.arange(n, n + 4)
                    n += 4
            lk.nodes = nodes
            e0 = len(el_L)
            Le = lk.length / lk.n_el
            for k in range(lk.n_el):
                el_L.append(Le)
                el_EA.append(lk.EA)
                el_EI.append(lk.EI)
                el_rhoA.append(lk.rhoA)
                edofs.append(np.concatenate([nodes[k], nodes[k + 1]]))
            lk.elements = np.arange(e0, len(el_L))
            self.links[name] = lk
        self.bodies = {}
        for name, bd0 in b.bodies.items():
            bd = RigidBody(bd0.name, bd0.mass, bd0.J, bd0.cm, np.array([n, n + 1, n + 2]), dict(bd0.attach))
            n += 3
            self.bodies[name] = bd
        self.ndof = n
        self.els = ElementSet(np.array(el_L), np.array(el_EA), np.array(el_EI), np.array(el_rhoA),
                              beta=self.beta, ngauss=ngauss) if el_L else None
        self.edofs = np.array(edofs, dtype=int).reshape(-1, 8)
        self._edofs_flat = self.edofs.ravel()
        # ---- constraints
        cons = []
        for spec in b.cons_spec:
            kind = spec[0]
            if kind == "fix":
                at = self.points[spec[1]] if spec[2] is None else np.asarray(spec[2], float)
                cons.append(Fixed(self.pdofs[spec[1]], at.copy()))
            elif kind == "slider":
                cons.append(Slider(self.pdofs[spec[1]], self.points[spec[1]].copy(), spec[2]))
            elif kind == "slope":
                lk = self.links[spec[1]]
                node = lk.nodes[0] if spec[2] == "a" else lk.nodes[-1]
                cons.append(SlopeDrive(node[2:].copy(), spec[3], spec[4]))
            elif kind == "angle":
                cons.append(BodyAngle(int(self.bodies[spec[1]].dofs[2]), spec[2]))
            elif kind == "force":
                pass  # an external force (below)
        for bd in self.bodies.values():
            for j, d in bd.attach.items():
                cons.append(BodyPin(self.pdofs[j], bd.dofs, d.copy()))
        self.constraints = cons
        self.ncon = sum(c.rows for c in cons)
        self._con_pattern()
        # ---- mass matrix (constant)
        rows, cols, vals = [], [], []
        if self.els is not None:
            rows.append(np.repeat(self.edofs, 8, axis=1).ravel())
            cols.append(np.tile(self.edofs, (1, 8)).ravel())
            vals.append(self.els.M.ravel())
        diag = np.zeros(n)
        for j, m in b.point_mass.items():
            diag[self.pdofs[j]] += m
        for bd in self.bodies.values():
            diag[bd.dofs] += [bd.mass, bd.mass, bd.J]
        rows.append(np.arange(n))
        cols.append(np.arange(n))
        vals.append(diag)
        self.M = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
        self.mdiag = diag
        # ---- gravity
        self.f_ext = np.zeros(n)
        if gravity is not None:
            pattern = np.zeros(n)
            gv = np.asarray(gravity, float)
            for dofs in self.pdofs.values():
                pattern[dofs] = gv
            for lk in self.links.values():
                pattern[lk.nodes[1:-1, :2]] = gv  # (an inner joint's point: once, as a joint point)
            for bd in self.bodies.values():
                pattern[bd.dofs[:2]] = gv
            self.f_ext = self.M @ pattern
        for spec in b.cons_spec:
            if spec[0] == "force":
                self.f_ext[self.pdofs[spec[1]]] += spec[2]
        self._jac_pattern()

    # ------------------------------------------------------------ constraints
    def _con_pattern(self):
        r, c = [], []
        off = 0
        self.con_offsets = []
        for con in self.constraints:
            self.con_offsets.append(off)
            for (i, col) in con.pattern():
                r.append(off + i)
                c.append(col)
            off += con.rows
        self.G_rows = np.array(r, dtype=int)
        self.G_cols = np.array(c, dtype=int)

    def constraints_eval(self, q, t):
        """``g`` (ncon,) and the Jacobian values (in ``G_rows, G_cols`` order)."""
        g = np.empty(self.ncon)
        vals = []
        for off, con in zip(self.con_offsets, self.constraints):
            gi, vi = con.eval(q, t)
            g[off:off + con.rows] = gi
            vals.append(vi)
        return g, (np.concatenate(vals) if vals else np.zeros(0))

    def constraint_hessian(self, q, t, lam):
        r, c, v = [], [], []
        for off, con in zip(self.con_offsets, self.constraints):
            if con.linear:
                continue
            ri, ci, vi = con.hessian(q, t, lam[off:off + con.rows])
            r.extend(ri)
            c.extend(ci)
            v.extend(vi)
        return r, c, v

    def G(self, q, t):
        """Constraint Jacobian (sparse, ncon x ndof)."""
        _, vals = self.constraints_eval(q, t)
        return sp.csr_matrix((vals, (self.G_rows, self.G_cols)), shape=(self.ncon, self.ndof))

    # ------------------------------------------------------------- iteration
    def _jac_pattern(self):
        """Fixed pattern of the (ndof + ncon) saddle-point matrix and its CSC map."""
        n, m = self.ndof, self.ncon
        rows, cols = [], []
        if self.els is not None:
            rows.append(np.repeat(self.edofs, 8, axis=1).ravel())
            cols.append(np.tile(self.edofs, (1, 8)).ravel())
        rows.append(np.arange(n))
        cols.append(np.arange(n))
        rows.append(n + self.G_rows)
        cols.append(self.G_cols)
        rows.append(self.G_cols)
        cols.append(n + self.G_rows)
        r = np.concatenate(rows)
        c = np.concatenate(cols)
        N = n + m
        key = c.astype(np.int64) * N + r
        uniq, inv = np.unique(key, return_inverse=True)
        self._N = N
        self._inv = inv
        self._nnz = uniq.size
        self._indices = (uniq % N).astype(np.int32)
        self._indptr = np.searchsorted(uniq // N, np.arange(N + 1)).astype(np.int32)
        self._n_el_entries = self.edofs.shape[0] * 64 if self.els is not None else 0

    def saddle(self, el_block, diag, Gvals, sigma):
        """CSC saddle-point matrix ``[[A, sigma G^T], [sigma G, 0]]`` from its parts."""
        data = np.concatenate([el_block.ravel(), diag, sigma * Gvals, sigma * Gvals])
        vals = np.bincount(self._inv, weights=data, minlength=self._nnz)
        return sp.csc_matrix((vals, self._indices, self._indptr), shape=(self._N, self._N))

    def element_coords(self, q):
        return q[self.edofs]

    def internal(self, q, v, *, tangent=True):
        """Global internal force ``Q(q, v)`` and element blocks of ``dQ/dq``, ``dQ/dv``."""
        Q = np.zeros(self.ndof)
        if self.els is None:
            return Q, None, None
        E = q[self.edofs]
        Ed = v[self.edofs] if self.beta != 0.0 else None
        Qe, Ke, Ce = self.els.forces(E, Ed, tangent=tangent)
        Q = np.bincount(self._edofs_flat, weights=Qe.ravel(), minlength=self.ndof)
        return Q, Ke, Ce

    # ------------------------------------------------------------- readouts
    def link_field(self, q, link, s, deriv=0):
        """Position (deriv=0) or slope (deriv=1) of ``link`` at arc lengths ``s``.

        ``q`` may be (ndof,) or (nt, ndof); returns (..., len(s), 2).
        """
        shapes, qq = self._element_fields(q, link, s)
        return np.einsum("sk,...skj->...sj", shapes[deriv][0], qq)

    def _element_fields(self, q, link, s):
        """Hermite shapes (N, N', N'') at arc lengths ``s`` and the element coordinates (..., len(s), 4, 2)."""
        lk = self.links[link]
        s = np.atleast_1d(np.asarray(s, float))
        Le = lk.length / lk.n_el
        e = np.clip((s // Le).astype(int), 0, lk.n_el - 1)
        shapes = hermite(s / Le - e, [Le])
        dofs = np.stack([lk.nodes[e], lk.nodes[e + 1]], 1).reshape(len(s), 8)  # (len(s), 8)
        return shapes, np.asarray(q)[..., dofs].reshape(q.shape[:-1] + (len(s), 4, 2))

    def link_strain(self, q, link, s):
        """Axial strain and curvature at arc lengths ``s`` (q of shape (nt, ndof))."""
        (_, N1, N2), qq = self._element_fields(q, link, s)
        a = np.einsum("sk,...skj->...sj", N1[0], qq)
        bb = np.einsum("sk,...skj->...sj", N2[0], qq)
        n = np.hypot(a[..., 0], a[..., 1])
        c = a[..., 0] * bb[..., 1] - a[..., 1] * bb[..., 0]
        return n - 1.0, c / n**3

    def chord_deflection(self, q, link, xi=0.5):
        """Signed distance of the material point at ``xi L`` from the chord (+ left of a -> b)."""
        lk = self.links[link]
        ra = q[..., self.pdofs[lk.a]]
        rb = q[..., self.pdofs[lk.b]]
        rm = self.link_field(q, link, [xi * lk.length])[..., 0, :]
        d = rb - ra
        w = rm - ra
        return (d[..., 0] * w[..., 1] - d[..., 1] * w[..., 0]) / np.hypot(d[..., 0], d[..., 1])

    def energy(self, q):
        return float(np.sum(self.els.energy(q[self.edofs]))) if self.els is not None else 0.0

    # ---------------------------------------------------------- rigid states
    def rigid_state(self, r, v, a, omega, alpha, theta_of, t=0.0, body_phi=None, body_w=None,
                    body_al=None):
        """State of the undeformed mechanism moving rigidly.

        Parameters
        ----------
        r, v, a : dict joint -> (2,)
            Joint positions, velocities, accelerations.
        omega, alpha : dict member -> float
            Angular velocities and accelerations of links and bodies.
        theta_of : dict link -> float
            Link angles (a -> b).
        body_phi : dict body -> float
            Body rotations from the reference.
        """
        n = self.ndof
        q, qd, qdd = np.zeros(n), np.zeros(n), np.zeros(n)
        for j, dofs in self.pdofs.items():
            q[dofs], qd[dofs], qdd[dofs] = r[j], v[j], a[j]
        for name, lk in self.links.items():
            th = theta_of[name]
            e = np.array([math.cos(th), math.sin(th)])
            en = _S @ e
            w, al = omega[name], alpha[name]
            s = lk.s_nodes
            ra, va, aa = r[lk.a], v[lk.a], a[lk.a]
            for k, sk in enumerate(s):
                d = lk.nodes[k]
                if 0 < k < lk.n_el:
                    q[d[:2]] = ra + sk * e
                    qd[d[:2]] = va + w * sk * en
                    qdd[d[:2]] = aa + al * sk * en - w * w * sk * e
                q[d[2:]] = e
                qd[d[2:]] = w * en
                qdd[d[2:]] = al * en - w * w * e
        for name, bd in self.bodies.items():
            phi = body_phi[name]
            w, al = body_w[name], body_al[name]
            j0, d0 = next(iter(bd.attach.items()))
            R = _rot(phi)
            rho = -(R @ d0)                       # joint -> cm
            q[bd.dofs[:2]] = r[j0] + rho
            q[bd.dofs[2]] = phi
            qd[bd.dofs[:2]] = v[j0] + w * (_S @ rho)
            qd[bd.dofs[2]] = w
            qdd[bd.dofs[:2]] = a[j0] + al * (_S @ rho) - w * w * rho
            qdd[bd.dofs[2]] = al
        return State(t, q, qd, qdd, qdd.copy(), np.zeros(self.ncon))

    def reference_q(self):
        """Coordinates of the reference configuration (straight links, bodies unrotated)."""
        q = np.zeros(self.ndof)
        for j, dofs in self.pdofs.items():
            q[dofs] = self.points[j]
        for lk in self.links.values():
            ra, rb = self.points[lk.a], self.points[lk.b]
            e = (rb - ra) / lk.length
            for k, sk in enumerate(lk.s_nodes):
                if 0 < k < lk.n_el:
                    q[lk.nodes[k, :2]] = ra + sk * e
                q[lk.nodes[k, 2:]] = e
        for bd in self.bodies.values():
            q[bd.dofs[:2]] = bd.cm
        return q

    def map_state(self, st: State, other: "Model") -> State:
        """``st`` of ``other`` (same mechanism, another mesh) carried onto this model's mesh."""
        out = []
        for vec in (st.q, st.v, st.vd, st.a):
            x = np.zeros(self.ndof)
            for j, dofs in self.pdofs.items():
                x[dofs] = vec[other.pdofs[j]]
            for name, lk in self.links.items():
                s = lk.s_nodes
                pos = other.link_field(vec, name, s, 0)
                slope = other.link_field(vec, name, s, 1)
                x[lk.nodes[1:-1, :2]] = pos[1:-1]
                x[lk.nodes[:, 2:]] = slope
            for name, bd in self.bodies.items():
                x[bd.dofs] = vec[other.bodies[name].dofs]
            out.append(x)
        lam = st.lam.copy() if other.ncon == self.ncon else np.zeros(self.ncon)
        return State(st.t, *out, lam)


# ------------------------------------------------------------------ mechanism
def from_mechanism(mech, *, elements_per_link=None, beta=0.0, alpha=0.0, gravity=False, ngauss=5):
    """Build a :class:`Model` from a kedfem ``Mechanism``.

    Supported: revolute joints, ground pivots, sliders, point masses (no
    rotary inertia), flexible links (pin ends), rigid links and bodies, a
    driven flexible link (clamped to its drive at its ground pivot), a driven
    rigid link or body, clamped ground joints. Anything else raises
    ``NotImplementedError``.

    Returns
    -------
    model : Model
    info : dict
        ``drive`` (member, w, th0 of the driven member's a -> b line, ground
        joint), ``rigid_links`` (names modelled as bodies).
    """
    unsupported = [n for n in ("springs", "torsional_springs", "frictions") if getattr(mech, n)]
    if any(ld.profile is not None for ld in mech.loads.values()):
        unsupported.append("loads with a profile")
    if unsupported:
        raise NotImplementedError(f"exact model: {', '.join(unsupported)} are not supported")
    if len(mech.drives) != 1:
        raise NotImplementedError("exact model: exactly one drive is supported")
    drive = mech.drives[0]
    if drive.torsional_stiffness is not None:
        raise NotImplementedError("exact model: drive shafts with torsional stiffness are not supported")
    b = Builder()
    for j in mech.joints.values():
        if j.welded and not j.clamped:
            raise NotImplementedError(f"exact model: welded joint '{j.name}' is not supported")
        b.point(j.name, j.at)
    for pm in mech.point_masses:
        if pm.J != 0.0:
            raise NotImplementedError("exact model: point masses with rotary inertia are not supported")
        b.add_mass(pm.joint, pm.mass)
    rigid_links = []
    for lk in mech.links.values():
        if not lk.kinematic or lk.timoshenko or lk.mass_matrix != "consistent":
            raise NotImplementedError(f"exact model: link '{lk.name}' options are not supported")
        if lk.rigid:
            pa, pb = np.array(mech.joints[lk.a].at), np.array(mech.joints[lk.b].at)
            b.body(lk.name, lk.mass, lk.J, 0.5 * (pa + pb), (lk.a, lk.b))
            rigid_links.append(lk.name)
            continue
        n_el = lk.elements if elements_per_link is None else int(elements_per_link)
        inner = {}
        for t, x in zip(lk.through, lk.through_at):  # a pin inside: it must fall on a node
            k = int(round(x / lk.length * n_el))
            if abs(x - k * lk.length / n_el) > 1e-9 * lk.length:
                raise NotImplementedError(f"exact model: joint '{t}' inside link '{lk.name}' is not at a node "
                                          f"of {n_el} equal elements")
            inner[k] = t
        E, rho = lk.material.E, lk.material.rho
        b.flexible(lk.name, lk.a, lk.b, n_el, E * lk.section.A, E * lk.section.I, rho * lk.section.A, inner)
    for bd in mech.bodies.values():
        b.body(bd.name, bd.mass, bd.J, bd.cm, bd.joints)
    for j in mech.joints.values():
        if j.kind == "ground":
            b.fix(j.name)
        elif j.kind == "slider":
            b.slider(j.name, j.axis)
    # link ends clamped to the frame / to the drive
    pa = {n: np.array(mech.joints[lk.a].at) for n, lk in mech.links.items()}
    th_ref = {n: math.atan2(*(np.array(mech.joints[lk.b].at) - pa[n])[::-1]) for n, lk in mech.links.items()}
    for lk in mech.links.values():
        if lk.rigid:
            continue
        for end, jn in (("a", lk.a), ("b", lk.b)):
            j = mech.joints[jn]
            clamp = lk.ends[0 if end == "a" else 1] == "clamp"
            driven = drive.member == lk.name and drive.ground_joint == jn
            if driven:
                b.slope(lk.name, end, th_ref[lk.name], drive.speed)
            elif j.clamped or clamp:
                if j.kind != "ground":
                    raise NotImplementedError(f"exact model: clamped end of '{lk.name}' at a moving joint")
                b.slope(lk.name, end, th_ref[lk.name], 0.0)
    if drive.member in mech.bodies or drive.member in rigid_links:
        b.body_angle(drive.member, drive.speed)
    for ld in mech.loads.values():  # constant loads on joints
        b.force(ld.joint, ld.force)
    g = mech.gravity if gravity else None
    model = b.build(beta=beta, alpha=alpha, gravity=g, ngauss=ngauss)
    info = dict(drive=drive.member, w=drive.speed, ground=drive.ground_joint,
                th0=th_ref.get(drive.member, 0.0), rigid_links=rigid_links)
    return model, info
