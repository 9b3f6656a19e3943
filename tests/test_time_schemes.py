"""The time schemes of the periodic solve against independent truth.

References: the periodic solution of a damped, parametrically excited 2-DOF
system computed by ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-13: the
monodromy matrix and the particular solution over one period, then the
periodicity condition); the first instability tongue of the Mathieu equation
from ``scipy.special.mathieu_a`` / ``mathieu_b``; the converged four-bar by
Radau collocation for the exact stiff split of the exponential holds; power
laws with known rates for the rate estimate.
"""

from __future__ import annotations

import dataclasses
import math
import re
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.special import mathieu_a, mathieu_b

import kedfem as kf
from kedfem.analysis import accuracy
from kedfem.solvers import fourier, schemes
from kedfem.errors import InputError, InstabilityWarning
from kedfem.analysis.results import stability_verdict

T = 1.0
W = 2 * math.pi / T
M0 = np.array([[1.0, 0.0], [0.0, 2.0]])
C0 = np.array([[0.4, -0.1], [-0.1, 0.3]])
K0 = np.array([[60.0, -20.0], [-20.0, 90.0]])
K1 = np.array([[15.0, 5.0], [5.0, -10.0]])


def K(t):
    return K0 + K1 * np.cos(W * np.asarray(t, float))[..., None, None]


def Q(t):
    t = np.asarray(t, float)
    return np.stack([np.sin(W * t) + 0.3 * np.cos(2 * W * t), 0.5 * np.cos(W * t + 0.4)], axis=-1)


@pytest.fixture(scope="module")
def reference():
    """Dense periodic solution and Floquet multipliers by solve_ivp (DOP853)."""
    N = 2
    Mi = np.linalg.inv(M0)

    def A(t):
        return np.block([[np.zeros((N, N)), np.eye(N)], [-Mi @ K(t), -Mi @ C0]])

    def f(t, y):
        z = y.reshape(2 * N, 2 * N + 1)
        dz = A(t) @ z
        dz[N:, -1] += Mi @ Q(t)
        return dz.ravel()

    y0 = np.hstack([np.eye(2 * N), np.zeros((2 * N, 1))]).ravel()
    s = solve_ivp(f, (0, T), y0, method="DOP853", rtol=1e-13, atol=1e-14)
    Z = s.y[:, -1].reshape(2 * N, 2 * N + 1)
    Phi, d = Z[:, :2 * N], Z[:, -1]
    x0 = np.linalg.solve(np.eye(2 * N) - Phi, d)
    s2 = solve_ivp(lambda t, x: A(t) @ x + np.concatenate([np.zeros(N), Mi @ Q(t)]), (0, T), x0,
                   method="DOP853", rtol=1e-13, atol=1e-14, dense_output=True)
    return s2.sol, np.linalg.eigvals(Phi)


def _solve(name, n):
    sc = schemes.get(name)
    ti = sc.instants(n, T)
    return sc.solve(M0, C0, K(ti), Q(ti), T, n)


def _rel(U, X):
    return float(np.abs(U - X[:2].T).max() / np.abs(X[:2]).max())


@pytest.mark.parametrize("name, order, dense_order", [
    ("radau2", 3, 2.8), ("radau3", 5, 3.8), ("gauss2", 4, 2.8), ("gauss3", 6, 3.8)])
def test_collocation_orders_at_the_nodes_and_between(reference, name, order, dense_order):
    sol, _mu = reference
    ns = (12, 24, 48)
    nodal, between = [], []
    for n in ns:
        d = _solve(name, n)
        tk = np.arange(n) * T / n
        nodal.append(_rel(d.U, sol(tk)))
        tm = (np.arange(n) + 0.37) * T / n
        between.append(_rel(d.at(tm)[0], sol(tm)))
    slopes = [math.log2(nodal[i] / nodal[i + 1]) for i in range(2)]
    assert all(abs(s - order) < 0.3 for s in slopes), (name, nodal, slopes)
    dslope = math.log2(between[1] / between[2])
    assert dslope >= dense_order, (name, between)
    assert nodal[-1] < 2e-3


