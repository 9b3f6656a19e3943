"""Fourier (trigonometric) collocation over the whole cycle.

The periodic response is the trigonometric polynomial through its values
``U_k`` at ``n`` equally spaced nodes ``t_k = k T / n`` (``n`` odd, so that
every harmonic up to ``(n - 1) / 2`` is represented and none is split at the
Nyquist frequency); its time derivatives at the nodes are ``D U`` with the
spectral differentiation matrix ``D`` (Trefethen, *Spectral Methods in
MATLAB*, ch. 3). The equations of motion hold at every node::

    M_k (D^2 U)_k + C_k (D U)_k + K_k U_k = Q_k,        k = 0 .. n - 1

one linear system of size ``n N`` for the whole cycle, with no time stepping
and no monodromy matrix. For smooth data the error falls faster than any
power of ``1 / n`` once the nodes resolve the response's harmonics; the
method is not L-stable, so modes the nodes do not resolve alias (measured on
the flexible four-bar: O(1) errors below about 70 nodes, ``docs/solver.md``).

Solvers: a dense LU for ``n N`` up to :data:`DENSE_LIMIT`; beyond it GMRES on
the operator applied by FFT, preconditioned harmonic by harmonic with the
cycle-mean matrices ``(K - w_j^2 M + i w_j C)^-1``.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla

from ..errors import InputError, KedError

__all__ = ["differentiation", "solve", "FourierSolution", "interpolate", "DENSE_LIMIT"]

log = logging.getLogger(__name__)

#: largest n N solved by a dense LU (about 1 s on one core at the limit)
DENSE_LIMIT = 3600


def differentiation(n: int, period: float) -> np.ndarray:
    """Spectral first-derivative matrix (n, n) [1/s] on ``k T / n`` (``n`` odd)."""
    if n % 2 == 0:
        raise InputError(f"Fourier collocation needs an odd number of nodes, got {n}")
    h = 2 * math.pi / n
    j = np.arange(1, n)
    col = np.zeros(n)
    col[1:] = 0.5 * (-1.0) ** j / np.sin(0.5 * j * h)
    return sla.toeplitz(col, -col) * (2 * math.pi / period)


@dataclass(frozen=True)
class FourierSolution:
    """Periodic response by Fourier collocation.

    Attributes
    ----------
    U, V : ndarray, shape (n, N)
        Displacements and velocities at the nodes ``k T / n``.
    period : float
    residual : float
        ``||A u - q|| / ||q||`` of the collocation system.
    method : str
        ``"dense"`` or ``"gmres"``.
    iterations : int
        GMRES iterations (0 for the dense solve).
    """

    U: np.ndarray
    V: np.ndarray
    period: float
    residual: float
    method: str
    iterations: int = 0

    def at(self, t):
        """Trigonometric interpolant of ``U`` and ``V`` at instants ``t`` (k,) [s]."""
        return interpolate(self.U, self.period, t), interpolate(self.V, self.period, t)


def interpolate(X: np.ndarray, period: float, t) -> np.ndarray:
    """Trigonometric interpolant of samples ``X`` (n, m) at ``k T / n``, evaluated at ``t`` (k,)."""
    n = X.shape[0]
    Xh = np.fft.rfft(X, axis=0) / n
    k = np.arange(Xh.shape[0])
    ph = np.exp(2j * math.pi * np.outer(np.asarray(t, float) / period, k))
    w = np.full(k.size, 2.0)
    w[0] = 1.0
    if n % 2 == 0:
        w[-1] = 1.0
    return ((ph * w) @ Xh).real


def _sampled(X, n, N, name):
    X = np.asarray(X, dtype=float)
    if X.ndim == 2:
        return np.broadcast_to(X, (n, N, N))
    if X.shape != (n, N, N):
        raise InputError(f"{name} must have shape ({n}, {N}, {N}) or ({N}, {N}), got {X.shape}")
    return X


def solve(M, C, K, Q, period: float, *, rtol: float = 1e-12, dense_limit: int = DENSE_LIMIT,
          maxiter: int = 10) -> FourierSolution:
    """Periodic steady state of ``M u'' + C u' + K u = Q`` by Fourier collocation.

    Parameters
    ----------
    M, C, K : ndarray, shape (n, N, N) or (N, N)
        At the nodes ``k T / n`` (``n`` odd), or constant.
    Q : ndarray, shape (n, N)
        Load at the nodes [N].
    period : float
        [s].
    rtol : float
        Relative residual asked from GMRES.
    dense_limit : int
        Largest ``n N`` solved directly.
    maxiter : int
        GMRES restart cycles allowed (of up to 200 iterations each).

    Returns
    -------
    FourierSolution

    Raises
    ------
    InputError
        Even ``n``, bad shapes, non-finite data.
    KedError
        GMRES did not reach ``rtol`` (the message names the residual).
    """
    Q = np.asarray(Q, dtype=float)
    if Q.ndim != 2:
        raise InputError(f"Q must have shape (n, N), got {Q.shape}")
    n, N = Q.shape
    D = differentiation(n, period)
    Ms, Cs, Ks = (_sampled(X, n, N, nm) for X, nm in ((M, "M"), (C, "C"), (K, "K")))
    for nm, X in (("M", Ms), ("C", Cs), ("K", Ks), ("Q", Q)):
        if not np.all(np.isfinite(X)):
            raise InputError(f"{nm} has non-finite values")
    q = Q.reshape(-1)
    if n * N <= dense_limit:
        D2 = D @ D
        A = (Ms[:, None] * D2[:, :, None, None] + Cs[:, None] * D[:, :, None, None])
        A = A.transpose(0, 2, 1, 3).reshape(n * N, n * N)
        idx = np.arange(n)
        A.reshape(n, N, n, N)[idx, :, idx, :] += Ks
        try:
            u = sla.solve(A, q, check_finite=False)
        except np.linalg.LinAlgError:
            raise KedError("Fourier collocation: the collocation system is singular (a resonance of "
                           "an undamped mode with a harmonic the nodes carry)") from None
        res = float(np.linalg.norm(A @ u - q) / max(np.linalg.norm(q), 1e-300))
        U = u.reshape(n, N)
        return FourierSolution(U, D @ U, period, res, "dense")
    w = 2 * math.pi / period * np.fft.fftfreq(n, 1.0 / n)

    def deriv(X, order):
        return np.fft.ifft((1j * w[:, None]) ** order * np.fft.fft(X, axis=0), axis=0).real

    def matvec(x):
        X = x.reshape(n, N)
        return (np.einsum("kij,kj->ki", Ms, deriv(X, 2)) + np.einsum("kij,kj->ki", Cs, deriv(X, 1))
                + np.einsum("kij,kj->ki", Ks, X)).reshape(-1)

    Mm, Cm, Km = Ms.mean(axis=0), Cs.mean(axis=0), Ks.mean(axis=0)
    P = Km[None] - (w ** 2)[:, None, None] * Mm[None] + 1j * w[:, None, None] * Cm[None]
    try:
        Pinv = np.linalg.inv(P)
    except np.linalg.LinAlgError:
        raise KedError("Fourier collocation: the cycle-mean system is singular at a harmonic "
                       "(preconditioner)") from None

    def precond(x):
        X = np.fft.fft(x.reshape(n, N), axis=0)
        return np.fft.ifft(np.einsum("kij,kj->ki", Pinv, X), axis=0).real.reshape(-1)

    A = spla.LinearOperator((n * N, n * N), matvec=matvec, dtype=float)
    Pop = spla.LinearOperator((n * N, n * N), matvec=precond, dtype=float)
    count = [0]

    def cb(_):
        count[0] += 1

    u, info = spla.gmres(A, q, M=Pop, rtol=rtol, atol=0.0, restart=min(200, n * N), maxiter=maxiter,
                         callback=cb, callback_type="pr_norm")
    res = float(np.linalg.norm(matvec(u) - q) / max(np.linalg.norm(q), 1e-300))
    if info != 0 or not np.isfinite(res) or res > 1e3 * rtol:
        raise KedError(f"Fourier collocation: GMRES reached a relative residual of {res:.1e} after "
                       f"{count[0]} iterations (asked {rtol:.0e}); the cycle-mean preconditioner does "
                       f"not capture this system's time variation -- use a collocation scheme "
                       f"(method='radau3')")
    U = u.reshape(n, N)
    return FourierSolution(U, deriv(U, 1), period, res, "gmres", count[0])
