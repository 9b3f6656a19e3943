"""Closed-form periodic steady state of ``M(t) u'' + C(t) u' + K(t) u = Q(t)``.

State-space method of Wang, Liu & Yuan (DETC2002, sections 1 and 3), corrected and
extended. The period ``T`` is split into ``n`` equal time elements with nodes
``t_k = k T / n``. With the state ``z = [u; u']`` each element is integrated
exactly for its held data::

    z' = F z + g(t),  F = [[0, I], [-M^-1 K, -M^-1 C]],  g = [0; M^-1 Q]
    z_{k+1} = A_k z_k + b_k,  A_k = exp(F dt),  b_k = int exp(F (dt - s)) g ds

Hold schemes (how the sampled data are held over element ``k``):

``"zoh"``
    ``F = F_k`` and ``g = g_k`` constant (the paper). First order when the data
    vary; exact for a time-invariant system under piecewise-constant forcing that
    switches at the nodes.
``"foh"``
    ``F = F_k`` constant, ``g`` linear from ``g_k`` to ``g_{k+1}``. Second order
    for a time-invariant ``F``; first order when ``F`` varies.
``"magnus2"``
    ``F`` from the element-mean data ``(M_k + M_{k+1}) / 2`` and likewise ``C``,
    ``K`` (the element midpoint to second order, indices modulo ``n``), with the
    first-order-hold forcing: second order for time-varying ``F`` too. Averaging
    the data rather than ``M^-1 K`` keeps the frequencies of each element real.

Periodicity ``z_n = z_0`` closes the block-cyclic system (paper Eq. 12). It is
solved by condensation (Eq. 13-16 with the corrected back substitution ``z_{k+1}
= A_k z_k + b_k``): ``Phi = A_{n-1} ... A_0`` (the monodromy matrix, whose
eigenvalues are the Floquet multipliers), ``d = sum_k A_{n-1}..A_{k+1} b_k``,
``(I - Phi) z_0 = d``, then forward propagation. When a multiplier lies outside
the unit circle forward propagation amplifies rounding errors, so the whole
cyclic system is instead solved by a sparse LU with partial pivoting
(``method="cyclic-lu"``) and an :class:`~kedfem.errors.InstabilityWarning` is
issued. If ``I - Phi`` is numerically singular (a multiplier at 1: undamped
resonance, a free rigid-body mode) :class:`~kedfem.errors.ResonanceError` is
raised.

Streaming: ``M``, ``C``, ``K`` and ``Q`` may be callables of the node indices, and
when keeping all ``n`` exponentials would exceed ``memory_budget`` the elements
are processed in chunks and the exponentials recomputed in a second pass, so the
peak memory does not grow with ``n`` beyond the ``O(n N)`` result.

The pieces, one module each: the coefficients (:mod:`~kedfem.solvers.inputs`), the mass check
and state matrices (:mod:`~kedfem.solvers.state_space`), the holds' element transitions
(:mod:`~kedfem.solvers.holds`), and the block-cyclic core that collocation shares
(:mod:`~kedfem.solvers.cyclic`: condensation, Floquet analysis, cyclic LU, marching).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ..errors import InputError
from . import cyclic as _cyclic
from . import monodromy as _monodromy
from . import parallel as _parallel
from . import state_space as _state_space
from .cyclic import CyclicSolution, solve_cyclic
from .holds import _element_bytes, _Elements, auto_delta
from .inputs import MIN_NODES, _Source, check_period
from .monodromy import MAX_CONDITION
from .parallel import default_workers
from .state_space import state_matrix
from .threads import one_blas_thread

__all__ = ["solve", "solve_cyclic", "CyclicSolution", "PeriodicSolution", "HOLDS", "METHODS", "auto_delta", "MIN_NODES",
           "state_matrix"]

#: Valid hold schemes.
HOLDS = ("zoh", "foh", "magnus2")
#: Valid solution methods (``"auto"`` picks one of the other two).
METHODS = ("auto", "condensation", "cyclic-lu")

# Names that this module held before issue 27 split it, still importable from here.
CyclicFactors = _cyclic.CyclicFactors
RESONANCE_GAP, INSTABILITY_TOL = _monodromy.RESONANCE_GAP, _monodromy.INSTABILITY_TOL
MASS_PIVOT_TOL = _state_space.MASS_PIVOT_TOL
_check_mass, _state_parts = _state_space._check_mass, _state_space._state_parts
_run_parallel, _split = _parallel._run_parallel, _parallel._split


@dataclass(frozen=True)
class PeriodicSolution:
    """Periodic steady state at the time nodes.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Time nodes ``k T / n``, s.
    U, V : ndarray, shape (n, N)
        Displacement and velocity at the nodes (units of the DOFs, per s for V).
    floquet_multipliers : ndarray of complex, shape (2N,)
        Eigenvalues of ``monodromy``, sorted by decreasing modulus.
    stable : bool
        All multipliers strictly inside the unit circle.
    residual : float
        Normwise relative residual ``||r|| / (||Acyc|| ||z|| + ||c||)`` (Frobenius
        / 2-norms) of the block-cyclic system actually solved.
    monodromy : ndarray, shape (2N, 2N)
        ``Phi = A_{n-1} ... A_0`` of the discrete system.
    method : str
        ``"condensation"`` or ``"cyclic-lu"``.
    hold : str
        Hold scheme used.
    period : float
        Period, s.
    delta : float
        Accuracy requested from the matrix exponentials (the smallest used).
    approximant : str
        ``"taylor"`` or ``"pade"``: the approximant inside the scaling and squaring.
    degree : int
        Degree of that approximant in the (last) batch of exponentials.
    max_squarings : int
        Largest number of squarings of any exponential.
    n_exponentials : int
        Number of (augmented) matrix exponentials computed, recomputations included.
    condition : float
        Condition estimate ``(1 + ||Phi||_2) / sigma_min(I - Phi)`` in balanced
        coordinates (relative to the data ``I`` and ``Phi`` it is formed from).
    passes : int
        1 when all ``A_k`` were kept, 2 when they were recomputed (streaming).
    timings : Mapping[str, float]
        Wall-clock seconds per phase.
    """

    t: np.ndarray
    U: np.ndarray
    V: np.ndarray
    floquet_multipliers: np.ndarray
    stable: bool
    residual: float
    monodromy: np.ndarray
    method: str
    hold: str
    period: float
    delta: float
    approximant: str
    degree: int
    max_squarings: int
    n_exponentials: int
    condition: float
    passes: int
    timings: Mapping[str, float] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of time elements."""
        return self.t.shape[0]

    @property
    def dt(self) -> float:
        """Element length, s."""
        return self.period / self.n

    @property
    def Z(self) -> np.ndarray:
        """State ``[U, V]`` at the nodes, shape (n, 2N)."""
        return np.concatenate([self.U, self.V], axis=1)

    @property
    def spectral_radius(self) -> float:
        """Largest Floquet multiplier modulus."""
        return float(np.abs(self.floquet_multipliers).max()) if self.floquet_multipliers.size else 0.0


