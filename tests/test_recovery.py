"""Section forces by element equilibrium (kedfem/analysis/recovery.py) against closed forms and mesh convergence."""

import dataclasses
import math

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem.analysis import recovery


def test_fixed_end_maps_give_the_textbook_fixed_end_moments():
    """Clamped-clamped beam: uniform load q -> M(0) = M(L) = q L^2/12, mid-span -q L^2/24 (EI v''
    signs); triangular load rising to q at x = L -> q L^2/30 and q L^2/20 at the ends (Roark,
    table 8.1); fixed-fixed bar under uniform p: N = p L (1/2 - x/L)."""
    xi = np.array([0.0, 0.5, 1.0])
    W, Wn = recovery.fixed_end_maps(xi)
    L, q = 0.7, 3.0
    uniform = np.full(4, q)
    np.testing.assert_allclose(L**2 * W @ uniform, [q * L**2 / 12, -q * L**2 / 24, q * L**2 / 12],
                               rtol=1e-12)
    tri = q * recovery.LOAD_POINTS
    M = L**2 * W @ tri
    assert M[0] == pytest.approx(q * L**2 / 30, rel=1e-12)
    assert M[2] == pytest.approx(q * L**2 / 20, rel=1e-12)
    np.testing.assert_allclose(L * Wn @ uniform, q * L * (0.5 - xi), rtol=1e-12, atol=1e-15)


def test_periodic_rates_are_exact_for_trigonometric_histories():
    T = 0.3
    t = np.arange(64) * T / 64
    w = 2 * math.pi / T
    X = np.stack([np.sin(3 * w * t), np.cos(5 * w * t) + 2.0], axis=1)
    d1, d2 = recovery.periodic_rates(X, T)
    np.testing.assert_allclose(d1[:, 0], 3 * w * np.cos(3 * w * t), atol=1e-9 * (3 * w))
    np.testing.assert_allclose(d2[:, 1], -(5 * w) ** 2 * np.cos(5 * w * t), atol=1e-9 * (5 * w) ** 2)


def test_static_cantilever_moment_under_weight_and_tip_force_is_exact_on_two_elements():
    """Exciter at 0.1 Hz (quasi-static) with gravity: M(x) = F (L - x) - rho A g (L - x)^2 / 2.

    Two elements: the curvature of the Hermite interpolation is linear in each
    element and misses the quadratic moment of the weight between the nodes; the
    element-equilibrium moment is exact (up to the 1e-4 dynamics of 0.1 Hz).
    """
    L, g = 0.8, 9.81
    m = mechanisms.build("exciter", speed=2 * math.pi * 0.1, tip_mass=0.0, elements=2)
    m.set_gravity((0.0, -g))
    res = kf.solve(kf.Scene(m, steps=96, effects=("springs", "gravity"), damping=kf.ModalDamping(0.002)))
    tip = res.joint_displacement("T")[:, 1]
    pin = res.motion.position("P")[:, 1] - res.motion.position("P")[0, 1]
    F = 2.0e4 * (pin - tip)
    sec = kf.Section.rectangle(0.04, 0.01)
    w = 7850.0 * sec.A * g
    x = res.stations("beam", per_element=8)
    expected = F[:, None] * (L - x)[None] - 0.5 * w * (L - x)[None] ** 2
    M = res.bending_moment("beam", per_element=8)
    assert M.shape == (res.n, 17)
    assert np.max(np.abs(M - expected)) < 2e-4 * np.max(np.abs(expected))
    # the linear curvature of the interpolation alone is off by w h^2 / 8 at each element's middle
    h = L / 2
    lin = res.bending_moment("beam")  # at the nodes, where both agree
    np.testing.assert_allclose(lin, M[:, ::8], rtol=0, atol=2e-4 * np.max(np.abs(expected)))
    assert 0.5 * w * h**2 / 4 > 50 * 2e-4 * np.max(np.abs(expected))  # the test would see the miss


