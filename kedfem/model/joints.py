"""The joints of a mechanism (the nodes of its graph) and where they are.

:class:`JointBuilder` is the part of :class:`~kedfem.model.mechanism.Mechanism` that adds joints
(``ground``, ``joint``, ``slider``), finds the joint a component names, and computes reference
positions from the lengths and angles of joints already placed (``at_angle``, ``at_lengths``,
``at_length_on_line``, wrapping the geometry of :mod:`kedfem.model.placement`). It is a mixin: the
dataclass :class:`~kedfem.model.mechanism.Mechanism` holds the state (``name``, ``joints``,
``graph``).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import placement
from .arguments import _number, _unit, _vec2
from .components import Joint
from .materials import MAX_LENGTH, flag

__all__ = ["GROUND", "JointBuilder"]

#: The frame's node name in the joint graph (reserved: no joint may take it)
GROUND = "ground"


def _welded_group(owner: str, welded) -> tuple[str, ...]:
    """Two or more different member names welded to each other at a joint."""
    if isinstance(welded, str) or not isinstance(welded, (tuple, list)) or \
            not all(isinstance(x, str) for x in welded):
        raise InputError(f"{owner}: welded must be True/False or a sequence of member names, got {welded!r}")
    welded = tuple(welded)
    if len(welded) < 2 or len(set(welded)) != len(welded):
        raise InputError(f"{owner}: welded names the members welded to each other: two or more "
                         f"different ones, got {welded!r}")
    return welded


class JointBuilder:
    """Joints and their reference positions: mixed into :class:`~kedfem.model.mechanism.Mechanism`."""

    # ------------------------------------------------------------------ joints
    def _new_joint(self, joint: Joint) -> Joint:
        if not isinstance(joint.name, str) or not joint.name:
            raise InputError(f"{self.name}: joint name must be a non-empty string, got {joint.name!r}")
        if joint.name == GROUND:
            raise InputError(f"{self.name}: '{GROUND}' is reserved for the frame; choose another joint name")
        if joint.name in self.joints:
            raise InputError(f"{self.name}: joint '{joint.name}' is defined twice")
        self.joints[joint.name] = joint
        self.graph.add_node(joint.name, joint=joint)
        return joint

    def ground(self, name: str, at, clamped: bool = False, welded=None) -> Joint:
        """Add a revolute joint to the frame (``clamped=True`` welds it).

        Parameters
        ----------
        name : str
            Joint name.
        at : (float, float)
            Position in the reference configuration [m].
        clamped : bool
            Weld the members meeting here to the frame (a cantilever root).
        welded : sequence of str, optional
            Two or more members welded to each other here and pinned to the
            frame together (the two arms of a walking beam on its saddle
            bearing); the other members at the joint stay pinned. For a
            member that passes the frame's pin, ``link(..., through=)`` does
            the same without splitting it.
        """
        owner = f"ground '{name}'"
        clamped = flag(owner, "clamped", clamped)
        if isinstance(welded, (bool, np.bool_)):
            if welded:
                raise InputError(f"{owner}: welded= names the members welded to each other (and pinned to "
                                 "the frame together); to weld every member to the frame, give clamped=True")
            welded = None
        if welded is not None:
            if clamped:
                raise InputError(f"{owner}: clamped=True welds every member to the frame; welded= names "
                                 "members welded to each other and pinned to the frame: give one of them")
            return self._new_joint(Joint(name, _vec2(owner, "at", at), "ground",
                                         welded=_welded_group(owner, welded)))
        return self._new_joint(Joint(name, _vec2(owner, "at", at), "ground", welded=clamped))

    def joint(self, name: str, at, welded=False) -> Joint:
        """Add a joint between members: revolute, or rigid when ``welded=True``.

        Parameters
        ----------
        name : str
            Joint name.
        at : (float, float)
            Position in the reference configuration [m]; it chooses the
            assembly branch of the linkage.
        welded : bool or sequence of str
            ``True``: connect all the members meeting here rigidly (kinematics
            and elasticity). A sequence of two or more member names welds
            those to each other and leaves the others pinned (a lever made of
            two links with a crank pinned where they meet).
        """
        owner = f"joint '{name}'"
        welded = bool(welded) if isinstance(welded, (bool, np.bool_)) else _welded_group(owner, welded)
        return self._new_joint(Joint(name, _vec2(owner, "at", at), "revolute", welded=welded))

    def slider(self, name: str, at, axis=None, *, on: str | None = None, rotation: str = "free",
               slide: str = "free") -> Joint:
        """Add a pin on a slider: along a fixed line, or along a line fixed in a moving member.

        Parameters
        ----------
        name : str
            Joint name.
        at : (float, float)
            Position in the reference configuration [m].
        axis : (float, float), optional
            Direction of the slider's line in the reference configuration
            (normalised here). Default ``(1, 0)`` on the frame, and the link's
            ``a -> b`` direction on a link (``on=``); required on a body.
        on : str, optional
            The member carrying the line (a link or a body): a prismatic pair
            between moving members (the slotted lever of a quick-return, the
            barrel of a cylinder). The line turns with ``on``; the block's
            travel along it is a coordinate of the kinematics. On a flexible
            link the line must be the link's own axis, and the block's
            transverse displacement follows the link's deflection at the
            block's current abscissa. ``None``: the frame.
        rotation : {"free", "locked"}
            ``"free"``: a pin in the slot, the members at the joint rotate
            freely. ``"locked"``: a piston in its cylinder, the members at the
            joint turn with ``on`` (rigidly, and elastically with the slope of
            a flexible ``on`` under the block); on the frame, a crosshead: the
            members at the joint do not turn (a Scotch yoke's frame).
        slide : {"free", "locked"}
            ``"locked"`` keeps the block at its abscissa: a pin on the member
            at any point of it (no need to split the link there).
        """
        owner = f"slider '{name}'"
        if not isinstance(rotation, str) or rotation not in ("free", "locked"):
            raise InputError(f"{owner}: rotation must be 'free' or 'locked', got {rotation!r}")
        if not isinstance(slide, str) or slide not in ("free", "locked"):
            raise InputError(f"{owner}: slide must be 'free' or 'locked', got {slide!r}")
        if on is None and slide != "free":
            raise InputError(f"{owner}: slide='locked' applies to a slider on a member (on=); "
                             "on the frame, a locked slide is a ground joint")
        if on is not None and (not isinstance(on, str) or not on):
            raise InputError(f"{owner}: on must be the name of a link or body, got {on!r}")
        if axis is None and on is None:
            axis = (1.0, 0.0)
        ax = _unit(owner, "axis", axis) if axis is not None else None
        kind = "slider" if on is None else "slot"
        return self._new_joint(Joint(name, _vec2(owner, "at", at), kind, axis=ax, on=on,
                                     rotation=rotation, slide=slide))

    def _check_joint(self, owner: str, jname: str) -> Joint:
        if not isinstance(jname, str):
            raise InputError(f"{owner}: a joint is named by a string, got {type(jname).__name__} {jname!r}")
        if jname not in self.joints:
            known = ", ".join(sorted(self.joints)) or "none yet"
            raise InputError(f"{owner} names unknown joint '{jname}' (defined joints: {known})")
        return self.joints[jname]

    # -------------------------------------------------------------- placement
    def _position(self, owner: str, ref) -> tuple[str, tuple[float, float]]:
        """(label, position) of a joint name or a point (x, y)."""
        if isinstance(ref, str):
            return ref, self._check_joint(owner, ref).at
        pt = _vec2(owner, "point", ref)
        return f"{pt}", pt

    def _anchor(self, owner: str, spec) -> tuple[str, tuple[float, float], float, str | None]:
        """(joint, position, length, label) of a ``(joint, length)`` or ``(joint, length, name)``."""
        if not isinstance(spec, (tuple, list)) or len(spec) not in (2, 3) or not isinstance(spec[0], str):
            raise InputError(f"{owner}: give each anchor as (joint, length) or (joint, length, name), "
                             f"got {spec!r}")
        joint, pos = self._position(owner, spec[0])
        length = _number(owner, f"the length from '{joint}'", spec[1], positive=True, limit=MAX_LENGTH, unit=" m")
        label = f"{spec[2]} {length:.6g} m" if len(spec) == 3 else None
        return joint, pos, length, label

    def at_angle(self, origin, length: float, angle: float) -> tuple[float, float]:
        """The point at ``length`` from a joint in the direction ``angle`` (a crank's end).

        Parameters
        ----------
        origin : str or (float, float)
            A joint (its reference position) or a point [m].
        length : float
            [m], > 0.
        angle : float
            [rad], counter-clockwise from +x.

        Returns
        -------
        (float, float)
            A position for ``at=`` of :meth:`joint`, :meth:`ground` or :meth:`slider` [m].

        Examples
        --------
        >>> m.joint("A", at=m.at_angle("O2", 0.108, math.radians(30)))
        """
        _label, pos = self._position("at_angle", origin)
        return placement.at_angle(pos, length, angle)

    def at_lengths(self, first, second, branch: str = "open") -> tuple[float, float]:
        """The point at given distances from two joints (closing a dyad).

        Parameters
        ----------
        first, second : (str, float) or (str, float, str)
            ``(joint, length)`` or ``(joint, length, link name)``: the point lies
            ``length`` [m] from each joint (the link name only words the errors).
        branch : {"open", "crossed", "left", "right"}
            Which of the two mirror-image points
            (:mod:`kedfem.model.placement`): ``"left"`` / ``"right"`` of the
            directed line from ``first`` to ``second``; ``"open"`` / ``"crossed"``
            are the four-bar's circuits in Norton's convention (one of the joints
            a ground pivot, the other the moving joint ``A``: ``"open"`` is
            left of ``A -> pivot``), in either order.

        Returns
        -------
        (float, float)
            A position for ``at=`` [m].

        Raises
        ------
        InputError
            The circles do not meet (naming the joints and lengths, e.g.
            ``coupler 0.2 m + rocker 0.2 m = 0.4 m < distance |A-O4| = 0.5 m``),
            or ``"open"`` / ``"crossed"`` without exactly one ground joint.

        Examples
        --------
        >>> m.joint("B", at=m.at_lengths(("A", 0.2794, "coupler"), ("O4", 0.2705, "rocker")))
        """
        owner = "at_lengths"
        p, pp, a, la = self._anchor(owner, first)
        q, qq, b, lb = self._anchor(owner, second)
        placement._side(branch, placement.BRANCHES, owner)
        side = branch
        if branch in ("open", "crossed"):
            grounds = [j for j in (p, q) if j in self.joints and self.joints[j].grounded]
            if len(grounds) != 1:
                raise InputError(f"{owner}: branch {branch!r} is a four-bar circuit, defined for a dyad that "
                                 f"closes on one ground pivot; of '{p}' and '{q}', "
                                 f"{len(grounds)} are ground joints: use branch 'left' or 'right' "
                                 f"(of the line from '{p}' to '{q}')")
            # open: left of the line from the moving joint to the ground pivot
            left_of_pq = (branch == "open") == (grounds[0] == q)
            side = "left" if left_of_pq else "right"
        return placement.circle_intersection(pp, a, qq, b, side, names=(p, q), labels=(la, lb))

    def at_length_on_line(self, first, through, axis=(1.0, 0.0), branch: str = "open") -> tuple[float, float]:
        """The point on a line at a given distance from a joint (a slider-crank's slider).

        Parameters
        ----------
        first : (str, float) or (str, float, str)
            ``(joint, length)`` or ``(joint, length, link name)``: the crank pin and the rod's length [m].
        through : str or (float, float)
            A joint or a point of the slider's line [m].
        axis : (float, float)
            The line's direction.
        branch : {"open", "ahead", "crossed", "behind"}
            ``"open"`` / ``"ahead"``: the point further along ``axis``
            (Norton's open slider-crank); ``"crossed"`` / ``"behind"``: the other.

        Returns
        -------
        (float, float)
            A position for ``at=`` of :meth:`slider` [m].

        Examples
        --------
        >>> m.slider("B", at=m.at_length_on_line(("A", 0.30, "rod"), through="O"), axis=(1.0, 0.0))
        """
        owner = "at_length_on_line"
        p, pp, a, la = self._anchor(owner, first)
        _label, c = self._position(owner, through)
        return placement.line_intersection(pp, a, c, axis, branch, name=p, label=la)