def _resolve_shapes(Ms, Cs, Ks, Qs, n):
    ns = {s.name: s.n for s in (Ms, Cs, Ks, Qs) if s.n is not None}
    if n is not None:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
            raise InputError(f"n must be an integer, got {n!r}")
        ns["n"] = int(n)
    if not ns:
        raise InputError("cannot infer the number of time elements: all of M, C, K, Q are "
                         "constant or callables; pass n=...")
    if len(set(ns.values())) > 1:
        raise InputError("inconsistent numbers of time nodes: "
                         + ", ".join(f"{k} has {v}" for k, v in ns.items()))
    n_ = next(iter(ns.values()))
    if n_ < MIN_NODES:
        raise InputError(f"need at least {MIN_NODES} time elements per period (a periodic "
                         f"signal needs more than two samples per period), got n = {n_}")
    Ns = {s.name: s.N for s in (Ms, Cs, Ks, Qs) if s.N is not None}
    if not Ns:
        probe = Qs if Qs.callable else Ms
        out = np.asarray(probe.value(np.array([0])))
        if out.ndim < 2:
            raise InputError(f"{probe.name}(idx) must return a 2-D or 3-D array, got {out.shape}")
        Ns[probe.name] = out.shape[-1]
    if len(set(Ns.values())) > 1:
        raise InputError("inconsistent numbers of DOFs: "
                         + ", ".join(f"{k} has {v}" for k, v in Ns.items()))
    N_ = next(iter(Ns.values()))
    if N_ < 1:
        raise InputError("need at least one DOF")
    return n_, N_


