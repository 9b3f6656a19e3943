"""The structure every scene assembles: element matrices of beams and springs, in local frames.

Beam mass and stiffness (Euler-Bernoulli or Timoshenko, consistent or lumped), the beams'
rigid-elastic coupling matrices ``m_t`` and ``m_s`` (used by the ``coupling`` effect), the
axes of linear springs, and the damping of objective local rates (docs/theory.md section 2).
Batched over elements; no effect is applied here.
"""

from __future__ import annotations

import numpy as np

from ..model import elements as el

__all__ = ["SHAT", "SHAT_T", "beam_stiffness", "beam_mass", "beam_coupling", "spring_axes",
           "objective_rates"]

_S = np.array([[0.0, -1.0], [1.0, 0.0]])
#: The 90-degree rotation ``S`` on both nodes' translations of a beam element, (6, 6).
SHAT = np.zeros((6, 6))
SHAT[0:2, 0:2] = _S
SHAT[3:5, 3:5] = _S
SHAT_T = SHAT.T.copy()


def beam_stiffness(b) -> np.ndarray:
    """Local stiffness of the beam elements ``b`` (:class:`kedfem.fe.model.BeamData`).

    Returns
    -------
    ndarray, shape (n_el, 6, 6)
        [N/m, N, N m]; Timoshenko where ``b.timoshenko``.
    """
    if not b.L.size:
        return np.zeros((0, 6, 6))
    k = el.frame_stiffness(b.L, b.EA, b.EI)
    if b.timoshenko.any():
        kt = el.timoshenko_stiffness(b.L, b.EA, b.EI, b.GAs)
        k[b.timoshenko] = kt[b.timoshenko]
    return k


def beam_mass(b) -> np.ndarray:
    """Local mass of the beam elements, consistent or lumped (``b.lumped``), (n_el, 6, 6) [kg, kg m^2]."""
    if not b.L.size:
        return np.zeros((0, 6, 6))
    m = el.consistent_mass(b.L, b.rhoA)
    if b.lumped.any():
        ml = el.lumped_mass(b.L, b.rhoA)
        m[b.lumped] = ml[b.lumped]
    return m


def beam_coupling(b) -> tuple[np.ndarray, np.ndarray]:
    """Translational mass ``m_t`` and skew coupling ``m_s`` of the beam elements, each (n_el, 6, 6) [kg].

    Consistent elements use the Hermite/linear fields; lumped elements are
    point masses at the nodes, for which ``m_s = m_t S_hat``.
    """
    if not b.L.size:
        return np.zeros((0, 6, 6)), np.zeros((0, 6, 6))
    mt = el.consistent_mass(b.L, b.rhoA)
    ms = el.coupling_skew(b.L, b.rhoA)
    if b.lumped.any():
        ml = el.lumped_mass(b.L, b.rhoA)
        ml[:, [2, 5], [2, 5]] = 0.0
        mt[b.lumped] = ml[b.lumped]
        ms[b.lumped] = ml[b.lumped] @ SHAT
    return mt, ms


def spring_axes(items) -> np.ndarray:
    """Extension operators ``B`` of linear springs, (n_spring, 4): ``d = B [x_a, x_b]`` [-]."""
    B = np.zeros((len(items), 4))
    for k, s in enumerate(items):
        B[k, 0:2] = s.axis
        B[k, 2:4] = -np.asarray(s.axis)
    return B


def objective_rates(D, T, Tt, w):
    """A local damping ``D`` on an element's objective local rates ``T x' + T' x``.

    Parameters
    ----------
    D : ndarray, shape (..., 6, 6)
        Local damping [N s/m].
    T, Tt : ndarray, shape (nt, n_el, 6, 6)
        Rotation to the element frame and its transpose.
    w : ndarray, shape (nt, n_el, 1, 1)
        The element's angular velocity [rad/s].

    Returns
    -------
    C, K : ndarray, shape (nt, n_el, 6, 6)
        The global-frame damping ``T^T D T`` and the stiffness-like term
        ``w T^T D S^T T`` of ``T' x = w S^T (T x)`` (translations turning with the
        element at ``w``), so that a rigid rotation of the element is not damped.
    """
    return Tt @ D @ T, w * (Tt @ D @ SHAT_T @ T)
