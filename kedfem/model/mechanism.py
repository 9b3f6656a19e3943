"""Mechanism builder: joints (graph nodes) joined by links, bodies and springs (edges).

A :class:`Mechanism` is a description, not a solver: it records the
reference configuration (every ``at=`` position), the components and the
drives, checks each call's input at once, and keeps a
:class:`networkx.MultiGraph` whose nodes are joints and whose edges are the
links, rigid bodies (a star of edges from their first attachment) and
springs. Kinematics, assembly and the solvers read it.

Conventions: SI units throughout; angles in radians, positive
counter-clockwise; a link's angle is the angle of its ``a -> b`` line.
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass, field
from functools import cached_property

import networkx as nx
import numpy as np

from ..errors import InputError
from .materials import MAX_LENGTH, Material, Section, flag, names, real
from ..checks import direction, pair
from . import placement
from .profiles import Profile
from ..errors import LengthWarning

__all__ = [
    "Mechanism",
    "require_mechanism",
    "MAX_ELEMENTS",
    "Joint",
    "Link",
    "Body",
    "PointMass",
    "Spring",
    "TorsionalSpring",
    "Drive",
    "Load",
    "Friction",
]

GROUND = "ground"
#: Largest number of frame elements per link (the cost grows with the cube of the DOF count;
#: 200 elements of 3 DOFs already make a 600-DOF link).
MAX_ELEMENTS = 200
#: Relative difference between a link's stated ``length=`` and its coordinates that warns
LENGTH_RTOL = 1e-6

log = logging.getLogger(__name__)


def _vec2(owner: str, name: str, value, limit: float | None = MAX_LENGTH, unit: str = " m") -> tuple[float, float]:
    """Two finite numbers (x, y); with ``limit``, each of magnitude at most ``limit``
    (:func:`kedfem.checks.pair`)."""
    return pair(owner, name, value, limit=limit, unit=unit)


def require_mechanism(obj, owner: str = "kedfem") -> "Mechanism":
    """``obj`` if it is a :class:`Mechanism`, else an :class:`InputError` naming ``owner``."""
    if not isinstance(obj, Mechanism):
        raise InputError(f"{owner}: expected a kedfem.Mechanism, got {type(obj).__name__} {_short(obj)}")
    return obj


def _short(v) -> str:
    r = repr(v)
    return r if len(r) <= 60 else r[:57] + "..."


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


_unit = direction  # a normalised direction (kedfem.checks.direction)


_number = real  # the finite-number check of materials.py


@dataclass(frozen=True)
class Joint:
    """A joint of the mechanism (a node of the graph).

    ``kind`` is ``"revolute"`` (pin between members), ``"ground"`` (pin to
    the frame), ``"slider"`` (pin on a slider moving along a fixed line) or
    ``"slot"`` (a block sliding along a line fixed in the member ``on``: a
    prismatic pair between moving members). ``welded`` joints (and clamped
    ground joints) connect their members rigidly, kinematically and
    elastically. A slot's ``rotation`` is ``"free"`` (pin in a slot) or
    ``"locked"`` (piston in a cylinder: the members at the joint turn with
    ``on``); its ``slide`` is ``"free"`` or ``"locked"`` (the block stays at
    its abscissa: a pin on the member).
    """

    name: str
    at: tuple[float, float]
    kind: str = "revolute"
    welded: bool | tuple[str, ...] = False
    axis: tuple[float, float] | None = None
    on: str | None = None
    rotation: str = "free"
    slide: str = "free"

    @property
    def grounded(self) -> bool:
        """True for joints whose translation is fixed to the frame."""
        return self.kind == "ground"

    @property
    def clamped(self) -> bool:
        """True for a ground joint that welds every member to the frame (``clamped=True``)."""
        return self.kind == "ground" and self.welded is True

    def welds(self, member: str) -> bool:
        """True if ``member`` is rigidly connected here (``welded=True``, or named in ``welded``)."""
        return self.welded is True or (isinstance(self.welded, tuple) and member in self.welded)


@dataclass(frozen=True)
class Link:
    """A straight link from joint ``a`` to joint ``b``.

    Flexible links are meshed into ``elements`` planar frame elements of
    ``material`` and ``section``. Rigid links add no elastic DOFs of their
    own; their mass is ``mass`` (or ``rho A L`` when a material and section
    are given) with rotary inertia ``J`` about the centre (default
    ``m L^2 / 12``).
    """

    name: str
    a: str
    b: str
    rigid: bool
    material: Material | None
    section: Section | None
    elements: int
    ends: tuple[str, str]
    mass: float
    J: float
    mass_matrix: str
    timoshenko: bool
    length: float
    kinematic: bool = True
    through: tuple[str, ...] = ()
    through_at: tuple[float, ...] = ()

    @property
    def joints(self) -> tuple[str, str]:
        """The link's end joints ``(a, b)``."""
        return (self.a, self.b)

    @property
    def attached(self) -> tuple[str, ...]:
        """Every joint of the link: its ends, then the joints it passes through (``through=``)."""
        return (self.a, self.b) + self.through

    @property
    def stretches(self) -> tuple[tuple[str, str], ...]:
        """The joints at the ends of each stretch between the link's ends and the joints it passes through."""
        js = (self.a,) + self.through + (self.b,)
        return tuple(zip(js[:-1], js[1:]))

    @property
    def cuts(self) -> tuple[float, ...]:
        """Abscissae [m] from ``a`` of the stretches' ends: 0, the joints passed through, the length."""
        return (0.0,) + self.through_at + (self.length,)

    @property
    def inner_nodes(self) -> tuple[int, ...]:
        """The mesh nodes at the joints the link passes through, in ``through`` order."""
        return tuple(f for f, _c, _le in self.segments()[1:])

    def segments(self) -> tuple[tuple[int, int, float], ...]:
        """The mesh's uniform stretches between the ends and the joints passed through.

        Returns
        -------
        tuple of (first, count, Le)
            First element, number of elements and element length [m] of each
            stretch, from ``a`` to ``b``. Without ``through=`` joints, one
            stretch of ``elements`` elements of ``length / elements``. The
            elements go to the stretches in proportion to their lengths
            (largest remainders, at least one each).
        """
        return self._segments

    @cached_property
    def _segments(self) -> tuple[tuple[int, int, float], ...]:
        """:meth:`segments`, computed once (the fields are frozen)."""
        if not self.elements:
            return ()
        if not self.through:
            return ((0, self.elements, self.length / self.elements),)
        lens = np.diff(self.cuts)
        share = self.elements * lens / self.length
        n = np.maximum(np.floor(share).astype(int), 1)
        while n.sum() < self.elements:
            n[int(np.argmax(share - n))] += 1
        while n.sum() > self.elements:  # the stretches raised to one element give theirs back
            n[int(np.argmin(np.where(n > 1, share - n, np.inf)))] -= 1
        out, first = [], 0
        for k in range(lens.size):
            out.append((first, int(n[k]), float(lens[k] / n[k])))
            first += int(n[k])
        return tuple(out)

    @property
    def element_lengths(self) -> np.ndarray:
        """Lengths (elements,) of the link's frame elements [m]."""
        return np.concatenate([np.full(c, le) for _f, c, le in self.segments()]) if self.elements \
            else np.zeros(0)

    @property
    def nodes(self) -> np.ndarray:
        """Abscissae (elements + 1,) of the mesh's nodes from joint ``a`` [m]."""
        out = [s0 + np.arange(c) * le for s0, (_f, c, le) in zip(self.cuts, self.segments())]
        return np.concatenate(out + [[self.length]]) if self.elements else np.zeros(0)

    def node_of(self, joint: str) -> int:
        """The mesh node (0 .. elements) at ``joint``, an end or a joint passed through."""
        if joint == self.a:
            return 0
        if joint == self.b:
            return self.elements
        return self.inner_nodes[self.through.index(joint)]


