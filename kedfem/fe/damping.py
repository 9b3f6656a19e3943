"""Damping models: Rayleigh (on objective strain rates) and modal damping.

A scene names one of these (or none). :func:`damping_matrix` gives the q-space
damping of a model from its assembled mass and structural stiffness; the beams'
share of Rayleigh's ``beta`` is applied on their objective strain rates by the
assembler (docs/theory.md section 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..model.materials import real
from .modal_damping import modal_damping

__all__ = ["Rayleigh", "ModalDamping", "damping_matrix", "check_damping"]


@dataclass(frozen=True)
class Rayleigh:
    """Rayleigh damping ``C = alpha M + beta K`` (K: structural stiffness).

    The beam elements take ``beta k`` on their strain rates in their own
    turning frame (objective: a rigid rotation of an element is not damped,
    whichever link's frame its joint DOFs are expressed in); springs and drive
    shafts on the rates of their DOFs; ``alpha M`` on the DOF rates.

    Parameters
    ----------
    alpha : float
        Mass-proportional coefficient [1/s].
    beta : float
        Stiffness-proportional coefficient [s].
    """

    alpha: float = 0.0
    beta: float = 0.0

    def __post_init__(self):
        real("Rayleigh", "alpha", self.alpha, nonneg=True)
        real("Rayleigh", "beta", self.beta, nonneg=True)


@dataclass(frozen=True)
class ModalDamping:
    """Modal damping: every elastic mode of ``(K, M)`` at each time node gets ratio ``zeta``.

    ``C = M Phi diag(2 zeta omega) Phi^T M`` with mass-normalised modes of the
    structural stiffness; zero-frequency (rigid-body) modes get no damping.
    """

    zeta: float = 0.02

    def __post_init__(self):
        if real("ModalDamping", "zeta", self.zeta, nonneg=True) >= 1.0:
            raise InputError(f"ModalDamping: zeta must be < 1, got {self.zeta!r}")


def check_damping(damping):
    """Return ``damping`` if it is a damping model or None; InputError otherwise."""
    if damping is not None and not isinstance(damping, (Rayleigh, ModalDamping)):
        raise InputError(f"damping must be kf.Rayleigh, kf.ModalDamping or None, got {damping!r}")
    return damping


def damping_matrix(damping, M: np.ndarray, Ks: np.ndarray, name: str = "", labels=None) -> np.ndarray:
    """q-space damping of a damping model at a batch of instants.

    Parameters
    ----------
    damping : Rayleigh or ModalDamping
    M, Ks : ndarray, shape (nt, N, N)
        Mass [kg] and structural stiffness [N/m] (or scipy.sparse matrices with Rayleigh).
    name : str
        The mechanism's name, for error messages.
    labels : sequence of str, optional
        DOF labels, for error messages.

    Returns
    -------
    ndarray, shape (nt, N, N)
        [N s/m].
    """
    if isinstance(damping, Rayleigh):
        return damping.alpha * M + damping.beta * Ks
    return modal_damping(M, Ks, damping.zeta, name, labels)
