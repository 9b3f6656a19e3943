"""Exact split of the stiff DOFs for the exponential holds.

On a closed loop of flexible links the axial stiffness of a link turns in the
frame of the joint DOFs it shares with another link; an exponential hold
freezes ``K`` over each time element, so the frozen stiff coupling pushes on
the soft bending DOFs with (axial / bending stiffness) x (angle turned over
the element), and the hold needs thousands of elements. The change of
variables ``u = T(t) z``::

    u_f = z_f,          u_s = G(t) z_f + z_s,       G = -K_ss^-1 K_sf

carries the stiff DOFs ``s`` as the static response of the soft DOFs ``f``
plus a deviation ``z_s`` that stays a DOF: the model is unchanged (an exact
change of variables), but ``T' K T`` is block diagonal at every instant, so
what the hold freezes no longer couples the stiff directions to the soft
ones. With ``u' = T z' + T' z`` and ``u'' = T z'' + 2 T' z' + T'' z``::

    M_r = T' M T,   C_r = T' (C T + 2 M T'),   K_r = T' (K T + C T' + M T''),   Q_r = T' Q

(``T'`` and ``T''`` are the time derivatives, from the Fourier series of ``G``
over the nodes of the cycle). The stiff DOFs are those whose diagonal
stiffness the links' axial stiffness carries throughout the cycle
(:meth:`kedfem.fe.effects.Assembler.axial_share`): the interior axial DOFs of
the links, slider travels, joint translations along a link, joint
translations across a link where another link never comes near collinear,
rigid members' rotations that links push and pull on.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["StiffSplit", "build"]

log = logging.getLogger(__name__)

@dataclass(frozen=True)
class StiffSplit:
    """The change of variables ``u = T z`` at the nodes ``k T / n`` of a cycle.

    Attributes
    ----------
    stiff : ndarray of bool, shape (N,)
        DOFs carried as static response plus deviation.
    T, Td, Tdd : ndarray, shape (n, N, N)
        ``T`` and its first and second time derivatives [1/s, 1/s^2].
    """

    stiff: np.ndarray
    T: np.ndarray
    Td: np.ndarray
    Tdd: np.ndarray

    def reduce(self, M, C, K, Q):
        """``M_r, C_r, K_r, Q_r`` of sampled ``M, C, K`` (n, N, N) and ``Q`` (n, N)."""
        T, Td, Tdd = self.T, self.Td, self.Tdd
        Tt = np.swapaxes(T, -1, -2)
        Mr = Tt @ M @ T
        Cr = Tt @ (C @ T + 2.0 * (M @ Td))
        Kr = Tt @ (K @ T + C @ Td + M @ Tdd)
        Qr = (Tt @ Q[..., None])[..., 0]
        return 0.5 * (Mr + np.swapaxes(Mr, -1, -2)), Cr, Kr, Qr

    def reduce_linearised(self, dC, dK, dQ):
        """Linearised state terms in ``z``: ``dC_r = T' dC T``, ``dK_r = T' (dK T + dC T')``, ``dQ_r = T' dQ``."""
        T, Td = self.T, self.Td
        Tt = np.swapaxes(T, -1, -2)
        dCr = None if dC is None else Tt @ dC @ T
        dKr = None
        if dK is not None or dC is not None:
            inner = 0.0
            if dK is not None:
                inner = inner + dK @ T
            if dC is not None:
                inner = inner + dC @ Td
            dKr = Tt @ inner
        dQr = None if dQ is None else (Tt @ dQ[..., None])[..., 0]
        return dCr, dKr, dQr

    def recover(self, Z, Zd):
        """``U = T z`` and ``V = T z' + T' z`` at the nodes, each (n, N)."""
        U = (self.T @ Z[..., None])[..., 0]
        V = (self.T @ Zd[..., None])[..., 0] + (self.Td @ Z[..., None])[..., 0]
        return U, V

    def to_z(self, U, V):
        """Inverse map: ``z = T^-1 u`` and ``z' = T^-1 (u' - T' z)`` at the nodes."""
        Z = np.linalg.solve(self.T, U[..., None])[..., 0]
        Zd = np.linalg.solve(self.T, (V - (self.Td @ Z[..., None])[..., 0])[..., None])[..., 0]
        return Z, Zd


def build(M: np.ndarray, K: np.ndarray, period: float, stiff: np.ndarray) -> StiffSplit | None:
    """The split of sampled ``M, K`` (n, N, N) at the nodes ``k T / n``.

    Parameters
    ----------
    M, K : ndarray, shape (n, N, N)
    period : float
        [s].
    stiff : ndarray of bool, shape (N,)
        DOFs to carry as static response plus deviation.

    Returns
    -------
    StiffSplit or None
        None when no DOF is stiff, or when ``K_ss`` is not positive definite
        at every node (then the split would not be a static response).
    """
    if M.ndim != 3 or K.ndim != 3:
        return None
    stiff = np.asarray(stiff, dtype=bool)
    n, N, _ = K.shape
    if not stiff.any() or stiff.all():
        return None
    s, f = np.flatnonzero(stiff), np.flatnonzero(~stiff)
    Kss = K[:, s[:, None], s[None, :]]
    Ksf = K[:, s[:, None], f[None, :]]
    try:
        np.linalg.cholesky(0.5 * (Kss + np.swapaxes(Kss, -1, -2)))
    except np.linalg.LinAlgError:
        log.info("stiff split: K_ss is not positive definite at every node; no split")
        return None
    G = -np.linalg.solve(Kss, Ksf)                      # (n, s, f)
    Gh = np.fft.rfft(G, axis=0)
    w = 2 * math.pi / period * np.arange(Gh.shape[0])
    if n % 2 == 0:
        w[-1] = 0.0  # the Nyquist harmonic has no defined derivative on the nodes
    Gd = np.fft.irfft(1j * w[:, None, None] * Gh, n=n, axis=0)
    Gdd = np.fft.irfft(-(w ** 2)[:, None, None] * Gh, n=n, axis=0)
    T = np.zeros((n, N, N))
    T[:, np.arange(N), np.arange(N)] = 1.0
    Td = np.zeros((n, N, N))
    Tdd = np.zeros((n, N, N))
    T[:, s[:, None], f[None, :]] = G
    Td[:, s[:, None], f[None, :]] = Gd
    Tdd[:, s[:, None], f[None, :]] = Gdd
    log.info("stiff split: %d of %d DOFs carried as static response plus deviation", s.size, N)
    return StiffSplit(stiff, T, Td, Tdd)
