"""Craig-Bampton reduction of flexible links.

A reduced link keeps its boundary DOFs (the six end DOFs in the link's own
frame) and replaces its interior nodes by static constraint modes ``Psi``
plus ``k`` fixed-interface normal modes ``Phi``, both computed once in the
link's frame, where they are constant over the cycle:

``d_interior = Psi d_boundary + Phi eta``  (local link frame).

In the global DOFs the interior then follows ``T(theta)^T (Psi T(theta)
x_boundary + Phi eta)``; :class:`kedfem.fe.model.FEModel` carries this as a
time-varying constraint map, so the coupling, stiffening and non-linear terms
of the full elements are projected consistently, with the exact time
derivatives of the map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..model import elements as el
from ..checks import flag, names
from ..errors import InputError

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
        element (single-element links have no interior to reduce) and no
        joints passed through (``through=``: those stay unreduced).
    static_correction : bool
        Also keep the static interior responses (boundary fixed) to the four
        load patterns of the rigid-body inertia and weight loads in the link
        frame (uniform and linearly varying, axial and transverse), made
        mass-orthogonal to the modes. The quasi-static part of the response,
        which dominates the stresses of a linkage running below resonance, is
        then exact, so the stress converges with far fewer modes. Adds up to
        four coordinates per link.
    """

    modes: int = 4
    links: tuple[str, ...] | None = None
    static_correction: bool = True

    def __post_init__(self):
        m = self.modes
        if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 0:
            raise InputError(f"CraigBampton: modes must be an integer >= 0, got {m!r}")
        if self.links is not None:
            object.__setattr__(self, "links", names("CraigBampton", "links", self.links))
        object.__setattr__(self, "static_correction", flag("CraigBampton", "static_correction",
                                                           self.static_correction))

    def applies_to(self, link) -> bool:
        """True if ``link`` (a :class:`kedfem.model.mechanism.Link`) is reduced."""
        if link.rigid or link.elements < 2:
            return False
        if link.through:  # its interface includes inner nodes: not reduced
            if self.links is not None and link.name in self.links:
                raise InputError(f"CraigBampton: link '{link.name}' passes through joint(s) "
                                 f"{', '.join(link.through)}; its reduction (interface at the two ends) "
                                 "does not apply: leave it out of links=")
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


def craig_bampton_basis(link, modes: int, static_correction: bool = False):
    """Constraint modes and fixed-interface modes of a flexible link.

    Parameters
    ----------
    link : kedfem.model.mechanism.Link
        A flexible link with at least two elements.
    modes : int
        Number of fixed-interface modes (capped at the number of interior DOFs).
    static_correction : bool
        Append the static responses to the link-frame inertia load patterns
        (see :class:`CraigBampton`), mass-orthonormalised against the modes.

    Returns
    -------
    Psi : ndarray, shape (n_i, 6)
        Interior displacement per unit boundary DOF (static condensation),
        interior DOFs in node order, boundary ``[u_a, v_a, th_a, u_b, v_b, th_b]``.
    Phi : ndarray, shape (n_i, k)
        Mass-normalised interior shapes: fixed-interface modes, then the
        static-correction vectors.
    omega : ndarray, shape (k_modes,)
        Circular frequencies of the fixed-interface modes [rad/s].
    """
    K, M = link_matrices(link)
    n = K.shape[0]
    b = np.array([0, 1, 2, n - 3, n - 2, n - 1])
    i = np.arange(3, n - 3)
    Kii, Kib, Mii = K[np.ix_(i, i)], K[np.ix_(i, b)], M[np.ix_(i, i)]
    Psi = -np.linalg.solve(Kii, Kib)
    k = min(int(modes), i.size)
    if k:
        lam, Phi = sla.eigh(Kii, Mii, subset_by_index=[0, k - 1])
        om = np.sqrt(np.clip(lam, 0.0, None))
    else:
        Phi, om = np.zeros((i.size, 0)), np.zeros(0)
    if static_correction and Phi.shape[1] < i.size:
        ne = link.elements
        Le = link.length / ne
        loads = []
        for comp in (0, 1):          # axial, transverse
            for lin in (False, True):  # uniform, linear in x
                p0 = np.zeros((ne, 2))
                p1 = np.zeros((ne, 2))
                s1 = np.arange(ne) * Le
                if lin:
                    p0[:, comp] = s1
                    p1[:, comp] = 1.0
                else:
                    p0[:, comp] = 1.0
                fe = el.linear_load(np.full(ne, Le), p0, p1)
                f = np.zeros(n)
                for e in range(ne):
                    f[3 * e:3 * e + 6] += fe[e]
                loads.append(np.linalg.solve(Kii, f[i]))
        for v in loads:  # mass-orthonormalise against the basis so far (twice, for round-off)
            for _ in range(2):
                v = v - Phi @ (Phi.T @ (Mii @ v))
            nv = float(np.sqrt(v @ Mii @ v))
            scale = float(np.sqrt(np.max(np.abs(loads[0] @ Mii @ loads[0])))) or 1.0
            if nv > 1e-8 * scale:
                Phi = np.column_stack([Phi, v / nv])
    return Psi, Phi, om
