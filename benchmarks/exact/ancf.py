"""Planar ANCF cable element (gradient-deficient, Euler-Bernoulli), geometrically exact.

Element coordinates ``e = (x_a, y_a, x'_a, y'_a, x_b, y_b, x'_b, y'_b)``: the
position and the slope vector ``r' = dr/ds`` at both ends, ``s`` the
reference arc length. The position field is the cubic Hermite interpolation
``r(s) = S(xi) e``, ``xi = s / L0``.

Strain measures (exact, no small-strain assumption on the kinematics):

* axial strain ``eps = |r'| - 1``,
* curvature ``kappa = (r' x r'') / |r'|^3``,

elastic energy ``U = 1/2 int (EA eps^2 + EI kappa^2) ds``. Internal forces
``dU/de`` and the exact tangent ``d2U/de2`` are integrated by Gauss quadrature;
all element work is batched over elements and quadrature points.

Damping: objective stiffness-proportional (Kelvin-Voigt on the strain
measures) ``Q_d = beta int (EA eps_dot deps/de + EI kappa_dot dkappa/de) ds``
with ``eps_dot = deps/de . e_dot`` (rigid-body motion is not damped).

Conventions: 8-vectors are handled as arrays of shape (..., 4, 2) (shape
function index, coordinate) and 8x8 matrices as (..., 4, 2, 4, 2); the flat
ordering is the C order of these shapes, i.e. the element ordering above.
"""

from __future__ import annotations

import numpy as np

__all__ = ["gauss01", "hermite", "mass_matrix", "ElementSet", "strains"]

_E = np.array([[0.0, 1.0], [-1.0, 0.0]])  # a x b = a^T E b
_I2 = np.eye(2)


def gauss01(n: int):
    """Gauss-Legendre points and weights on [0, 1] (weights sum to 1)."""
    x, w = np.polynomial.legendre.leggauss(int(n))
    return 0.5 * (x + 1.0), 0.5 * w


def hermite(xi, L):
    """Cubic Hermite shape functions and their arc-length derivatives.

    Parameters
    ----------
    xi : array_like, shape (g,)
        Local coordinates in [0, 1].
    L : array_like, shape (ne,)
        Reference element lengths.

    Returns
    -------
    N, N1, N2 : ndarray, shape (ne, g, 4)
        Values, first and second derivatives with respect to ``s``.
    """
    xi = np.atleast_1d(np.asarray(xi, float))[None, :]
    L = np.atleast_1d(np.asarray(L, float))[:, None]
    x2, x3 = xi * xi, xi * xi * xi
    one = np.ones_like(L)
    N = np.stack([(1 - 3 * x2 + 2 * x3) * one, L * (xi - 2 * x2 + x3),
                  (3 * x2 - 2 * x3) * one, L * (x3 - x2)], -1)
    N1 = np.stack([(-6 * xi + 6 * x2) / L, (1 - 4 * xi + 3 * x2) * one,
                   (6 * xi - 6 * x2) / L, (3 * x2 - 2 * xi) * one], -1)
    N2 = np.stack([(-6 + 12 * xi) / L**2, (-4 + 6 * xi) / L,
                   (6 - 12 * xi) / L**2, (-2 + 6 * xi) / L], -1)
    return N, N1, N2


def mass_matrix(L, rhoA, ngauss: int = 5):
    """Consistent mass matrices ``int rhoA S^T S ds``, shape (ne, 8, 8) (exact for ngauss >= 4)."""
    L = np.atleast_1d(np.asarray(L, float))
    rhoA = np.broadcast_to(np.asarray(rhoA, float), L.shape)
    xg, wg = gauss01(ngauss)
    N, _, _ = hermite(xg, L)
    m4 = np.einsum("g,egk,egl->ekl", wg, N, N) * (rhoA * L)[:, None, None]
    return np.einsum("ekl,ij->ekilj", m4, _I2).reshape(-1, 8, 8)


def strains(E, L, xi):
    """Axial strain and curvature at local coordinates ``xi`` of each element.

    Parameters
    ----------
    E : ndarray, shape (ne, 8)
        Element coordinates.
    L : ndarray, shape (ne,)
    xi : array_like, shape (g,)

    Returns
    -------
    eps, kappa : ndarray, shape (ne, g)
    """
    _, N1, N2 = hermite(xi, L)
    Ek = E.reshape(-1, 4, 2)
    a = np.einsum("egk,ekj->egj", N1, Ek)
    b = np.einsum("egk,ekj->egj", N2, Ek)
    n = np.sqrt(a[..., 0] ** 2 + a[..., 1] ** 2)
    c = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return n - 1.0, c / n**3


