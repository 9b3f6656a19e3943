"""Blocks on members: the constraint forms of a slot joint's translation and locked rotation.

A block ``B`` slides along a line fixed in a moving member ``M`` (a
prismatic pair between moving members, :meth:`kedfem.Mechanism.slider` with
``on=``). With ``u(t)`` the line's direction, ``n = S u`` its normal,
``xi(t)`` the block's abscissa on ``M`` and ``x_M(xi)`` the elastic
displacement of the material point of ``M`` under the block:

* slide free: ``x_B = u q_s + n (n^T x_M(xi))``; the block's own DOF
  ``q_s`` is its elastic travel along the line, its transverse displacement
  is the member's;
* slide locked (a pin on the member at any abscissa): ``x_B = x_M(xi)``;
* rotation locked (a piston in its cylinder): the elastic rotation of the
  members at ``B`` is the slope of ``M`` under the block.

For a rigid ``M``, ``x_M`` is the member's body point at ``B``; for a
flexible link it is the element under the block interpolated with the
element's own shape functions (linear axial, cubic Hermite transverse),
evaluated at the current abscissa. The forms therefore vary in time as the
block moves, and their time derivatives (the transport terms) include the
sliding rate: ``d/dt N(zeta) = N_zeta zeta'``. The contact force then moves
along the beam through ``E^T``, as a moving load does.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..model.elements import hermite
from ..motion.kinematics import slot_direction
from .forms import EntityForm

__all__ = ["slot_point_form", "slot_rotation_form", "block_abscissa", "element_at", "node_crossings"]

_S = np.array([[0.0, -1.0], [1.0, 0.0]])


def _chain(f, z1, z2):
    """Value and time derivatives of ``f(zeta(t))`` from ``f = (f, f_z, f_zz)``."""
    return f[0], f[1] * z1, f[2] * z1**2 + f[1] * z2


def _line(fe, joint, motion):
    """Direction ``u`` of the block's line with its time derivatives, each (nt, 2), and the abscissa."""
    mech = fe.mech
    jt = mech.joints[joint]
    _origin, d, ax = mech.slot_line(joint)
    nt = motion.n
    xi = np.zeros((3, nt))
    if jt.on in mech.links:
        lk = mech.links[jt.on]
        e1 = (np.array(mech.joints[lk.b].at) - np.array(mech.joints[lk.a].at)) / lk.length
        xi[0] = d @ e1
        if jt.slide == "free":
            k = motion.slider_names.index(joint)
            cos = float(ax @ e1)
            xi[0] = xi[0] + motion.s[:, k] * cos
            xi[1] = motion.sd[:, k] * cos
            xi[2] = motion.sdd[:, k] * cos
    return slot_direction(mech, motion, joint), xi


def block_abscissa(fe, joint: str, motion) -> np.ndarray:
    """Abscissa (nt,) [m] of a slot joint's block on its link, from the link's joint ``a``."""
    return _line(fe, joint, motion)[1][0]


