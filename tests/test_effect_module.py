"""An effect in its own module (kedfem/fe/joint_torque.py) joins the registry with one line."""

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem.fe import effects
from kedfem.fe.joint_torque import JointTorque


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
