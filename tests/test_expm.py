"""Tests of kedfem.solvers.expm against independent truth.

References: a 60-digit decimal-arithmetic exponential (Taylor series with scaling
and squaring in ``decimal``, exact conversion of the double input), closed forms,
and scipy.linalg.expm / scipy.sparse.linalg.expm.

Tolerances. For well-conditioned matrices kedfem must agree with the 60-digit
reference to 1e-13 (relative, Frobenius). A matrix whose eigenvalues have
imaginary parts up to ``omega dt`` is sensitive to the rounding of its own
entries: the phase ``omega dt`` is only known to ``u omega dt`` (u = 2**-53), and
where ``sin(omega dt) ~ 0`` the Frobenius-relative error of ``-omega sin`` grows by
``1/|sin|`` on top, so no double-precision algorithm does 1e-13 there. For stiff
state matrices the tolerance is ``max(1e-13, 20 u omega_max dt, 10 x the error of
the better of scipy.linalg.expm and scipy.sparse.linalg.expm)``. Against
scipy.linalg.expm the tolerance is that plus scipy's own measured error (SciPy
1.17's expm loses up to ~1e-11 on some random matrices).
"""

from __future__ import annotations

import math
from decimal import Decimal, localcontext

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse.linalg as spla
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kedfem.errors import InputError
from reference import augmented_transition
from kedfem.solvers.expm import (affine_exponential, balance, expm, exponential_integrals,
                         pade_coefficients, pade_degree, pade_error_bound,
                         second_order_transition, taylor_expm)

U = 2.0 ** -53


def rel(a, b):
    """Relative Frobenius error, scaled first so that tiny (e^-500) matrices do not underflow."""
    a, b = np.asarray(a), np.asarray(b)
    s = np.abs(b).max()
    return float(np.linalg.norm((a - b) / s) / np.linalg.norm(b / s))


def dexpm(A, digits=60):
    """exp(A) in `digits`-digit decimal arithmetic (independent reference)."""
    A = np.asarray(A, dtype=float)
    m = A.shape[0]
    with localcontext() as ctx:
        ctx.prec = digits
        D = [[Decimal(float(A[i, j])) for j in range(m)] for i in range(m)]
        nrm = max(sum(abs(x) for x in row) for row in D)
        s = 0
        while nrm > Decimal("1e-3"):
            nrm /= 2
            s += 1
        sc = Decimal(2) ** s
        X = [[x / sc for x in row] for row in D]

        def mul(P, Q):
            return [[sum(P[i][k] * Q[k][j] for k in range(m)) for j in range(m)] for i in range(m)]

        S = [[Decimal(int(i == j)) for j in range(m)] for i in range(m)]
        T = [row[:] for row in S]
        eps = Decimal(10) ** (-digits)
        for k in range(1, 400):
            T = [[x / k for x in row] for row in mul(T, X)]
            S = [[S[i][j] + T[i][j] for j in range(m)] for i in range(m)]
            if max(abs(x) for row in T for x in row) < eps:
                break
        for _ in range(s):
            S = mul(S, S)
        return np.array([[float(x) for x in row] for row in S])


def chain_state(masses, springs, zeta, wdt):
    """State matrix F dt of a fixed-free mass-spring chain, scaled to omega_max dt = wdt."""
    N = len(masses)
    K = np.zeros((N, N))
    for i, k in enumerate(springs):  # spring i between mass i-1 (or ground) and i
        K[i, i] += k
        if i > 0:
            K[i - 1, i - 1] += k
            K[i, i - 1] -= k
            K[i - 1, i] -= k
    M = np.diag(masses)
    w2, _ = sla.eigh(K, M)
    wmax = math.sqrt(w2[-1])
    C = (2 * zeta / wmax) * K  # damping ratio zeta at the highest mode
    dt = wdt / wmax
    S = np.linalg.solve(M, K)
    Dm = np.linalg.solve(M, C)
    F = np.block([[np.zeros((N, N)), np.eye(N)], [-S, -Dm]])
    return F * dt


