"""Tests of kedfem.lab.transient (direct integration reference) against closed forms."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from kedfem.errors import ConvergenceWarning, InputError
from kedfem.lab.transient import integrate_periodic, integrate_sampled, sampled_system

M1, K1, ZETA1, T1 = 1.0, (2 * math.pi * 3) ** 2, 0.1, 1.0
C1 = 2 * ZETA1 * math.sqrt(K1 * M1)
W1 = 2 * math.pi / T1


def sdof(t):
    return np.eye(1) * M1, np.eye(1) * C1, np.eye(1) * K1, np.array([math.sin(W1 * t)])


def sdof_exact(t):
    X = 1.0 / (K1 - M1 * W1 ** 2 + 1j * C1 * W1)
    return np.imag(X * np.exp(1j * W1 * t)), np.imag(1j * W1 * X * np.exp(1j * W1 * t))


@pytest.mark.parametrize("method,tol", [("dop853", 1e-8), ("radau", 1e-6)])
def test_sdof_harmonic_vs_closed_form(method, tol):
    rtol = 1e-11 if method == "dop853" else 1e-8
    r = integrate_periodic(sdof, 1, T1, method, rtol=rtol, atol=1e-13, tol=1e-9, n_out=25)
    u, v = sdof_exact(r.t)
    assert r.converged and r.defect <= 1e-9 and r.cycles > 1
    assert np.abs(r.U[:, 0] - u).max() / np.abs(u).max() < tol
    assert np.abs(r.V[:, 0] - v).max() / np.abs(v).max() < tol
    assert r.method == method and r.nfev > 0


def test_newmark_second_order_vs_closed_form():
    errs = []
    for sub in (5, 10, 20):
        r = integrate_periodic(sdof, 1, T1, "newmark", n_out=20, steps_per_output=sub, tol=1e-10)
        u, _ = sdof_exact(r.t)
        errs.append(np.abs(r.U[:, 0] - u).max() / np.abs(u).max())
    order = -np.polyfit(np.log([5, 10, 20]), np.log(errs), 1)[0]
    assert 1.9 <= order <= 2.1
    # average acceleration: relative period error (omega h)^2 / 12
    assert errs[-1] < 2 * (2 * math.pi * 3 / (20 * 20)) ** 2


def test_mdof_time_invariant_vs_frequency_domain():
    N = 3
    K = np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]]) * 400.0
    M = np.diag([1.0, 2.0, 0.5])
    C = 0.02 * K + 2.0 * M
    T = 0.7
    W = 2 * math.pi / T
    F = np.array([1.0, -0.5, 2.0])
    X = np.linalg.solve(K - W ** 2 * M + 1j * W * C, F)
    r = integrate_periodic(lambda t: (M, C, K, F * math.cos(W * t)), N, T, "dop853",
                           rtol=1e-11, atol=1e-13, tol=1e-10, n_out=30)
    U = np.real(X[None, :] * np.exp(1j * W * r.t)[:, None])
    V = np.real(1j * W * X[None, :] * np.exp(1j * W * r.t)[:, None])
    assert np.linalg.norm(r.U - U) / np.linalg.norm(U) < 1e-8
    assert np.linalg.norm(r.V - V) / np.linalg.norm(V) < 1e-8


def test_not_periodic_after_max_cycles_warns():
    light = lambda t: (np.eye(1), np.eye(1) * 0.01, np.eye(1) * 100.0,  # noqa: E731
                       np.array([math.sin(2 * math.pi * t)]))
    with pytest.warns(ConvergenceWarning, match="not periodic"):
        r = integrate_periodic(light, 1, 1.0, "dop853", max_cycles=3, tol=1e-10, n_out=10)
    assert not r.converged and r.cycles == 3 and r.defect > 1e-10


def test_zero_response_is_periodic_immediately():
    zero = lambda t: (np.eye(2), np.eye(2), np.eye(2) * 10.0, np.zeros(2))  # noqa: E731
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = integrate_periodic(zero, 2, 1.0, "newmark", n_out=8)
    assert r.converged and r.cycles == 1 and r.defect == 0.0
    assert np.all(r.U == 0)


def test_sampled_system_interpolation():
    n, T = 16, 2.0
    t = np.arange(n) * T / n
    K = np.stack([np.eye(2) * (3 + math.cos(2 * math.pi * x / T)) for x in t])
    Q = np.stack([np.sin(2 * np.pi * t / T), np.cos(2 * np.pi * t / T)], axis=1)
    for kind in ("linear", "cubic"):
        sysf = sampled_system(np.eye(2), np.eye(2) * 0.1, K, Q, T, kind=kind)
        for k in (0, 5, 15):  # exact at the nodes, periodic
            M_, C_, K_, Q_ = sysf(t[k] + 3 * T)
            assert np.allclose(K_, K[k], atol=1e-12) and np.allclose(Q_, Q[k], atol=1e-12)
            assert np.array_equal(M_, np.eye(2)) and np.array_equal(C_, np.eye(2) * 0.1)
        tm = 0.37 * T
        err = abs(sysf(tm)[3][0] - math.sin(2 * math.pi * 0.37))
        assert err < (1e-4 if kind == "cubic" else 2e-2)
    with pytest.raises(InputError, match="kind"):
        sampled_system(np.eye(2), np.eye(2), K, Q, T, kind="quintic")


def test_transient_input_validation():
    with pytest.raises(InputError, match="radau, dop853, newmark"):
        integrate_periodic(sdof, 1, 1.0, "euler")
    with pytest.raises(InputError, match="period"):
        integrate_periodic(sdof, 1, -1.0)


def _sdof_samples(n):
    """SDOF terms sampled at t_k = k T1 / n: constant M, C, K (1, 1) and Q (n, 1)."""
    t = np.arange(n) * (T1 / n)
    return np.eye(1) * M1, np.eye(1) * C1, np.eye(1) * K1, np.sin(W1 * t)[:, None]


def _two_dof_samples(n, T=0.5):
    """Time-varying 2-DOF terms at t_k = k T / n: M, C, K (n, 2, 2), Q (n, 2)."""
    t = np.arange(n) * (T / n)
    s = np.sin(2 * math.pi * t / T)
    K = np.array([[300.0, -100.0], [-100.0, 200.0]]) * (1 + 0.1 * s)[:, None, None]
    M = np.broadcast_to(np.diag([1.0, 2.0]), (n, 2, 2)) * (1 + 0.05 * s**2)[:, None, None]
    C = np.broadcast_to(np.diag([2.0, 3.0]), (n, 2, 2)).copy()
    Q = np.stack([np.cos(2 * math.pi * t / T), 0.5 * s], axis=1)
    return M, C, K, Q, T


def test_sampled_newmark_equals_newmark_on_the_interpolated_system():
    n_out, sub = 10, 4
    M, C, K, Q, T = _two_dof_samples(n_out * sub)
    system = sampled_system(M, C, K, Q, T, kind="linear")  # exact at the steps
    a = integrate_periodic(system, 2, T, "newmark", n_out=n_out, steps_per_output=sub, tol=1e-11)
    b = integrate_sampled(M, C, K, Q, T, "newmark", n_out=n_out, tol=1e-11)
    assert a.converged and b.converged and a.cycles == b.cycles
    assert b.U.shape == b.V.shape == (n_out, 2) and np.allclose(b.t, a.t)
    assert np.abs(a.U - b.U).max() < 1e-12 * np.abs(a.U).max()
    assert np.abs(a.V - b.V).max() < 1e-12 * np.abs(a.V).max()
    assert (a.nfev, b.nfev, b.njev) == (n_out * sub + 1, n_out * sub, 0)


@pytest.mark.parametrize("method", ["radau", "dop853"])
def test_sampled_ivp_vs_closed_form(method):
    rtol = 1e-10 if method == "dop853" else 1e-8
    r = integrate_sampled(*_sdof_samples(128), T1, method, rtol=rtol, atol=1e-13, tol=1e-8, n_out=32)
    u, v = sdof_exact(r.t)
    assert r.converged and r.U.shape == (32, 1)
    # periodic cubic spline of sin on 128 nodes: relative error ~ (2 pi / 128)^4 / 384
    assert np.abs(r.U[:, 0] - u).max() / np.abs(u).max() < 2e-6
    assert np.abs(r.V[:, 0] - v).max() / np.abs(v).max() < 2e-6
    assert r.nfev > 0 and (r.njev > 0) == (method == "radau")


def test_monitor_stops_at_the_first_cycle_whose_history_repeats():
    M, C, K, Q, T = _two_dof_samples(64)
    def monitor(U):
        return U[:, 1]

    r = integrate_sampled(M, C, K, Q, T, "newmark", tol=1e-6, monitor=monitor, scale=1e-3)
    assert r.converged and r.cycles > 2 and r.defect <= 1e-6
    with pytest.warns(ConvergenceWarning, match="not periodic"):
        early = integrate_sampled(M, C, K, Q, T, "newmark", tol=1e-6, monitor=monitor, scale=1e-3,
                                  max_cycles=r.cycles - 1)
    assert not early.converged and early.defect > 1e-6
    # the state test at a tight tolerance agrees with the monitored run to about its tolerance
    s = integrate_sampled(M, C, K, Q, T, "newmark", tol=1e-12)
    assert np.abs(s.U[:, 1] - r.U[:, 1]).max() < 1e-5 * 1e-3
    with pytest.warns(ConvergenceWarning):
        one = integrate_sampled(M, C, K, Q, T, "newmark", monitor=monitor, max_cycles=1, tol=1.0)
    assert not one.converged and one.defect == math.inf  # no previous cycle to compare with


def test_sampled_input_validation():
    M, C, K, Q = _sdof_samples(10)
    with pytest.raises(InputError, match="multiple of n_out"):
        integrate_sampled(M, C, K, Q, T1, "newmark", n_out=3)
    with pytest.raises(InputError, match="K must have shape"):
        integrate_sampled(M, C, np.ones((9, 1, 1)), Q, T1)
    with pytest.raises(InputError, match="Q must have shape"):
        integrate_sampled(M, C, K, Q[:, 0], T1)
    with pytest.raises(InputError, match="radau, dop853, newmark"):
        integrate_sampled(M, C, K, Q, T1, "euler")
