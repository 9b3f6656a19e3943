"""Diagonal scalings by powers of two: exact similarities that balance a matrix.

:func:`balance` is Osborne's balancing (LAPACK ``gebal`` without permutations) of a whole stack
at once; :func:`second_order_scaling` the one-sweep scaling of a second-order state matrix
``[[0, dt I], [-S dt, -D dt]]``. Powers of two make ``D^-1 A D`` and its undoing exact.
"""

from __future__ import annotations

import numpy as np


def _inf_norm(X: np.ndarray) -> np.ndarray:
    return np.abs(X).sum(axis=-1).max(axis=-1)


def balance(A: np.ndarray, max_iter: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Diagonal balancing by powers of two, batched over leading axes.

    Finds ``d`` (powers of two) such that ``B = D^-1 A D`` (``D = diag(d)``) has
    comparable off-diagonal row and column norms (Osborne / LAPACK ``gebal``
    scaling, without permutations). All indices are updated simultaneously,
    with step halving where a step does not reduce the off-diagonal norm, so the
    whole stack is processed by vectorized numpy operations. Because ``d`` holds
    powers of two, ``B`` is exact and ``exp(A) = D exp(B) D^-1`` is undone
    exactly. Per matrix, the balancing is kept only if it reduces ``||A||_inf``.

    Parameters
    ----------
    A : ndarray, shape (..., m, m)
    max_iter : int
        Maximum number of simultaneous sweeps.

    Returns
    -------
    B : ndarray, shape (..., m, m)
    d : ndarray, shape (..., m)
        Real powers of two.
    """
    A = np.asarray(A)
    m = A.shape[-1]
    batch = A.shape[:-2]
    absA = np.abs(A).reshape((-1, m, m)).astype(float)
    nb = absA.shape[0]
    idx = np.arange(m)
    absA[:, idx, idx] = 0.0
    # entries below 1e-150 of the largest do not steer the scaling (a subnormal
    # entry would ask for factors 2^+-537 whose ratios overflow)
    big = absA.reshape(nb, -1).max(axis=1)
    absA[absA < (1e-150 * big)[:, None, None]] = 0.0
    x = np.zeros((nb, m))  # log2 of d

    def offnorm(xx):
        # sum_ij |a_ij| 2^(x_j - x_i)
        w = np.exp2(xx)
        return np.einsum("bij,bj,bi->b", absA, w, 1.0 / w)

    cur = offnorm(x)
    active = np.ones(nb, dtype=bool)
    for _ in range(max_iter):
        if not active.any():
            break
        w = np.exp2(x)
        Bm = absA * (w[:, None, :] / w[:, :, None])
        r = Bm.sum(axis=2)  # row sums
        c = Bm.sum(axis=1)  # column sums
        ok = (r > 0) & (c > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(ok, np.round(0.5 * (np.log2(np.where(ok, r, 1.0)) - np.log2(np.where(ok, c, 1.0)))),
                            0.0)
        step[~active] = 0.0
        if not np.any(step):
            break
        improved = np.zeros(nb, dtype=bool)
        trial_step = step
        for _half in range(6):
            xt = x + trial_step
            val = offnorm(xt)
            better = (val < cur * (1 - 1e-12)) & ~improved & active & np.any(trial_step != 0, axis=1)
            x[better] = xt[better]
            cur[better] = val[better]
            improved |= better
            if improved[active].all():
                break
            trial_step = np.trunc(trial_step / 2.0)
            if not np.any(trial_step):
                break
        active &= improved
    d = np.exp2(x)
    B = A.reshape((-1, m, m)) * (d[:, None, :] / d[:, :, None])
    # keep the balancing only where it reduces the inf-norm
    keep = _inf_norm(B) < _inf_norm(A.reshape((-1, m, m)))
    d[~keep] = 1.0
    B[~keep] = A.reshape((-1, m, m))[~keep]
    return B.reshape(A.shape), d.reshape(batch + (m,))


def _pow2(x: np.ndarray) -> np.ndarray:
    """Nearest power of two (elementwise), 1 where x is 0 or not finite."""
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x) & (x > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.where(ok, np.round(np.log2(np.where(ok, x, 1.0))), 0.0)
    return np.exp2(np.clip(e, -300, 300))


def second_order_scaling(Fd: np.ndarray) -> np.ndarray:
    """Diagonal scaling ``d`` (powers of two) balancing a second-order state matrix.

    For ``Fd = [[0, dt I], [-S dt, -D dt]]`` (``S = M^-1 K``, ``D = M^-1 C``) the
    displacement components are scaled so that the off-diagonal row and column
    norms of each displacement index agree: ``sigma_i = 2**round(log2(sqrt(r_i /
    c_i)))`` with ``r_i`` the row norm and ``c_i`` the column norm of index ``i``.
    Since the displacement-displacement block is zero this single Osborne sweep is
    already the balanced point for those indices; it turns ``||Fd|| ~ omega_max**2
    dt`` into ``~ omega_max dt``. Velocities keep scale 1.

    Parameters
    ----------
    Fd : ndarray, shape (..., 2N, 2N)

    Returns
    -------
    d : ndarray, shape (..., 2N)
        ``B = D^-1 Fd D`` with ``D = diag(d)`` is the balanced matrix.
    """
    m = Fd.shape[-1]
    N = m // 2
    absF = np.abs(Fd)
    r = absF[..., :N, :].sum(axis=-1) - np.abs(np.diagonal(Fd, axis1=-2, axis2=-1)[..., :N])
    c = absF[..., :, :N].sum(axis=-2) - np.abs(np.diagonal(Fd, axis1=-2, axis2=-1)[..., :N])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where((r > 0) & (c > 0), r / np.where(c > 0, c, 1.0), 1.0)
    sigma = _pow2(np.sqrt(ratio))
    ones = np.ones(Fd.shape[:-2] + (m - N,))
    return np.concatenate([sigma, ones], axis=-1)
