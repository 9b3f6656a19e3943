"""StaticResult's deflection, section-force and stress accessors against closed-form beam statics."""

import math

import numpy as np
import pytest

import kedfem as kf
from kedfem import catalogue

STEEL = kf.Material(E=2.0e11, rho=7850.0)
SEC = kf.Section.rectangle(0.02, 0.01)
EI = STEEL.E * SEC.I
G = 9.80665
q = STEEL.rho * SEC.A * G  # weight per length [N/m]


def cantilever(L=1.3, elements=4, direction=(1.0, 0.0), section=SEC):
    m = kf.Mechanism("cantilever")
    m.ground("C", at=(0.0, 0.0), clamped=True)
    m.joint("T", at=(L * direction[0], L * direction[1]))
    m.link("beam", "C", "T", material=STEEL, section=section, elements=elements)
    return m


def test_cantilever_under_gravity():
    L = 1.3
    r = kf.static_response(cantilever(L), effects=("gravity",))
    assert r.deflection("beam", 1.0) == pytest.approx(-q * L**4 / (8 * EI), rel=1e-12)
    x = r.stations("beam", per_element=3)
    assert x.shape == (13,) and x[0] == 0.0 and x[-1] == pytest.approx(L)
    # M(x) = -q (L - x)^2 / 2 everywhere: the recovery is exact for the uniform weight
    M = r.bending_moment("beam", per_element=3)
    assert np.allclose(M, -q * (L - x) ** 2 / 2, rtol=1e-10, atol=1e-10 * q * L**2)
    assert M[0] == pytest.approx(-q * L**2 / 2, rel=1e-12)
    s = r.stress("beam", per_element=3)
    assert s[0] == pytest.approx(q * L**2 / 2 * SEC.c / SEC.I, rel=1e-12)
    assert np.allclose(s, np.abs(M) * SEC.c / SEC.I, rtol=1e-12, atol=1e-6)
    N, M2 = r.section_forces("beam", per_element=3)
    assert np.allclose(M2, M) and np.allclose(N, 0.0, atol=1e-9)
    assert np.allclose(r.axial_force("beam"), 0.0, atol=1e-9)
    # deflection at the nodes and between them (xi = 0.5 is a node of 4 elements)
    def v(s_):
        return -q * s_**2 * (6 * L**2 - 4 * L * s_ + s_**2) / (24 * EI)

    assert r.deflection("beam", 0.5) == pytest.approx(v(L / 2), rel=1e-12)
    assert r.deflection("beam", 0.3) == pytest.approx(v(0.3 * L), rel=2e-3)  # Hermite between nodes
    assert r.deflection("beam", 1.0, relative_to="chord") == pytest.approx(0.0, abs=1e-18)
    tip = r.deflection("beam", 1.0)
    assert r.deflection("beam", 0.5, relative_to="chord") == pytest.approx(v(L / 2) - tip / 2, rel=1e-12)
    assert np.allclose(r.joint_displacement("T"), (0.0, tip), atol=1e-18)
    ld = r.link_displacement("beam")
    assert ld.shape == (5, 2) and np.allclose(ld[:, 1], v(x[::3]), rtol=1e-12, atol=1e-18)
    assert np.allclose(r.joint_displacement("C"), 0.0)


def test_cantilever_tip_load_and_pull():
    L, P = 1.0, 50.0
    m = cantilever(L, elements=3)
    m.load("P", "T", force=(0.0, -P))
    r = kf.static_response(m, effects=("loads",))
    assert r.deflection("beam", 1.0) == pytest.approx(-P * L**3 / (3 * EI), rel=1e-12)
    x = r.stations("beam", per_element=2)
    assert np.allclose(r.bending_moment("beam", per_element=2), -P * (L - x), rtol=1e-10, atol=1e-9)
    assert r.stress("beam")[0] == pytest.approx(P * L * SEC.c / SEC.I, rel=1e-12)
    m = cantilever(L, elements=3)
    m.load("P", "T", force=(2.0e3, 0.0))
    r = kf.static_response(m, effects=("loads",))
    assert np.allclose(r.axial_force("beam"), 2.0e3, rtol=1e-12)
    N, M = r.section_forces("beam")
    assert np.allclose(N, 2.0e3, rtol=1e-12) and np.allclose(M, 0.0, atol=1e-9)
    assert np.allclose(r.stress("beam"), 2.0e3 / SEC.A, rtol=1e-12)
    assert r.joint_displacement("T")[0] == pytest.approx(2.0e3 * L / (STEEL.E * SEC.A), rel=1e-12)


def test_signs_follow_the_link_frame():
    """A cantilever pointing to -x: its frame's +y is global -y, the moment flips, the joint does not."""
    L = 1.3
    r = kf.static_response(cantilever(L, direction=(-1.0, 0.0)), effects=("gravity",))
    assert r.deflection("beam", 1.0) == pytest.approx(+q * L**4 / (8 * EI), rel=1e-12)
    assert r.bending_moment("beam")[0] == pytest.approx(+q * L**2 / 2, rel=1e-12)
    assert r.joint_displacement("T")[1] == pytest.approx(-q * L**4 / (8 * EI), rel=1e-12)