def node_crossings(fe, cycle, period: float, samples: int = 2048) -> np.ndarray:
    """Instants [s] in ``(0, period)`` at which a sliding block crosses a node of its flexible link.

    Under the block the link's displacement is read with the shape functions of the element
    it is on; they change element at a node, where the interpolated curvature jumps, so the
    block's map has a kink in time there: its second time derivative jumps (a free block: the
    stiffness and load terms ``E^T M E''``), or its first (a locked rotation follows the slope,
    whose rate is the curvature). Time elements with these instants at their ends see smooth
    data and converge at the scheme's order (uniform ones converge at second order, or first
    with a locked rotation: the oscillating cylinder took 12288 elements at ``rtol`` 1e-3).

    Parameters
    ----------
    fe : FEModel
    cycle : kedfem.motion.kinematics.Cycle
    period : float
        [s].
    samples : int
        Instants of the search grid (a crossing between two of them is found; one that
        touches a node and turns back between them is not, and its kink is weaker).

    Returns
    -------
    ndarray, shape (k,)
        Sorted, to round-off (Newton on the abscissa from the grid's bracket).
    """
    mech = fe.mech
    blocks = [j for j in mech.joints.values()
              if j.kind == "slot" and j.slide == "free" and j.on in mech.links
              and not mech.links[j.on].rigid and mech.links[j.on].elements > 1]
    if not blocks:
        return np.zeros(0)
    t = np.arange(samples) * (period / samples)
    mo = cycle.at(t)
    lo, hi, which = [], [], []
    for jt in blocks:
        lk = mech.links[jt.on]
        x = block_abscissa(fe, jt.name, mo)
        nodes = (lk.length / lk.elements) * np.arange(1, lk.elements)
        f = np.append(x, x[0])[:, None] - nodes[None, :]  # (samples + 1, nodes), periodic
        i, k = np.nonzero(np.sign(f[:-1]) * np.sign(f[1:]) < 0)
        lo.append(t[i])
        hi.append(np.append(t, period)[i + 1])
        which += [(jt.name, float(nodes[j])) for j in k]
    a, b = np.concatenate(lo), np.concatenate(hi)
    if not a.size:
        return np.zeros(0)
    names = [w[0] for w in which]
    xn = np.array([w[1] for w in which])

    def gap(tt):
        """Abscissa minus node and its rate, at each crossing's instant."""
        m = cycle.at(np.mod(tt, period))
        g, r = np.empty(tt.size), np.empty(tt.size)
        for name in set(names):
            sel = np.array([nm == name for nm in names])
            xi = _line(fe, name, m)[1]
            g[sel], r[sel] = xi[0][sel] - xn[sel], xi[1][sel]
        return g, r

    ga, _ = gap(a)
    gb, _ = gap(b)
    tc = a - ga * (b - a) / (gb - ga)  # secant on the bracket, then Newton kept inside it
    for _ in range(6):
        g, r = gap(tc)
        step = np.where(r != 0.0, g / np.where(r != 0.0, r, 1.0), 0.0)
        tc = np.clip(tc - step, a, b)
    out = np.unique(np.mod(tc, period))
    out = out[np.append(True, np.diff(out) > 1e-9 * period)]  # a crossing found from both sides
    if out.size > 1 and out[0] + period - out[-1] <= 1e-9 * period:
        out = out[:-1]  # at the end of the cycle and at its start: the same instant
    return out


def element_at(lk, x):
    """Element index and fraction ``zeta`` in it of abscissae ``x`` [m] on flexible link ``lk``."""
    Le = lk.length / lk.elements
    e = np.clip(np.floor(np.asarray(x, dtype=float) / Le).astype(int), 0, lk.elements - 1)
    return e, np.asarray(x, dtype=float) / Le - e


def _rotate(v):
    """(v, v', v'') of a direction -> those of ``S v``."""
    return tuple(x @ _S.T for x in v)


class _Sum:
    """Accumulates ``sum_terms d(t) g(t)^T x_entity(t)`` as an affine form over the union of columns."""

    def __init__(self, nt: int, dim: int):
        self.nt, self.dim = nt, dim
        self.cols: list[int] = []
        self.parts: list = []  # (positions, C, C1, C2) each (nt, dim, k)
        self.p = None

    def _positions(self, cols):
        pos = []
        for c in cols:
            if c not in self.cols:
                self.cols.append(c)
            pos.append(self.cols.index(c))
        return pos

    def add(self, d, w, form, proj=None):
        """Add ``d (w proj^T x)`` (a point entity) or ``d (w x)`` (a rotation, ``proj`` None).

        ``d``, ``proj``: directions with their time derivatives, each (nt, dim) / (nt, 2);
        ``w``: scalar weights (w, w', w''), each (nt,); ``form``: the entity's :class:`EntityForm`.
        """
        cols, C, C1, C2, p, p1, p2 = form
        nt = self.nt
        if proj is not None:  # g = w proj
            g = (w[0][:, None] * proj[0], w[1][:, None] * proj[0] + w[0][:, None] * proj[1],
                 w[2][:, None] * proj[0] + 2 * w[1][:, None] * proj[1] + w[0][:, None] * proj[2])
        else:
            g = tuple(x[:, None] for x in w)
        z = np.zeros((nt,) + C.shape[1:])
        X = (np.broadcast_to(C, z.shape), z if C1 is None else np.broadcast_to(C1, z.shape),
             z if C2 is None else np.broadcast_to(C2, z.shape))
        a = _product(g, X, "tw,twk->tk")
        self.parts.append((self._positions(cols),) + _product(d, a, "td,tk->tdk"))
        if p is not None:
            zp = np.zeros((nt, C.shape[1]))
            P = (p, zp if p1 is None else p1, zp if p2 is None else p2)
            b = _product(g, P, "tw,tw->t")
            q = _product(d, b, "td,t->td")
            self.p = q if self.p is None else tuple(x + y for x, y in zip(self.p, q))

    def add_own(self, d, cols):
        """The block's own DOF along ``d``."""
        self.parts.append((self._positions(cols), d[0][..., None], d[1][..., None], d[2][..., None]))

    def form(self, order) -> EntityForm:
        """The affine form with the columns in ``order``."""
        cols = list(order)
        where = np.array([cols.index(c) for c in self.cols], dtype=int)  # own column -> final column
        C = np.zeros((3, self.nt, self.dim, len(cols)))
        for pos, *Ms in self.parts:
            at = where[pos]  # distinct within a part
            for o in range(3):
                C[o][..., at] += Ms[o]
        p = (None, None, None) if self.p is None else self.p
        return EntityForm(tuple(cols), C[0], C[1], C[2], *p)