def solve(M, C, K, Q, period: float, hold: str = "zoh", *, n: int | None = None,
          delta: float | None = None, method: str = "auto", approximant: str = "taylor",
          memory_budget: float = 256e6, max_condition: float = MAX_CONDITION,
          workers: int | None = None, Kz=None, Qz=None, Cz=None) -> PeriodicSolution:
    """Periodic steady state of ``M u'' + C u' + K u = Q`` by the state-space method.

    Parameters
    ----------
    M, C, K : ndarray, shape (n, N, N) or (N, N), or callable
        Mass [kg], damping [N s/m] and stiffness [N/m] (or consistent units),
        sampled at ``t_k = k * period / n``, or constant. A callable
        ``f(idx) -> ndarray (len(idx), N, N)`` is evaluated on chunks of node
        indices ``idx`` (int array, values in ``0..n-1``) so that huge ``n`` can be
        streamed without materialising ``(n, N, N)`` arrays. ``M`` must be
        positive definite (its symmetric part is checked); massless DOFs raise
        :class:`~kedfem.errors.SingularMassError`.
    Q : ndarray, shape (n, N), or callable
        Load [N] at the nodes; a callable ``q(idx) -> ndarray (len(idx), N)``.
    period : float
        Period ``T`` > 0, s.
    hold : {"zoh", "foh", "magnus2"}
        Hold scheme, see the module docstring.
    n : int, optional
        Number of time elements; needed only if no argument is a sampled array.
    delta : float, optional
        Relative backward error asked from each matrix exponential. ``None``
        (default): :func:`auto_delta`, matched to the hold's discretization error,
        clipped to ``[1e-15, 1e-10]`` and divided by ``max(1, omega_max dt)``.
    method : {"auto", "condensation", "cyclic-lu"}
        ``"auto"``: condensation unless a Floquet multiplier lies outside the unit
        circle (then cyclic LU, with an ``InstabilityWarning``).
    approximant : {"taylor", "pade"}
        Approximant inside the scaling and squaring (see
        :func:`kedfem.solvers.expm.expm`). Default Taylor/Paterson-Stockmeyer: same
        backward-error bound and scaling rule as Pade, no batched linear solve,
        measured 1.3-2x faster per exponential (``docs/solver.md``).
    memory_budget : float
        Bytes. If keeping all ``A_k`` (``n (2N)**2 8`` bytes) exceeds half of it,
        exponentials are computed in chunks and recomputed in a second pass.
    max_condition : float
        Largest acceptable condition estimate ``(1 + ||Phi||) / sigma_min(I - Phi)``
        (balanced coordinates, 2-norms); above it
        :class:`~kedfem.errors.ResonanceError` is raised. The default ``1e12``
        keeps the rounding error of ``z_0`` below about ``1e-4`` relative; a
        lightly damped resonance (``zeta = 1e-6``) has a condition of about
        ``1 / (2 pi zeta)`` per period and is solved.
    workers : int, optional
        Threads for the element exponentials (default: usable CPUs, at most 8);
        while they run BLAS is limited to one thread per worker (threadpoolctl).
        Callables are always evaluated from the calling thread.

    Kz, Qz, Cz : ndarray, shape (n, N, N), (n, N) and (n, N, N), optional
        Stiffness, load and damping of a linearisation about each time node,
        held constant over the element that starts at the node whatever the
        hold (``K_k + Kz_k``, ``C_k + Cz_k`` and ``Q(t) + Qz_k`` on
        ``[t_k, t_k+1]``). The non-linear
        iteration passes its state-dependent terms here: the tangent stiffness
        and the load ``-f_nl + K_nl x`` linearised at node ``k`` then cancel
        exactly at the node, so that a fixed point solves the non-linear
        equations and the iteration converges as Newton's method would, while
        the error of the linearisation over the element stays ``O(dt^2)``.

    Returns
    -------
    PeriodicSolution

    Raises
    ------
    InputError
        Bad shapes, ``n < 3``, bad period or hold, non-finite values (named, with
        the first bad index), before any numerical work for array inputs.
    SingularMassError
        ``M`` singular or indefinite at some node (names node and DOFs).
    ResonanceError
        ``I - Phi`` numerically singular (condition above ``max_condition``).

    Notes
    -----
    All linear algebra runs on one BLAS thread per kedfem worker
    (:func:`kedfem.solvers.threads.one_blas_thread`): the matrices are small
    (2N up to a few hundred) and OpenBLAS's own threading of them was 2-60x
    slower than one thread whenever the other cores were busy (measured on a
    shared 2-core machine, ``benchmarks/peers.py``).

    The steps: check the options (:func:`_check_options`), build the
    transitions (:func:`_element_transitions`), solve the block-cyclic system
    and its Floquet analysis (:func:`solve_cyclic`).
    """
    with one_blas_thread():
        timings: dict[str, float] = {}
        t_start = time.perf_counter()
        period, delta = _check_options(period, hold, method, approximant, delta, memory_budget)
        elems = _element_transitions(M, C, K, Q, period, hold, n, delta, approximant, workers,
                                     Kz, Qz, Cz)
        cyc = solve_cyclic(elems, _element_bytes(elems), method=method,
                           memory_budget=memory_budget, max_condition=max_condition,
                           timings=timings, t_start=t_start)
        return _periodic_solution(elems, cyc, timings)


