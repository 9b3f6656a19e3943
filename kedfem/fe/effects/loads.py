"""``loads``: declared loads and friction forces.

A :class:`kedfem.model.mechanism.Load` is a force on a joint, constant or times the factor of
its profile over the cycle (a process load, :mod:`kedfem.motion.profiles`). A
friction force (tanh-regularised Coulomb law along an axis) follows either the
rigid-body velocity of its joint (``follows="rigid"``: a load) or the total
velocity (``follows="total"``: iterated, with the tangent damping ``c_t n n^T``).
Both load the kinetostatics too (docs/theory.md section 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...model.mechanism import Load
from ...motion.kinematics import Motion, slot_direction
from ...motion.profiles import breaks, distinct_instants, factor, quantity
from .base import Chunk, Effect, StateTerms

__all__ = ["Loads", "rigid_friction", "friction_law", "pair_friction", "load_force", "load_breaks", "idle_loads"]


def idle_loads(mech, cycle, samples: int = 720) -> list[str]:
    """A message for every process load whose factor is zero over the whole cycle (its table lies
    outside the joint's travel, or its stroke never comes): it would add nothing, silently."""
    out = []
    mo = None
    for ld in mech.loads.values():
        if ld.profile is None:
            continue
        if mo is None:
            mo = cycle.at(np.arange(samples) * (mech.period / samples))
        f = factor(ld.profile, mo)
        if not np.any(f != 0.0):
            q, _rate = quantity(ld.profile, mo)
            unit = {"crank_angle": "deg", "position": "m", "velocity": "m/s"}[ld.profile.of]
            out.append(f"{mech.name}: load '{ld.name}' never acts: its profile's factor is zero over the whole "
                       f"cycle ({ld.profile.of} from {q.min():.6g} to {q.max():.6g} {unit}, the table from "
                       f"{ld.profile.x[0]:.6g} to {ld.profile.x[-1]:.6g} {unit}"
                       + (f", stroke '{ld.profile.stroke}'" if ld.profile.stroke != "both" else "")
                       + "); check the table's sign and the axis")
    return out


def load_breaks(mech, cycle, period: float) -> np.ndarray:
    """Instants [s] in ``[0, period)`` where a process load's force kinks or steps (sorted, each
    once): :func:`kedfem.motion.profiles.breaks` of every declared load's profile."""
    found = [breaks(ld.profile, cycle, period) for ld in mech.loads.values() if ld.profile is not None]
    return distinct_instants(np.concatenate(found), period) if found else np.zeros(0)


def load_force(mo: Motion, ld: Load) -> np.ndarray:
    """A declared load's force [N] (nt, 2) at the motion's instants (its profile's factor times
    its force vector; the force itself without a profile)."""
    F = np.asarray(ld.force, dtype=float)
    if ld.profile is None:
        return np.broadcast_to(F, (mo.n, 2))
    return factor(ld.profile, mo)[:, None] * F


def friction_law(mo: Motion, f, dv=None) -> np.ndarray:
    """The friction force's regularised sign ``tanh(v_rel / smoothing)`` (nt,) [-], with ``v_rel``
    the relative speed along its axis of the joint's rigid-body velocity plus ``dv`` (nt, 2)
    [m/s], the elastic part, if given; in a sliding pair (``axis`` None) the block's sliding
    speed on its member."""
    if f.axis is None:
        vrel = mo.sd[:, mo.slider_names.index(f.joint)] - f.reference_speed
        return np.tanh(vrel / f.smoothing)
    n = np.asarray(f.axis)
    v = mo.v[:, mo.joint_names.index(f.joint)]
    vrel = (v if dv is None else v + dv) @ n - f.reference_speed
    return np.tanh(vrel / f.smoothing)


def rigid_friction(mo: Motion, f, dv=None, mech=None) -> np.ndarray:
    """Friction force [N] (nt, 2) on the rigid-body velocity of its joint (tanh-regularised
    sign), or on the total velocity with the elastic part ``dv`` (nt, 2) [m/s]. In a sliding
    pair (``axis`` None; ``mech`` needed) the force of the member on the block, along its line."""
    if f.axis is None:
        return pair_friction(mo, f)[:, None] * slot_direction(mech, mo, f.joint)[0]
    return -(f.force * friction_law(mo, f, dv))[:, None] * np.asarray(f.axis)


def pair_friction(mo: Motion, f) -> np.ndarray:
    """Force (nt,) [N] the member exerts on the block of a sliding pair along the block's line."""
    return -f.force * friction_law(mo, f)


@dataclass(frozen=True)
class Loads(Effect):
    """Declared external loads and friction."""

    name: str = "loads"
    adds: str = "declared external loads and friction"

    def state_dependent(self, mech) -> bool:
        return any(f.follows == "total" for f in mech.frictions.values())

    def joint_loads(self, asm, motion: Motion, loads: np.ndarray, moments: np.ndarray) -> None:
        for ld in asm.mech.loads.values():
            loads[:, motion.joint_names.index(ld.joint)] += load_force(motion, ld)
        for f in asm.mech.frictions.values():
            if f.axis is not None:  # a sliding pair's friction is a force inside the pair
                loads[:, motion.joint_names.index(f.joint)] += rigid_friction(motion, f)

    def pair_loads(self, asm, motion: Motion) -> dict:
        return {f.joint: pair_friction(motion, f) for f in asm.mech.frictions.values() if f.axis is None}

    def element_terms(self, asm, chunk: Chunk) -> None:
        g = asm.model.groups["load"]
        if not g.n:
            return
        Q = np.zeros((chunk.motion.n, g.n, 2))
        for k, it in enumerate(g.meta["items"]):
            if isinstance(it, Load):
                Q[:, k] = load_force(chunk.motion, it)
            elif isinstance(it, tuple):  # ("reaction", f): the member's side of a sliding pair's friction
                Q[:, k] = -rigid_friction(chunk.motion, it[1], mech=asm.mech)
            elif it.follows == "rigid":
                Q[:, k] = rigid_friction(chunk.motion, it, mech=asm.mech)
        chunk.acc.add("load", "Q", Q)

    def state_terms(self, asm, motion: Motion, U, V, out: StateTerms) -> None:
        """Friction on the total velocity: force and its tangent damping ``c_t n n^T``."""
        if not self.state_dependent(asm.mech):
            return
        items = asm.model.groups["load"].meta["items"]
        x, xd, _xq, gm = asm.element_state("load", motion, U, V)
        xdq = gm.apply(V)  # the part of x' carried by q'
        Qx = np.zeros(x.shape)
        Cx = np.zeros(x.shape + (x.shape[-1],))
        for k, it in enumerate(items):
            if getattr(it, "follows", None) != "total":
                continue
            n = np.asarray(it.axis)
            th = friction_law(motion, it, xd[:, k])
            ct = it.force / it.smoothing * (1.0 - th**2)  # d(force)/d(speed) >= 0
            Cx[:, k] = ct[:, None, None] * np.outer(n, n)
            # Newton: F(v_i) + c_t (v - v_i) -> load -F(v_i) + c_t (q'-part of v_i)
            Qx[:, k] = (-(it.force * th) + ct * (xdq[:, k] @ n))[:, None] * n
        asm.apply_state("load", gm, Cx, Qx, out.damping(), out.dQ)
