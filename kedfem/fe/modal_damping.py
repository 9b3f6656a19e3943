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
sampled band (``3 m / 8 .. m / 2``) fall below ``rtol`` of each
entry's scale ``sqrt(C_ii C_jj)`` (a thousandth of the solve's tolerance, at least
:data:`FIELD_RTOL`, in :func:`field_over_cycle`; the interpolation error is of that order;
a relative error ``e`` of the damping matrix moves the response by at most
about ``e``), and checks the interpolant
against exact matrices at instants between the samples. A field that does
not settle by :data:`MAX_SAMPLES` falls back to the exact matrices at every
instant.

Where a block slides on a flexible link, ``C(t)`` has a kink at every instant the block
crosses a node of the link (the element its mass and contact stiffness follow changes), and
the harmonics decay slowly: :class:`PiecewiseDampingField` interpolates it between the kinks
by Chebyshev series instead.
"""

from __future__ import annotations

import copy
import logging
import math
from typing import Callable

import numpy as np
from scipy import fft

from ..solvers.eigen import generalised_eigh

__all__ = ["modal_damping", "DampingField", "PiecewiseDampingField", "field_over_cycle", "FIELD_RTOL",
           "MAX_SAMPLES", "PIECE_POINTS", "PIECE_COST"]

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
#: first and largest Chebyshev degrees per piece of :class:`PiecewiseDampingField`
PIECE_POINTS = (8, 64)
#: exact damping matrices a piece between two kinks costs, about (degree 32 and its checks)
PIECE_COST = 40


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
    max_samples : int
        Most samples per cycle (at most :data:`MAX_SAMPLES`): a field that needs more falls
        back to exact matrices at every instant.

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
                 rtol: float = FIELD_RTOL, max_samples: int = MAX_SAMPLES):
        self._exact = exact
        self.period = float(period)
        self.samples = 0
        self.constant = False
        self.error = 0.0
        m = FIRST_SAMPLES
        # the check instants (between the samples of every doubling) ride on the first batch:
        # an evaluation has a fixed cost of about ten instants' (the motion, the assembler)
        tc = (np.arange(CHECKS) + 0.37) * (self.period / CHECKS)
        both = exact(np.concatenate([np.arange(m) * (self.period / m), tc]))
        C, Cc = both[:m], both[m:]
        while True:
            if np.array_equal(C, np.broadcast_to(C[0], C.shape)) and np.array_equal(
                    Cc, np.broadcast_to(C[0], Cc.shape)):
                self.constant, self.samples, self._C0 = True, m, C[0].copy()
                return
            scale = self._scale(C)
            coef = np.fft.rfft(C, axis=0) / m
            upper = np.abs(coef[(3 * m) // 8:]) / scale
            tail = float(upper.max()) if upper.size else 0.0
            if tail <= rtol:
                break
            if 2 * m > max_samples:
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
        self._coef = _full(self._real_coefficients(coef[:keep, self._iu[0], self._iu[1]], m), self._iu, N)
        # belt and braces: exact matrices between the samples
        self.error = float(np.max(np.abs(self._interpolate(tc) - Cc) / scale))
        if self.error > max(CHECK_RTOL, 10.0 * rtol):
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
        N = int(self._iu[0].max()) + 1
        return (basis @ self._coef).reshape(-1, N, N)  # the series of every entry, both triangles

    def at(self, t) -> np.ndarray:
        """``C`` at instants ``t`` (k,) [s] (a scalar is one instant), shape (k, N, N) [N s/m]."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.constant:
            return np.broadcast_to(self._C0, (t.size,) + self._C0.shape).copy()
        if self._coef is None:
            return self._exact(t)
        return self._interpolate(t)

    def at_period(self, period: float) -> "DampingField":
        """This field on a cycle of ``period`` [s]: the same matrices at the same phase ``t / period``.

        For the same mechanism at another drive speed (every drive scaled alike, as
        :meth:`kedfem.model.mechanism.Mechanism.with_speed` does): the modal damping comes from the
        structural mass and stiffness of the configuration, which the phase alone sets, so a
        continuation in speed builds its field once (a tenth of the four-bar's run-up at 350 rpm
        went to building it again at every speed).
        """
        new = copy.copy(self)
        new.period = float(period)
        base, scale = self._exact, self.period / float(period)
        new._exact = lambda t: base(np.asarray(t, dtype=float) * scale)
        return new


def _full(c: np.ndarray, iu, N: int) -> np.ndarray:
    """Coefficients (K, N N) of every entry from those (K, N (N + 1) / 2) of the upper triangle
    ``iu``: an interpolant then writes its matrices by one product, no scatter into both triangles
    (a tenth of the Whitworth's solve went to that scatter)."""
    full = np.empty((c.shape[0], N, N))
    i, j = iu
    full[:, i, j] = c
    full[:, j, i] = c
    return full.reshape(c.shape[0], N * N)