@pytest.mark.parametrize("name, n, tol", [("radau3", 48, 1e-6), ("gauss3", 24, 1e-6), ("magnus2", 720, 1e-4)])
def test_floquet_multipliers_match_the_integrated_monodromy(reference, name, n, tol):
    _sol, mu = reference
    d = _solve(name, n)
    got = np.sort(np.abs(d.floquet_multipliers))
    assert np.abs(got - np.sort(np.abs(mu))).max() < tol


def test_fourier_collocation_is_spectral_and_its_two_solvers_agree(reference):
    sol, _mu = reference
    errs = [_rel(_solve("fourier", n).U, sol(np.arange(n) * T / n)) for n in (9, 15)]
    assert errs[0] < 1e-5 and errs[1] < 1e-10, errs
    n = 21
    ti = schemes.get("fourier").instants(n, T)
    a = fourier.solve(M0, C0, K(ti), Q(ti), T)
    b = fourier.solve(M0, C0, K(ti), Q(ti), T, dense_limit=10)   # forces preconditioned GMRES
    assert b.method == "gmres" and a.method == "dense"
    assert np.abs(a.U - b.U).max() < 1e-10 * np.abs(a.U).max()
    # the differentiation matrix is exact on trigonometric polynomials of degree (n - 1) / 2
    t = np.arange(n) * T / n
    D = fourier.differentiation(n, T)
    f = np.sin(3 * W * t) + np.cos(10 * W * t)
    assert np.allclose(D @ f, 3 * W * np.cos(3 * W * t) - 10 * W * np.sin(10 * W * t), atol=1e-9 * W * 10)


def test_scheme_registry_and_bad_input():
    assert schemes.get("auto") is schemes.get(schemes.AUTO)
    assert set(schemes.names()) >= {"auto", "radau3", "radau2", "gauss3", "gauss2", "magnus2", "foh", "zoh",
                                    "fourier"}
    with pytest.raises(InputError, match="radau3"):
        schemes.get("rk4")
    with pytest.raises(InputError, match="odd"):
        schemes.get("fourier").check_elements(20)
    with pytest.raises(InputError, match="odd"):
        fourier.differentiation(8, T)
    assert schemes.get("fourier").refine(9) == 17 and schemes.get("radau3").refine(12) == 24


def _rho(a, q, name, n, c=0.0):
    sc = schemes.get(name)
    ti = sc.instants(n, math.pi)
    Kt = (a - 2 * q * np.cos(2 * ti))[:, None, None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InstabilityWarning)
        d = sc.solve(np.eye(1), np.full((1, 1), c), Kt, np.zeros((ti.size, 1)), math.pi, n)
    return float(np.abs(d.floquet_multipliers).max())


def _edge(q, name, n, outside, inside):
    """Bisection for the tongue boundary between an a outside and one inside."""
    for _ in range(34):
        mid = 0.5 * (outside + inside)
        if _rho(mid, q, name, n) > 1 + 1e-9:
            inside = mid
        else:
            outside = mid
    return 0.5 * (outside + inside)


@pytest.mark.parametrize("q", [0.1, 1.0])
def test_mathieu_first_tongue(q):
    """u'' + (a - 2 q cos 2t) u = 0: unstable for b1(q) < a < a1(q) (scipy's characteristic values)."""
    b1, a1 = mathieu_b(1, q), mathieu_a(1, q)
    mid = 0.5 * (a1 + b1)
    # the scheme of the stability verdict (Radau IIA), 32 elements a period
    assert abs(_edge(q, "radau3", 32, b1 - 0.2, mid) - b1) < 1e-6
    assert abs(_edge(q, "radau3", 32, a1 + 0.2, mid) - a1) < 1e-6
    # the paper's method, second order: 1e-4 at 1024 elements
    assert abs(_edge(q, "magnus2", 1024, b1 - 0.2, mid) - b1) < 1e-4
    # the verdict, with the error band of a coarser solve: undamped outside the tongue the
    # multipliers lie on the unit circle (marginal); lightly damped, stable; inside, unstable
    for a, c, want in ((b1 - 0.05, 0.0, "marginal"), (b1 - 0.05, 0.02, "stable"), (mid, 0.02, "unstable")):
        rho, rho_c = _rho(a, q, "radau3", 32, c), _rho(a, q, "radau3", 16, c)
        assert stability_verdict(rho, abs(rho - rho_c)) == want, (a, c, rho, rho_c)


