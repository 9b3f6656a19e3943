"""One discretised periodic problem of a scene: its instants, its assembled system, its Newton map.

A :class:`PeriodicProblem` is a scene on ``n`` time elements of one scheme (over one cycle,
or over ``periods`` cycles for a subharmonic response): the rigid-body motion at the scheme's
instants, the chosen effects assembled there, and

* :meth:`PeriodicProblem.linear` -- the periodic solve when nothing depends on the elastic state;
* :meth:`PeriodicProblem.step` -- the map ``G(x)``: one linear periodic solve with the
  state-dependent effects in tangent form about a trial response ``x`` (its correction
  ``G(x) - x`` is Newton's step of the discrete problem);
* :meth:`PeriodicProblem.merit` -- the scaled norm of the discrete equations' residual at ``x``
  (stiffly accurate collocation: no solve);
* :meth:`PeriodicProblem.solve` -- Newton's method with a line search (or the paper's
  iteration, or Anderson's) from a start, returning a :class:`Solved`.

The refinement of :func:`kedfem.solve` builds one problem per level; the continuation of
:mod:`kedfem.analysis.continuation` builds one per parameter value. A trial response is given
at the problem's instants, ``x = (U, V)``, each ``(n_i, N)``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import time
import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import InstabilityWarning
from ..fe.assembler import Assembler
from ..fe.damping import ModalDamping
from ..fe.modal_damping import DampingField, PiecewiseDampingField, field_over_cycle
from ..fe.slots import node_crossings
from ..solvers import collocation, defect, schemes
from ..solvers.nonlinear import fixed_point, fixed_point_or_anderson, newton

__all__ = ["PeriodicProblem", "Solved", "STREAM_BYTES"]

log = logging.getLogger(__name__)

#: above this many bytes for the (n, N, N) matrices of a linear scene, assemble chunk by chunk
STREAM_BYTES = 400e6
#: a full Newton solve whose change (relative) is at most this keeps its factorisations, and the
#: steps after it are chord steps on its tangent (:meth:`PeriodicProblem.step`)
CHORD_CHANGE = 0.05
#: a chord step must shrink the change by at least this factor; else the next step is a full one
CHORD_CONTRACTION = 0.25
#: a chord step only from stage states whose kinematic rows hold to this (relative; round-off of
#: the solves' states and their combinations is 1e-15 .. 1e-13)
KINEMATIC_DEFECT = 1e-10
#: chord steps only on an orbit whose spectral radius is at most this: the multipliers of a chord
#: step are those of the tangent it froze (an iterate up to CHORD_CHANGE away); near the
#: stability limit, where their digits decide a verdict, every step is a full solve
CHORD_RHO = 0.9


@dataclass(frozen=True)
class Solved:
    """A periodic solve of a :class:`PeriodicProblem`.

    Attributes
    ----------
    discrete : kedfem.solvers.schemes.Discrete
        The linear periodic solve at the last iterate (when converged: at the solution, with the
        Floquet multipliers of the orbit's linearisation).
    converged : bool
        The iteration met its tolerance (always True for a linear problem).
    iterations : int
        Linear periodic solves.
    history : tuple of float
        Relative change of the displacements at each iterate (the paper's Eq. 21).
    method : str
        The non-linear method that produced it (``""`` for a linear problem).
    caught : list
        Warnings raised while solving (re-issued by the caller for the result it keeps).
    rate : kedfem.solvers.nonlinear.NewtonRate or None
        Newton's rate observed at the end (for a finer level's :meth:`PeriodicProblem.solve`).
    predicted : float or None
        Newton stopped on a predicted next change, this one (relative), instead of a last change
        below ``eps`` (see :func:`kedfem.solvers.nonlinear.newton`).
    orbit : callable or None
        For a solve that ended on a chord step: ``orbit()`` is :attr:`discrete` with the Floquet
        multipliers of the tangent about its last iterate (to first order), where
        :attr:`discrete` has those of the frozen tangent (an iterate up to
        :data:`CHORD_CHANGE` away; at a spectral radius of at most :data:`CHORD_RHO`). None
        otherwise.
    """

    discrete: object
    converged: bool
    iterations: int
    history: tuple
    method: str
    caught: list
    rate: object = None
    predicted: float | None = None
    orbit: object = None


class _Chunks:
    """Lazy per-chunk assembly for the streaming periodic solver (M, C, K, Q callables)."""

    def __init__(self, asm: Assembler):
        self.asm = asm
        self._idx = None
        self._terms = None

    def _get(self, idx):
        idx = np.asarray(idx)
        if self._idx is None or self._idx.shape != idx.shape or not np.array_equal(self._idx, idx):
            self._terms = self.asm.system(idx)
            self._idx = idx.copy()
        return self._terms

    def M(self, idx):
        return self._get(idx).M

    def C(self, idx):
        return self._get(idx).C

    def K(self, idx):
        return self._get(idx).K

    def Q(self, idx):
        return self._get(idx).Q


def damping_field(scene, model, cycle, instants: int, kinks=None) -> DampingField | PiecewiseDampingField | None:
    """The scene's modal damping over the cycle for problems read at ``instants`` instants in all
    (:func:`kedfem.fe.modal_damping.field_over_cycle`: between the kinks where a block crosses
    a node of its link); None for other damping, or where an eigenproblem per instant is cheaper.

    ``kinks``: those instants [s], when the caller has them (default
    :func:`kedfem.fe.slots.node_crossings`).
    """
    if not isinstance(scene.damping, ModalDamping):
        return None

    def exact(t):
        asm = Assembler(model, cycle.at(t), (), damping=scene.damping)
        return asm.damping_matrix(*asm.structural())

    if kinks is None:
        kinks = node_crossings(model, cycle, scene.period)
    return field_over_cycle(exact, scene.period, kinks, instants, scene.rtol)


def constant_or_sampled(X: np.ndarray) -> np.ndarray:
    """``X[0]`` when every instant holds exactly the same matrix, else ``X``.

    A time-invariant scene (every body translating, or none moving) then takes
    the solvers' constant-matrix path: one exponential (or one stage
    factorisation) instead of one per element.
    """
    if X.ndim == 3 and X.shape[0] > 1 and np.array_equal(X, np.broadcast_to(X[0], X.shape)):
        return X[0]
    return X


def _static_inverse(K, M, n: int, N: int) -> np.ndarray:
    """``K(t)^-1`` at every instant (n, N, N) (or one (N, N)): a force residual as the static
    displacement it would cause. A stiff direction (a link's axial stiffness) then weighs no more
    than a soft one: in units of force the von Karman strains of a small bending error make the
    axial rows dominate, and a line search on them took steps of a few per cent. Where ``K`` is
    singular, ``K + (trace K / trace M) M``."""
    K = np.asarray(K, dtype=float)
    Mm = np.asarray(M, dtype=float)
    try:
        return np.linalg.inv(K)
    except np.linalg.LinAlgError:
        s = np.trace(K, axis1=-2, axis2=-1) / np.trace(np.broadcast_to(Mm, K.shape), axis1=-2, axis2=-1)
        return np.linalg.inv(K + s[..., None, None] * Mm)


def mass_scale(M, n: int, N: int) -> np.ndarray:
    """``1 / diag(M)`` at every instant, shape (n, N): a force residual in units of acceleration."""
    d = np.diagonal(np.asarray(M), axis1=-2, axis2=-1)
    d = np.broadcast_to(d, (n, N))
    return 1.0 / np.where(d > 0, d, np.max(d))


#: an element's end stage on a kink of the data reads it this fraction of the element earlier
LEFT_LIMIT = 1e-7


def snapped_edges(n: int, period: float, breaks) -> np.ndarray | None:
    """Element edges [s] (n + 1,): the uniform ones, each moved onto the nearest instant of
    ``breaks`` (where the data has a kink) that is nearer to it than to its neighbours.

    The number of elements stays ``n`` (the levels of a solve keep their ratio of two); no
    edge moves by more than half an element. None when there is nothing to snap, or fewer
    than two elements per break (the coarse levels of a solve stay uniform); the uniform edges
    when the only break is at the cycle's start (the last element's end stage then reads the
    left limit, :class:`PeriodicProblem`).
    """
    b = np.mod(np.asarray(breaks, dtype=float), period)
    inner = (b > 1e-9 * period) & (b < (1.0 - 1e-9) * period)
    at_start = bool(np.any(~inner))  # a kink at 0 is an element end already (its stage reads it)
    b = b[inner]
    h = period / n
    edges = np.arange(n + 1) * h
    if b.size == 0:
        return edges if at_start else None
    if n < 2 * b.size:
        return None
    k = np.clip(np.rint(b / h).astype(int), 1, n - 1)
    taken: set[int] = set()
    for i in np.argsort(np.abs(b - k * h)):  # the nearest breaks first
        for kk in (k[i], k[i] - 1 if b[i] < k[i] * h else k[i] + 1):
            if 1 <= kk <= n - 1 and kk not in taken:
                taken.add(int(kk))
                edges[kk] = b[i]
                break
    edges = np.sort(edges)
    if not np.all(np.diff(edges) > 1e-9 * h):
        return None
    return edges


class _Frozen(NamedTuple):
    """A full solve's factorisations kept for chord steps (:meth:`PeriodicProblem.step`)."""

    resolver: object  # kedfem.solvers.collocation.Resolver
    change: float     # the change of the last step on it (the full solve's, then each chord step's)
    dC: object        # the state terms the tangent was frozen with, (n_i, N, N) or None
    dK: object
    U: np.ndarray     # the iterate it was frozen at (n_i, N)