@dataclass(frozen=True)
class Body:
    """A rigid body attached at several joints (e.g. an oscillation table).

    Its rotation is measured from the reference configuration; ``cm`` is
    the centre of mass there, ``J`` the rotary inertia about it [kg m^2].
    """

    name: str
    joints: tuple[str, ...]
    mass: float
    J: float
    cm: tuple[float, float]


@dataclass(frozen=True)
class PointMass:
    """A lumped mass [kg] (and rotary inertia J [kg m^2]) at a joint."""

    joint: str
    mass: float
    J: float = 0.0


@dataclass(frozen=True)
class Spring:
    """Translational spring acting along a fixed global ``axis``.

    Between joint ``a`` and joint ``b`` (or the frame when ``b`` is None).
    Its extension is ``delta = (x_a - x_b) . axis`` measured from the
    reference configuration, and the force it exerts on ``a`` is
    ``-(preload + k delta + k3 delta^3) axis`` (``+`` that on ``b``).
    """

    name: str
    a: str
    b: str | None
    k: float
    axis: tuple[float, float]
    k3: float = 0.0
    preload: float = 0.0

    @property
    def nonlinear(self) -> bool:
        return self.k3 != 0.0


@dataclass(frozen=True)
class TorsionalSpring:
    """Torsional spring between two members at a joint (or a member and the frame).

    Relative rotation ``delta = phi_1 - phi_2`` from the reference
    configuration; moment on member 1 ``-(preload + k delta)``.
    """

    name: str
    joint: str
    member: str
    other: str | None
    k: float
    preload: float = 0.0


