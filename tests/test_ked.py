"""KED end to end: scenes, effects, results, post-processing."""

import dataclasses
import math

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem.fe import assembler
from kedfem.fe.effects.geometric_nonlinearity import GeometricNonlinearity
from kedfem.fe.assembler import Assembler

SC_EFF = ("inertia", "coupling")


def slider_crank_scene(elements=8, steps=360, effects=SC_EFF, hold="foh"):
    return kf.Scene(mechanisms.build("slider_crank", elements=elements), steps=steps, effects=effects,
                    damping=kf.Rayleigh(alpha=0.0, beta=3e-5), hold=hold)


def peak(res):
    w = res.deflection("rod", 0.5, relative_to="chord")
    i = int(np.argmax(np.abs(w)))
    return w[i], res.crank_angle[i]


def test_result_contract_shapes():
    res = kf.solve(slider_crank_scene(elements=4, steps=120))
    n, N = res.n, res.model.n_dof
    assert res.elements == 120 and n == 360          # output instants: >= 360, the element ends among them
    np.testing.assert_allclose(res.t, np.arange(n) * res.scene.period / n, rtol=0, atol=1e-15)
    assert res.t.shape == (n,) and res.crank_angle.shape == (n,)
    assert res.U.shape == (n, N) and res.V.shape == (n, N)
    assert res.deflection("rod", 0.5).shape == (n,)
    assert res.axial_force("rod").shape == (n, 4)
    assert res.bending_moment("rod").shape == (n, 5)
    assert res.stress("rod").shape == (n, 5)
    assert res.floquet_multipliers.shape == (2 * N,)
    assert res.stable and res.converged and res.iterations == 1
    assert np.all(np.abs(res.floquet_multipliers) < 1)
    with pytest.raises(kf.InputError, match="rigid"):
        res.deflection("crank")
    with pytest.raises(kf.InputError, match="unknown link"):
        res.stress("nope")


def test_slider_crank_mesh_and_time_convergence():
    peaks = [abs(peak(kf.solve(slider_crank_scene(elements=e, steps=360)))[0]) for e in (4, 8, 16)]
    d1, d2 = abs(peaks[0] - peaks[1]), abs(peaks[1] - peaks[2])
    assert d2 < d1 and d2 < 1e-3 * peaks[2]
    # the published undamped transient reaches about 1.65 mm: the damped steady state is of that size
    assert 1.0e-3 < peaks[2] < 2.5e-3
    # time nodes: whole response at 90 nodes against a fine magnus2 reference
    def at90(res):
        return res.resample(np.arange(90) * res.scene.period / 90).U

    def scene(steps, hold):
        return dataclasses.replace(slider_crank_scene(elements=4, steps=steps, hold=hold), estimate=False)

    ref = at90(kf.solve(scene(2880, "magnus2")))
    for hold, order in (("foh", 1), ("magnus2", 2)):
        err = []
        for s in (180, 360, 720):
            U = at90(kf.solve(scene(s, hold)))
            err.append(np.max(np.abs(U - ref)) / np.max(np.abs(ref)))
        # foh holds the time-varying state matrix per element: first order; magnus2: second order
        rates = np.log2(np.array(err[:-1]) / np.array(err[1:]))
        assert np.all(rates > order - 0.25) and np.all(rates < order + 0.35), (hold, err, rates)


def test_effect_switches_change_answer_in_expected_direction():
    # no inertia: nothing loads the slider-crank
    res = kf.solve(slider_crank_scene(elements=4, steps=90, effects=("coupling",)))
    assert np.max(np.abs(res.U)) == 0.0
    base = peak(kf.solve(slider_crank_scene(elements=4, steps=180)))[0]
    stiff = peak(kf.solve(slider_crank_scene(elements=4, steps=180,
                                             effects=SC_EFF + ("axial_stiffening",))))[0]
    # against the geometrically exact model (ANCF, benchmarks/exact_comparison.py, beta = 3e-5 s):
    # peak 1.5463 mm; the kinetostatic axial force's stiffening brings the linear model to it
    exact = 1.5463e-3
    assert abs(abs(stiff) / exact - 1) < 0.01 and abs(base) / exact - 1 > 0.04, (base, stiff)
    # rotating blade: axial stiffening raises, centripetal coupling lowers the bending frequency
    m = kf.Mechanism("blade")
    m.ground("O", at=(0, 0), clamped=True)
    m.joint("T", at=(0.5, 0))
    m.link("b", "O", "T", material=kf.Material(2e11, 7850), section=kf.Section.rectangle(0.01, 0.004),
           elements=6)
    m.drive("b", speed=40.0)  # gamma ~ 1.7: centripetal softening alone keeps it stable
    f = {eff: kf.natural_frequencies(m, n_modes=1, effects=eff).frequencies[0]
         for eff in ((), ("coupling",), ("axial_stiffening",), ("coupling", "axial_stiffening"))}
    assert f[("coupling",)] < f[()] < f[("axial_stiffening",)]
    assert f[("coupling",)] < f[("coupling", "axial_stiffening")] < f[("axial_stiffening",)]


