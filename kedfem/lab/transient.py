"""Direct time integration, cycle by cycle until periodic: the reference method.

``integrate_periodic`` integrates ``M(t) u'' + C(t) u' + K(t) u = Q(t)`` over one
period at a time, restarting each cycle from the state the previous one ended
in, until the state repeats (the transient has decayed). Methods:

``"radau"``, ``"dop853"``
    :func:`scipy.integrate.solve_ivp` (implicit Radau IIA order 5 with the exact
    Jacobian, or explicit Dormand-Prince order 8) on ``z = [u; u']``.
``"newmark"``
    Average-acceleration Newmark (``beta = 1/4``, ``gamma = 1/2``): implicit,
    unconditionally stable, second order, fixed step.

:func:`sampled_system` builds the continuous ``system(t)`` from sampled arrays by
periodic linear or cubic-spline interpolation.
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

from ..errors import ConvergenceWarning, InputError

__all__ = ["integrate_periodic", "sampled_system", "TransientResult", "TRANSIENT_METHODS"]

log = logging.getLogger(__name__)

TRANSIENT_METHODS = ("radau", "dop853", "newmark")

System = Callable[[float], tuple]


@dataclass(frozen=True)
class TransientResult:
    """Periodic response found by direct integration.

    Attributes
    ----------
    t : ndarray, shape (n_out,)
        Output times ``k T / n_out`` within the last cycle, s.
    U, V : ndarray, shape (n_out, N)
        Displacement and velocity at ``t``.
    cycles : int
        Number of periods integrated.
    defect : float
        Periodicity defect of the last cycle: ``max(|U(T) - U(0)|_inf / max|U|,
        |V(T) - V(0)|_inf / max|V|)`` (0 for a zero response).
    converged : bool
        ``defect <= tol``.
    method : str
    message : str
    nfev : int
        Number of evaluations of ``system``.
    """

    t: np.ndarray
    U: np.ndarray
    V: np.ndarray
    cycles: int
    defect: float
    converged: bool
    method: str
    message: str
    nfev: int


def _eval(system, t, N):
    M, C, K, Q = system(t)
    M = np.asarray(M, dtype=float).reshape(N, N)
    C = np.asarray(C, dtype=float).reshape(N, N)
    K = np.asarray(K, dtype=float).reshape(N, N)
    Q = np.asarray(Q, dtype=float).reshape(N)
    return M, C, K, Q


def _defect(Z, zT, N):
    out = 0.0
    for sl in (slice(0, N), slice(N, 2 * N)):
        scale = max(float(np.abs(Z[:, sl]).max()), float(np.abs(zT[sl]).max()))
        if scale > 0:
            out = max(out, float(np.abs(zT[sl] - Z[0, sl]).max()) / scale)
    return out


def integrate_periodic(system: System, N: int, period: float, method: str = "radau", *,
                       rtol: float = 1e-10, atol: float = 1e-12, tol: float = 1e-10,
                       max_cycles: int = 500, n_out: int = 100, steps_per_output: int = 10,
                       z0: np.ndarray | None = None) -> TransientResult:
    """Integrate cycle by cycle until the response is periodic.

    Parameters
    ----------
    system : callable
        ``system(t) -> (M, C, K, Q)`` for ``0 <= t <= period``: mass, damping and
        stiffness ``(N, N)`` and load ``(N,)`` at time ``t`` [s] (SI units).
    N : int
        Number of DOFs.
    period : float
        Period ``T``, s.
    method : {"radau", "dop853", "newmark"}
    rtol, atol : float
        Tolerances of :func:`scipy.integrate.solve_ivp` (ignored by newmark).
    tol : float
        Periodicity tolerance on the defect (see :class:`TransientResult`).
    max_cycles : int
        Give up (``converged=False``, :class:`ConvergenceWarning`) after this many.
    n_out : int
        Output nodes per period, ``t_k = k T / n_out``.
    steps_per_output : int
        Newmark steps between output nodes (step ``T / (n_out steps_per_output)``).
    z0 : ndarray, shape (2N,), optional
        Initial state ``[u; u']``, default zero.

    Returns
    -------
    TransientResult
    """
    if method not in TRANSIENT_METHODS:
        raise InputError(f"unknown method {method!r}; valid methods: {', '.join(TRANSIENT_METHODS)}")
    period = float(period)
    if not (math.isfinite(period) and period > 0):
        raise InputError(f"period must be a positive finite number, got {period!r}")
    if int(N) < 1 or int(n_out) < 1 or int(max_cycles) < 1 or int(steps_per_output) < 1:
        raise InputError("N, n_out, max_cycles and steps_per_output must be positive integers")
    N, n_out = int(N), int(n_out)
    z = np.zeros(2 * N) if z0 is None else np.asarray(z0, dtype=float).reshape(2 * N).copy()
    t_out = np.arange(n_out) * (period / n_out)
    nfev = [0]

    def counted(t):
        nfev[0] += 1
        return _eval(system, t, N)

    if method == "newmark":
        h = period / (n_out * steps_per_output)
        t_steps = np.arange(n_out * steps_per_output + 1) * h
        mats = [counted(float(t)) for t in t_steps]  # system is periodic: reuse every cycle
        cycle = lambda z_: _newmark_cycle(mats, z_, h, N, steps_per_output)  # noqa: E731
    else:
        ivp_method = "Radau" if method == "radau" else "DOP853"

        def rhs(t, y):
            M, C, K, Q = counted(t)
            u, v = y[:N], y[N:]
            return np.concatenate([v, np.linalg.solve(M, Q - C @ v - K @ u)])

        def jac(t, y):
            M, C, K, _ = counted(t)
            J = np.zeros((2 * N, 2 * N))
            J[:N, N:] = np.eye(N)
            J[N:, :N] = -np.linalg.solve(M, K)
            J[N:, N:] = -np.linalg.solve(M, C)
            return J

        def cycle(z_):
            kw = dict(method=ivp_method, t_eval=np.append(t_out, period), rtol=rtol, atol=atol)
            if ivp_method == "Radau":
                kw["jac"] = jac
            sol = solve_ivp(rhs, (0.0, period), z_, **kw)
            if not sol.success:
                raise RuntimeError(f"solve_ivp failed: {sol.message}")
            return sol.y[:, :-1].T, sol.y[:, -1]

    defect = math.inf
    for c in range(1, int(max_cycles) + 1):
        Z, zT = cycle(z)
        defect = _defect(Z, zT, N)
        z = zT
        if defect <= tol:
            msg = f"periodic after {c} cycles (defect {defect:.2e})"
            log.info("integrate_periodic(%s): %s", method, msg)
            return TransientResult(t_out, Z[:, :N].copy(), Z[:, N:].copy(), c, defect, True,
                                   method, msg, nfev[0])
    msg = f"not periodic after {max_cycles} cycles (defect {defect:.2e} > tol {tol:.1e})"
    warnings.warn(msg, ConvergenceWarning, stacklevel=2)
    return TransientResult(t_out, Z[:, :N].copy(), Z[:, N:].copy(), int(max_cycles), defect,
                           False, method, msg, nfev[0])


def _newmark_cycle(mats, z, h, N, sub):
    """One period of average-acceleration Newmark; returns (Z at outputs, z(T))."""
    beta, gamma = 0.25, 0.5
    u, v = z[:N].copy(), z[N:].copy()
    M, C, K, Q = mats[0]
    a = np.linalg.solve(M, Q - C @ v - K @ u)
    n_steps = len(mats) - 1
    out = np.empty((n_steps // sub, 2 * N))
    for i in range(n_steps):
        if i % sub == 0:
            out[i // sub, :N] = u
            out[i // sub, N:] = v
        M, C, K, Q = mats[i + 1]
        u_pred = u + h * v + (0.5 - beta) * h * h * a
        v_pred = v + (1 - gamma) * h * a
        a = np.linalg.solve(M + gamma * h * C + beta * h * h * K, Q - C @ v_pred - K @ u_pred)
        u = u_pred + beta * h * h * a
        v = v_pred + gamma * h * a
    return out, np.concatenate([u, v])


def sampled_system(M, C, K, Q, period: float, kind: str = "cubic") -> System:
    """Continuous ``system(t)`` from periodic samples at ``t_k = k T / n``.

    Parameters
    ----------
    M, C, K : ndarray, shape (n, N, N) or (N, N)
        Sampled (or constant) mass, damping, stiffness.
    Q : ndarray, shape (n, N)
        Sampled load.
    period : float
        Period, s.
    kind : {"linear", "cubic"}
        Periodic piecewise-linear or periodic cubic-spline interpolation.

    Returns
    -------
    callable
        ``system(t) -> (M, C, K, Q)`` for any real ``t`` (taken modulo the period).
    """
    if kind not in ("linear", "cubic"):
        raise InputError(f"unknown kind {kind!r}; valid kinds: linear, cubic")
    period = float(period)
    Q = np.asarray(Q, dtype=float)
    if Q.ndim != 2:
        raise InputError(f"Q must have shape (n, N), got {Q.shape}")
    n = Q.shape[0]
    tk = np.arange(n + 1) * (period / n)

    def make(X, name):
        X = np.asarray(X, dtype=float)
        if X.ndim == 2 and name != "Q":
            return lambda t: X
        if X.shape[0] != n:
            raise InputError(f"{name} has {X.shape[0]} samples, Q has {n}")
        Xc = np.concatenate([X, X[:1]], axis=0)
        if kind == "cubic":
            spl = CubicSpline(tk, Xc, axis=0, bc_type="periodic")
            return lambda t: spl(t % period)

        def lin(t):
            s = (t % period) / period * n
            k = min(int(math.floor(s)), n - 1)
            w = s - k
            return (1 - w) * Xc[k] + w * Xc[k + 1]
        return lin

    fM, fC, fK, fQ = make(M, "M"), make(C, "C"), make(K, "K"), make(Q, "Q")
    return lambda t: (fM(t), fC(t), fK(t), fQ(t))
