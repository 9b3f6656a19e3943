"""Periodic response of systems with state-dependent terms (paper section 4).

The equation ``(M + dM) u'' + (C + dC) u' + (K + dK) u = Q + dQ`` has parts
``dM, dC, dK, dQ`` that depend on the response itself (geometric non-linearity,
non-linear springs, friction following the velocity sign, ...). They are supplied
by a callback ``state_terms(U, V) -> (dM, dC, dK, dQ)`` evaluated on a trial
periodic response ``U, V`` at the time nodes; the linear periodic problem with
the terms frozen is solved by :func:`kedfem.solvers.periodic.solve`; this is the map
``G``. The iteration looks for a fixed point of ``G``:

``"fixed-point"``
    The paper's iteration ``x_{i+1} = G(x_i)``.
``"relaxation"``
    ``x_{i+1} = (1 - w) x_i + w G(x_i)`` with ``0 < w <= 1`` (``relaxation``).
``"anderson"``
    Anderson acceleration, type II (Walker & Ni 2011), on the stacked vector
    ``x = [U, V T / (2 pi)]`` (velocities scaled to displacement units) with the
    last ``depth`` differences.

The first iterate is the linear solve with the state terms evaluated at the zero
response ``U = V = 0`` (which is the paper's linear first step whenever the terms
vanish at zero). Convergence is the paper's Eq. 21,
``||U_G - U_i||_F / ||U_G||_F <= eps`` with ``U_G = G(x_i)`` (the paper writes the
ratio times 100 % against a percentage; here ``eps`` is a fraction). For the
plain iteration ``U_G`` is the next iterate, so this is literally Eq. 21; for the
accelerated methods it is the same fixed-point residual, not the (damped) step.
A zero change over a zero response counts as converged (no 0/0).
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np

from . import periodic
from ..errors import ConvergenceWarning, InputError, UnboundedResponseError, user_stacklevel

__all__ = ["solve", "fixed_point", "newton", "NewtonRate", "NewtonOutcome", "NonlinearResult", "NONLINEAR_METHODS"]

log = logging.getLogger(__name__)

NONLINEAR_METHODS = ("newton", "fixed-point", "relaxation", "anderson")
#: Smallest damping factor of Newton's line search before it gives up (the step is then too far
#: from the solution for the linearisation to point the way: continuation, not iteration)
NEWTON_LAMBDA_MIN = 1.0 / 1024
#: Sufficient decrease of the residual merit in Newton's line search (Armijo's constant)
ARMIJO = 1e-4
#: Most step fractions tried per Newton iteration
MAX_TRIALS = 12
#: Full Newton steps taken, watched, before the line search (see :func:`newton`)
WATCHDOG = 10
#: A watched full step whose correction exceeds the best one by this factor ends the watch
WATCHDOG_GROWTH = 10.0
#: The line search stalls when, over this many accepted steps, all of them damped (a step
#: fraction below 1), the change of the iterate ...
STALL_STEPS = 10
#: ... has not fallen below this fraction of what it was: the merit creeps down while the
#: corrections stay of the response's size (the four-bar preset with geometric_nonlinearity at
#: 350 rpm from the linear response: 0.93, 0.92, ... 0.86 over 10 steps, 0.67 after 35, which a
#: continuation in speed then had to do anyway; at 300 rpm its line search falls 0.74 -> 0.33 ->
#: 0.22 over twice 10 steps and converges after 33 solves: 0.7 stopped it there). Full steps
#: never stall: their change may rise on the way to the solution (sinh(u - 1) = 0 from 20)
STALL_RATIO = 0.85
#: Newton stops on a change its rate predicts the next one to be below this fraction of ``eps``
#: (see :class:`NewtonRate`): a tenth, so that a prediction off by 10x still meets ``eps``
PREDICT_FRACTION = 0.1
#: ... and only on a change at most this large (a step still far from the solution is not predicted)
PREDICT_MAX_CHANGE = 1e-2
#: On an iteration's first solve (no rate of its own yet), the residual after the step must have
#: shrunk to at most this multiple of the predicted ratio of changes
PREDICT_SLACK = 10.0
#: Stop as diverging when the change grows this much above its smallest value...
DIVERGENCE_FACTOR = 1e4
#: ... or when the response grows this much beyond the first (linear) solve.
GROWTH_LIMIT = 1e8

StateTerms = Callable[[np.ndarray, np.ndarray], tuple]


@dataclass(frozen=True)
class NonlinearResult:
    """Outcome of the non-linear periodic iteration.

    Attributes
    ----------
    solution : PeriodicSolution
        Linear periodic solution with the state terms evaluated at the last
        accepted iterate (when converged: the fixed point to ``eps``).
    iterations : int
        Number of linear periodic solves.
    history : ndarray, shape (iterations,)
        Relative change ``||U_G - U_i||_F / ||U_G||_F`` of each solve (Eq. 21).
    converged : bool
    message : str
    method : str
    """

    solution: periodic.PeriodicSolution
    iterations: int
    history: np.ndarray
    converged: bool
    message: str
    method: str


@dataclass(frozen=True)
class NewtonRate:
    """How fast Newton's corrections shrank at the end of an iteration, to predict the next one.

    Newton's method converges quadratically near a solution, ``d_{k+1} ~ C d_k^2`` for the
    relative changes ``d`` (Eq. 21), with a constant ``C`` of the problem (its curvature over
    its conditioning; Kantorovich), not of its discretisation; a tangent that is not exact
    converges linearly, ``d_{k+1} ~ r d_k``. Both are read off the last two full steps of a
    converged iteration (:attr:`constant` = ``d_{k+1} / d_k^2``, :attr:`ratio` =
    ``d_{k+1} / d_k``), and a later iteration of the same problem on finer time elements
    predicts its next change as the larger of the two models (:meth:`predict`): the quadratic
    model is pessimistic for changes larger than the one measured, the linear model for
    smaller ones. On the Whitworth with geometric non-linearity the second solve of each finer
    level changed the response by 2e-7 and 6e-10 where the prediction from the coarser level
    said 4e-7 and 9e-9: that solve is then not made.

    Attributes
    ----------
    constant : float
        ``C`` [-].
    ratio : float
        ``r`` [-].
    """

    constant: float
    ratio: float

    @classmethod
    def observed(cls, before: float, after: float) -> "NewtonRate | None":
        """The rate of two successive full steps' changes.

        Parameters
        ----------
        before, after : float
            Relative changes (Eq. 21) of an iterate and of the next, after a full step.

        Returns
        -------
        NewtonRate or None
            None unless both are finite and the change shrank.
        """
        if not (math.isfinite(before) and math.isfinite(after) and 0.0 < after < before):
            return None
        return cls(after / (before * before), after / before)

    def predict(self, change: float) -> float:
        """Upper estimate of the next change.

        Parameters
        ----------
        change : float
            A relative change (Eq. 21) of the iteration.

        Returns
        -------
        float
            ``max(C change^2, r change)``.
        """
        return max(self.constant * change * change, self.ratio * change)


@dataclass(frozen=True)
class NewtonOutcome:
    """What :func:`newton` returns.

    Attributes
    ----------
    solution : object
        The linear solve at the last iterate (when converged: at the solution).
    history : list of float
        Relative change of every iterate (Eq. 21).
    converged : bool
        A change met ``eps``, or the predicted next one met a tenth of it.
    message : str
        How it ended (for logs and warnings).
    rate : NewtonRate or None
        Observed on the last two full steps that shrank (None without such a pair).
    predicted : float or None
        When it stopped on a prediction: the predicted change of the next iterate, the
        distance of ``solution`` from the solution (else None: the last change met ``eps``).
    """

    solution: object
    history: list
    converged: bool
    message: str
    rate: NewtonRate | None = None
    predicted: float | None = None


def _add(base, extra, name, shape, it):
    if extra is None:
        return base
    extra = np.asarray(extra, dtype=float)
    if extra.shape != shape:
        raise InputError(f"state_terms returned {name} with shape {extra.shape} at iteration "
                         f"{it}; expected {shape} (or None)")
    bad = ~np.isfinite(extra)
    if bad.any():
        raise InputError(f"state_terms returned a non-finite {name} at iteration {it}, index "
                         f"{tuple(int(i) for i in np.argwhere(bad)[0])}")
    return base + extra  # broadcasting lifts constant (N, N) bases to (n, N, N)


def solve(M, C, K, Q, period: float, state_terms: StateTerms, hold: str = "foh", *,
          eps: float = 1e-6, max_iter: int = 50, method: str = "fixed-point",
          relaxation: float = 0.5, depth: int = 5, linearization: str = "secant",
          **solver_kwargs) -> NonlinearResult:
    """Iterate the linear periodic solve until the state-dependent terms settle.

    Parameters
    ----------
    M, C, K : ndarray, shape (n, N, N) or (N, N)
        State-independent (linear) parts, as in :func:`kedfem.solvers.periodic.solve`
        (callables are not accepted here: the state terms are sampled arrays).
    Q : ndarray, shape (n, N)
        State-independent load.
    period : float
        Period, s.
    state_terms : callable
        ``state_terms(U, V) -> (dM, dC, dK, dQ)`` for a trial response ``U, V``
        of shape ``(n, N)``; each returned item is ``None`` or an array of shape
        ``(n, N, N)`` (``dM, dC, dK``) or ``(n, N)`` (``dQ``).
    hold : str
        Hold scheme of the linear solves.
    eps : float
        Convergence tolerance of Eq. 21 as a fraction (not percent).
    max_iter : int
        Maximum number of linear solves.
    method : {"fixed-point", "relaxation", "anderson"}
    relaxation : float
        Weight ``w`` of the relaxation method, ``0 < w <= 1``.
    depth : int
        Number of previous differences Anderson acceleration keeps.
    linearization : {"secant", "tangent"}
        What ``state_terms`` returns. ``"secant"`` (the paper's form): parts of
        the equation's coefficients, ``K_N(U)`` etc., sampled at the nodes and
        interpolated by the hold like ``K`` and ``Q``. ``"tangent"``: a
        linearisation about the trial response at each node (tangent
        ``dC, dK`` with the matching load ``dQ = -f_nl + K_nl U + C_nl V``),
        held over the element that starts at the node (``Kz, Cz, Qz`` of
        :func:`kedfem.solvers.periodic.solve`) so that it cancels at the node: the
        fixed point then solves the non-linear equations, the plain iteration
        is Newton's method, and the error of the linearisation over an
        element is ``O(dt^2)``.
    **solver_kwargs
        Passed on to :func:`kedfem.solvers.periodic.solve` (``delta``, ``memory_budget``...).

    Returns
    -------
    NonlinearResult
        ``converged=False`` with a :class:`~kedfem.errors.ConvergenceWarning` when
        ``max_iter`` is reached or the iteration diverges; the last iterate and
        its history are returned either way.
    """
    if method not in NONLINEAR_METHODS:
        raise InputError(f"unknown method {method!r}; valid methods: {', '.join(NONLINEAR_METHODS)}")
    if linearization not in ("secant", "tangent"):
        raise InputError(f"linearization must be 'secant' or 'tangent', got {linearization!r}")
    if not callable(state_terms):
        raise InputError("state_terms must be callable: state_terms(U, V) -> (dM, dC, dK, dQ)")
    if not (isinstance(max_iter, (int, np.integer)) and max_iter >= 1):
        raise InputError(f"max_iter must be a positive integer, got {max_iter!r}")
    if not (math.isfinite(eps) and eps > 0):
        raise InputError(f"eps must be a positive number, got {eps!r}")
    if not (0 < relaxation <= 1):
        raise InputError(f"relaxation must lie in (0, 1], got {relaxation!r}")
    if not (isinstance(depth, (int, np.integer)) and depth >= 1):
        raise InputError(f"depth must be a positive integer, got {depth!r}")
    for name, X in (("M", M), ("C", C), ("K", K), ("Q", Q)):
        if callable(X):
            raise InputError(f"{name} must be an array for the non-linear iteration, not a callable")
    Q = np.asarray(Q, dtype=float)
    if Q.ndim != 2:
        raise InputError(f"Q must have shape (n, N), got {Q.shape}")
    n, N = Q.shape
    period = float(period)

    def G(U, V, it):
        dM, dC, dK, dQ = state_terms(U, V)
        Mi = _add(M, dM, "dM", (n, N, N), it)
        if hold == "zoh" or linearization == "secant":
            Ci = _add(C, dC, "dC", (n, N, N), it)
            Ki = _add(K, dK, "dK", (n, N, N), it)
            Qi = _add(Q, dQ, "dQ", (n, N), it)
            return periodic.solve(Mi, Ci, Ki, Qi, period, hold=hold, **solver_kwargs)
        # foh / magnus2: the state-dependent stiffness and load are a linearisation
        # about node k; held over element k they cancel at the node (Newton-like
        # convergence) -- interpolating the load but not the stiffness would not.
        Kz = _add(np.zeros((n, N, N)), dK, "dK", (n, N, N), it) if dK is not None else None
        Qz = _add(np.zeros((n, N)), dQ, "dQ", (n, N), it) if dQ is not None else None
        Cz = _add(np.zeros((n, N, N)), dC, "dC", (n, N, N), it) if dC is not None else None
        return periodic.solve(Mi, C, K, Q, period, hold=hold, Kz=Kz, Qz=Qz, Cz=Cz, **solver_kwargs)

    Gx = (lambda U, V, it: (lambda so: (so, so.U, so.V))(G(U, V, it)))
    if method == "newton":  # with the tangent linearisation G is Newton's step; with the secant a damped iteration
        out = newton(Gx, n, N, period, eps=eps, max_iter=max_iter)
        sol, history, converged, message = out.solution, out.history, out.converged, out.message
    else:
        sol, history, converged, message = fixed_point(Gx, n, N, period, eps=eps, max_iter=max_iter, method=method,
                                                       relaxation=relaxation, depth=depth)
    return NonlinearResult(solution=sol, iterations=len(history),
                           history=np.asarray(history), converged=converged,
                           message=message, method=method)


def fixed_point(G, n: int, N: int, period: float, *, eps: float = 1e-6, max_iter: int = 50,
                method: str = "fixed-point", relaxation: float = 0.5, depth: int = 5,
                x0: tuple[np.ndarray, np.ndarray] | None = None):
    """Fixed point of a periodic solve map ``(U, V) -> G(U, V)`` (see the module docstring).

    Parameters
    ----------
    G : callable
        ``G(U, V, it) -> (solution, U_new, V_new)``: one linear periodic solve
        with the state-dependent terms evaluated at the trial response
        ``U, V`` (n, N) at the instants where the scheme needs them; returns
        its solution object and the new response at the same instants.
    n, N : int
        Instants and DOFs of the iterate.
    period : float
        [s] (scales velocities into the stacked vector of Anderson's method).
    eps, max_iter, method, relaxation, depth
        As in :func:`solve`.
    x0 : (U, V), optional
        First trial response (default zero: the first solve is the linear one).

    Returns
    -------
    solution : object
        Of the last solve.
    history : list of float
        Eq. 21 changes.
    converged : bool
    message : str
    """
    vscale = period / (2 * math.pi)  # velocity -> displacement units in the stacked vector

    def pack(U, V):
        return np.concatenate([U.ravel(), (V * vscale).ravel()])

    def unpack(x):
        return x[:n * N].reshape(n, N), x[n * N:].reshape(n, N) / vscale

    x = np.zeros(2 * n * N) if x0 is None else pack(np.asarray(x0[0], float), np.asarray(x0[1], float))
    history: list[float] = []
    dG: list[np.ndarray] = []
    dF: list[np.ndarray] = []
    f_prev = g_prev = None
    first_norm = 0.0
    sol = None
    converged = False
    message = ""
    for it in range(1, max_iter + 1):
        U, V = unpack(x)
        try:
            sol, Un, Vn = G(U, V, it)
        except UnboundedResponseError as exc:
            if sol is None:   # the first solve: the response itself is unbounded
                raise
            history.append(math.inf)
            message = (f"diverging: the linear solve at iteration {it} is unbounded ({exc}); the last "
                       f"bounded iterate is kept (after {it - 1} linear solves)")
            break
        g = pack(Un, Vn)
        f = g - x
        dU = float(np.linalg.norm(Un - U))
        nU = float(np.linalg.norm(Un))
        change = 0.0 if dU == 0.0 else (dU / nU if nU > 0 else math.inf)
        history.append(change)
        log.debug("nonlinear (%s): iteration %d change %.3e", method, it, change)
        if change <= eps:
            converged = True
            message = f"converged after {it} linear solves (change {change:.2e} <= eps {eps:.1e})"
            break
        if it == 1:
            first_norm = float(np.linalg.norm(g))
        growth = float(np.linalg.norm(g)) / max(first_norm, np.finfo(float).tiny)
        if (not np.isfinite(change) or not np.all(np.isfinite(g))
                or change > DIVERGENCE_FACTOR * max(min(history), eps)
                or growth > GROWTH_LIMIT):
            message = (f"diverging: change {change:.2e}, response {growth:.2e} times the first "
                       f"linear solve, after {it} linear solves (smallest change "
                       f"{min(history):.2e})")
            break
        if method == "fixed-point":
            x_new = g
        elif method == "relaxation":
            x_new = x + relaxation * f
        else:
            if f_prev is not None:
                dG.append(g - g_prev)
                dF.append(f - f_prev)
                if len(dF) > depth:
                    dG.pop(0)
                    dF.pop(0)
            x_new = g
            if dF:
                Fm = np.stack(dF, axis=1)
                gamma, *_ = np.linalg.lstsq(Fm, f, rcond=1e-10)
                x_new = g - np.stack(dG, axis=1) @ gamma
            f_prev, g_prev = f, g
        x = x_new
    else:
        message = (f"not converged after {max_iter} linear solves (last change "
                   f"{history[-1]:.2e} > eps {eps:.1e})")
    if not converged:
        warnings.warn(f"non-linear iteration ({method}): {message}", ConvergenceWarning, stacklevel=user_stacklevel())
    log.info("non-linear iteration (%s): %s", method, message)
    return sol, history, converged, message


def _chord(solution) -> bool:
    """The solution was made by a chord step (a frozen tangent), not by Newton's."""
    return bool(getattr(solution, "chord", False))


def newton(G, n: int, N: int, period: float, *, eps: float = 1e-6, max_iter: int = 50,
           x0: tuple[np.ndarray, np.ndarray] | None = None, merit=None,
           lambda_min: float = NEWTON_LAMBDA_MIN, warn: bool = True,
           rate: NewtonRate | None = None, unfreeze=None) -> NewtonOutcome:
    """Newton's method with a line search on the periodic problem (the G map is its Newton step).

    With the state terms in tangent form, ``G(x) - x`` is the full Newton correction of the
    discrete periodic problem at ``x`` (the linear periodic solve is the tangent's block-cyclic
    system). The step ``x + lambda (G(x) - x)`` is accepted by a sufficient decrease of the
    residual, ``phi(x_new) <= (1 - ARMIJO lambda) phi(x)`` with ``phi = merit`` (the scaled norm
    of the discrete equations' residual: a trial costs no linear solve, and the Newton direction
    is a descent direction of it), or without a merit by the natural monotonicity of the
    corrections, ``||G(x_new) - x_new|| <= (1 - lambda / 2) ||G(x) - x||`` (a trial then costs
    a solve). A rejected ``lambda`` is replaced by the minimum of the quadratic model of
    ``phi^2`` along the step, clipped to ``[lambda / 10, lambda / 2]``, down to ``lambda_min``.
    Near the solution ``lambda = 1`` is accepted and the convergence is quadratic: one linear
    solve per iteration.

    It stops when a change meets ``eps``, or, given the ``rate`` of an earlier iteration of the
    same problem (a coarser level), when the change is at most :data:`PREDICT_MAX_CHANGE` and
    the next change it predicts (:meth:`NewtonRate.predict`, the larger of that rate's and the
    rate observed here) is below :data:`PREDICT_FRACTION` of ``eps``: the solve that would only
    confirm it is not made, and the returned solution (the solve about the last iterate) is
    that predicted distance from the solution. On the first solve, before a rate of its own is
    observed, the prediction must be borne out by the residual: the merit after the step at most
    :data:`PREDICT_SLACK` times the predicted ratio of changes times the merit before (without a
    merit no first solve stops on a prediction).

    Parameters
    ----------
    G : callable
        ``G(U, V, it) -> (solution, U_new, V_new)`` (see :func:`fixed_point`).
    n, N, period, eps, max_iter, x0
        As :func:`fixed_point` (``max_iter``: linear solves).
    merit : callable, optional
        ``merit(U, V) -> float``, the norm of the residual of the discrete equations at a trial
        response (see :func:`kedfem.solvers.collocation.residual`).
    lambda_min : float
        Smallest step fraction tried.
    warn : bool
        Issue a :class:`ConvergenceWarning` when it does not converge.
    rate : NewtonRate, optional
        Observed at the end of an earlier iteration of the same problem: lets it stop on a
        predicted change (see above). None: only a change that meets ``eps`` stops it.
    unfreeze : callable, optional
        ``unfreeze()`` makes ``G``'s next step a full Newton step (drops a frozen tangent). Where
        the line search finds no decrease along a chord step's direction (a tangent frozen at
        another iterate, which need not lower the residual), Newton's own direction at the
        iterate is tried before the iteration gives up.

    Returns
    -------
    NewtonOutcome
        ``history`` holds the Eq. 21 change of every iterate (the relative Newton correction
        of the displacements). ``solution`` is the linear solve at the last iterate; when not
        converged it is no answer (the caller must not read it as one).
    """
    vscale = period / (2 * math.pi)

    def pack(U, V):
        return np.concatenate([U.ravel(), (V * vscale).ravel()])

    def unpack(x):
        return x[:n * N].reshape(n, N), x[n * N:].reshape(n, N) / vscale

    def evaluate(x, it):
        U, V = unpack(x)
        sol, Un, Vn = G(U, V, it)
        g = pack(Un, Vn)
        if not np.all(np.isfinite(g)):
            raise UnboundedResponseError("the linear solve about the trial iterate is not finite")
        return sol, g - x, float(np.linalg.norm(Un - U)), float(np.linalg.norm(Un))

    def phi_of(x):
        try:
            v = float(merit(*unpack(x)))
        except (UnboundedResponseError, FloatingPointError, OverflowError):
            return math.inf
        return v if math.isfinite(v) else math.inf

    x = np.zeros(2 * n * N) if x0 is None else pack(np.asarray(x0[0], float), np.asarray(x0[1], float))
    solves = 1
    history: list[float] = []
    sol, d, dU, nU = evaluate(x, 1)

    def rel(dU, nU):
        return 0.0 if dU == 0.0 else (dU / nU if nU > 0 else math.inf)

    seen: NewtonRate | None = None  # observed on this iteration's last two full steps that shrank
    borne: dict[float, bool] = {}  # change -> its prediction borne out by the residual (first solve)

    def predicted(change):
        """The next change predicted from ``change`` (inf without a rate to predict it by)."""
        if rate is None or not change <= PREDICT_MAX_CHANGE:
            return math.inf
        return max(rate.predict(change), seen.predict(change) if seen is not None else 0.0)

    def settled(change, at, step, solution):
        """``change`` (of the iterate ``at``, whose solve ``solution`` is ``at + step``) ends the
        iteration. A chord step's solution is not Newton's: only a change below ``eps`` ends it."""
        if change <= eps:
            return True
        if _chord(solution):
            return False
        guess = predicted(change)
        if not guess <= PREDICT_FRACTION * eps:
            return False
        if seen is not None:
            return True
        # nothing observed on this iteration yet (its first solve): the residual must have shrunk
        # as the prediction says, within PREDICT_SLACK (an assembly each, no solve); a map that
        # converges slower than the coarser level's (a resonance it did not resolve) does not stop
        if merit is None:
            return False
        if change not in borne:  # the watch and the line search ask about the same iterate
            before, after = phi_of(at), phi_of(at + step)
            borne[change] = math.isfinite(after) and after <= PREDICT_SLACK * (guess / change) * before
        return borne[change]

    # watched full steps: on a stiff, strongly non-linear problem the full Newton step often
    # converges where a monotone line search creeps (the residual of the stiff axial rows rises
    # for a step or two); the best iterate is kept and the line search starts from it if not
    best = (rel(dU, nU), x, sol, d, dU, nU)
    watched = 0
    while watched < WATCHDOG and solves < max_iter and not settled(best[0], best[1], best[3], best[2]):
        history.append(rel(dU, nU))
        xt = x + d
        solves += 1
        watched += 1
        try:
            st, dt, dUt, nUt = evaluate(xt, solves)
        except UnboundedResponseError:
            break
        ct = rel(dUt, nUt)
        if not math.isfinite(ct) or ct > WATCHDOG_GROWTH * best[0]:
            break
        if not _chord(sol):  # the rate of Newton's own steps, not of a chord step's
            seen = NewtonRate.observed(history[-1], ct) or seen
        x, sol, d, dU, nU = xt, st, dt, dUt, nUt
        if ct < best[0]:
            best = (ct, x, sol, d, dU, nU)
    _c, x, sol, d, dU, nU = best
    phi = None  # the merit of x: evaluated only when a line search needs it (it costs an assembly)
    lam = 1.0
    converged, message, guess = False, "", None
    last = None  # the change before a full step of the line search, for the observed rate
    # (change, step fraction) of the iterates the line search accepted (not the watch's best it
    # starts from: a damped step lowers the residual while the correction may grow, 0.056 -> 0.74)
    searched: list[tuple[float, float]] = []
    while True:
        change = 0.0 if dU == 0.0 else (dU / nU if nU > 0 else math.inf)
        if last is not None:
            seen = NewtonRate.observed(last, change) or seen
        history.append(change)
        if phi is not None:  # an iterate of the line search, by a step of fraction lam
            searched.append((change, lam))
        log.debug("newton: solve %d change %.3e merit %s lambda %.3g", solves, change,
                  "-" if phi is None else f"{phi:.3e}", lam)
        if change <= eps:
            converged = True
            message = f"converged after {solves} linear solves (change {change:.2e} <= eps {eps:.1e})"
            break
        if settled(change, x, d, sol):
            converged, guess = True, predicted(change)
            message = (f"converged after {solves} linear solves (change {change:.2e}; Newton's rate "
                       f"predicts the next below {guess:.1e} <= {PREDICT_FRACTION:g} eps {eps:.1e})")
            break
        if solves >= max_iter:
            message = f"not converged after {max_iter} linear solves (last change {change:.2e} > eps {eps:.1e})"
            break
        if len(searched) > STALL_STEPS and change > STALL_RATIO * searched[-STALL_STEPS - 1][0] \
                and all(f < 1.0 for _c, f in searched[-STALL_STEPS:]):
            message = (f"stalled: the change went from {searched[-STALL_STEPS - 1][0]:.2e} to {change:.2e} over "
                       f"{STALL_STEPS} damped steps ({solves} linear solves in all): the line search creeps, the "
                       "iterate is too far from a periodic response for the linearisation to lead to it")
            break
        if phi is None:
            phi = phi_of(x) if merit is not None else float(np.linalg.norm(d))
        lam = min(1.0, 4.0 * lam)  # after a damped step, try a longer one
        accepted, trials = False, 0
        while lam >= lambda_min and trials < MAX_TRIALS:
            trials += 1
            xt = x + lam * d
            if merit is not None:
                phit = phi_of(xt)
                ok = phit <= (1.0 - ARMIJO * lam) * phi
            else:
                solves += 1
                try:
                    st, dt, dUt, nUt = evaluate(xt, solves)
                    phit = float(np.linalg.norm(dt))
                except UnboundedResponseError:
                    phit = math.inf
                ok = phit <= (1.0 - 0.5 * lam) * phi
            if ok:
                accepted = True
                break
            if math.isfinite(phit) and phit > 0:
                # phi^2 along the step: phi0^2 (1 - 2 l) + c l^2 through phi(lam); its minimum
                c = (phit * phit - phi * phi * (1.0 - 2.0 * lam)) / (lam * lam)
                pred = phi * phi / c if c > 0 else 0.5 * lam
                lam = min(max(pred, 0.1 * lam), 0.5 * lam)
            else:
                lam *= 0.1
        if not accepted and _chord(sol) and unfreeze is not None and solves < max_iter:
            # a chord step's direction: Newton's own at x before giving up (a Watt six-bar by a
            # resonance gave up at a change of 1.2e-3 after 43 solves and ran up in speed, 10x the time)
            unfreeze()
            solves += 1
            try:
                sol, d, dU, nU = evaluate(x, solves)
            except UnboundedResponseError as exc:
                message = f"the linear solve about the iterate is unbounded ({exc})"
                break
            lam, last = 0.25, None  # (the next line search starts at the full step)
            continue
        if not accepted:
            message = (f"the line search found no step that lowers the residual (step fraction below "
                       f"{max(lam, lambda_min):.2g} after {solves} linear solves; last change {change:.2e}): "
                       "the iterate is too far from a periodic response for the linearisation to lead to it")
            break
        if merit is not None:
            solves += 1
            try:
                st, dt, dUt, nUt = evaluate(xt, solves)
            except UnboundedResponseError as exc:
                message = f"the linear solve about an accepted iterate is unbounded ({exc})"
                break
        last = change if lam == 1.0 and not _chord(sol) else None
        x, sol, d, dU, nU, phi = xt, st, dt, dUt, nUt, phit
    if not converged and warn:
        warnings.warn(f"non-linear iteration (newton): {message}", ConvergenceWarning, stacklevel=user_stacklevel())
    log.info("non-linear iteration (newton): %s", message)
    return NewtonOutcome(sol, history, converged, message, seen, guess)


def fixed_point_or_anderson(G, n: int, N: int, period: float, *, eps: float = 1e-6, max_iter: int = 50,
                            method: str = "fixed-point", x0=None, merit=None):
    """:func:`fixed_point`, and when the plain iteration fails, Anderson acceleration from the start.

    The plain iteration diverges where a resonance or buckling makes the state
    terms amplify (an offset slider-crank with two flexible links, Rayleigh
    beta = 1e-5 s); Anderson converges there. Other methods run as asked.

    Returns
    -------
    solution, history, converged, method
        ``history`` holds both attempts' changes; ``method`` is the one whose
        solution is returned. The abandoned attempt's warnings are dropped.
    """
    import warnings as _w
    if method == "newton":
        out = newton(G, n, N, period, eps=eps, max_iter=max_iter, x0=x0, merit=merit)
        return out.solution, tuple(out.history), out.converged, method
    if method != "fixed-point":
        sol, hist, conv, _msg = fixed_point(G, n, N, period, eps=eps, max_iter=max_iter, method=method, x0=x0)
        return sol, tuple(hist), conv, method
    with _w.catch_warnings(record=True) as first:
        _w.simplefilter("always")
        sol, hist, conv, _msg = fixed_point(G, n, N, period, eps=eps, max_iter=max_iter, x0=x0)
    if conv:
        _reissue(first)
        return sol, tuple(hist), conv, method
    with _w.catch_warnings(record=True) as second:
        _w.simplefilter("always")
        sol2, hist2, conv2, _msg = fixed_point(G, n, N, period, eps=eps, max_iter=max_iter, method="anderson")
    log.info("the fixed-point iteration did not converge; Anderson acceleration %s after %d solves",
             "converged" if conv2 else "did not converge either", len(hist2))
    if conv2:
        _reissue(second)
        return sol2, tuple(hist) + tuple(hist2), True, "anderson"
    _reissue(first)
    return sol, tuple(hist) + tuple(hist2), False, method


def _reissue(caught) -> None:
    import warnings as _w
    for w in caught:
        _w.warn_explicit(w.message, w.category, w.filename, w.lineno)
