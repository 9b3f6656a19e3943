"""Periodic states of a one-step time discretisation: ``z_{k+1} = A_k z_k + b_k``, ``z_n = z_0``.

:func:`solve_cyclic` is the block-cyclic core that the exponential holds
(:mod:`kedfem.solvers.periodic`) and the collocation elements (:mod:`kedfem.solvers.collocation`)
share: it plans the chunks (:func:`_plan_chunks`), condenses the system
(:mod:`kedfem.solvers.condensation`), analyses the monodromy matrix
(:mod:`kedfem.solvers.monodromy`), then marches the states from ``z_0``
(:mod:`kedfem.solvers.march`) or solves the whole system by sparse LU
(:mod:`kedfem.solvers.cyclic_lu`). :class:`CyclicFactors` keeps a condensed system for other
loads.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from .condensation import _check_bounded, _condense, _Condensed, _second_pass
from .cyclic_lu import _solve_by_cyclic_lu
from .march import _march
from .monodromy import (MAX_CONDITION, _balanced_condition, _check_resonance, _choose_method,
                        _floquet_multipliers, _solve_z0)

# the records keep the logger they had before the split (issue 27): a filter on it still works
log = logging.getLogger("kedfem.solvers.periodic")


@dataclass(frozen=True)
class CyclicSolution:
    """Outcome of :func:`solve_cyclic` (see :class:`PeriodicSolution` for the fields)."""

    Z: np.ndarray
    multipliers: np.ndarray
    stable: bool
    residual: float
    monodromy: np.ndarray
    method: str
    condition: float
    passes: int
    factors: "CyclicFactors | None" = None


@dataclass(frozen=True)
class CyclicFactors:
    """The condensed transitions of a solved block-cyclic system, kept for other loads.

    ``z_{k+1} = A_k z_k + b'_k``, ``z_n = z_0`` with the same ``A_k`` and new ``b'_k``: one march
    from zero gives the particular part, ``I - Phi`` (balanced, as the first solve) gives ``z_0``,
    and a second march the states: ``2 n`` products ``A_k z`` instead of the transitions'
    computation and condensation.

    Attributes
    ----------
    bounds : tuple of (int, int)
        The chunks ``(a, b)`` of elements.
    A : tuple of ndarray
        Per chunk, its ``A_k`` (L, m, m), or the one ``A`` (m, m) when invariant.
    ImP, Bal, dsc : ndarray
        ``I - Phi`` and its balanced form and scaling (:func:`_balanced_condition`).
    a_norm2 : float
        ``sum_k ||A_k||_F**2``.
    """

    bounds: tuple
    A: tuple
    ImP: np.ndarray
    Bal: np.ndarray
    dsc: np.ndarray
    a_norm2: float

    def solve(self, b: list) -> tuple[np.ndarray, float]:
        """Periodic states for the forced parts ``b`` (per chunk, (L, m)).

        Returns
        -------
        Z : ndarray, shape (n, m)
            States at the element starts.
        residual : float
            Normwise relative residual of the cyclic system (as :func:`solve_cyclic`).
        """
        n, m = self.bounds[-1][1], self.ImP.shape[0]
        Z = np.empty((n, m))
        chunks = [(a, e, A, bb) for (a, e), A, bb in zip(self.bounds, self.A, b)]
        d = _march(chunks, np.zeros(m), Z)
        z0 = _solve_z0(self.ImP, self.Bal, self.dsc, d)
        z_end = _march(chunks, z0, Z)
        rnorm = float(np.linalg.norm(z_end - Z[0]))
        bnorm2 = sum(float(np.sum(bb * bb)) for bb in b)
        denom = math.sqrt(self.a_norm2 + n * m) * float(np.linalg.norm(Z)) + math.sqrt(bnorm2)
        return Z, (rnorm / denom if denom > 0 else 0.0)


def solve_cyclic(elems, per_element: float, *, method: str = "auto", memory_budget: float = 256e6,
                 max_condition: float = MAX_CONDITION, timings: dict | None = None,
                 t_start: float | None = None, factors: bool = False) -> CyclicSolution:
    """Periodic states of ``z_{k+1} = A_k z_k + b_k``, ``z_n = z_0``, and its Floquet analysis.

    The block-cyclic system of any one-step time discretisation (the
    exponential holds of :mod:`kedfem.solvers.periodic`, the collocation schemes of
    :mod:`kedfem.solvers.collocation`): condensation (paper Eq. 13-16) or, when a
    multiplier lies outside the unit circle or ``I - Phi`` is non-normal and
    ill-conditioned, a sparse LU of the whole cyclic system.

    Parameters
    ----------
    elems : transition source
        Object with attributes ``n`` (elements), ``m`` (state size),
        ``invariant`` (one ``A`` for all elements), ``chunk`` (set here),
        ``workers``, and methods ``bounds()`` (chunks ``(a, b)``) and
        ``compute(a, b) -> (A (b-a, m, m) or (m, m), b (b-a, m))``.
    per_element : float
        Work memory of ``compute`` per element [bytes] (sets the chunk size).
    method, memory_budget, max_condition
        As in :func:`solve`.
    timings : dict, optional
        Filled with the wall time of the phases [s].
    factors : bool
        Keep the condensed transitions for other loads (:class:`CyclicFactors`), where the
        system was condensed with its transitions kept (not by the sparse LU, not streamed).

    Returns
    -------
    CyclicSolution
        States ``Z`` (n, m) at the element starts and the Floquet analysis.

    Notes
    -----
    The steps: plan the chunks (:func:`_plan_chunks`); condense the cyclic
    system into ``Phi`` and ``d`` (:func:`_condense`); the Floquet multipliers,
    the condition of ``I - Phi`` and the choice of method
    (:func:`_floquet_multipliers`, :func:`_balanced_condition`,
    :func:`_check_resonance`, :func:`_choose_method`); then either solve for
    ``z_0`` (:func:`_solve_z0`) and march the states (:func:`_march`), or solve
    the cyclic system by sparse LU (:func:`_solve_by_cyclic_lu`); last the
    normwise residual (:func:`_relative_residual`).
    """
    timings = {} if timings is None else timings
    t_start = time.perf_counter() if t_start is None else t_start
    n, m = elems.n, elems.m
    keep, seg = _plan_chunks(elems, per_element, memory_budget)

    t0 = time.perf_counter()
    pass1 = _condense(elems, keep, seg)
    timings["exponentials"] = pass1.t_exp
    timings["condensation"] = time.perf_counter() - t0 - pass1.t_exp

    t0 = time.perf_counter()
    _check_bounded(pass1, n)
    mult = _floquet_multipliers(pass1.Phi)
    rho = float(np.abs(mult).max())
    ImP = np.eye(m) - pass1.Phi
    Bal, dsc, condition = _balanced_condition(ImP)
    ill_conditioned = _check_resonance(mult, condition, max_condition)
    method = _choose_method(method, rho, ill_conditioned, mult[int(np.argmax(np.abs(mult)))])
    timings["floquet"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    Z = np.empty((n, m))
    if method == "condensation":
        z0 = _solve_z0(ImP, Bal, dsc, pass1.d)
        z_end = _march(_second_pass(elems, pass1, keep), z0, Z)
        rnorm = float(np.linalg.norm(z_end - Z[0]))  # only the closing row is not exact
    else:
        rnorm = _solve_by_cyclic_lu(elems, pass1, keep, seg, Z)
    residual = _relative_residual(rnorm, pass1, Z)
    timings["solve"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    log.debug("periodic: n=%d m=%d method=%s rho=%.6g cond=%.3g residual=%.2e (%.3f s)",
             n, m, method, rho, condition, residual, timings["total"])
    kept = None
    if factors and keep and method == "condensation":
        kept = CyclicFactors(tuple(elems.bounds()), tuple(pass1.kept_A), ImP, Bal, dsc, pass1.a_norm2)
    return CyclicSolution(Z, mult, bool(rho < 1.0), float(residual), pass1.Phi, method,
                          float(condition), 1 if keep else 2, kept)


# --------------------------------------------------------------------------
# Steps of solve_cyclic
# --------------------------------------------------------------------------

def _plan_chunks(elems, per_element: float, memory_budget: float) -> tuple[bool, int]:
    """Chunk size (set on ``elems.chunk``), whether to keep the ``A_k``, and the LU segment.

    Parameters
    ----------
    elems : transition source
        As in :func:`solve_cyclic`, with ``n`` elements of state size ``m``.
    per_element : float
        Work memory of ``elems.compute`` per element, bytes.
    memory_budget : float
        Bytes. A chunk's work fits the budget; the ``A_k`` (``n m**2 8`` bytes)
        are kept when they fit half of it.

    Returns
    -------
    keep : bool
        Keep every chunk's ``A_k`` for the second pass (always when invariant);
        otherwise they are recomputed.
    seg : int
        Elements per segment of the cyclic system solved by sparse LU: 1 (the
        whole system) unless its LU would not fit the budget. Time-varying
        segments lie inside one chunk or span whole chunks.
    """
    n, m, invariant = elems.n, elems.m, elems.invariant
    chunk = max(1, min(n, int(memory_budget // per_element)))
    keep = invariant or n * m * m * 8 <= memory_budget / 2
    s_max = max(1, int(memory_budget // (48 * m * m)))
    seg = -(-n // s_max)
    if not invariant:
        if seg <= chunk:
            chunk = max(seg, (chunk // seg) * seg)
        else:
            seg = -(-seg // chunk) * chunk
    elems.chunk = chunk
    log.debug("solve_cyclic: n=%d m=%d chunk=%d keep=%s segment=%d", n, m, chunk, keep, seg)
    return keep, seg


def _relative_residual(rnorm: float, pass1: _Condensed, Z: np.ndarray) -> float:
    """Normwise relative residual ``||r|| / (||Acyc||_F ||z|| + ||c||)`` of the cyclic system.

    Parameters
    ----------
    rnorm : float
        ``||r||_2``.
    pass1 : _Condensed
        For ``sum ||A_k||_F**2`` and the ``b_k``.
    Z : ndarray, shape (n, m)
        The states.

    Returns
    -------
    float
    """
    n, m = Z.shape
    bnorm2 = sum(float(np.sum(bb * bb)) for bb in pass1.kept_b)
    denom = math.sqrt(pass1.a_norm2 + n * m) * float(np.linalg.norm(Z)) + math.sqrt(bnorm2)
    return rnorm / denom if denom > 0 else 0.0
