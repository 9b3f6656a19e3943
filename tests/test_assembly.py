"""Assembly: DOF map, symmetry and definiteness, rigid-body modes, bodies and springs, statics."""

import math

import numpy as np
import pytest
import scipy.sparse as sp

import kedfem as kf
import mechanisms

STEEL = kf.Material(E=2.0e11, rho=7800.0)


def test_slider_crank_dof_map():
    m = mechanisms.build("slider_crank", elements=8)
    fe = kf.FEModel(m)
    # rigid driven crank: A fixed; rod: end rotations 2 + 7 internal nodes x 3; slider travel 1
    assert fe.n_dof == 24
    assert "B.s" in fe.dof_labels and "rod.theta@A" in fe.dof_labels
    assert not any(lbl.startswith("A.") for lbl in fe.dof_labels)


def test_global_matrices_symmetric_definite_sparse():
    for name in ("slider_crank", "four_bar"):
        m = mechanisms.build(name)
        g = kf.global_matrices(m, crank_angle=0.7)
        assert sp.isspmatrix_csr(g.M) and sp.isspmatrix_csr(g.K)
        M, K = g.M.toarray(), g.K.toarray()
        assert np.allclose(M, M.T, atol=1e-14 * abs(M).max())
        assert np.allclose(K, K.T, atol=1e-12 * abs(K).max())
        assert np.linalg.eigvalsh(M).min() > 0
        assert np.linalg.eigvalsh(K).min() > 0  # a pinned linkage with rigid drive is a structure


def test_free_free_beam_has_three_rigid_body_modes():
    m = kf.Mechanism("free")
    m.joint("A", at=(0, 0))
    m.joint("B", at=(1.0, 0.3))
    m.link("b", "A", "B", material=STEEL, section=kf.Section.rectangle(0.02, 0.01), elements=6)
    g = kf.global_matrices(m)
    lam = np.linalg.eigvalsh(g.K.toarray())
    assert np.sum(np.abs(lam) < 1e-12 * lam.max()) == 3
    f = np.asarray(kf.natural_frequencies(m, n_modes=5).frequencies)
    # free-free elastic modes share beta L with clamped-clamped
    sec = kf.Section.rectangle(0.02, 0.01)
    Lb = math.hypot(1.0, 0.3)
    f1 = 4.730041**2 * math.sqrt(STEEL.E * sec.I / (STEEL.rho * sec.A * Lb**4)) / (2 * math.pi)
    assert np.sum(np.abs(f) < 1e-3) == 3
    assert f[3] == pytest.approx(f1, rel=1e-3)


def test_welded_joint_shares_rotation_and_pinned_keeps_two():
    def frame(welded):
        m = kf.Mechanism("L")
        m.ground("O", at=(0, 0), clamped=True)
        m.joint("C", at=(0, 1.0), welded=welded)
        m.joint("T", at=(1.0, 1.0))
        sec = kf.Section.rectangle(0.02, 0.02)
        m.link("post", "O", "C", material=STEEL, section=sec, elements=1)
        m.link("arm", "C", "T", material=STEEL, section=sec, elements=1)
        return kf.FEModel(m)
    assert frame(True).n_dof == 2 + 1 + 3
    assert frame(False).n_dof == 2 + 2 + 3


def test_cantilever_static_tip_load_and_gravity():
    sec = kf.Section.rectangle(0.02, 0.01)
    Lb = 1.3
    m = kf.Mechanism("cantilever")
    m.ground("O", at=(0, 0), clamped=True)
    m.joint("T", at=(Lb, 0))
    m.link("b", "O", "T", material=STEEL, section=sec, elements=4)
    m.load("P", "T", force=(0.0, -50.0))
    r = kf.static_response(m, effects=("loads",))
    EI = STEEL.E * sec.I
    assert r.dof("T.v[b]") == pytest.approx(-50.0 * Lb**3 / (3 * EI), rel=1e-12)
    r = kf.static_response(m, effects=("gravity",))
    w = STEEL.rho * sec.A * 9.80665
    assert r.dof("T.v[b]") == pytest.approx(-w * Lb**4 / (8 * EI), rel=1e-12)


def test_simply_supported_gravity_midspan():
    sec = kf.Section.rectangle(0.02, 0.01)
    Lb = 2.0
    m = kf.Mechanism("ss")
    m.ground("A", at=(0, 0))
    m.slider("B", at=(Lb, 0), axis=(1, 0))
    m.link("b", "A", "B", material=STEEL, section=sec, elements=4)
    r = kf.static_response(m, effects=("gravity",))
    w = STEEL.rho * sec.A * 9.80665
    assert r.dof("b.n2.v") == pytest.approx(-5 * w * Lb**4 / (384 * STEEL.E * sec.I), rel=1e-12)


