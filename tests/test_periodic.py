"""Tests of kedfem.solvers.periodic against independent truth.

References: exact periodic solutions in closed form (harmonic: complex amplitude;
square wave: piecewise exact solution with periodic matching), the exact
frequency-domain solution of a multi-DOF system, direct time integration with
scipy.integrate (cycle by cycle until periodic), the monodromy matrix integrated
column by column with solve_ivp, and the same discretization computed
independently (scipy.linalg.expm per element on the augmented matrix, dense
numpy solve of the whole cyclic system).
"""

from __future__ import annotations

import dataclasses
import math
import tracemalloc
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from kedfem.solvers import periodic
from kedfem.errors import InputError, InstabilityWarning, ResonanceError, SingularMassError
from reference import augmented_transition


def rel(a, b):
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b))


def slope(ns, errs):
    """Observed convergence order: minus the log-log slope of error versus n."""
    return -float(np.polyfit(np.log(ns), np.log(errs), 1)[0])


def independent_discrete(M, C, K, Q, T, hold):
    """Same discretization, computed independently: scipy expm per element + dense solve."""
    n, N = Q.shape
    m = 2 * N
    dt = T / n

    def at(X, k):
        return X[k % n] if X.ndim == 3 else X

    def state(k):
        Mi = np.linalg.inv(at(M, k))
        F = np.block([[np.zeros((N, N)), np.eye(N)], [-Mi @ at(K, k), -Mi @ at(C, k)]])
        return F, np.concatenate([np.zeros(N), Mi @ Q[k % n]])

    def mean_state(k):
        """magnus2: F of the element-mean M, C, K; forcing at both ends with the mean M."""
        Mm, Cm, Km = (0.5 * (at(X, k) + at(X, k + 1)) for X in (M, C, K))
        Mi = np.linalg.inv(Mm)
        F = np.block([[np.zeros((N, N)), np.eye(N)], [-Mi @ Km, -Mi @ Cm]])
        z = np.zeros(N)
        return F, np.concatenate([z, Mi @ Q[k % n]]), np.concatenate([z, Mi @ Q[(k + 1) % n]])

    big = np.zeros((n * m, n * m))
    rhs = np.zeros(n * m)
    for k in range(n):
        F0, g0 = state(k)
        F1, g1 = state(k + 1)
        if hold == "magnus2":
            F0, g0, g1 = mean_state(k)
        Ak, bk = augmented_transition(F0, dt, g0, None if hold == "zoh" else g1)
        big[k * m:(k + 1) * m, k * m:(k + 1) * m] = Ak
        kk = (k + 1) % n
        big[k * m:(k + 1) * m, kk * m:(kk + 1) * m] -= np.eye(m)
        rhs[k * m:(k + 1) * m] = -bk
    z = np.linalg.solve(big, rhs).reshape(n, m)
    return z[:, :N], z[:, N:]


def state_error(sol, U, V, T):
    """Relative error of the state; velocities on the scale (2 pi / T) |U| + |V|."""
    vscale = np.linalg.norm(V) + 2 * math.pi / T * np.linalg.norm(U)
    return max(rel(sol.U, U), float(np.linalg.norm(sol.V - V)) / vscale)


# ------------------------------------------------------------------ SDOF exact
SD_M, SD_K, SD_ZETA, SD_T, SD_F0 = 2.0, 2.0 * (2 * math.pi * 1.7) ** 2, 0.05, 1.0, 3.0
SD_C = 2 * SD_ZETA * math.sqrt(SD_K * SD_M)
SD_W = 2 * math.pi / SD_T


def harmonic_exact(t):
    X = SD_F0 / (SD_K - SD_M * SD_W ** 2 + 1j * SD_C * SD_W)
    return np.real(X * np.exp(1j * SD_W * t)), np.real(1j * SD_W * X * np.exp(1j * SD_W * t))


def square_force(t, t_up=0.25):
    """+F0 for t in [-T/4, T/4), -F0 for t in [T/4, 3T/4) (mod T), jumps at T/4, 3T/4."""
    return np.where(((t - t_up * SD_T) % SD_T) < SD_T / 2, -SD_F0, SD_F0)


