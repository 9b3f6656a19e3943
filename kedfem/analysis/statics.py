"""Static response of a mechanism held at one crank position (or a structure).

Solves ``K u = Q`` with the chosen effects' stiffness and loads at rest
(velocities zero unless the mechanism runs: then the kinetostatic loads of
that position are included as quasi-static loads).

The deflections, section forces and stresses of a :class:`StaticResult` are
those of :class:`~kedfem.analysis.results.PeriodicResult`, computed by the
same code: the static state is read as a one-instant periodic result whose
elastic coordinates do not move (:meth:`StaticResult._periodic`), so the
element-equilibrium recovery (:mod:`kedfem.analysis.recovery`) adds the
distributed loads the chosen effects put on each element (weight, and the
rigid-body inertia of a running mechanism's crank position).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse.linalg as spla

from ..errors import EffectWarning, KedError, user_stacklevel
from ..fe.assembler import Assembler
from ..fe.effects import check_effects, unsimulated
from ..fe.model import FEModel
from ..model.mechanism import Mechanism, require_mechanism
from ..motion.kinematics import Motion
from .modal import _motion_at

__all__ = ["StaticResult", "static_response"]


@dataclass(frozen=True)
class _Held:
    """What the periodic result's post-processing reads of a scene, for a static state."""

    mech: Mechanism
    effects: tuple[str, ...]
    name: str = ""
    damping: object = None


class _AtRest:
    """A sampler of a state held still: every elastic acceleration is zero.

    With it the periodic result derives the element rates from the constraint
    maps alone (``x' = E' q + p'``, ``x'' = E'' q + p''``), which is what a
    static solve of ``K q = Q`` (``q' = q'' = 0``) assumes.
    """

    def __init__(self, n_dof: int):
        self.n_dof = n_dof

    def acceleration(self, t) -> np.ndarray:
        return np.zeros((np.size(t), self.n_dof))


