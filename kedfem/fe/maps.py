"""Constraint maps: element DOFs as affine functions of ``q`` over the cycle.

Per component the element DOFs are ``x = E(t) q_e + p(t)``: ``E`` turns with
the members a point or a rotation is slaved to, and ``p`` is a prescribed
offset where an elastically clamped end sits on a kinematic pin. The maps'
first and second time derivatives ``E', E''`` and ``p', p''`` feed the
transport terms ``E^T (C E + 2 M E')``, ``E^T (K E + C E' + M E'')`` and
``E^T (Q - M p'' - C p' - K p)`` of the assembler (docs/theory.md section 2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..motion.kinematics import Motion
from .forms import EntityForm
from .slots import slot_point_form, slot_rotation_form, support_entities

__all__ = ["ConstraintMaps", "GroupMap"]

_S = np.array([[0.0, -1.0], [1.0, 0.0]])
#: Elements with more q columns than this (and twice the group's median) form their maps apart
WIDE = 12


@dataclass(frozen=True)
class GroupMap:
    """Time-sampled constraint map of one group (``nt`` time nodes).

    ``cols``: (n_el, m) global q index per element column (``n_dof`` = padding);
    ``E, E1, E2``: (nt or 1, n_el, d, m) map and its first and second time
    derivatives; ``p, p1, p2``: (nt or 1, n_el, d) prescribed offsets.
    """

    cols: np.ndarray
    E: np.ndarray
    E1: np.ndarray | None
    E2: np.ndarray | None
    p: np.ndarray | None
    p1: np.ndarray | None
    p2: np.ndarray | None

    def apply(self, U: np.ndarray, sl=slice(None), *, offset: bool = False, E=None) -> np.ndarray:
        """Element DOFs ``E q`` (and ``+ p`` with ``offset``) of DOF histories ``U`` (nt, N).

        ``E``: another map of the same layout (e.g. ``E1`` for the transport
        term of the rates). Returns shape (nt, n_el, d) for the elements ``sl``.
        """
        E = self.E if E is None else E
        Up = np.concatenate([U, np.zeros((U.shape[0], 1))], axis=1)  # column N: the padding
        x = (E[:, sl] @ Up[:, self.cols[sl]][..., None])[..., 0]
        if offset and self.p is not None:
            x = x + self.p[:, sl]
        return x


class NodeForms(NamedTuple):
    """Forms of an interior node of a Craig-Bampton block: its translation and its rotation."""

    point: EntityForm
    rotation: EntityForm


class DynamicSlot(NamedTuple):
    """An entity slot of a group's element whose map varies in time or carries an offset.

    :meth:`ConstraintMaps.group_map` adds the entity's :class:`EntityForm` into the element's
    rows ``row:row + width`` at its columns ``positions``.

    Attributes
    ----------
    element : int
        Element index in the group (or bucket, see :meth:`ConstraintMaps.buckets`).
    row : int
        First row of the slot among the element's DOFs.
    positions : ndarray of int, shape (k,)
        Element column of each of the entity's q columns, in the order of its ``cols``.
    kind : str
        ``"P"`` (translation point) or ``"R"`` (rotation).
    eid : int
        Entity id.
    width : int
        2 for a point, 1 for a rotation.
    moving : bool
        The entity's map varies in time (else only its offset is added).
    """

    element: int
    row: int
    positions: np.ndarray
    kind: str
    eid: int
    width: int
    moving: bool


class PassiveEnd(NamedTuple):
    """End ``b`` of a passive link's last beam element, where the chord stretch is prescribed.

    Attributes
    ----------
    element : int
        Element index in the group (or bucket).
    row : int
        First row of the end's translation among the element's DOFs.
    link : str
        The passive link (:meth:`ConstraintMaps.chord_stretch`).
    """

    element: int
    row: int
    link: str


class StaticLayout(NamedTuple):
    """What of a group's maps does not move with the mechanism (:meth:`ConstraintMaps._static_layout`).

    Attributes
    ----------
    cols : ndarray of int, shape (n_el, m)
        Each element's q columns (unused trailing ones hold ``n_dof``).
    E0 : ndarray, shape (n_el, d, m)
        The constant part of the elements' maps ``x = E q + p``.
    dynamic : list of DynamicSlot
        The entity slots whose map moves or carries an offset.
    passive : list of PassiveEnd
        The passive links' last-element ends (the chord stretch).
    """

    cols: np.ndarray
    E0: np.ndarray
    dynamic: list
    passive: list


class ConstraintMaps:
    """The constraint-map part of :class:`kedfem.fe.model.FEModel`: entity forms and group maps."""

    # Every entity has an affine *form* (EntityForm) over the time nodes:
    #   x_entity(t) = C(t) q[cols] + p(t),  with C (nt|1, width, k) and p (nt, width)
    # plus the first and second time derivatives of C and p (None when constant).

    def entity_cols(self, kind: str, eid: int) -> tuple[int, ...]:
        """Global q columns an entity depends on (fixed over the cycle)."""
        key = (kind, eid)
        cache = self.__dict__.setdefault("_cols_cache", {})
        if key in cache:
            return cache[key]
        if kind == "P":
            pd = self.points[eid]
            if pd.kind == "fixed":
                out = ()
            elif pd.kind in ("free", "slider", "corot"):
                out = pd.cols
            elif pd.kind == "body":
                out = self.entity_cols("P", pd.parent) + (self.rots[pd.phi].cols if pd.phi >= 0 else ())
            elif pd.kind in ("slot", "contact"):
                out = self._slot_cols(pd.cols, pd.loc[1])
            else:
                out = self._block_cols(pd.block)
        else:
            rd = self.rots[eid]
            if rd.kind == "cb":
                out = self._block_cols(rd.block)
            elif rd.kind == "slot":
                out = self._slot_cols((), rd.slot)
            else:
                out = rd.cols
        cache[key] = out
        return out

    def _slot_cols(self, own: tuple, joint: str) -> tuple[int, ...]:
        """A block's own column and those of the member it slides on (every node it may reach)."""
        out = list(own)
        for kind, eid in support_entities(self, joint):
            out += [c for c in self.entity_cols(kind, eid) if c not in out]
        return tuple(out)

    def _block_cols(self, b: int) -> tuple[int, ...]:
        blk = self.blocks[b]
        pa, ra, pb, rb = blk["bounds"]
        return (self.entity_cols("P", pa) + self.entity_cols("R", ra) + self.entity_cols("P", pb)
                + self.entity_cols("R", rb) + blk["modal"])

    def entity_dynamic(self, kind: str, eid: int) -> tuple[bool, bool]:
        """(moving, offset): whether the entity's map varies in time / carries an offset."""
        if kind == "P":
            pd = self.points[eid]
            if pd.kind == "body":
                mv, of = self.entity_dynamic("P", pd.parent)
                return (pd.phi >= 0 or mv), of
            if pd.kind == "cb":
                return True, self._block_offset(pd.block)
            if pd.kind == "corot":
                return True, False
            if pd.kind in ("slot", "contact"):
                return True, self._slot_offset(pd.loc[1])
            return False, False
        rd = self.rots[eid]
        if rd.kind == "cb":
            return True, self._block_offset(rd.block)
        if rd.kind == "slot":
            return True, self._slot_offset(rd.slot)
        return False, rd.offset

    def _slot_offset(self, joint: str) -> bool:
        return any(self.entity_dynamic(k, e)[1] for k, e in support_entities(self, joint))

    def _block_offset(self, b: int) -> bool:
        blk = self.blocks[b]
        pa, ra, pb, rb = blk["bounds"]
        passive = not self.mech.links[blk["link"]].kinematic
        return passive or any(self.entity_dynamic(k, e)[1] for k, e in (("P", pa), ("R", ra), ("P", pb), ("R", rb)))

    def has_moving_maps(self) -> bool:
        """True if some constraint map depends on time (rotating rigid members, reduced links)."""
        return (any(self.entity_dynamic("P", i)[0] for i in range(len(self.points)))
                or bool(self.blocks))

    def has_offsets(self) -> bool:
        """True if some entity or passive link end carries a prescribed offset."""
        return (any(rd.offset for rd in self.rots)
                or any(not lk.kinematic for lk in self.mech.flexible_links))

    def entity_forms(self, motion: Motion) -> dict[str, list[EntityForm]]:
        """Affine forms of all entities over the motion's time nodes.

        Returns
        -------
        dict
            ``{"P": [...], "R": [...]}``: the :class:`~kedfem.fe.forms.EntityForm` of every
            point and rotation, by entity id: ``cols``, ``C`` (nt or 1, width, k) and its
            time derivatives ``C1, C2`` (None if constant), and the prescribed offset ``p``
            (nt, width) with its derivatives ``p1, p2`` (None if there is none).
        """
        nt = motion.n
        rp, rp1, rp2 = self.rot_offsets(motion) if any(rd.offset for rd in self.rots) else (None,) * 3
        pforms: list = [None] * len(self.points)
        rforms: list = [None] * len(self.rots)
        locs: dict = {}
        blocks: dict = {}

        def loc_state(pid):
            if pid not in locs:
                locs[pid] = self.loc_motion(self.points[pid].loc, motion)
            return locs[pid]

        def constant(cols, C):  # a map fixed over the cycle, no offset
            return EntityForm(cols, C, None, None, None, None, None)

        def rform(rid):
            if rforms[rid] is not None:
                return rforms[rid]
            rd = self.rots[rid]
            if rd.kind == "cb":
                out = block(rd.block)[rd.node].rotation
            elif rd.kind == "slot":
                out = slot_rotation_form(self, rid, motion, pform, rform)
            else:
                C = np.ones((1, 1, len(rd.cols)))
                if rd.offset:
                    out = EntityForm(rd.cols, C, None, None,
                                     rp[:, rid:rid + 1], rp1[:, rid:rid + 1], rp2[:, rid:rid + 1])
                else:
                    out = constant(rd.cols, C)
            rforms[rid] = out
            return out

        def pform(pid):
            if pforms[pid] is not None:
                return pforms[pid]
            pd = self.points[pid]
            if pd.kind == "fixed":
                out = constant((), np.zeros((1, 2, 0)))
            elif pd.kind == "free":
                out = constant(pd.cols, np.eye(2)[None])
            elif pd.kind == "slider":
                out = constant(pd.cols, np.asarray(pd.axis, float).reshape(1, 2, 1))
            elif pd.kind == "cb":
                out = block(pd.block)[pd.node].point
            elif pd.kind in ("slot", "contact"):
                out = slot_point_form(self, pid, motion, pform, rform)
            elif pd.kind == "corot":  # components in the link's rotating frame: x = R(theta) q
                i = motion.member_names.index(pd.loc[1])
                th, w, al = motion.theta[:, i], motion.omega[:, i], motion.alpha[:, i]
                c, s_ = np.cos(th), np.sin(th)
                R = np.stack([np.stack([c, -s_], -1), np.stack([s_, c], -1)], -2)
                RS = R @ _S
                out = EntityForm(pd.cols, R, w[:, None, None] * RS,
                                 al[:, None, None] * RS - (w**2)[:, None, None] * R, None, None, None)
            else:
                parent = pform(pd.parent)
                if pd.phi < 0:
                    out = parent
                else:
                    pc, pC, pC1, pC2 = parent.cols, parent.C, parent.C1, parent.C2
                    r, v, a = loc_state(pid)
                    rr, rv, ra = loc_state(pd.parent) if self.points[pd.parent].loc else (0, 0, 0)
                    rho, rho1, rho2 = r - rr, v - rv, a - ra
                    col = (rho @ _S.T)[..., None]
                    col1 = (rho1 @ _S.T)[..., None]
                    col2 = (rho2 @ _S.T)[..., None]
                    bC = np.broadcast_to(pC, (nt,) + pC.shape[1:])
                    z = np.zeros((nt, 2, pC.shape[2]))
                    bC1 = z if pC1 is None else np.broadcast_to(pC1, z.shape)
                    bC2 = z if pC2 is None else np.broadcast_to(pC2, z.shape)
                    cols = tuple(pc) + tuple(self.rots[pd.phi].cols)
                    out = EntityForm(cols, np.concatenate([bC, col], -1), np.concatenate([bC1, col1], -1),
                                     np.concatenate([bC2, col2], -1), parent.p, parent.p1, parent.p2)
            pforms[pid] = out
            return out

        def block(b):
            if b not in blocks:
                blocks[b] = self._block_forms(b, motion, pform, rform)
            return blocks[b]

        for pid in range(len(self.points)):
            pform(pid)
        for rid in range(len(self.rots)):
            rform(rid)
        return {"P": pforms, "R": rforms}

    def _block_forms(self, b, motion, pform, rform) -> list[NodeForms]:
        """Forms of the interior nodes of a Craig-Bampton block (see kedfem.fe.reduction), node by node.

        Interior (global) ``x_i = W x_b + Z eta`` with ``W = T_i^T Psi T_b``,
        ``Z = T_i^T Phi`` and ``T' = -w S_hat T``:
        ``W' = w T_i^T D1 T_b``, ``W'' = a T_i^T D1 T_b + w^2 T_i^T D2 T_b`` with
        ``D1 = S_hat Psi - Psi S_hat``, ``D2 = S_hat D1 - D1 S_hat``.
        """
        blk = self.blocks[b]
        nt = motion.n
        lk = self.mech.links[blk["link"]]
        Psi, Phi = blk["Psi"], blk["Phi"]
        ni = Psi.shape[0]
        # boundary map x_b = E_b q_b + p_b (nt, 6, m_b) and offsets (nt, 6)
        forms = [pform(blk["bounds"][0]), rform(blk["bounds"][1]), pform(blk["bounds"][2]),
                 rform(blk["bounds"][3])]
        mb = sum(len(f.cols) for f in forms)
        Eb = np.zeros((3, nt, 6, mb))  # value, first, second derivative
        pb = np.zeros((3, nt, 6))
        row = col = 0
        for f in forms:
            _cols, C, C1, C2, p, p1, p2 = f
            w, k = C.shape[1], C.shape[2]
            for d, X in enumerate((C, C1, C2)):
                if X is not None:
                    Eb[d, :, row:row + w, col:col + k] = X
            for d, X in enumerate((p, p1, p2)):
                if X is not None:
                    pb[d, :, row:row + w] += X
            row += w
            col += k
        if not lk.kinematic:  # passive link: chord stretch at end b
            sp_ = self.chord_stretch(lk.name, motion)
            for d in range(3):
                pb[d, :, 3:5] += sp_[d]
        # frame rotation of the link
        i = motion.member_names.index(lk.name)
        th, w, al = motion.theta[:, i], motion.omega[:, i], motion.alpha[:, i]
        c, s_ = np.cos(th), np.sin(th)
        Sb = np.zeros((6, 6))
        Sb[0:2, 0:2] = _S
        Sb[3:5, 3:5] = _S
        Si = np.kron(np.eye(ni // 3), np.pad(_S, ((0, 1), (0, 1))))
        D1 = Si @ Psi - Psi @ Sb
        D2 = Si @ D1 - D1 @ Sb

        # rotations node by node: T3 = blockdiag(R^T, 1); X (ni, c) -> T_i^T X per 3-row block
        T3 = np.zeros((nt, 3, 3))
        T3[:, 0, 0], T3[:, 0, 1], T3[:, 1, 0], T3[:, 1, 1], T3[:, 2, 2] = c, s_, -s_, c, 1.0
        Tb = np.zeros((nt, 6, 6))
        Tb[:, 0:3, 0:3] = T3
        Tb[:, 3:6, 3:6] = T3
        T3t = np.swapaxes(T3, 1, 2)
        nn = ni // 3

        def rot_in(X):  # T_i^T X for X (ni, c) or (nt, ni, c) -> (nt, ni, c)
            Xb = X.reshape(nn, 3, -1) if X.ndim == 2 else X.reshape(nt, nn, 3, -1)
            if X.ndim == 2:
                Y = np.einsum("tij,njc->tnic", T3t, Xb)
            else:
                Y = np.einsum("tij,tnjc->tnic", T3t, Xb)
            return Y.reshape(nt, ni, -1)

        w3, a3 = w[:, None, None], al[:, None, None]
        W0 = rot_in(Psi) @ Tb
        TD1 = rot_in(D1) @ Tb
        W1 = w3 * TD1
        W2 = a3 * TD1 + w3**2 * (rot_in(D2) @ Tb)
        Z0 = rot_in(Phi)
        SPhi = rot_in(Si @ Phi)
        Z1 = w3 * SPhi
        Z2 = a3 * SPhi + w3**2 * rot_in(Si @ Si @ Phi)
        E0 = np.concatenate([W0 @ Eb[0], Z0], axis=-1)
        E1 = np.concatenate([W1 @ Eb[0] + W0 @ Eb[1], Z1], axis=-1)
        E2 = np.concatenate([W2 @ Eb[0] + 2 * W1 @ Eb[1] + W0 @ Eb[2], Z2], axis=-1)
        has_p = self._block_offset(b)
        if has_p:
            P0 = (W0 @ pb[0][..., None])[..., 0]
            P1 = (W1 @ pb[0][..., None] + W0 @ pb[1][..., None])[..., 0]
            P2 = (W2 @ pb[0][..., None] + 2 * W1 @ pb[1][..., None] + W0 @ pb[2][..., None])[..., 0]
        cols = self._block_cols(b)
        out = []
        for j in range(ni // 3):
            r = slice(3 * j, 3 * j + 2)
            t = slice(3 * j + 2, 3 * j + 3)
            pt = EntityForm(cols, E0[:, r], E1[:, r], E2[:, r],
                            *((P0[:, r], P1[:, r], P2[:, r]) if has_p else (None,) * 3))
            ro = EntityForm(cols, E0[:, t], E1[:, t], E2[:, t],
                            *((P0[:, t], P1[:, t], P2[:, t]) if has_p else (None,) * 3))
            out.append(NodeForms(pt, ro))
        return out

    def rot_offsets(self, motion: Motion):
        """Prescribed rotation offsets ``(p, p1, p2)``, each (nt, n_rots)."""
        nt = motion.n
        p = np.zeros((nt, len(self.rots)))
        p1 = np.zeros_like(p)
        p2 = np.zeros_like(p)
        for rid, rd in enumerate(self.rots):
            if not rd.offset:
                continue
            i = motion.member_names.index(rd.member)
            val = -(motion.theta[:, i] - motion.theta_ref[i])
            d1 = -motion.omega[:, i]
            d2 = -motion.alpha[:, i]
            if rd.master is not None:
                k = motion.member_names.index(rd.master)
                val = val + motion.theta[:, k] - motion.theta_ref[k]
                d1 = d1 + motion.omega[:, k]
                d2 = d2 + motion.alpha[:, k]
            p[:, rid], p1[:, rid], p2[:, rid] = val, d1, d2
        return p, p1, p2

    def _static_layout(self, gname: str) -> StaticLayout:
        """The group's :class:`StaticLayout`: its column map (n_el, m), the constant part of E
        (n_el, d, m), its :class:`DynamicSlot` and :class:`PassiveEnd` items.

        The q columns of an element are the union of its entities' columns
        (each global column once), so that element matrices in q-space stay as
        small as the element's actual couplings.
        """
        if gname in self._static_cache:
            return self._static_cache[gname]
        base, _hash, part = gname.partition("#")
        g = self.groups[base]
        elements = self.buckets(base)[gname] if part else np.arange(g.n)
        n_el = elements.size
        per_el = []
        for e in elements:
            ucols: list[int] = []
            for slot, kind in enumerate(g.layout):
                eid = g.ids[e, slot]
                if eid >= 0:
                    for c in self.entity_cols(kind, eid):
                        if c not in ucols:
                            ucols.append(c)
            per_el.append(ucols)
        m = max([len(c) for c in per_el], default=0)
        m = max(m, 1)
        colarr = np.full((n_el, m), len(self.dof_labels), dtype=int)
        E0 = np.zeros((n_el, g.d, m))
        dynamic: list[DynamicSlot] = []
        passive: list[PassiveEnd] = []  # chord stretch at end b
        passive_end = {}
        if base == "beam":
            local = {int(e): i for i, e in enumerate(elements)}
            for name in self.beam.links:
                end = self.beam.first[name] + self.beam.count[name] - 1
                if not self.mech.links[name].kinematic and end in local:
                    passive_end[local[end]] = name
        for e in range(n_el):
            ucols = per_el[e]
            colarr[e, :len(ucols)] = ucols
            index = {c: i for i, c in enumerate(ucols)}
            row = 0
            for slot, kind in enumerate(g.layout):
                eid = g.ids[elements[e], slot]
                width = 2 if kind == "P" else 1
                if eid >= 0:
                    pos = np.array([index[c] for c in self.entity_cols(kind, eid)], dtype=int)
                    moving, offset = self.entity_dynamic(kind, eid)
                    if moving or offset:
                        dynamic.append(DynamicSlot(e, row, pos, kind, eid, width, moving))
                    if not moving and pos.size:
                        C = self._const_C(kind, eid)
                        for j, pj in enumerate(pos):
                            E0[e, row:row + width, pj] += C[:, j]
                if kind == "P" and slot == 2 and e in passive_end:
                    passive.append(PassiveEnd(e, row, passive_end[e]))
                row += width
        out = StaticLayout(colarr, E0, dynamic, passive)
        self._static_cache[gname] = out
        return out

    def buckets(self, gname: str) -> dict:
        """The elements of a group by width of their q-space maps: ``{key: element indices}``.

        A block on a member (a slot joint) depends on every node of that member, so the
        few elements at the block have far more columns than the others; their maps are
        formed apart (key ``gname#wide``) so that the others keep their narrow width.
        Groups without such elements have the single key ``gname``.
        """
        cache = self.__dict__.setdefault("_bucket_cache", {})
        if gname in cache:
            return cache[gname]
        g = self.groups[gname]
        width = np.array([len({c for slot, kind in enumerate(g.layout) if g.ids[e, slot] >= 0
                               for c in self.entity_cols(kind, g.ids[e, slot])}) for e in range(g.n)], int)
        limit = max(WIDE, 2 * int(np.median(width))) if width.size else WIDE
        wide = width > limit
        out = {gname: np.arange(g.n)}
        if wide.any():
            out = {f"{gname}#narrow": np.flatnonzero(~wide), f"{gname}#wide": np.flatnonzero(wide)}
            out = {k: v for k, v in out.items() if v.size}
        cache[gname] = out
        return out

    def _const_C(self, kind, eid):
        if kind == "R":
            return np.ones((1, len(self.rots[eid].cols)))
        pd = self.points[eid]
        while pd.kind == "body":
            pd = self.points[pd.parent]
        if pd.kind == "free":
            return np.eye(2)
        if pd.kind == "slider":
            return np.asarray(pd.axis, float).reshape(2, 1)
        return np.zeros((2, 0))

    def chord_stretch(self, link: str, motion: Motion):
        """Prescribed end displacement of a passive link and its time derivatives.

        ``p = (l - L0) e1`` with ``l`` the chord length between the link's end
        joints and ``e1`` the chord direction; returns three (nt, 2) arrays.
        """
        lk = self.mech.links[link]
        ia, ib = motion.joint_names.index(lk.a), motion.joint_names.index(lk.b)
        d = motion.r[:, ib] - motion.r[:, ia]
        dd = motion.v[:, ib] - motion.v[:, ia]
        ddd = motion.a[:, ib] - motion.a[:, ia]
        ell = np.linalg.norm(d, axis=1)
        e1 = d / ell[:, None]
        e2 = e1 @ _S.T
        l1 = np.einsum("nd,nd->n", d, dd) / ell
        l2 = (np.einsum("nd,nd->n", dd, dd) + np.einsum("nd,nd->n", d, ddd)) / ell - l1**2 / ell
        i = motion.member_names.index(link)
        w, al = motion.omega[:, i, None], motion.alpha[:, i, None]
        ext = (ell - lk.length)[:, None]
        p = ext * e1
        p1 = l1[:, None] * e1 + ext * w * e2
        p2 = l2[:, None] * e1 + 2 * l1[:, None] * w * e2 + ext * (al * e2 - w**2 * e1)
        return p, p1, p2

    def group_map(self, gname: str, motion: Motion, forms: dict[str, list[EntityForm]] | None = None) -> GroupMap:
        """Constraint map of a group over the motion's time nodes.

        ``forms`` (from :meth:`entity_forms` on the same motion) may be passed
        to share them between groups.
        """
        colarr, E0, dynamic, passive = self._static_layout(gname)
        nt = motion.n
        n_el, d, m = E0.shape
        if (dynamic or passive) and forms is None:
            forms = self.entity_forms(motion)
        moving = any(dyn.moving for dyn in dynamic)
        if moving:
            E = np.broadcast_to(E0, (nt, n_el, d, m)).copy()
            E1 = np.zeros_like(E)
            E2 = np.zeros_like(E)
        else:
            E = E0[None]
            E1 = E2 = None
        p = p1 = p2 = None
        if any(forms[dyn.kind][dyn.eid].p is not None for dyn in dynamic) or passive:
            p = np.zeros((nt, n_el, d))
            p1 = np.zeros_like(p)
            p2 = np.zeros_like(p)
        for e, row, pos, kind, eid, width, mv in dynamic:
            _cols, C, C1, C2, q0, q1, q2 = forms[kind][eid]
            rs = slice(row, row + width)
            if mv:
                for j, pj in enumerate(pos):
                    E[:, e, rs, pj] += C[..., j]
                    if C1 is not None:
                        E1[:, e, rs, pj] += C1[..., j]
                        E2[:, e, rs, pj] += C2[..., j]
            if q0 is not None:
                p[:, e, rs] += q0
                p1[:, e, rs] += q1
                p2[:, e, rs] += q2
        for e, row, name in passive:
            a, b_, c_ = self.chord_stretch(name, motion)
            p[:, e, row:row + 2] += a
            p1[:, e, row:row + 2] += b_
            p2[:, e, row:row + 2] += c_
        return GroupMap(colarr, E, E1, E2, p, p1, p2)