def test_axial_force_of_a_spinning_flexible_crank_is_the_centrifugal_closed_form():
    """A free flexible crank at constant speed: N(x) = rho A w^2 (L^2 - x^2) / 2 (rotating bar)."""
    L, w, rho = 0.5, 60.0, 7850.0
    sec = kf.Section.rectangle(0.02, 0.02)
    m = kf.Mechanism("spinning crank")
    m.ground("O", at=(0.0, 0.0))
    m.joint("A", at=(L, 0.0))
    m.link("crank", "O", "A", material=kf.Material(E=2e11, rho=rho), section=sec, elements=2)
    m.drive("crank", speed=w)
    res = kf.solve(kf.Scene(m, steps=48, effects=("inertia", "coupling"), damping=kf.ModalDamping(0.02),
                            estimate=False))  # steady rotation: no bending to estimate the error of
    xm = res.stations("crank")[:-1] + L / 4
    expected = rho * sec.A * w**2 * (L**2 - xm**2) / 2
    N = res.axial_force("crank")
    # the bar's own stretch adds (w / w_axial)^2 = (60 / 15850)^2 = 1.4e-5 (w_axial = pi/2 sqrt(E/rho)
    # / L); the interpolation alone gives each element's mean force, 2.2 % and 4.8 % off at these midpoints
    np.testing.assert_allclose(N, np.broadcast_to(expected, N.shape), rtol=3e-5)


@pytest.mark.parametrize("name", ["four_bar", "slider_crank"])
def test_four_element_stresses_match_an_eight_element_mesh(name):
    """Peak stresses on the presets' 4-element links within 1e-3 of 8 elements per link (themselves
    within 2e-5 of 16 on the four-bar; before the element-equilibrium recovery the 4-element
    stresses were 3 % high)."""
    from kedfem.io.scenefile import preset
    p = preset(name)
    peaks = {}
    for ne in (4, 8):
        m = mechanisms.build(name, elements=ne)
        res = kf.solve(kf.Scene(m, effects=p.effects, damping=p.damping, steps=192, estimate=False))
        peaks[ne] = {pk.link: pk.stress for pk in res.peaks()}
    for link, s in peaks[4].items():
        assert s == pytest.approx(peaks[8][link], rel=1e-3), link


def test_modal_damping_field_matches_the_eigenproblem_at_any_instant():
    """The interpolated C(t) of a solve against an eigenproblem per instant (kedfem/fe/modal_damping.py)."""
    from kedfem.analysis import pipeline
    from kedfem.fe.assembler import Assembler
    from kedfem.io.scenefile import preset
    p = preset("four_bar")
    sc = kf.Scene(mechanisms.build("four_bar"), effects=p.effects, damping=p.damping)
    run = pipeline._Run(sc)
    field = run.damping_field(48)
    assert field.samples >= 64 and not field.constant
    t = np.random.default_rng(1).random(9) * sc.period
    asm = Assembler(run.model, run.cycle.at(t), (), damping=sc.damping)
    exact = asm.damping_matrix(*asm.structural())
    d = np.sqrt(np.abs(np.einsum("tii->ti", exact)).max(axis=0))
    # accepted at a thousandth of the solve's rtol (a relative error e of C moves the response
    # by about e): 1e-6 at the preset's rtol 1e-3
    assert np.max(np.abs(field.at(t) - exact) / np.outer(d, d)) < 1e-3 * sc.rtol
    # a time-invariant scene keeps its constant matrix exactly (the solvers' constant path)
    ex = kf.Scene(mechanisms.build("exciter"), effects=("inertia", "coupling", "springs"),
                  damping=kf.ModalDamping(0.02))
    f2 = pipeline._Run(ex).damping_field(48)
    assert f2.constant
    C = f2.at(np.array([0.0, 0.01, 0.02]))
    assert np.array_equal(C[0], C[1]) and np.array_equal(C[0], C[2])


