"""The global consistency check of a mechanism, :meth:`~kedfem.model.mechanism.Mechanism.validate`.

A mechanism's builder checks each call's input at once; what only the whole can show is checked
here: some member at all, every joint on a member, the graph of joints and members (plus the
frame) connected, every slot's member carrying the block's line, welds naming members at their
joint, drives on members. A fingerprint of the records skips the check when nothing was added
since the last. :class:`ConsistencyChecks` is a mixin of :class:`~kedfem.model.mechanism.Mechanism`.
"""

from __future__ import annotations

import networkx as nx
import numpy as np

from ..errors import InputError
from .queries import MechanismQueries

__all__ = ["ConsistencyChecks"]


class ConsistencyChecks(MechanismQueries):
    """:meth:`validate`, on the graph queries: mixed into :class:`~kedfem.model.mechanism.Mechanism`."""

    def validate(self) -> None:
        """Check global consistency; raise :class:`InputError` naming the problem.

        Checks: at least one member; every joint used by a member; the graph
        of joints and members (plus the frame) connected; every flexible
        link has a length; drives on members with one ground joint.
        """
        state = self._fingerprint()
        if getattr(self, "_valid", None) == state:
            return  # validated before, and nothing was added since
        if not self.links and not self.bodies:
            raise InputError(f"{self.name}: has no links or bodies")
        used = {j for m in self.links.values() for j in m.attached} | \
            {j for m in self.bodies.values() for j in m.joints}
        unused = [j for j in self.joints if j not in used]
        if unused:
            raise InputError(f"{self.name}: joint(s) {', '.join(unused)} belong to no link or body")
        # the builder's graph, links and bodies only; every grounded part is one part (the frame)
        g = self.graph
        members = nx.subgraph_view(g, filter_edge=lambda u, v, k: g.edges[u, v, k]["kind"] in ("link", "body"))
        self._check_slots()
        for j in self.joints.values():
            if isinstance(j.welded, tuple):
                here = self.members_at(j.name)
                for m in j.welded:
                    if m not in here:
                        raise InputError(f"joint '{j.name}': welded names '{m}', which is not attached there "
                                         f"(members at '{j.name}': {', '.join(here) or 'none'})")
        members = nx.Graph(members)
        for j in self.joints.values():  # a block belongs to the part of its member
            if j.kind == "slot":
                members.add_edge(j.name, self._member_joints(j.on)[0])
        grounded, parts = set(), []
        for comp in nx.connected_components(members):
            if any(self.joints[j].kind in ("ground", "slider") for j in comp):
                grounded |= comp
            else:
                parts.append(comp)
        if grounded:
            parts.append(grounded)
        if len(parts) > 1:
            parts = sorted((sorted(c) for c in parts), key=len)
            raise InputError(f"{self.name}: the mechanism graph is disconnected; separate parts: "
                             + "; ".join("{" + ", ".join(p) + "}" for p in parts))
        for d in self.drives:
            if d.member not in self.links and d.member not in self.bodies:
                raise InputError(f"drive on '{d.member}': unknown member")
        self._valid = state

    def _check_slots(self) -> None:
        """The member of every slot exists, carries the block's line, and the block lies on it."""
        for j in self.joints.values():
            if j.kind != "slot":
                continue
            owner = f"slider '{j.name}'"
            if j.on not in self.links and j.on not in self.bodies:
                known = ", ".join([*self.links, *self.bodies]) or "none"
                raise InputError(f"{owner}: on='{j.on}' is not a link or body (members: {known})")
            if j.name in self._member_joints(j.on):
                raise InputError(f"{owner}: it is a joint of '{j.on}' itself; a block slides on a member "
                                 "it is not an end of")
            if j.on in self.bodies and j.axis is None:
                raise InputError(f"{owner}: on a body, give the line's axis=")
            lk = self.links.get(j.on)
            if lk is None:
                continue
            if not lk.kinematic:
                raise InputError(f"{owner}: link '{lk.name}' has kinematic=False; a block slides on a "
                                 "link of the kinematics")
            _o, d, ax = self.slot_line(j.name)
            e1 = (np.array(self.joints[lk.b].at) - np.array(self.joints[lk.a].at)) / lk.length
            xi = float(d @ e1)
            off = float(d[0] * e1[1] - d[1] * e1[0])
            if not lk.rigid:
                if abs(off) > 1e-9 * lk.length or abs(ax[0] * e1[1] - ax[1] * e1[0]) > 1e-9:
                    raise InputError(f"{owner}: on flexible link '{lk.name}' the block's line must be the "
                                     f"link's axis: the block at {j.at} is {abs(off):.3g} m off the line "
                                     f"{self.joints[lk.a].at} -> {self.joints[lk.b].at}, its axis "
                                     f"({ax[0]:.6g}, {ax[1]:.6g}); check at= and axis=, or make the link "
                                     "rigid for an offset or oblique slot")
                if lk.through:
                    raise InputError(f"{owner}: a block on flexible link '{lk.name}', which passes through "
                                     f"joint(s) {', '.join(lk.through)}, is not supported; split the link "
                                     "at the joint (two links welded there) instead")
                if lk.elements and self.links[lk.name].timoshenko:
                    raise InputError(f"{owner}: a block on Timoshenko link '{lk.name}' is not supported "
                                     "(the deflection under the block uses Euler-Bernoulli shape functions)")
            if not -1e-9 * lk.length <= xi <= lk.length * (1 + 1e-9):
                raise InputError(f"{owner}: the block is at abscissa {xi:.6g} m of link '{lk.name}', "
                                 f"outside the link (0 to {lk.length:.6g} m)")

    def _fingerprint(self) -> tuple:
        """What :meth:`validate` depends on: the members, joints and drives (all immutable records)."""
        return (tuple(self.joints.values()), tuple(self.links.values()), tuple(self.bodies.values()),
                tuple(self.drives), self.graph.number_of_edges())