def test_effect_not_named_is_never_computed(monkeypatch):
    def boom(*a, **k):
        raise AssertionError("code of an effect that was not asked for ran")
    monkeypatch.setattr(GeometricNonlinearity, "state_terms", boom)
    monkeypatch.setattr(Assembler, "state_terms", boom)
    monkeypatch.setattr(assembler, "kinetostatics", boom)
    sc = slider_crank_scene(elements=4, steps=60)
    assert not sc.state_dependent
    res = kf.solve(sc)
    assert res.iterations == 1 and res.history == ()
    # and the same scene with the effect does run it
    sc2 = slider_crank_scene(elements=4, steps=60, effects=SC_EFF + ("geometric_nonlinearity",))
    assert sc2.state_dependent
    with pytest.raises(AssertionError, match="not asked for"):
        kf.solve(sc2)


def test_bending_moment_of_quasi_static_cantilever():
    """Exciter at 0.1 Hz (far below resonance): root moment = tip force x length."""
    m = mechanisms.build("exciter", speed=2 * math.pi * 0.1, tip_mass=0.0)
    res = kf.solve(kf.Scene(m, steps=360, effects=("springs",), damping=kf.ModalDamping(0.002)))
    tip = res.joint_displacement("T")[:, 1]
    pin = res.motion.position("P")[:, 1] - res.motion.position("P")[0, 1]
    F = 2.0e4 * (pin - tip)  # spring force on the tip (+y)
    M = res.bending_moment("beam")
    x = res.stations("beam")
    expected = F[:, None] * (0.8 - x)[None, :]  # EI v'' > 0 at the root for an upward tip force
    assert np.max(np.abs(M - expected)) < 1e-3 * np.max(np.abs(expected))
    s = res.stress("beam")
    sec = kf.Section.rectangle(0.04, 0.01)
    assert np.max(s[:, 0]) == pytest.approx(np.max(np.abs(expected[:, 0])) * sec.c / sec.I, rel=1e-3)


@pytest.mark.parametrize("kwargs,match", [
    (dict(steps=2), "steps"),
    (dict(speed=0.0), "speed is zero"),
    (dict(effects=("inertia", "warp")), "known effects: inertia, coupling"),
    (dict(hold="rk4"), "hold"),
    (dict(damping=0.02), "damping"),
    (dict(eps=0.0), "eps"),
    (dict(speed=1e-300), "cycle lasts 6.28e\\+300 s"),
    (dict(speed=1e12), r"outside \[1e-09, 1e\+09\] s"),
])
def test_scene_input_errors(kwargs, match):
    with pytest.raises(kf.InputError, match=match):
        kf.Scene(mechanisms.build("slider_crank"), **kwargs)


def test_scene_on_structure_without_drive():
    m = kf.Mechanism("post")
    m.ground("O", at=(0, 0), clamped=True)
    m.joint("T", at=(0, 1))
    m.link("p", "O", "T", material=kf.Material(2e11, 7850), section=kf.Section.circle(0.02))
    with pytest.raises(kf.InputError, match="no drive"):
        kf.Scene(m)


def test_speed_override_scales_all_drives():
    m = mechanisms.build("mould_oscillator")
    sc = kf.Scene(m, speed=10.0, effects=("inertia",))
    assert [d.speed for d in sc.mech.drives] == [10.0, 10.0]
    assert [d.speed for d in m.drives] == [d.speed for d in mechanisms.build("mould_oscillator").drives]
    assert sc.period == pytest.approx(2 * math.pi / 10.0)


def test_periodic_result_matches_direct_integration():
    """Damped slider-crank: the state-space periodic result against Newmark run until periodic.

    Newmark (average acceleration, second order) integrates the same assembled
    equations: the scene's M, C, K, Q evaluated exactly at every Newmark step
    time, from rest, cycle by cycle until the cycle-to-cycle defect is below
    1e-9. Its step T/16384 gives an error of about (w1 dt)^2/12 ~ 1e-6.
    """
    from kedfem.analysis.pipeline import assemble_scene
    from kedfem.lab.transient import integrate_periodic, sampled_system
    m = mechanisms.build("slider_crank", elements=2)
    eff = ("inertia", "coupling", "axial_stiffening")
    damp = kf.Rayleigh(alpha=5.0, beta=3e-5)
    res = kf.solve(kf.Scene(m, effects=eff, damping=damp, accuracy="tight"))  # rtol 1e-5
    assert res.error.met
    n_out, sub = 256, 64
    mo, model, asm = assemble_scene(kf.Scene(m, steps=n_out * sub, effects=eff, damping=damp))
    S = asm.system()
    system = sampled_system(S.M, S.C, S.K, S.Q, mo.period, kind="linear")  # exact at the steps
    tr = integrate_periodic(system, model.n_dof, mo.period, method="newmark", tol=1e-9,
                            n_out=n_out, steps_per_output=sub)
    assert tr.converged and tr.cycles > 5
    U = res.resample(tr.t).U
    err = np.max(np.abs(U - tr.U)) / np.max(np.abs(tr.U))
    assert err < 1e-5 and err < 3 * res.error.history + 1e-6  # Newmark's own error ~1e-6