def _product(f, g, spec):
    """Value, first and second time derivative of the product ``f g`` (Leibniz)."""
    return (np.einsum(spec, f[0], g[0]),
            np.einsum(spec, f[1], g[0]) + np.einsum(spec, f[0], g[1]),
            np.einsum(spec, f[2], g[0]) + 2 * np.einsum(spec, f[1], g[1]) + np.einsum(spec, f[0], g[2]))


def _beam_terms(fe, joint, motion, pform, rform, acc: _Sum, u, xi, what: str):
    """Add the flexible link's displacement under the block to ``acc``.

    ``what``: ``"normal"`` (n n^T x_M), ``"full"`` (x_M) or ``"slope"`` (theta_M).
    """
    mech = fe.mech
    lk = mech.links[mech.joints[joint].on]
    pts, rots = fe.link_nodes[lk.name]
    ne = lk.elements
    Le = lk.length / ne
    nt = motion.n
    e, z = element_at(lk, xi[0])
    z1, z2 = xi[1] / Le, xi[2] / Le
    n = _rotate(u)
    rows = np.arange(nt)
    orders = (1, 2, 3) if what == "slope" else (0, 1, 2)
    H = [hermite(z, k) / (Le if what == "slope" else 1.0) for k in orders]  # d/dx = d/dzeta / Le
    # weights of every node (nt, ne + 1): transverse point (H1, H3) and rotation (Le H2, Le H4) terms
    wv = np.zeros((3, nt, ne + 1))
    wr = np.zeros((3, nt, ne + 1))
    for o, val in enumerate(_chain(H, z1, z2)):
        wv[o, rows, e] += val[0]
        wv[o, rows, e + 1] += val[2]
        wr[o, rows, e] += Le * val[1]
        wr[o, rows, e + 1] += Le * val[3]
    wa = np.zeros((3, nt, ne + 1))  # the axial part, linear in zeta
    for o, (v1, v2) in enumerate(((1 - z, z), (-z1, z1), (-z2, z2))):
        wa[o, rows, e] += v1
        wa[o, rows, e + 1] += v2
    one = (np.ones((nt, 1)), np.zeros((nt, 1)), np.zeros((nt, 1)))
    d = one if what == "slope" else n
    for j in range(ne + 1):
        if not np.any(wa[0, :, j]) and not np.any(wr[0, :, j]):
            continue  # the block never reaches this node's elements
        acc.add(d, tuple(wv[:, :, j]), pform(pts[j]), proj=n)
        acc.add(d, tuple(wr[:, :, j]), rform(rots[j]))
        if what == "full":
            acc.add(u, tuple(wa[:, :, j]), pform(pts[j]), proj=u)