# ---------------------------------------------------------------- Pade degree
def test_table1_pade_degree():
    """The paper's Table 1: q = 1..6 for delta = 1e-1, 1e-4, 1e-6, 1e-9, 1e-13, 1e-16."""
    table = {1e-1: 1, 1e-4: 2, 1e-6: 3, 1e-9: 4, 1e-13: 5, 1e-16: 6}
    for delta, q in table.items():
        assert pade_degree(delta) == q
        # Table 1 lists the Golub & Van Loan bound rounded down to its decade
        assert math.floor(math.log10(pade_error_bound(q))) == round(math.log10(delta))
    # exact values of the bound 2^(3-2q) (q!)^2 / ((2q)! (2q+1)!)
    assert pade_error_bound(1) == pytest.approx(1 / 6, rel=1e-15)
    assert pade_error_bound(2) == pytest.approx(2 ** -1 * 4 / (24 * 120), rel=1e-15)
    degrees = [pade_degree(10.0 ** -e) for e in np.linspace(1, 17, 60)]
    assert degrees == sorted(degrees)
    for bad in (0.0, -1e-3, float("nan"), float("inf")):
        with pytest.raises(InputError):
            pade_degree(bad)


def test_pade_coefficients_are_the_pade_approximant():
    """e^x - R_qq(x) = (-1)^q (q!)^2/((2q)!(2q+1)!) x^(2q+1) (1 + O(x)) (scalar check)."""
    for q in (1, 2, 3):
        c = pade_coefficients(q)
        for x in (0.05, 0.1):
            num = sum(ck * x ** k for k, ck in enumerate(c))
            den = sum(ck * (-x) ** k for k, ck in enumerate(c))
            lead = math.factorial(q) ** 2 / (math.factorial(2 * q) * math.factorial(2 * q + 1))
            ratio = (math.exp(x) - num / den) / ((-1) ** q * lead * x ** (2 * q + 1))
            assert ratio == pytest.approx(1.0, abs=2 * x)


# ----------------------------------------------------- accuracy, hypothesis
random_matrices = st.integers(1, 6).flatmap(
    lambda m: st.tuples(
        st.lists(st.floats(-1, 1, allow_nan=False, allow_infinity=False),
                 min_size=m * m, max_size=m * m).map(lambda v: np.array(v).reshape(m, m)),
        st.floats(-3, 1.5)))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=random_matrices, approximant=st.sampled_from(["pade", "taylor"]))
def test_expm_random_matrices_vs_60_digit_reference_and_scipy(data, approximant):
    A0, e = data
    A = A0 * 10.0 ** e
    ref = dexpm(A)
    E = expm(A, delta=1e-15, approximant=approximant)
    tol = 1e-13
    assert rel(E, ref) <= tol
    E_sp = sla.expm(A)
    assert rel(E, E_sp) <= tol + rel(E_sp, ref)


chains = st.tuples(
    st.integers(1, 3).flatmap(lambda N: st.tuples(
        st.lists(st.floats(0.5, 2.0), min_size=N, max_size=N),
        st.lists(st.floats(0.5, 2.0), min_size=N, max_size=N))),
    st.sampled_from([0.0, 1e-6, 1e-3, 0.05]),
    st.floats(-3, 4))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(params=chains, approximant=st.sampled_from(["pade", "taylor"]))
def test_expm_stiff_chain_state_matrices(params, approximant):
    (masses, springs), zeta, log_wdt = params
    wdt = 10.0 ** log_wdt
    # stiffness scale 1e6: ||M^-1 K|| dt ~ omega_max^2 dt >> omega_max dt
    F = chain_state(masses, [1e6 * s for s in springs], zeta, wdt)
    ref = dexpm(F, 50)
    E_sp, E_sps = sla.expm(F), spla.expm(F)
    best_scipy = min(rel(E_sp, ref), rel(E_sps, ref))
    # phase-limited: the rounded entries fix omega dt only to u omega dt, and where
    # sin(omega dt) ~ 0 the Frobenius-relative error grows by 1/|sin| on top; so
    # 1e-13, or 50 u omega dt, or as good as the better of SciPy's two routines
    # (hypothesis found 35 u omega dt, 1.2e-11, for a Pade exponential at omega dt = 3.0e3,
    # 10 squarings; SciPy 1.2e-12 there: both rounding-level)
    tol = max(1e-13, 50 * U * wdt, 10 * best_scipy)
    E = expm(F, delta=1e-15, approximant=approximant)
    assert rel(E, ref) <= tol
    assert rel(E, E_sp) <= tol + rel(E_sp, ref)


