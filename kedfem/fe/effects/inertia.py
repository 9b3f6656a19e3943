"""``inertia``: the rigid-body inertial loads ``-M r0''`` on the elastic DOFs.

Beams take the distributed load of their rigid-body acceleration (linear over
an element: the acceleration of the link's joint plus the centripetal and
tangential parts along the link); rigid members and point masses take
``-m a_c`` and ``-J alpha`` (docs/theory.md section 3). Prescribed offsets'
accelerations load the elastic DOFs too (``offset_inertia``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...model import elements as el
from ...motion.kinetostatics import member_centre
from .base import Chunk, Effect

__all__ = ["Inertia"]


@dataclass(frozen=True)
class Inertia(Effect):
    """Rigid-body inertial loads of beams, rigid members and point masses."""

    name: str = "inertia"
    adds: str = "rigid-body inertial loads -M r0''"
    offset_inertia = True

    def element_terms(self, asm, chunk: Chunk) -> None:
        mo, bk = chunk.motion, chunk.beam
        if bk is not None:
            b = asm.model.beam
            c = np.stack([-(bk.omega**2), bk.alpha], axis=-1)  # (nt, n_el, 2)
            a_loc = np.einsum("tnji,tnj->tni", bk.R_T, bk.a_a)  # R^T a_a
            p0 = -b.rhoA[:, None] * (a_loc + b.s1[:, None] * c)
            p1 = -b.rhoA[:, None] * c
            f = el.linear_load(b.L, p0, p1)
            chunk.acc.add("beam", "Q", np.einsum("tnji,tnj->tni", bk.T, f))
        g = asm.model.groups["rigid"]
        if g.n:
            Q = np.zeros((mo.n, g.n, 3))
            for k, m in enumerate(g.meta["members"]):
                mass, J = asm.member_inertia(m)
                _r, _v, ac = member_centre(asm.mech, mo, m)
                Q[:, k, 0:2] -= mass * ac
                Q[:, k, 2] -= J * mo.alpha[:, mo.member_names.index(m)]
            chunk.acc.add("rigid", "Q", Q)
        g = asm.model.groups["pmass"]
        if g.n:
            Q = np.zeros((mo.n, g.n, 3))
            for k, p in enumerate(g.meta["items"]):
                Q[:, k, 0:2] -= p.mass * mo.a[:, mo.joint_names.index(p.joint)]
                rid = g.ids[k, 1]
                if rid >= 0 and p.J > 0:
                    mem = asm.model.rots[rid].member
                    Q[:, k, 2] -= p.J * mo.alpha[:, mo.member_names.index(mem)]
            chunk.acc.add("pmass", "Q", Q)
