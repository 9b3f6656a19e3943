"""Element matrices against closed-form entries and independent quadrature."""

import numpy as np
import pytest

from kedfem.model import elements as el

L, EA, EI, RHOA = 0.7, 3.0e6, 250.0, 2.5


def gauss(f, n=8):
    """Integrate f(x) over [0, L] by Gauss-Legendre (exact for polynomials of degree < 2n)."""
    xg, wg = np.polynomial.legendre.leggauss(n)
    x = 0.5 * L * (xg + 1)
    return sum(0.5 * L * w * f(xx) for xx, w in zip(x, wg))


def N_at(x):
    """2 x 6 shape-function matrix written out by hand (independent of the package)."""
    xi = x / L
    return np.array([
        [1 - xi, 0, 0, xi, 0, 0],
        [0, 1 - 3 * xi**2 + 2 * xi**3, L * (xi - 2 * xi**2 + xi**3), 0, 3 * xi**2 - 2 * xi**3,
         L * (-xi**2 + xi**3)],
    ])


def test_stiffness_closed_form_entries():
    k = el.frame_stiffness(L, EA, EI)[0]
    exp = np.zeros((6, 6))
    a = EA / L
    exp[np.ix_([0, 3], [0, 3])] = a * np.array([[1, -1], [-1, 1]])
    b = EI / L**3
    exp[np.ix_([1, 2, 4, 5], [1, 2, 4, 5])] = b * np.array([
        [12, 6 * L, -12, 6 * L], [6 * L, 4 * L**2, -6 * L, 2 * L**2],
        [-12, -6 * L, 12, -6 * L], [6 * L, 2 * L**2, -6 * L, 4 * L**2]])
    np.testing.assert_allclose(k, exp, rtol=1e-14, atol=0)
    # three rigid-body modes: translation x, y and rotation about node 1
    rb = np.array([[1, 0, 0, 1, 0, 0], [0, 1, 0, 0, 1, 0], [0, 0, 1, 0, L, 1]], float).T
    assert np.max(np.abs(k @ rb)) < 1e-9 * np.max(np.abs(k))
    ev = np.linalg.eigvalsh(k)
    assert np.sum(ev > 1e-8 * ev.max()) == 3


def test_cantilever_tip_deflection_exact_with_one_element():
    P = 120.0
    k = el.frame_stiffness(L, EA, EI)[0]
    free = [3, 4, 5]
    u = np.linalg.solve(k[np.ix_(free, free)], np.array([0, P, 0]))
    assert u[1] == pytest.approx(P * L**3 / (3 * EI), rel=1e-12)
    assert u[2] == pytest.approx(P * L**2 / (2 * EI), rel=1e-12)


def test_consistent_mass_matches_quadrature_and_closed_form():
    m = el.consistent_mass(L, RHOA)[0]
    mq = gauss(lambda x: RHOA * N_at(x).T @ N_at(x))
    np.testing.assert_allclose(m, mq, rtol=1e-12, atol=1e-14)
    assert m[1, 1] == pytest.approx(156 * RHOA * L / 420)
    assert m[1, 2] == pytest.approx(22 * L * RHOA * L / 420)
    assert m[0, 3] == pytest.approx(RHOA * L / 6)
    # total translational mass
    ones_x = np.array([1, 0, 0, 1, 0, 0.0])
    assert ones_x @ m @ ones_x == pytest.approx(RHOA * L)


def test_lumped_mass_is_diagonal_positive_with_total_mass():
    m = el.lumped_mass(L, RHOA)[0]
    assert np.allclose(m, np.diag(np.diag(m)))
    assert np.all(np.diag(m) > 0)
    assert m[0, 0] + m[3, 3] == pytest.approx(RHOA * L)
    assert m[2, 2] == pytest.approx(RHOA * L * L**2 / 78)


def test_geometric_matrix_is_int_of_slope_products():
    def dNv(x):
        xi = x / L
        return np.array([0, (-6 * xi + 6 * xi**2) / L, 1 - 4 * xi + 3 * xi**2, 0,
                         (6 * xi - 6 * xi**2) / L, -2 * xi + 3 * xi**2])
    Gq = gauss(lambda x: np.outer(dNv(x), dNv(x)))
    kg = el.geometric_stiffness(L, 1.0)[0]
    np.testing.assert_allclose(kg, Gq, rtol=1e-12, atol=1e-14)
    assert kg[1, 1] == pytest.approx(36 / (30 * L))
    assert kg[2, 2] == pytest.approx(4 * L**2 / (30 * L))
    # batched leading axes
    kgb = el.geometric_stiffness([L, 2 * L], np.array([[1.0, 2.0], [3.0, 4.0]]))
    assert kgb.shape == (2, 2, 6, 6)
    np.testing.assert_allclose(kgb[1, 0], 3.0 * kg)


