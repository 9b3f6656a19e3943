"""An effect in its own module (kedfem/fe/effects/joint_torque.py) joins the registry with one line."""

from dataclasses import dataclass

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem.fe import effects
from kedfem.fe.effects import Effect
from kedfem.fe.effects.joint_torque import JointTorque


@pytest.fixture()
def registry(monkeypatch):
    monkeypatch.setattr(effects, "EFFECTS", dict(effects.EFFECTS))
    return effects


def test_a_tip_torque_bends_a_cantilever_into_the_closed_form(registry):
    """The exciter's cantilever (its spring set to 0, so the crank does not touch it) under a
    constant tip torque: the periodic response is the static one, tip rotation tau L / EI and
    deflection tau L^2 / (2 EI) (exact for cubic elements under an end moment)."""
    registry.register_effect(JointTorque("tip_torque", member="beam", joint="T", torque=10.0))
    m = mechanisms.build("exciter", spring=0.0)
    res = kf.solve(kf.Scene(m, effects=("tip_torque",), damping=kf.ModalDamping(0.02), steps=24))
    beam = m.links["beam"]
    EI = beam.material.E * beam.section.I
    L = 0.8
    np.testing.assert_allclose(res.dof("beam.theta@T"), 10.0 * L / EI, rtol=1e-9)
    np.testing.assert_allclose(res.dof("T.v[beam]"), 10.0 * L**2 / (2 * EI), rtol=1e-9)
    # the same scene without the effect: nothing loads the beam
    still = kf.solve(kf.Scene(m, effects=(), damping=kf.ModalDamping(0.02), steps=24))
    assert np.max(np.abs(still.U)) == 0.0


def test_registry_rules(registry):
    with pytest.raises(kf.InputError, match="already registered"):
        registry.register_effect(JointTorque("inertia", member="beam", joint="T", torque=1.0))
    with pytest.raises(kf.InputError, match="own terms"):
        registry.register_effect(effects.Effect("plain", "nothing"))
    registry.register_effect(JointTorque("at_clamp", member="beam", joint="C", torque=1.0))
    with pytest.raises(kf.InputError, match="no elastic rotation at joint 'C'"):
        kf.solve(kf.Scene(mechanisms.build("exciter"), effects=("at_clamp",), steps=24))


@dataclass(frozen=True)
class HardeningTipSpring(JointTorque):
    """A state-dependent plug-in: a hardening rotational spring ``k1 th + k3 th^3`` [N m] on the
    elastic rotation at a joint, iterated by the solve (state_terms)."""

    adds: str = "a hardening rotational spring to ground"
    k1: float = 0.0
    k3: float = 0.0

    def state_dependent(self, mech) -> bool:
        return True

    def terms(self, asm, chunk):
        return None

    def state_terms(self, asm, motion, U, V, out):
        i = self.dof(asm.model)
        th = U[:, i]
        out.dK[:, i, i] += self.k1 + 3.0 * self.k3 * th**2
        out.dQ[:, i] += -(self.k1 * th + self.k3 * th**3) + (self.k1 + 3.0 * self.k3 * th**2) * th


def test_a_state_dependent_plugin_effect_is_iterated_to_the_closed_form(registry):
    """Tip torque tau on the cantilever against a hardening tip spring: the end moment is
    tau - k1 th - k3 th^3 = EI th / L, a cubic whose real root numpy finds independently."""
    registry.register_effect(JointTorque("tip_torque", member="beam", joint="T", torque=40.0))
    registry.register_effect(HardeningTipSpring("tip_spring", member="beam", joint="T", k1=500.0, k3=4e7))
    m = mechanisms.build("exciter", spring=0.0)
    sc = kf.Scene(m, effects=("tip_torque", "tip_spring"), damping=kf.ModalDamping(0.02), steps=24)
    assert sc.state_dependent
    res = kf.solve(sc)
    beam = m.links["beam"]
    EI, L = beam.material.E * beam.section.I, 0.8
    roots = np.roots([4e7, 0.0, EI / L + 500.0, -40.0])
    th = float(roots[np.abs(roots.imag) < 1e-12].real[0])
    assert th < 0.5 * 40.0 / (EI / L + 500.0)  # the cubic term matters: less than half the linear answer
    np.testing.assert_allclose(res.dof("beam.theta@T"), th, rtol=1e-8)


@dataclass(frozen=True)
class GroundSpring(Effect):
    """A plug-in through ``asm.joint_terms``: an isotropic spring [N/m] from a joint to the frame."""

    adds: str = "a spring from a joint to the frame"
    joint: str = ""
    k: float = 0.0

    def terms(self, asm, chunk):
        return asm.joint_terms(self.joint, chunk.motion, K=self.k * np.eye(2))


def test_a_plugin_at_a_moving_joint_equals_the_built_in_spring(registry):
    """Joint B of the four-bar turns with the follower (DOFs B.u[...], B.v[...]), so the plug-in's
    stiffness goes through a moving map and its rates; two built-in springs to the frame along x
    and y (structural stiffness, no 'springs' effect) are the same physics assembled another way."""
    registry.register_effect(GroundSpring("b_spring", "a spring", joint="B", k=3.0e4))
    eff = ("inertia", "coupling", "axial_stiffening")
    damping = kf.Rayleigh(alpha=20.0)
    plain = mechanisms.build("four_bar", elements=2)
    built = mechanisms.build("four_bar", elements=2)
    built.spring("gx", "B", None, k=3.0e4, axis=(1.0, 0.0))
    built.spring("gy", "B", None, k=3.0e4, axis=(0.0, 1.0))
    a = kf.solve(kf.Scene(plain, effects=eff + ("b_spring",), damping=damping, steps=48))
    b = kf.solve(kf.Scene(built, effects=eff, damping=damping, steps=48))
    c = kf.solve(kf.Scene(plain, effects=eff, damping=damping, steps=48))
    assert any("B." in lab and "[" in lab for lab in a.dof_labels)  # B's DOFs turn with a link
    scale = np.abs(b.U).max()
    assert np.abs(a.U - b.U).max() < 1e-9 * scale
    assert np.abs(c.U - b.U).max() > 1e-3 * scale  # the spring matters
