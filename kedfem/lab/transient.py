"""Direct time integration, cycle by cycle until periodic: the reference method.

The integrators solve ``M(t) u'' + C(t) u' + K(t) u = Q(t)`` over one period at a
time, restarting each cycle from the state the previous one ended in, until the
response repeats (the transient has decayed). Two entry points share one
implementation of each method:

:func:`integrate_periodic`
    The terms as a continuous function ``system(t)``.
:func:`integrate_sampled`
    The terms sampled at ``t_k = k T / n`` (as assembled by kedfem): Newmark steps
    on that grid, ``solve_ivp`` integrates periodic cubic splines of
    ``M^-1 K``, ``M^-1 C``, ``M^-1 Q``.

Methods:

``"radau"``, ``"dop853"``
    :func:`scipy.integrate.solve_ivp` (implicit Radau IIA order 5 with the exact
    Jacobian, or explicit Dormand-Prince order 8) on ``z = [u; u']``, i.e.
    ``u'' = f - S u - D u'`` with ``S = M^-1 K``, ``D = M^-1 C``, ``f = M^-1 Q``.
``"newmark"``
    Average-acceleration Newmark (``beta = 1/4``, ``gamma = 1/2``): implicit,
    unconditionally stable, second order, fixed step. The per-step operators
    ``E^-1 [K C]`` and ``E^-1 Q``, ``E = M + h C / 2 + h^2 K / 4``, are formed once
    (batched) and reused by every cycle, so a step is one matrix-vector product.

A cycle is periodic when its periodicity defect is below ``tol``: by default
the jump of the state over the cycle; with a ``monitor``, the change of a
quantity of interest's history from the previous cycle.

:func:`sampled_system` builds the continuous ``system(t)`` from sampled arrays by
periodic linear or cubic-spline interpolation.
"""

from __future__ import annotations

import logging
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

from ..errors import ConvergenceWarning, InputError, user_stacklevel

__all__ = ["TRANSIENT_METHODS", "TransientResult", "integrate_periodic", "integrate_sampled",
           "sampled_system"]

log = logging.getLogger(__name__)

TRANSIENT_METHODS = ("radau", "dop853", "newmark")

System = Callable[[float], tuple]
Monitor = Callable[[np.ndarray], np.ndarray]
Cycle = Callable[[np.ndarray], tuple]


