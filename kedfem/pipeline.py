"""``kf.solve(scene)``: kinematics -> assembly of the chosen effects -> periodic solve (-> iteration)."""

from __future__ import annotations

import logging
import time
import warnings

import numpy as np

from . import nonlinear, periodic
from .assembly import FEModel
from .effects import Assembler
from .errors import ConvergenceWarning
from .kinematics import kinematics
from .results import PeriodicResult, Timings
from .scene import Scene

__all__ = ["solve", "assemble_scene"]

log = logging.getLogger(__name__)

#: above this many bytes for the (n, N, N) matrices of a linear scene, assemble chunk by chunk
STREAM_BYTES = 400e6


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


def _constant_or_sampled(X: np.ndarray) -> np.ndarray:
    """``X[0]`` when every time node holds exactly the same matrix, else ``X``.

    A time-invariant scene (every body translating, or none moving) then takes
    the periodic solver's constant-matrix path: one exponential instead of one
    per element (about 10x faster on the exciter).
    """
    if X.ndim == 3 and X.shape[0] > 1 and np.array_equal(X, np.broadcast_to(X[0], X.shape)):
        return X[0]
    return X


def assemble_scene(scene: Scene):
    """Kinematics, FE model and assembler of a scene (no solve).

    Returns
    -------
    motion : Motion
    model : FEModel
    assembler : Assembler
    """
    motion = kinematics(scene.mech, steps=scene.steps)
    model = FEModel(scene.mech, reduction=scene.reduction)
    asm = Assembler(model, motion, scene.effects, damping=scene.damping)
    return motion, model, asm


def solve(scene: Scene) -> PeriodicResult:
    """Periodic steady-state elastic response of a scene.

    Assembles exactly the scene's effects at every time node, solves the
    periodic state-space problem (:func:`kedfem.periodic.solve`), and iterates
    (:func:`kedfem.nonlinear.solve`, the paper's Eq. 21 criterion) only when a
    chosen effect depends on the elastic state.

    Parameters
    ----------
    scene : Scene

    Returns
    -------
    PeriodicResult

    Raises
    ------
    KinematicsError, MobilityError
        The linkage cannot run through its cycle.
    ResonanceError
        ``I - Phi`` singular (undamped resonance or a free rigid-body mode).
    SingularMassError
        Massless DOFs.
    """
    if not isinstance(scene, Scene):
        from .errors import InputError
        raise InputError(f"solve: expected a kf.Scene, got {type(scene).__name__}")
    # one BLAS thread: the batched small-matrix work (eigh of the modal
    # damping, products, the periodic solve) ran 10-40x slower on OpenBLAS's
    # threads whenever the other core was busy (benchmarks/peers.py)
    with periodic._blas_one_thread():
        return _solve(scene)


def _solve(scene: Scene) -> PeriodicResult:
    t0 = time.perf_counter()
    motion = kinematics(scene.mech, steps=scene.steps)
    t1 = time.perf_counter()
    model = FEModel(scene.mech, reduction=scene.reduction)
    asm = Assembler(model, motion, scene.effects, damping=scene.damping)
    n, N = motion.n, model.n_dof
    kw = {"delta": scene.delta} if scene.delta is not None else {}
    state = asm.state_dependent
    stream = (not state) and 3 * n * N * N * 8 > STREAM_BYTES
    if stream:
        ch = _Chunks(asm)
        t2 = time.perf_counter()
        sol = periodic.solve(ch.M, ch.C, ch.K, ch.Q, motion.period, hold=scene.hold, n=n, **kw)
        t3 = time.perf_counter()
        converged, iters, hist = True, 1, ()
    else:
        terms = asm.system()
        t2 = time.perf_counter()
        if state:
            def state_terms(U, V):
                dC, dK, dQ = asm.state_terms(U, V)
                return None, dC, dK, dQ

            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", ConvergenceWarning)
                nl = nonlinear.solve(terms.M, terms.C, terms.K, terms.Q, motion.period, state_terms,
                                     hold=scene.hold, eps=scene.eps, max_iter=scene.max_iter,
                                     method=scene.nonlinear_method, linearization="tangent", **kw)
            for w in caught:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            sol = nl.solution
            converged, iters, hist = bool(nl.converged), int(nl.iterations), tuple(float(h) for h in nl.history)
        else:
            M, C, K = (_constant_or_sampled(X) for X in (terms.M, terms.C, terms.K))
            sol = periodic.solve(M, C, K, terms.Q, motion.period, hold=scene.hold, **kw)
            converged, iters, hist = True, 1, ()
        t3 = time.perf_counter()
    timings = Timings(kinematics=t1 - t0, assembly=t2 - t1, solve=t3 - t2, total=t3 - t0)
    log.info("%s: n=%d N=%d iterations=%d converged=%s stable=%s %.3f s", scene.mech.name, n, N,
             iters, converged, sol.stable, timings.total)
    return PeriodicResult(scene, model, motion, motion.t, motion.crank_angle, sol.U, sol.V,
                          tuple(model.dof_labels), sol.floquet_multipliers, bool(sol.stable), converged,
                          iters, hist, float(sol.residual), timings, getattr(sol, "method", "condensation"))
