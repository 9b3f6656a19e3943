"""The assembler: the structure and the chosen effects of a scene, at any set of instants.

For a chunk of instants it builds the rigid-body kinematics of the beams'
frames, asks the structure (:mod:`kedfem.fe.structure`) and each chosen effect
(:mod:`kedfem.fe.effects`) for their element terms, pushes them through the
constraint maps of :class:`kedfem.fe.model.FEModel` (``x = E q + p``, with the
transport of moving maps), scatters them into q-space and adds the damping.
State-dependent effects give their tangents about a trial response the same way.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import InputError, KedError
from ..model import elements as el
from ..motion.kinematics import Motion
from ..motion.kinetostatics import JointForces, kinetostatics, link_axial_force_at
from .maps import GroupMap
from .model import FEModel
from .scatter import ACTIVE_WIDTH, ActiveTerms, column_patterns
from .damping import ModalDamping, Rayleigh, check_damping, damping_matrix
from . import effects as registry
from .effects.base import BeamKinematics, Chunk, Effect, GroupTerms, StateTerms, slice_motion
from .structure import beam_coupling, beam_mass, beam_stiffness, objective_rates, spring_axes

__all__ = ["Assembler", "SystemTerms", "slice_motion"]

log = logging.getLogger(__name__)
#: mechanisms whose assembler said that geometric_nonlinearity carries the links' axial forces
_TOLD_AXIAL: set[str] = set()


@dataclass
class SystemTerms:
    """Assembled q-space terms at ``nt`` time nodes.

    ``M, C, K``: (nt, N, N) [kg, N s/m, N/m]; ``Q``: (nt, N) [N].
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    Q: np.ndarray