def test_stiff_state_matrix_scaled_by_spectral_size():
    """j follows omega_max dt, not ||M^-1 K|| dt ~ omega_max^2 dt (the paper's rule)."""
    F = chain_state([1.0, 2.0, 1.0], [1e6, 2e6, 1e6], 1e-3, 100.0)  # omega_max dt = 100
    ref = dexpm(F, 50)
    j_paper = 1 + math.floor(math.log2(np.abs(F).sum(axis=1).max()))
    for approximant in ("pade", "taylor"):
        E, info = expm(F, approximant=approximant, return_info=True)
        assert rel(E, ref) <= 1e-13
        assert info.squarings[0] <= j_paper - 8
        assert info.squarings[0] <= 1 + math.ceil(math.log2(100.0 / 0.5))


def test_balancing_badly_scaled_matrix():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((4, 4))
    d = np.array([1.0, 1e6, 1e-6, 1e3])
    A = X * d[None, :] / d[:, None]
    ref = dexpm(A)
    E_b, info_b = expm(A, return_info=True)
    E_n, info_n = expm(A, balance=False, return_info=True)
    assert rel(E_b, ref) <= 1e-13
    assert info_n.squarings[0] >= info_b.squarings[0] + 5
    B, dd = balance(A)
    assert np.array_equal(np.log2(dd), np.round(np.log2(dd)))  # powers of two
    assert np.array_equal(B, A * dd[None, :] / dd[:, None])    # exact similarity
    assert np.abs(B).sum(1).max() < 1e-3 * np.abs(A).sum(1).max()


# ------------------------------------------------------------ hard matrices
e = math.e
eps = np.spacing(1.0)


def _eig_closed(V, lam):
    V = np.array(V, dtype=float)
    return V @ np.diag(np.exp(lam)) @ np.linalg.inv(V)


def _forsythe10():
    A = np.diag(np.ones(9), 1)
    A[9, 0] = 1e-10
    # A^10 = 1e-10 I  =>  exp(A) = sum_r c_r A^r, c_r = sum_j 1e-10^j / (10 j + r)!
    E = np.zeros((10, 10))
    P = np.eye(10)
    for r in range(10):
        c = sum(1e-10 ** j / math.factorial(10 * j + r) for j in range(4))
        E += c * P
        P = P @ A
    return A, E


def _tri2(a, b, c):
    """exp([[a, b], [0, c]]) in closed form (cancellation-free for a ~ c)."""
    h = 0.5 * (a - c)
    if abs(h) < 0.5:
        off = b * math.exp(0.5 * (a + c)) * (math.sinh(h) / h if h else 1.0)
    else:
        off = b * (math.exp(a) - math.exp(c)) / (a - c)
    return np.array([[math.exp(a), off], [0.0, math.exp(c)]])


