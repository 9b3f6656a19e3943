"""What the other wings ask a mechanism about its graph: the members at a joint and the joints
of a member, the flexible links, a member's drive, the cycle's period and a slot joint's line.

:class:`MechanismQueries` is a mixin of :class:`~kedfem.model.mechanism.Mechanism` (the dataclass
holds the joints, links, bodies and drives it reads).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from .components import Drive, Link

__all__ = ["MechanismQueries"]


class MechanismQueries:
    """Queries on the joints, members and drives: mixed into :class:`~kedfem.model.mechanism.Mechanism`."""

    # ------------------------------------------------------------------ queries
    def _member_joints(self, member: str) -> tuple[str, ...]:
        if member in self.links:
            return self.links[member].attached
        return self.bodies[member].joints

    def members_at(self, joint: str) -> list[str]:
        """Links and bodies attached at ``joint``, in definition order."""
        out = [n for n, lk in self.links.items() if joint in lk.attached]
        out += [n for n, b in self.bodies.items() if joint in b.joints]
        return out

    @property
    def flexible_links(self) -> list[Link]:
        """Flexible links in definition order."""
        return [lk for lk in self.links.values() if not lk.rigid]

    def driven(self, member: str) -> Drive | None:
        """The drive of ``member`` or None."""
        for d in self.drives:
            if d.member == member:
                return d
        return None

    @property
    def period(self) -> float:
        """Cycle period ``2 pi / |speed|`` of the first drive [s]."""
        if not self.drives:
            raise InputError(f"{self.name}: has no drive, so it has no cycle")
        w = self.drives[0].speed
        if w == 0.0:
            raise InputError(f"{self.name}: the first drive's speed is zero, so there is no cycle")
        return 2.0 * math.pi / abs(w)

    def slot_line(self, joint: str) -> tuple[str, np.ndarray, np.ndarray]:
        """The line of a slot joint: (origin joint of the member, offset, unit axis) in the reference.

        Parameters
        ----------
        joint : str
            A slider joint with ``on=``.

        Returns
        -------
        origin : str
            The member's first joint (a link's ``a``).
        offset : ndarray, shape (2,)
            From ``origin`` to the block in the reference configuration [m].
        axis : ndarray, shape (2,)
            Unit direction of the line in the reference configuration.
        """
        jt = self.joints[joint]
        on = self.links.get(jt.on) or self.bodies.get(jt.on)
        origin = on.a if jt.on in self.links else on.joints[0]
        p0 = np.array(self.joints[origin].at)
        if jt.axis is not None:
            ax = np.array(jt.axis)
        else:
            lk = self.links[jt.on]
            ax = (np.array(self.joints[lk.b].at) - p0) / lk.length
        return origin, np.array(jt.at) - p0, ax
