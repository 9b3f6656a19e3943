"""Mechanism builder: joints (graph nodes) joined by links, bodies and springs (edges).

A :class:`Mechanism` is a description, not a solver: it records the
reference configuration (every ``at=`` position), the components and the
drives, checks each call's input at once, and keeps a
:class:`networkx.MultiGraph` whose nodes are joints and whose edges are the
links, rigid bodies (a star of edges from their first attachment) and
springs. Kinematics, assembly and the solvers read it.

Conventions: SI units throughout; angles in radians, positive
counter-clockwise; a link's angle is the angle of its ``a -> b`` line.

The class is put together from parts, each in its module: the joints and their placement
(:mod:`kedfem.model.joints`), the graph queries (:mod:`kedfem.model.queries`) and
:meth:`Mechanism.validate` (:mod:`kedfem.model.consistency`); the records it holds are in
:mod:`kedfem.model.components`. This module holds the dataclass and the members, springs, drives
and loads that join the joints.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field

import networkx as nx
import numpy as np

from ..errors import InputError, user_stacklevel
from .materials import MAX_LENGTH, Material, Section, flag, names
from .arguments import _number, _unit, _vec2
from .components import Body, Drive, Friction, Joint, Link, Load, PointMass, Spring, TorsionalSpring
from .consistency import ConsistencyChecks
from .joints import GROUND as _GROUND, JointBuilder
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

#: The frame's node name in the joint graph, which no joint may take (:data:`kedfem.model.joints.GROUND`)
GROUND = _GROUND
#: Largest number of frame elements per link (the cost grows with the cube of the DOF count;
#: 200 elements of 3 DOFs already make a 600-DOF link).
MAX_ELEMENTS = 200
#: Relative difference between a link's stated ``length=`` and its coordinates that warns
LENGTH_RTOL = 1e-6

log = logging.getLogger(__name__)


def require_mechanism(obj, owner: str = "kedfem") -> "Mechanism":
    """``obj`` if it is a :class:`Mechanism`, else an :class:`InputError` naming ``owner``."""
    if not isinstance(obj, Mechanism):
        raise InputError(f"{owner}: expected a kedfem.Mechanism, got {type(obj).__name__} {_short(obj)}")
    return obj


def _short(v) -> str:
    r = repr(v)
    return r if len(r) <= 60 else r[:57] + "..."


@dataclass
class Mechanism(JointBuilder, ConsistencyChecks):
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

    # -------------------------------------------------------------- components
    def _check_component_name(self, kind: str, name: str):
        if not isinstance(name, str) or not name:
            raise InputError(f"{self.name}: {kind} name must be a non-empty string, got {name!r}")
        taken = set(self.links) | set(self.bodies) | set(self.springs) | set(self.torsional_springs)
        if name in taken:
            raise InputError(f"{self.name}: component name '{name}' is used twice")

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
            warnings.warn(msg, LengthWarning, stacklevel=user_stacklevel())

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
        (the ram ``B`` moves along -y, reaching y = -0.35 m at the bottom dead centre), rising
        along an S-curve from where the tool meets the part (a step there rings the links' axial
        modes and costs thousands of time elements, docs/loads.md):

        >>> m.load("forming", "B", force=(0.0, 40e3),  # doctest: +SKIP
        ...        profile=kf.Profile.position("B", (0, -1), [0.34, 0.35], [0, 1],
        ...                                    stroke="forward", smooth=True))
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

    # ------------------------------------------------------- a copy, a summary
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
