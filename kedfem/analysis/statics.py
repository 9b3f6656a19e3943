"""Static response of a mechanism held at one crank position (or a structure).

Solves ``K u = Q`` with the chosen effects' stiffness and loads at rest
(velocities zero unless the mechanism runs: then the kinetostatic loads of
that position are included as quasi-static loads).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg as spla

from ..fe.model import FEModel
from ..fe.assembler import Assembler
from ..fe.effects import check_effects
from ..errors import KedError
from ..model.mechanism import Mechanism
from .modal import _motion_at

__all__ = ["StaticResult", "static_response"]


@dataclass(frozen=True)
class StaticResult:
    """Static elastic displacements.

    ``U`` (N,) [m, rad] with ``dof_labels``; ``model`` the FE model.
    """

    U: np.ndarray
    dof_labels: tuple[str, ...]
    model: FEModel

    def dof(self, label: str) -> float:
        """Value of the DOF with ``label``."""
        return float(self.U[self.model.dof_index(label)])


def static_response(mechanism: Mechanism, effects=("gravity", "loads"), crank_angle: float = 0.0) -> StaticResult:
    """Static elastic displacements under the chosen load effects.

    Parameters
    ----------
    mechanism : Mechanism
    effects : sequence of str
        Effects; typically ``gravity``, ``loads``, ``springs`` (and
        ``inertia`` for a quasi-static kinetostatic load case of a running
        mechanism).
    crank_angle : float
        Crank angle [rad] of a driven mechanism.

    Returns
    -------
    StaticResult

    Raises
    ------
    KedError
        The stiffness matrix is singular (a mechanism, i.e. a free
        rigid-body motion, in the structure).
    """
    eff = check_effects(effects)
    model = FEModel(mechanism)
    motion = _motion_at(mechanism, crank_angle)
    asm = Assembler(model, motion, eff)
    _M, _C, K, Q = asm.sparse_system(0)
    K = K.tocsc()
    lu = spla.splu(K)
    diag = np.abs(lu.U.diagonal())
    if diag.min() <= 1e-12 * diag.max():
        raise KedError(f"{mechanism.name}: the stiffness matrix is singular: the structure can move "
                       "without deforming (a free rigid-body mode); add supports")
    U = lu.solve(Q)
    return StaticResult(U, tuple(model.dof_labels), model)