def square_exact(t):
    """Piecewise exact underdamped solution with periodic matching."""
    wn = math.sqrt(SD_K / SD_M)
    z = SD_C / (2 * SD_M * wn)
    wd = wn * math.sqrt(1 - z * z)

    def Phi(s):
        e, c, sn = math.exp(-z * wn * s), math.cos(wd * s), math.sin(wd * s)
        return np.array([[e * (c + z * wn / wd * sn), e * sn / wd],
                         [-e * wn ** 2 / wd * sn, e * (c - z * wn / wd * sn)]])

    Ph = Phi(SD_T / 2)
    p1 = np.array([-SD_F0 / SD_K, 0.0])  # static state under -F0 (half starting at T/4)
    p2 = -p1
    z0 = np.linalg.solve(np.eye(2) - Ph @ Ph, -Ph @ Ph @ p1 + Ph @ (p1 - p2) + p2)  # at T/4
    z1 = Ph @ (z0 - p1) + p1                                                        # at 3T/4
    out = []
    for tt in np.atleast_1d(t):
        s = (tt - SD_T / 4) % SD_T
        out.append(Phi(s) @ (z0 - p1) + p1 if s < SD_T / 2 else Phi(s - SD_T / 2) @ (z1 - p2) + p2)
    out = np.array(out)
    return out[:, 0], out[:, 1]


def sdof_errors(force, exact, hold, ns):
    errs = []
    for n in ns:
        t = np.arange(n) * SD_T / n
        sol = periodic.solve(np.eye(1) * SD_M, np.eye(1) * SD_C, np.eye(1) * SD_K,
                             force(t)[:, None], SD_T, hold=hold)
        u, _ = exact(t)
        errs.append(float(np.abs(sol.U[:, 0] - u).max() / np.abs(u).max()))
    return errs


NS = [34, 66, 130, 258, 514]  # n = 2 mod 4: square-wave jumps fall at element midpoints


@pytest.mark.parametrize("hold,lo,hi", [("zoh", 0.9, 1.1), ("foh", 1.8, 2.2), ("magnus2", 1.8, 2.2)])
def test_sdof_harmonic_convergence_order(hold, lo, hi):
    errs = sdof_errors(lambda t: SD_F0 * np.cos(SD_W * t), harmonic_exact, hold, NS)
    assert lo <= slope(NS, errs) <= hi
    assert errs[-1] < (2e-2 if hold == "zoh" else 5e-5)


@pytest.mark.parametrize("hold,lo,hi", [("zoh", 0.9, 1.1), ("foh", 1.8, 2.2)])
def test_sdof_square_wave_convergence_order(hold, lo, hi):
    """Jumps at element midpoints: the linear hold's error integrates to zero there."""
    errs = sdof_errors(square_force, square_exact, hold, NS)
    assert lo <= slope(NS, errs) <= hi
    assert errs[-1] < (2e-2 if hold == "zoh" else 5e-5)


def test_sdof_square_wave_zoh_exact_when_jumps_on_nodes():
    """Piecewise-constant forcing switching at nodes: zero-order hold is exact."""
    n = 64  # T/4 and 3T/4 are nodes; sampled values are the right-continuous ones
    t = np.arange(n) * SD_T / n
    sol = periodic.solve(np.eye(1) * SD_M, np.eye(1) * SD_C, np.eye(1) * SD_K,
                         square_force(t)[:, None], SD_T, hold="zoh", delta=1e-15)
    u, v = square_exact(t)
    assert np.abs(sol.U[:, 0] - u).max() / np.abs(u).max() < 1e-12
    assert np.abs(sol.V[:, 0] - v).max() / np.abs(v).max() < 1e-12


# ----------------------------------------------------- MDOF frequency domain
def mdof_system():
    rng = np.random.default_rng(3)
    N = 5
    K = (np.diag(np.full(N, 2.0)) - np.diag(np.ones(N - 1), 1) - np.diag(np.ones(N - 1), -1)) * 4e3
    M = np.diag(rng.uniform(0.5, 2.0, N))
    C = np.diag(rng.uniform(0.5, 3.0, N))
    C[0, 1] = C[1, 0] = -0.3  # non-proportional damping
    return M, C, K, rng.standard_normal(N)