def slot_point_form(fe, pid: int, motion, pform, rform) -> EntityForm:
    """Affine form (:class:`EntityForm`) of a slot joint's translation (see module docstring),
    or (kind ``"contact"``) of the member's point under the block.

    ``C`` (nt, 2, k) and its first and second time derivatives; ``p`` (nt, 2) or None.
    ``pform``, ``rform``: point and rotation id -> :class:`EntityForm` of the entities drawn on.
    """
    pd = fe.points[pid]
    joint = pd.loc[1]
    jt = fe.mech.joints[joint]
    u, xi = _line(fe, joint, motion)
    n = _rotate(u)
    acc = _Sum(motion.n, 2)
    full = pd.kind == "contact" or jt.slide == "locked"  # the member's own point under the block
    if not full:
        acc.add_own(u, pd.cols)
    support = fe.slot_support.get(joint)
    if support is not None:  # a rigid member: its body point under the block
        form = pform(support)
        if full:
            return form
        acc.add(n, (np.ones(motion.n), np.zeros(motion.n), np.zeros(motion.n)), form, proj=n)
    else:
        _beam_terms(fe, joint, motion, pform, rform, acc, u, xi, "full" if full else "normal")
    return acc.form(fe.entity_cols("P", pid))


def _spline_slope(fe, joint, motion, rform, acc: _Sum, xi):
    """Add the slope of a flexible link under a sliding block: the cubic spline through the
    link's nodal rotations (not-a-knot), so that the slope is twice continuously differentiable
    along the link and the block's rotation smooth in time.

    The element's own (Hermite) slope has a curvature that jumps at the nodes: a piston locked
    to it would turn at a rate that jumps as it crosses a node, an impulse the mesh invents
    (the oscillating cylinder rang after every crossing and converged at first order in time,
    12288 elements at ``rtol`` 1e-3). At the nodes both are the nodal rotation.
    """
    from scipy.interpolate import CubicSpline
    lk = fe.mech.links[fe.mech.joints[joint].on]
    _pts, rots = fe.link_nodes[lk.name]
    ne = lk.elements
    x_nodes = np.linspace(0.0, lk.length, ne + 1)
    sp = CubicSpline(x_nodes, np.eye(ne + 1), bc_type="not-a-knot" if ne >= 3 else "natural")
    x = np.clip(xi[0], 0.0, lk.length)
    S = [sp(x, nu) for nu in (0, 1, 2)]  # (nt, ne + 1): the weights of the nodal rotations and their x-derivatives
    w = _chain(S, xi[1][:, None], xi[2][:, None])
    for j in range(ne + 1):
        acc.add((np.ones((motion.n, 1)), np.zeros((motion.n, 1)), np.zeros((motion.n, 1))),
                tuple(v[:, j] for v in w), rform(rots[j]))


def slot_rotation_form(fe, rid: int, motion, pform, rform) -> EntityForm:
    """Affine form of the elastic rotation of a member locked to a slot: the slope under the block
    (a sliding block: the spline slope of :func:`_spline_slope`; a block locked at its abscissa:
    the element's own slope there, as if the link were split and welded to the member)."""
    rd = fe.rots[rid]
    joint = rd.slot
    u, xi = _line(fe, joint, motion)
    acc = _Sum(motion.n, 1)
    if fe.mech.joints[joint].slide == "free" and joint not in fe.slot_support:
        _spline_slope(fe, joint, motion, rform, acc, xi)
    else:
        _beam_terms(fe, joint, motion, pform, rform, acc, u, xi, "slope")
    return acc.form(fe.entity_cols("R", rid))


def support_entities(fe, joint: str) -> list[tuple[str, int]]:
    """The entities a slot joint's forms draw on: the member's body point, or its nodes' points and rotations."""
    if joint in fe.slot_support:
        return [("P", fe.slot_support[joint])]
    lk = fe.mech.links[fe.mech.joints[joint].on]
    if lk.name not in fe.link_nodes:
        raise InputError(f"slider '{joint}' slides on link '{lk.name}', which is reduced (Craig-Bampton); "
                         "keep the slotted link unreduced")
    pts, rots = fe.link_nodes[lk.name]
    return [("P", p) for p in pts] + [("R", r) for r in rots]