def test_simply_supported_beam_sags_positive():
    """Two links welded at mid-span under a load there: M = P x / 2 (sagging positive), P L^3 / (48 EI)."""
    L, P = 2.0, 300.0
    m = kf.Mechanism("ss")
    m.ground("A", at=(0.0, 0.0))
    m.joint("M", at=(L / 2, 0.0), welded=True)
    m.slider("B", at=(L, 0.0), axis=(1.0, 0.0))
    for name, a, b in (("left", "A", "M"), ("right", "M", "B")):
        m.link(name, a, b, material=STEEL, section=SEC, elements=2)
    m.load("P", "M", force=(0.0, -P))
    r = kf.static_response(m, effects=("loads",))
    x = r.stations("left", per_element=2)
    assert np.allclose(r.bending_moment("left", per_element=2), P * x / 2, rtol=1e-10, atol=1e-9)
    assert np.allclose(r.bending_moment("right", per_element=2), P * (L / 2 - x) / 2, rtol=1e-10, atol=1e-9)
    assert r.deflection("left", 1.0) == pytest.approx(-P * L**3 / (48 * EI), rel=1e-12)
    assert r.deflection("right", 0.0) == pytest.approx(-P * L**3 / (48 * EI), rel=1e-12)
    assert r.dof("M.theta") == pytest.approx(0.0, abs=1e-15)  # the shared rotation of the weld


def test_shipped_exciter_cantilever_under_gravity():
    """The exciter's clamped beam: its weight, the tip mass's and the tip spring to the (fixed) crank pin."""
    p = {"length": 0.8, "width": 0.04, "height": 0.01, "spring": 2.0e4, "tip_mass": 0.5}
    m = catalogue.build("exciter", **p)
    r = kf.static_response(m, effects=("gravity",))
    sec = kf.Section.rectangle(p["width"], p["height"])
    L, EI_ = p["length"], 2.0e11 * sec.I
    qb, W, k = 7850.0 * sec.A * G, p["tip_mass"] * G, p["spring"]
    free = -(qb * L**4 / (8 * EI_) + W * L**3 / (3 * EI_))
    tip = free / (1 + k * L**3 / (3 * EI_))  # the spring takes k |tip| back
    assert r.deflection("beam", 1.0) == pytest.approx(tip, rel=1e-10)
    root = -(qb * L**2 / 2 + W * L) - k * tip * L
    M = r.bending_moment("beam")
    assert M[0] == pytest.approx(root, rel=1e-10)
    assert r.stress("beam")[0] == pytest.approx(abs(root) * sec.c / sec.I, rel=1e-10)
    assert r.dof("T.v[beam]") == pytest.approx(tip, rel=1e-10)
    assert "exciter" in repr(r) and "gravity" in repr(r) and "crank angle" in repr(r)


def test_running_mechanism_quasi_static_matches_a_slow_periodic_solve():
    """At a speed far below the first frequency the periodic response is the static one of the
    inertia loads at each crank angle, to about (w / w1)^2 (here 2.5e-4)."""
    m = catalogue.build("slider_crank").with_speed(20.0)
    effects = ("inertia", "coupling")
    res = kf.solve(kf.Scene(m, effects=effects, steps=64, estimate=False))
    ca = 1.0
    one = res.resample(crank_angle=[ca])
    st = kf.static_response(m, effects=effects, crank_angle=ca)
    scale = np.abs(one.bending_moment("rod", per_element=2)[0]).max()
    assert np.allclose(st.bending_moment("rod", per_element=2), one.bending_moment("rod", per_element=2)[0],
                       rtol=0, atol=3e-3 * scale)
    assert np.allclose(st.axial_force("rod"), one.axial_force("rod")[0], rtol=3e-3)
    assert st.deflection("rod") == pytest.approx(one.deflection("rod")[0], rel=3e-3)
    assert np.allclose(st.joint_displacement("B"), one.joint_displacement("B")[0], rtol=3e-3, atol=1e-15)


def test_a_result_made_by_hand_and_the_errors():
    m = cantilever(1.0, elements=2, section=kf.Section(A=SEC.A, I=SEC.I))  # no extreme fibre c
    m.load("P", "T", force=(0.0, -10.0))
    r = kf.static_response(m, effects=("loads",))
    bare = kf.StaticResult(r.U, r.dof_labels, r.model)  # the old three-field form still reads
    assert bare.deflection("beam", 1.0) == pytest.approx(r.deflection("beam", 1.0), rel=1e-14)
    assert np.allclose(bare.bending_moment("beam"), r.bending_moment("beam"))
    with pytest.raises(kf.InputError, match="extreme-fibre"):
        r.stress("beam")
    with pytest.raises(kf.InputError, match="unknown link"):
        r.deflection("nope")
    with pytest.raises(kf.InputError, match="xi"):
        r.deflection("beam", 1.5)
    with pytest.raises(kf.InputError, match="unknown joint"):
        r.joint_displacement("nope")
    m = kf.Mechanism("crank")
    m.ground("O", at=(0.0, 0.0))
    m.joint("A", at=(0.1, 0.0))
    m.link("crank", "O", "A", rigid=True, mass=1.0)
    m.drive("crank", speed=1.0, torsional_stiffness=1.0e3)
    r = kf.static_response(m, effects=("gravity",), crank_angle=math.pi / 2)
    with pytest.raises(kf.InputError, match="rigid"):
        r.bending_moment("crank")
    assert "crank angle 90 deg" in repr(r)


def test_a_free_structure_is_a_ked_error():
    m = kf.Mechanism("loose")
    m.ground("O", at=(0.0, 0.0))
    m.joint("T", at=(1.0, 0.0))
    m.link("beam", "O", "T", material=STEEL, section=SEC, elements=2)  # pinned, nothing holds it
    with pytest.raises(kf.KedError, match="singular"):
        kf.static_response(m, effects=("gravity",))
