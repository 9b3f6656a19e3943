"""Modal damping matrices: exact at given instants, and over a whole cycle by interpolation.

:class:`kedfem.fe.effects.ModalDamping` gives every elastic mode of the
structural ``(K, M)`` at an instant the ratio ``zeta``::

    C = M Phi diag(2 zeta omega) Phi^T M,     K Phi = M Phi diag(omega^2),  Phi^T M Phi = I

which costs a symmetric eigenproblem per instant (:func:`modal_damping`). A
periodic solve needs ``C`` at thousands of instants (every stage of every
time element of every level), while ``C(t)`` is a smooth periodic function
of time: the mass and structural stiffness change only with the rigid-body
positions, and ``C = 2 zeta M^(1/2) (M^(-1/2) K M^(-1/2))^(1/2) M^(1/2)`` is an
analytic function of them. :class:`DampingField` therefore evaluates it
exactly at ``m`` equally spaced instants and anywhere else by trigonometric
interpolation (of the upper triangle, the harmonics that matter), doubling
``m`` until the harmonics of the top eighth of the
sampled band (``3 m / 8 .. m / 2``) fall below :data:`FIELD_RTOL` of each
entry's scale ``sqrt(C_ii C_jj)`` (the interpolation error is of that order;
a relative error ``e`` of the damping matrix moves the response by at most
about ``e``), and checks the interpolant
against exact matrices at instants between the samples. A field that does
not settle by :data:`MAX_SAMPLES` falls back to the exact matrices at every
instant.
"""

from __future__ import annotations

import logging
import math
from typing import Callable

import numpy as np

from ..solvers.eigen import generalised_eigh

__all__ = ["modal_damping", "DampingField", "FIELD_RTOL", "MAX_SAMPLES"]

log = logging.getLogger(__name__)

#: largest harmonic of the top eighth of the sampled band, relative to each entry's scale
#: ``sqrt(C_ii C_jj)``, for the interpolation to be accepted
FIELD_RTOL = 1e-10
#: largest relative difference, on the same scale, between the interpolant and exact
#: matrices at check instants between the samples
CHECK_RTOL = 1e-9
#: first and largest numbers of samples per cycle
FIRST_SAMPLES = 32
MAX_SAMPLES = 1024
#: instants between the samples where the accepted interpolant is checked
CHECKS = 3


def modal_damping(M: np.ndarray, K: np.ndarray, zeta: float, name: str = "",
                  labels=None) -> np.ndarray:
    """Exact modal damping matrices at a batch of instants.

    ``M = L L^T``, ``L^-1 K L^-T = V diag(omega^2) V^T``, ``C = L V diag(2
    zeta omega) V^T L^T`` (:func:`kedfem.solvers.eigen.generalised_eigh`, on the
    worker threads); modes of frequency below ``1e-8`` of the largest
    (rigid-body modes) get no damping.

    Parameters
    ----------
    M, K : ndarray, shape (nt, N, N)
        Mass [kg] and structural stiffness [N/m], symmetric.
    zeta : float
        Damping ratio of every elastic mode.
    name : str
        Mechanism name for messages.
    labels : sequence of str, optional
        DOF labels, to name massless DOFs.

    Returns
    -------
    C : ndarray, shape (nt, N, N)
        [N s/m].

    Raises
    ------
    SingularMassError
        ``M`` is not positive definite.
    KedError
        The eigenproblem has no solution in floating point (units).
    """
    lam, L, _Li, V = generalised_eigh(M, K, name, labels, parallel=True, what="modal damping")
    om = np.sqrt(np.clip(lam, 0.0, None))
    scale = np.max(om, axis=-1, keepdims=True) if om.size else np.zeros(om.shape[:-1] + (1,))
    om = np.where(om > 1e-8 * np.maximum(scale, 1e-300), om, 0.0)
    LV = L @ V
    return (LV * (2.0 * zeta * om)[..., None, :]) @ np.swapaxes(LV, -1, -2)