def test_mdof_time_invariant_vs_frequency_domain():
    M, C, K, Fv = mdof_system()
    T = 0.5
    W = 2 * math.pi / T
    X = np.linalg.solve(K - W ** 2 * M + 1j * W * C, Fv)  # exact complex amplitudes
    errs, ns = [], [50, 100, 200, 400]
    for n in ns + [2 ** 18]:
        t = np.arange(n) * T / n
        Q = np.real(Fv[None, :] * np.exp(1j * W * t)[:, None])
        sol = periodic.solve(M, C, K, Q, T, hold="foh")
        errs.append(rel(sol.U, np.real(X[None, :] * np.exp(1j * W * t)[:, None])))
    assert 1.95 <= slope(ns, errs[:4]) <= 2.05    # order-consistent error at coarse n
    assert errs[-1] < 1e-10                        # and 1e-10 at fine n
    assert sol.n_exponentials == 1                 # time-invariant: one exponential


def test_time_invariant_path_equals_time_varying_path():
    M, C, K, Fv = mdof_system()
    n, T = 40, 0.5
    t = np.arange(n) * T / n
    Q = np.outer(np.sin(2 * math.pi * t / T), Fv)
    for hold in periodic.HOLDS:
        a = periodic.solve(M, C, K, Q, T, hold=hold, delta=1e-15)
        b = periodic.solve(np.broadcast_to(M, (n, 5, 5)), C, np.broadcast_to(K, (n, 5, 5)), Q,
                           T, hold=hold, delta=1e-15)
        assert a.n_exponentials == 1 and b.n_exponentials == n
        assert rel(a.U, b.U) < 1e-12 and rel(a.V, b.V) < 1e-12
        assert np.allclose(a.monodromy, b.monodromy, rtol=0, atol=1e-12)


# ------------------------------------------- time-varying vs direct integration
TV_T = 0.2
TV_M0 = np.diag([1.0, 0.5])
TV_K0 = np.array([[3000.0, -1000.0], [-1000.0, 1000.0]])
TV_C = 0.004 * TV_K0 + 2.0 * TV_M0


def tv_M(t):
    return TV_M0 * (1 + 0.1 * np.sin(2 * np.pi * t / TV_T))


def tv_K(t):
    return TV_K0 * (1 + 0.25 * np.cos(2 * np.pi * t / TV_T))


def tv_Q(t):
    return np.array([10 * np.sin(2 * np.pi * t / TV_T), 5 * np.cos(4 * np.pi * t / TV_T)])


def tv_sampled(n):
    t = np.arange(n) * TV_T / n
    return (np.stack([tv_M(x) for x in t]), TV_C, np.stack([tv_K(x) for x in t]),
            np.stack([tv_Q(x) for x in t]))


def test_time_varying_vs_direct_integration():
    """magnus2 at n = 3200 against DOP853 (rtol 1e-12) integrated until periodic."""
    def rhs(t, y):
        u, v = y[:2], y[2:]
        return np.concatenate([v, np.linalg.solve(tv_M(t), tv_Q(t) - TV_C @ v - tv_K(t) @ u)])

    n_out = 40
    t_out = np.arange(n_out + 1) * TV_T / n_out
    z = np.zeros(4)
    for _ in range(200):
        r = solve_ivp(rhs, (0, TV_T), z, method="DOP853", t_eval=t_out, rtol=1e-12, atol=1e-14)
        z_new = r.y[:, -1]
        done = np.abs(z_new - z).max() <= 1e-11 * np.abs(r.y).max()
        z = z_new
        if done:
            break
    assert done
    U_ref, V_ref = r.y[:2, :-1].T, r.y[2:, :-1].T
    sol = periodic.solve(*tv_sampled(3200), TV_T, hold="magnus2")
    assert sol.stable and sol.method == "condensation"
    assert rel(sol.U[::80], U_ref) < 1e-6
    assert rel(sol.V[::80], V_ref) < 1e-6