HARD = {
    # name: (A, exact or None (-> 60-digit reference), tolerance)
    "Ward 1977 #1 (defective)": ([[4, 2, 0], [1, 4, 1], [1, 1, 4]], None, 1e-14),
    "Ward 1977 #2 (symmetric)": ([[29.87942128909879, 0.7815750847907159, -2.289519314033932],
                                  [0.7815750847907159, 25.72656945571064, 8.680737820540137],
                                  [-2.289519314033932, 8.680737820540137, 34.39400925519054]],
                                 None, 1e-14),
    "Ward 1977 #3 (eig -1,-2,-20)": ([[-131, 19, 18], [-390, 56, 54], [-387, 57, 52]], None,
                                     "kappa"),
    "Ward 1977 #4 (Forsythe 10x10)": (_forsythe10()[0], _forsythe10()[1], 1e-14),
    "Moler-Van Loan 2x2": ([[-49, 24], [-64, 31]],
                           _eig_closed([[1, 3], [2, 4]], [-1.0, -17.0]), "kappa"),
    "Moler-Van Loan nilpotent": ([[0, 6, 0, 0], [0, 0, 6, 0], [0, 0, 0, 6], [0, 0, 0, 0]],
                                 [[1, 6, 18, 36], [0, 1, 6, 18], [0, 0, 1, 6], [0, 0, 0, 1]],
                                 1e-15),
    "Moler-Van Loan defective": ([[1, 1], [0, 1]], [[e, e], [0, e]], 1e-15),
    "Moler-Van Loan near-defective": ([[1 + eps, 1], [0, 1 - eps]], _tri2(1 + eps, 1, 1 - eps),
                                      1e-15),
    "Laub (Taylor killer)": ([[0, 1], [-39, -40]],
                             _eig_closed([[1, 1], [-1, -39]], [-1.0, -39.0]), "kappa"),
    "Kenney-Laub 1989 4x4": ([[48, -49, 50, 49], [0, -2, 100, 0], [0, -1, -2, 1],
                              [-50, 50, 50, -52]], None, "kappa"),
    "Kenney-Laub 1998 ex.3 (badly scaled)": ([[-1, 1e7], [0, -1e7]], _tri2(-1.0, 1e7, -1e7),
                                             1e-15),
    "Al-Mohy-Higham overscaling b=1e4": ([[1, 1e4], [0, -1]], _tri2(1.0, 1e4, -1.0), 1e-15),
    "Al-Mohy-Higham overscaling b=1e8": ([[1, 1e8], [0, -1]], _tri2(1.0, 1e8, -1.0), 1e-15),
    "Al-Mohy-Higham [[1,1e17],[0,1]]": ([[1, 1e17], [0, 1]], [[e, 1e17 * e], [0, e]], 1e-15),
}


@pytest.mark.parametrize("name", list(HARD))
def test_classic_hard_matrices(name):
    A, exact, tol = HARD[name]
    A = np.array(A, dtype=float)
    exact = dexpm(A, 80) if exact is None else np.array(exact, dtype=float)
    if tol == "kappa":  # forward error bound of a backward-stable method: 4 u kappa_exp
        tol = max(1e-14, 4 * U * sla.expm_cond(A))
    E = expm(A)
    assert rel(E, exact) <= tol, name
    E_sp = sla.expm(A)
    assert rel(E, E_sp) <= tol + rel(E_sp, exact)


def test_taylor_series_fails_where_pade_does_not():
    # cancellation: eigenvalues -1 and -39, ||A|| = 79
    A = np.array([[0.0, 1.0], [-39.0, -40.0]])
    exact = _eig_closed([[1, 1], [-1, -39]], [-1.0, -39.0])
    assert rel(taylor_expm(A), exact) > 1e-3
    assert rel(expm(A), exact) < 1e-13
    # large norm: the terms overflow
    B = np.array([[-1.0, 1e7], [0.0, -1e7]])
    T = taylor_expm(B)
    assert not np.all(np.isfinite(T)) or rel(T, _tri2(-1.0, 1e7, -1e7)) > 1.0
    assert rel(expm(B), _tri2(-1.0, 1e7, -1e7)) < 1e-15
    # and the literal series is fine for a small norm (the implementation is right)
    S = np.array([[4, 2, 0], [1, 4, 1], [1, 1, 4]]) / 100.0
    assert rel(taylor_expm(S), dexpm(S)) < 1e-15


def test_batch_with_different_scalings_equals_single():
    rng = np.random.default_rng(0)
    mats = np.stack([rng.standard_normal((4, 4)) * s for s in (1e-4, 0.3, 5.0, 40.0)] +
                    [np.array([[1, 1e8, 0, 0], [0, -1, 0, 0], [0, 0, 2, 1], [0, 0, 0, 2.0]])])
    for approximant in ("pade", "taylor"):
        E, info = expm(mats, approximant=approximant, return_info=True)
        assert len(set(info.squarings.tolist())) >= 3  # genuinely different j in one batch
        for k in range(len(mats)):
            tol = max(1e-13, 4 * U * sla.expm_cond(mats[k]))
            assert rel(E[k], dexpm(mats[k])) <= tol
            # the batch may pick another degree than a single call: both meet delta
            assert rel(E[k], expm(mats[k], approximant=approximant)) <= 2 * tol
    E2 = expm(mats.reshape(5, 1, 4, 4))
    assert E2.shape == (5, 1, 4, 4)