class DampingField:
    """Modal damping ``C(t)`` over a cycle: exact samples, trigonometric interpolation.

    Parameters
    ----------
    exact : callable
        ``exact(t)`` -> ndarray (k, N, N): the exact matrices at instants
        ``t`` (k,) [s] (:func:`modal_damping` of the structural matrices there).
    period : float
        Cycle [s].
    rtol : float
        Acceptance level of the highest harmonics (see the module docstring).

    Attributes
    ----------
    samples : int
        Instants per cycle the interpolant is built on (0 when it fell back
        to exact matrices at every instant).
    constant : bool
        Every sample is the same matrix (a time-invariant scene): :meth:`at`
        returns it exactly.
    error : float
        Largest difference between the interpolant and the exact matrices at
        the check instants, relative to each entry's scale.
    """

    def __init__(self, exact: Callable[[np.ndarray], np.ndarray], period: float,
                 rtol: float = FIELD_RTOL):
        self._exact = exact
        self.period = float(period)
        self.samples = 0
        self.constant = False
        self.error = 0.0
        m = FIRST_SAMPLES
        C = exact(np.arange(m) * (self.period / m))
        while True:
            if np.array_equal(C, np.broadcast_to(C[0], C.shape)):
                self.constant, self.samples, self._C0 = True, m, C[0].copy()
                return
            scale = self._scale(C)
            coef = np.fft.rfft(C, axis=0) / m
            upper = np.abs(coef[(3 * m) // 8:]) / scale
            tail = float(upper.max()) if upper.size else 0.0
            if tail <= rtol:
                break
            if 2 * m > MAX_SAMPLES:
                log.info("modal damping: the harmonics of C(t) reach %.1e of its scale at %d samples "
                         "per cycle; exact matrices at every instant instead", tail, m)
                self._coef = None
                return
            # the instants between the samples double the sampling
            mid = exact((np.arange(m) + 0.5) * (self.period / m))
            both = np.empty((2 * m,) + C.shape[1:])
            both[0::2], both[1::2] = C, mid
            C, m = both, 2 * m
        self.samples = m
        N = C.shape[1]
        self._iu = np.triu_indices(N)
        # harmonics whose every entry is below a thousandth of the acceptance level add nothing
        sig = np.flatnonzero((np.abs(coef) / scale).reshape(coef.shape[0], -1).max(axis=1) > 1e-3 * rtol)
        keep = int(sig.max()) + 1 if sig.size else 1
        self._coef = self._real_coefficients(coef[:keep, self._iu[0], self._iu[1]], m)
        # belt and braces: exact matrices between the samples
        tc = (np.arange(CHECKS) + 0.37) * (self.period / CHECKS)
        self.error = float(np.max(np.abs(self._interpolate(tc) - exact(tc)) / scale))
        if self.error > CHECK_RTOL:
            log.info("modal damping: interpolant %.1e off the exact matrices between samples; "
                     "exact matrices at every instant instead", self.error)
            self._coef, self.samples = None, 0
        else:
            log.debug("modal damping: %d samples per cycle, interpolation error %.1e", m, self.error)

    @staticmethod
    def _scale(C):
        d = np.sqrt(np.abs(np.diagonal(C, axis1=-2, axis2=-1)).max(axis=0))
        s = d[:, None] * d[None, :]
        return np.where(s > 0, s, max(float(s.max()), 1e-300))

    @staticmethod
    def _real_coefficients(coef, m):
        """Rows ``[a_0, a_1 .. a_K, b_1 .. b_K]`` with ``C(t) = sum a_k cos(k w t) - b_k sin(k w t)``.

        ``coef`` (K + 1, entries): the rfft coefficients / m of the upper triangle.
        """
        w = np.full(coef.shape[0], 2.0)
        w[0] = 1.0
        if m % 2 == 0 and coef.shape[0] == m // 2 + 1:
            w[-1] = 1.0
        c = coef * w[:, None]
        return np.concatenate([c.real, c.imag[1:]], axis=0)

    def _interpolate(self, t):
        K = (self._coef.shape[0] + 1) // 2  # harmonics 0..K-1
        ph = np.multiply.outer(np.asarray(t, float) * (2.0 * math.pi / self.period), np.arange(K))
        basis = np.concatenate([np.cos(ph), -np.sin(ph[:, 1:])], axis=1)
        vals = basis @ self._coef  # (k, N (N + 1) / 2)
        i, j = self._iu
        N = int(i.max()) + 1
        out = np.empty((vals.shape[0], N, N))
        out[:, i, j] = vals
        out[:, j, i] = vals
        return out

    def at(self, t) -> np.ndarray:
        """``C`` at instants ``t`` (k,) [s], shape (k, N, N) [N s/m]."""
        t = np.asarray(t, dtype=float)
        if self.constant:
            return np.broadcast_to(self._C0, (t.size,) + self._C0.shape).copy()
        if self._coef is None:
            return self._exact(t)
        return self._interpolate(t)
