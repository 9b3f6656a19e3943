"""DOF numbering: the independent elastic coordinates ``q`` of a mechanism, from its graph.

Every component (beam element, rigid member's mass, point mass, spring,
load) acts on a few *entities*: translation points (2 components) and
rotations (1). Points are ``fixed`` (ground joint), ``free`` (two q's),
``slider`` (one q along the slider's axis) or ``body`` (slaved to a rigid
member group); rotations ``free`` (own q), ``fixed`` or ``tied`` to a master
rotation. The rules (docs/theory.md section 2): revolute joints share
translations and keep separate rotations; welded joints share rotations;
sliders constrain the normal direction; rigid links add no elastic DOFs of
their own (a rigid member group has at most a reference translation and one
rotation); the driven member's elastic rotation at its ground joint is
fixed, or tied to the motor through the drive's torsional spring.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, did_you_mean
from ..motion.kinematics import Motion

__all__ = ["DofNumbering", "PointDof", "RotDof", "Group", "BeamData"]

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
    slot: str | None = None  # kind "slot": the locked slider joint whose member's slope it follows


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



class DofNumbering:
    """The DOF numbering part of :class:`kedfem.fe.model.FEModel`: entities, labels, element groups."""

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
        return mech.links[name].attached if name in mech.links else mech.bodies[name].joints

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
            if j.welded and not j.clamped:
                here = [m for m in mech.members_at(j.name) if m in parent and j.welds(m)]
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
        sliders = [j for j in atts if mech.joints[j].kind in ("slider", "slot")]
        grounded = [j for j in atts if mech.joints[j].kind == "ground"]
        shared = [j for j in atts if j in self._rigid_joint_points]
        drive = next((mech.driven(m) for m in members if mech.driven(m) is not None), None)
        if sliders:
            self._check_rigid_on_slider(name, sliders, grounded, shared)
        if sliders:
            # the slider's point is the group's reference: x = x_slider + phi S rho
            j = sliders[0]
            ref_pt = self._slider_point(j)
            self._rigid_joint_points[j] = ref_pt
            if mech.joints[j].kind == "slider" and mech.joints[j].rotation == "locked":
                phi = -1  # a crosshead: the group does not turn
            else:
                q = self._new_q(f"{name}.phi")
                phi = self._add_rot(RotDof("free", f"{name}.phi", (q,), members[0]))
        elif len(grounded) >= 2:
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
            if mech.joints[g].clamped:
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

    def _check_rigid_on_slider(self, name, sliders, grounded, shared):
        """A rigid group may ride on one slider, taking its point as reference, and nothing else fixed."""
        mech = self.mech
        j = sliders[0]
        why = None
        if len(sliders) > 1:
            why = f"it rides on two sliders ('{sliders[0]}' and '{sliders[1]}')"
        elif grounded:
            why = f"it is also pinned to the frame at '{grounded[0]}'"
        elif shared:
            why = f"it is also pinned to rigid member(s) at '{shared[0]}'"
        elif mech.joints[j].kind == "slot" and mech.joints[j].rotation == "locked":
            why = f"it is locked in rotation to '{mech.joints[j].on}'"
        elif mech.joints[j].kind == "slot" and mech.joints[j].on in name.split("+"):
            why = f"it carries the line of slider '{j}' itself"
        if why is None:
            return
        raise InputError(
            f"rigid member(s) '{name}' on slider '{j}': {why}, so the slider's constraint would act "
            "on the deflection of other members, which kedfem does not eliminate; make one of these links "
            "flexible with its real section: its deflection is then part of the answer (the summary lists "
            "it among the flexible members; a Whitworth's crank, flexible or rigid, changes the ram's elastic "
            "displacement by about 10 %); a section far stiffer than the real one approaches a rigid member, at the "
            "cost of stiffer modes to resolve")

    def _slider_point(self, jn: str) -> int:
        """The translation entity of a slider joint: along its line (fixed or on a member)."""
        j = self.mech.joints[jn]
        if j.kind == "slider":
            q = self._new_q(f"{jn}.s")
            return self._add_point(PointDof("slider", jn, (q,), axis=j.axis, loc=("joint", jn)))
        cols = (self._new_q(f"{jn}.s[{j.on}]"),) if j.slide == "free" else ()
        return self._add_point(PointDof("slot", jn, cols, loc=("joint", jn)))

    def _build_slots(self):
        """The body point of a rigid member under each block sliding on it; the member's point
        under each block (``slot_contact``: where the pair's friction reaction acts)."""
        self.slot_support = {}
        self.slot_contact = {}
        for jn, j in self.mech.joints.items():
            if j.kind == "slot" and j.on not in self.member_rot:
                self.slot_contact[jn] = self._add_point(PointDof("contact", f"{j.on}@{jn}", (),
                                                                 loc=("joint", jn)))
            if j.kind != "slot" or j.on not in self.member_rot:
                continue
            grp = next(g for g in self.rigid_groups if j.on in g["members"])
            ref, phi = grp["ref"], grp["phi"]
            if phi < 0 and self.points[ref].kind == "fixed":
                pid = self._add_point(PointDof("fixed", f"{j.on}@{jn}", loc=("joint", jn)))
            else:
                pid = self._add_point(PointDof("body", f"{j.on}@{jn}", parent=ref, phi=phi, loc=("joint", jn)))
            self.slot_support[jn] = pid
            self.slot_contact[jn] = pid

    def _build_joint_points(self):
        mech = self.mech
        for jn, j in mech.joints.items():
            if jn in self._rigid_joint_points:
                self.joint_point[jn] = self._rigid_joint_points[jn]
            elif j.kind == "ground":
                self.joint_point[jn] = self._add_point(PointDof("fixed", jn, loc=("joint", jn)))
            elif j.kind in ("slider", "slot"):
                self.joint_point[jn] = self._slider_point(jn)
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

    def _drive_rotation(self, drive) -> int:
        """The elastic rotation of a driven flexible link at its ground joint: the shaft's twist
        with a torsional stiffness, else fixed."""
        label = f"{drive.member}.theta@{drive.ground_joint}"
        if drive.torsional_stiffness is not None:
            return self._add_rot(RotDof("free", label, (self._new_q(label),), drive.member))
        return self._add_rot(RotDof("fixed", label, (), drive.member))

    def _end_rotation(self, lk, joint, k, clamp_groups):
        mech = self.mech
        jt = mech.joints[joint]
        label = f"{lk.name}.theta@{joint}"
        drive = mech.driven(lk.name)
        if drive is not None and drive.ground_joint == joint:
            if clamp_groups.get(joint, (None, None))[1] == lk.name:  # its welded group's (_build_beams)
                return clamp_groups[joint][0]
            return self._drive_rotation(drive)
        if jt.kind == "slot" and jt.rotation == "locked" and jt.on != lk.name:
            return self._add_rot(RotDof("slot", label, (), lk.name, slot=joint))
        if jt.kind == "slider" and jt.rotation == "locked":  # a crosshead
            return self._add_rot(RotDof("fixed", label, (), lk.name, None, offset=True))
        welds = jt.welds(lk.name)  # else an end clamped to what the joint connects to
        if not (welds or (k is not None and lk.ends[k] == "clamp")):
            q = self._new_q(label)
            return self._add_rot(RotDof("free", label, (q,), lk.name))
        if jt.kind == "ground" and (jt.clamped or not welds):  # (not welded to members pinned there)
            return self._add_rot(RotDof("fixed", label, (), lk.name, None, offset=True))
        rigid_here = [m for m in mech.members_at(joint) if m in self.member_rot and (jt.welds(m) or not welds)]
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
        if self.rots[rid0].kind == "fixed":  # welded to a crank driven without a shaft's stiffness
            return self._add_rot(RotDof("fixed", label, (), lk.name, master, offset=True))
        return self._add_rot(RotDof("tied", label, self.rots[rid0].cols, lk.name, master, offset=True))

    def _build_beams(self):
        mech = self.mech
        clamp_groups: dict = {}
        for d in mech.drives:  # a driven flexible crank welded to other members at its pivot: their rotation
            jt, lk = mech.joints[d.ground_joint], mech.links.get(d.member)
            if lk is None or lk.rigid or jt.clamped or not jt.welds(d.member):
                continue
            clamp_groups[d.ground_joint] = (self._drive_rotation(d), d.member)
        self.link_nodes = {}  # unreduced flexible link -> (node point ids, node rotation ids)
        rows = {k: [] for k in ("link", "L", "EA", "EI", "rhoA", "GAs", "s1", "lumped", "timo")}
        ids = []
        first, count = {}, {}
        names = []
        for li, lk in enumerate(mech.flexible_links):
            names.append(lk.name)
            ne = lk.elements
            le = lk.length / ne
            lengths, nodes = lk.element_lengths, lk.nodes
            inner = dict(zip(lk.inner_nodes, lk.through))  # mesh nodes at joints passed through
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
                if i in inner:
                    t = inner[i]
                    rt = self._end_rotation(lk, t, None, clamp_groups)
                    self.end_rot[(lk.name, t)] = rt
                    node_pts.append(self.joint_point[t])
                    node_rots.append(rt)
                    continue
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
                                                         loc=("member", lk.name, lk.a, nodes[i] * e1))))
                node_rots.append(self._add_rot(RotDof("free", f"{lk.name}.n{i}.theta", (qt,), lk.name)))
            rb = self._end_rotation(lk, lk.b, 1, clamp_groups)
            self.end_rot[(lk.name, lk.b)] = rb
            node_pts.append(self.joint_point[lk.b])
            node_rots.append(rb)
            if reduced:
                blk["bounds"] = (node_pts[0], ra, node_pts[-1], rb)
            else:
                self.link_nodes[lk.name] = (tuple(node_pts), tuple(node_rots))
            for i in range(ne):
                ids.append((node_pts[i], node_rots[i], node_pts[i + 1], node_rots[i + 1]))
                rows["link"].append(li)
                rows["L"].append(lengths[i])
                rows["EA"].append(mat.E * sec.A)
                rows["EI"].append(mat.E * sec.I)
                rows["rhoA"].append(mat.rho * sec.A)
                rows["GAs"].append(sec.kappa * mat.G * sec.A)
                rows["s1"].append(nodes[i])
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
        pair = [f for f in mech.frictions.values() if f.axis is None]  # their reactions on the member
        loads += [(self.slot_contact[f.joint],) for f in pair]
        groups["load"] = Group("load", ("P",), np.asarray(loads, int).reshape(-1, 1),
                               {"items": list(mech.loads.values()) + list(mech.frictions.values())
                                + [("reaction", f) for f in pair]})
        self.groups = {k: g for k, g in groups.items()}

    # ------------------------------------------------------------ evaluation
    def loc_motion(self, loc, motion: Motion):
        """Position, velocity and acceleration of a point location (a joint, or a point of a
        member) over the instants of ``motion``, each (nt, 2) [m, m/s, m/s^2]."""
        if loc[0] == "joint":
            j = motion.joint_names.index(loc[1])
            return motion.r[:, j], motion.v[:, j], motion.a[:, j]
        _k, member, origin, offset = loc
        return motion.point(member, origin, offset)

    # ---------------------------------------------------------------- labels
    def dof_index(self, label: str, owner: str = "") -> int:
        """Index of the DOF with ``label`` (see :attr:`dof_labels`); ``owner`` prefixes the error."""
        try:
            return self.dof_labels.index(label)
        except ValueError:
            raise InputError(f"{owner}unknown DOF label {label!r}{did_you_mean(label, self.dof_labels)}") from None

    def link_elements(self, link: str) -> slice:
        """Slice of the beam elements of a flexible link."""
        if not isinstance(link, str) or link not in self.beam.first:
            kind = "rigid" if link in self.mech.links else "unknown"
            raise InputError(f"link '{link}' is {kind}: it has no beam elements "
                             f"(flexible links: {', '.join(self.beam.links)})")
        i0 = self.beam.first[link]
        return slice(i0, i0 + self.beam.count[link])