def test_delta_trades_accuracy_for_work():
    A = np.array([[0.0, 1.0], [-39.0, -40.0]]) / 3.0
    exact = _eig_closed([[1, 1], [-1, -39]], [-1 / 3, -13.0])
    E6, i6 = expm(A, delta=1e-6, return_info=True)
    E15, i15 = expm(A, delta=1e-15, return_info=True)
    assert rel(E6, exact) < 1e-6 * 4 * sla.expm_cond(A)
    assert rel(E15, exact) < 1e-13
    assert i6.degree < i15.degree
    assert i6.products + i6.squarings[0] < i15.products + i15.squarings[0]


def test_expm_input_validation():
    with pytest.raises(InputError, match="non-finite"):
        expm(np.array([[1.0, np.nan], [0.0, 1.0]]))
    with pytest.raises(InputError, match="shape"):
        expm(np.ones((2, 3)))
    with pytest.raises(InputError, match="delta"):
        expm(np.eye(2), delta=-1.0)
    with pytest.raises(InputError, match="approximant"):
        expm(np.eye(2), approximant="chebyshev")
    assert np.array_equal(expm(np.zeros((3, 3))), np.eye(3))


# ------------------------------------------------ element discretization
def _augmented_reference(F, dt, g0, g1):
    return augmented_transition(F, dt, g0, g1, expm=spla.expm)


@pytest.mark.parametrize("hold", ["zoh", "foh"])
@pytest.mark.parametrize("approximant", ["pade", "taylor"])
def test_affine_exponential_and_second_order_transition_vs_van_loan(hold, approximant):
    rng = np.random.default_rng(1)
    N, L, dt = 3, 6, 2e-3
    Kr = rng.standard_normal((L, N, N))
    S = Kr @ Kr.transpose(0, 2, 1) * 1e5 + np.eye(N) * 1e3   # M^-1 K, omega dt ~ 1
    D = 1e-3 * S + 0.5 * np.eye(N)
    f0 = rng.standard_normal((L, N)) * 1e4                    # large loads
    f1 = None if hold == "zoh" else f0 + rng.standard_normal((L, N)) * 1e2
    F = np.zeros((L, 2 * N, 2 * N))
    F[:, :N, N:] = np.eye(N)
    F[:, N:, :N] = -S
    F[:, N:, N:] = -D
    g0 = np.concatenate([np.zeros((L, N)), f0], axis=1)
    g1 = None if f1 is None else np.concatenate([np.zeros((L, N)), f1], axis=1)
    A1, b1 = affine_exponential(F, dt, g0, g1, delta=1e-15, approximant=approximant)
    A2, b2 = second_order_transition(S, D, dt, f0, f1, delta=1e-15, approximant=approximant)
    for k in range(L):
        Ar, br = _augmented_reference(F[k], dt, g0[k], None if g1 is None else g1[k])
        assert rel(A1[k], Ar) < 1e-13 and rel(b1[k], br) < 1e-13
        assert rel(A2[k], Ar) < 1e-13 and rel(b2[k], br) < 1e-13


def test_exponential_integrals_map_linear_forcing():
    rng = np.random.default_rng(2)
    N, dt = 3, 0.01
    Kr = rng.standard_normal((N, N))
    S = Kr @ Kr.T * 100 + np.eye(N)
    F = np.block([[np.zeros((N, N)), np.eye(N)], [-S, -0.02 * S]])
    G = np.vstack([np.zeros((N, N)), np.diag([1.0, 0.5, 2.0])])
    A, G0, G1 = exponential_integrals(F, G, dt, scaling="second-order", delta=1e-15)
    q0, q1 = rng.standard_normal(N), rng.standard_normal(N)
    Ar, br = _augmented_reference(F, dt, G @ q0, G @ q1)
    assert rel(A, Ar) < 1e-13
    assert rel(G0 @ q0 + G1 @ (q1 - q0), br) < 1e-13


def test_balance_ignores_subnormal_entries():
    """Found by hypothesis: a subnormal entry made the balancing ratio overflow (RuntimeWarning)."""
    A = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 5e-324, 0.0, 0.0]).reshape(3, 3)
    for approximant in ("pade", "taylor"):
        E = expm(A, approximant=approximant)
        assert np.allclose(E, sla.expm(A), rtol=1e-15, atol=1e-15)