def test_an_instability_warning_names_how_the_response_grows():
    """Inside Mathieu's first tongue (between scipy's b1 and a1) the multiplier is real negative:
    the period doubles; inside the second (b2 .. a2) it is real positive. A new user's flip was
    reported as a bare |mu| > 1."""
    sc = schemes.get("radau3")
    q = 1.0
    for a, want, not_want in ((0.5 * (mathieu_a(1, q) + mathieu_b(1, q)), "period doubling", "real positive"),
                              (0.5 * (mathieu_a(2, q) + mathieu_b(2, q)), "real positive", "period doubling")):
        ti = sc.instants(32, math.pi)
        Kt = (a - 2 * q * np.cos(2 * ti))[:, None, None]
        with pytest.warns(InstabilityWarning) as caught:
            d = sc.solve(np.eye(1), np.full((1, 1), 0.01), Kt, np.ones((ti.size, 1)), math.pi, 32)
        mu = d.floquet_multipliers[np.argmax(np.abs(d.floquet_multipliers))]
        text = " ".join(str(w.message) for w in caught)
        assert want in text and not_want not in text, (a, mu, text)
        assert (mu.real < 0) == (want == "period doubling") and abs(mu.imag) < 1e-9 * abs(mu)


@pytest.fixture(scope="module")
def four_bar():
    import mechanisms
    return mechanisms.build("four_bar"), dict(effects=("inertia", "coupling", "axial_stiffening"),
                                              damping=kf.ModalDamping(0.02))


def _peaks(res):
    return np.array([[p.deflection, p.stress] for p in res.peaks()])


def test_stiff_split_makes_the_paper_hold_converge_on_a_closed_loop(four_bar):
    """magnus2 on the four-bar: the held, turning axial stiffness rings without the split."""
    m, kw = four_bar
    ref = _peaks(kf.solve(kf.Scene(m, steps=384, method="radau3", estimate=False, **kw)))
    err = {}
    for split in (True, False):
        r = kf.solve(kf.Scene(m, steps=360, method="magnus2", estimate=False, stiff_split=split, **kw))
        err[split] = float(np.abs(_peaks(r) / ref - 1).max())
    assert err[True] < 0.1 and err[False] > 0.5, err


def test_observed_rate_recovers_a_power_law():
    for p in (1.0, 2.0, 4.5):
        lv = (24, 48, 96)
        e = [3.0 * n ** -p for n in lv]
        assert accuracy.observed_rate(lv, (e[0] - e[1], e[1] - e[2])) == pytest.approx(p, rel=1e-6)
    assert math.isnan(accuracy.observed_rate((24, 48, 96), (1e-3, 2e-3)))  # not converging


def _levels(peak_err, burst_err, levels=(96, 192, 384), rate=3.0, burst_rate=1.5):
    """Observables of three levels: a peak at instant 10 off by ``peak_err (384/n)^rate`` and a
    burst at instant 40, away from it, off by ``burst_err (384/n)^burst_rate`` (the Whitworth's
    histories: the error made at t/T = 0.6-0.7)."""
    t = np.arange(64) / 64
    exact = np.exp(-((t - 10 / 64) / 0.05) ** 2) + 0.3 * np.exp(-((t - 40 / 64) / 0.05) ** 2)
    out = []
    for n in levels:
        h = exact.copy()
        h[10] *= 1 + peak_err * (384 / n) ** rate
        h[40] += burst_err * (384 / n) ** burst_rate
        out.append(accuracy.Observables(("rod",), n, np.array([h[10]]), np.array([10]), np.zeros(1),
                                        np.zeros(1, int), np.zeros(1, int), (h,), (np.zeros((64, 0)),),
                                        (False,)))
    return list(levels), out