def test_a_damping_field_read_at_another_speed_is_the_eigenproblem_there():
    """A continuation in speed builds its modal damping field once (``Family(in_speed=True)``):
    read at another speed's period it must be that speed's eigenproblem at every instant, also
    where the interpolant fell back to exact matrices (the wrapped ``exact`` takes the other
    speed's instants), and a family in another parameter must not reuse it."""
    from kedfem.analysis import pipeline
    from kedfem.analysis.branch import Family
    from kedfem.fe.assembler import Assembler
    from kedfem.fe.modal_damping import DampingField
    from kedfem.io.scenefile import preset
    from kedfem.solvers import schemes
    p = preset("four_bar")
    base = kf.Scene(mechanisms.build("four_bar"), effects=p.effects, damping=p.damping)
    field = pipeline._Run(base).damping_field(48)
    other = kf.Scene(mechanisms.build("four_bar"), effects=p.effects, damping=p.damping, speed=2.7 * base.mech.drives[0].speed)
    run = pipeline._Run(other)
    t = np.random.default_rng(2).random(7) * other.period
    asm = Assembler(run.model, run.cycle.at(t), (), damping=other.damping)
    exact = asm.damping_matrix(*asm.structural())
    d = np.sqrt(np.abs(np.einsum("tii->ti", exact)).max(axis=0))
    moved = field.at_period(other.period)
    assert np.max(np.abs(moved.at(t) - exact) / np.outer(d, d)) < 1e-3 * other.rtol
    assert np.max(np.abs(field.at(t * (base.period / other.period)) - moved.at(t))) == 0.0
    fallback = DampingField(field._exact, base.period, max_samples=8)  # exact matrices at every instant
    assert fallback.samples == 0
    assert np.max(np.abs(fallback.at_period(other.period).at(t) - exact) / np.outer(d, d)) < 1e-10  # (eigenproblems: round-off)
    scheme = schemes.get("radau3")
    w = base.mech.drives[0].speed
    for in_speed in (True, False):
        fam = Family(lambda s: dataclasses.replace(base, speed=s), 24, scheme, in_speed=in_speed)
        f1 = fam.problem(w).assembler.damping_field
        f2 = fam.problem(1.3 * w).assembler.damping_field
        assert f2.period == pytest.approx(f1.period / 1.3, rel=1e-14)
        assert (fam._field is not None and fam._field[0] is f1) == in_speed  # built once, or at each speed


def test_piecewise_damping_field_settles_between_kinks_where_harmonics_do_not():
    """A matrix field with kinks (|sin|: its slope jumps at 0 and T/2) against its closed form: the
    trigonometric interpolant gives up, the Chebyshev pieces between the kinks meet their rtol."""
    from kedfem.fe.modal_damping import DampingField, PiecewiseDampingField
    T = 0.3
    rng = np.random.default_rng(3)
    S = [a @ a.T + 4 * np.eye(4) for a in rng.standard_normal((3, 4, 4))]

    def exact(t):
        f = np.abs(np.sin(2 * np.pi * np.asarray(t) / T))[:, None, None]
        return S[0] + f * S[1] + np.exp(f) * S[2]

    assert DampingField(exact, T, rtol=1e-7).samples == 0  # fell back to exact matrices
    field = PiecewiseDampingField(exact, T, [0.0, T / 2], rtol=1e-7)
    assert field.samples < 200 and field.degrees.min() > 0
    t = np.concatenate([rng.random(50) * T, [0.0, T / 2, T - 1e-12, 1e-12]])
    E = exact(t)
    d = np.sqrt(np.einsum("tii->ti", E).max(axis=0))
    assert np.max(np.abs(field.at(t) - E) / np.outer(d, d)) < 1e-6
    # breaks given twice, across the period's end, or as a tiny negative number (whose mod is T):
    # the same two pieces, no piece of zero length, no 0/0 at the cycle's end
    odd = PiecewiseDampingField(exact, T, [T / 2, -1e-20, T / 2 + 1e-16, T, 0.0], rtol=1e-7)
    assert odd.degrees.size == 2
    te = np.array([-1e-18, 0.0, T, T / 2])
    assert np.max(np.abs(odd.at(te) - exact(te)) / np.outer(d, d)) < 1e-6


def test_piecewise_damping_field_of_a_sliding_block_matches_the_eigenproblem():
    """The Whitworth's C(t), kinked where the block crosses the lever's nodes, read between the kinks
    against an eigenproblem per instant, to a thousandth of the solve's rtol."""
    from kedfem.analysis import pipeline
    from kedfem.fe.assembler import Assembler
    from kedfem.fe.modal_damping import PiecewiseDampingField
    from kedfem.io.scenefile import preset
    p = preset("whitworth")
    sc = kf.Scene(mechanisms.build("whitworth"), effects=p.effects, damping=p.damping, rtol=1e-3)
    run = pipeline._Run(sc)
    field = run.damping_field(192)
    assert isinstance(field, PiecewiseDampingField) and field.samples < 600
    t = np.random.default_rng(1).random(40) * sc.period
    asm = Assembler(run.model, run.cycle.at(t), (), damping=sc.damping)
    exact = asm.damping_matrix(*asm.structural())
    d = np.sqrt(np.abs(np.einsum("tii->ti", exact)).max(axis=0))
    assert np.max(np.abs(field.at(t) - exact) / np.outer(d, d)) < 1e-6
