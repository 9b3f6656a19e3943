"""Planar frame element matrices, batched over a leading element axis.

All functions are pure: they take arrays of element properties of shape
``(n_el,)`` (scalars broadcast) and return ``(n_el, 6, 6)`` matrices or
``(n_el, 6)`` load vectors in the element's *local* frame. The local DOF
order is ``[u1, v1, theta1, u2, v2, theta2]``: axial and transverse nodal
translations [m] and nodal rotations [rad] at the element's start (1) and end
(2) node. Axial displacement is interpolated linearly, transverse
displacement by cubic Hermite polynomials (Euler-Bernoulli).

The rigid-elastic coupling integrals follow docs/theory.md section 2 with the
shape-function matrix ``N(x) = [[N_u], [N_v]]`` (2 x 6):

* ``m_t = int rhoA N^T N dx`` (translational mass; equals the consistent mass
  of an Euler-Bernoulli element without rotary inertia),
* ``m_s = int rhoA N^T S N dx`` with ``S = [[0, -1], [1, 0]]`` (skew).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = [
    "frame_stiffness",
    "consistent_mass",
    "lumped_mass",
    "geometric_matrix",
    "geometric_stiffness",
    "geometric_stiffness_varying",
    "AXIAL_XI",
    "AXIAL_W",
    "coupling_skew",
    "linear_load",
    "rotation_blocks",
    "shape_functions",
    "hermite",
    "shape_slopes",
    "shape_curvatures",
    "timoshenko_stiffness",
    "U_DOFS",
    "V_DOFS",
]

#: local indices of the axial DOFs (u1, u2)
U_DOFS = np.array([0, 3])
#: local indices of the bending DOFs (v1, theta1, v2, theta2)
V_DOFS = np.array([1, 2, 4, 5])


def _props(*arrays):
    out = np.broadcast_arrays(*[np.atleast_1d(np.asarray(a, dtype=float)) for a in arrays])
    return [np.ascontiguousarray(a) for a in out]


def _check_positive(name, a):
    if not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise InputError(f"element property {name} must be finite and > 0, got {a}")


def frame_stiffness(L, EA, EI):
    """Linear stiffness of planar Euler-Bernoulli frame elements.

    Parameters
    ----------
    L : array_like, shape (n_el,)
        Element lengths [m].
    EA : array_like, shape (n_el,)
        Axial rigidity [N].
    EI : array_like, shape (n_el,)
        Bending rigidity [N m^2].

    Returns
    -------
    k : ndarray, shape (n_el, 6, 6)
        Local stiffness matrices [N/m, N, N m].
    """
    L, EA, EI = _props(L, EA, EI)
    _check_positive("L", L)
    n = L.size
    k = np.zeros((n, 6, 6))
    a = EA / L
    k[:, 0, 0] = k[:, 3, 3] = a
    k[:, 0, 3] = k[:, 3, 0] = -a
    b = EI / L**3
    kb = np.empty((n, 4, 4))
    kb[:] = np.array([[12.0, 0, -12.0, 0], [0, 0, 0, 0], [-12.0, 0, 12.0, 0], [0, 0, 0, 0]])
    kb *= b[:, None, None]
    c = EI / L**2 * 6.0
    d = EI / L
    kb[:, 0, 1] = kb[:, 1, 0] = kb[:, 0, 3] = kb[:, 3, 0] = c
    kb[:, 2, 1] = kb[:, 1, 2] = kb[:, 2, 3] = kb[:, 3, 2] = -c
    kb[:, 1, 1] = kb[:, 3, 3] = 4.0 * d
    kb[:, 1, 3] = kb[:, 3, 1] = 2.0 * d
    k[:, V_DOFS[:, None], V_DOFS[None, :]] = kb
    return k


def timoshenko_stiffness(L, EA, EI, GAs):
    """Linear stiffness of planar Timoshenko frame elements (shear-flexible).

    Uses the exact interdependent-interpolation element: the Euler-Bernoulli
    bending block with ``phi = 12 EI / (GAs L^2)``.

    Parameters
    ----------
    L, EA, EI : array_like, shape (n_el,)
        Length [m], axial [N] and bending [N m^2] rigidity.
    GAs : array_like, shape (n_el,)
        Shear rigidity ``kappa G A`` [N].

    Returns
    -------
    k : ndarray, shape (n_el, 6, 6)
    """
    L, EA, EI, GAs = _props(L, EA, EI, GAs)
    _check_positive("GAs", GAs)
    k = frame_stiffness(L, EA, EI)
    phi = 12.0 * EI / (GAs * L**2)
    f = 1.0 / (1.0 + phi)
    kb = k[:, V_DOFS[:, None], V_DOFS[None, :]]
    # scale: translation-translation and translation-rotation by f; rotation
    # diagonal (4+phi)/(4(1+phi)), off-diagonal rotation (2-phi)/(2(1+phi))
    scale = np.ones((L.size, 4, 4)) * f[:, None, None]
    scale[:, 1, 1] = scale[:, 3, 3] = (4.0 + phi) / (4.0 * (1.0 + phi))
    scale[:, 1, 3] = scale[:, 3, 1] = (2.0 - phi) / (2.0 * (1.0 + phi))
    k[:, V_DOFS[:, None], V_DOFS[None, :]] = kb * scale
    return k


def consistent_mass(L, rhoA, rhoI=0.0):
    """Consistent mass of planar frame elements.

    Parameters
    ----------
    L : array_like, shape (n_el,)
        Element lengths [m].
    rhoA : array_like, shape (n_el,)
        Mass per unit length [kg/m].
    rhoI : array_like, shape (n_el,), optional
        Rotary inertia per unit length [kg m] (Rayleigh beam); 0 for the
        Euler-Bernoulli element.

    Returns
    -------
    m : ndarray, shape (n_el, 6, 6)
        Local mass matrices [kg, kg m, kg m^2].
    """
    L, rhoA, rhoI = _props(L, rhoA, rhoI)
    _check_positive("L", L)
    n = L.size
    m = np.zeros((n, 6, 6))
    f = (rhoA * L / 6.0)[:, None, None]
    m[:, U_DOFS[:, None], U_DOFS[None, :]] = f * np.array([[2.0, 1.0], [1.0, 2.0]])
    base = np.array([[156.0, 0, 54.0, 0], [0, 0, 0, 0], [54.0, 0, 156.0, 0], [0, 0, 0, 0]])
    mb = np.broadcast_to(base, (n, 4, 4)).copy()
    mb[:, 0, 1] = mb[:, 1, 0] = 22.0 * L
    mb[:, 0, 3] = mb[:, 3, 0] = -13.0 * L
    mb[:, 2, 1] = mb[:, 1, 2] = 13.0 * L
    mb[:, 2, 3] = mb[:, 3, 2] = -22.0 * L
    mb[:, 1, 1] = mb[:, 3, 3] = 4.0 * L**2
    mb[:, 1, 3] = mb[:, 3, 1] = -3.0 * L**2
    mb *= (rhoA * L / 420.0)[:, None, None]
    if np.any(rhoI != 0.0):
        mb = mb + (rhoI / L)[:, None, None] * geometric_matrix(L)
    m[:, V_DOFS[:, None], V_DOFS[None, :]] = mb
    return m


def lumped_mass(L, rhoA):
    """Lumped (HRZ diagonal) mass of planar frame elements.

    Half the element mass on each node's translations and ``m L^2 / 78`` on
    each rotation (HRZ scaling of the consistent diagonal), so that the matrix
    is positive definite.

    Parameters
    ----------
    L, rhoA : array_like, shape (n_el,)
        Element lengths [m] and mass per unit length [kg/m].

    Returns
    -------
    m : ndarray, shape (n_el, 6, 6)
    """
    L, rhoA = _props(L, rhoA)
    _check_positive("L", L)
    me = rhoA * L
    d = np.stack([me / 2, me / 2, me * L**2 / 78.0] * 2, axis=1)
    m = np.zeros((L.size, 6, 6))
    idx = np.arange(6)
    m[:, idx, idx] = d
    return m


def geometric_matrix(L):
    """Geometric matrix ``G = int N_v'^T N_v' dx`` of planar frame elements.

    ``G`` is the geometric stiffness per unit axial force: ``k_G = N G``.

    Parameters
    ----------
    L : array_like, shape (n_el,)
        Element lengths [m].

    Returns
    -------
    G : ndarray, shape (n_el, 4, 4)
        On the bending DOFs ``[v1, theta1, v2, theta2]`` [1/m, 1, m].
    """
    (L,) = _props(L)
    n = L.size
    G = np.empty((n, 4, 4))
    G[:] = np.array([[36.0, 0, -36.0, 0], [0, 0, 0, 0], [-36.0, 0, 36.0, 0], [0, 0, 0, 0]])
    G[:, 0, 1] = G[:, 1, 0] = G[:, 0, 3] = G[:, 3, 0] = 3.0 * L
    G[:, 2, 1] = G[:, 1, 2] = G[:, 2, 3] = G[:, 3, 2] = -3.0 * L
    G[:, 1, 1] = G[:, 3, 3] = 4.0 * L**2
    G[:, 1, 3] = G[:, 3, 1] = -(L**2)
    G /= (30.0 * L)[:, None, None]
    return G


def geometric_stiffness(L, N):
    """Geometric stiffness of planar frame elements under axial force.

    Parameters
    ----------
    L : array_like, shape (n_el,)
        Element lengths [m].
    N : array_like, shape (..., n_el)
        Axial force [N], tension positive; leading axes (e.g. time) allowed.

    Returns
    -------
    kG : ndarray, shape (..., n_el, 6, 6)
    """
    G = geometric_matrix(L)
    N = np.asarray(N, dtype=float)
    if N.ndim == 0:
        N = np.full(G.shape[0], float(N))
    out = np.zeros(N.shape + (6, 6))
    out[..., V_DOFS[:, None], V_DOFS[None, :]] = N[..., None, None] * G
    return out


#: Abscissae (fractions of the element's length) and weights of the 4-point Gauss-Legendre
#: rule :func:`geometric_stiffness_varying` reads the axial force at
AXIAL_XI, AXIAL_W = (0.5 * (np.polynomial.legendre.leggauss(4)[0] + 1.0),
                     0.5 * np.polynomial.legendre.leggauss(4)[1])


def geometric_stiffness_varying(L, N):
    """Geometric stiffness ``int N(x) v'^T v' dx`` of planar frame elements under an axial force
    that varies along them (exact for ``N`` up to cubic in ``x``).

    A link's kinetostatic axial force varies along it (quadratically under its own inertia):
    an element's mean force in :func:`geometric_stiffness` makes the bending deflection
    converge at second order in the element length, the force at the Gauss points at fourth.

    Parameters
    ----------
    L : array_like, shape (n_el,)
        Element lengths [m].
    N : array_like, shape (..., n_el, 4)
        Axial force [N], tension positive, at the abscissae :data:`AXIAL_XI` of each element.

    Returns
    -------
    kG : ndarray, shape (..., n_el, 6, 6)
    """
    (L,) = _props(L)
    N = np.asarray(N, dtype=float)
    xi = AXIAL_XI
    dv = shape_slopes(L, xi)[..., V_DOFS]  # v' per bending DOF at the Gauss points, (n_el, 4, 4)
    basis = (AXIAL_W * L[:, None])[..., None, None] * dv[..., :, None] * dv[..., None, :]  # (n_el, 4, 4, 4)
    lead = N.shape[:-2]
    Ne = np.moveaxis(N.reshape((int(np.prod(lead)),) + N.shape[-2:]), 1, 0)  # (n_el, prod(lead), 4)
    kv = np.moveaxis(Ne @ basis.reshape(L.size, xi.size, 16), 0, 1).reshape(lead + (L.size, 4, 4))
    out = np.zeros(N.shape[:-1] + (6, 6))
    out[..., V_DOFS[:, None], V_DOFS[None, :]] = kv
    return out


def coupling_skew(L, rhoA):
    """Skew rigid-elastic coupling matrix ``m_s = int rhoA N^T S N dx``.

    Parameters
    ----------
    L, rhoA : array_like, shape (n_el,)
        Element lengths [m] and mass per unit length [kg/m].

    Returns
    -------
    ms : ndarray, shape (n_el, 6, 6)
        Skew-symmetric; ``ms = rhoA (B^T - B)`` with ``B = int N_u^T N_v dx``.
    """
    L, rhoA = _props(L, rhoA)
    n = L.size
    B = np.zeros((n, 6, 6))
    # rows u1, u2; columns v1, theta1, v2, theta2 (integrals of (1-xi), xi times Hermite)
    B[:, 0, 1] = 7.0 / 20.0 * L
    B[:, 0, 2] = L**2 / 20.0
    B[:, 0, 4] = 3.0 / 20.0 * L
    B[:, 0, 5] = -(L**2) / 30.0
    B[:, 3, 1] = 3.0 / 20.0 * L
    B[:, 3, 2] = L**2 / 30.0
    B[:, 3, 4] = 7.0 / 20.0 * L
    B[:, 3, 5] = -(L**2) / 20.0
    return rhoA[:, None, None] * (np.swapaxes(B, 1, 2) - B)


def linear_load(L, p0, p1):
    """Consistent nodal loads of a distributed load linear along the element.

    The load per unit length in local components is ``p(x) = p0 + x p1``
    for ``0 <= x <= L``.

    Parameters
    ----------
    L : array_like, shape (n_el,)
        Element lengths [m].
    p0 : array_like, shape (..., n_el, 2)
        Load per unit length at the start node, local (axial, transverse) [N/m].
    p1 : array_like, shape (..., n_el, 2)
        Load gradient [N/m^2].

    Returns
    -------
    f : ndarray, shape (..., n_el, 6)
        Consistent nodal loads [N, N m].
    """
    (L,) = _props(L)
    p0 = np.asarray(p0, dtype=float)
    p1 = np.asarray(p1, dtype=float)
    shape = np.broadcast_shapes(p0.shape, p1.shape)
    f = np.zeros(shape[:-1] + (6,))
    # int N dx and int x N dx for the axial (linear) and transverse (Hermite) fields
    iu = np.stack([L / 2, L / 2], axis=-1)
    ixu = np.stack([L**2 / 6, L**2 / 3], axis=-1)
    iv = np.stack([L / 2, L**2 / 12, L / 2, -(L**2) / 12], axis=-1)
    ixv = np.stack([3 * L**2 / 20, L**3 / 30, 7 * L**2 / 20, -(L**3) / 20], axis=-1)
    f[..., U_DOFS] = p0[..., 0:1] * iu + p1[..., 0:1] * ixu
    f[..., V_DOFS] = p0[..., 1:2] * iv + p1[..., 1:2] * ixv
    return f


def rotation_blocks(theta):
    """Global-to-local transformation ``T(theta)`` of planar frame elements.

    ``u_local = T u_global`` with ``T = blockdiag(R^T, 1, R^T, 1)`` and
    ``R(theta)`` the rotation by the element's angle ``theta`` [rad].

    Parameters
    ----------
    theta : array_like, shape (...)
        Element angles [rad].

    Returns
    -------
    T : ndarray, shape (..., 6, 6)
    """
    theta = np.asarray(theta, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    T = np.zeros(theta.shape + (6, 6))
    for o in (0, 3):
        T[..., o, o] = c
        T[..., o, o + 1] = s
        T[..., o + 1, o] = -s
        T[..., o + 1, o + 1] = c
        T[..., o + 2, o + 2] = 1.0
    return T


def hermite(xi, order: int = 0) -> np.ndarray:
    """Derivative ``order`` (0-3) w.r.t. ``xi`` of the cubic Hermite functions of the element.

    Parameters
    ----------
    xi : array_like, shape (n,)
        Fractions of the element length, 0 at node 1, 1 at node 2.
    order : int

    Returns
    -------
    H : ndarray, shape (4, n)
        ``H1, H2, H3, H4`` with ``v = H1 v1 + L H2 theta1 + H3 v2 + L H4 theta2``.
    """
    xi = np.atleast_1d(np.asarray(xi, dtype=float))
    if order == 0:
        return np.stack([1 - 3 * xi**2 + 2 * xi**3, xi - 2 * xi**2 + xi**3, 3 * xi**2 - 2 * xi**3,
                         -(xi**2) + xi**3])
    if order == 1:
        return np.stack([-6 * xi + 6 * xi**2, 1 - 4 * xi + 3 * xi**2, 6 * xi - 6 * xi**2, -2 * xi + 3 * xi**2])
    if order == 2:
        return np.stack([-6 + 12 * xi, -4 + 6 * xi, 6 - 12 * xi, -2 + 6 * xi])
    if order == 3:
        one = np.ones_like(xi)
        return np.stack([12 * one, 6 * one, -12 * one, 6 * one])
    raise InputError(f"hermite: order must be 0 to 3, got {order!r}")


def shape_functions(L, xi):
    """Axial and transverse shape functions at fractions ``xi`` of the element.

    Parameters
    ----------
    L : float or array_like, shape (n_el,)
        Element length(s) [m].
    xi : array_like, shape (n_pts,)
        Fractions of the element length, 0 at node 1, 1 at node 2.

    Returns
    -------
    N : ndarray, shape (n_el, n_pts, 2, 6)
        Rows: axial ``u(x)`` and transverse ``v(x)`` interpolation.
    """
    (L,) = _props(L)
    xi = np.atleast_1d(np.asarray(xi, dtype=float))
    N = np.zeros((L.size, xi.size, 2, 6))
    N[..., 0, 0] = 1 - xi
    N[..., 0, 3] = xi
    H = hermite(xi)
    N[..., 1, 1] = H[0]
    N[..., 1, 2] = L[:, None] * H[1]
    N[..., 1, 4] = H[2]
    N[..., 1, 5] = L[:, None] * H[3]
    return N


def _shape_derivative(L, xi, order: int) -> np.ndarray:
    """``d^order N_v / dx^order`` of the transverse shape functions, (n_el, n_pts, 6)."""
    (L,) = _props(L)
    xi = np.atleast_1d(np.asarray(xi, dtype=float))
    Lc = L[:, None]
    B = np.zeros((L.size, xi.size, 6))
    H = hermite(xi, order)
    B[..., 1] = H[0] / Lc**order
    B[..., 2] = H[1] / Lc**(order - 1)
    B[..., 4] = H[2] / Lc**order
    B[..., 5] = H[3] / Lc**(order - 1)
    return B


def shape_slopes(L, xi):
    """First derivatives ``d N_v / dx`` of the transverse shape functions.

    Parameters
    ----------
    L : array_like, shape (n_el,)
        Element lengths [m].
    xi : array_like, shape (n_pts,)
        Fractions of the element length.

    Returns
    -------
    S : ndarray, shape (n_el, n_pts, 6)
        Slope per unit DOF [1/m for translations, 1 for rotations].
    """
    return _shape_derivative(L, xi, 1)


def shape_curvatures(L, xi):
    """Second derivatives ``d^2 N_v / dx^2`` of the transverse shape functions.

    Parameters
    ----------
    L : array_like, shape (n_el,)
        Element lengths [m].
    xi : array_like, shape (n_pts,)
        Fractions of the element length.

    Returns
    -------
    B : ndarray, shape (n_el, n_pts, 6)
        Curvature per unit DOF [1/m^2 for translations, 1/m for rotations].
    """
    return _shape_derivative(L, xi, 2)
