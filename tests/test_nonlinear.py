"""Tests of kedfem.solvers.nonlinear: Duffing oscillators against harmonic balance."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.optimize import root

from kedfem.solvers import nonlinear
from kedfem.errors import ConvergenceWarning, InputError


def harmonic_balance_duffing(m, c, k, k3, F, W, Nt=64):
    """Periodic solution of m u'' + c u' + k u + k3 u^3 = F cos(W t) by spectral collocation.

    Nt equispaced collocation points, derivatives by FFT (exact for the
    trigonometric interpolant), Newton-type solve to 1e-14. Independent of kedfem.
    """
    T = 2 * math.pi / W
    t = np.arange(Nt) * T / Nt
    w = np.fft.fftfreq(Nt, d=T / Nt) * 2 * math.pi

    def deriv(u, p):
        return np.real(np.fft.ifft((1j * w) ** p * np.fft.fft(u)))

    f = F * np.cos(W * t)

    def residual(u):
        return m * deriv(u, 2) + c * deriv(u, 1) + k * u + k3 * u ** 3 - f

    u0 = np.real(F / (k - m * W ** 2 + 1j * c * W) * np.exp(1j * W * t))
    sol = root(residual, u0, method="hybr", tol=1e-14)
    assert np.abs(residual(sol.x)).max() < 1e-10
    return t, sol.x


def duffing_problem(m, c, k, k3, F, W, n):
    T = 2 * math.pi / W
    t = np.arange(n) * T / n
    Q = (F * np.cos(W * t))[:, None]

    def cubic_spring(U, V):  # secant stiffness: k3 u^2 * u = k3 u^3
        return None, None, (k3 * U[:, 0] ** 2)[:, None, None], None
    return np.eye(1) * m, np.eye(1) * c, np.eye(1) * k, Q, T, cubic_spring


@pytest.mark.parametrize("method", ["fixed-point", "relaxation", "anderson"])
def test_duffing_below_jump_vs_harmonic_balance(method):
    p = dict(m=1.0, c=0.2, k=1.0, k3=0.5, F=0.3, W=0.8)
    _, u_hb = harmonic_balance_duffing(**p)
    n = 512
    M, C, K, Q, T, terms = duffing_problem(**p, n=n)
    res = nonlinear.solve(M, C, K, Q, T, terms, hold="magnus2", method=method, eps=1e-10)
    assert res.converged and res.iterations == len(res.history)
    assert res.history[-1] <= 1e-10
    err = np.abs(res.solution.U[::n // 64, 0] - u_hb).max() / np.abs(u_hb).max()
    assert err < 2e-5  # magnus2 discretization error at n = 512 (second order)
    # the non-linearity matters: the linear response differs by far more
    lin = nonlinear.solve(M, C, K, Q, T, lambda U, V: (None,) * 4, hold="magnus2")
    assert np.abs(lin.solution.U[::n // 64, 0] - u_hb).max() / np.abs(u_hb).max() > 1e-2


def test_anderson_converges_where_fixed_point_stalls():
    p = dict(m=1.0, c=1.0, k=1.0, k3=2.0, F=2.0, W=0.3)  # k3 u^2 ~ 1.5 k at the peaks
    _, u_hb = harmonic_balance_duffing(**p)
    n = 512
    M, C, K, Q, T, terms = duffing_problem(**p, n=n)
    with pytest.warns(ConvergenceWarning, match="fixed-point"):
        fp = nonlinear.solve(M, C, K, Q, T, terms, hold="magnus2", method="fixed-point",
                             eps=1e-8, max_iter=40)
    assert not fp.converged and fp.iterations == 40 and len(fp.history) == 40
    assert min(fp.history[-10:]) > 1e-2            # it oscillates, it does not converge
    aa = nonlinear.solve(M, C, K, Q, T, terms, hold="magnus2", method="anderson", eps=1e-8,
                         max_iter=40)
    assert aa.converged and aa.iterations < 30
    assert aa.history[-1] < 1e-3 * aa.history[0]
    # monotone-ish: every later window of 5 reaches a new low
    lows = [min(aa.history[:i + 5]) for i in range(0, len(aa.history) - 5, 5)]
    assert all(b < a for a, b in zip(lows, lows[1:]))
    err = np.abs(aa.solution.U[::n // 64, 0] - u_hb).max() / np.abs(u_hb).max()
    assert err < 1e-3


def test_zero_response_converges_without_division_by_zero():
    M, C, K, Q, T, terms = duffing_problem(1.0, 0.2, 1.0, 0.5, 0.0, 0.8, n=32)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = nonlinear.solve(M, C, K, Q, T, terms)
    assert res.converged and res.iterations == 1
    assert res.history.tolist() == [0.0]
    assert np.all(res.solution.U == 0)


def test_not_converged_reports_last_iterate_and_history():
    M, C, K, Q, T, terms = duffing_problem(1.0, 0.2, 1.0, 0.5, 0.3, 0.8, n=64)
    with pytest.warns(ConvergenceWarning, match="not converged after 3"):
        res = nonlinear.solve(M, C, K, Q, T, terms, eps=1e-12, max_iter=3)
    assert not res.converged and res.iterations == 3 and res.history.shape == (3,)
    assert res.solution.U.shape == (64, 1) and "not converged" in res.message


def test_divergence_is_detected():
    M, C, K, Q, T, _ = duffing_problem(1.0, 0.2, 1.0, 0.0, 0.3, 0.8, n=64)

    def runaway(U, V):  # a load growing with the response: G(x) ~ 100 x
        return None, None, None, 100.0 * np.abs(U) + 1e-3
    with pytest.warns(ConvergenceWarning, match="diverging"):
        res = nonlinear.solve(M, C, K, Q, T, runaway, max_iter=50)
    assert not res.converged and res.iterations < 50


def test_nonlinear_input_validation():
    M, C, K, Q, T, terms = duffing_problem(1.0, 0.2, 1.0, 0.5, 0.3, 0.8, n=16)
    with pytest.raises(InputError, match="newton, fixed-point, relaxation, anderson"):
        nonlinear.solve(M, C, K, Q, T, terms, method="bisection")
    with pytest.raises(InputError, match="dK with shape"):
        nonlinear.solve(M, C, K, Q, T, lambda U, V: (None, None, np.ones((3, 1, 1)), None))
    with pytest.raises(InputError, match="non-finite dQ"):
        nonlinear.solve(M, C, K, Q, T, lambda U, V: (None, None, None, U * np.nan))
    with pytest.raises(InputError, match="relaxation"):
        nonlinear.solve(M, C, K, Q, T, terms, method="relaxation", relaxation=1.5)


def _toy(contract):
    """A fixed-point map on 4 instants x 2 DOFs with a known solution, contracting by
    ``contract(e)`` (the error after a step, given the error before), and its residual norm."""
    rng = np.random.default_rng(7)
    Us, Vs = rng.standard_normal((4, 2)), rng.standard_normal((4, 2))

    def G(U, V, it):
        Un, Vn = Us + contract(U - Us), Vs + contract(V - Vs)
        return Un, Un, Vn  # the "solution" is the new displacements

    def merit(U, V):
        return float(np.linalg.norm(U - Us) + np.linalg.norm(V - Vs))

    start = (Us * (1 + 1e-4), Vs * (1 + 1e-4))
    return G, merit, start, Us


def test_newton_stops_on_a_predicted_change_only_where_the_residual_bears_it_out():
    """A coarser level's quadratic rate predicts the first change's successor far below eps. A map
    that converges quadratically stops after that one solve; one that only halves its error (a
    resonance the coarser level did not resolve) goes on to eps instead of stopping 65x off."""
    prior = nonlinear.NewtonRate(constant=0.36, ratio=1e-3)
    G, merit, start, Us = _toy(lambda e: 50.0 * e * np.abs(e))
    quick = nonlinear.newton(G, 4, 2, 1.0, eps=1e-6, x0=start, merit=merit, rate=prior)
    assert quick.converged and len(quick.history) == 1 and quick.predicted is not None
    off = np.linalg.norm(quick.solution - Us) / np.linalg.norm(Us)
    # within the slack the residual check allows on the prediction, and within eps
    assert off <= nonlinear.PREDICT_SLACK * quick.predicted and off <= 1e-6, (off, quick.predicted)
    G, merit, start, Us = _toy(lambda e: 0.5 * e)
    slow = nonlinear.newton(G, 4, 2, 1.0, eps=1e-6, x0=start, merit=merit, rate=prior)
    assert slow.converged and len(slow.history) > 3
    assert np.linalg.norm(slow.solution - Us) / np.linalg.norm(Us) <= 1e-6
    without_merit = nonlinear.newton(G, 4, 2, 1.0, eps=1e-6, x0=start, rate=prior)
    assert len(without_merit.history) > 3


def _rotating(theta, scale=1.0):
    """A map whose correction turns the error by ``theta`` in each DOF pair (scaled by ``scale``):
    a full step never gets nearer, and the residual falls along it by a factor per line-search
    step that shrinks with ``theta`` (creeping for a small one)."""
    rng = np.random.default_rng(3)
    Us, Vs = rng.standard_normal((4, 2)), rng.standard_normal((4, 2))
    c, s_ = math.cos(theta), math.sin(theta)
    R = scale * np.array([[c, -s_], [s_, c]])

    def G(U, V, it):
        Un, Vn = Us + (U - Us) @ R.T, Vs + (V - Vs) @ R.T
        return Un, Un, Vn

    def merit(U, V):
        return float(np.linalg.norm(U - Us) + np.linalg.norm(V - Vs))

    return G, merit, (Us + 0.01, Vs + 0.01), Us


def test_newton_stops_when_its_line_search_creeps_and_not_while_it_gains():
    """A line search that lowers the residual by about 1 % per solve (the corrections stay the size
    they were) is named stalled after STALL_STEPS of them, not run to max_iter; one that gains a
    quarter per solve goes on to converge."""
    G, merit, start, Us = _rotating(0.3)
    with pytest.warns(ConvergenceWarning, match="stalled"):
        out = nonlinear.newton(G, 4, 2, 1.0, eps=1e-6, x0=start, merit=merit, max_iter=50)
    assert not out.converged and "stalled" in out.message
    assert len(out.history) <= nonlinear.WATCHDOG + nonlinear.STALL_STEPS + 2, len(out.history)
    G, merit, start, Us = _rotating(1.5)
    out = nonlinear.newton(G, 4, 2, 1.0, eps=1e-6, x0=start, merit=merit, max_iter=50)
    assert out.converged, out.message
    assert np.linalg.norm(out.solution - Us) / np.linalg.norm(Us) <= 1e-5


def test_newton_full_steps_never_stall():
    """Full steps may raise the change on the way to the solution (``sinh(u - 1) = 0`` from 20:
    the change falls slowly, then rises before it converges); only damped steps can stall."""
    def G(U, V, it):
        Un = U - np.tanh(U - 1.0)  # Newton's step on sinh(u - 1) = 0: u - sinh / cosh
        return Un, Un, V

    def merit(U, V):
        return float(np.abs(np.sinh(U - 1.0)).sum())

    start = (np.full((4, 2), 20.0), np.zeros((4, 2)))
    out = nonlinear.newton(G, 4, 2, 1.0, eps=1e-8, x0=start, merit=merit, max_iter=60)
    assert out.converged, out.message
    assert np.allclose(out.solution, 1.0, atol=1e-6)


def test_newton_tries_its_own_direction_where_a_chord_steps_direction_does_not_lower_the_residual():
    """A chord step (a tangent frozen at another iterate) need not point downhill: the line search
    found no decrease along one and Newton gave up (a Watt six-bar by a resonance, at a change of
    1.2e-3 after 43 solves, then ran up in speed: 13.7 s where Newton's own step converges in 3 s).
    Here the frozen tangent points away from the solution: given ``unfreeze``, Newton's own
    direction is tried and converges; without it the iteration fails as before."""
    rng = np.random.default_rng(3)
    Us, Vs = rng.standard_normal((4, 2)), rng.standard_normal((4, 2))

    class Step:
        def __init__(self, chord):
            self.chord = chord

    state = {"frozen": True, "unfrozen": 0}

    def G(U, V, it):
        if state["frozen"]:  # a chord step whose direction doubles the error
            return Step(True), U + (U - Us), V + (V - Vs)
        return Step(False), Us.copy(), Vs.copy()  # Newton's step on this linear problem: exact

    def merit(U, V):
        return float(np.linalg.norm(U - Us) + np.linalg.norm(V - Vs))

    def unfreeze():
        state["frozen"] = False
        state["unfrozen"] += 1

    start = (Us + 0.01, Vs + 0.01)
    with pytest.warns(ConvergenceWarning, match="line search found no step"):
        stuck = nonlinear.newton(G, 4, 2, 1.0, eps=1e-9, x0=start, merit=merit)
    assert not stuck.converged
    out = nonlinear.newton(G, 4, 2, 1.0, eps=1e-9, x0=start, merit=merit, unfreeze=unfreeze)
    assert out.converged and state["unfrozen"] == 1
    assert out.solution.chord is False and len(out.history) <= 15