def _minus(a, b):
    """``a - b`` of two optional state terms (None: zero)."""
    if a is None and b is None:
        return None
    return (0.0 if a is None else a) - (0.0 if b is None else b)


def _relative_change(U, Un) -> float:
    """``||Un - U|| / ||Un||`` (the non-linear iterations' change, Eq. 21)."""
    nn = float(np.linalg.norm(Un))
    dd = float(np.linalg.norm(Un - U))
    return 0.0 if dd == 0.0 else (dd / nn if nn > 0 else np.inf)


class PeriodicProblem:
    """A scene discretised on ``n`` time elements (see the module docstring).

    Parameters
    ----------
    scene : Scene
    model : FEModel
        The scene's FE model.
    cycle : kedfem.motion.kinematics.Cycle
        The rigid-body motion of the scene's mechanism (at the scene's speed).
    scheme : kedfem.solvers.schemes.Scheme
    n : int
        Time elements over the problem's period.
    damping_field : DampingField, optional
        The scene's modal damping over the cycle (instead of an eigenproblem per instant).
    stiff : ndarray of bool, optional
        DOFs of the exact stiff split of the exponential holds.
    periods : int
        Cycles of the drive the problem spans (2: a period-doubled response).
    edges : ndarray, shape (n + 1,), optional
        Non-uniform element edges [s] from 0 to the period (a scheme with ``graded``; one
        period): elements that end where the data has a kink (:func:`snapped_edges`).
    kinks : ndarray, optional
        Those instants [s]: an element's stage at its end (Radau IIA) takes the data just
        before it (the left limit, :data:`LEFT_LIMIT` of the element earlier), not whichever
        side the round-off of the block's abscissa picks (a one-sided stage left the
        oscillating cylinder at first order on snapped elements).
    chord : bool
        Chord steps in :meth:`solve` and :meth:`polish` (:meth:`step`): the full solves keep
        their factorisations (10-20 % more each) for the cheap steps after them. It pays where
        an iteration takes several steps near its solution (the refinement's levels, which
        :func:`kedfem.solve` builds with it); the continuation in speed, whose Newton solves
        take two or three steps on 48 elements each, made 292 factorised solves and 85 chord
        steps where it made 345 plain solves, 20.6 s against 14.2 s (the four-bar at 340 rpm;
        its bordered corrector also differentiates :meth:`step` in speed, which a chord step
        would spoil), so it is off by default.

    Attributes
    ----------
    period : float
        The problem's period, ``periods`` drive cycles [s].
    instants : ndarray, shape (n_i,)
        The scheme's instants [s] in ``[0, period)``.
    motion : Motion
        The rigid-body motion at the instants.
    assembler : Assembler
    state : bool
        A chosen effect depends on the elastic state (the problem is non-linear).
    kinematics, assembly : float
        Seconds spent on the motion and the assembly.
    """

    def __init__(self, scene, model, cycle, scheme, n: int, *, damping_field=None, stiff=None,
                 periods: int = 1, edges=None, kinks=None, chord: bool = False):
        ta = time.perf_counter()
        self.scene, self.model, self.scheme, self.n = scene, model, scheme, int(n)
        self.periods = int(periods)
        self.period = scene.period * self.periods
        self.edges = edges if (edges is not None and scheme.graded and self.periods == 1) else None
        self.instants = scheme.instants(self.n, self.period, self.edges)
        t = self.instants if self.periods == 1 else np.mod(self.instants, scene.period)
        if self.edges is not None and kinks is not None and len(kinks):
            h = np.diff(self.edges)
            s = self.instants.size // self.n
            at_kink = np.isin(self.edges[1:], kinks)  # snapped edges are the kinks' own values
            # a kink or step at the cycle's start is the last element's end (a press drawn at its
            # dead centre, where its stroke's load steps)
            at_kink[-1] |= bool(np.any(np.minimum(np.mod(kinks, self.period), self.period - np.mod(kinks, self.period))
                                       <= 1e-9 * self.period))
            t = t.copy().reshape(self.n, s)
            t[at_kink, -1] -= LEFT_LIMIT * h[at_kink]
            t = t.ravel()
        self.motion = cycle.at(t)
        tb = time.perf_counter()
        self.assembler = Assembler(model, self.motion, scene.effects, damping=scene.damping,
                                   damping_field=damping_field)
        self.state = bool(self.assembler.state_dependent)
        self.options = {"delta": scene.delta} if scene.delta is not None else {}
        if stiff is not None:
            self.options["stiff"] = stiff
        if self.edges is not None:
            self.options["edges"] = self.edges
        self._terms = None
        self._D = None
        self._chord: _Frozen | None = None  # the last full solve's, for chord steps
        # chord steps only inside solve() and polish(), whose iterates are this problem's own
        # solutions and their combinations (the kinematic rows hold, the residual is the whole
        # one); step() called directly (the continuation's bordered corrector differentiates it
        # in speed) is always Newton's full step
        self._iterating = False
        self.chord = bool(chord)
        # the last chord step's solution and its tangent's change since the frozen one
        self._last_chord: tuple | None = None
        self._kept: _Frozen | None = None  # the factorised tangent at the last converged iteration's end
        self._converged = False
        self.chord_steps = 0
        self.kinematics = tb - ta
        self.assembly = time.perf_counter() - tb

    @property
    def N(self) -> int:
        """Elastic DOFs."""
        return self.model.n_dof

    @property
    def terms(self):
        """The assembled state-independent system at the instants (``M, C, K, Q``)."""
        if self._terms is None:
            t0 = time.perf_counter()
            self._terms = self.assembler.system()
            self.assembly += time.perf_counter() - t0
        return self._terms

    # ------------------------------------------------------------------ linear
    def linear(self):
        """The periodic solve of the state-independent system (streamed when it is large).

        Returns
        -------
        kedfem.solvers.schemes.Discrete
        """
        N, ni = self.N, self.instants.size
        if not self.state and 3 * ni * N * N * 8 > STREAM_BYTES:
            ch = _Chunks(self.assembler)
            return self.scheme.solve(ch.M, ch.C, ch.K, ch.Q, self.period, self.n, **self.options)
        terms = self.terms
        M, C, K = (constant_or_sampled(X) for X in (terms.M, terms.C, terms.K))
        return self.scheme.solve(M, C, K, terms.Q, self.period, self.n, **self.options)

    # ------------------------------------------------------------------ non-linear
    def step(self, U, V, it: int = 0):
        """``G(x)``: the linear periodic solve with the state terms in tangent form about ``U, V``.

        Parameters
        ----------
        U, V : ndarray, shape (n_i, N)
            Trial response at the instants [m, rad; m/s, rad/s].
        it : int
            Iteration number (for messages).

        Returns
        -------
        discrete : Discrete
        U, V : ndarray, shape (n_i, N)
            The new response at the instants.
        """
        terms = self.terms
        dC, dK, dQ = self.assembler.state_terms(U, V)
        if self._chord is not None and self._iterating:
            out = self._chord_step(U, V, dC, dK, dQ)
            if out is not None:
                return out
        keep = self.chord and self.has_residual and self._iterating
        options = dict(self.options, factors=True) if keep else self.options
        d = self.scheme.solve(terms.M, terms.C, terms.K, terms.Q, self.period, self.n, dC=dC, dK=dK, dQ=dQ,
                              **options)
        if isinstance(self.scheme, schemes.Collocation):
            self.options["check_mass"] = False  # the state terms have no dM and the terms are assembled once:
            # M is checked on this problem's first solve only
        Un, Vn = d.instant_states()
        change = _relative_change(U, Un)
        self._chord = (_Frozen(d.resolver, change, dC, dK, U) if d.resolver is not None and change <= CHORD_CHANGE
                       and d.spectral_radius <= CHORD_RHO else None)
        if d.resolver is not None:
            d = dataclasses.replace(d, resolver=None)
        return d, Un, Vn

    def _unfreeze(self) -> None:
        """The next :meth:`step` a full one (Newton's line search found no decrease along a chord
        step's direction)."""
        self._chord = None

    def _chord_step(self, U, V, dC, dK, dQ):
        """``G(x)`` by a chord step: the correction ``-J_0^-1 F(x)`` with the tangent ``J_0`` of
        the last full solve (its factorisations kept), ``F(x)`` the residual of the discrete
        equations with the state terms about ``x``. Its fixed point is Newton's; it converges
        linearly at a rate of about the distance from the factorised tangent's iterate (a
        change of at most :data:`CHORD_CHANGE`), for a triangular solve per element instead
        of a factorisation. None (a full step is due) when the iterate is farther than twice
        :data:`CHORD_CHANGE` from the one the tangent was frozen at (an iteration started again
        elsewhere: Anderson's after a failed fixed-point iteration), when the last chord step
        did not shrink the change by :data:`CHORD_CONTRACTION`, or when its result is not finite.
        """
        frozen = self._chord
        resolver, U0 = frozen.resolver, frozen.U
        if _relative_change(U0, U) > 2.0 * CHORD_CHANGE or collocation.kinematic_defect(
                U, V, self.period, self.scheme.name, edges=self.edges) > KINEMATIC_DEFECT:
            # far from the frozen tangent, or an iterate the residual does not measure whole (a
            # relaxed step from an interpolated start keeps half its kinematic defect, which a
            # chord correction, itself free of one, never removes: it stopped 3e-3 off)
            self._chord = None
            return None
        terms = self.terms
        Ct, Kt, Qt = schemes.with_state_terms(terms.C, terms.K, terms.Q, dC, dK, dQ)
        r = collocation.residual(terms.M, Ct, Kt, Qt, U, V, self.period, self.scheme.name, edges=self.edges)
        delta = resolver.solve(-r)
        n, s = self.n, self.scheme.stages
        SU = U.reshape(n, s, -1) + delta.stage_U
        SV = V.reshape(n, s, -1) + delta.stage_V
        if not (np.all(np.isfinite(SU)) and np.all(np.isfinite(SV))):
            self._chord = None
            return None
        # element starts: the last stage of the element before (a stiffly accurate scheme)
        sol = dataclasses.replace(delta, U=np.roll(SU[:, -1], 1, axis=0), V=np.roll(SV[:, -1], 1, axis=0),
                                  stage_U=SU, stage_V=SV, resolver=None)
        d = dataclasses.replace(self.scheme.discrete(sol), chord=True)
        Un, Vn = d.instant_states()
        change = _relative_change(U, Un)
        self.chord_steps += 1
        self._last_chord = (sol, resolver, _minus(dC, frozen.dC), _minus(dK, frozen.dK))
        self._chord = (frozen._replace(change=change) if change <= CHORD_CONTRACTION * frozen.change
                       else None)
        return d, Un, Vn

    @contextlib.contextmanager
    def _chords(self, fresh: bool):
        """Chord steps allowed while an iteration of :meth:`solve` or :meth:`polish` runs (from
        a full step on: a start may be no solution of this problem, interpolated from a coarser
        level or a continuation's predictor)."""
        if fresh:
            self._chord = None
        self._iterating = True
        self._converged = False  # set by _orbit_multipliers when the iteration returns (inside this context)
        try:
            yield
        finally:
            # the factorisations go when the iteration ends (a problem outlives it in the
            # refinement's bookkeeping and a continuation's cache): the next starts with a full step;
            # the last tangent near the solution stays for the defect estimate (:meth:`corrected`)
            # until :meth:`release`
            self._kept = self._chord if self._converged else None
            self._iterating, self._chord = False, None

    def release(self) -> None:
        """Drop the factorisations kept for :meth:`corrected`."""
        self._kept = None

    def _orbit_multipliers(self, solved: Solved) -> Solved:
        """A solve that ended on a chord step, with :attr:`Solved.orbit`: the multipliers of the
        tangent about its last iterate instead of the frozen one's, on demand
        (:meth:`kedfem.solvers.collocation.Resolver.multipliers`, to first order in the
        tangent's change: the square of a change of at most :data:`CHORD_CHANGE`; 10-25 ms on
        192 elements, so only the result's level asks)."""
        self._converged = bool(solved.converged)
        d = solved.discrete
        last, self._last_chord = self._last_chord, None
        if not getattr(d, "chord", False) or last is None or last[0] is not d.raw:
            return solved
        scheme = self.scheme

        def orbit():
            _sol, resolver, dC, dK = last
            mu = resolver.multipliers(dC, dK)
            rho = float(np.abs(mu).max()) if mu.size else 0.0
            raw = dataclasses.replace(d.raw, floquet_multipliers=mu, stable=bool(rho < 1.0))
            return dataclasses.replace(scheme.discrete(raw), chord=True)

        return dataclasses.replace(solved, orbit=orbit)

    @property
    def has_residual(self) -> bool:
        """The discrete equations' residual is available (a stiffly accurate collocation scheme)."""
        return isinstance(self.scheme, schemes.Collocation) and collocation.stiffly_accurate(self.scheme.name)

    def merit(self, U, V) -> float:
        """Norm of the discrete equations' residual at a trial response, each DOF's row in units of
        acceleration (divided by its mass); zero at the solution.

        Raises
        ------
        InputError
            For a scheme without a residual (:attr:`has_residual` False).
        """
        terms = self.terms
        if self._D is None:
            self._D = _static_inverse(terms.K, terms.M, self.instants.size, self.N)
        Ct, Kt, Qt = schemes.with_state_terms(terms.C, terms.K, terms.Q, *self.assembler.state_terms(U, V))
        r = collocation.residual(terms.M, Ct, Kt, Qt, U, V, self.period, self.scheme.name, edges=self.edges)
        return float(np.linalg.norm(np.einsum("tij,tj->ti", self._D, r) if self._D.ndim == 3 else r @ self._D.T))

    def corrected(self, discrete):
        """The defect-corrected solution of one of this problem's solves (the one-level error
        estimate of :mod:`kedfem.solvers.defect`): the same system, with the state terms in
        tangent form about ``discrete`` for a non-linear scene, and the same elements.

        Parameters
        ----------
        discrete : kedfem.solvers.schemes.Discrete
            A solve of this problem (a Radau IIA collocation).

        Returns
        -------
        kedfem.solvers.schemes.Discrete or None
            Its difference from ``discrete`` is the estimated error; None for schemes the estimate
            does not read (:func:`kedfem.solvers.defect.available`), a solve on other elements or of
            another period, or a result that is not finite.
        """
        if not defect.available(discrete):
            return None
        raw = discrete.raw
        same_edges = (raw.edges is None) == (self.edges is None) and (
            raw.edges is None or np.array_equal(raw.edges, self.edges))
        if raw.n != self.n or raw.scheme != self.scheme.name or not same_edges \
                or not np.isclose(raw.period, self.period, rtol=1e-12):
            return None  # solved on other elements, at another speed or period: not this system's
        terms = self.terms
        M, C, K, Q = terms.M, terms.C, terms.K, terms.Q
        if self.state:
            C, K, Q = schemes.with_state_terms(C, K, Q, *self.assembler.state_terms(*discrete.instant_states()))
        M, C, K = (constant_or_sampled(X) for X in (M, C, K))
        options = {k: v for k, v in self.options.items() if k != "factors"}
        kept = self._kept
        if kept is not None and _relative_change(kept.U, discrete.instant_states()[0]) > 2.0 * CHORD_CHANGE:
            kept = None  # frozen elsewhere (an iteration that failed before a continuation solved it)

        def resolve(load):
            if kept is not None:
                # the tangent factorised within 2 CHORD_CHANGE of the solution: its response to the
                # defect is off by about that fraction of the estimate, for a triangular solve per
                # element instead of a solve (the solution it returns holds no factorisations)
                return self.scheme.discrete(dataclasses.replace(kept.resolver.solve(load), resolver=None))
            with warnings.catch_warnings():
                # the same system under the defect: its multipliers are the level's, which its own
                # solve warned of (an unstable linkage's warning came three times per solve)
                warnings.simplefilter("ignore", InstabilityWarning)
                return self.scheme.solve(M, C, K, load, self.period, self.n, **options)

        out = defect.corrected(discrete, M, C, K, Q, resolve)
        return out if (np.all(np.isfinite(out.U)) and np.all(np.isfinite(out.V))) else None

    def solve(self, x0=None, *, eps: float, max_iter: int, method: str = "newton", rate=None) -> Solved:
        """The periodic response: linear, or iterated from ``x0`` (default the linear response).

        Parameters
        ----------
        x0 : (U, V), optional
            Start at the instants.
        eps : float
            Tolerance on the relative change of the displacements (Eq. 21).
        max_iter : int
            Most linear solves.
        method : {"newton", "fixed-point", "relaxation", "anderson"}
            ``"fixed-point"`` falls back to Anderson when it diverges
            (:func:`kedfem.solvers.nonlinear.fixed_point_or_anderson`).
        rate : kedfem.solvers.nonlinear.NewtonRate, optional
            Newton's rate on a coarser level of the same problem: Newton may stop on the next
            change it predicts (:func:`kedfem.solvers.nonlinear.newton`).

        Returns
        -------
        Solved
        """
        with warnings.catch_warnings(record=True) as caught, self._chords(fresh=True):
            warnings.simplefilter("always")
            if not self.state:
                return Solved(self.linear(), True, 1, (), "", list(caught))
            merit = self.merit if self.has_residual else None
            if method == "newton":
                out = newton(self.step, self.instants.size, self.N, self.period, eps=eps, max_iter=max_iter,
                             x0=x0, merit=merit, rate=rate, unfreeze=self._unfreeze)
                return self._orbit_multipliers(Solved(
                    out.solution, bool(out.converged), len(out.history), tuple(float(h) for h in out.history),
                    method, list(caught), out.rate, out.predicted))
            d, hist, converged, used = fixed_point_or_anderson(
                self.step, self.instants.size, self.N, self.period, eps=eps, max_iter=max_iter, method=method,
                x0=x0, merit=merit)
            # inside the iteration's context, as Newton's: it notes the convergence before the
            # context keeps the last tangent (a review found the fixed-point paths never kept one)
            return self._orbit_multipliers(Solved(d, bool(converged), len(hist), tuple(float(h) for h in hist),
                                                  used, list(caught)))

    def polish(self, solved: Solved, *, eps: float, max_iter: int, rate=None) -> Solved:
        """Iterate a solve on to a tighter ``eps`` from where it stopped.

        Parameters
        ----------
        solved : Solved
            The solve to go on from (its method is kept).
        eps : float
            The tighter tolerance on the relative change (Eq. 21).
        max_iter : int
            Most linear solves.
        rate : kedfem.solvers.nonlinear.NewtonRate, optional
            As :meth:`solve`.

        Returns
        -------
        Solved
            Its iterations and history include those of ``solved``.
        """
        with warnings.catch_warnings(record=True) as caught, self._chords(fresh=False):
            warnings.simplefilter("always")
            x0 = solved.discrete.instant_states()
            if solved.method == "newton":
                out = newton(self.step, self.instants.size, self.N, self.period, eps=eps, max_iter=max_iter,
                             x0=x0, merit=self.merit if self.has_residual else None, rate=rate,
                             unfreeze=self._unfreeze)
                return self._orbit_multipliers(Solved(
                    out.solution, bool(out.converged), solved.iterations + len(out.history),
                    solved.history + tuple(float(h) for h in out.history), solved.method,
                    list(caught), out.rate or solved.rate, out.predicted))
            d, hist, conv, _m = fixed_point(self.step, self.instants.size, self.N, self.period, eps=eps,
                                            max_iter=max_iter, method=solved.method, x0=x0)
            return self._orbit_multipliers(Solved(d, bool(conv), solved.iterations + len(hist),
                                                  solved.history + tuple(float(h) for h in hist), solved.method,
                                                  list(caught)))
