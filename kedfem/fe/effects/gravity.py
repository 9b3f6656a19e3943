"""``gravity``: weight loads ``m g`` (``mechanism.gravity`` [m/s^2]).

On the elastic DOFs: the beams' distributed weight, rigid members' and point
masses' weight at their centres. On the rigid-body motion: the kinetostatic
joint forces include the weights (``weight``), so the links' axial forces of
``axial_stiffening`` do too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...model import elements as el
from .base import Chunk, Effect

__all__ = ["Gravity"]


@dataclass(frozen=True)
class Gravity(Effect):
    """Weight of beams, rigid members and point masses."""

    name: str = "gravity"
    adds: str = "weight loads"
    weight = True

    def element_terms(self, asm, chunk: Chunk) -> None:
        g_vec = np.asarray(asm.mech.gravity)
        nt, bk = chunk.motion.n, chunk.beam
        if bk is not None:
            b = asm.model.beam
            g_loc = np.einsum("tnji,j->tni", bk.R_T, g_vec)
            f = el.linear_load(b.L, b.rhoA[:, None] * g_loc, np.zeros_like(g_loc))
            chunk.acc.add("beam", "Q", np.einsum("tnji,tnj->tni", bk.T, f))
        g = asm.model.groups["rigid"]
        if g.n:
            mass = np.array([asm.member_inertia(m)[0] for m in g.meta["members"]])
            Q = np.zeros((nt, g.n, 3))
            Q[:, :, 0:2] += mass[:, None] * g_vec
            chunk.acc.add("rigid", "Q", Q)
        g = asm.model.groups["pmass"]
        if g.n:
            mass = np.array([p.mass for p in g.meta["items"]])
            Q = np.zeros((nt, g.n, 3))
            Q[:, :, 0:2] += mass[:, None] * g_vec
            chunk.acc.add("pmass", "Q", Q)