class ElementSet:
    """A batch of ANCF cable elements with fixed properties.

    Parameters
    ----------
    L, EA, EI, rhoA : array_like, shape (ne,)
        Reference length, axial and bending stiffness, mass per length.
    beta : float or array_like
        Stiffness-proportional damping coefficient [s] on the strain rates.
    ngauss : int
        Gauss points per element.
    """

    def __init__(self, L, EA, EI, rhoA, beta=0.0, ngauss: int = 5):
        self.L = np.atleast_1d(np.asarray(L, float))
        ne = self.L.size
        self.EA = np.broadcast_to(np.asarray(EA, float), (ne,)).copy()
        self.EI = np.broadcast_to(np.asarray(EI, float), (ne,)).copy()
        self.rhoA = np.broadcast_to(np.asarray(rhoA, float), (ne,)).copy()
        self.beta = np.broadcast_to(np.asarray(beta, float), (ne,)).copy()
        self.ngauss = int(ngauss)
        xg, wg = gauss01(ngauss)
        self.xg = xg
        _, self.N1, self.N2 = hermite(xg, self.L)          # (ne, g, 4)
        self.wL = wg[None, :] * self.L[:, None]               # (ne, g) quadrature weights * L
        # products of shape-function derivatives, (ne, g, 4, 4)
        self.P11 = np.einsum("egk,egl->egkl", self.N1, self.N1)
        self.P12 = np.einsum("egk,egl->egkl", self.N1, self.N2)
        self.P1112 = np.stack([self.P11, self.P12], 2)       # (ne, g, 2, 4, 4)
        self.N12 = np.stack([self.N1, self.N2], 1)           # (ne, 2, g, 4)
        self.EAw = self.EA[:, None] * self.wL
        self.EIw = self.EI[:, None] * self.wL
        self.bEAw = self.beta[:, None] * self.EAw
        self.bEIw = self.beta[:, None] * self.EIw
        self.damped = bool(np.any(self.beta != 0.0))
        self.M = mass_matrix(self.L, self.rhoA, max(4, ngauss))

    @property
    def n(self) -> int:
        return self.L.size

    # --------------------------------------------------------------- evaluate
    def forces(self, E, Ed=None, *, tangent=True):
        """Internal (elastic + damping) forces and their Jacobians.

        Parameters
        ----------
        E : ndarray, shape (ne, 8)
            Element coordinates.
        Ed : ndarray, shape (ne, 8), optional
            Their rates (for the damping force).
        tangent : bool
            Also return the Jacobians.

        Returns
        -------
        Q : ndarray, shape (ne, 8)
        K : ndarray, shape (ne, 8, 8) or None
            ``dQ/de`` (elastic tangent plus the position derivative of the damping force).
        C : ndarray, shape (ne, 8, 8) or None
            ``dQ/de_dot``.

        Notes
        -----
        With ``a = r'``, ``b = r''``, ``n = |a|``, ``c = a x b`` and the 8-vectors
        ``deps = N1 (x) a/n``, ``Na = N1 (x) a``, ``dc = N1 (x) E b + N2 (x) E^T a``,
        ``dkap = dc / n^3 - 3 c Na / n^5``, the Hessians are::

            d2eps = (N1 N1^T) (x) I / n - deps deps^T / n
            d2kap = (N1 N2^T (x) E + N2 N1^T (x) E^T) / n^3 - 3 (dc Na^T + Na dc^T) / n^5
                    + 15 c Na Na^T / n^7 - 3 c (N1 N1^T) (x) I / n^5

        so every quadrature sum is a weighted Gram product of 8-vectors or a
        Kronecker product of a summed 4x4 matrix with a constant 2x2 one.
        """
        ne = self.n
        g = self.ngauss
        N1, N2 = self.N1, self.N2
        ab = self.N12 @ E.reshape(ne, 1, 4, 2)                 # (ne, 2, g, 2): r', r''
        a, b = ab[:, 0], ab[:, 1]
        ax, ay, bx, by = a[..., 0], a[..., 1], b[..., 0], b[..., 1]
        n2 = ax * ax + ay * ay
        n = np.sqrt(n2)
        c = ax * by - ay * bx
        inv_n = 1.0 / n
        inv_n3 = inv_n / n2
        inv_n5 = inv_n3 / n2
        eps = n - 1.0
        kap = c * inv_n3
        # 2-vectors of the gradients: deps = N1 (x) u, Na = N1 (x) a, dc = N1 (x) pa + N2 (x) pb
        u = a * inv_n[..., None]
        pa = np.stack([by, -bx], -1)
        pb = np.stack([-ay, ax], -1)
        N1e = N1[..., :, None]
        N2e = N2[..., :, None]
        deps = (N1e * u[..., None, :]).reshape(ne, g, 8)
        Na = (N1e * a[..., None, :]).reshape(ne, g, 8)
        dc = (N1e * pa[..., None, :] + N2e * pb[..., None, :]).reshape(ne, g, 8)
        dkap = dc * inv_n3[..., None] - (3.0 * c * inv_n5)[..., None] * Na
        EAw = self.EAw
        EIw = self.EIw
        fa = EAw * eps
        fb = EIw * kap
        damp = Ed is not None and self.damped
        if damp:
            abd = self.N12 @ Ed.reshape(ne, 1, 4, 2)
            ad, bd = abd[:, 0], abd[:, 1]
            Ed8 = Ed.reshape(ne, 1, 8)
            epsd = np.sum(deps * Ed8, -1)
            kapd = np.sum(dkap * Ed8, -1)
            bEA = self.bEAw
            bEI = self.bEIw
            fa = fa + bEA * epsd
            fb = fb + bEI * kapd
        V = np.stack([deps, dkap], 2)                              # (ne, g, 2, 8)
        Q = np.einsum("egc,egci->ei", np.stack([fa, fb], -1), V)
        if not tangent:
            return Q, None, None
        # K = sum_g sum_cd C_cd V_c V_d^T over the vectors (deps, dkap, dc, Na[, g_a, g_b])
        if damp:
            ud = np.sum(u * ad, -1)
            g_a = (N1e * ((ad - u * ud[..., None]) * inv_n[..., None])[..., None, :]).reshape(ne, g, 8)
            Eb = np.stack([bd[..., 1], -bd[..., 0]], -1)
            ETa = np.stack([-ad[..., 1], ad[..., 0]], -1)
            a_ad = np.sum(a * ad, -1)
            cd = np.sum(pa * ad, -1) + np.sum(pb * bd, -1)
            Na_ed = (N1e * ad[..., None, :]).reshape(ne, g, 8)
            g_b = (((N1e * Eb[..., None, :] + N2e * ETa[..., None, :]).reshape(ne, g, 8)) * inv_n3[..., None]
                   - 3.0 * inv_n5[..., None] * (dc * a_ad[..., None] + Na * cd[..., None])
                   + (15.0 * c * inv_n5 / n2 * a_ad)[..., None] * Na
                   - (3.0 * c * inv_n5)[..., None] * Na_ed)
        else:
            g_a = g_b = None
        # K = sum_g [X0 W0^T + ...]: X = (deps, dkap, dc, Na) against the weighted combinations W
        c_aa = (EAw - fa * inv_n)[..., None]
        c_dn = (-3.0 * fb * inv_n5)[..., None]
        W0 = c_aa * deps
        W1 = EIw[..., None] * dkap
        if damp:
            W0 = W0 + bEA[..., None] * g_a
            W1 = W1 + bEI[..., None] * g_b
        W2 = c_dn * Na
        W3 = c_dn * dc + (15.0 * fb * c * inv_n5 / n2)[..., None] * Na
        X = np.stack([deps, dkap, dc, Na], 2).reshape(ne, g * 4, 8)
        W = np.stack([W0, W1, W2, W3], 2).reshape(ne, g * 4, 8)
        K = np.swapaxes(X, 1, 2) @ W
        # Kronecker parts: (sum_g coef P11) (x) I + (sum_g coef P12) (x) E + transpose
        coef = np.stack([fa * inv_n - 3.0 * fb * c * inv_n5, fb * inv_n3], -1)    # (ne, g, 2)
        P = np.einsum("egc,egckl->eckl", coef, self.P1112)                       # (ne, 2, 4, 4)
        K5 = K.reshape(ne, 4, 2, 4, 2)                  # a view: [k, i, l, j]
        K5[:, :, 0, :, 0] += P[:, 0]
        K5[:, :, 1, :, 1] += P[:, 0]
        D = P[:, 1] - np.swapaxes(P[:, 1], 1, 2)        # P12 (x) E + P12^T (x) E^T
        K5[:, :, 0, :, 1] += D
        K5[:, :, 1, :, 0] -= D
        C = None
        if damp:
            V2 = V.reshape(ne, g * 2, 8)
            Wd = (np.stack([bEA, bEI], -1)[..., None] * V).reshape(ne, g * 2, 8)
            C = np.swapaxes(V2, 1, 2) @ Wd
        return Q, K, C

    def energy(self, E):
        """Elastic energy per element, shape (ne,)."""
        _, N1, N2 = None, self.N1, self.N2
        Ek = E.reshape(-1, 4, 2)
        a = np.einsum("egk,ekj->egj", N1, Ek)
        b = np.einsum("egk,ekj->egj", N2, Ek)
        n = np.sqrt(a[..., 0] ** 2 + a[..., 1] ** 2)
        c = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
        eps, kap = n - 1.0, c / n**3
        return 0.5 * np.sum(self.wL * (self.EA[:, None] * eps**2 + self.EI[:, None] * kap**2), axis=1)
