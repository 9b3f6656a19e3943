"""The records a :class:`~kedfem.model.mechanism.Mechanism` is made of: joints, links, rigid
bodies, point masses, translational and torsional springs, drives, loads and friction forces.

Frozen dataclasses; the builder's methods (:mod:`kedfem.model.mechanism`, :mod:`kedfem.model.joints`)
check their input and create them. A :class:`Link` also knows its mesh: the stretches between its
ends and the joints it passes through, and the abscissae of its frame elements' nodes.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .materials import Material, Section
from .profiles import Profile

__all__ = ["Joint", "Link", "Body", "PointMass", "Spring", "TorsionalSpring", "Drive", "Load", "Friction"]


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
