"""``springs``: forces of declared springs over the rigid-body motion, preload, cubic laws.

The linear stiffness of springs is structure (always assembled). This effect
adds what the rigid-body motion does to them: a linear spring's force
``F = preload + k d + k3 d^3`` at its rigid-body extension ``d`` and a torsional
spring's moment, as loads on the elastic DOFs and on the kinetostatics; with
``k3 != 0`` the cubic part about the elastic extension is iterated (docs/theory.md
section 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...motion.kinematics import Motion
from ..structure import spring_axes
from .base import Chunk, Effect, StateTerms

__all__ = ["Springs", "spring_extension", "torsional_moment"]


def spring_extension(mech, mo: Motion, s) -> np.ndarray:
    """Extension [m] (nt,) of a linear spring along its axis over the rigid-body motion."""
    n = np.asarray(s.axis)
    d = (mo.r[:, mo.joint_names.index(s.a)] - np.asarray(mech.joints[s.a].at)) @ n
    if s.b is not None:
        d = d - (mo.r[:, mo.joint_names.index(s.b)] - np.asarray(mech.joints[s.b].at)) @ n
    return d


def torsional_moment(mo: Motion, t):
    """Moment [N m] (nt,) of a torsional spring over the rigid-body motion, on ``member`` (index i,
    taken negative) and ``other`` (index k or None, taken positive)."""
    i = mo.member_names.index(t.member)
    rel = mo.theta[:, i] - mo.theta_ref[i]
    k = None
    if t.other is not None:
        k = mo.member_names.index(t.other)
        rel = rel - (mo.theta[:, k] - mo.theta_ref[k])
    return i, k, t.preload + t.k * rel


def _rigid_extensions(asm, mo: Motion) -> np.ndarray:
    """Rigid-body extension of every spring of the ``spring`` group, (nt, n_spring) [m]."""
    items = asm.model.groups["spring"].meta["items"]
    return np.stack([spring_extension(asm.mech, mo, s) for s in items], axis=-1) if items \
        else np.zeros((mo.n, 0))


@dataclass(frozen=True)
class Springs(Effect):
    """Spring forces of the rigid-body motion and preload; cubic spring laws (iterated)."""

    name: str = "springs"
    adds: str = "spring forces of the rigid-body motion and preload; cubic spring laws"

    def state_dependent(self, mech) -> bool:
        return any(s.nonlinear for s in mech.springs.values())

    def joint_loads(self, asm, motion: Motion, loads: np.ndarray, moments: np.ndarray) -> None:
        for s in asm.mech.springs.values():
            n = np.asarray(s.axis)
            d = spring_extension(asm.mech, motion, s)
            F = s.preload + s.k * d + s.k3 * d**3
            loads[:, motion.joint_names.index(s.a)] -= F[:, None] * n
            if s.b is not None:
                loads[:, motion.joint_names.index(s.b)] += F[:, None] * n
        for t in asm.mech.torsional_springs.values():
            i, k, Mt = torsional_moment(motion, t)
            moments[:, i] -= Mt
            if k is not None:
                moments[:, k] += Mt

    def element_terms(self, asm, chunk: Chunk) -> None:
        mo = chunk.motion
        g = asm.model.groups["spring"]
        if g.n:
            items = g.meta["items"]
            d = _rigid_extensions(asm, mo)
            F = np.array([s.preload for s in items]) + np.array([s.k for s in items]) * d \
                + np.array([s.k3 for s in items]) * d**3
            chunk.acc.add("spring", "Q", -F[..., None] * spring_axes(items))
        g = asm.model.groups["tspring"]
        if g.n:
            Q = np.zeros((mo.n, g.n, 2))
            for k, (kind, t) in enumerate(g.meta["items"]):
                if kind == "spring":
                    Mt = torsional_moment(mo, t)[2]
                    Q[:, k, 0] = -Mt
                    Q[:, k, 1] = Mt
            chunk.acc.add("tspring", "Q", Q)

    def state_terms(self, asm, motion: Motion, U, V, out: StateTerms) -> None:
        if not self.state_dependent(asm.mech):
            return
        items = asm.model.groups["spring"].meta["items"]
        x, _xd, _xq, gm = asm.element_state("spring", motion, U)
        B = spring_axes(items)
        de = np.einsum("ni,tni->tn", B, x)  # spring ends are points: no prescribed part
        dr = _rigid_extensions(asm, motion)
        k3 = np.array([s.k3 for s in items])
        knl = 3.0 * k3 * (dr + de)**2
        fnl = k3 * ((dr + de)**3 - dr**3)  # F(dr + de) - F(dr) - k de
        Kx = knl[..., None, None] * (B[:, :, None] * B[:, None, :])
        Qx = (-fnl + knl * de)[..., None] * B
        asm.apply_state("spring", gm, Kx, Qx, out.dK, out.dQ)