def _check_options(period, hold, method, approximant, delta,
                   memory_budget) -> tuple[float, float | None]:
    """Validate the scalar options of :func:`solve` before any work.

    Parameters
    ----------
    period : float
        Period, s.
    hold, method, approximant : str
        Names, checked against :data:`HOLDS`, :data:`METHODS` and the approximants.
    delta : float or None
        Requested exponential accuracy, in (0, 1), or ``None`` (automatic).
    memory_budget : float
        Bytes, > 0.

    Returns
    -------
    period : float
        Period as a float, s.
    delta : float or None
        ``delta`` as a float (or ``None``).

    Raises
    ------
    InputError
        The first invalid option, named.
    """
    if hold not in HOLDS:
        raise InputError(f"unknown hold {hold!r}; valid holds: {', '.join(HOLDS)}")
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; valid methods: {', '.join(METHODS)}")
    if approximant not in ("taylor", "pade"):
        raise InputError(f"unknown approximant {approximant!r}; valid: taylor, pade")
    period = check_period(period)
    if delta is not None:
        delta = float(delta)
        if not (math.isfinite(delta) and 0 < delta < 1):
            raise InputError(f"delta must lie in (0, 1), got {delta!r}")
    if not (isinstance(memory_budget, (int, float, np.integer, np.floating))
            and memory_budget > 0):
        raise InputError(f"memory_budget must be a positive number of bytes, got {memory_budget!r}")
    return period, delta


def _linearisation_source(name: str, value, matrix: bool, n: int, N: int) -> _Source:
    """``Kz``, ``Cz`` (``matrix``: shape (n, N, N)) or ``Qz`` (shape (n, N)), checked sampled."""
    src = _Source(name, value, matrix)
    if src.n != n or src.N != N:  # constant or callable: n is None
        want = f"be sampled with shape ({n}, {N}, {N})" if matrix else f"have shape ({n}, {N})"
        raise InputError(f"{name} must {want}")
    return src


def _element_transitions(M, C, K, Q, period: float, hold: str, n, delta, approximant: str,
                         workers, Kz=None, Qz=None, Cz=None) -> _Elements:
    """Build the transitions: the source of ``(A_k, b_k)`` of the ``n`` time elements.

    Wraps the inputs, infers and checks ``n`` and ``N``, and resolves ``workers``;
    no exponential is computed here (see :meth:`_Elements.compute`).

    Parameters
    ----------
    M, C, K, Q, n, Kz, Qz, Cz
        As in :func:`solve`: (n, N, N) / (N, N) / callable matrices in kg, N s/m,
        N/m; (n, N) loads in N.
    period : float
        Period, s (checked).
    hold, approximant : str
        Checked names.
    delta : float or None
        Checked exponential accuracy.
    workers : int or None
        Threads for the exponentials; ``None``: :func:`default_workers`.

    Returns
    -------
    _Elements
        State size ``m = 2 N``; ``invariant`` when one ``A`` serves all elements.

    Raises
    ------
    InputError
        Bad shapes or values, in the order: ``M, C, K, Q``, ``n``, ``Cz, Kz, Qz``, ``workers``.
    """
    Ms = _Source("M", M, True)
    Cs = _Source("C", C, True)
    Ks = _Source("K", K, True)
    Qs = _Source("Q", Q, False)
    n, N = _resolve_shapes(Ms, Cs, Ks, Qs, n)
    Czs = None if Cz is None else _linearisation_source("Cz", Cz, True, n, N)
    Kzs = None if Kz is None else _linearisation_source("Kz", Kz, True, n, N)
    Qzs = None if Qz is None else _linearisation_source("Qz", Qz, False, n, N)
    if workers is None:
        workers = default_workers()
    elif not (isinstance(workers, (int, np.integer)) and workers >= 1):
        raise InputError(f"workers must be a positive integer or None, got {workers!r}")
    return _Elements(Ms, Cs, Ks, Qs, n, N, period, hold, delta, 1, approximant, int(workers),
                     Kzs, Qzs, Czs)


def _periodic_solution(elems: _Elements, cyc: CyclicSolution, timings: dict) -> PeriodicSolution:
    """The :class:`PeriodicSolution` of the states ``cyc.Z`` (n, 2N) and the exponentials' record."""
    n, N, period = elems.n, elems.N, elems.period
    return PeriodicSolution(
        t=np.arange(n) * (period / n), U=cyc.Z[:, :N].copy(), V=cyc.Z[:, N:].copy(),
        floquet_multipliers=cyc.multipliers, stable=cyc.stable, residual=cyc.residual,
        monodromy=cyc.monodromy, method=cyc.method, hold=elems.hold, period=period,
        delta=float(elems.delta_used), approximant=elems.approximant, degree=int(elems.degree),
        max_squarings=int(elems.max_squarings), n_exponentials=int(elems.n_exponentials),
        condition=cyc.condition, passes=cyc.passes, timings=MappingProxyType(timings))
