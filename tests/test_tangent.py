"""Tangent (Newton) linearisation in the non-linear iteration, held per element."""

import math

import numpy as np
import pytest

from kedfem.solvers import nonlinear, periodic
from test_nonlinear import harmonic_balance_duffing  # tests/ is on sys.path under pytest


def tangent_duffing(k3):
    def terms(U, V):
        u = U[:, 0]
        return None, None, (3 * k3 * u**2)[:, None, None], (2 * k3 * u**3)[:, None]
    return terms


@pytest.mark.parametrize("hold", ["zoh", "foh", "magnus2"])
def test_tangent_duffing_converges_like_newton(hold):
    p = dict(m=1.0, c=0.2, k=1.0, k3=0.5, F=0.3, W=0.8)
    _, u_hb = harmonic_balance_duffing(**p)
    n = 512
    T = 2 * math.pi / p["W"]
    t = np.arange(n) * T / n
    Q = (p["F"] * np.cos(p["W"] * t))[:, None]
    res = nonlinear.solve(np.eye(1), np.eye(1) * p["c"], np.eye(1) * p["k"], Q, T, tangent_duffing(p["k3"]),
                          hold=hold, eps=1e-12, linearization="tangent", max_iter=20)
    assert res.converged and res.iterations <= 9
    h = np.asarray(res.history)
    # quadratic convergence: each change at most a modest power of the previous one
    assert h[3] < h[2] ** 1.5 and h[4] < h[3] ** 1.5
    err = np.abs(res.solution.U[::n // 64, 0] - u_hb).max() / np.abs(u_hb).max()
    order = 1 if hold == "zoh" else 2
    assert err < (1e-2 if order == 1 else 1e-5)


def test_held_terms_equal_plain_terms_for_zoh():
    rng = np.random.default_rng(3)
    n, N = 40, 3
    M = np.eye(N) * 2.0
    C = np.eye(N) * 0.3
    K = np.diag([4.0, 9.0, 16.0]) + 0.1
    Kz = 0.5 * np.abs(rng.normal(size=(n, N, N)))
    Kz = 0.5 * (Kz + np.swapaxes(Kz, 1, 2))
    Cz = 0.05 * np.abs(rng.normal(size=(n, N, N)))
    Qz = rng.normal(size=(n, N))
    Q = rng.normal(size=(n, N))
    a = periodic.solve(M, C, K, Q, 1.0, hold="zoh", Kz=Kz, Qz=Qz, Cz=Cz)
    b = periodic.solve(M[None] + 0 * Kz, C + Cz, K + Kz, Q + Qz, 1.0, hold="zoh")
    np.testing.assert_allclose(a.U, b.U, rtol=1e-12, atol=1e-14)
    # with foh the held load differs from an interpolated one
    c = periodic.solve(M, C, K, Q, 1.0, hold="foh", Qz=Qz)
    d = periodic.solve(M, C, K, Q + Qz, 1.0, hold="foh")
    assert np.max(np.abs(c.U - d.U)) > 1e-6