def test_floquet_multipliers_vs_integrated_monodromy():
    def hom(t, y):
        Y = y.reshape(4, 4)
        Mi = np.linalg.inv(tv_M(t))
        F = np.block([[np.zeros((2, 2)), np.eye(2)], [-Mi @ tv_K(t), -Mi @ TV_C]])
        return (F @ Y).ravel()

    r = solve_ivp(hom, (0, TV_T), np.eye(4).ravel(), method="DOP853", rtol=1e-13, atol=1e-15)
    Phi = r.y[:, -1].reshape(4, 4)
    mu_ref = np.linalg.eigvals(Phi)
    sol = periodic.solve(*tv_sampled(12800), TV_T, hold="magnus2")
    assert np.allclose(sol.floquet_multipliers, np.linalg.eigvals(sol.monodromy)[
        np.argsort(-np.abs(np.linalg.eigvals(sol.monodromy)), kind="stable")])
    err = max(np.abs(sol.floquet_multipliers - m).min() for m in mu_ref)
    assert err < 1e-8
    assert rel(sol.monodromy, Phi) < 1e-6
    assert sol.stable == bool(np.abs(mu_ref).max() < 1)


def test_magnus2_second_order_for_time_varying_stiffness():
    """Damped, forced, stable Mathieu equation: magnus2 order 2, foh only order 1."""
    a, q, c, T = 2.0, 0.4, 0.3, math.pi

    def rhs(t, y):
        return [y[1], math.cos(2 * t) + 0.5 - c * y[1] - (a - 2 * q * math.cos(2 * t)) * y[0]]

    n_ref = 64
    t_ref = np.arange(n_ref + 1) * T / n_ref
    z = np.zeros(2)
    for _ in range(300):
        r = solve_ivp(rhs, (0, T), z, method="DOP853", t_eval=t_ref, rtol=1e-12, atol=1e-14)
        done = np.abs(r.y[:, -1] - z).max() <= 1e-12 * np.abs(r.y).max()
        z = r.y[:, -1]
        if done:
            break
    assert done
    u_ref = r.y[0, :-1]
    ns = [64, 128, 256, 512]
    errs = {"magnus2": [], "foh": []}
    for n in ns:
        t = np.arange(n) * T / n
        K = (a - 2 * q * np.cos(2 * t))[:, None, None]
        Q = (np.cos(2 * t) + 0.5)[:, None]
        for hold in errs:
            sol = periodic.solve(np.eye(1), np.eye(1) * c, K, Q, T, hold=hold)
            assert sol.stable
            errs[hold].append(rel(sol.U[::n // n_ref, 0], u_ref))
    assert 1.8 <= slope(ns, errs["magnus2"]) <= 2.2
    assert 0.9 <= slope(ns, errs["foh"]) <= 1.1
    assert errs["magnus2"][-1] < 1e-4


# -------------------------------------------------------------- hard cases
def test_undamped_resonance_raises():
    n, T = 64, 1.0
    w = 2 * (2 * math.pi / T)  # second harmonic of the period
    t = np.arange(n) * T / n
    with pytest.raises(ResonanceError) as info:
        periodic.solve(np.eye(1), np.zeros((1, 1)), np.eye(1) * w ** 2,
                       np.sin(w * t)[:, None], T, hold="foh")
    err = info.value
    assert abs(err.multiplier - 1) < 1e-6
    assert err.condition > periodic.MAX_CONDITION
    assert "multiplier" in str(err) and "condition" in str(err)


def test_free_rigid_body_mode_raises():
    n, T = 50, 1.0
    t = np.arange(n) * T / n
    K = np.array([[1.0, -1.0], [-1.0, 1.0]]) * 100.0  # singular: free translation
    Q = np.stack([np.sin(2 * math.pi * t), np.zeros(n)], axis=1)
    for C in (np.zeros((2, 2)), 0.01 * K):  # also with damping that does not hold it
        with pytest.raises(ResonanceError) as info:
            periodic.solve(np.eye(2), C, K, Q, T, hold="foh")
        assert abs(info.value.multiplier - 1) < 1e-6
        assert info.value.condition > 1e12


def test_light_damping_at_resonance_is_solved_not_rejected():
    """zeta = 1e-6 exactly at resonance: ill-conditioned (~1e5) but well defined."""
    n, T, zeta = 256, 1.0, 1e-6
    w = 2 * math.pi / T
    t = np.arange(n) * T / n
    sol = periodic.solve(np.eye(1), np.eye(1) * 2 * zeta * w, np.eye(1) * w ** 2,
                         np.sin(w * t)[:, None], T, hold="foh")
    U, V = independent_discrete(np.eye(1), np.eye(1) * 2 * zeta * w, np.eye(1) * w ** 2,
                                np.sin(w * t)[:, None], T, "foh")
    assert 1e4 < sol.condition < 1e7
    assert state_error(sol, U, V, T) < 1e-8
    # amplitude 1 / (2 zeta w^2) up to the O(dt^2) discretization error
    assert np.abs(sol.U).max() == pytest.approx(1 / (2 * zeta * w ** 2), rel=1e-3)


def mathieu(a, q, c, n, force=True):
    T = math.pi
    t = np.arange(n) * T / n
    K = (a - 2 * q * np.cos(2 * t))[:, None, None]
    Q = (np.cos(2 * t) + 0.3 * np.sin(4 * t))[:, None] if force else np.zeros((n, 1))
    return np.eye(1), np.eye(1) * c, K, Q, T


@pytest.mark.parametrize("a,q,c", [(1.0, 0.3, 0.02), (1.0, 150.0, 0.0)])
def test_parametric_instability_solved_by_cyclic_lu(a, q, c):
    """First Mathieu tongue (|mu| ~ 1.5) and a violent one (|mu| ~ 1e9)."""
    M, C, K, Q, T = mathieu(a, q, c, 400)
    with pytest.warns(InstabilityWarning, match="multiplier"):
        sol = periodic.solve(M, C, K, Q, T, hold="magnus2")
    assert sol.method == "cyclic-lu" and not sol.stable
    assert np.abs(sol.floquet_multipliers).max() > 1.2
    assert sol.residual <= 1e-10
    U, V = independent_discrete(M, C, K, Q, T, "magnus2")
    assert state_error(sol, U, V, T) < 1e-8
    # streamed: segments of the cyclic system, states propagated inside them
    with pytest.warns(InstabilityWarning):
        sol_s = periodic.solve(M, C, K, Q, T, hold="magnus2", memory_budget=2e4)
    assert sol_s.passes == 2 and sol_s.residual <= 1e-10
    assert state_error(sol_s, U, V, T) < 1e-8


def test_condensation_alone_degrades_when_strongly_unstable():
    """Why the fallback exists: forward propagation amplifies by |mu| ~ 1e9."""
    M, C, K, Q, T = mathieu(1.0, 150.0, 0.0, 400)
    with pytest.warns(InstabilityWarning):
        lu = periodic.solve(M, C, K, Q, T, hold="magnus2")
        cond = periodic.solve(M, C, K, Q, T, hold="magnus2", method="condensation")
    assert cond.residual > 1e3 * lu.residual


def chain_system(N, n, wdt, zeta, T=1.0):
    """Chain with omega_max dt = wdt, damping ratio zeta at the lowest and highest modes."""
    dt = T / n
    w = wdt / dt
    k = (w / 2) ** 2
    K0 = (np.diag(np.full(N, 2.0)) - np.diag(np.ones(N - 1), 1) - np.diag(np.ones(N - 1), -1)) * k
    K0[-1, -1] = k
    M = np.eye(N)
    wn = np.sqrt(np.linalg.eigvalsh(K0))
    beta = 2 * zeta / (wn[0] + wn[-1])
    C = beta * wn[0] * wn[-1] * M + beta * K0
    t = np.arange(n) * dt
    K = K0[None] * (1 + 0.2 * np.cos(2 * np.pi * t / T))[:, None, None]
    Q = np.zeros((n, N))
    Q[:, 0] = k * (np.sin(2 * np.pi * t / T) + 0.5 * np.cos(6 * np.pi * t / T))
    return M, C, K, Q, T


@pytest.mark.parametrize("wdt", [1e-3, 1e-1, 10.0, 1e3, 1e4])
@pytest.mark.parametrize("zeta", [1e-6, 0.05])
def test_stiff_and_lightly_damped_vs_independent_discretization(wdt, zeta):
    M, C, K, Q, T = chain_system(3, 24, wdt, zeta)
    for hold in ("zoh", "magnus2"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", InstabilityWarning)  # coarse zoh may pump energy
            sol = periodic.solve(M, C, K, Q, T, hold=hold)
        U, V = independent_discrete(M, C, K, Q, T, hold)
        assert state_error(sol, U, V, T) < 1e-8, hold


def test_singular_mass_names_dofs_and_node():
    n = 10
    M = np.eye(3)
    M[1, 1] = 0.0
    with pytest.raises(SingularMassError, match=r"DOFs: \[1\]"):
        periodic.solve(M, np.eye(3), np.eye(3) * 10, np.ones((n, 3)), 1.0)
    M = np.eye(3)
    M[2, 2] = -1.0
    with pytest.raises(SingularMassError, match=r"indefinite.*DOFs: \[2\]"):
        periodic.solve(M, np.eye(3), np.eye(3) * 10, np.ones((n, 3)), 1.0)
    Mt = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    Mt[6, 0, 0] = 0.0  # massless at one time node only
    with pytest.raises(SingularMassError, match=r"time node 6.*DOFs: \[0\]"):
        periodic.solve(Mt, np.eye(3), np.eye(3) * 10, np.ones((n, 3)), 1.0, hold="foh")


@pytest.mark.parametrize("arg", ["M", "C", "K", "Q"])
def test_non_finite_input_rejected_before_work(arg):
    n = 12
    data = {"M": np.broadcast_to(np.eye(2), (n, 2, 2)).copy(),
            "C": np.broadcast_to(np.eye(2), (n, 2, 2)).copy(),
            "K": np.broadcast_to(np.eye(2) * 50, (n, 2, 2)).copy(), "Q": np.ones((n, 2))}
    bad = data[arg]
    bad[(5,) + (1,) * (bad.ndim - 1)] = np.inf if arg != "Q" else np.nan
    with pytest.raises(InputError, match=rf"^{arg} has a non-finite value at index \(5, 1"):
        periodic.solve(data["M"], data["C"], data["K"], data["Q"], 1.0)


def test_callable_returning_non_finite_names_node():
    def K(idx):
        out = np.broadcast_to(np.eye(2) * 50.0, (len(idx), 2, 2)).copy()
        out[idx == 7] = np.nan
        return out
    with pytest.raises(InputError, match="K has a non-finite value at time node 7"):
        periodic.solve(np.eye(2), np.eye(2), K, np.ones((12, 2)), 1.0)
    with pytest.raises(InputError, match="must return shape"):
        periodic.solve(np.eye(2), np.eye(2), lambda i: np.eye(2), np.ones((12, 2)), 1.0)


def test_input_validation_messages():
    M, C, K = np.eye(2), np.eye(2), np.eye(2) * 10
    Q = np.ones((8, 2))
    with pytest.raises(InputError, match="at least 3"):
        periodic.solve(M, C, K, np.ones((2, 2)), 1.0)
    for T in (0.0, -1.0, float("inf"), float("nan"), "abc"):
        with pytest.raises(InputError, match="period"):
            periodic.solve(M, C, K, Q, T)
    with pytest.raises(InputError, match="zoh, foh, magnus2"):
        periodic.solve(M, C, K, Q, 1.0, hold="rk4")
    with pytest.raises(InputError, match="inconsistent numbers of time nodes"):
        periodic.solve(M, C, np.broadcast_to(K, (9, 2, 2)), Q, 1.0)
    with pytest.raises(InputError, match="inconsistent numbers of DOFs"):
        periodic.solve(np.eye(3), C, K, Q, 1.0)
    with pytest.raises(InputError, match="shape"):
        periodic.solve(M, C, K, np.ones(8), 1.0)
    with pytest.raises(InputError, match="pass n="):
        periodic.solve(M, C, K, lambda i: np.ones((len(i), 2)), 1.0)
    with pytest.raises(InputError, match="method"):
        periodic.solve(M, C, K, Q, 1.0, method="gauss")


# ------------------------------------------------------- streaming, result
def test_streaming_callables_match_in_memory():
    M, C, K, Q = tv_sampled(200)
    ref = periodic.solve(M, C, K, Q, TV_T, hold="magnus2")
    sol = periodic.solve(lambda i: M[i], lambda i: np.broadcast_to(C, (len(i), 2, 2)),
                         lambda i: K[i], lambda i: Q[i], TV_T, hold="magnus2", n=200,
                         memory_budget=4e4)
    assert sol.passes == 2 and sol.n_exponentials == 400   # recomputed in a second pass
    assert rel(sol.U, ref.U) < 1e-13 and rel(sol.V, ref.V) < 1e-13
    assert np.allclose(sol.floquet_multipliers, ref.floquet_multipliers, atol=1e-13)


def test_streaming_peak_memory_independent_of_n():
    N = 6

    def run(n):
        t = np.arange(n) / n
        K0 = (np.diag(np.full(N, 2.0)) - np.diag(np.ones(N - 1), 1)
              - np.diag(np.ones(N - 1), -1)) * 1e3

        def K(i):
            return K0[None] * (1 + 0.2 * np.cos(2 * np.pi * t[i]))[:, None, None]

        def Q(i):
            out = np.zeros((len(i), N))
            out[:, 0] = np.sin(2 * np.pi * t[i])
            return out
        tracemalloc.start()
        sol = periodic.solve(np.eye(N), 0.01 * K0, K, Q, 1.0, n=n, memory_budget=2e6)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return peak, sol

    p1, s1 = run(1000)
    p2, s2 = run(4000)
    assert s1.passes == s2.passes == 2
    result_growth = (4000 - 1000) * 2 * N * 8 * 4  # Z, U, V, b_k grow with n: O(n N)
    assert p2 - p1 < result_growth + 1e6
    assert p2 < 2e6 + 4000 * 2 * N * 8 * 6


def test_solution_object():
    M, C, K, Q = tv_sampled(50)
    sol = periodic.solve(M, C, K, Q, TV_T, hold="foh")
    assert dataclasses.is_dataclass(sol)
    with pytest.raises(dataclasses.FrozenInstanceError):
        sol.U = None
    assert sol.U.shape == sol.V.shape == (50, 2) and sol.monodromy.shape == (4, 4)
    assert np.allclose(sol.t, np.arange(50) * TV_T / 50) and sol.dt == pytest.approx(TV_T / 50)
    assert sol.floquet_multipliers.shape == (4,) and sol.hold == "foh"
    mods = np.abs(sol.floquet_multipliers)
    assert np.all(np.diff(mods) <= 1e-15) and sol.spectral_radius == pytest.approx(mods[0])
    assert sol.Z.shape == (50, 4) and sol.residual < 1e-14
    assert set(sol.timings) >= {"exponentials", "solve", "total"}
    # the closing equation of the cyclic system holds
    z = sol.Z
    Ms, Cs, Ks, Qs = tv_sampled(50)
    U, V = independent_discrete(Ms, Cs, Ks, Qs, TV_T, "foh")
    assert state_error(sol, U, V, TV_T) < 1e-10
    assert z.shape == (50, 4)


def test_approximant_and_workers_do_not_change_the_answer():
    M, C, K, Q = tv_sampled(64)
    U, V = independent_discrete(M, C, K, Q, TV_T, "magnus2")
    for kw in ({}, {"approximant": "pade"}, {"workers": 1}, {"workers": 3, "delta": 1e-15}):
        sol = periodic.solve(M, C, K, Q, TV_T, hold="magnus2", **kw)
        assert state_error(sol, U, V, TV_T) < 1e-10, kw
    with pytest.raises(InputError, match="approximant"):
        periodic.solve(M, C, K, Q, TV_T, approximant="chebyshev")
    with pytest.raises(InputError, match="workers"):
        periodic.solve(M, C, K, Q, TV_T, workers=0)


def test_large_condition_without_multiplier_near_one_is_solved_by_cyclic_lu():
    """cond(I - Phi) above max_condition with every Floquet multiplier far from 1 is non-normality,
    not resonance: solved by sparse LU (forced here by a tiny max_condition), same answer."""
    M, C, K, Q = tv_sampled(64)
    ref = periodic.solve(M, C, K, Q, TV_T, hold="magnus2")
    assert ref.method == "condensation" and np.abs(ref.floquet_multipliers - 1).min() > periodic.RESONANCE_GAP
    sol = periodic.solve(M, C, K, Q, TV_T, hold="magnus2", max_condition=1.0)
    assert sol.method == "cyclic-lu" and sol.residual < 1e-12
    assert np.abs(sol.U - ref.U).max() <= 1e-10 * np.abs(ref.U).max()
