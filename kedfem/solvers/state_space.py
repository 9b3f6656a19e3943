"""The mass matrix check and the state-space form of ``M u'' + C u' + K u = Q``.

:func:`_check_mass` raises :class:`~kedfem.errors.SingularMassError` (naming the time node and
the massless DOFs) unless ``M`` is positive definite, :func:`_state_parts` forms ``M^-1 K``,
``M^-1 C`` and ``M^-1 Q`` node by node, and :func:`state_matrix` the state matrix ``F = [[0, I],
[-M^-1 K, -M^-1 C]]`` of ``z = [u; u']``.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..errors import SingularMassError

#: A mass matrix pivot below this fraction of the largest diagonal entry is zero.
MASS_PIVOT_TOL = 1e-13


def _mass_error(M: np.ndarray, nodes: np.ndarray) -> SingularMassError:
    Ms = 0.5 * (M + np.swapaxes(M, -1, -2))
    d = np.abs(np.diagonal(Ms, axis1=-2, axis2=-1))
    # Jacobi scaling (each DOF's own mass 1; a DOF without mass keeps the heaviest one's scale)
    s = 1.0 / np.sqrt(np.where(d <= 0, d.max(axis=-1, keepdims=True), d))
    Ms = s[:, :, None] * Ms * s[:, None, :]
    w, v = np.linalg.eigh(Ms)
    scale = np.maximum(np.abs(w).max(axis=-1), np.finfo(float).tiny)
    bad = w <= MASS_PIVOT_TOL * scale[:, None]
    k = int(np.nonzero(bad.any(axis=-1))[0][0]) if bad.any() else int(np.argmin(w[:, 0] / scale))
    vecs = v[k][:, bad[k]] if bad[k].any() else v[k][:, :1]
    weight = np.abs(vecs).max(axis=1)
    dofs = [int(i) for i in np.nonzero(weight >= 0.3 * weight.max())[0]]
    kind = "indefinite" if w[k, 0] < -MASS_PIVOT_TOL * scale[k] else "singular"
    return SingularMassError(
        f"mass matrix M at time node {int(nodes[k])} is {kind} (smallest eigenvalue of its "
        f"symmetric part {w[k, 0]:.3g}, largest {w[k, -1]:.3g}); massless or negative-mass "
        f"DOFs: {dofs}. The state-space method needs M positive definite; give those DOFs "
        f"mass or condense them out before calling the solver.")


def _check_mass(M: np.ndarray, nodes: np.ndarray) -> None:
    """Raise SingularMassError unless every M (symmetric part) is positive definite."""
    Mb = M if M.ndim == 3 else M[None]
    Ms = 0.5 * (Mb + np.swapaxes(Mb, -1, -2))
    try:
        L = np.linalg.cholesky(Ms)
    except np.linalg.LinAlgError:
        raise _mass_error(Mb, nodes) from None
    # each pivot against its own DOF's mass: a heavy DOF beside light ones (a 1e12 kg press ram on
    # a 1e-6 kg m^2 rotary inertia of a beam node) is not a massless one; a DOF without mass, or
    # one whose mass its neighbours' coupling cancels, is
    piv = np.diagonal(L, axis1=-2, axis2=-1) ** 2
    diag = np.diagonal(Ms, axis1=-2, axis2=-1)
    if np.any(piv <= MASS_PIVOT_TOL * diag):
        raise _mass_error(Mb, nodes)


def _state_parts(M, C, K, Q, nodes, inverse=False):
    """S = M^-1 K, D = M^-1 C, f = M^-1 Q for the given nodes (constants broadcast).

    A sampled ``M`` is inverted once per node (batched LU with partial
    pivoting, ``np.linalg.inv``) and the inverses applied by batched matrix
    products: numpy's stacked ``solve`` runs LAPACK node by node with a copy of
    every right-hand side and is several times slower for these small blocks
    (measured 4.9 against 3.0 ms for 91 nodes of 33 DOFs), and the inverse is
    reused for the linearised terms of the non-linear iteration. The fourth
    item is the inverses (for a constant ``M`` the one inverse, always formed).
    """
    N = Q.shape[-1]
    _check_mass(M, nodes if M.ndim == 3 else nodes[:1])
    if M.ndim == 2:
        # one inverse, applied by (batched) matrix products: faster than
        # triangular solves with L*N right-hand sides (0.1 s of 0.8 s at N = 100)
        Minv = sla.lu_solve(sla.lu_factor(M), np.eye(N))
        S, D = Minv @ K, Minv @ C
        f = Q @ Minv.T
    else:  # the inverses are needed for S, D, f anyway
        Minv = np.linalg.inv(M)
        S = Minv @ K
        D = Minv @ C
        f = (Minv @ Q[:, :, None])[..., 0]
    return S, D, f, Minv


def state_matrix(S, D, dtype=float):
    """State matrix ``F = [[0, I], [-S, -D]]``, (..., 2N, 2N), of ``S = M^-1 K`` [1/s^2] and
    ``D = M^-1 C`` [1/s], each a stack (L, N, N) or a single (N, N)."""
    N = S.shape[-1]
    shape = np.broadcast_shapes(S.shape, D.shape)
    F = np.zeros(shape[:-2] + (2 * N, 2 * N), dtype=dtype)
    F[..., :N, N:] = np.eye(N)
    F[..., N:, :N] = -S
    F[..., N:, N:] = -D
    return F
