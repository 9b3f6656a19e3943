"""DOF numbering from the mechanism graph, constraint maps and scatter.

Elastic displacements are expressed in the global frame. Every component
(beam element, rigid member's mass, point mass, spring, load) acts on a few
*entities*: translation points (2 components) and rotations (1). An entity
is an affine function of the independent generalized coordinates ``q``:

* points: ``fixed`` (ground joint), ``free`` (two q's), ``slider`` (one q
  along the slider's axis) or ``body`` (slaved to a rigid member group:
  ``x_P = x_ref + phi S rho_P(t)`` with ``rho_P = r_P - r_ref`` turning with
  the member),
* rotations: ``free`` (own q), ``fixed`` or ``tied`` to a master rotation,
  plus a prescribed offset ``p(t)`` where an elastically clamped end sits on
  a kinematic pin (the change of relative rigid-body angle).

Per component the element DOFs are ``x = E(t) q_e + p(t)``; the assembler
forms ``E^T M E``, ``E^T (C E + 2 M E')``, ``E^T (K E + C E' + M E'')`` and
``E^T (Q - M p'' - C p' - K p)`` batched over time nodes and elements, and
scatters them once through a sparse operator built from the element DOF
index map (``(n_el, m)``, COO -> CSR).

Rules (docs/theory.md section 2): revolute joints share translations and keep
separate rotations; welded joints share rotations; sliders constrain the
normal direction; rigid links add no elastic DOFs of their own (a rigid
member group has at most a reference translation and one rotation); the
driven member's elastic rotation at its ground joint is fixed, or tied to
the motor through the drive's torsional spring.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import InputError, did_you_mean
from ..motion.kinematics import Motion
from ..model.mechanism import Mechanism

__all__ = ["FEModel", "GroupMap", "PointDof", "RotDof", "Group"]

log = logging.getLogger(__name__)

_S = np.array([[0.0, -1.0], [1.0, 0.0]])


@dataclass(frozen=True)
class PointDof:
    """A translation entity (see module docstring)."""

    kind: str
    label: str
    cols: tuple[int, ...] = ()
    axis: tuple[float, float] | None = None
    parent: int = -1
    phi: int = -1
    loc: tuple = ()
    block: int = -1  # kind "cb": Craig-Bampton block and interior node index
    node: int = -1


@dataclass(frozen=True)
class RotDof:
    """A rotation entity: ``theta_e = q[cols] + offset``.

    The offset is ``(theta_master - theta_master_ref) - (theta_member -
    theta_member_ref)`` when ``offset`` is True (``master`` None = frame).
    """

    kind: str
    label: str
    cols: tuple[int, ...] = ()
    member: str | None = None
    master: str | None = None
    offset: bool = False
    block: int = -1  # kind "cb": Craig-Bampton block and interior node index
    node: int = -1


@dataclass
class Group:
    """Components of one kind: entity layout and entity ids per element."""

    name: str
    layout: tuple[str, ...]
    ids: np.ndarray  # (n_el, len(layout)), -1 = frame (fixed, no DOFs)
    meta: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return int(self.ids.shape[0])

    @property
    def d(self) -> int:
        return sum(2 if s == "P" else 1 for s in self.layout)


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


@dataclass(frozen=True)
class BeamData:
    """Flexible-link elements, concatenated over links (arrays of shape (n_el,))."""

    link: np.ndarray        # index into links list
    links: tuple[str, ...]
    L: np.ndarray
    EA: np.ndarray
    EI: np.ndarray
    rhoA: np.ndarray
    GAs: np.ndarray
    s1: np.ndarray          # start of element from joint a [m]
    lumped: np.ndarray      # bool
    timoshenko: np.ndarray  # bool
    first: dict             # link name -> first element index
    count: dict             # link name -> number of elements


class FEModel:
    """Finite-element model of a mechanism: DOF map and element groups.

    Parameters
    ----------
    mechanism : Mechanism
        The mechanism (validated here).

    Attributes
    ----------
    n_dof : int
        Number of independent elastic DOFs ``N``.
    dof_labels : list of str
        One label per DOF, e.g. ``"B.ux"`` (joint, global), ``"A.u[crank]"`` (joint, in the
        frame of its stiffest link), ``"rod.n3.v"`` (interior node,
        transverse in the link frame), ``"rod.n3.theta"``.
    groups : dict of str -> Group
        ``beam``, ``rigid``, ``pmass``, ``spring``, ``tspring``, ``load``.
    reduction : CraigBampton or None
        Craig-Bampton reduction of flexible links (see :mod:`kedfem.fe.reduction`).
    corotate : bool
        Interior nodes of flexible links carry their translations in the link's
        rotating frame (``x = R(theta) q``: DOFs ``link.nK.u`` axial, ``.v``
        transverse), default; ``False`` keeps global components (``.ux``,
        ``.uy``). Both are exact changes of variables (the time derivatives of
        the map enter through the ``coupling`` effect), but in the co-rotating
        DOFs the stiff element couplings do not turn with the link, so the
        time discretisation error is far smaller, and switching ``coupling``
        off gives the classical link-frame KED model without coupling.
    """

    def __init__(self, mechanism: Mechanism, reduction=None, corotate: bool = True):
        from .reduction import CraigBampton
        self.corotate = bool(corotate)
        mechanism.validate()
        if reduction is not None and not isinstance(reduction, CraigBampton):
            raise InputError(f"reduction must be kf.CraigBampton(...) or None, got {reduction!r}")
        if reduction is not None and reduction.links is not None:
            for name in reduction.links:
                if name not in mechanism.links or mechanism.links[name].rigid:
                    raise InputError(f"CraigBampton: '{name}' is not a flexible link of {mechanism.name}")
        self.reduction = reduction
        self.blocks: list[dict] = []  # Craig-Bampton blocks, one per reduced link
        self.mech = mechanism
        self.points: list[PointDof] = []
        self.rots: list[RotDof] = []
        self.dof_labels: list[str] = []
        self.joint_point: dict[str, int] = {}
        self.end_rot: dict[tuple[str, str], int] = {}   # (flexible link, joint) -> rot id
        self.member_rot: dict[str, int] = {}            # rigid member -> group rot id (-1 fixed)
        self.member_com: dict[str, int] = {}            # rigid member -> CoM point id
        self.rigid_groups: list[dict] = []
        self._build_rigid_groups()
        self._build_joint_points()
        self._build_beams()
        self._build_groups()
        self.n_dof = len(self.dof_labels)
        if self.n_dof == 0:
            raise InputError(f"{mechanism.name}: the model has no elastic DOFs (all links rigid and fixed)")
        self._scatter_cache: dict = {}
        self._static_cache: dict = {}
        log.debug("FE model of %s: %d DOFs, %d beam elements", mechanism.name, self.n_dof,
                  self.beam.L.size)

    # ------------------------------------------------------------------ build
    def _new_q(self, label: str) -> int:
        self.dof_labels.append(label)
        return len(self.dof_labels) - 1

    def _add_point(self, pd: PointDof) -> int:
        self.points.append(pd)
        return len(self.points) - 1

    def _add_rot(self, rd: RotDof) -> int:
        self.rots.append(rd)
        return len(self.rots) - 1

    def _member_joints(self, name):
        mech = self.mech
        return mech.links[name].joints if name in mech.links else mech.bodies[name].joints

    def _com_loc(self, name):
        mech = self.mech
        if name in mech.links:
            lk = mech.links[name]
            a, b = np.array(mech.joints[lk.a].at), np.array(mech.joints[lk.b].at)
            return ("member", name, lk.a, 0.5 * (b - a))
        body = mech.bodies[name]
        o = body.joints[0]
        return ("member", name, o, np.array(body.cm) - np.array(mech.joints[o].at))

    def _build_rigid_groups(self):
        mech = self.mech
        rigid = [n for n, lk in mech.links.items() if lk.rigid] + list(mech.bodies)
        # union-find over welded joints
        parent = {m: m for m in rigid}

        def find(x):
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        for j in mech.joints.values():
            if j.welded and j.kind != "ground":
                here = [m for m in mech.members_at(j.name) if m in parent]
                for m in here[1:]:
                    parent[find(m)] = find(here[0])
        groups: dict[str, list[str]] = {}
        for m in rigid:
            groups.setdefault(find(m), []).append(m)
        glist = list(groups.values())
        atts = [{j for m in g for j in self._member_joints(m)} for g in glist]
        # resolution order: breadth first from grounded groups through shared joints,
        # so that a group pinned to an already resolved group takes that joint as reference
        grounded = [i for i, a in enumerate(atts)
                    if any(mech.joints[j].kind == "ground" for j in a)]
        order, seen = [], set()
        starts = grounded + [i for i in range(len(glist)) if i not in grounded]
        for s0 in starts:
            if s0 in seen:
                continue
            queue = [s0]
            seen.add(s0)
            while queue:
                i = queue.pop(0)
                order.append(i)
                for k in range(len(glist)):
                    if k not in seen and atts[i] & atts[k]:
                        seen.add(k)
                        queue.append(k)
        self._rigid_joint_points = {}
        for i in order:
            self._resolve_rigid_group(glist[i])

    def _resolve_rigid_group(self, members):
        mech = self.mech
        name = "+".join(members)
        atts = []
        for m in members:
            for j in self._member_joints(m):
                if j not in atts:
                    atts.append(j)
        sliders = [j for j in atts if mech.joints[j].kind == "slider"]
        if sliders:
            raise InputError(f"rigid member '{members[0]}' attaches to slider joint '{sliders[0]}': a slider on "
                             "a rigid member is not supported; make that link flexible")
        grounded = [j for j in atts if mech.joints[j].kind == "ground"]
        shared = [j for j in atts if j in self._rigid_joint_points]
        drive = next((mech.driven(m) for m in members if mech.driven(m) is not None), None)
        if len(grounded) >= 2:
            ref_pt = self._add_point(PointDof("fixed", f"{name}.ref"))
            phi = -1
        elif len(grounded) == 1:
            g = grounded[0]
            closing = [j for j in shared if mech.joints[j].kind != "ground"]
            if closing:
                # groups are resolved breadth first from the grounded ones: a grounded group that
                # meets an already resolved rigid group closes a loop of rigid members with the frame
                raise InputError(f"rigid member(s) '{name}' close a loop of rigid members with the frame "
                                 f"(through joint {g} and joint(s) {', '.join(closing)}): such a loop has "
                                 "no elastic freedom and its rotations would be spurious DOFs; make at "
                                 "least one link of the loop flexible")
            ref_pt = self._add_point(PointDof("fixed", g, loc=("joint", g)))
            self._rigid_joint_points[g] = ref_pt
            if mech.joints[g].welded:
                phi = -1
            elif drive is not None:
                if drive.torsional_stiffness is not None:
                    q = self._new_q(f"{drive.member}.phi")
                    phi = self._add_rot(RotDof("free", f"{drive.member}.phi", (q,), members[0]))
                else:
                    phi = -1
            else:
                q = self._new_q(f"{name}.phi")
                phi = self._add_rot(RotDof("free", f"{name}.phi", (q,), members[0]))
        else:
            if len(shared) > 1:
                raise InputError(f"rigid members '{name}' and their neighbours form a closed rigid chain "
                                 f"through joints {', '.join(shared)}: make one of these links flexible")
            if shared:
                ref_pt = self._rigid_joint_points[shared[0]]
            else:
                loc = self._com_loc(members[0])
                qx = self._new_q(f"{members[0]}.ux")
                qy = self._new_q(f"{members[0]}.uy")
                ref_pt = self._add_point(PointDof("free", f"{members[0]}.cm", (qx, qy), loc=loc))
            q = self._new_q(f"{name}.phi")
            phi = self._add_rot(RotDof("free", f"{name}.phi", (q,), members[0]))
        ref_loc = self.points[ref_pt].loc

        def slaved(label, loc):
            pdef = self.points[ref_pt]
            if phi < 0 and pdef.kind == "fixed":
                return self._add_point(PointDof("fixed", label, loc=loc))
            return self._add_point(PointDof("body", label, parent=ref_pt, phi=phi, loc=loc))

        for j in atts:
            if j in self._rigid_joint_points:
                continue
            self._rigid_joint_points[j] = slaved(j, ("joint", j))
        for m in members:
            loc = self._com_loc(m)
            if ref_loc and ref_loc[0] == "member" and ref_loc[1] == m:
                self.member_com[m] = ref_pt
            else:
                self.member_com[m] = slaved(f"{m}.cm", loc)
            self.member_rot[m] = phi
        self.rigid_groups.append({"members": tuple(members), "ref": ref_pt, "phi": phi,
                                  "drive": drive})

    def _build_joint_points(self):
        mech = self.mech
        for jn, j in mech.joints.items():
            if jn in self._rigid_joint_points:
                self.joint_point[jn] = self._rigid_joint_points[jn]
            elif j.kind == "ground":
                self.joint_point[jn] = self._add_point(PointDof("fixed", jn, loc=("joint", jn)))
            elif j.kind == "slider":
                q = self._new_q(f"{jn}.s")
                self.joint_point[jn] = self._add_point(PointDof("slider", jn, (q,), axis=j.axis,
                                                                loc=("joint", jn)))
            else:
                frame = self._joint_frame(jn) if self.corotate else None
                if frame is None:
                    qx = self._new_q(f"{jn}.ux")
                    qy = self._new_q(f"{jn}.uy")
                    self.joint_point[jn] = self._add_point(PointDof("free", jn, (qx, qy), loc=("joint", jn)))
                else:  # components in the frame of the stiffest flexible link at the joint
                    qx = self._new_q(f"{jn}.u[{frame}]")
                    qy = self._new_q(f"{jn}.v[{frame}]")
                    self.joint_point[jn] = self._add_point(PointDof("corot", jn, (qx, qy),
                                                                    loc=("member", frame, jn, (0.0, 0.0))))

    def _joint_frame(self, joint: str):
        """The flexible (kinematic) link at a joint with the largest axial element stiffness."""
        best, kmax = None, 0.0
        for name in self.mech.members_at(joint):
            lk = self.mech.links.get(name)
            if lk is None or lk.rigid or not lk.kinematic:
                continue
            k = lk.material.E * lk.section.A * lk.elements / lk.length
            if k > kmax:
                best, kmax = name, k
        return best

    def _end_rotation(self, lk, joint, k, clamp_groups):
        mech = self.mech
        jt = mech.joints[joint]
        label = f"{lk.name}.theta@{joint}"
        drive = mech.driven(lk.name)
        if drive is not None and drive.ground_joint == joint:
            if drive.torsional_stiffness is not None:
                q = self._new_q(label)
                return self._add_rot(RotDof("free", label, (q,), lk.name))
            return self._add_rot(RotDof("fixed", label, (), lk.name))
        clamped = lk.ends[k] == "clamp" or jt.welded
        if not clamped:
            q = self._new_q(label)
            return self._add_rot(RotDof("free", label, (q,), lk.name))
        if jt.kind == "ground":
            return self._add_rot(RotDof("fixed", label, (), lk.name, None, offset=True))
        rigid_here = [m for m in mech.members_at(joint) if m in self.member_rot]
        if rigid_here:
            groups = {self.member_rot[m] for m in rigid_here}
            if len(groups) > 1:
                raise InputError(f"link '{lk.name}' is clamped at joint '{joint}' where several rigid "
                                 "members pivot; weld the joint or pin the link")
            phi = self.member_rot[rigid_here[0]]
            master = rigid_here[0]
            if phi < 0:
                return self._add_rot(RotDof("fixed", label, (), lk.name, master, offset=True))
            return self._add_rot(RotDof("tied", label, self.rots[phi].cols, lk.name, master, offset=True))
        if joint not in clamp_groups:
            q = self._new_q(f"{joint}.theta")
            rid = self._add_rot(RotDof("free", label, (q,), lk.name))
            clamp_groups[joint] = (rid, lk.name)
            return rid
        rid0, master = clamp_groups[joint]
        return self._add_rot(RotDof("tied", label, self.rots[rid0].cols, lk.name, master, offset=True))

    def _build_beams(self):
        mech = self.mech
        clamp_groups: dict = {}
        rows = {k: [] for k in ("link", "L", "EA", "EI", "rhoA", "GAs", "s1", "lumped", "timo")}
        ids = []
        first, count = {}, {}
        names = []
        for li, lk in enumerate(mech.flexible_links):
            names.append(lk.name)
            ne = lk.elements
            le = lk.length / ne
            mat, sec = lk.material, lk.section
            first[lk.name] = len(rows["L"])
            count[lk.name] = ne
            ra = self._end_rotation(lk, lk.a, 0, clamp_groups)
            self.end_rot[(lk.name, lk.a)] = ra
            node_pts = [self.joint_point[lk.a]]
            node_rots = [ra]
            pa = np.array(mech.joints[lk.a].at)
            e1 = (np.array(mech.joints[lk.b].at) - pa) / lk.length
            reduced = self.reduction is not None and self.reduction.applies_to(lk)
            if reduced:
                from .reduction import craig_bampton_basis
                Psi, Phi, om = craig_bampton_basis(lk, self.reduction.modes,
                                                   self.reduction.static_correction)
                bi = len(self.blocks)
                mcols = tuple(self._new_q(f"{lk.name}.eta{j + 1}") for j in range(Phi.shape[1]))
                blk = {"link": lk.name, "Psi": Psi, "Phi": Phi, "omega": om, "modal": mcols,
                       "bounds": None, "pts": [], "rots": []}
                self.blocks.append(blk)
            for i in range(1, ne):
                if reduced:
                    node_pts.append(self._add_point(PointDof(
                        "cb", f"{lk.name}.n{i}", (), loc=("member", lk.name, lk.a, i * le * e1),
                        block=bi, node=i - 1)))
                    node_rots.append(self._add_rot(RotDof("cb", f"{lk.name}.n{i}.theta", (), lk.name,
                                                          block=bi, node=i - 1)))
                    continue
                if self.corotate:
                    qx = self._new_q(f"{lk.name}.n{i}.u")
                    qy = self._new_q(f"{lk.name}.n{i}.v")
                    kind = "corot"
                else:
                    qx = self._new_q(f"{lk.name}.n{i}.ux")
                    qy = self._new_q(f"{lk.name}.n{i}.uy")
                    kind = "free"
                qt = self._new_q(f"{lk.name}.n{i}.theta")
                node_pts.append(self._add_point(PointDof(kind, f"{lk.name}.n{i}", (qx, qy),
                                                         loc=("member", lk.name, lk.a, i * le * e1))))
                node_rots.append(self._add_rot(RotDof("free", f"{lk.name}.n{i}.theta", (qt,), lk.name)))
            rb = self._end_rotation(lk, lk.b, 1, clamp_groups)
            self.end_rot[(lk.name, lk.b)] = rb
            node_pts.append(self.joint_point[lk.b])
            node_rots.append(rb)
            if reduced:
                blk["bounds"] = (node_pts[0], ra, node_pts[-1], rb)
            for i in range(ne):
                ids.append((node_pts[i], node_rots[i], node_pts[i + 1], node_rots[i + 1]))
                rows["link"].append(li)
                rows["L"].append(le)
                rows["EA"].append(mat.E * sec.A)
                rows["EI"].append(mat.E * sec.I)
                rows["rhoA"].append(mat.rho * sec.A)
                rows["GAs"].append(sec.kappa * mat.G * sec.A)
                rows["s1"].append(i * le)
                rows["lumped"].append(lk.mass_matrix == "lumped")
                rows["timo"].append(lk.timoshenko)
        arr = {k: np.asarray(v, dtype=float) for k, v in rows.items()}
        self.beam = BeamData(arr["link"].astype(int), tuple(names), arr["L"], arr["EA"], arr["EI"],
                             arr["rhoA"], arr["GAs"], arr["s1"], arr["lumped"].astype(bool),
                             arr["timo"].astype(bool), first, count)
        self._beam_ids = np.asarray(ids, dtype=int).reshape(-1, 4)

    def rotation_at(self, joint: str, member: str | None) -> int:
        """Rotation entity id of ``member`` at ``joint`` (-1: the frame or fixed)."""
        if member is None:
            return -1
        if member in self.member_rot:
            return self.member_rot[member]
        if (member, joint) in self.end_rot:
            return self.end_rot[(member, joint)]
        raise InputError(f"member '{member}' is not attached at joint '{joint}'")

    def _unique_rotation(self, joint: str) -> int:
        rids = set()
        for m in self.mech.members_at(joint):
            r = self.rotation_at(joint, m)
            rids.add(r if r < 0 or self.rots[r].cols else -1)
        cols = {self.rots[r].cols for r in rids if r >= 0}
        if len(cols) > 1:
            raise InputError(f"point mass with rotary inertia J at joint '{joint}': the members meeting "
                             "there rotate independently; weld the joint or put J on one member")
        return next((r for r in rids if r >= 0), -1)

    def _build_groups(self):
        mech = self.mech
        groups = {}
        groups["beam"] = Group("beam", ("P", "R", "P", "R"), self._beam_ids)
        rig = [(self.member_com[m], self.member_rot[m]) for m in self.member_com
               if (mech.links[m].mass if m in mech.links else mech.bodies[m].mass) > 0
               or (mech.links[m].J if m in mech.links else mech.bodies[m].J) > 0]
        rig_names = [m for m in self.member_com
                     if (mech.links[m].mass if m in mech.links else mech.bodies[m].mass) > 0
                     or (mech.links[m].J if m in mech.links else mech.bodies[m].J) > 0]
        groups["rigid"] = Group("rigid", ("P", "R"), np.asarray(rig, int).reshape(-1, 2),
                                {"members": rig_names})
        pm = []
        for p in mech.point_masses:
            rid = self._unique_rotation(p.joint) if p.J > 0 else -1
            pm.append((self.joint_point[p.joint], rid))
        groups["pmass"] = Group("pmass", ("P", "R"), np.asarray(pm, int).reshape(-1, 2),
                                {"items": list(mech.point_masses)})
        spr = [(self.joint_point[s.a], self.joint_point[s.b] if s.b is not None else -1)
               for s in mech.springs.values()]
        groups["spring"] = Group("spring", ("P", "P"), np.asarray(spr, int).reshape(-1, 2),
                                 {"items": list(mech.springs.values())})
        ts, titems = [], []
        for t in mech.torsional_springs.values():
            ts.append((self.rotation_at(t.joint, t.member), self.rotation_at(t.joint, t.other)))
            titems.append(("spring", t))
        for d in mech.drives:
            if d.torsional_stiffness is not None:
                ts.append((self.rotation_at(d.ground_joint, d.member), -1))
                titems.append(("drive", d))
        groups["tspring"] = Group("tspring", ("R", "R"), np.asarray(ts, int).reshape(-1, 2),
                                  {"items": titems})
        loads = [(self.joint_point[ld.joint],) for ld in mech.loads.values()]
        loads += [(self.joint_point[f.joint],) for f in mech.frictions.values()]
        groups["load"] = Group("load", ("P",), np.asarray(loads, int).reshape(-1, 1),
                               {"items": list(mech.loads.values()) + list(mech.frictions.values())})
        self.groups = {k: g for k, g in groups.items()}

    # ------------------------------------------------------------ evaluation
    def _loc_motion(self, loc, motion: Motion):
        if loc[0] == "joint":
            j = motion.joint_names.index(loc[1])
            return motion.r[:, j], motion.v[:, j], motion.a[:, j]
        _k, member, origin, offset = loc
        return motion.point(member, origin, offset)

    # Every entity has an affine *form* over the time nodes:
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
            else:
                out = self._block_cols(pd.block)
        else:
            rd = self.rots[eid]
            out = self._block_cols(rd.block) if rd.kind == "cb" else rd.cols
        cache[key] = out
        return out

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
            return False, False
        rd = self.rots[eid]
        if rd.kind == "cb":
            return True, self._block_offset(rd.block)
        return False, rd.offset

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

    def entity_forms(self, motion: Motion) -> dict:
        """Affine forms of all entities over the motion's time nodes.

        Returns
        -------
        dict
            ``{"P": [...], "R": [...]}``, each item ``(cols, C, C1, C2, p, p1, p2)``
            with ``C`` (nt or 1, width, k) and its time derivatives (None if
            constant), and the prescribed offset ``p`` (nt, width) with its
            derivatives (None if there is none).
        """
        nt = motion.n
        rp, rp1, rp2 = self.rot_offsets(motion) if any(rd.offset for rd in self.rots) else (None,) * 3
        pforms: list = [None] * len(self.points)
        rforms: list = [None] * len(self.rots)
        locs: dict = {}
        blocks: dict = {}

        def loc_state(pid):
            if pid not in locs:
                locs[pid] = self._loc_motion(self.points[pid].loc, motion)
            return locs[pid]

        def rform(rid):
            if rforms[rid] is not None:
                return rforms[rid]
            rd = self.rots[rid]
            if rd.kind == "cb":
                out = block(rd.block)[rd.node][1]
            else:
                k = len(rd.cols)
                C = np.ones((1, 1, k))
                if rd.offset:
                    p = (rp[:, rid:rid + 1], rp1[:, rid:rid + 1], rp2[:, rid:rid + 1])
                else:
                    p = (None, None, None)
                out = (rd.cols, C, None, None) + p
            rforms[rid] = out
            return out

        def pform(pid):
            if pforms[pid] is not None:
                return pforms[pid]
            pd = self.points[pid]
            none3 = (None, None, None)
            if pd.kind == "fixed":
                out = ((), np.zeros((1, 2, 0)), None, None) + none3
            elif pd.kind == "free":
                out = (pd.cols, np.eye(2)[None], None, None) + none3
            elif pd.kind == "slider":
                out = (pd.cols, np.asarray(pd.axis, float).reshape(1, 2, 1), None, None) + none3
            elif pd.kind == "cb":
                out = block(pd.block)[pd.node][0]
            elif pd.kind == "corot":  # components in the link's rotating frame: x = R(theta) q
                i = motion.member_names.index(pd.loc[1])
                th, w, al = motion.theta[:, i], motion.omega[:, i], motion.alpha[:, i]
                c, s_ = np.cos(th), np.sin(th)
                R = np.stack([np.stack([c, -s_], -1), np.stack([s_, c], -1)], -2)
                RS = R @ _S
                out = (pd.cols, R, w[:, None, None] * RS,
                       al[:, None, None] * RS - (w**2)[:, None, None] * R) + none3
            else:
                pc, pC, pC1, pC2, pp, pp1, pp2 = pform(pd.parent)
                if pd.phi < 0:
                    out = (pc, pC, pC1, pC2, pp, pp1, pp2)
                else:
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
                    out = (cols, np.concatenate([bC, col], -1), np.concatenate([bC1, col1], -1),
                           np.concatenate([bC2, col2], -1), pp, pp1, pp2)
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

    def _block_forms(self, b, motion, pform, rform):
        """Forms of the interior nodes of a Craig-Bampton block (see kedfem.fe.reduction).

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
        mb = sum(len(f[0]) for f in forms)
        Eb = np.zeros((3, nt, 6, mb))  # value, first, second derivative
        pb = np.zeros((3, nt, 6))
        row = col = 0
        for f in forms:
            cols, C, C1, C2, p, p1, p2 = f
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
            pt = (cols, E0[:, r], E1[:, r], E2[:, r]) + ((P0[:, r], P1[:, r], P2[:, r]) if has_p else (None,) * 3)
            ro = (cols, E0[:, t], E1[:, t], E2[:, t]) + ((P0[:, t], P1[:, t], P2[:, t]) if has_p else (None,) * 3)
            out.append((pt, ro))
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

    def _static_layout(self, gname: str):
        """Column map, constant part of E and the dynamic slots of a group.

        The q columns of an element are the union of its entities' columns
        (each global column once), so that element matrices in q-space stay as
        small as the element's actual couplings.
        """
        if gname in self._static_cache:
            return self._static_cache[gname]
        g = self.groups[gname]
        n_el = g.n
        per_el = []
        for e in range(n_el):
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
        dynamic = []  # (element, row, positions, kind, entity id, width, moving)
        passive = []  # (element, row, passive link name): chord stretch at end b
        passive_end = {}
        if gname == "beam":
            for name in self.beam.links:
                if not self.mech.links[name].kinematic:
                    passive_end[self.beam.first[name] + self.beam.count[name] - 1] = name
        for e in range(n_el):
            ucols = per_el[e]
            colarr[e, :len(ucols)] = ucols
            index = {c: i for i, c in enumerate(ucols)}
            row = 0
            for slot, kind in enumerate(g.layout):
                eid = g.ids[e, slot]
                width = 2 if kind == "P" else 1
                if eid >= 0:
                    pos = np.array([index[c] for c in self.entity_cols(kind, eid)], dtype=int)
                    moving, offset = self.entity_dynamic(kind, eid)
                    if moving or offset:
                        dynamic.append((e, row, pos, kind, eid, width, moving))
                    if not moving and pos.size:
                        C = self._const_C(kind, eid)
                        for j, pj in enumerate(pos):
                            E0[e, row:row + width, pj] += C[:, j]
                if kind == "P" and slot == 2 and e in passive_end:
                    passive.append((e, row, passive_end[e]))
                row += width
        out = (colarr, E0, dynamic, passive)
        self._static_cache[gname] = out
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

    def group_map(self, gname: str, motion: Motion, forms=None) -> GroupMap:
        """Constraint map of a group over the motion's time nodes.

        ``forms`` (from :meth:`entity_forms` on the same motion) may be passed
        to share them between groups.
        """
        colarr, E0, dynamic, passive = self._static_layout(gname)
        nt = motion.n
        n_el, d, m = E0.shape
        if (dynamic or passive) and forms is None:
            forms = self.entity_forms(motion)
        moving = any(dyn[6] for dyn in dynamic)
        if moving:
            E = np.broadcast_to(E0, (nt, n_el, d, m)).copy()
            E1 = np.zeros_like(E)
            E2 = np.zeros_like(E)
        else:
            E = E0[None]
            E1 = E2 = None
        p = p1 = p2 = None
        if any(forms[kind][eid][4] is not None for (_e, _r, _p, kind, eid, _w, _mv) in dynamic) or passive:
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

    # --------------------------------------------------------------- scatter
    def _operators(self, gname: str):
        """Segment sums of a group's element entries: (gather order, segment starts, targets).

        Entries ``(element, i, j)`` that land on the same global entry are
        adjacent after the gather, so one ``np.add.reduceat`` sums them; the
        padding column ``N`` (an element DOF with no unknown) is dropped.
        """
        if gname in self._scatter_cache:
            return self._scatter_cache[gname]
        colarr = self._static_layout(gname)[0]
        N = self.n_dof

        def plan(flat_targets, keep):
            idx = np.flatnonzero(keep)
            tgt = flat_targets[idx]
            order = np.argsort(tgt, kind="stable")
            idx, tgt = idx[order], tgt[order]
            starts = np.flatnonzero(np.r_[True, tgt[1:] != tgt[:-1]]) if tgt.size else np.zeros(0, int)
            return idx, starts, tgt[starts]

        r, c = colarr[:, :, None], colarr[:, None, :]
        mat = plan((r * N + c).reshape(-1), ((r < N) & (c < N)).reshape(-1))
        vec = plan(colarr.reshape(-1), colarr.reshape(-1) < N)
        self._scatter_cache[gname] = (mat, vec)
        return mat, vec

    @staticmethod
    def _segment_add(plan, data2d, out2d):
        idx, starts, targets = plan
        if idx.size:
            out2d[:, targets] += np.add.reduceat(data2d[:, idx], starts, axis=1)

    def scatter_matrix(self, gname: str, data: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Scatter element matrices ``(nt, n_el, m, m)`` to dense ``(nt, N, N)``.

        With ``out`` (nt, N, N), C-contiguous, the entries are added to it.
        """
        (mat, _vec) = self._operators(gname)
        nt = data.shape[0]
        N = self.n_dof
        if out is None:
            out = np.zeros((nt, N, N))
        self._segment_add(mat, np.ascontiguousarray(data).reshape(nt, -1), out.reshape(nt, N * N))
        return out

    def scatter_vector(self, gname: str, data: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Scatter element vectors ``(nt, n_el, m)`` to dense ``(nt, N)`` (added to ``out`` if given)."""
        (_mat, vec) = self._operators(gname)
        nt = data.shape[0]
        if out is None:
            out = np.zeros((nt, self.n_dof))
        self._segment_add(vec, np.ascontiguousarray(data).reshape(nt, -1), out)
        return out

    def scatter_sparse(self, gname: str, data: np.ndarray) -> sp.csr_matrix:
        """Scatter element matrices of one time node ``(n_el, m, m)`` to CSR ``(N, N)``."""
        colarr = self._static_layout(gname)[0]
        n_el, m = colarr.shape
        r = np.repeat(colarr, m, axis=1).reshape(-1)
        c = np.tile(colarr, (1, m)).reshape(-1)
        keep = (r < self.n_dof) & (c < self.n_dof)
        return sp.coo_matrix((data.reshape(-1)[keep], (r[keep], c[keep])),
                             shape=(self.n_dof, self.n_dof)).tocsr()

    # ---------------------------------------------------------------- labels
    def dof_index(self, label: str, owner: str = "") -> int:
        """Index of the DOF with ``label`` (see :attr:`dof_labels`); ``owner`` prefixes the error."""
        try:
            return self.dof_labels.index(label)
        except ValueError:
            raise InputError(f"{owner}unknown DOF label {label!r}{did_you_mean(label, self.dof_labels)}") from None

    def link_elements(self, link: str) -> slice:
        """Slice of the beam elements of a flexible link."""
        if link not in self.beam.first:
            kind = "rigid" if link in self.mech.links else "unknown"
            raise InputError(f"link '{link}' is {kind}: it has no beam elements "
                             f"(flexible links: {', '.join(self.beam.links)})")
        i0 = self.beam.first[link]
        return slice(i0, i0 + self.beam.count[link])
