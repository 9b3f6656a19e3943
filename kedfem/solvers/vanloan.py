"""Exact discretisation of one time element from one exponential of an augmented matrix.

Van Loan (1978): :func:`affine_exponential` gives ``A = exp(F dt)`` and the affine part ``b`` of
``z' = F z + g(s)`` with ``g`` constant or linear over the element; :func:`second_order_transition`
does the same for ``F = [[0, I], [-M^-1 K, -M^-1 C]]``, building the balanced augmented matrix
directly; :func:`exponential_integrals` gives the operators ``A, Gamma0, Gamma1`` that map a
whole sampled forcing at once when ``F`` is time-invariant. The exponentials are those of
:mod:`kedfem.solvers.expm`.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .balancing import _inf_norm, _pow2, balance, second_order_scaling
from .scaling_squaring import _exp_scaled_core


def _state_scaling(Fd: np.ndarray, scaling) -> np.ndarray | None:
    if scaling is None or scaling is False:
        return None
    if isinstance(scaling, str):
        if scaling == "second-order":
            if Fd.shape[-1] % 2:
                raise InputError("scaling='second-order' needs an even state dimension")
            return second_order_scaling(Fd)
        if scaling in ("general", "auto"):
            return balance(Fd)[1]
        raise InputError(f"unknown scaling {scaling!r}; valid: None, 'general', 'second-order'")
    d = np.asarray(scaling, dtype=float)
    if d.shape[-1] != Fd.shape[-1]:
        raise InputError(f"scaling must have length {Fd.shape[-1]}, got shape {d.shape}")
    return _pow2(d)  # force powers of two so that the similarity is exact


def affine_exponential(F: np.ndarray, dt: float, g0: np.ndarray, g1: np.ndarray | None = None,
                       *, delta: float = 1e-15, scaling="general", degree="auto",
                       approximant: str = "taylor", return_info: bool = False):
    """Exact transition of ``z' = F z + g(s)`` over one element ``0 <= s <= dt``.

    ``g`` is constant (``g1 is None``: zero-order hold) or linear from ``g0`` at
    ``s = 0`` to ``g1`` at ``s = dt`` (first-order hold). Then ``z(dt) = A z(0) +
    b`` with ``A = exp(F dt)`` and ``b = int_0^dt exp(F (dt - s)) g(s) ds``, both
    taken from ONE exponential of the augmented matrix (Van Loan 1978)::

        [[F dt, (g1 - g0) dt, g0 dt],      exp ->  [[A, *, b],
         [0,    0,            1    ],               [0, 1, 1],
         [0,    0,            0    ]]               [0, 0, 1]]

    The forcing columns are rescaled by powers of two to the size of ``F dt``
    (exact by linearity) so that a large load does not force extra squarings.
    Batched over leading axes.

    Parameters
    ----------
    F : ndarray, shape (..., m, m)
        State matrix, 1/s.
    dt : float
        Element length, s.
    g0, g1 : ndarray, shape (..., m)
        Forcing at the start and end of the element (state units / s).
    delta : float
        Requested relative backward error of the exponential.
    scaling : None, "general", "second-order" or ndarray (..., m)
        State balancing: none, :func:`balance`, :func:`second_order_scaling`
        (for ``F = [[0, I], [-M^-1 K, -M^-1 C]]``), or explicit powers of two.
    degree : int or "auto"
        Degree of the approximant, see :func:`expm`.
    approximant : {"taylor", "pade"}
        See :func:`expm`. Default Taylor: in a batch the Pade solve costs more
        than the products it saves (see ``docs/solver.md``).
    return_info : bool
        Also return the :class:`ExpmInfo`.

    Returns
    -------
    A : ndarray, shape (..., m, m)
    b : ndarray, shape (..., m)
    info : ExpmInfo, only if ``return_info``
    """
    F = np.asarray(F)
    m = F.shape[-1]
    batch = np.broadcast_shapes(F.shape[:-2], np.shape(g0)[:-1],
                                np.shape(g1)[:-1] if g1 is not None else ())
    dtype = np.result_type(F.dtype, np.asarray(g0).dtype, float)
    Fd = np.broadcast_to(F * dt, batch + (m, m)).reshape((-1, m, m)).astype(dtype, copy=False)
    nb = Fd.shape[0]
    g0d = np.broadcast_to(np.asarray(g0) * dt, batch + (m,)).reshape((nb, m))
    dgd = None
    if g1 is not None:
        dgd = np.broadcast_to((np.asarray(g1) - np.asarray(g0)) * dt, batch + (m,)).reshape((nb, m))
    d = _state_scaling(Fd, scaling)
    if d is not None:
        d = np.broadcast_to(d, (nb, m))
        B = Fd * (d[:, None, :] / d[:, :, None])
        g0d = g0d / d
        if dgd is not None:
            dgd = dgd / d
    else:
        B = Fd
    tau = np.maximum(_inf_norm(B), 2.0 ** -20)
    gmax0 = np.abs(g0d).max(axis=-1) if m else np.zeros(nb)
    beta = _pow2(np.where(gmax0 > 0, tau / np.where(gmax0 > 0, gmax0, 1.0), 1.0))
    ma = m + (1 if dgd is None else 2)
    X = np.zeros((nb, ma, ma), dtype=dtype)
    X[:, :m, :m] = B
    if dgd is None:
        X[:, :m, m] = g0d * beta[:, None]
    else:
        gmax1 = np.abs(dgd).max(axis=-1)
        alpha = np.where(gmax1 > 0, _pow2(tau / np.where(gmax1 > 0, gmax1, 1.0)), beta)
        # keep the coupling entry beta/alpha <= max(1, tau): a vanishing g0 next to
        # a finite slope must not create a huge entry (that would cost squarings)
        beta = np.minimum(beta, alpha * _pow2(np.maximum(1.0, tau)))
        X[:, :m, m] = dgd * alpha[:, None]
        X[:, :m, m + 1] = g0d * beta[:, None]
        X[:, m, m + 1] = beta / alpha
    E, info = _exp_scaled_core(X, float(delta), degree, triangular=False,
                               approximant=approximant)
    A = E[:, :m, :m]
    b = E[:, :m, ma - 1] / beta[:, None]
    if d is not None:
        A = A * (d[:, :, None] / d[:, None, :])
        b = b * d
    A = A.reshape(batch + (m, m))
    b = b.reshape(batch + (m,))
    return (A, b, info) if return_info else (A, b)


def exponential_integrals(F: np.ndarray, G: np.ndarray, dt: float, *, delta: float = 1e-15,
                          scaling="general", degree="auto", approximant: str = "taylor",
                          return_info: bool = False):
    """Operators of the exact element transition for a time-invariant ``F``.

    For ``z' = F z + G q(s)`` with ``q`` linear over the element (``q_k`` at
    ``s = 0``, ``q_{k+1}`` at ``s = dt``)::

        z_{k+1} = A z_k + Gamma0 q_k + Gamma1 (q_{k+1} - q_k)

    with ``A = exp(F dt)``, ``Gamma0 = int_0^dt exp(F (dt-s)) ds G`` and ``Gamma1 =
    int_0^dt exp(F (dt-s)) (s/dt) ds G``; zero-order hold uses ``Gamma0`` only.
    All three come from one exponential of ``[[F dt, G dt, 0], [0, 0, I], [0, 0,
    0]]`` of size ``m + 2p``; afterwards a whole sampled forcing is mapped at once
    by two matrix products.

    Parameters
    ----------
    F : ndarray, shape (m, m)
        State matrix, 1/s.
    G : ndarray, shape (m, p)
        Input matrix.
    dt : float
        Element length, s.
    delta, scaling, degree, approximant, return_info
        As in :func:`affine_exponential`.

    Returns
    -------
    A : ndarray, shape (m, m)
    Gamma0, Gamma1 : ndarray, shape (m, p)
    info : ExpmInfo, only if ``return_info``
    """
    F = np.asarray(F)
    G = np.asarray(G)
    m = F.shape[-1]
    p = G.shape[-1]
    dtype = np.result_type(F.dtype, G.dtype, float)
    Fd = (F * dt).astype(dtype)
    Gd = (G * dt).astype(dtype)
    d = _state_scaling(Fd[None], scaling)
    if d is not None:
        d = d[0]
        B = Fd * (d[None, :] / d[:, None])
        Gd = Gd / d[:, None]
    else:
        B = Fd
    tau = max(float(_inf_norm(B)), 2.0 ** -20)
    gn = float(np.abs(Gd).sum(axis=-1).max()) if Gd.size else 0.0
    alpha = float(_pow2(tau / gn)) if gn > 0 else 1.0
    ma = m + 2 * p
    X = np.zeros((1, ma, ma), dtype=dtype)
    X[0, :m, :m] = B
    X[0, :m, m:m + p] = Gd * alpha
    X[0, m:m + p, m + p:] = np.eye(p)
    E, info = _exp_scaled_core(X, float(delta), degree, triangular=False,
                               approximant=approximant)
    E = E[0]
    A = E[:m, :m]
    G0 = E[:m, m:m + p] / alpha
    G1 = E[:m, m + p:] / alpha
    if d is not None:
        A = A * (d[:, None] / d[None, :])
        G0 = G0 * d[:, None]
        G1 = G1 * d[:, None]
    return (A, G0, G1, info) if return_info else (A, G0, G1)


def second_order_transition(S: np.ndarray, D: np.ndarray, dt: float, f0: np.ndarray,
                            f1: np.ndarray | None = None, *, delta: float = 1e-15,
                            degree="auto", approximant: str = "taylor",
                            return_info: bool = False):
    """Element transitions of a second-order system, built in balanced form.

    Same result as :func:`affine_exponential` with ``F = [[0, I], [-S, -D]]``,
    ``g = [0; f]`` and ``scaling="second-order"``, but the balanced augmented
    matrix is written directly from ``S = M^-1 K`` and ``D = M^-1 C`` (the
    identity block is diagonal, the scaling is a column scaling of ``S``), which
    saves several passes over the ``(L, 2N+2, 2N+2)`` stack; this matters because
    batched elementwise passes cost about half a matrix product at ``N ~ 40``.

    Parameters
    ----------
    S, D : ndarray, shape (L, N, N)
        ``M^-1 K`` [1/s^2] and ``M^-1 C`` [1/s] held over each element (``D`` may
        be ``(N, N)``).
    dt : float
        Element length, s.
    f0, f1 : ndarray, shape (L, N)
        ``M^-1 Q`` at the start and end of the element (``f1=None``: held constant).
    delta, degree, approximant, return_info
        As in :func:`affine_exponential`.

    Returns
    -------
    A : ndarray, shape (L, 2N, 2N)
    b : ndarray, shape (L, 2N)
    info : ExpmInfo, only if ``return_info``
    """
    L, N, _ = S.shape
    m = 2 * N
    ma = m + (1 if f1 is None else 2)
    absS = np.abs(S)
    col = absS.sum(axis=-2)  # column sums of |S|
    sigma = _pow2(np.where(col > 0, 1.0 / np.sqrt(np.where(col > 0, col, 1.0)), 1.0))
    X = np.zeros((L, ma, ma))
    iu = np.arange(N)
    X[:, iu, N + iu] = dt / sigma
    np.multiply(S, (-dt) * sigma[:, None, :], out=X[:, N:m, :N])
    np.multiply(D, -dt, out=X[:, N:m, N:m])
    # upper bound of ||B||_inf (no extra pass over the whole stack)
    rows_v = np.einsum("lij,lj->li", absS, sigma) * dt + np.abs(D).sum(axis=-1) * dt
    tau = np.maximum(np.maximum((dt / sigma).max(axis=-1), rows_v.max(axis=-1)), 2.0 ** -20)
    g0d = f0 * dt
    gmax0 = np.abs(g0d).max(axis=-1)
    beta = _pow2(np.where(gmax0 > 0, tau / np.where(gmax0 > 0, gmax0, 1.0), 1.0))
    if f1 is None:
        X[:, N:m, m] = g0d * beta[:, None]
        extra = np.abs(X[:, N:m, m]).max(axis=-1)
    else:
        dgd = (f1 - f0) * dt
        gmax1 = np.abs(dgd).max(axis=-1)
        alpha = np.where(gmax1 > 0, _pow2(tau / np.where(gmax1 > 0, gmax1, 1.0)), beta)
        beta = np.minimum(beta, alpha * _pow2(np.maximum(1.0, tau)))  # see affine_exponential
        X[:, N:m, m] = dgd * alpha[:, None]
        X[:, N:m, m + 1] = g0d * beta[:, None]
        X[:, m, m + 1] = beta / alpha
        extra = np.abs(X[:, N:m, m]).max(axis=-1) + np.abs(X[:, N:m, m + 1]).max(axis=-1)
        extra = np.maximum(extra, beta / alpha)
    bound = tau + extra
    E, info = _exp_scaled_core(X, float(delta), degree, triangular=False,
                               approximant=approximant, copy=False, norm_bound=bound)
    A = E[:, :m, :m]
    A[:, :N, :] *= sigma[:, :, None]
    A[:, :, :N] /= sigma[:, None, :]
    b = E[:, :m, ma - 1] / beta[:, None]
    b[:, :N] *= sigma
    return (A, b, info) if return_info else (A, b)