def test_six_bar_two_loops_and_rigid_bellcrank():
    m = mechanisms.build("six_bar", elements=2)
    mo = kf.kinematics(m, steps=90)
    assert mo.residual < 1e-12
    # both loops close: output rocker stays at its length from O6 and the bellcrank is rigid
    d = np.linalg.norm(mo.position("D") - np.array(m.joints["O6"].at), axis=1)
    np.testing.assert_allclose(d, m.links["rocker"].length, rtol=1e-12)
    bc = np.linalg.norm(mo.position("C") - mo.position("B"), axis=1)
    np.testing.assert_allclose(bc, bc[0], rtol=1e-12)
    res = kf.solve(kf.Scene(m, steps=90, effects=("inertia", "coupling", "axial_stiffening"),
                            damping=kf.ModalDamping(0.02)))
    assert res.stable and np.all(np.isfinite(res.U))
    assert np.max(np.abs(res.deflection("link", 0.5))) > 0


def test_validate_time_invariant_scene_against_modal_superposition():
    sc = kf.Scene(mechanisms.build("exciter"), effects=("springs",), damping=kf.ModalDamping(0.02))
    rep = kf.validate(sc, foh_steps=120)
    exact, foh = rep.responses
    # the tolerance-driven solve against the exact response, within its own estimate
    assert exact.max_rel_error <= sc.rtol and exact.max_rel_error <= 3 * exact.estimate
    assert foh.max_rel_error < 1e-9 and foh.n == 120   # the discretisation foh solves exactly
    assert rep.frequencies[0].difference < 1e-6
    assert "modal superposition" in rep.table()


@pytest.mark.parametrize("steps", [24, 90])
def test_magnus2_keeps_a_damped_six_bar_stable_at_coarse_steps(steps):
    """magnus2 averages M, C, K over the element before forming M^-1 K.

    Averaging M^-1 K itself (as kedfem did before) gave its stiff, rotating
    joint couplings complex eigenvalues and a spurious parametric instability:
    |mu| = 1.8 at 90 steps and 1e17 at 24 on this 2 %-damped six-bar, whose
    zero-order hold (frozen data per element) is stable.
    """
    m = mechanisms.build("six_bar", elements=2)
    kw = dict(steps=steps, effects=("inertia", "coupling", "axial_stiffening"), damping=kf.ModalDamping(0.02))
    frozen = kf.solve(kf.Scene(m, hold="zoh", **kw))
    assert frozen.stable
    res = kf.solve(kf.Scene(m, hold="magnus2", **kw))
    assert res.stable and np.abs(res.floquet_multipliers).max() < 1.0


def test_time_invariant_scene_takes_the_constant_matrix_path():
    """The exciter's M, C, K do not vary: kf.solve passes them as constants (one exponential);
    the answer is the sampled-matrix solve of the same discretisation."""
    from kedfem.solvers import periodic
    from kedfem.analysis.pipeline import _constant_or_sampled, assemble_scene
    sc = kf.Scene(mechanisms.build("exciter"), steps=72, effects=("inertia", "coupling", "springs"),
                  damping=kf.ModalDamping(0.02), hold="foh", estimate=False)
    mo, _model, asm = assemble_scene(sc)
    S = asm.system()
    assert all(_constant_or_sampled(X).ndim == 2 for X in (S.M, S.C, S.K))
    sampled = periodic.solve(S.M, S.C, S.K, S.Q, mo.period, hold="foh")
    assert sampled.n_exponentials == 72
    res = kf.solve(sc)
    assert np.abs(res.resample(mo.t).U - sampled.U).max() <= 1e-9 * np.abs(sampled.U).max()
    # a time-varying scene keeps its samples
    mo2, _m2, asm2 = assemble_scene(kf.Scene(mechanisms.build("slider_crank", elements=2), steps=12))
    assert _constant_or_sampled(asm2.system().K).ndim == 3


def test_absurd_density_is_a_named_error_not_a_linalg_traceback():
    """rho = 1e-300 kg/m^3: natural frequencies beyond floating point (issue 12, item 1)."""
    import warnings
    m = mechanisms.build("exciter", rho=1e-300)
    with pytest.raises(kf.KedError, match="the eigenproblem of M and K has no solution"), \
            warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # numpy's overflow on the way to the error
        kf.solve(kf.Scene(m, effects=("inertia", "coupling", "springs"), damping=kf.ModalDamping(0.02)))


def test_replace_does_not_share_the_old_results_cache():
    """``dataclasses.replace(res, U=...)`` returned the old deflections from a shared cache (issue 13)."""
    res = kf.solve(kf.Scene(mechanisms.build("slider_crank"), effects=("inertia", "coupling"),
                            damping=kf.ModalDamping(0.02), steps=48, estimate=False))
    d = res.deflection("rod", 0.5, relative_to="chord")
    s = res.stress("rod")
    twice = dataclasses.replace(res, U=2.0 * res.U, V=2.0 * res.V)
    np.testing.assert_allclose(twice.deflection("rod", 0.5, relative_to="chord"), 2.0 * d, rtol=1e-12)
    assert not np.allclose(twice.stress("rod"), s)