def test_an_estimate_far_inside_rtol_with_converging_histories_is_met_clearly():
    """Before the asymptotic range (histories at rate 1.5 < 2), peaks 100x inside rtol: met clearly;
    not with the peaks only 10x inside, nor with histories that do not converge."""
    kw = dict(assumed=3.0, order=4.0, rtol=1e-3)
    est = accuracy.estimate(*_levels(1e-6, 1e-3), **kw)
    assert not est.asymptotic and est.clear and est.met and est.peak <= 1e-5
    assert est.history > 1e-3  # the histories' estimate stays as large as their differences say
    # met is on the peaks; the one line says the histories are beyond rtol (bearing loads)
    assert "met on the peaks, histories beyond it (bearing loads up to" in est.describe()
    near = accuracy.estimate(*_levels(3e-5, 1e-3), **kw)
    assert not near.asymptotic and not near.clear and near.peak > 1e-5
    stalled = accuracy.estimate(*_levels(1e-6, 1e-3, burst_rate=-0.5), **kw)  # the burst grows
    assert not stalled.clear
    # in the asymptotic range (histories at rate 4) it is the ordinary estimate, not "clear"
    asym = accuracy.estimate(*_levels(1e-6, 1e-3, rate=4.0, burst_rate=4.0), **kw)
    assert asym.asymptotic and not asym.clear


def test_peaks_that_do_not_move_do_not_make_an_estimate_clear():
    """A quasi-static peak exact on every level (its differences 0) beside a ringing that the
    scheme's numerical damping holds below it on coarse levels (0.65 / 0.85 / 0.95 of the true
    1.05 on 96 / 192 / 384 elements): its histories converge at rate 1, but the peak about to be
    overtaken is no converged peak, so the estimate is not 'clear' and the refinement goes on (the
    true error of the reported peak is 5 %: a stop there would print 0 at rtol 1e-3)."""
    t = np.arange(64) / 64
    levels, out = (96, 192, 384), []
    for n in levels:
        h = np.exp(-((t - 10 / 64) / 0.05) ** 2) + (1.05 - 0.1 * (384 / n)) * np.exp(-((t - 40 / 64) / 0.05) ** 2)
        k = int(np.argmax(np.abs(h)))
        out.append(accuracy.Observables(("rod",), n, np.array([h[k]]), np.array([k]), np.zeros(1),
                                        np.zeros(1, int), np.zeros(1, int), (h,), (np.zeros((64, 0)),), (False,)))
    assert [o.deflection[0] for o in out] == [1.0, 1.0, 1.0]  # the ringing is still below the peak
    for rtol in (1e-2, 1e-3, 1e-5):
        est = accuracy.estimate(list(levels), out, assumed=3.0, order=4.0, rtol=rtol)
        assert not est.clear and not est.asymptotic and not est.settled, rtol


def test_default_stability_of_the_four_bar_agrees_with_the_split_exponential(four_bar):
    """The verdict's spectral radius (Radau, finest level) within its error of magnus2 + split."""
    m, kw = four_bar
    res = kf.solve(kf.Scene(m, **kw))
    ref = kf.solve(kf.Scene(m, steps=2880, method="magnus2", estimate=False, **kw)).stability.spectral_radius
    s = res.stability
    assert s.verdict == "stable" and s.scheme == "radau3"
    assert s.error is not None and abs(s.spectral_radius - ref) <= max(s.error, 1e-6), (s, ref)


@pytest.mark.parametrize("name, n", [("radau3", 4096), ("magnus2", 48)])
def test_unbounded_response_is_a_named_error(name, n):
    """Negative damping c = -2000 1/s over a 1 s cycle: growth e^2000 overflows floating point.

    (Radau IIA, being L-stable, turns a growth it does not resolve, lambda h >> 1, into decay:
    the elements must resolve it. In a linkage the growth rates of parametric instabilities are
    below the modal frequencies that the resolution floor of a solve resolves.)
    """
    sc = schemes.get(name)
    ti = sc.instants(n, T)
    with pytest.raises(kf.UnboundedResponseError, match="response unbounded"), warnings.catch_warnings():
        warnings.simplefilter("ignore", InstabilityWarning)
        sc.solve(np.eye(1), np.full((1, 1), -2000.0), np.full((ti.size, 1, 1), 50.0),
                 np.ones((ti.size, 1)), T, n)