@dataclass(frozen=True)
class StaticResult:
    """Static elastic displacements, with their deflections, section forces and stresses.

    Attributes
    ----------
    U : ndarray, shape (N,)
        Elastic displacements [m, rad], in the order of ``dof_labels``.
    dof_labels : tuple of str
        DOF labels (:attr:`kedfem.fe.model.FEModel.dof_labels`).
    model : FEModel
        The finite-element model.
    motion : Motion, optional
        The rigid-body state the response was solved at (one time node);
        default the mechanism's at ``crank_angle``.
    effects : tuple of str
        The effects of the solve (they decide which distributed loads the
        section-force recovery adds).
    crank_angle : float
        Crank angle [rad] of a driven mechanism.

    The accessors are those of :class:`~kedfem.analysis.results.PeriodicResult`
    without the time axis: ``deflection`` a float, ``bending_moment`` an array
    over the stations, ``joint_displacement`` a vector (2,).
    """

    U: np.ndarray
    dof_labels: tuple[str, ...]
    model: FEModel
    motion: Motion | None = None
    effects: tuple[str, ...] = ()
    crank_angle: float = 0.0
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __repr__(self) -> str:
        mech = self.model.mech
        where = f", crank angle {math.degrees(self.crank_angle):.6g} deg" if mech.drives else ""
        eff = ", ".join(self.effects) or "no effects"
        return f"<StaticResult {mech.name}: {self.model.n_dof} DOFs, {eff}{where}>"

    def dof(self, label: str) -> float:
        """Value of the DOF with ``label`` [m or rad]."""
        return float(self.U[self.model.dof_index(label)])

    def _periodic(self):
        """The state as a one-instant :class:`PeriodicResult` (built once): its accessors do the work."""
        view = self._cache.get("periodic")
        if view is None:
            from .results import PeriodicResult
            mech = self.model.mech
            mo = self.motion if self.motion is not None else _motion_at(mech, self.crank_angle)
            U = np.asarray(self.U, dtype=float)[None]
            view = PeriodicResult(_Held(mech, tuple(self.effects), mech.name), self.model, mo, mo.t,
                                  mo.crank_angle, U, np.zeros_like(U), tuple(self.dof_labels),
                                  floquet_multipliers=np.zeros(0), stable=True, converged=True, iterations=1,
                                  history=(), residual=0.0, timings=None, method="static",
                                  sampler=_AtRest(self.model.n_dof))
            self._cache["periodic"] = view
        return view

    # ----------------------------------------------------------- link results
    def stations(self, link: str, per_element: int = 1) -> np.ndarray:
        """Stations (n_el per_element + 1,) along a flexible link, from joint ``a`` [m]."""
        return self._periodic().stations(link, per_element)

    def deflection(self, link: str, xi: float = 0.5, relative_to: str = "frame") -> float:
        """Transverse elastic deflection [m] at fraction ``xi`` (0..1, from joint ``a``) of a link.

        ``relative_to="frame"``: along the link frame's +y (the ``a -> b``
        direction turned +90 deg, counter-clockwise); ``"chord"``: relative to
        the chord through the deflected end points.
        """
        return float(self._periodic().deflection(link, xi, relative_to)[0])

    def bending_moment(self, link: str, per_element: int = 1) -> np.ndarray:
        """Bending moment ``M = EI v''`` [N m] at the link's stations (n_el per_element + 1,).

        By element equilibrium (exact within each Euler-Bernoulli element for
        the distributed loads of the effects); positive when the link bends
        concave towards its frame's +y.
        """
        return self._periodic().bending_moment(link, per_element)[0]

    def axial_force(self, link: str) -> np.ndarray:
        """Axial force [N] at the element midpoints (n_el,), tension positive."""
        return self._periodic().axial_force(link)[0]

    def section_forces(self, link: str, per_element: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Axial force ``N`` [N] (tension positive) and bending moment ``M`` [N m] at the stations."""
        N, M = self._periodic().section_forces(link, per_element)
        return N[0], M[0]

    def stress(self, link: str, per_element: int = 1) -> np.ndarray:
        """Largest absolute normal stress ``|N|/A + |M| c / I`` [Pa] at the stations (needs ``Section.c``)."""
        return self._periodic().stress(link, per_element)[0]

    def link_displacement(self, link: str) -> np.ndarray:
        """Elastic displacement (n_el + 1, 2) [m] of a flexible link's nodes, global components."""
        return self._periodic().link_displacement(link)[0]

    def joint_displacement(self, joint: str) -> np.ndarray:
        """Elastic displacement (2,) [m] of a joint, global components."""
        return self._periodic().joint_displacement(joint)[0]


def static_response(mechanism: Mechanism, effects=("gravity", "loads"), crank_angle: float = 0.0) -> StaticResult:
    """Static elastic displacements under the chosen load effects.

    Parameters
    ----------
    mechanism : Mechanism
    effects : sequence of str
        Effects; typically ``gravity``, ``loads``, ``springs`` (and
        ``inertia`` for a quasi-static kinetostatic load case of a running
        mechanism; ``axial_stiffening`` adds the geometric stiffness of the
        kinetostatic axial forces, which a slender link under compression
        needs: the same effect names as :class:`kedfem.Scene`'s, so a scene's
        quasi-static limit is ``static_response(m, scene.effects, angle)``
        without its dynamic terms).
    crank_angle : float
        Absolute crank angle [rad] of a driven mechanism: the first driven
        member's ``a -> b`` line from +x, counter-clockwise, as
        :attr:`PeriodicResult.crank_angle` and :class:`kedfem.motion.stroke.Stroke`
        give it (not the angle turned from the drawing, which
        ``Profile.crank_angle`` tables take).

    Returns
    -------
    StaticResult
        Displacements, with deflection, section-force and stress accessors.

    Raises
    ------
    KedError
        The stiffness matrix is singular (a mechanism, i.e. a free
        rigid-body motion, in the structure).
    """
    require_mechanism(mechanism, "static_response")
    eff = check_effects(effects)
    for msg in unsimulated(mechanism, eff):  # a spring's preload or a load the effects leave out
        warnings.warn(msg, EffectWarning, stacklevel=user_stacklevel())
    model = FEModel(mechanism)
    motion = _motion_at(mechanism, crank_angle)
    asm = Assembler(model, motion, eff)
    _M, _C, K, Q = asm.sparse_system(0)
    K = K.tocsc()
    singular = KedError(f"{mechanism.name}: the stiffness matrix is singular: the structure can move "
                        "without deforming (a free rigid-body mode); add supports")
    try:
        lu = spla.splu(K)
    except RuntimeError:  # SuperLU: "Factor is exactly singular"
        raise singular from None
    diag = np.abs(lu.U.diagonal())
    if diag.min() <= 1e-12 * diag.max():
        raise singular
    U = lu.solve(Q)
    return StaticResult(U, tuple(model.dof_labels), model, motion, eff, float(motion.crank_angle[0]))