class Assembler:
    """Assemble the structure and the effects of a scene at any set of time nodes.

    Parameters
    ----------
    model : FEModel
        DOF map and element groups.
    motion : Motion
        Rigid-body motion over the cycle (all time nodes).
    effects : sequence of str
        Effects to apply (see :data:`kedfem.fe.effects.EFFECTS`).
    damping : Rayleigh or ModalDamping or None
        Damping model.
    frame : bool
        Co-moving-frame formulation for frequency analysis: each link in its
        own rotating frame (Coriolis ``2 w m_s``, ``a m_s``, ``-w^2 m_t``),
        rigid members in translating frames; the terms of the time
        derivatives of the frame transformations are left out. ``False``
        (default) is the inertial-frame formulation the response is solved in.
    damping_field : kedfem.fe.modal_damping.DampingField, optional
        With :class:`ModalDamping`: ``C(t)`` interpolated over the cycle
        instead of an eigenproblem per instant (built once per solve from the
        same model and cycle).
    """

    def __init__(self, model: FEModel, motion: Motion, effects=(), damping=None, frame=False,
                 damping_field=None):
        self.model = model
        self.mech = model.mech
        self.motion = motion
        self.chosen = registry.chosen(effects)
        self.effects = tuple(e.name for e in self.chosen)
        self.damping = check_damping(damping)
        self.frame = bool(frame)
        self.damping_field = damping_field
        # how the chosen effects change the assembler's own work (kedfem.fe.effects.base)
        self.weight = any(e.weight for e in self.chosen)
        self.transport = any(e.transports_maps for e in self.chosen) and not self.frame
        self.offset_inertia = any(e.offset_inertia for e in self.chosen)
        self.carries_axial_forces = any(e.carries_axial_forces for e in self.chosen)
        self._forces: JointForces | None = None
        self._axial: np.ndarray | None = None
        b = model.beam
        self.beam_member = np.array([motion.member_names.index(b.links[i]) for i in b.link], dtype=int)
        self._beam_joint_a = np.array([motion.joint_names.index(self.mech.links[b.links[i]].a)
                                       for i in b.link], dtype=int)
        if (self.carries_axial_forces and "axial_stiffening" in self.effects and b.L.size
                and self.mech.name not in _TOLD_AXIAL):
            # once per mechanism: a continuation builds an assembler per speed (511 lines at 1600 rpm)
            _TOLD_AXIAL.add(self.mech.name)
            log.info("geometric_nonlinearity carries the axial forces of the links: the links' k_G of "
                     "axial_stiffening is not added twice (rigid members keep theirs)")
        self._k_local = beam_stiffness(b)
        self._m_local = beam_mass(b)
        self._coupling = None
        self._full_maps: dict = {}  # group maps over the whole cycle, for the state terms
        self._full_forms = None     # the entity forms they are built from
        self._local_beam = None     # the beam elements' map to their local DOFs (local_beam_map)
        self._forms = None

    # ------------------------------------------------------------- properties
    @property
    def state_dependent(self) -> bool:
        """True if some chosen effect depends on the elastic state (needs iteration)."""
        return any(e.state_dependent(self.mech) for e in self.chosen)

    @property
    def coupling_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """The beams' ``m_t`` and ``m_s``, each (n_el, 6, 6) [kg] (:func:`kedfem.fe.structure.beam_coupling`)."""
        if self._coupling is None:
            self._coupling = beam_coupling(self.model.beam)
        return self._coupling

    def member_inertia(self, member: str) -> tuple[float, float]:
        """Mass [kg] and centroidal moment of inertia [kg m^2] of a rigid member or body."""
        m = self.mech.links[member] if member in self.mech.links else self.mech.bodies[member]
        return m.mass, m.J

    def objective_beta(self) -> float:
        """Rayleigh's stiffness coefficient [s] when the beams take it on their strain rates.

        In the inertial-frame formulation (not for the co-moving frequency
        analysis, which keeps ``beta K`` on its DOFs).
        """
        d = self.damping
        return float(d.beta) if isinstance(d, Rayleigh) and d.beta and not self.frame else 0.0

    # ------------------------------------------------------------ kinetostatics
    def joint_forces(self) -> JointForces:
        """Kinetostatic joint forces over the whole cycle, with the chosen effects' loads (computed once)."""
        if self._forces is None:
            mo = self.motion
            loads = moments = None
            hooks = [e for e in self.chosen if type(e).joint_loads is not Effect.joint_loads]
            if hooks:
                loads = np.zeros((mo.n, len(mo.joint_names), 2))
                moments = np.zeros((mo.n, len(mo.member_names)))
                for e in hooks:
                    e.joint_loads(self, mo, loads, moments)
            self._forces = kinetostatics(self.mech, mo, inertia=True, gravity=self.weight,
                                         joint_loads=loads, member_moments=moments,
                                         pair_loads=self.pair_loads(mo))
        return self._forces

    def pair_loads(self, mo: Motion) -> dict:
        """The chosen effects' known forces inside sliding pairs (:meth:`Effect.pair_loads`)."""
        out: dict = {}
        for e in self.chosen:
            for j, F in e.pair_loads(self, mo).items():
                out[j] = out[j] + F if j in out else F
        return out

    def _beam_kinematics(self, mo: Motion) -> BeamKinematics | None:
        """Kinematics of the beam elements' frames at the instants of ``mo`` (None without beams)."""
        if not self.model.beam.L.size:
            return None
        th = mo.theta[:, self.beam_member]
        T = el.rotation_blocks(th)
        return BeamKinematics(th, mo.omega[:, self.beam_member], mo.alpha[:, self.beam_member],
                              mo.a[:, self._beam_joint_a], T, np.swapaxes(T, -1, -2),
                              np.swapaxes(T[..., 0:2, 0:2], -1, -2))

    # ------------------------------------------------------------ structure
    def _structure_terms(self, chunk: Chunk, damped: bool = True) -> None:
        """Mass and stiffness of beams, rigid members, point masses and springs (always assembled).

        ``Ks`` is the structural stiffness (Rayleigh's ``beta K``, modal
        damping); with ``damped`` and Rayleigh ``beta`` the beams take ``beta k``
        on their objective strain rates instead of on their DOFs.
        """
        acc, bk = chunk.acc, chunk.beam
        if bk is not None:
            acc.add("beam", "M", bk.Tt @ self._m_local @ bk.T)
            Kg = bk.Tt @ self._k_local @ bk.T
            acc.add("beam", "K", Kg)
            beta = self.objective_beta() if damped else 0.0
            if beta:
                # stiffness-proportional damping of the elements' strain rates in their own
                # turning frame: f = beta k (T x' + T' x), T' x = w S^T (T x) on the translations
                # (the transport of the DOF maps follows in _transform); not of rigid rotation
                Cb, Kb = objective_rates(beta * self._k_local, bk.T, bk.Tt, bk.omega[..., None, None])
                acc.add("beam", "C", Cb)
                acc.add("beam", "K", Kb)
            else:
                acc.add("beam", "Ks", Kg)
        for gname, masses in (("rigid", [self.member_inertia(m) for m in self.model.groups["rigid"].meta.get("members", ())]),
                              ("pmass", self._point_inertia())):
            if masses:
                M = np.zeros((1, len(masses), 3, 3))
                M[0, :, 0, 0] = M[0, :, 1, 1] = [m for m, _J in masses]
                M[0, :, 2, 2] = [J for _m, J in masses]
                acc.add(gname, "M", M)
        g = self.model.groups["spring"]
        if g.n:
            items = g.meta["items"]
            B = spring_axes(items)
            k = np.array([s.k for s in items])
            Kx = (k[:, None, None] * (B[:, :, None] * B[:, None, :]))[None]
            acc.add("spring", "K", Kx)
            acc.add("spring", "Ks", Kx)
        g = self.model.groups["tspring"]
        if g.n:
            kt = np.array([it[1].k if it[0] == "spring" else it[1].torsional_stiffness for it in g.meta["items"]])
            Kt = (kt[:, None, None] * np.array([[1.0, -1.0], [-1.0, 1.0]]))[None]
            acc.add("tspring", "K", Kt)
            acc.add("tspring", "Ks", Kt)

    def _point_inertia(self) -> list[tuple[float, float]]:
        """Mass and moment of inertia of the point masses (J only where an elastic rotation carries it)."""
        g = self.model.groups["pmass"]
        return [(p.mass, p.J if g.ids[k, 1] >= 0 else 0.0) for k, p in enumerate(g.meta.get("items", ()))]

    def beam_axial_kinetostatic(self) -> np.ndarray:
        """Kinetostatic axial force of every beam element at its Gauss points
        (:data:`kedfem.model.elements.AXIAL_XI`), shape (n, n_el, 4) [N]."""
        if self._axial is None:
            b = self.model.beam
            forces = self.joint_forces()
            out = np.zeros((self.motion.n, b.L.size, el.AXIAL_XI.size))
            for name in b.links:
                if not self.mech.links[name].kinematic:
                    continue  # a redundant member takes no kinetostatic force
                sl = self.model.link_elements(name)
                s = b.s1[sl, None] + b.L[sl, None] * el.AXIAL_XI
                out[:, sl] = link_axial_force_at(self.mech, self.motion, forces, name, s, gravity=self.weight,
                                                 side=(b.s1[sl] + 0.5 * b.L[sl])[:, None])
            self._axial = out
        return self._axial

    # ------------------------------------------------------------ element terms
    def _transform(self, gname, acc: GroupTerms, mo, nt, key=None, elements=None, structural=True):
        """q-space terms of a group's elements (those of bucket ``key``, see ``FEModel.buckets``);
        without ``structural`` the structural stiffness ``Ks`` is left out (a modal damping field
        or no damping: nothing reads it)."""
        model = self.model
        terms = [acc.get(gname, k) if k != "Ks" or structural else None for k in ("M", "C", "K", "Ks", "Q")]
        if key is not None and key != gname:
            terms = [None if x is None else x[:, elements] for x in terms]
        M, C, K, Ks, Q = terms
        if M is None and C is None and K is None and Q is None:
            return None
        gm = model.group_map(gname if key is None else key, mo, self._forms)
        if gm.E.shape[-1] >= ACTIVE_WIDTH and nt > 1 and gm.E.shape[0] == nt:
            return self._transform_active(gm, (M, C, K, Ks, Q), nt)
        return self._q_terms(gm, M, C, K, Ks, Q, nt)

    def _transform_active(self, gm, terms, nt: int) -> dict:
        """:meth:`_q_terms` of a wide group (the elements and point masses at a block, whose maps
        span every node of the member it slides on) on the columns each instant uses: instants
        alike are formed together, the columns left out being zeros (the Whitworth's lever
        element: 11 of 54), and kept as :class:`~kedfem.fe.scatter.ActiveTerms`."""
        act = (gm.E != 0.0).any(axis=(1, 2))
        for X in (gm.E1, gm.E2):
            if X is not None:
                act = act | (X != 0.0).any(axis=(1, 2)) if X.shape[0] == nt else act | (X != 0.0).any(axis=(0, 1, 2))
        parts: dict[str, list] = {}

        def rows_of(X, rows):
            return X if X is None or X.shape[0] != nt else X[rows]

        for rows, cols in column_patterns(act):
            sub = GroupMap(gm.cols[:, cols], rows_of(gm.E, rows)[..., cols],
                           *(None if X is None else rows_of(X, rows)[..., cols] for X in (gm.E1, gm.E2)),
                           *(rows_of(X, rows) for X in (gm.p, gm.p1, gm.p2)))
            out = self._q_terms(sub, *(rows_of(X, rows) for X in terms), rows.size)
            for name, val in out.items():
                parts.setdefault(name, []).append((rows, cols, val))
        return {name: ActiveTerms(nt, tuple(p_)) for name, p_ in parts.items()}

    def _q_terms(self, gm, M, C, K, Ks, Q, nt: int) -> dict:
        """``E^T M E``, ``E^T (C E + 2 M E')``, ``E^T (K E + C E' + M E'')``, ``E^T Ks E`` and
        ``E^T (Q - K p - C p' - M p'')`` of element terms (shapes (nt or 1, n_el, d, d) and
        (nt or 1, n_el, d)) through the map ``gm`` (:class:`~kedfem.fe.maps.GroupMap`)."""
        E = gm.E
        Et = np.swapaxes(E, -1, -2)
        out = {}

        def full(x):
            return np.broadcast_to(x, (nt,) + x.shape[1:])

        # E^T M and E^T C serve the transport terms too (a product each fewer)
        EtM = Et @ M if M is not None else None
        EtC = Et @ C if C is not None else None
        if M is not None:
            out["M"] = full(EtM @ E)
        Cq = EtC @ E if C is not None else None
        Kq = Et @ K @ E if K is not None else None
        if Ks is not None:
            out["Ks"] = full(Et @ Ks @ E)
        transport = self.transport and gm.E1 is not None
        if transport:
            if M is not None:
                add = 2.0 * (EtM @ gm.E1)
                Cq = add if Cq is None else Cq + add
                add = EtM @ gm.E2
                Kq = add if Kq is None else Kq + add
            if C is not None:
                add = EtC @ gm.E1
                Kq = add if Kq is None else Kq + add
        if Cq is not None:
            out["C"] = full(Cq)
        if Kq is not None:
            out["K"] = full(Kq)
        Qx = Q
        if gm.p is not None and not self.frame:
            extra = 0.0
            if K is not None:
                extra = extra + K @ gm.p[..., None]
            if C is not None:
                extra = extra + C @ gm.p1[..., None]
            if M is not None and self.offset_inertia:
                extra = extra + M @ gm.p2[..., None]
            if not isinstance(extra, float):
                Qx = -extra[..., 0] if Qx is None else Qx - extra[..., 0]
        if Qx is not None:
            out["Q"] = full((Et @ Qx[..., None])[..., 0])
        return out

    def _chunk(self, idx) -> Chunk:
        """The chunk of instants ``idx`` with the structure's and the chosen effects' element terms."""
        mo = slice_motion(self.motion, idx)
        chunk = Chunk(mo, idx, self._beam_kinematics(mo))
        self._structure_terms(chunk)
        for e in self.chosen:
            e.element_terms(self, chunk)
        return chunk

    def _to_q(self, chunk: Chunk, structural: bool = True) -> dict:
        """q-space terms of every element group of ``chunk``, by group name (``Ks`` only with
        ``structural``)."""
        mo, nt = chunk.motion, chunk.idx.size
        dyn = self.model.has_moving_maps() or self.model.has_offsets()
        self._forms = self.model.entity_forms(mo) if dyn else None
        try:
            out = {key: self._transform(g, chunk.acc, mo, nt, key, els, structural)
                   for g in self.model.groups for key, els in self.model.buckets(g).items()}
        finally:
            self._forms = None
        return {g: o for g, o in out.items() if o}

    def joint_terms(self, joint: str, motion: Motion, *, M=None, C=None, K=None, Q=None) -> dict:
        """q-space terms of global-frame terms on a joint's elastic translation, for plug-in effects.

        A joint's translation is ``x = E(t) q + p(t)`` (its DOFs may turn with a link:
        ``B.u[rocker]``); this pushes terms given on ``x`` through that map as the assembler does
        for its element groups: ``E^T M E``, ``E^T (C E + 2 M E')``, ``E^T (K E + C E' + M E'')``
        and ``E^T (Q - M p'' - C p' - K p)`` (the map's rates with ``coupling``, as for every
        element).

        Parameters
        ----------
        joint : str
        motion : Motion
            The instants (``chunk.motion`` in a hook).
        M, C, K : array_like, shape (2, 2) or (nt, 2, 2), optional
            [kg, N s/m, N/m] on ``x``, global components.
        Q : array_like, shape (2,) or (nt, 2), optional
            [N] on ``x``.

        Returns
        -------
        dict
            ``"M"``, ``"C"``, ``"K"`` (nt, N, N) and/or ``"Q"`` (nt, N): what a hook's ``terms``
            returns.
        """
        if joint not in self.model.joint_point:
            raise InputError(f"joint_terms: unknown joint {joint!r} (joints: {', '.join(self.model.joint_point)})")
        cols, E, E1, E2, p, p1, p2 = self.model.entity_forms(motion)["P"][self.model.joint_point[joint]]
        nt, N = motion.n, self.model.n_dof
        M, C, K = (None if X is None else np.broadcast_to(np.asarray(X, float), (nt, 2, 2)) for X in (M, C, K))
        Q = None if Q is None else np.broadcast_to(np.asarray(Q, float), (nt, 2))
        moving = self.transport and E1 is not None
        Et = np.swapaxes(E, -1, -2)
        q = {"M": None, "C": None, "K": None}
        if M is not None:
            q["M"] = Et @ M @ E
        if C is not None or (moving and M is not None):
            q["C"] = (Et @ C @ E if C is not None else 0.0) + (2.0 * Et @ M @ E1 if moving and M is not None else 0.0)
        if K is not None or (moving and (M is not None or C is not None)):
            q["K"] = sum(x for x in (Et @ K @ E if K is not None else None,
                                     Et @ C @ E1 if moving and C is not None else None,
                                     Et @ M @ E2 if moving and M is not None else None) if x is not None)
        Qx = None if Q is None else Q.copy()
        if p is not None and not self.frame:
            for A, off in ((K, p), (C, p1), (M if self.offset_inertia else None, p2)):
                if A is not None and off is not None:
                    Qx = (0.0 if Qx is None else Qx) - (A @ off[..., None])[..., 0]
        out = {}
        ix = np.asarray(cols, dtype=int)
        for key, val in q.items():
            if val is not None and ix.size:
                full = np.zeros((nt, N, N))
                full[:, ix[:, None], ix[None, :]] = np.broadcast_to(val, (nt, ix.size, ix.size))
                out[key] = full
        if Qx is not None and ix.size:
            full = np.zeros((nt, N))
            full[:, ix] = (Et @ Qx[..., None])[..., 0]
            out["Q"] = full
        return out

    def _effect_terms(self, chunk: Chunk):
        """The chosen effects' q-space terms (``Effect.terms``): (key, array) pairs."""
        for e in self.chosen:
            for key, val in (e.terms(self, chunk) or {}).items():
                if key not in ("M", "C", "K", "Q"):
                    raise KedError(f"effect {e.name!r}: terms() returned an unknown key {key!r}")
                yield key, val

    def system(self, idx=None) -> SystemTerms:
        """Linear (state-independent) terms at time nodes ``idx``.

        Parameters
        ----------
        idx : array_like of int, optional
            Time node indices; default all.

        Returns
        -------
        SystemTerms
            ``M, C, K`` (nt, N, N) and ``Q`` (nt, N) in q-space.
        """
        idx = np.arange(self.motion.n) if idx is None else np.asarray(idx)
        nt, N = idx.size, self.model.n_dof
        chunk = self._chunk(idx)
        field = self.damping_field if isinstance(self.damping, ModalDamping) else None
        keys = ("M", "C", "K") if field is not None or self.damping is None else ("M", "C", "K", "Ks")
        groups = self._to_q(chunk, structural="Ks" in keys)
        tot = {k: np.zeros((nt, N, N)) for k in keys}
        tot["Q"] = np.zeros((nt, N))
        for gname, out in groups.items():
            for key in keys:
                if key in out:
                    self.model.scatter_matrix(gname, out[key], out=tot[key])
            if "Q" in out:
                self.model.scatter_vector(gname, out["Q"], out=tot["Q"])
        for key, val in self._effect_terms(chunk):
            tot[key] += val
        if field is not None:
            tot["C"] += field.at(chunk.motion.t)
        elif self.damping is not None:
            tot["C"] += self.damping_matrix(tot["M"], tot["Ks"])
        return SystemTerms(tot["M"], tot["C"], tot["K"], tot["Q"])

    def sparse_system(self, node: int = 0):
        """Terms at one time node as scipy.sparse CSR matrices (COO -> CSR scatter).

        Returns
        -------
        M, C, K : scipy.sparse.csr_matrix, shape (N, N)
        Q : ndarray, shape (N,)
        """
        N = self.model.n_dof
        chunk = self._chunk(np.array([node]))
        tot = {k: sp.csr_matrix((N, N)) for k in ("M", "C", "K", "Ks")}
        Q = np.zeros(N)
        for gname, out in self._to_q(chunk).items():
            for key in tot:
                if key in out:
                    tot[key] = tot[key] + self.model.scatter_sparse(gname, out[key][0])
            if "Q" in out:
                Q += self.model.scatter_vector(gname, out["Q"])[0]
        for key, val in self._effect_terms(chunk):
            if key == "Q":
                Q += val[0]
            else:
                tot[key] = tot[key] + sp.csr_matrix(val[0])
        if isinstance(self.damping, Rayleigh):
            tot["C"] = tot["C"] + self.damping_matrix(tot["M"], tot["Ks"])
        elif self.damping is not None:
            Cd = self.damping_matrix(tot["M"].toarray()[None], tot["Ks"].toarray()[None])[0]
            tot["C"] = tot["C"] + sp.csr_matrix(Cd)
        return tot["M"], tot["C"], tot["K"], Q

    def structural(self, idx=None):
        """Mass and structural stiffness only (no effects, no damping), each (nt, N, N) [kg, N/m]."""
        idx = np.arange(self.motion.n) if idx is None else np.asarray(idx)
        mo = slice_motion(self.motion, idx)
        chunk = Chunk(mo, idx, self._beam_kinematics(mo))
        self._structure_terms(chunk, damped=False)
        nt, N = idx.size, self.model.n_dof
        M = np.zeros((nt, N, N))
        Ks = np.zeros((nt, N, N))
        for gname, out in self._to_q(chunk).items():
            if "M" in out:
                self.model.scatter_matrix(gname, out["M"], out=M)
            if "Ks" in out:
                self.model.scatter_matrix(gname, out["Ks"], out=Ks)
        return M, Ks

    def axial_share(self, idx=None) -> np.ndarray:
        """Share of each DOF's diagonal structural stiffness that the links' axial stiffness carries.

        ``diag(K_axial) / diag(K_structural)`` at time nodes ``idx`` (default
        all), shape (nt, N): near 1 for the directions a link's axial
        stiffness holds (its interior axial translations, a slider's travel,
        a joint translation along a link, a rigid member's rotation resisted
        by links pushing and pulling on it), near 0 for bending.
        """
        if idx is None:
            idx = np.arange(self.motion.n)
        idx = np.asarray(idx)
        b = self.model.beam
        M, Ks = self.structural(idx)
        d_all = np.diagonal(Ks, axis1=-2, axis2=-1)
        if not b.L.size:
            return np.zeros_like(d_all)
        mo = slice_motion(self.motion, idx)
        T = self._beam_kinematics(mo).T
        ka = el.frame_stiffness(b.L, b.EA, np.zeros_like(b.EI))  # EI = 0: the axial part alone
        Kx = np.swapaxes(T, -1, -2) @ ka @ T
        dyn = self.model.has_moving_maps() or self.model.has_offsets()
        gm = self.model.group_map("beam", mo, self.model.entity_forms(mo) if dyn else None)
        E = gm.E
        Kq = np.broadcast_to(np.swapaxes(E, -1, -2) @ Kx @ E, (idx.size,) + (E.shape[1], E.shape[3], E.shape[3]))
        d_ax = np.diagonal(self.model.scatter_matrix("beam", Kq), axis1=-2, axis2=-1)
        return d_ax / np.where(d_all > 0, d_all, 1.0)

    def damping_matrix(self, M, Ks):
        """q-space damping of the scene's damping model from mass and structural stiffness
        (:func:`kedfem.fe.damping.damping_matrix`), (nt, N, N) [N s/m]."""
        return damping_matrix(self.damping, M, Ks, self.model.mech.name, self.model.dof_labels)

    # ----------------------------------------------------------- state terms
    def _state_map(self, gname, mo):
        """Group map of ``gname`` over ``mo``; kept when ``mo`` is the whole cycle.

        The non-linear iteration evaluates the state terms over the same cycle
        at every iterate: the constraint maps (and the entity forms they are
        built from) depend on the motion only, so they are built once.
        """
        if mo is not self.motion:
            return self.model.group_map(gname, mo)
        gm = self._full_maps.get(gname)
        if gm is None:
            if self._full_forms is None and (self.model.has_moving_maps() or self.model.has_offsets()):
                self._full_forms = self.model.entity_forms(mo)
            gm = self._full_maps[gname] = self.model.group_map(gname, mo, self._full_forms)
        return gm

    def local_beam_map(self, mo):
        """The beam elements' map from the unknowns to their local DOFs over ``mo`` (kept when
        ``mo`` is the whole cycle, as :meth:`_state_map`): ``d = T (E q + p) = A q + T p``.

        Returns ``(A, Tp, T, gm)``: ``A = T E`` as a :class:`~kedfem.fe.maps.GroupMap` of the
        group's layout (its ``E`` the product, no derivatives or offsets), ``T p`` (nt, n_el, 6)
        or None, the rotations ``T`` (nt, n_el, 6, 6) and the group map ``gm`` itself. The
        state terms of every iterate map through the product once instead of through ``E`` and
        ``T`` in turn (two products of small matrices fewer each way).
        """
        if mo is self.motion and self._local_beam is not None:
            return self._local_beam
        gm = self._state_map("beam", mo)
        T = el.rotation_blocks(mo.theta[:, self.beam_member])
        A = GroupMap(gm.cols, T @ gm.E, None, None, None, None, None)
        Tp = (T @ gm.p[..., None])[..., 0] if gm.p is not None else None
        out = (A, Tp, T, gm)
        if mo is self.motion:
            self._local_beam = out
        return out

    def element_state(self, gname, mo, U, V=None):
        """Element DOFs of a group for the trial response ``U, V``.

        Returns ``x = E q + p`` (total elastic, incl. prescribed offsets), its
        rate ``x'`` (None without ``V``), the part ``E q`` that the unknowns
        carry, and the group map; arrays (nt, n_el, d).
        """
        gm = self._state_map(gname, mo)
        xq = gm.apply(U)  # (nt, n_el, d)
        x = xq + gm.p if gm.p is not None else xq
        xd = None
        if V is not None:
            xd = gm.apply(V)
            if gm.E1 is not None:
                xd = xd + gm.apply(U, E=gm.E1)
            if gm.p1 is not None:
                xd = xd + gm.p1
        return x, xd, xq, gm

    def state_terms(self, U, V, idx=None):
        """State-dependent terms of the chosen effects for the trial response ``U, V`` (n, N).

        Returns
        -------
        dC : ndarray, shape (n, N, N) or None
            Tangent damping of the state-dependent effects (velocity-dependent friction).
        dK : ndarray, shape (n, N, N) or None
            Tangent stiffness of the state-dependent effects.
        dQ : ndarray, shape (n, N) or None
            Matching load, ``-f_nl(x) + K_nl x + C_nl x'`` so that a fixed point of
            the linear solve satisfies the non-linear equations (Newton's
            linearisation about the trial response). All None if no chosen
            effect depends on the state.
        """
        if idx is None:
            idx = np.arange(self.motion.n)
            mo = self.motion  # the whole cycle: the group maps are reused across iterates
        else:
            mo = slice_motion(self.motion, idx)
        active = [e for e in self.chosen if e.state_dependent(self.mech)]
        if not active:
            return None, None, None
        nt, N = len(idx), self.model.n_dof
        out = StateTerms(np.zeros((nt, N, N)), np.zeros((nt, N)))
        for e in active:
            e.state_terms(self, mo, U, V, out)
        return out.dC, out.dK, out.dQ

    def apply_state(self, gname, gm, Kx, Qx, dK, dQ, right=None) -> None:
        """Add element-coordinate state terms of group ``gname`` to q-space arrays.

        ``dK += E^T Kx R`` (``R = right`` or ``E``), ``dQ += E^T Qx``; ``Kx``
        (nt, n_el, d, d) and ``Qx`` (nt, n_el, d) may be None.
        """
        E = gm.E
        R = E if right is None else right
        nt = dK.shape[0]
        for key, els, m in self._narrow_parts(gname, E.shape[-1]):  # each bucket at its own width
            Ek, Rk = E[:, els, :, :m], R[:, els, :, :m]  # (a block widens a few elements only)
            Et = np.swapaxes(Ek, -1, -2)
            if Kx is not None:  # added into dK, dQ (in place: no (nt, N, N) temporary)
                self.model.scatter_matrix(key, np.broadcast_to(Et @ Kx[:, els] @ Rk, (nt,) + (Ek.shape[1], m, m)),
                                          out=dK)
            if Qx is not None:
                self.model.scatter_vector(key, np.broadcast_to((Et @ Qx[:, els, :, None])[..., 0],
                                                               (nt,) + (Ek.shape[1], m)), out=dQ)

    def _narrow_parts(self, gname: str, width: int) -> list:
        """``(key, elements, width)`` of a group's buckets (:meth:`FEModel.buckets`) when the whole
        group's map (``width`` columns) holds each bucket's columns first, in its order; else the
        group whole. The state terms are built on the whole group's map (one map for all its
        elements); scattered per bucket, the elements away from a block keep their narrow width."""
        cache = self.__dict__.setdefault("_parts_cache", {})
        if (gname, width) not in cache:
            full = self.model._static_layout(gname).cols
            parts = [(gname, slice(None), width)]
            buckets = self.model.buckets(gname)
            if len(buckets) > 1 and full.shape[1] == width:
                cand = []
                for key, els in buckets.items():
                    cols = self.model._static_layout(key).cols
                    m = cols.shape[1]
                    beyond = full[els, m:]
                    if not (np.array_equal(full[els, :m], cols) and (beyond >= self.model.n_dof).all()):
                        cand = None
                        break
                    cand.append((key, els, m))
                parts = cand or parts
            cache[(gname, width)] = parts
        return cache[(gname, width)]