@dataclass(frozen=True)
class Drive:
    """Constant-speed input on a member pivoting at a ground joint.

    ``speed`` [rad/s] (+ counter-clockwise). Without ``torsional_stiffness``
    the member's elastic rotation at the ground joint is fixed; with it the
    member is tied to the motor through a torsional spring [N m/rad].
    """

    member: str
    speed: float
    ground_joint: str
    torsional_stiffness: float | None = None


@dataclass(frozen=True)
class Load:
    """External force [N] at a joint, in global components: constant, or times the factor of a
    :class:`~kedfem.model.profiles.Profile` over the cycle (a process load)."""

    name: str
    joint: str
    force: tuple[float, float]
    profile: Profile | None = None


@dataclass(frozen=True)
class Friction:
    """Friction force of magnitude ``force`` [N] at a joint along ``axis``.

    The force opposes the joint's velocity component along ``axis`` relative
    to ``reference_speed`` [m/s] (e.g. the casting speed of a strand):
    ``F = -force * tanh((v . axis - reference_speed) / smoothing) * axis``.
    ``follows="rigid"`` uses the rigid-body velocity (state independent);
    ``"total"`` adds the elastic velocity (state dependent: iterated).
    ``axis=None``: friction in a sliding pair (a slot joint): the force acts
    between the block and the member it slides on, along the turning line,
    and opposes the block's sliding speed on it.
    """

    name: str
    joint: str
    force: float
    axis: tuple[float, float] | None
    reference_speed: float = 0.0
    smoothing: float = 1e-3
    follows: str = "rigid"