class PiecewiseDampingField:
    """Modal damping ``C(t)`` over a cycle with kinks: a Chebyshev interpolant between them.

    Where a block crosses a node of its link, the mass and stiffness it adds follow the
    shape functions of another element: ``C(t)`` has a kink there, and its trigonometric
    interpolant (:class:`DampingField`) does not settle before 1024 samples (the Whitworth's
    harmonics stayed above 1e-6 of the entries' scale). Between two kinks it is smooth: each
    piece gets the Chebyshev series through the exact matrices at the Chebyshev-Lobatto points
    of the piece, of degree :data:`PIECE_POINTS` ``[0]`` doubled (the points nest) until the
    top quarter of its coefficients falls below ``rtol`` of each entry's scale
    ``sqrt(C_ii C_jj)``, or to exact matrices on that piece beyond ``PIECE_POINTS[1]``. The
    accepted series are checked against exact matrices at two instants per piece.

    A relative error ``e`` of the damping matrix moves the response by at most about ``e``
    (at a resonance the response is inversely proportional to the damping, elsewhere less), so
    ``rtol`` is set a thousandth of the solve's tolerance by the caller.

    Parameters
    ----------
    exact : callable
        ``exact(t)`` -> ndarray (k, N, N): the exact matrices at instants ``t`` (k,) [s].
    period : float
        Cycle [s].
    breaks : array_like of float, shape (b,)
        Instants of the kinks [s] in ``[0, period)``, at least one.
    rtol : float
        Acceptance level of the top coefficients (and of the check).

    Attributes
    ----------
    samples : int
        Exact matrices evaluated to build it (the checks included).
    degrees : ndarray of int, shape (b,)
        Degree per piece (0 for a piece read from exact matrices).
    error : float
        Largest difference between the series and exact matrices at the check instants,
        relative to each entry's scale.
    constant : bool
        Always False (the interface of :class:`DampingField`).
    period : float
        Cycle [s].
    """

    constant = False

    def __init__(self, exact: Callable[[np.ndarray], np.ndarray], period: float, breaks, rtol: float):
        self._exact = exact
        self.period = T = float(period)
        b = np.mod(np.asarray(breaks, dtype=float).ravel(), T)
        b = np.unique(np.where(b >= T, b - T, b))  # mod of a tiny negative number is T itself
        if b.size == 0:
            raise ValueError("PiecewiseDampingField needs at least one break")
        # breaks closer than a trillionth of the period (and across its end) are one: no piece of
        # (almost) zero length, whose local abscissa would be 0/0
        keep = np.append(True, np.diff(b) > 1e-12 * T)
        b = b[keep]
        if b.size > 1 and b[0] + T - b[-1] <= 1e-12 * T:
            b = b[:-1]
        self._starts = b
        self._ends = np.append(b[1:], b[0] + T)
        lo, hi = PIECE_POINTS
        # the first degree of every piece from one batch of exact matrices
        first = exact(np.mod(np.concatenate([self._points(a, z, lo) for a, z in zip(b, self._ends)]), T))
        self.samples = first.shape[0]
        self._iu = np.triu_indices(first.shape[1])
        scale = DampingField._scale(first[:lo + 1])[self._iu]
        coefs, degrees, checks = [], [], []
        for k, (a, z) in enumerate(zip(self._starts, self._ends)):
            p = lo
            C = first[k * (lo + 1):(k + 1) * (lo + 1)]
            while True:
                c = self._coefficients(C[:, self._iu[0], self._iu[1]], p)
                tail = float((np.abs(c[-max(1, p // 4):]).max(axis=0) / scale).max())
                if tail <= rtol or 2 * p > hi:
                    break
                # the Lobatto points of degree 2p: those of degree p and the midpoints between them
                mid = exact(np.mod(self._points(a, z, 2 * p)[1::2], T))
                self.samples += p
                both = np.empty((2 * p + 1,) + C.shape[1:])
                both[0::2], both[1::2] = C, mid
                C, p = both, 2 * p
            if tail <= rtol:
                coefs.append(_full(c, self._iu, first.shape[1]))
                degrees.append(p)
                checks.append(a + np.array([0.31, 0.77]) * (z - a))
            else:
                log.info("modal damping: piece [%.6g, %.6g] s does not settle (top coefficients %.1e of "
                         "the scale at degree %d): exact matrices there", a, z, tail, p)
                coefs.append(None)
                degrees.append(0)
        self._coefs = coefs
        self.degrees = np.array(degrees, dtype=int)
        self.error = 0.0
        if checks:
            tc = np.concatenate(checks)
            E = exact(np.mod(tc, T))
            self.samples += tc.size
            diff = np.abs(self._interpolate(tc)[:, self._iu[0], self._iu[1]] - E[:, self._iu[0], self._iu[1]])
            self.error = float((diff / scale).max())
            if self.error > 10.0 * rtol:
                log.info("modal damping: piecewise interpolant %.1e off the exact matrices; exact matrices "
                         "at every instant instead", self.error)
                self._coefs = [None] * len(coefs)
                self.degrees[:] = 0
        log.debug("modal damping: %d pieces, degrees %s, %d exact matrices, check %.1e", b.size,
                  self.degrees.tolist(), self.samples, self.error)

    @staticmethod
    def _points(a: float, z: float, p: int) -> np.ndarray:
        """Chebyshev-Lobatto points of degree ``p`` on ``[a, z]``, from ``z`` down to ``a``."""
        x = np.cos(np.pi * np.arange(p + 1) / p)
        return a + 0.5 * (x + 1.0) * (z - a)

    @staticmethod
    def _coefficients(values: np.ndarray, p: int) -> np.ndarray:
        """Chebyshev coefficients (p + 1, E) of the values (p + 1, E) at the Lobatto points (DCT-I)."""
        c = fft.dct(values, type=1, axis=0) / p
        c[0] *= 0.5
        c[-1] *= 0.5
        return c

    def _piece(self, t: np.ndarray) -> np.ndarray:
        """Index of the piece of each instant (k,)."""
        b = self._starts
        tt = np.mod(t, self.period)
        tt = np.where(tt >= self.period, 0.0, tt)
        return np.searchsorted(b, tt, side="right") - 1  # -1: before the first break, the last piece

    def _interpolate(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        piece = self._piece(t)
        i, j = self._iu
        N = int(i.max()) + 1
        out = np.empty((t.size, N, N))
        T = self.period
        piece[piece < 0] = len(self._coefs) - 1  # before the first break: the last piece, wrapped
        for k, c in enumerate(self._coefs):  # a loop over the pieces (the kinks), not the instants
            sel = np.flatnonzero(piece == k)
            if sel.size == 0:
                continue
            if c is None:
                out[sel] = self._exact(np.mod(t[sel], T))
                continue
            a, z = self._starts[k], self._ends[k]
            tk = np.mod(t[sel], T)
            tk = np.where(tk < a, tk + T, tk)  # the last piece runs past the period's end
            x = np.clip(2.0 * (tk - a) / (z - a) - 1.0, -1.0, 1.0)
            vals = (np.polynomial.chebyshev.chebvander(x, c.shape[0] - 1) @ c).reshape(-1, N, N)
            if sel[-1] - sel[0] + 1 == sel.size:  # a piece's instants in time order: a slice
                out[sel[0]:sel[-1] + 1] = vals
            else:
                out[sel] = vals
        return out

    def at(self, t) -> np.ndarray:
        """The damping matrices at given instants.

        Parameters
        ----------
        t : array_like of float, shape (k,)
            Instants [s] (any, taken modulo the period).

        Returns
        -------
        ndarray, shape (k, N, N)
            ``C`` [N s/m].
        """
        return self._interpolate(np.atleast_1d(np.asarray(t, dtype=float)))


def field_over_cycle(exact: Callable[[np.ndarray], np.ndarray], period: float, kinks, instants: int,
                     solve_rtol: float | None = None) -> "DampingField | PiecewiseDampingField | None":
    """The cheaper way to the modal damping at ``instants`` instants of a cycle.

    Without kinks the trigonometric interpolant (:class:`DampingField`), where ``instants`` is at
    least twice its first batch, sampled at most half as often as ``instants``. With them (a block
    crossing the nodes of its link) the Chebyshev pieces between them
    (:class:`PiecewiseDampingField`) when their exact matrices, about :data:`PIECE_COST` per
    piece, are fewer than half of ``instants``; else None (an eigenproblem per instant is
    cheaper: the oscillating cylinder's 4 pieces against its 12/24/48 elements).

    Parameters
    ----------
    exact : callable
        ``exact(t)`` -> ndarray (k, N, N): the exact matrices at instants ``t`` (k,) [s].
    period : float
        Cycle [s].
    kinks : array_like of float, shape (b,)
        Instants of the kinks [s] (may be empty).
    instants : int
        How many instants the field will be read at.
    solve_rtol : float, optional
        The solve's tolerance (None: 1e-3); either interpolant is accepted at a
        thousandth of it (at least :data:`FIELD_RTOL`): a relative error ``e`` of ``C`` moves
        the response by at most about ``e``.

    Returns
    -------
    DampingField, PiecewiseDampingField or None
    """
    kinks = np.asarray(kinks, dtype=float).ravel()
    rtol = max(1e-3 * (solve_rtol if solve_rtol is not None else 1e-3), FIELD_RTOL)
    if kinks.size == 0:
        if instants < 2 * (FIRST_SAMPLES + CHECKS):
            return None  # its first batch would cost half the eigenproblems
        # doubled no further than half the instants it serves (beyond, they are cheaper)
        return DampingField(exact, period, rtol, max_samples=min(MAX_SAMPLES, max(FIRST_SAMPLES, instants // 2)))
    if PIECE_COST * kinks.size < 0.5 * instants:
        return PiecewiseDampingField(exact, period, kinks, rtol)
    return None