def test_rigid_body_on_springs_frequencies():
    """A rigid bar on two vertical springs: bounce sqrt(2k/m), pitch sqrt(2 k a^2 / J)."""
    mass, J, a, k = 50.0, 4.0, 0.4, 2.0e5
    m = kf.Mechanism("bar")
    m.joint("L", at=(-a, 0))
    m.joint("R", at=(a, 0))
    m.body("bar", ("L", "R"), mass=mass, J=J, cm=(0.0, 0.0))
    m.spring("kl", "L", k=k, axis=(0, 1))
    m.spring("kr", "R", k=k, axis=(0, 1))
    m.spring("kx", "L", k=1e3, axis=(1, 0))
    f = np.sort(np.asarray(kf.natural_frequencies(m, n_modes=3).frequencies))
    exp = np.sort([math.sqrt(1e3 / mass), math.sqrt(2 * k / mass), math.sqrt(2 * k * a**2 / J)]) / (2 * math.pi)
    np.testing.assert_allclose(f, exp, rtol=1e-12)


def test_rigid_crank_on_drive_shaft_spring():
    """A rigid crank pivoting on a torsional drive shaft: f = sqrt(k_t / J_O) / 2 pi."""
    mass, Lc, kt = 3.0, 0.2, 5.0e3
    m = kf.Mechanism("shaft")
    m.ground("O", at=(0, 0))
    m.joint("A", at=(Lc, 0))
    m.link("crank", "O", "A", rigid=True, mass=mass)
    m.drive("crank", speed=10.0, torsional_stiffness=kt)
    JO = mass * Lc**2 / 12 + mass * (Lc / 2) ** 2
    for eff in ((), ("coupling", "axial_stiffening")):
        f = kf.natural_frequencies(m, n_modes=1, effects=eff).frequencies[0]
        assert f == pytest.approx(math.sqrt(kt / JO) / (2 * math.pi), rel=1e-12)


def test_clamped_end_on_pin_is_prescribed_rotation():
    """A guide link clamped at both ends but pinned kinematically bends when it swings."""
    m = kf.Mechanism("guide")
    m.ground("G", at=(0, 0))
    m.ground("O", at=(0.6, -0.5))
    m.joint("T", at=(0.6, 0.0))
    m.joint("E", at=(0.6 + 0.05, -0.5))
    sec = kf.Section.rectangle(0.05, 0.005)
    m.link("leaf", "G", "T", material=STEEL, section=sec, elements=4, ends=("clamp", "pin"))
    m.link("crank", "O", "E", rigid=True)
    m.link("rod", "E", "T", rigid=False, material=STEEL, section=kf.Section.rectangle(0.03, 0.03), elements=2)
    m.drive("crank", speed=5.0)
    fe = kf.FEModel(m)
    assert fe.has_offsets()
    mo = kf.kinematics(m, steps=8)
    p, p1, p2 = fe.rot_offsets(mo)
    rid = fe.end_rot[("leaf", "G")]
    np.testing.assert_allclose(p[:, rid], -(mo.angle("leaf") - mo.angle("leaf")[0]), atol=1e-14)
    np.testing.assert_allclose(p1[:, rid], -mo.angular_velocity("leaf"), atol=1e-14)


def test_passive_link_follows_chord_and_prescribes_stretch():
    """A redundant bar from the frame to the slider: its chord stretch is a prescribed elongation."""
    m = mechanisms.build("slider_crank", elements=2)
    m.ground("G", at=(0.8, 0.0))
    bar = kf.Section.rectangle(0.01, 0.01)
    m.link("bar", "B", "G", material=STEEL, section=bar, elements=1, kinematic=False)
    mo = kf.kinematics(m, steps=12)
    # the passive link's angle is the chord angle (B -> G along +x), not a loop unknown
    np.testing.assert_allclose(np.cos(mo.angle("bar")), 1.0, atol=1e-12)
    with pytest.raises(kf.MobilityError):
        m2 = mechanisms.build("slider_crank", elements=2)
        m2.ground("G", at=(0.8, 0.0))
        m2.link("bar", "B", "G", material=STEEL, section=bar, elements=1)  # kinematic: over-constrained
        kf.kinematics(m2, steps=12)
    xB = mo.position("B")[:, 0]
    stretch = (0.8 - xB) - (0.8 - xB[0])
    for k in (0, 3, 7):
        g = kf.global_matrices(m, crank_angle=mo.crank_angle[k])
        i = g.dof_labels.index("B.s")
        EA = STEEL.E * bar.A
        # the bar (B -> G) pulls B towards G (+x) when it is stretched
        assert g.Q[i] == pytest.approx(EA / 0.35 * stretch[k], rel=1e-9, abs=1e-6)


def test_geometric_nonlinearity_says_once_that_it_carries_the_axial_forces(monkeypatch, caplog):
    """A continuation in speed builds an assembler per speed: the line was logged 511 times in one
    run-up (the six-bar preset at 1600 rpm); it is said once per mechanism."""
    import logging

    from kedfem.fe import assembler as asm_mod
    from kedfem.analysis.pipeline import assemble_scene

    monkeypatch.setattr(asm_mod, "_TOLD_AXIAL", set())
    sc = kf.Scene(mechanisms.build("four_bar"), effects=("inertia", "axial_stiffening", "geometric_nonlinearity"))
    with caplog.at_level(logging.INFO, logger="kedfem.fe.assembler"):
        for _ in range(3):
            assemble_scene(sc, steps=8)
    said = [r for r in caplog.records if "carries the axial forces" in r.getMessage()]
    assert len(said) == 1
