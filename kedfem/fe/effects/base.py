"""The contract of an effect, and what the assembler hands it.

An effect is a frozen dataclass with a ``name`` and a one-line ``adds``. It
overrides the hooks it needs; each hook has a no-op default:

=================== =========================================================== ==================
hook                adds                                                        space
=================== =========================================================== ==================
``joint_loads``     loads on the rigid-body motion, for the kinetostatic forces joints, members
``element_terms``   ``M, C, K, Q`` of element groups, in element coordinates    x (per group)
``terms``           ``M, C, K, Q`` of the whole model                           q (DOFs)
``state_terms``     tangents ``dC, dK`` and load ``dQ`` about a trial response  q (DOFs)
=================== =========================================================== ==================

``state_dependent(mech)`` says whether ``state_terms`` is needed (then the solve
iterates). Four flags say how an effect changes the assembler's own work:
``weight`` (the kinetostatic forces include gravity), ``transports_maps`` (the
time derivatives of moving constraint maps enter ``C`` and ``K``),
``offset_inertia`` (prescribed offsets' accelerations load the elastic DOFs)
and ``carries_axial_forces`` (the links' axial forces come from the elastic
state, so no kinetostatic geometric stiffness is added for them).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ...motion.kinematics import Motion

__all__ = ["Effect", "Chunk", "BeamKinematics", "StateTerms", "GroupTerms", "slice_motion"]


def slice_motion(motion: Motion, idx) -> Motion:
    """The motion restricted to time nodes ``idx``."""
    idx = np.asarray(idx)
    fields = {}
    for f in ("t", "crank_angle", "r", "v", "a", "theta", "omega", "alpha", "s", "sd", "sdd"):
        fields[f] = getattr(motion, f)[idx]
    return dataclasses.replace(motion, **fields)


class GroupTerms:
    """Per-group element-coordinate accumulator of ``M, C, K, Ks, Q`` for one chunk of instants.

    Arrays are (nt or 1, n_el, d, d) for matrices and (nt, n_el, d) for ``Q``;
    ``Ks`` is the structural stiffness that stiffness-proportional damping uses.
    """

    def __init__(self):
        self.data: dict[str, dict[str, np.ndarray]] = {}

    def add(self, group: str, key: str, val: np.ndarray) -> None:
        """Add ``val`` to term ``key`` of element group ``group`` (broadcasting over instants)."""
        d = self.data.setdefault(group, {})
        if key in d:
            a = d[key]
            if a.shape != val.shape:
                a = np.broadcast_to(a, np.broadcast_shapes(a.shape, val.shape)).copy()
            d[key] = a + val
        else:
            d[key] = np.array(val, dtype=float, copy=True)

    def get(self, group: str, key: str):
        """Term ``key`` of ``group``, or None."""
        return self.data.get(group, {}).get(key)


@dataclass(frozen=True)
class BeamKinematics:
    """Rigid-body kinematics of every beam element's frame at a chunk of instants.

    ``theta, omega, alpha``: (nt, n_el) [rad, rad/s, rad/s^2] of the element's
    link; ``a_a``: (nt, n_el, 2) acceleration [m/s^2] of the link's joint ``a``;
    ``T``: (nt, n_el, 6, 6) rotation to the element frame, ``Tt`` its transpose,
    ``R_T``: (nt, n_el, 2, 2) the rotation ``R(theta)``.
    """

    theta: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    a_a: np.ndarray
    T: np.ndarray
    Tt: np.ndarray
    R_T: np.ndarray


@dataclass
class Chunk:
    """What ``element_terms`` works on: a chunk of instants and its accumulator.

    ``motion`` is the rigid-body motion at the chunk's instants ``idx`` (indices
    into the assembler's cycle); ``beam`` the beam frames' kinematics there (None
    without flexible links); ``acc`` the accumulator the hooks add to.
    """

    motion: Motion
    idx: np.ndarray
    beam: BeamKinematics | None
    acc: GroupTerms = field(default_factory=GroupTerms)


@dataclass
class StateTerms:
    """q-space state terms about a trial response, filled by the effects' ``state_terms``.

    ``dK``: (nt, N, N) tangent stiffness [N/m]; ``dQ``: (nt, N) matching load
    [N]; ``dC``: (nt, N, N) tangent damping [N s/m], created by :meth:`damping`
    when an effect first needs it.
    """

    dK: np.ndarray
    dQ: np.ndarray
    dC: np.ndarray | None = None

    def damping(self) -> np.ndarray:
        """The tangent damping array, created (zero) on first use."""
        if self.dC is None:
            self.dC = np.zeros_like(self.dK)
        return self.dC


@dataclass(frozen=True)
class Effect:
    """An effect: its name, what it adds, and its hooks (all no-ops here).

    Subclass it in a module of its own, override the hooks the physics needs,
    and add one line to the registry (:mod:`kedfem.fe.effects`) or call
    :func:`kedfem.fe.effects.register_effect`.
    """

    name: str
    adds: str

    weight = False
    transports_maps = False
    offset_inertia = False
    carries_axial_forces = False

    def state_dependent(self, mech) -> bool:
        """True if this effect makes the equations depend on the elastic state (the solve iterates)."""
        return False

    def joint_loads(self, asm, motion: Motion, loads: np.ndarray, moments: np.ndarray) -> None:
        """Add this effect's loads on the rigid-body motion, over the whole cycle.

        ``loads``: (n, n_joints, 2) forces on joints [N]; ``moments``: (n,
        n_members) moments on members [N m]. They enter the kinetostatic joint
        forces (and so the links' axial forces of ``axial_stiffening``).
        """

    def pair_loads(self, asm, motion: Motion) -> dict:
        """Known forces inside sliding pairs on the rigid-body motion: slot joint -> (n,) [N].

        The force the member exerts on the block along the block's line (the
        block exerts the opposite on the member, at the block); it enters the
        kinetostatics with the pair's unknown normal force.
        """
        return {}

    def element_terms(self, asm, chunk: Chunk) -> None:
        """Add element-coordinate terms to ``chunk.acc`` (by element group)."""

    def terms(self, asm, chunk: Chunk) -> dict | None:
        """q-space terms at the chunk's instants (``chunk.motion``, ``chunk.idx``).

        Returns ``None`` or a dict with any of ``"M"``, ``"C"``, ``"K"`` (nt,
        N, N) and ``"Q"`` (nt, N) [SI], added to the assembled system;
        ``asm.model`` is the :class:`kedfem.fe.model.FEModel`.
        """
        return None

    def state_terms(self, asm, motion: Motion, U: np.ndarray, V: np.ndarray, out: StateTerms) -> None:
        """Add tangents and load about the trial response ``U, V`` (nt, N) to ``out``.

        Newton's linearisation: ``dQ = -f_nl(x) + K_nl x + C_nl x'`` so that a
        fixed point of the linear solve satisfies the non-linear equations.
        """

    def has_own_terms(self) -> bool:
        """True if the subclass overrides any hook (a registrable effect)."""
        hooks = ("joint_loads", "element_terms", "terms", "state_terms")
        return any(getattr(type(self), h) is not getattr(Effect, h) for h in hooks)