@dataclass
class Mechanism:
    """A planar linkage: joints joined by links, rigid bodies and springs.

    Examples
    --------
    >>> import kedfem as kf
    >>> m = kf.Mechanism("slider-crank")
    >>> m.ground("O", at=(0.0, 0.0))
    >>> m.joint("A", at=(0.15, 0.0))
    >>> m.slider("B", at=(0.45, 0.0), axis=(1.0, 0.0))
    >>> m.link("crank", "O", "A", rigid=True)
    >>> m.link("rod", "A", "B", material=kf.Material(E=2e11, rho=7870),
    ...        section=kf.Section.rectangle(0.008, 0.008), elements=8)
    >>> m.point_mass("B", 0.075552)
    >>> m.drive("crank", speed=150.0)
    """

    name: str = "mechanism"
    joints: dict[str, Joint] = field(default_factory=dict)
    links: dict[str, Link] = field(default_factory=dict)
    bodies: dict[str, Body] = field(default_factory=dict)
    point_masses: list[PointMass] = field(default_factory=list)
    springs: dict[str, Spring] = field(default_factory=dict)
    torsional_springs: dict[str, TorsionalSpring] = field(default_factory=dict)
    drives: list[Drive] = field(default_factory=list)
    loads: dict[str, Load] = field(default_factory=dict)
    frictions: dict[str, Friction] = field(default_factory=dict)
    gravity: tuple[float, float] = (0.0, -9.80665)
    gravity_declared: bool = False
    graph: nx.MultiGraph = field(default_factory=nx.MultiGraph, repr=False)

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip():
            raise InputError(f"Mechanism: name must be a non-empty string, got {self.name!r}")

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

    # -------------------------------------------------------------- components
    def _check_component_name(self, kind: str, name: str):
        if not isinstance(name, str) or not name:
            raise InputError(f"{self.name}: {kind} name must be a non-empty string, got {name!r}")
        taken = set(self.links) | set(self.bodies) | set(self.springs) | set(self.torsional_springs)
        if name in taken:
            raise InputError(f"{self.name}: component name '{name}' is used twice")

    def _check_joint(self, owner: str, jname: str) -> Joint:
        if not isinstance(jname, str):
            raise InputError(f"{owner}: a joint is named by a string, got {type(jname).__name__} {jname!r}")
        if jname not in self.joints:
            known = ", ".join(sorted(self.joints)) or "none yet"
            raise InputError(f"{owner} names unknown joint '{jname}' (defined joints: {known})")
        return self.joints[jname]

    def link(self, name: str, a: str, b: str, *, material: Material | None = None,
             section: Section | None = None, elements: int = 1, rigid: bool = False,
             ends=("pin", "pin"), mass: float | None = None, J: float | None = None,
             mass_matrix: str = "consistent", timoshenko: bool = False,
             kinematic: bool = True, length: float | None = None, through=None) -> Link:
        """Add a straight link from joint ``a`` to joint ``b``.

        Parameters
        ----------
        name : str
            Link name (unique among components).
        a, b : str
            Joints at the link's ends; the link's angle is that of the ``a -> b`` line.
        material : Material, optional
            Required for flexible links; for rigid links it gives the mass.
        section : Section, optional
            Required for flexible links; for rigid links it gives the mass.
        elements : int
            Number of frame elements of a flexible link.
        rigid : bool
            Rigid link: no elastic DOFs of its own.
        ends : (str, str)
            Elastic end conditions at ``a`` and ``b``: ``"pin"`` (own elastic
            rotation) or ``"clamp"`` (elastic rotation tied to what the joint
            connects to: the frame, a rigid body or the other clamped ends).
            At a revolute joint the kinematics still treat the end as a pin;
            the change of relative rigid-body angle then becomes a prescribed
            elastic rotation (a guiding leaf spring bending in an S).
        mass, J : float, optional
            Rigid links only: mass [kg] and rotary inertia about the centre [kg m^2].
        mass_matrix : {"consistent", "lumped"}
            Element mass matrix of a flexible link.
        timoshenko : bool
            Shear-flexible (Timoshenko) stiffness for a flexible link.
        kinematic : bool
            ``False`` for a redundant flexible member (e.g. a second guiding
            leaf-spring pack): it takes no part in the rigid-body kinematics;
            its frame follows the chord between its end joints, and the change
            of chord length is a prescribed elastic elongation. It carries no
            kinetostatic force; its axial force comes from the elastic solution.
        length : float, optional
            The link's length as specified [m]. The coordinates of ``a`` and
            ``b`` define the length used; when they give one that differs from
            ``length`` by more than :data:`LENGTH_RTOL` (relative), a
            :class:`~kedfem.errors.LengthWarning` is issued (and
            logged) naming the joints and both lengths.
        through : str or sequence of str, optional
            Joints inside the link, on its ``a -> b`` line, that it passes
            through: a pin to the frame (a ground joint: a walking beam on its
            saddle bearing) or to other members (a revolute joint) anywhere
            along it, without splitting the link. A flexible link gets a mesh
            node at each (the stretches between them meshed uniformly, the
            ``elements`` shared in proportion to their lengths); its elastic
            rotation there is its own, or tied to the members the joint welds
            it to (``welded=``).
        """
        self._check_component_name("link", name)
        owner = f"link '{name}'"
        ja = self._check_joint(owner, a)
        jb = self._check_joint(owner, b)
        if a == b:
            raise InputError(f"{owner}: both ends at joint '{a}'")
        stated = length
        length = float(np.hypot(jb.at[0] - ja.at[0], jb.at[1] - ja.at[1]))
        if length <= 1e-12:
            raise InputError(f"{owner}: zero length (joints '{a}' and '{b}' coincide at {ja.at})")
        if stated is not None:
            stated = _number(owner, "length", stated, positive=True, limit=MAX_LENGTH, unit=" m")
        if isinstance(ends, str):
            ends = (ends, ends)
        if not isinstance(ends, (tuple, list)) or len(ends) != 2 or \
                any(not isinstance(e, str) or e not in ("pin", "clamp") for e in ends):
            raise InputError(f"{owner}: ends must be two of 'pin'/'clamp', got {ends!r}")
        ends = tuple(ends)
        rigid = flag(owner, "rigid", rigid)
        timoshenko = flag(owner, "timoshenko", timoshenko)
        kinematic = flag(owner, "kinematic", kinematic)
        if not isinstance(mass_matrix, str) or mass_matrix not in ("consistent", "lumped"):
            raise InputError(f"{owner}: mass_matrix must be 'consistent' or 'lumped', got {mass_matrix!r}")
        if material is not None and not isinstance(material, Material):
            raise InputError(f"{owner}: material must be a kedfem.Material, got {material!r}")
        if section is not None and not isinstance(section, Section):
            raise InputError(f"{owner}: section must be a kedfem.Section, got {section!r}")
        if not kinematic and rigid:
            raise InputError(f"{owner}: a rigid link must take part in the kinematics (kinematic=False "
                             "is for redundant flexible members)")
        if rigid:
            if mass is not None:
                m = _number(owner, "mass", mass, nonneg=True)
            elif material is not None and section is not None:
                m = material.rho * section.A * length
            else:
                m = 0.0
            j = _number(owner, "J", J, nonneg=True) if J is not None else m * length**2 / 12.0
            n_el = 0
        else:
            if material is None or section is None:
                raise InputError(f"{owner}: a flexible link needs material= and section= (or rigid=True)")
            if mass is not None or J is not None:
                raise InputError(f"{owner}: mass=/J= apply to rigid links only")
            if isinstance(elements, bool) or not isinstance(elements, (int, np.integer)) or \
                    not 1 <= elements <= MAX_ELEMENTS:
                raise InputError(f"{owner}: elements must be an integer in 1 .. {MAX_ELEMENTS} "
                                 f"(kedfem.model.mechanism.MAX_ELEMENTS: the cost grows with the cube of the "
                                 f"DOF count), got {elements!r}")
            n_el = int(elements)
            m = material.rho * section.A * length
            j = m * length**2 / 12.0
        through, through_at = self._through(owner, ja, jb, length, through)
        if not kinematic and through:
            raise InputError(f"{owner}: a link with kinematic=False follows the chord between its ends; "
                             "it cannot pass through a joint (through=)")
        if n_el and n_el < len(through) + 1:
            raise InputError(f"{owner}: {len(through)} joint(s) passed through make {len(through) + 1} "
                             f"stretches; elements must be at least {len(through) + 1}, got {n_el}")
        lk = Link(name, a, b, bool(rigid), material, section, n_el, ends, float(m), float(j),
                  mass_matrix, bool(timoshenko), length, bool(kinematic), through, through_at)
        if stated is not None:
            self._check_length(owner, ja, jb, length, stated)
        self.links[name] = lk
        self.graph.add_edge(a, b, key=name, kind="link", component=lk)
        for t in through:  # the joints passed through belong to the link's part
            self.graph.add_edge(a, t, key=f"{name}@{t}", kind="link", component=lk)
        return lk

    def _through(self, owner: str, ja: Joint, jb: Joint, length: float, through):
        """The joints a link passes through, sorted from ``a``, and their abscissae [m]."""
        if through is None:
            return (), ()
        if isinstance(through, str):
            through = (through,)
        if not isinstance(through, (tuple, list)) or not all(isinstance(t, str) for t in through):
            raise InputError(f"{owner}: through must be a joint name or a sequence of joint names, "
                             f"got {through!r}")
        if len(set(through)) != len(through):
            raise InputError(f"{owner}: through names a joint twice: {list(through)!r}")
        pa = np.array(ja.at)
        e1 = (np.array(jb.at) - pa) / length
        out = []
        for t in through:
            jt = self._check_joint(owner, t)
            if t in (ja.name, jb.name):
                raise InputError(f"{owner}: through='{t}' is an end of the link; through names joints "
                                 "inside it")
            if jt.kind not in ("ground", "revolute"):
                raise InputError(f"{owner}: through='{t}' is a {jt.kind} joint; a link passes through a "
                                 "ground joint (a pin to the frame) or a revolute joint (a pin to other "
                                 "members); for a block on the link use slider(..., on=)")
            d = np.array(jt.at) - pa
            xi = float(d @ e1)
            off = float(d[0] * e1[1] - d[1] * e1[0])
            if abs(off) > 1e-9 * length:
                raise InputError(f"{owner}: joint '{t}' at {jt.at} is {abs(off):.3g} m off the link's line "
                                 f"{ja.at} -> {jb.at}; a link passes through joints on its axis")
            if not 1e-9 * length < xi < length * (1 - 1e-9):
                raise InputError(f"{owner}: joint '{t}' is at abscissa {xi:.6g} m, not inside the link "
                                 f"(0 to {length:.6g} m)")
            out.append((xi, t))
        out.sort()
        return tuple(t for _x, t in out), tuple(x for x, _t in out)

    @staticmethod
    def _check_length(owner: str, ja: Joint, jb: Joint, length: float, stated: float) -> None:
        """Warn (and log) when the coordinates give a link another length than the stated one."""
        rel = abs(length - stated) / stated
        if rel > LENGTH_RTOL:
            msg = (f"{owner}: joints '{ja.name}' {ja.at} and '{jb.name}' {jb.at} are {length:.9g} m apart, "
                   f"not the stated length {stated:.9g} m (relative difference {rel:.2g}); the coordinates "
                   "are used (place joints from lengths with Mechanism.at_lengths / at_angle)")
            log.warning(msg)
            warnings.warn(msg, LengthWarning, stacklevel=3)

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

    def body(self, name: str, joints, *, mass: float, J: float, cm=None) -> Body:
        """Add a rigid body attached at several joints.

        Parameters
        ----------
        name : str
            Body name.
        joints : sequence of str
            Attachment joints (at least one); each is a revolute connection
            unless the joint is welded or a link end is clamped there.
        mass : float
            Mass [kg].
        J : float
            Rotary inertia about the centre of mass [kg m^2].
        cm : (float, float), optional
            Centre of mass in the reference configuration [m]; default the
            centroid of the attachment joints.
        """
        self._check_component_name("body", name)
        owner = f"body '{name}'"
        joints = names(owner, "joints", joints)
        if not joints:
            raise InputError(f"{owner}: needs at least one attachment joint")
        if len(set(joints)) != len(joints):
            raise InputError(f"{owner}: attachment joints repeat: {joints}")
        pts = [self._check_joint(owner, j).at for j in joints]
        mass = _number(owner, "mass", mass, nonneg=True)
        J = _number(owner, "J", J, nonneg=True)
        cm = _vec2(owner, "cm", cm) if cm is not None else tuple(np.mean(pts, axis=0).tolist())
        b = Body(name, joints, mass, J, cm)
        self.bodies[name] = b
        for j in joints[1:]:
            self.graph.add_edge(joints[0], j, key=f"{name}:{j}", kind="body", component=b)
        if len(joints) == 1:
            self.graph.nodes[joints[0]].setdefault("bodies", []).append(name)
        return b

    def point_mass(self, joint: str, mass: float, J: float = 0.0) -> PointMass:
        """Add a lumped mass [kg] (and rotary inertia ``J`` [kg m^2]) at a joint."""
        owner = f"point mass at '{joint}'"
        jt = self._check_joint(owner, joint)
        mass = _number(owner, "mass", mass, nonneg=True)
        J = _number(owner, "J", J, nonneg=True)
        if J and jt.kind == "slot" and jt.rotation == "free":
            raise InputError(f"{owner}: a block in a slot turns with the member '{jt.on}', not with the "
                             "members pinned to it; give the block's rotary inertia to that member (J=0 here)")
        pm = PointMass(joint, mass, J)
        self.point_masses.append(pm)
        return pm

    def spring(self, name: str, a: str, b: str | None = None, *, k: float, axis=(0.0, 1.0),
               k3: float = 0.0, preload: float = 0.0) -> Spring:
        """Add a translational spring along a fixed global axis.

        Parameters
        ----------
        name : str
            Spring name.
        a : str
            Joint the spring acts on.
        b : str, optional
            Second joint; ``None`` anchors the spring to the frame.
        k : float
            Linear stiffness [N/m] (>= 0).
        axis : (float, float)
            Line of action (normalised here).
        k3 : float
            Cubic stiffness [N/m^3]: force ``preload + k d + k3 d^3`` for the
            extension ``d`` [m] from the reference configuration.
        preload : float
            Force [N] in the reference configuration (tension positive).
        """
        self._check_component_name("spring", name)
        owner = f"spring '{name}'"
        self._check_joint(owner, a)
        if b is not None:
            self._check_joint(owner, b)
            if b == a:
                raise InputError(f"{owner}: both ends at joint '{a}'")
        s = Spring(name, a, b, _number(owner, "k", k, nonneg=True), _unit(owner, "axis", axis),
                   _number(owner, "k3", k3), _number(owner, "preload", preload))
        self.springs[name] = s
        self.graph.add_edge(a, b if b is not None else a, key=name, kind="spring", component=s)
        return s

    def torsional_spring(self, name: str, joint: str, member: str, other: str | None = None, *,
                         k: float, preload: float = 0.0) -> TorsionalSpring:
        """Add a torsional spring [N m/rad] between two members at a joint.

        ``other=None`` ties ``member`` to the frame. Members are links or bodies
        attached at ``joint``.
        """
        self._check_component_name("torsional spring", name)
        owner = f"torsional spring '{name}'"
        self._check_joint(owner, joint)
        for mem in (member, other):
            if mem is None:
                continue
            if not isinstance(mem, str):
                raise InputError(f"{owner}: a member is named by a string, got {type(mem).__name__} {mem!r}")
            if mem not in self.links and mem not in self.bodies:
                raise InputError(f"{owner} names unknown member '{mem}'")
            if joint not in self._member_joints(mem):
                raise InputError(f"{owner}: member '{mem}' is not attached at joint '{joint}'")
        if other is not None and other == member:
            raise InputError(f"{owner}: ties member '{member}' to itself; give another member at '{joint}' or "
                             "other=None for the frame")
        if other is None and not self.joints[joint].grounded:
            raise InputError(f"{owner}: other=None ties to the frame, but joint '{joint}' is not a ground joint")
        ts = TorsionalSpring(name, joint, member, other, _number(owner, "k", k, nonneg=True),
                             _number(owner, "preload", preload))
        self.torsional_springs[name] = ts
        self.graph.add_edge(joint, joint, key=name, kind="torsional_spring", component=ts)
        return ts

    def drive(self, member: str, speed: float, torsional_stiffness: float | None = None) -> Drive:
        """Drive a link or body at constant speed about its ground joint.

        Parameters
        ----------
        member : str
            Link or body with exactly one ground joint.
        speed : float
            Input speed [rad/s], + counter-clockwise. Several drives are
            synchronised: their speeds must be integer multiples of the first.
        torsional_stiffness : float, optional
            Stiffness of the drive shaft [N m/rad] tying the member to the motor.
        """
        owner = f"drive on '{member}'"
        if not isinstance(member, str) or (member not in self.links and member not in self.bodies):
            raise InputError(f"{owner}: unknown link or body '{member}'")
        if member in self.links and not self.links[member].kinematic:
            raise InputError(f"{owner}: '{member}' has kinematic=False and cannot be driven")
        if any(d.member == member for d in self.drives):
            raise InputError(f"{owner}: '{member}' is driven twice")
        speed = _number(owner, "speed", speed)
        grounds = [j for j in self._member_joints(member) if self.joints[j].grounded]
        if len(grounds) != 1:
            raise InputError(f"{owner}: a driven member needs exactly one ground joint, "
                             f"'{member}' has {len(grounds)} ({', '.join(grounds) or 'none'})")
        kt = None
        if torsional_stiffness is not None:
            kt = _number(owner, "torsional_stiffness", torsional_stiffness, positive=True)
        if self.drives:
            if speed == 0.0 or self.drives[0].speed == 0.0:
                raise InputError(f"{owner}: synchronised drives need non-zero speeds")
            ratio = speed / self.drives[0].speed
            if abs(ratio - round(ratio)) > 1e-9:
                raise InputError(f"{owner}: speed {speed} rad/s is not an integer multiple of the first "
                                 f"drive's {self.drives[0].speed} rad/s, so the motion is not periodic "
                                 "over the first drive's cycle")
        d = Drive(member, speed, grounds[0], kt)
        self.drives.append(d)
        return d

    def load(self, name: str, joint: str, force, profile: Profile | None = None) -> Load:
        """Add an external force [N] (global components) at a joint.

        Parameters
        ----------
        name : str
        joint : str
            Joint the force acts on.
        force : (float, float)
            Force [N]; constant without ``profile``.
        profile : Profile, optional
            A process load: the force times the profile's factor over the cycle, from a table
            of the crank angle, or of a joint's position (on one stroke or both) or velocity
            along an axis (:class:`~kedfem.model.profiles.Profile`; docs/loads.md).

        Examples
        --------
        A press's forming force, 40 kN against the ram over the last 10 mm of its down-stroke
        (the ram ``B`` moves along -y, reaching y = -0.35 m at the bottom dead centre):

        >>> m.load("forming", "B", force=(0.0, 40e3),  # doctest: +SKIP
        ...        profile=kf.Profile.position("B", (0, -1), [0.34, 0.34, 0.35], [0, 1, 1],
        ...                                    stroke="forward"))
        """
        owner = f"load '{name}'"
        if not isinstance(name, str) or not name:
            raise InputError(f"{self.name}: load name must be a non-empty string, got {name!r}")
        if name in self.loads or name in self.frictions:
            raise InputError(f"{self.name}: load name '{name}' is used twice")
        self._check_joint(owner, joint)
        if profile is not None:
            if not isinstance(profile, Profile):
                raise InputError(f"{owner}: profile must be a kf.Profile (Profile.crank_angle, .position or "
                                 f".velocity), got {type(profile).__name__}")
            if profile.joint is not None:
                self._check_joint(f"{owner}: its profile", profile.joint)
        ld = Load(name, joint, _vec2(owner, "force", force, limit=None, unit=" N"), profile)
        self.loads[name] = ld
        return ld

    def friction(self, name: str, joint: str, force: float, axis=None, *, reference_speed: float = 0.0,
                 smoothing: float = 1e-3, follows: str = "rigid") -> Friction:
        """Add a friction force opposing the joint's motion along ``axis``.

        Parameters
        ----------
        name : str
            Load name.
        joint : str
            Joint the force acts on.
        force : float
            Magnitude [N].
        axis : (float, float), optional
            Direction along which the velocity is measured and the force acts.
            Leave it out at a slot joint (``slider(..., on=member)``): the
            friction of the sliding pair, along the block's line, on the
            block's sliding speed relative to the member; the member takes
            the reaction at the block (``follows="rigid"`` only).
        reference_speed : float
            Speed [m/s] of the counter-body along ``axis`` (e.g. the strand's
            casting speed); the force follows the sign of the relative speed.
        smoothing : float
            Regularisation speed [m/s] of the sign function (``tanh``).
        follows : {"rigid", "total"}
            Velocity used: rigid-body only, or rigid plus elastic (iterated).
        """
        owner = f"friction '{name}'"
        if not isinstance(name, str) or not name:
            raise InputError(f"{self.name}: load name must be a non-empty string, got {name!r}")
        if name in self.loads or name in self.frictions:
            raise InputError(f"{self.name}: load name '{name}' is used twice")
        jt = self._check_joint(owner, joint)
        if not isinstance(follows, str) or follows not in ("rigid", "total"):
            raise InputError(f"{owner}: follows must be 'rigid' or 'total', got {follows!r}")
        slot = jt.kind == "slot"
        if slot and axis is not None:
            raise InputError(f"{owner}: at slot joint '{joint}' the friction acts along the block's line on "
                             f"'{jt.on}'; leave axis= out")
        if slot and (follows != "rigid" or jt.slide != "free"):
            raise InputError(f"{owner}: friction in the sliding pair '{joint}' needs slide='free' and "
                             "follows='rigid'")
        if not slot and axis is None:
            raise InputError(f"{owner}: give the axis= the friction acts along (it may be left out only "
                             "at a slot joint)")
        unit = None if slot else _unit(owner, "axis", axis)
        fr = Friction(name, joint, _number(owner, "force", force, nonneg=True), unit,
                      _number(owner, "reference_speed", reference_speed),
                      _number(owner, "smoothing", smoothing, positive=True), follows)
        self.frictions[name] = fr
        return fr

    def set_gravity(self, g) -> None:
        """Set the gravity vector [m/s^2] used by the ``gravity`` effect (and declare it: a scene
        that names no effects simulates it, one that leaves ``gravity`` out says so)."""
        self.gravity = _vec2(self.name, "gravity", g, limit=None, unit=" m/s^2")
        self.gravity_declared = True

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

    def with_speed(self, speed: float) -> "Mechanism":
        """A copy whose drives run at ``speed`` [rad/s] (first drive; the others keep their ratio)."""
        import copy
        if not self.drives:
            raise InputError(f"{self.name}: has no drive to set a speed on")
        speed = _number(f"{self.name}", "speed", speed)
        if speed == 0.0:
            raise InputError(f"{self.name}: speed must be non-zero: a scene needs a cycle of the drive")
        new = copy.deepcopy(self)
        ratio = speed / self.drives[0].speed
        new.drives = [Drive(d.member, d.speed * ratio, d.ground_joint, d.torsional_stiffness)
                      for d in self.drives]
        return new

    def summary(self) -> str:
        """One-line-per-component text description."""
        lines = [f"Mechanism '{self.name}': {len(self.joints)} joints, {len(self.links)} links, "
                 f"{len(self.bodies)} bodies, {len(self.drives)} drives"]
        for lk in self.links.values():
            kind = "rigid" if lk.rigid else f"flexible, {lk.elements} el."
            lines.append(f"  link {lk.name}: {lk.a} -> {lk.b}, L = {lk.length:.6g} m, {kind}")
        for b in self.bodies.values():
            lines.append(f"  body {b.name}: joints {', '.join(b.joints)}, m = {b.mass:.6g} kg")
        return "\n".join(lines)
