"""One-level error estimate of a Radau IIA collocation solve by defect correction.

Zadunaisky's "neighbouring problem": the solve's element-end states ``u_k, v_k`` and the
accelerations there (the last stage's, at the element end of a stiffly accurate scheme) define
the piecewise quintic Hermite interpolant ``P(t)`` (twice continuously differentiable). ``P``
solves exactly the problem whose load is ``Q + d``, with its defect

    d(t) = M P'' + C P' + K P - Q

at the collocation instants. Solving that neighbouring problem with the same scheme on the
same elements makes an error ``u~ - P`` that mimics the solve's own error ``u - y``; since the
problem is linear in its load, ``u~ = u + w`` with ``w`` the scheme's response to ``d`` alone,
and the corrected solution is ``y ~ P - w``. Its difference from the solve, ``u - (P - w)``,
is the estimate, at every instant of the cycle (dense output included).

Measured (``benchmarks/defect_probe.py``) against radau3 references on 1536 elements, on the
response over the cycle: est / true 1.0 .. 1.2 once the elements resolve the modes that carry
the error, 0.2 .. 0.7 before. The pipeline therefore believes it only where it also explains
the change between two levels (:meth:`kedfem.analysis.pipeline._Run.defect_estimate`).

For a non-linear scene the defect is that of the tangent system about the converged iterate (the
state terms in tangent form reproduce the non-linear forces there to first order; ``P - u`` is
of the order of the error); the response to it may come from a tangent factorised at an earlier
iterate near the solution (:meth:`kedfem.analysis.problem.PeriodicProblem.corrected`), which
changes the estimate by about that iterate's relative distance.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import InputError
from . import collocation
from .collocation import apply_at_instants
from .schemes import Discrete

__all__ = ["available", "corrected"]


def _hermite5() -> np.ndarray:
    """Monomial coefficients (6 powers x 6 basis functions) of the quintic Hermite basis on
    [0, 1], basis order ``u0, h v0, h^2 a0, u1, h v1, h^2 a1``."""
    rows = []
    for x in (0.0, 1.0):
        for d in range(3):
            rows.append([math.factorial(p) / math.factorial(p - d) * x ** (p - d) if p >= d else 0.0
                         for p in range(6)])
    return np.linalg.inv(np.array(rows))


_H5 = _hermite5()


def _basis(theta: np.ndarray, d: int) -> np.ndarray:
    """``d``-th derivative in ``theta`` of the six Hermite basis functions, shape (k, 6)."""
    pw = np.zeros((theta.size, 6))
    for p in range(d, 6):
        pw[:, p] = math.factorial(p) / math.factorial(p - d) * theta ** (p - d)
    return pw @ _H5


def offered(scheme: str) -> bool:
    """The estimate reads solves of this scheme: a stiffly accurate collocation (Radau IIA) of
    stage order at least 3 (``radau3``)."""
    try:
        tab = collocation.tableau(scheme)
    except InputError:  # an exponential hold or Fourier: no collocation tableau
        return False
    return bool(tab.c[-1] == 1.0 and tab.stage_order >= 3)


def available(discrete: Discrete) -> bool:
    """The solve is a stiffly accurate collocation (Radau IIA) of stage order at least 3
    (``radau3``), whose element-end states and accelerations the estimate reads. With ``radau2``
    (stage order 2) the end stage's acceleration is too rough for the quintic interpolant: the
    estimate came out 5x the true error on 24 elements (a test)."""
    raw = discrete.raw
    return isinstance(raw, collocation.CollocationSolution) and raw.stage_V is not None and offered(raw.scheme)


class _Hermite:
    """The piecewise quintic Hermite interpolant of a collocation solution's element ends."""

    def __init__(self, sol: collocation.CollocationSolution):
        n, s, N = sol.stage_V.shape
        self.n, self.period, self.edges = n, sol.period, sol.edges
        self.h, acc = collocation._stage_accelerations(sol.stage_V.reshape(n * s, N), sol.period, sol.scheme,
                                                       sol.edges)
        A = np.roll(acc[:, -1], 1, axis=0)  # the end stage of the element before: at the element start
        self.U, self.V, self.A = sol.U, sol.V, A

    def locate(self, t):
        """Element and fraction of each instant ``t`` [s] (modulo the period)."""
        return collocation.locate(t, self.n, self.period, self.edges)

    def eval(self, k, theta, d: int) -> np.ndarray:
        """``d``-th time derivative (k, N) at element ``k``, fraction ``theta``."""
        h = self.h[k][:, None]
        k1 = (k + 1) % self.n
        B = _basis(theta, d) / h ** d
        return (B[:, 0:1] * self.U[k] + B[:, 1:2] * h * self.V[k] + B[:, 2:3] * h * h * self.A[k]
                + B[:, 3:4] * self.U[k1] + B[:, 4:5] * h * self.V[k1] + B[:, 5:6] * h * h * self.A[k1])

    def at(self, t):
        k, th = self.locate(t)
        return self.eval(k, th, 0), self.eval(k, th, 1)

    def velocities(self, t):
        k, th = self.locate(t)
        return self.eval(k, th, 1)


