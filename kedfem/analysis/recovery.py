"""Section forces of flexible links by element equilibrium (stress recovery).

The curvature of the Hermite interpolation, ``EI v_h''``, is linear along an
element, so nodal moments averaged from it converge only as ``h^2`` and miss
the bending that the distributed loads cause between the nodes (measured on
the four-bar preset's 4-element links: peak stresses 3 % high). Within an
Euler-Bernoulli element the exact deflection, given its end displacements,
is the Hermite interpolation plus the particular solution of the element
clamped at both ends under its distributed load ``q(x)``::

    M(x) = EI v_h''(x) + M_q(x),      N(x) = EA u_h' + N_q(x)

``M_q`` is the moment of a clamped-clamped beam under ``q``, ``N_q`` the
force of a fixed-fixed bar under the axial load ``p`` (the consistent nodal
loads of the element are exactly those fixed-end reactions, so the element
stays in equilibrium with its end forces). In the link's rotating frame
(``d`` the element's local DOFs, dots rotating-frame rates, ``w, a`` the
link's angular speed and acceleration, ``r0''`` the rigid-body acceleration
of the point, ``N`` the axial force)::

    q = -rhoA [(R^T r0'')_y + v'' + 2 w u' + a u - w^2 v] + rhoA g_y + (N v_h')'
    p = -rhoA [(R^T r0'')_x + u'' - 2 w v' - a v - w^2 u] + rhoA g_x

(``(N v_h')' = N v_h'' - p v_h'`` with ``N`` varying along the element as the
axial load ``p`` makes it) with each term present only when the scene's effects put it in the model
(``inertia``, ``coupling``, ``gravity``, ``axial_stiffening`` or
``geometric_nonlinearity``). The loads are taken cubic along the element
(their values at four points; the rigid-body part is linear, the elastic
part the Hermite interpolation), so ``M_q`` and ``N_q`` follow from fixed
linear maps (:func:`fixed_end_maps`). Lumped-mass and Timoshenko elements
keep the interpolated forces. Damping forces are left out of ``q`` (they are
not attributed to elements under modal damping).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.polynomial import Polynomial

from ..model import elements as el

__all__ = ["LOAD_POINTS", "fixed_end_maps", "periodic_rates", "element_loads", "section_forces"]

#: fractions of the element where its distributed loads are sampled (a cubic through them)
LOAD_POINTS = np.array([0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0])


def _lagrange(j: int) -> Polynomial:
    """The Lagrange polynomial of :data:`LOAD_POINTS` that is 1 at the ``j``-th and 0 at the others."""
    others = np.delete(LOAD_POINTS, j)
    return Polynomial.fromroots(others) / np.prod(LOAD_POINTS[j] - others)


@lru_cache(maxsize=1)
def _basis() -> tuple[np.ndarray, np.ndarray]:
    """Power-series coefficients (4, 7) of the fixed-end moment and force of each Lagrange load
    (read-only; computed once)."""
    cm = np.zeros((LOAD_POINTS.size, 7))
    cn = np.zeros((LOAD_POINTS.size, 7))

    def integral(p):
        P = p.integ()
        return P(1.0) - P(0.0)

    for j in range(LOAD_POINTS.size):
        lj = _lagrange(j)  # Lagrange load, L = 1
        # M'' = q with v = v' = 0 at both ends: M = Q2 + a + b x, int M = 0, int (1 - x) M = 0
        Q2 = lj.integ(2)
        a, b = np.linalg.solve([[1.0, 0.5], [0.5, 1.0 / 6.0]],
                               [-integral(Q2), -integral(Polynomial([1.0, -1.0]) * Q2)])
        c = (Q2 + Polynomial([a, b])).coef
        cm[j, :c.size] = c
        # N' = -p with u = 0 at both ends: N = -int_0^x p + c, int N = 0
        Q1 = lj.integ(1)
        c = (Polynomial([integral(Q1)]) - Q1).coef
        cn[j, :c.size] = c
    cm.flags.writeable = cn.flags.writeable = False
    return cm, cn


def fixed_end_maps(xi) -> tuple[np.ndarray, np.ndarray]:
    """Linear maps from loads at :data:`LOAD_POINTS` to fixed-end section forces.

    Parameters
    ----------
    xi : array_like, shape (nx,)
        Fractions of the element length where the forces are wanted.

    Returns
    -------
    W : ndarray, shape (nx, 4)
        ``M_q(xi) = L^2 W @ q(LOAD_POINTS)`` [N m] for a transverse load ``q``
        [N/m] (moment ``EI v''`` of the element clamped at both ends).
    Wn : ndarray, shape (nx, 4)
        ``N_q(xi) = L Wn @ p(LOAD_POINTS)`` [N] for an axial load ``p`` [N/m]
        (bar fixed at both ends; tension positive).
    """
    x = np.atleast_1d(np.asarray(xi, dtype=float))
    powers = x[:, None] ** np.arange(7)[None, :]
    cm, cn = _basis()
    return powers @ cm.T, powers @ cn.T


def periodic_rates(X: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
    """First and second time derivatives of a periodic history sampled uniformly (spectral).

    Parameters
    ----------
    X : ndarray, shape (n, ...)
        Values at ``t0 + k T / n``.
    period : float
        ``T`` [s].

    Returns
    -------
    dX, ddX : ndarray, shape (n, ...)
    """
    n = X.shape[0]
    F = np.fft.rfft(X, axis=0)
    k = np.arange(F.shape[0], dtype=float)
    if n % 2 == 0:
        k[-1] = 0.0  # the Nyquist harmonic has no defined derivative on the samples
    iw = (1j * 2.0 * math.pi / period * k).reshape((-1,) + (1,) * (X.ndim - 1))
    return np.fft.irfft(F * iw, n=n, axis=0), np.fft.irfft(F * iw * iw, n=n, axis=0)


def element_loads(d, dd, ddd, *, L, rhoA, s1, omega, alpha, a_loc, g_loc=None, N=None,
                  inertia=True, coupling=True):
    """Distributed loads of a link's elements at :data:`LOAD_POINTS`, in the link's frame.

    Parameters
    ----------
    d, dd, ddd : ndarray, shape (n, ne, 6)
        Local element DOFs and their rotating-frame rates [m, rad, /s, /s^2].
    L : float or ndarray, shape (ne,)
        Element length(s) [m].
    rhoA : float
        Mass per length [kg/m].
    s1 : ndarray, shape (ne,)
        Distance of each element's start from the link's joint ``a`` [m].
    omega, alpha : ndarray, shape (n,)
        Angular speed [rad/s] and acceleration [rad/s^2] of the link.
    a_loc : ndarray, shape (n, 2)
        Acceleration of joint ``a`` in the link's frame [m/s^2].
    g_loc : ndarray, shape (n, 2), optional
        Gravity in the link's frame [m/s^2] (None: no weight).
    N : ndarray, shape (n, ne) or (n, ne, 4), optional
        Axial force of the elements [N]: the mean (the axial load ``p`` makes it vary along
        the element) or its values at :data:`LOAD_POINTS` (None: no geometric stiffness).
    inertia, coupling : bool
        The rigid-body inertial load, and the rotating-frame terms of the
        elastic motion, are in the model.

    Returns
    -------
    q, p : ndarray, shape (n, ne, 4)
        Transverse and axial loads per length [N/m].
    """
    if np.ndim(L) == 0:  # one element length
        Nf = el.shape_functions(L, LOAD_POINTS)[0]  # (4, 2, 6)
        Nt = Nf.reshape(-1, Nf.shape[-1]).T  # (6, 8): one product per rate

        def interp(x):
            return (x @ Nt).reshape(x.shape[:-1] + Nf.shape[:2])

        u, ud, udd = interp(d), interp(dd), interp(ddd)
        Lx = L
    else:  # an element length each
        Nf = el.shape_functions(L, LOAD_POINTS)  # (ne, 4, 2, 6)
        u = np.einsum("epij,tej->tepi", Nf, d)
        ud = np.einsum("epij,tej->tepi", Nf, dd)
        udd = np.einsum("epij,tej->tepi", Nf, ddd)
        Lx = np.asarray(L, float)[:, None]
    q = -rhoA * udd[..., 1]
    p = -rhoA * udd[..., 0]
    w = omega[:, None, None]
    a = alpha[:, None, None]
    if coupling:
        q = q - rhoA * (2.0 * w * ud[..., 0] + a * u[..., 0] - w * w * u[..., 1])
        p = p - rhoA * (-2.0 * w * ud[..., 1] - a * u[..., 1] - w * w * u[..., 0])
    if inertia:
        x = (s1[:, None] + LOAD_POINTS[None, :] * Lx)[None]  # (1, ne, 4)
        q = q - rhoA * (a_loc[:, None, None, 1] + a * x)
        p = p - rhoA * (a_loc[:, None, None, 0] - w * w * x)
    if g_loc is not None:
        q = q + rhoA * g_loc[:, None, None, 1]
        p = p + rhoA * g_loc[:, None, None, 0]
    if N is not None:
        # (N v')' = N v'' + N' v', N along the element: the mean plus the fixed-end force of p,
        # or given at the load points
        if N.ndim == q.ndim:
            Nx = N
        else:
            Nx = N[..., None] + Lx * (p @ fixed_end_maps(LOAD_POINTS)[1].T)
        dN = (Nx @ _LOAD_SLOPES.T) / Lx
        B = el.shape_curvatures(L, LOAD_POINTS)  # (ne or 1, 4, 6)
        S = el.shape_slopes(L, LOAD_POINTS)
        if np.ndim(L) == 0:
            q = q + Nx * (d @ B[0].T) + dN * (d @ S[0].T)
        else:
            q = q + Nx * np.einsum("epi,tei->tep", B, d) + dN * np.einsum("epi,tei->tep", S, d)
    return q, p


def _load_slopes() -> np.ndarray:
    """``D`` (4, 4): the slope ``d f / d xi`` at :data:`LOAD_POINTS` of the cubic through ``f`` there."""
    return np.stack([_lagrange(j).deriv()(LOAD_POINTS) for j in range(LOAD_POINTS.size)], axis=1)


_LOAD_SLOPES = _load_slopes()


def section_forces(d, q, p, *, L, EA, EI, xi, N_h=None):
    """Bending moment and axial force along the elements by element equilibrium.

    Parameters
    ----------
    d : ndarray, shape (n, ne, 6)
        Local element DOFs.
    q, p : ndarray, shape (n, ne, 4) or None
        Distributed loads at :data:`LOAD_POINTS` (:func:`element_loads`);
        None keeps the interpolated forces.
    L : float or ndarray, shape (ne,)
        Element length(s) [m].
    EA, EI : float
        Axial [N] and bending [N m^2] rigidity.
    xi : array_like, shape (nx,)
        Fractions of each element where the forces are wanted.
    N_h : ndarray, shape (n, ne), optional
        Interpolated axial force (default ``EA (u2 - u1) / L``).

    Returns
    -------
    M, N : ndarray, shape (n, ne, nx)
        ``EI v''`` [N m] and tension [N].
    """
    if np.ndim(L) == 0:  # one element length
        B = el.shape_curvatures(L, xi)[0]  # (nx, 6)
        M = EI * (d @ B.T)
        Lx = L
    else:  # an element length each
        B = el.shape_curvatures(L, xi)  # (ne, nx, 6)
        M = EI * np.einsum("exi,tei->tex", B, d)
        L = np.asarray(L, float)
        Lx = L[:, None]
    if N_h is None:
        N_h = EA * (d[..., 3] - d[..., 0]) / L
    N = np.broadcast_to(N_h[..., None], M.shape).copy()
    if q is not None:
        W, Wn = fixed_end_maps(xi)
        M = M + Lx * Lx * (q @ W.T)
        N = N + Lx * (p @ Wn.T)
    return M, N