def test_a_diverging_iterate_keeps_the_last_bounded_one():
    from kedfem.solvers.nonlinear import fixed_point
    calls = []

    def G(U, V, it):
        calls.append(it)
        if it == 2:
            raise kf.UnboundedResponseError("response unbounded: test")
        return "sol1", U + 1.0, V

    with pytest.warns(kf.ConvergenceWarning, match="unbounded"):
        sol, hist, converged, msg = fixed_point(G, 4, 2, T, eps=1e-9)
    assert sol == "sol1" and not converged and calls == [1, 2] and math.isinf(hist[-1])


def _straight_line_linkage(rpm):
    """A Hoekens straight-line linkage (not in the catalogue): rigid crank, a flexible coupler in
    two halves welded to a small hub where the rocker pins, a 0.1 kg point mass at its end.
    Its first mode (~105 Hz) has 21 periods per cycle at 300 rpm."""
    u = 0.05
    steel = kf.Material(E=2.1e11, rho=7850.0)
    strip = kf.Section.rectangle(0.020, 0.006)
    A, B, d, eps = (0.0, u), (2 * u, 2.5 * u), (0.8, 0.6), 0.0002
    m = kf.Mechanism("straight-line")
    m.ground("O2", at=(0.0, 0.0))
    m.ground("O4", at=(2 * u, 0.0))
    m.joint("A", at=A)
    m.joint("B", at=B)
    m.joint("B1", at=(B[0] - eps * d[0], B[1] - eps * d[1]), welded=True)
    m.joint("B2", at=(B[0] + eps * d[0], B[1] + eps * d[1]), welded=True)
    m.joint("P", at=(A[0] + 5 * u * d[0], A[1] + 5 * u * d[1]))
    m.link("crank", "O2", "A", rigid=True, mass=0.05)
    m.link("coupler1", "A", "B1", material=steel, section=strip, elements=4)
    m.link("coupler2", "B2", "P", material=steel, section=strip, elements=4)
    hub = 7850.0 * 0.02 * 0.006 * 2 * eps
    m.body("hub", ["B1", "B", "B2"], mass=hub, J=hub * (2 * eps) ** 2 / 12)
    m.link("rocker", "O4", "B", material=steel, section=strip, elements=4)
    m.point_mass("P", 0.1)
    m.drive("crank", speed=rpm * 2 * math.pi / 60)
    return m


