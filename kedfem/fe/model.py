"""The finite-element model of a mechanism: DOF numbering, constraint maps and scatter, together.

Elastic displacements are expressed in the global frame, or (the default, ``corotate``) a
joint's and an interior node's translations in the frame of a link turning with the mechanism,
so labels read ``B.u[rocker]``, ``rod.n3.v``. Every component
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

from ..errors import InputError
from ..model.mechanism import Mechanism, require_mechanism
from .dofs import BeamData, DofNumbering, Group, PointDof, RotDof
from .maps import ConstraintMaps, GroupMap
from .scatter import Scatter

__all__ = ["FEModel", "GroupMap", "PointDof", "RotDof", "Group", "BeamData"]

log = logging.getLogger(__name__)


class FEModel(DofNumbering, ConstraintMaps, Scatter):
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
        require_mechanism(mechanism, "FE model")
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
        self._build_slots()
        self._build_groups()
        self.n_dof = len(self.dof_labels)
        if self.n_dof == 0:
            raise InputError(f"{mechanism.name}: the model has no elastic DOFs (all links rigid and fixed)")
        self._scatter_cache: dict = {}
        self._static_cache: dict = {}
        log.debug("FE model of %s: %d DOFs, %d beam elements", mechanism.name, self.n_dof,
                  self.beam.L.size)

