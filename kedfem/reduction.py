"""Craig-Bampton reduction of flexible links.

A reduced link keeps its boundary DOFs (the six end DOFs in the link's own
frame) and replaces its interior nodes by static constraint modes ``Psi``
plus ``k`` fixed-interface normal modes ``Phi``, both computed once in the
link's frame, where they are constant over the cycle:

``d_interior = Psi d_boundary + Phi eta``  (local link frame).

In the global DOFs the interior then follows ``T(theta)^T (Psi T(theta)
x_boundary + Phi eta)``; :class:`kedfem.assembly.FEModel` carries this as a
time-varying constraint map, so the coupling, stiffening and non-linear terms
of the full elements are projected consistently, with the exact time
derivatives of the map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from . import elements as el
from .errors import InputError

__all__ = ["CraigBampton", "link_matrices", "craig_bampton_basis"]


@dataclass(frozen=True)
class CraigBampton:
    """Craig-Bampton reduction: ``modes`` fixed-interface modes per flexible link.

    Parameters
    ----------
    modes : int
        Fixed-interface normal modes kept per reduced link (>= 0).
    links : tuple of str, optional
        Links to reduce; default every flexible link with more than one
        element (single-element links have no interior to reduce).
    """

    modes: int = 4
    links: tuple[str, ...] | None = None

    def __post_init__(self):
        m = self.modes
        if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 0:
            raise InputError(f"CraigBampton: modes must be an integer >= 0, got {m!r}")
        if self.links is not None:
            if isinstance(self.links, str):
                object.__setattr__(self, "links", (self.links,))
            else:
                object.__setattr__(self, "links", tuple(self.links))

    def applies_to(self, link) -> bool:
        """True if ``link`` (a :class:`kedfem.mechanism.Link`) is reduced."""
        if link.rigid or link.elements < 2:
            return False
        return self.links is None or link.name in self.links


def link_matrices(link):
    """Stiffness and consistent mass of a flexible link in its own frame.

    Returns
    -------
    K, M : ndarray, shape (3 (n_el + 1), 3 (n_el + 1))
        DOF order ``[u0, v0, theta0, u1, v1, theta1, ...]`` along the link.
    """
    ne = link.elements
    Le = link.length / ne
    mat, sec = link.material, link.section
    if link.timoshenko:
        k = el.timoshenko_stiffness([Le], mat.E * sec.A, mat.E * sec.I, sec.kappa * mat.G * sec.A)[0]
    else:
        k = el.frame_stiffness([Le], mat.E * sec.A, mat.E * sec.I)[0]
    if link.mass_matrix == "lumped":
        m = el.lumped_mass([Le], mat.rho * sec.A)[0]
    else:
        m = el.consistent_mass([Le], mat.rho * sec.A)[0]
    n = 3 * (ne + 1)
    K = np.zeros((n, n))
    M = np.zeros((n, n))
    for e in range(ne):
        s = slice(3 * e, 3 * e + 6)
        K[s, s] += k
        M[s, s] += m
    return K, M


def craig_bampton_basis(link, modes: int):
    """Constraint modes and fixed-interface modes of a flexible link.

    Parameters
    ----------
    link : kedfem.mechanism.Link
        A flexible link with at least two elements.
    modes : int
        Number of fixed-interface modes (capped at the number of interior DOFs).

    Returns
    -------
    Psi : ndarray, shape (n_i, 6)
        Interior displacement per unit boundary DOF (static condensation),
        interior DOFs in node order, boundary ``[u_a, v_a, th_a, u_b, v_b, th_b]``.
    Phi : ndarray, shape (n_i, k)
        Mass-normalised fixed-interface modes.
    omega : ndarray, shape (k,)
        Their circular frequencies [rad/s].
    """
    K, M = link_matrices(link)
    n = K.shape[0]
    b = np.array([0, 1, 2, n - 3, n - 2, n - 1])
    i = np.arange(3, n - 3)
    Kii, Kib = K[np.ix_(i, i)], K[np.ix_(i, b)]
    Psi = -np.linalg.solve(Kii, Kib)
    k = min(int(modes), i.size)
    if k == 0:
        return Psi, np.zeros((i.size, 0)), np.zeros(0)
    lam, Phi = sla.eigh(Kii, M[np.ix_(i, i)], subset_by_index=[0, k - 1])
    return Psi, Phi, np.sqrt(np.clip(lam, 0.0, None))
