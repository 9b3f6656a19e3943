"""``axial_stiffening``: geometric stiffness of the kinetostatic (rigid-body) forces.

A link's elements take ``int N(x) v'^T v' dx`` of the kinetostatic axial force
along them (read at four Gauss points per element: exact for the quadratic
force of a link's own inertia, so the deflection converges at fourth order in
the element length; unless ``geometric_nonlinearity`` carries the links' axial
forces from the elastic state); a rigid member with an elastic rotation
``phi`` takes ``sum F . rho`` of the forces on it about its reference point
(joint forces, its weight with ``gravity``, and its inertial force in the
inertial frame; docs/theory.md section 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...model import elements as el
from ...motion.kinematics import Motion
from ...motion.kinetostatics import member_centre
from .base import Chunk, Effect

__all__ = ["AxialStiffening"]


@dataclass(frozen=True)
class AxialStiffening(Effect):
    """Geometric stiffness of links and rigid members under their kinetostatic forces."""

    name: str = "axial_stiffening"
    adds: str = "geometric stiffness of the kinetostatic (rigid-body) forces"

    def element_terms(self, asm, chunk: Chunk) -> None:
        bk = chunk.beam
        if bk is None or asm.carries_axial_forces:
            return
        N = asm.beam_axial_kinetostatic()[chunk.idx]
        chunk.acc.add("beam", "K", bk.Tt @ el.geometric_stiffness_varying(asm.model.beam.L, N) @ bk.T)

    def terms(self, asm, chunk: Chunk) -> dict | None:
        if not asm.model.rigid_groups:
            return None
        return {"K": _rigid_geometric(asm, chunk.motion, chunk.idx)}


def _rigid_geometric(asm, mo: Motion, idx: np.ndarray) -> np.ndarray:
    """q-space geometric stiffness ``sum F . rho`` of rigid member groups at the cycle's
    instants ``idx`` (``mo`` the motion there), (nt, N, N) [N m]."""
    model, mech = asm.model, asm.mech
    out = np.zeros((mo.n, model.n_dof, model.n_dof))
    forces = asm.joint_forces()
    for grp in model.rigid_groups:
        phi = grp["phi"]
        if phi < 0:
            continue
        q = model.rots[phi].cols[0]
        ref = model.points[grp["ref"]].loc
        rr = model.loc_motion(ref, mo)[0] if ref else np.zeros((mo.n, 2))
        val = np.zeros(mo.n)
        for m in grp["members"]:
            for k, (mem, j) in enumerate(forces.pairs):
                if mem == m:
                    rj = mo.r[:, mo.joint_names.index(j)]
                    val += np.einsum("nd,nd->n", forces.force[idx, k], rj - rr)
            mass = asm.member_inertia(m)[0]
            rc, _vc, ac = member_centre(mech, mo, m)
            own = np.zeros((mo.n, 2))
            if asm.weight:
                own += mass * np.asarray(mech.gravity)
            if not asm.frame:
                own -= mass * ac
            val += np.einsum("nd,nd->n", own, rc - rr)
        out[:, q, q] += val
    return out
