"""Batched generalised symmetric eigenproblem ``K phi = lambda M phi``, with named errors.

Shared by the natural frequencies (:func:`kedfem.analysis.modal.eig_frequencies`) and the
modal damping matrices (:mod:`kedfem.fe.modal_damping`): ``M = L L^T`` (Cholesky),
``L^-1 K L^-T = V diag(lambda) V^T`` (``eigh``), mass-normalised modes
``Phi = L^-T V``.
"""

from __future__ import annotations

import numpy as np

from ..errors import KedError, SingularMassError

__all__ = ["generalised_eigh"]


def generalised_eigh(M: np.ndarray, K: np.ndarray, name: str = "", labels=None, parallel: bool = False,
                     what: str = "natural frequencies"):
    """Eigenvalues and factors of ``K phi = lambda M phi`` for a batch of instants.

    Parameters
    ----------
    M, K : ndarray, shape (..., N, N)
        Mass [kg] and stiffness [N/m]; their symmetric parts are used.
    name : str
        Mechanism name for messages.
    labels : sequence of str, optional
        DOF labels, to name massless DOFs.
    parallel : bool
        Split a stack over the worker threads (LAPACK releases the GIL).
    what : str
        What the eigenproblem is for, in messages.

    Returns
    -------
    lam : ndarray, shape (..., N)
        Eigenvalues ``omega^2`` [rad^2/s^2], ascending.
    L : ndarray, shape (..., N, N)
        Cholesky factor of ``M``.
    Li : ndarray, shape (..., N, N)
        Its inverse (``Phi = Li^T V``).
    V : ndarray, shape (..., N, N)
        Orthonormal eigenvectors of ``Li K Li^T``.

    Raises
    ------
    SingularMassError
        ``M`` is not positive definite (the message names massless DOFs).
    KedError
        The eigenproblem has no solution in floating point (absurd units).
    """
    who = f"{name}: " if name else ""
    M = 0.5 * (M + np.swapaxes(M, -1, -2))
    K = 0.5 * (K + np.swapaxes(K, -1, -2))
    try:
        L = np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        d = np.diagonal(M, axis1=-2, axis2=-1).reshape(-1, M.shape[-1])
        bad = np.flatnonzero(np.min(d, axis=0) <= 0)
        names = ", ".join((labels[i] if labels is not None else str(i)) for i in bad[:8])
        raise SingularMassError(f"{who}the mass matrix is singular or indefinite (DOFs without mass: "
                                f"{names or '(no zero diagonal)'}); give the members mass or rotary "
                                "inertia") from None
    lam = np.empty(M.shape[:-1])
    Li = np.empty_like(M)
    V = np.empty_like(M)

    def work(_i, lo, hi):
        Li[lo:hi] = np.linalg.inv(L[lo:hi])
        A = Li[lo:hi] @ K[lo:hi] @ np.swapaxes(Li[lo:hi], -1, -2)
        A = 0.5 * (A + np.swapaxes(A, -1, -2))
        try:
            lam[lo:hi], V[lo:hi] = np.linalg.eigh(A)
        except np.linalg.LinAlgError:
            raise KedError(f"{who}{what}: the eigenproblem of M and K has no solution in "
                           "floating point (natural frequencies beyond ~1e150 rad/s: check the units of "
                           "density, stiffness and section)") from None

    if M.ndim == 2:
        lam, Li, V = lam[None], Li[None], V[None]
        L, K = L[None], K[None]
        work(0, 0, 1)
        return lam[0], L[0], Li[0], V[0]
    shape = M.shape
    lam, Li, V = (x.reshape((-1,) + x.shape[len(shape) - 2:]) for x in (lam, Li, V))
    L, K = L.reshape((-1,) + shape[-2:]), K.reshape((-1,) + shape[-2:])
    if parallel:
        from .parallel import _run_parallel, _split, default_workers
        _run_parallel(work, _split(L.shape[0], default_workers(), min_part=4))
    else:
        work(0, 0, L.shape[0])
    return (lam.reshape(shape[:-1]), L.reshape(shape), Li.reshape(shape), V.reshape(shape))