@dataclass(frozen=True)
class TransientResult:
    """Periodic response found by direct integration.

    Attributes
    ----------
    t : ndarray, shape (n_out,)
        Output times ``k T / n_out`` within the last cycle, s.
    U, V : ndarray, shape (n_out, N)
        Displacement and velocity at ``t`` (SI units of the DOFs, and per s).
    cycles : int
        Number of periods integrated.
    defect : float
        Periodicity defect of the last cycle. Without a monitor: ``max(|U(T) -
        U(0)|_inf / max|U|, |V(T) - V(0)|_inf / max|V|)`` (0 for a zero response);
        with one: ``max|w_c - w_(c-1)| / scale`` for the monitored history ``w``
        of cycle ``c`` (``inf`` after the first cycle).
    converged : bool
        ``defect <= tol``.
    method : str
    message : str
    nfev : int
        Evaluations of the terms: calls of the right-hand side ``f(t, z)`` (radau,
        dop853), or step times at which the terms were evaluated or sampled, once
        and reused by every cycle (newmark).
    njev : int
        Jacobian evaluations (radau; 0 otherwise).
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
    njev: int = 0


# ------------------------------------------------------------------ entry points
def integrate_periodic(system: System, N: int, period: float, method: str = "radau", *,
                       rtol: float = 1e-10, atol: float = 1e-12, tol: float = 1e-10,
                       max_cycles: int = 500, n_out: int = 100, steps_per_output: int = 10,
                       z0: np.ndarray | None = None, monitor: Monitor | None = None,
                       scale: float | None = None) -> TransientResult:
    """Integrate a continuous system cycle by cycle until the response is periodic.

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
        Tolerances of :func:`scipy.integrate.solve_ivp` (ignored by newmark);
        ``atol`` in the units of ``z = [u; u']``.
    tol : float
        Periodicity tolerance on the defect (see :class:`TransientResult`).
    max_cycles : int
        Give up (``converged=False``, :class:`ConvergenceWarning`) after this many.
    n_out : int
        Output nodes per period, ``t_k = k T / n_out``.
    steps_per_output : int
        Newmark steps between output nodes (step ``T / (n_out steps_per_output)``).
    z0 : ndarray, shape (2N,), optional
        Initial state ``[u; u']`` at ``t = 0``, default zero (rest).
    monitor : callable, optional
        ``monitor(U) -> ndarray``: a quantity of interest's history from the
        displacements ``U`` (n_out, N) of one cycle. When given, a cycle is
        periodic when its history differs from the previous cycle's by at most
        ``tol * scale`` (max-norm), instead of the state-jump test.
    scale : float, optional
        Reference magnitude of the monitored quantity (its units); default the
        max-norm of the current cycle's history.

    Returns
    -------
    TransientResult
    """
    _check_common(method, period, n_out, max_cycles)
    if int(N) < 1 or int(steps_per_output) < 1:
        raise InputError("N and steps_per_output must be positive integers")
    N, n_out, period = int(N), int(n_out), float(period)
    z = _initial_state(z0, N)
    if method == "newmark":
        n_steps = n_out * int(steps_per_output)
        times = np.arange(n_steps + 1) * (period / n_steps)
        M, C, K, Q = (np.stack(x) for x in zip(*(_eval(system, float(t), N) for t in times)))
        cycle = _newmark_cycler(M, C, K, Q, period / n_steps, z, int(steps_per_output))
        counts = {"nfev": n_steps + 1, "njev": 0}
    else:
        counts = {"nfev": 0, "njev": 0}
        cycle = _ivp_cycler(lambda t: _system_accel(system, t, N), N, period, n_out, method,
                            rtol, atol, counts)
    return _until_periodic(cycle, z, N, period, n_out, method, tol, int(max_cycles), monitor,
                           scale, counts)


def integrate_sampled(M, C, K, Q, period: float, method: str = "radau", *, rtol: float = 1e-10,
                      atol: float = 1e-12, tol: float = 1e-10, max_cycles: int = 500,
                      n_out: int | None = None, z0: np.ndarray | None = None,
                      monitor: Monitor | None = None, scale: float | None = None) -> TransientResult:
    """Integrate sampled periodic terms cycle by cycle until the response is periodic.

    Newmark steps on the sample grid ``h = T / n`` with the terms exactly at the
    step times; radau and dop853 integrate periodic cubic splines (through the
    samples) of ``M^-1 K``, ``M^-1 C`` and ``M^-1 Q``.

    Parameters
    ----------
    M, C, K : ndarray, shape (n, N, N) or (N, N)
        Mass, damping and stiffness at ``t_k = k T / n`` (or constant), SI units.
    Q : ndarray, shape (n, N)
        Load at ``t_k``.
    period : float
        Period ``T``, s.
    method : {"radau", "dop853", "newmark"}
    rtol, atol : float
        Tolerances of :func:`scipy.integrate.solve_ivp` (ignored by newmark).
    tol : float
        Periodicity tolerance on the defect (see :class:`TransientResult`).
    max_cycles : int
        Give up (``converged=False``, :class:`ConvergenceWarning`) after this many.
    n_out : int, optional
        Output nodes per period, ``t_k = k T / n_out``; default ``n``. Newmark
        needs ``n`` to be a multiple of ``n_out``.
    z0 : ndarray, shape (2N,), optional
        Initial state ``[u; u']`` at ``t = 0``, default zero (rest).
    monitor, scale
        Periodicity test on a quantity of interest, as in :func:`integrate_periodic`.

    Returns
    -------
    TransientResult
    """
    M, C, K, Q = _samples(M, C, K, Q)
    n, N = Q.shape
    n_out = n if n_out is None else n_out
    _check_common(method, period, n_out, max_cycles)
    n_out, period = int(n_out), float(period)
    z = _initial_state(z0, N)
    if method == "newmark":
        if n % n_out:
            raise InputError(f"newmark outputs at steps: n = {n} samples is not a multiple of "
                             f"n_out = {n_out}")
        M, C, K, Q = (np.concatenate([x, x[:1]]) for x in (M, C, K, Q))  # t_0 .. t_n = T
        cycle = _newmark_cycler(M, C, K, Q, period / n, z, n // n_out)
        counts = {"nfev": n, "njev": 0}
    else:
        counts = {"nfev": 0, "njev": 0}
        cycle = _ivp_cycler(_spline_accel(M, C, K, Q, period), N, period, n_out, method, rtol,
                            atol, counts)
    return _until_periodic(cycle, z, N, period, n_out, method, tol, int(max_cycles), monitor,
                           scale, counts)


# ------------------------------------------------------------------ input checks
def _check_common(method, period, n_out, max_cycles):
    """Raise :class:`InputError` on an unknown method, a bad period or bad counts."""
    if method not in TRANSIENT_METHODS:
        raise InputError(f"unknown method {method!r}; valid methods: {', '.join(TRANSIENT_METHODS)}")
    period = float(period)
    if not (math.isfinite(period) and period > 0):
        raise InputError(f"period must be a positive finite number, got {period!r}")
    if int(n_out) < 1 or int(max_cycles) < 1:
        raise InputError("n_out and max_cycles must be positive integers")


def _initial_state(z0, N):
    """Initial state ``[u; u']`` (2N,), zero by default."""
    return np.zeros(2 * N) if z0 is None else np.asarray(z0, dtype=float).reshape(2 * N).copy()


def _eval(system, t, N):
    """``system(t)`` as float arrays M, C, K (N, N) and Q (N,)."""
    M, C, K, Q = system(t)
    M = np.asarray(M, dtype=float).reshape(N, N)
    C = np.asarray(C, dtype=float).reshape(N, N)
    K = np.asarray(K, dtype=float).reshape(N, N)
    Q = np.asarray(Q, dtype=float).reshape(N)
    return M, C, K, Q


def _samples(M, C, K, Q):
    """Sampled terms as float arrays M, C, K (n, N, N) and Q (n, N); constants broadcast."""
    Q = np.asarray(Q, dtype=float)
    if Q.ndim != 2:
        raise InputError(f"Q must have shape (n, N), got {Q.shape}")
    n, N = Q.shape
    out = []
    for name, X in (("M", M), ("C", C), ("K", K)):
        X = np.asarray(X, dtype=float)
        if X.shape not in ((N, N), (n, N, N)):
            raise InputError(f"{name} must have shape ({n}, {N}, {N}) or ({N}, {N}), got {X.shape}")
        out.append(np.broadcast_to(X, (n, N, N)))
    return (*out, Q)


# ------------------------------------------------------------------ Newmark
def _newmark_operators(M, C, K, Q, h):
    """Average-acceleration Newmark operators of the steps ending at the given samples.

    Parameters
    ----------
    M, C, K : ndarray, shape (n, N, N)
        Terms at the end time of each step.
    Q : ndarray, shape (n, N)
    h : float
        Step, s.

    Returns
    -------
    R : ndarray, shape (n, N, 2N)
        ``E^-1 [K C]`` with ``E = M + h C / 2 + h^2 K / 4``.
    q : ndarray, shape (n, N)
        ``E^-1 Q``; the end acceleration of step ``k`` is ``q[k] - R[k] @ [u~; v~]``
        for the predictors ``u~, v~``.
    """
    Einv = np.linalg.inv(M + (0.5 * h) * C + (0.25 * h * h) * K)
    R = np.concatenate([Einv @ K, Einv @ C], axis=2)
    q = (Einv @ Q[..., None])[..., 0]
    return R, q


def _newmark_cycler(M, C, K, Q, h, z0, sub):
    """One-period Newmark integrator carrying the acceleration from cycle to cycle.

    Parameters
    ----------
    M, C, K : ndarray, shape (n + 1, N, N)
        Terms at the step times ``t_0 = 0, ..., t_n = T``.
    Q : ndarray, shape (n + 1, N)
    h : float
        Step ``T / n``, s.
    z0 : ndarray, shape (2N,)
        Initial state; its acceleration follows from the equation of motion at ``t_0``.
    sub : int
        Steps between output nodes.

    Returns
    -------
    callable
        ``cycle(z) -> (Z, z_T)``: states (n / sub, 2N) at the output nodes and the
        end state (2N,). Successive calls must continue from the previous end state.
    """
    N = Q.shape[1]
    R, q = _newmark_operators(M[1:], C[1:], K[1:], Q[1:], h)
    acc = [np.linalg.solve(M[0], Q[0] - C[0] @ z0[N:] - K[0] @ z0[:N])]

    def cycle(z):
        Z, zT, acc[0] = _newmark_cycle(R, q, h, z, acc[0], sub)
        return Z, zT
    return cycle


def _newmark_cycle(R, q, h, z, a, sub):
    """One period of average-acceleration Newmark from state ``z`` and acceleration ``a``.

    Returns (Z at the output nodes (n / sub, 2N), end state (2N,), end acceleration (N,)).
    """
    n, N = q.shape
    hh, hg = 0.25 * h * h, 0.5 * h
    u, v = z[:N].copy(), z[N:].copy()
    y = np.empty(2 * N)  # predictors [u~; v~]
    Z = np.empty((n // sub, 2 * N))
    for j in range(n // sub):
        Z[j, :N] = u
        Z[j, N:] = v
        for k in range(j * sub, (j + 1) * sub):
            y[:N] = u + h * v + hh * a
            y[N:] = v + hg * a
            a = q[k] - R[k] @ y
            u = y[:N] + hh * a
            v = y[N:] + hg * a
    return Z, np.concatenate([u, v]), a


# ------------------------------------------------------------------ solve_ivp
def _system_accel(system, t, N):
    """``(S, D, f) = M^-1 (K, C, Q)`` of ``system(t)``: S, D (N, N), f (N,)."""
    M, C, K, Q = _eval(system, t, N)
    X = np.linalg.solve(M, np.concatenate([K, C, Q[:, None]], axis=1))
    return X[:, :N], X[:, N:2 * N], X[:, 2 * N]


def _spline_accel(M, C, K, Q, period):
    """``t -> (S, D, f)``: periodic cubic splines of ``M^-1 K``, ``M^-1 C``, ``M^-1 Q``.

    Parameters
    ----------
    M, C, K : ndarray, shape (n, N, N)
        Terms at ``t_k = k T / n``.
    Q : ndarray, shape (n, N)
    period : float
        ``T``, s.
    """
    n = Q.shape[0]
    tk = np.arange(n + 1) * (period / n)
    Mi = np.linalg.inv(M)

    def spline(X):
        return CubicSpline(tk, np.concatenate([X, X[:1]]), bc_type="periodic")

    sS, sD, sf = spline(Mi @ K), spline(Mi @ C), spline((Mi @ Q[..., None])[..., 0])
    return lambda t: (sS(t), sD(t), sf(t))


def _ivp_cycler(accel, N, period, n_out, method, rtol, atol, counts):
    """One-period ``solve_ivp`` integrator of ``u'' = f - S u - D u'``.

    Parameters
    ----------
    accel : callable
        ``accel(t) -> (S, D, f)``, shapes (N, N), (N, N), (N,).
    N : int
    period : float
        ``T``, s.
    n_out : int
        Output nodes ``k T / n_out``.
    method : {"radau", "dop853"}
    rtol, atol : float
        Tolerances of :func:`scipy.integrate.solve_ivp`.
    counts : dict
        ``"nfev"``, ``"njev"`` counters, incremented in place.

    Returns
    -------
    callable
        ``cycle(z) -> (Z, z_T)``: states (n_out, 2N) at the output nodes and the end
        state (2N,).
    """
    J = np.zeros((2 * N, 2 * N))
    J[:N, N:] = np.eye(N)

    def rhs(t, y):
        counts["nfev"] += 1
        S, D, f = accel(t)
        return np.concatenate([y[N:], f - S @ y[:N] - D @ y[N:]])

    def jac(t, y):
        counts["njev"] += 1
        S, D, _ = accel(t)
        J[N:, :N] = -S
        J[N:, N:] = -D
        return J.copy()

    kw = {"method": "Radau", "jac": jac} if method == "radau" else {"method": "DOP853"}
    t_eval = np.append(np.arange(n_out) * (period / n_out), period)

    def cycle(z):
        sol = solve_ivp(rhs, (0.0, period), z, t_eval=t_eval, rtol=rtol, atol=atol, **kw)
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
        return sol.y[:, :-1].T, sol.y[:, -1]
    return cycle


# ------------------------------------------------------------------ cycling
def _state_defect(Z, zT, N):
    """State jump over a cycle, displacement and velocity each relative to their peak.

    Z : (n_out, 2N) states in the cycle (``Z[0]`` at its start); zT : (2N,) end state.
    """
    peak = np.abs(np.vstack([Z, zT])).reshape(-1, 2, N).max(axis=(0, 2))
    jump = np.abs(zT - Z[0]).reshape(2, N).max(axis=1)
    return float(np.divide(jump, peak, out=np.zeros(2), where=peak > 0).max())


def _monitor_defect(w, w_prev, scale, tol):
    """(defect, periodic) of a monitored history ``w`` against the previous cycle's."""
    if scale is None:
        scale = float(np.abs(w).max())
    if w_prev is None:
        return math.inf, False
    change = float(np.abs(w - w_prev).max())
    defect = change / scale if scale > 0 else (0.0 if change == 0 else math.inf)
    return defect, change <= tol * scale


def _until_periodic(cycle: Cycle, z, N, period, n_out, method, tol, max_cycles, monitor, scale,
                    counts) -> TransientResult:
    """Run ``cycle`` from state ``z`` until a cycle is periodic or ``max_cycles`` are spent."""
    w_prev = None
    for c in range(1, max_cycles + 1):
        Z, z = cycle(z)
        U = Z[:, :N].copy()
        if monitor is None:
            defect = _state_defect(Z, z, N)
            periodic = defect <= tol
        else:
            w = np.asarray(monitor(U))
            defect, periodic = _monitor_defect(w, w_prev, scale, tol)
            w_prev = w
        if periodic:
            break
    if periodic:
        msg = f"periodic after {c} cycles (defect {defect:.2e})"
        log.info("direct integration (%s): %s", method, msg)
    else:
        msg = f"not periodic after {max_cycles} cycles (defect {defect:.2e} > tol {tol:.1e})"
        warnings.warn(msg, ConvergenceWarning, stacklevel=user_stacklevel())
    t = np.arange(n_out) * (period / n_out)
    return TransientResult(t, U, Z[:, N:].copy(), c, defect, periodic, method, msg,
                           counts["nfev"], counts["njev"])


# ------------------------------------------------------------------ interpolation
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
