"""A constant torque on a member at a joint: the worked example of an effect in its own module.

An effect in its own module subclasses :class:`kedfem.fe.effects.Effect`, says
what it adds, and overrides the hooks it needs (here ``terms``: q-space terms at
the instants of a chunk of the cycle; :mod:`kedfem.fe.effects.base` lists them);
``register_effect`` puts it in the registry, after which scenes and scene files
name it like any built-in effect::

    import kedfem as kf
    from kedfem.fe.effects import register_effect
    from kedfem.fe.effects.joint_torque import JointTorque

    register_effect(JointTorque("brake", member="follower", joint="B", torque=5.0))
    res = kf.solve(kf.Scene(m, effects=("inertia", "coupling", "axial_stiffening", "brake")))

The torque [N m] acts on the member's elastic rotation at the joint (the DOF
``member.theta@joint`` of a flexible link, or ``member.phi`` of a rigid body),
counter-clockwise positive, at every instant. It is a load on the elastic
equations only: the rigid-body motion is prescribed, so the drive balances
it, and it does not enter the kinetostatic axial forces of ``axial_stiffening``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from .base import Chunk, Effect

__all__ = ["JointTorque"]


@dataclass(frozen=True)
class JointTorque(Effect):
    """Constant torque ``torque`` [N m] on ``member`` at ``joint``.

    Attributes
    ----------
    name : str
        The effect's name in scenes.
    member, joint : str
        Where the torque acts.
    torque : float
        [N m], counter-clockwise positive.
    """

    adds: str = "a constant torque on a member at a joint"
    member: str = ""
    joint: str = ""
    torque: float = 0.0

    def dof(self, model) -> int:
        """Index of the elastic rotation the torque works on (InputError if there is none)."""
        labels = model.dof_labels
        for label in (f"{self.member}.theta@{self.joint}", f"{self.member}.phi"):
            if label in labels:
                return model.dof_index(label)
        raise InputError(f"effect {self.name!r}: member {self.member!r} has no elastic rotation at joint "
                         f"{self.joint!r} (a clamped end or a driven crank's pivot carries none; rotation "
                         f"DOFs: {', '.join(x for x in labels if 'theta@' in x or x.endswith('.phi'))})")

    def terms(self, asm, chunk: Chunk) -> dict:
        Q = np.zeros((chunk.motion.n, asm.model.n_dof))
        Q[:, self.dof(asm.model)] = float(self.torque)
        return {"Q": Q}