def test_spectral_radius_is_not_lowered_by_the_schemes_numerical_damping():
    """With 2 % modal damping and no parametric resonance the spectral radius is the least damped
    mode's decay over a cycle, exp(-zeta * integral of omega_1 dt) (adiabatic). Radau on the 48
    elements the peaks need damps that 105 Hz mode 5x more per cycle (it printed 0.014 +- 1e-3
    before the stability floor); the default solve, whose verdict is not in doubt, stops below the
    floor once its histories meet rtol too (192 elements) and its error band, which includes what
    the numerical damping may hide, holds the truth; on the elements the floor asks for, the
    spectral radius is right."""
    m = _straight_line_linkage(300)
    eff, z2 = ("inertia", "coupling", "axial_stiffening"), kf.ModalDamping(0.02)
    res = kf.solve(kf.Scene(m, effects=eff, damping=z2))
    f1 = res.frequencies(n_modes=1, nodes=range(0, res.n, max(1, res.n // 72))).modal[:, 0]
    expected = math.exp(-0.02 * 2 * math.pi * float(np.mean(f1)) * res.scene.period)
    st = res.stability
    assert st.verdict == "stable" and "not needed" in st.note
    assert st.spectral_radius - st.error <= expected <= st.spectral_radius + st.error, st.describe()
    # and on the 48 elements the peaks alone need, the band holds it too
    coarse = kf.solve(kf.Scene(m, effects=eff, damping=z2, steps=48)).stability
    assert coarse.spectral_radius < 0.5 * expected <= expected <= coarse.spectral_radius + coarse.error, \
        coarse.describe()
    need = int(re.search(r"a resolved radius needs about (\d+) elements", st.note).group(1))
    fine = kf.solve(kf.Scene(m, effects=eff, damping=z2, steps=need)).stability
    assert fine.spectral_radius == pytest.approx(expected, rel=1e-2), (fine.describe(), expected)
    assert fine.verdict == "stable" and not fine.note


def test_an_undamped_scene_is_marginal_not_stable():
    m = _straight_line_linkage(600)
    res = kf.solve(kf.Scene(m, effects=("inertia", "coupling"), damping=None))
    assert res.stability.verdict == "marginal" and "undamped" in res.stability.note
    assert not res.stable


@pytest.mark.parametrize("name", ["radau3", "radau2"])
def test_kept_factorisations_solve_another_load_and_move_the_multipliers(name):
    """A collocation solve that keeps its factorisations (``factors=True``) solves a second load
    as a fresh solve does, to round-off; and its multipliers for a changed ``C, K`` (first order,
    :meth:`Resolver.multipliers`) are within the square of the change of the changed system's
    own, where the frozen ones are off by the change itself."""
    from kedfem.solvers import collocation
    n = 40
    ti = collocation.instants(name, n, T).ravel()
    first = collocation.solve(M0, C0, K(ti), Q(ti), T, name, factors=True)
    assert collocation.solve(M0, C0, K(ti), Q(ti), T, name).resolver is None
    Q2 = np.stack([np.cos(3 * W * ti) ** 2, np.sin(W * ti) ** 3], axis=-1)
    again, fresh = first.resolver.solve(Q2), collocation.solve(M0, C0, K(ti), Q2, T, name)
    for a, b in ((again.U, fresh.U), (again.V, fresh.V), (again.stage_U, fresh.stage_U)):
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()
    errs = []
    for eps in (1e-2, 1e-3):
        dK = eps * K1[None] * np.sin(2 * W * ti)[:, None, None]
        dC = np.broadcast_to(0.5 * eps * C0, dK.shape)
        exact = collocation.solve(M0, C0 + dC, K(ti) + dK, Q(ti), T, name).floquet_multipliers
        moved = first.resolver.multipliers(dC, dK)
        rho = np.abs(exact).max()
        frozen = abs(np.abs(first.floquet_multipliers).max() - rho)
        errs.append(abs(np.abs(moved).max() - rho))
        assert errs[-1] <= 0.05 * frozen
    assert errs[1] <= errs[0] / 30  # second order: 100x for a 10x smaller change


def test_defect_correction_is_not_offered_for_radau2(reference):
    """Stage order 2: the end stage's acceleration is too rough for the quintic interpolant (the
    estimate 5x the true error on 24 elements), so ``available`` says no and the pipeline keeps
    the levels' estimate."""
    from kedfem.solvers import defect
    assert not defect.available(_solve("radau2", 24)) and defect.available(_solve("radau3", 24))
    assert not defect.available(_solve("gauss3", 24))  # not stiffly accurate


@pytest.mark.parametrize("name", ["radau3"])
def test_defect_correction_estimates_the_error_between_the_nodes(reference, name):
    """The one-level defect-corrected solution (:mod:`kedfem.solvers.defect`) against the
    solve_ivp reference: its difference from the solve is the solve's error at instants between
    the nodes to within 30 % once the elements resolve the response, and it is itself at least
    10x closer to the reference; on graded elements too (the Hermite interpolant per element)."""
    from kedfem.solvers import defect
    sol, _mu = reference
    sc = schemes.get(name)
    tm = (np.arange(400) + 0.5) * (T / 400)
    X = sol(tm)[:2].T
    for n, graded in ((24, False), (48, False), (96, False), (48, True)):
        edges = None
        if graded:  # elements shorter in the second half of the cycle
            x = np.linspace(0.0, 1.0, n + 1)
            edges = T * (x + 0.15 * np.sin(2 * math.pi * x) / (2 * math.pi))
        ti = sc.instants(n, T, edges)
        Kt, Qt = K(ti), Q(ti)
        d = sc.solve(M0, C0, Kt, Qt, T, n, edges=edges)
        y = defect.corrected(d, M0, C0, Kt, Qt, lambda q: sc.solve(M0, C0, Kt, q, T, n, edges=edges))
        u, uc = d.at(tm)[0], y.at(tm)[0]
        true, est = np.abs(u - X).max(), np.abs(u - uc).max()
        assert 0.7 * true <= est <= 1.3 * true, (name, n, graded, true, est)
        assert np.abs(uc - X).max() <= 0.1 * true, (name, n, graded)
        v, vc = d.velocities(tm), y.velocities(tm)
        Xv = sol(tm)[2:].T
        assert 0.5 * np.abs(v - Xv).max() <= np.abs(v - vc).max() <= 2.0 * np.abs(v - Xv).max()


def test_a_defect_estimate_is_believed_only_where_it_explains_the_change():
    """Two levels and their corrected solutions: believed (``reliable``) when the coarser level's
    correction accounts for most of the change to the finer one; not when it leaves the change
    as it was (an unresolved mode: the correction sees the scheme's own response)."""
    levels, obs = _levels(1e-5, 0.0, levels=(96, 192, 384), rate=4.0)
    truth = _levels(0.0, 0.0, levels=(96,))[1][0]
    coarse, fine = obs[0], obs[1]
    kw = dict(assumed=3.0, order=4.0, rtol=1e-3)
    good = accuracy.defect_estimate((96, 192), coarse, fine, truth, truth, **kw)
    assert good.reliable and good.method == "defect" and good.met
    # fine's true error 1e-5 (384/192)^4 = 1.6e-4 relative: the estimate says so, with SAFETY
    assert good.peak == pytest.approx(accuracy.SAFETY * 1.6e-4, rel=0.05)
    bad = accuracy.defect_estimate((96, 192), coarse, fine, coarse, truth, **kw)
    assert not bad.reliable and not bad.met
    # the peaks changed by 2.4e-3: Richardson at order 4 says 1.6e-4 for the finer level
    assert accuracy.promising(coarse, fine, ratio=2.0, order=4.0, rtol=2e-4)
    assert not accuracy.promising(coarse, fine, ratio=2.0, order=4.0, rtol=1e-4)
    # with the histories (the peak's history is the only one here): 1.35 x 2.4e-3 / (2^3 - 1) = 4.6e-4
    assert accuracy.promising(coarse, fine, ratio=2.0, order=4.0, rtol=5e-4, assumed=3.0)
    assert not accuracy.promising(coarse, fine, ratio=2.0, order=4.0, rtol=4e-4, assumed=3.0)


def _preset(name):
    import os
    return kf.load_scene(os.path.join(os.path.dirname(__file__), "..", "examples", "scenes", f"{name}.toml"))[0]


def _solve_and_reference(sc, steps=768):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return kf.solve(sc), kf.solve(dataclasses.replace(sc, steps=steps, estimate=False, rtol=None))


def test_the_slider_crank_ends_on_an_honest_defect_estimate():
    """The slider-crank preset at its default rtol: the refinement stops on two levels whose
    coarser correction explains their change (24/48 elements, where three levels went on to 96),
    and every peak is within its estimate of a 768-element solve (estimate / true between 1/3
    and 10), the histories' estimate within rtol as that stop requires."""
    sc = _preset("slider_crank")
    res, ref = _solve_and_reference(sc)
    assert res.error.method == "defect" and res.error.met and res.error.levels == (24, 48)
    assert res.error.history <= sc.rtol
    for p, q in zip(res.peaks(), ref.peaks()):
        e = res.error.link(p.link)
        for est, a, b in ((e.deflection, p.deflection, q.deflection), (e.stress, p.stress, q.stress)):
            true = abs(a - b) / abs(b)
            assert true <= sc.rtol and true / 3 <= est <= 10 * true, (p.link, est, true)


def test_the_four_bar_keeps_its_bearing_loads_within_rtol():
    """The four-bar preset (geometric non-linearity): its 48/96 levels' defect correction explains
    their peaks' change, but its coupler's axial force history (on which the bearing loads ride)
    is estimated 16 % off there, so the refinement goes on to 192 elements, and every bearing's
    peak force is within rtol of a 768-element solve (a review found them 3.4 % off when the
    defect estimate stopped it on 96)."""
    sc = _preset("four_bar")
    res, ref = _solve_and_reference(sc)
    assert res.elements >= 192 and res.error.met
    L, R = res.loads(), ref.loads()
    step = R.n // L.n
    assert step * L.n == R.n and np.allclose(R.t[::step], L.t)
    for joint, member in L.bearings:
        a, b = L.magnitude(joint, member), R.magnitude(joint, member)[::step]
        assert abs(a.max() - b.max()) <= sc.rtol * b.max(), (joint, member, a.max(), b.max())


def test_explained_allows_round_off_and_no_more():
    """``accuracy.explained`` allows READ_NOISE (1e-7) for read-out round-off, not a share of rtol:
    a coarser correction that leaves 60 % of a 1e-4 change is not an explanation (rtol / 100 let
    a crank-rocker at rtol 1e-2 pass with half its change left)."""
    _levels_, obs = _levels(1e-4 / 240.0, 0.0, levels=(96, 192, 384), rate=4.0)
    coarse, fine = obs[0], obs[1]
    truth = _levels(0.0, 0.0, levels=(96,))[1][0]
    change = accuracy._peak_differences(fine, coarse).max()
    assert 5e-5 < change < 2e-4
    h = truth.deflection_history[0].copy()
    h[10] = fine.deflection_history[0][10] + 0.6 * (coarse.deflection_history[0][10] - fine.deflection_history[0][10])
    partly = dataclasses.replace(truth, deflection=np.array([h[10]]), deflection_history=(h,))
    ok, left = accuracy.explained(coarse, fine, partly)
    assert not ok and left == pytest.approx(0.6, rel=1e-6)
    assert accuracy.explained(coarse, fine, truth)[0]


def test_a_corrected_solution_holds_no_factorisations_and_refuses_other_systems():
    """``PeriodicProblem.corrected`` on a non-linear level (the four-bar's geometric non-linearity):
    it uses the tangent Newton's converged iteration kept, its result holds no factorisation once the
    problem releases its own (a review found every corrected level holding its LU factors), a failed
    iteration keeps none, and a solve of another system (another speed, the same elements) gets no
    correction."""
    import gc
    from kedfem.analysis import pipeline
    from kedfem.solvers.collocation import Resolver
    sc = _preset("four_bar")
    run = pipeline._Run(sc)
    _ti, prob = run.problem(48)
    failed = prob.solve(eps=1e-12, max_iter=1)
    assert not failed.converged and prob._kept is None
    out = prob.solve(eps=1e-8, max_iter=20)
    assert out.converged and prob._kept is not None
    out = dataclasses.replace(out, orbit=None)  # (a chord step's orbit keeps its tangent by design)
    y = prob.corrected(out.discrete)
    assert y is not None and y.resolver is None
    prob.release()
    gc.collect()
    assert not [o for o in gc.get_objects() if isinstance(o, Resolver)]
    u = out.discrete.at(np.linspace(0.0, sc.period, 50, endpoint=False))[0]
    assert 0 < np.abs(u - y.at(np.linspace(0.0, sc.period, 50, endpoint=False))[0]).max() < 5e-2 * np.abs(u).max()
    other = pipeline._Run(dataclasses.replace(sc, speed=1.1 * sc.mech.drives[0].speed))
    _t2, prob2 = other.problem(48)
    assert prob.corrected(prob2.solve(eps=1e-6, max_iter=20).discrete) is None