def test_geometric_stiffness_of_a_varying_axial_force_is_its_integral():
    """int N(x) v'^T v' dx for a quadratic N (a link's own inertia makes it so), against quadrature;
    a constant N gives the mean-force matrix."""
    def dNv(x):
        xi = x / L
        return np.array([0, (-6 * xi + 6 * xi**2) / L, 1 - 4 * xi + 3 * xi**2, 0,
                         (6 * xi - 6 * xi**2) / L, -2 * xi + 3 * xi**2])

    def N(x):
        return 120.0 - 300.0 * x + 450.0 * x**2
    Gq = gauss(lambda x: N(x) * np.outer(dNv(x), dNv(x)))
    kg = el.geometric_stiffness_varying([L], N(el.AXIAL_XI * L)[None, :])[0]
    np.testing.assert_allclose(kg, Gq, rtol=1e-12, atol=1e-12)
    # the mean force alone misses the variation: the matrices differ by far more than round-off
    mean = gauss(lambda x: N(x) * np.ones((1, 1)))[0, 0] / L
    assert np.abs(el.geometric_stiffness(L, mean)[0] - Gq).max() > 1e-3 * np.abs(Gq).max()
    np.testing.assert_allclose(el.geometric_stiffness_varying([L, 2 * L], np.full((3, 2, 4), 2.0))[1, 1],
                               el.geometric_stiffness(2 * L, 2.0)[0], rtol=1e-13, atol=1e-14)


def test_coupling_skew_matches_quadrature_and_is_skew():
    S = np.array([[0, -1.0], [1.0, 0]])
    msq = gauss(lambda x: RHOA * N_at(x).T @ S @ N_at(x))
    ms = el.coupling_skew(L, RHOA)[0]
    np.testing.assert_allclose(ms, msq, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(ms, -ms.T, atol=1e-15)
    # closed form: int (1 - x/L) H1 dx = 7 L / 20
    assert ms[1, 0] == pytest.approx(RHOA * 7 * L / 20)


def test_linear_load_matches_quadrature():
    p0 = np.array([1.5, -2.0])
    p1 = np.array([0.3, 4.0])
    f = el.linear_load(L, p0[None], p1[None])[0]
    fq = gauss(lambda x: N_at(x).T @ (p0 + x * p1))
    np.testing.assert_allclose(f, fq, rtol=1e-12, atol=1e-14)


def test_rotation_blocks_orthogonal():
    T = el.rotation_blocks(np.array([0.3, -2.0]))
    for t in T:
        np.testing.assert_allclose(t @ t.T, np.eye(6), atol=1e-15)
    # local axial unit vector of an element at 30 degrees is the global direction
    th = np.pi / 6
    T = el.rotation_blocks(th)
    u_global = np.array([np.cos(th), np.sin(th), 0, 0, 0, 0])
    np.testing.assert_allclose(T @ u_global, [1, 0, 0, 0, 0, 0], atol=1e-15)


def test_timoshenko_tends_to_euler_bernoulli_and_adds_shear_compliance():
    k_eb = el.frame_stiffness(L, EA, EI)[0]
    k_t = el.timoshenko_stiffness(L, EA, EI, 1e12 * EI)[0]
    np.testing.assert_allclose(k_t, k_eb, rtol=1e-9, atol=1e-9)
    GAs = 12 * EI / L**2  # phi = 1
    k_t = el.timoshenko_stiffness(L, EA, EI, GAs)[0]
    free = [3, 4, 5]
    u = np.linalg.solve(k_t[np.ix_(free, free)], np.array([0, 1.0, 0]))
    assert u[1] == pytest.approx(L**3 / (3 * EI) + L / GAs, rel=1e-12)


def test_shape_curvature_of_hermite():
    B = el.shape_curvatures([L], [0.0, 0.5, 1.0])[0]
    # pure curvature mode v = x^2/2 -> nodal values v2 = L^2/2, theta1 = 0, theta2 = L
    d = np.array([0, 0, 0, 0, L**2 / 2, L])
    np.testing.assert_allclose(B @ d, [1.0, 1.0, 1.0], rtol=1e-12)


def test_bad_element_properties_raise():
    with pytest.raises(ValueError, match="L"):
        el.frame_stiffness(-1.0, EA, EI)