def defect(sol: collocation.CollocationSolution, M, C, K, Q) -> tuple[_Hermite, np.ndarray]:
    """The Hermite interpolant of ``sol`` and its defect (n s, N) [N] at the collocation instants.

    Parameters
    ----------
    sol : CollocationSolution
        A stiffly accurate collocation solve.
    M, C, K : ndarray, shape (n s, N, N) or (N, N)
        The system it solved (with any state terms), at the collocation instants.
    Q : ndarray, shape (n s, N)
    """
    P = _Hermite(sol)
    c = collocation.tableau(sol.scheme).c
    n, s = P.n, c.size
    k = np.repeat(np.arange(n), s)
    th = np.tile(c, n)
    d = (apply_at_instants(M, P.eval(k, th, 2)) + apply_at_instants(C, P.eval(k, th, 1))
         + apply_at_instants(K, P.eval(k, th, 0)) - np.asarray(Q, dtype=float))
    return P, d


def corrected(discrete: Discrete, M, C, K, Q, resolve) -> Discrete:
    """The defect-corrected solution ``P - w`` of a collocation solve (see the module docstring).

    Parameters
    ----------
    discrete : Discrete
        A stiffly accurate collocation solve (:func:`available`).
    M, C, K : ndarray, shape (n s, N, N) or (N, N)
        Its system at the collocation instants [kg, N s/m, N/m] (with any state terms in tangent
        form about the solution).
    Q : ndarray, shape (n s, N)
        Its load [N].
    resolve : callable
        ``resolve(load) -> Discrete``: the same scheme, system and elements under another load
        (n s, N) (a kept factorisation, or a solve).

    Returns
    -------
    Discrete
        Reads like ``discrete`` (``at``, ``velocities``, ``instant_states``); its difference from
        it is the estimated error of ``discrete`` at any instant.
    """
    sol = discrete.raw
    P, d = defect(sol, M, C, K, Q)
    w = resolve(d)
    n, s, N = sol.stage_V.shape
    c = collocation.tableau(sol.scheme).c

    def at(t):
        u, v = P.at(t)
        wu, wv = w.at(t)
        return u - wu, v - wv

    def velocities(t):
        return P.velocities(t) - w.velocities(t)

    def instant_states():
        k, th = np.repeat(np.arange(n), s), np.tile(c, n)
        wu, wv = w.instant_states()
        return P.eval(k, th, 0) - wu, P.eval(k, th, 1) - wv

    return dataclasses.replace(discrete, U=sol.U - w.U, V=sol.V - w.V, raw=None, _at=at,
                               _instant_states=instant_states, _velocities=velocities, resolver=None,
                               chord=False)
