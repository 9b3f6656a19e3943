"""kedfem against its peers, at equal accuracy, and against the flop bound of this machine.

Run: ``python benchmarks/peers.py`` (full, about 6 min on 2 cores) or
``python benchmarks/peers.py --quick`` (smoke run, < 1 min). Prints the tables
as it goes, then a markdown summary that is also written to
``benchmarks/results/peers.md`` with every row in ``benchmarks/results/peers.csv``.
All times are wall-clock medians of repeated runs (one run when a run takes
more than 10 s) and every ratio is formed from times measured in the same run,
because the machine is shared and noisy. BLAS threading: on a shared machine
OpenBLAS's threads make small products and eigen-decompositions 10-100x slower
whenever the other core is busy, so every method is timed on one BLAS thread
and, when a probe finds threaded BLAS healthy at that moment, also with the
configured threads; the faster counts (labelled ``blas1`` / ``blas2``). The
flop-bound table and the default scene report kedfem as shipped (BLAS threads
as configured) and inside ``threadpool_limits(1)``.

What is compared
----------------
1. **Slider-crank KED, equal accuracy** (``mechanisms/slider_crank.py``,
   ``build(elements=8)``: 24 DOFs, crank at 150 rad/s; effects inertia,
   coupling, axial stiffening; 2 % and 0.5 % modal damping). kedfem
   (``kf.solve``, Radau IIA collocation, the fewest elements meeting the target,
   one solve; and the tolerance-driven solve ``rtol = target`` with its three
   levels and error estimate, as a user runs it) against direct time
   integration run cycle by cycle from rest until periodic (both by
   :func:`kedfem.lab.transient.integrate_sampled`, the shared reference integrators):

   * Newmark, average acceleration (``beta = 1/4``, ``gamma = 1/2``), step
     ``T / n``, with ``M, C, K, Q`` assembled by kedfem at the step times; the
     per-step matrices ``(M + h C / 2 + h^2 K / 4)^-1 [K C]`` are formed once
     (batched) and reused by every cycle, so a step is one small matrix-vector
     product (the fastest form of the method for this linear periodic system);
   * ``scipy.integrate.solve_ivp`` Radau IIA (implicit, order 5) with the exact
     Jacobian, on periodic cubic splines of ``M^-1 K``, ``M^-1 C``, ``M^-1 Q``
     sampled by kedfem's assembly.

   **Equal accuracy.** The error of a run is the max-norm over the cycle of the
   rod's mid-span deflection relative to its chord, at 72 crank positions
   (every 5 deg), divided by the peak deflection, against a converged
   reference: kedfem ``radau3`` at 1536 elements, whose agreement with
   ``gauss3`` on as many elements is printed. For each target (1e-4 and 1e-6)
   every method takes the cheapest setting of its ladder that meets the
   target. An integrator stops at the first cycle whose deflection history
   differs from the previous cycle's by less than the target (relative to the
   peak); its error is measured after that cycle. Times are to steady state:
   "solver" from assembled matrices (kedfem: the solve phase of ``kf.solve``),
   "end to end" adds the kinematics and assembly each method needs on its own
   time grid.
2. **Same discretization, time-varying chain** (N masses, every spring
   modulated +-10 % with its own phase, 5 % modal damping, loads at two DOFs,
   ``n`` zoh elements): kedfem ``periodic.solve`` against plain SciPy
   (``scipy.linalg.expm`` per element on the augmented matrix, then either the
   condensation Eq. 13-16 in a Python loop or ``spsolve`` of the whole cyclic
   system; the faster counts) and the paper's literal method (Taylor series per
   element to 1e-16, condensation in a Python loop). They solve the same
   discrete problem; the largest relative difference of ``U`` is printed.
3. **Time-invariant exciter** (``mechanisms/exciter.py``): kedfem against
   modal superposition at equal accuracy (beam mid-span deflection at 72
   nodes against kedfem foh at 4608 elements): ``kedfem.analysis.validation.
   modal_superposition`` (the same piecewise-linear load as ``foh``) and a
   spectral modal superposition (DFT of the sampled load, exact harmonic
   response per mode), which is exact for this single-harmonic load and wins.
4. **The flop bound**: the flops of kedfem's periodic solve on the chain
   (:func:`kedfem.lab.flops.periodic_flops`, with the Taylor degree and the
   squarings the exponentials actually chose) divided by this machine's
   batched matmul rate measured in the same run at the same sizes (best of
   ``np.matmul`` on the whole ``(n, m, m)`` stack and of a two-thread split
   with one BLAS thread each); kedfem's time as a multiple of that bound.
5. **Default scene**: ``kf.solve(kf.default_scene())``, median of 5 after a
   warm-up, and in units of one batched ``(n, 2N, 2N)`` matmul of its size.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import datetime
import functools
import math
import os
import platform
import statistics
import sys
import time
import warnings

import numpy as np
import scipy
import scipy.linalg as sla
from threadpoolctl import threadpool_info, threadpool_limits

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)
import kedfem as kf
from kedfem.lab import flops
from kedfem.lab.transient import integrate_sampled
from kedfem.solvers import periodic
from kedfem.solvers.expm import second_order_transition
from kedfem.analysis.pipeline import assemble_scene
from kedfem.analysis.validation import modal_superposition
from mechanisms import exciter, slider_crank

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import periodic_vs_scipy as pvs  # noqa: E402  the plain-SciPy and paper baselines
from periodic_vs_scipy import condense_loop, cyclic_spsolve  # noqa: E402

RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
NE = 72  # evaluation grid of the equal-accuracy studies: every 5 deg of crank
ROWS: list[dict] = []  # CSV rows
TRY_THREADED = True  # --quick: one BLAS thread only (except the "shipped" columns)
DEFAULT_THREADS = max([d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"] or [1])


def record(section, case, method, **kw):
    row = dict(section=section, case=case, method=method)
    row.update(kw)
    ROWS.append(row)
    return row


def _blas(threads):
    """Context: BLAS limited to ``threads`` threads (None: as configured at start)."""
    return threadpool_limits(limits=threads or DEFAULT_THREADS, user_api="blas")


def _median_time(fn, repeats, long):
    times, out = [], None
    for i in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
        if i == 0 and times[0] > long:
            break
    return statistics.median(times), out


def threaded_blas_healthy():
    """Is multi-threaded BLAS no slower than one thread on small batched work right now?

    On a shared machine whose other core is busy, OpenBLAS's threads wait for a
    time slice on every call, and small products or eigen-decompositions become
    10-100x slower than with one thread; then timing a method with threaded
    BLAS only measures the scheduler.
    """
    rng = np.random.default_rng(1)
    A = rng.standard_normal((32, 128, 128))
    S = rng.standard_normal((16, 33, 33))
    S = S + np.swapaxes(S, 1, 2)

    def probe():
        t0 = time.perf_counter()
        np.matmul(A, A)
        t1 = time.perf_counter()
        np.linalg.eigh(S)
        return np.array([t1 - t0, time.perf_counter() - t1])

    best = {}
    for thr in (1, None):
        with _blas(thr):
            best[thr] = np.min([probe() for _ in range(3)], axis=0)
    return bool(np.all(best[None] <= 1.5 * best[1] + 2e-4))


def timed(fn, repeats, long=10.0):
    """Median wall time of ``repeats`` calls (one call if the first takes > ``long`` s).

    Every method gets the better of two BLAS configurations: one thread, and
    the configured number (tried only when :func:`threaded_blas_healthy`, and
    not in ``--quick`` runs).
    Returns (seconds, last output, configuration label).
    """
    with _blas(1):
        t1, out1 = _median_time(fn, repeats, long)
    if TRY_THREADED and DEFAULT_THREADS > 1 and threaded_blas_healthy():
        with _blas(None):
            t2, out2 = _median_time(fn, repeats, long)
        if t2 < t1:
            return t2, out2, f"blas{DEFAULT_THREADS}"
    return t1, out1, "blas1"


T0 = time.perf_counter()


def say(*a):
    print(*a, flush=True)


def stamp(label):
    say(f"[{label} done at {time.perf_counter() - T0:.0f} s, load {os.getloadavg()[0]:.1f}]")


# ============================================================ 1. slider-crank
class Deflection:
    """Affine map U (at the NE evaluation nodes) -> rod mid-span deflection rel. to the chord."""

    def __init__(self, result, link, xi, relative_to):
        n, N = result.U.shape
        base = dataclasses.replace(result, U=np.zeros((n, N)), V=np.zeros((n, N)))
        self.w0 = base.deflection(link, xi, relative_to=relative_to)
        W = np.empty((n, N))
        for i in range(N):
            U = np.zeros((n, N))
            U[:, i] = 1.0
            r = dataclasses.replace(result, U=U, V=U)
            W[:, i] = r.deflection(link, xi, relative_to=relative_to) - self.w0
        self.W = W
        self.n = n

    def __call__(self, U):
        """Deflection history (NE,) from displacements at any multiple of the NE nodes."""
        s = U.shape[0] // self.n
        return np.einsum("kj,kj->k", self.W, U[::s]) + self.w0


class SliderCrank:
    """The slider-crank study at one damping: scenes, assembly, reference, error measure."""

    EFFECTS = ("inertia", "coupling", "axial_stiffening")

    def __init__(self, zeta, n_ref):
        self.zeta = zeta
        self.mech = slider_crank.build(elements=8)
        self.T = self.mech.period
        self.tk = np.arange(NE) * (self.T / NE)
        t0 = time.perf_counter()
        ref = kf.solve(self.scene(n_ref, "radau3"))
        gauss = kf.solve(self.scene(n_ref, "gauss3"))
        self.t_ref = time.perf_counter() - t0
        at = ref.resample(self.tk)
        self.defl = Deflection(at, "rod", 0.5, "chord")
        self.wref = self.defl(at.U)
        self.peak = float(np.abs(self.wref).max())
        self.ref_err = self.error_of(gauss)   # Radau vs Gauss on as many elements
        self.n_ref = n_ref
        self.N = ref.U.shape[1]
        self._terms = {}

    def scene(self, n=None, method="radau3", rtol=None):
        kw = dict(steps=n, estimate=False) if n is not None else dict(rtol=rtol)
        return kf.Scene(self.mech, effects=self.EFFECTS, damping=kf.ModalDamping(self.zeta), method=method, **kw)

    def assemble(self, n):
        _motion, _model, asm = assemble_scene(self.scene(n, "foh"), steps=n)
        return asm.system()

    def terms(self, n):
        if n not in self._terms:
            self._terms[n] = self.assemble(n)
        return self._terms[n]

    def error(self, U):
        return float(np.abs(self.defl(U) - self.wref).max() / self.peak)

    def error_of(self, res):
        return self.error(res.resample(self.tk).U)


def direct_periodic(terms, T, study: SliderCrank, method, tol, **kw):
    """Direct integration from rest (:func:`kedfem.lab.transient.integrate_sampled`), cycle by cycle.

    Stops at the first cycle whose deflection history (at the NE nodes) differs from the previous
    cycle's by at most ``tol`` times the reference peak; ``kw`` goes to ``integrate_sampled``.
    """
    r = integrate_sampled(terms.M, terms.C, terms.K, terms.Q, T, method, tol=tol, n_out=NE,
                          monitor=study.defl, scale=study.peak, **kw)
    if not r.converged:
        raise RuntimeError(f"{method}: {r.message}")
    return r


def study_slider_crank(targets, zeta, n_ref, repeats):
    say(f"\n== 1. slider-crank KED (N = 24, zeta = {zeta}): kedfem vs direct integration at equal accuracy")
    st = SliderCrank(zeta, n_ref)
    T = st.T
    say(f"reference: kedfem radau3, n = {n_ref} ({st.t_ref:.1f} s with gauss3); Radau vs Gauss on as many "
        f"elements: {st.ref_err:.1e}; peak mid-span deflection {st.peak * 1e3:.3f} mm; period {T * 1e3:.2f} ms")
    ladder = [NE * k for k in (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 48, 64, 96, 128)]
    k_ladder = (6, 12, 24, 48, 96, 192, 384)
    out = []
    t_asm = {}

    def asm_time(n):
        if n not in t_asm:
            # kinematics + FE model + assembly on this grid, as a method on its own grid needs
            t_asm[n] = timed(lambda: st.assemble(n), repeats)[0]
        return t_asm[n]

    hdr = (f"{'target':>7} {'method':34} {'cycles':>6} {'error':>8} | {'solver s':>9} {'ratio':>7} | "
           f"{'end-to-end s':>12} {'ratio':>7}")
    for tol in targets:
        say(f"\n-- target {tol:.0e}")
        # kedfem: fewest radau3 elements meeting the target (one solve, no estimate)
        n_k = next(n for n in k_ladder if st.error_of(kf.solve(st.scene(n))) <= tol)
        tk_e2e, res, bk = timed(lambda: kf.solve(st.scene(n_k)), repeats)
        tk_solver = res.timings.solve
        err_k = st.error_of(res)
        # kedfem as a user runs it: rtol = target, three levels and the estimate
        tt_e2e, rt, bt = timed(lambda: kf.solve(st.scene(rtol=tol)), repeats)
        err_t = st.error_of(rt)
        # Newmark: fewest steps meeting the target (the cycling included)
        nm = None
        for n in ladder:
            if st.error(direct_periodic(st.terms(n), T, st, "newmark", tol).U) <= tol:
                nm = n
                break
        if nm is None:
            raise RuntimeError(f"Newmark does not reach {tol:.0e} within {ladder[-1]} steps a cycle")
        tn_solver, r, bn = timed(lambda: direct_periodic(st.terms(nm), T, st, "newmark", tol), repeats)
        err_n, cyc_n = st.error(r.U), r.cycles
        tn_e2e = tn_solver + asm_time(nm)
        # Radau: loosest rtol on the coarsest spline grid meeting the target
        rd = None
        for ns in (NE * 4, NE * 8, NE * 16, NE * 32):
            for rtol in (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8):
                if rtol > 10 * tol:
                    continue
                r = direct_periodic(st.terms(ns), T, st, "radau", tol, rtol=rtol, atol=1e-3 * rtol)
                if st.error(r.U) <= tol:
                    rd = (ns, rtol)
                    break
            if rd:
                break
        if rd is None:
            raise RuntimeError(f"solve_ivp Radau does not reach {tol:.0e}")
        tr_solver, r, br = timed(functools.partial(direct_periodic, st.terms(rd[0]), T, st, "radau", tol,
                                                   rtol=rd[1], atol=1e-3 * rd[1]), repeats)
        err_r, cyc_r, nfev = st.error(r.U), r.cycles, r.nfev
        tr_e2e = tr_solver + asm_time(rd[0])
        say(hdr)
        say("-" * len(hdr))
        rows = [
            ("kedfem radau3", f"n = {n_k} [{bk}]", 1, err_k, tk_solver, tk_e2e),
            ("kedfem, rtol = target", f"n = {rt.elements}, levels {'/'.join(map(str, rt.error.levels))}, "
             f"estimate {rt.error.peak:.0e} [{bt}]", 1, err_t, rt.timings.solve, tt_e2e),
            ("Newmark avg. accel. (from rest)", f"n = {nm} steps/cycle [{bn}]", cyc_n, err_n, tn_solver,
             tn_e2e),
            ("solve_ivp Radau (from rest)", f"rtol = {rd[1]:.0e}, spline grid {rd[0]}, "
             f"{nfev // cyc_r} f-evals/cycle [{br}]", cyc_r, err_r, tr_solver, tr_e2e),
        ]
        for name, setting, cyc, err, ts, te in rows:
            rs, re_ = ts / tk_solver, te / tk_e2e
            say(f"{tol:7.0e} {name:34} {cyc:6d} {err:8.1e} | {ts:9.3f} {rs:7.1f} | {te:12.3f} {re_:7.1f}"
                f"   {setting}")
            record("slider-crank", f"zeta {zeta}, target {tol:.0e}", name, setting=setting, cycles=cyc, error=err,
                   solver_s=ts, e2e_s=te, ratio_solver=rs, ratio_e2e=re_)
        out.append(dict(tol=tol, rows=rows, n_k=n_k))
    say("ratio = method time / kedfem radau3 time (> 1: kedfem faster). solver: from assembled M, C, K, Q "
        "(kedfem: the solve phase of kf.solve); end-to-end: + kinematics and assembly on the method's own "
        "grid (kedfem: kf.solve).")
    return dict(zeta=zeta, ref_err=st.ref_err, n_ref=n_ref, peak=st.peak, targets=out, N=st.N)


# ===================================================================== 2. chain
T_CHAIN, W_MAX, ZETA_CHAIN, MOD = 1.0, 30.0, 0.05, 0.1


def chain(N, n):
    """Time-varying chain: M (N,N), C (N,N), K (n,N,N), Q (n,N) at t_k = k T / n."""
    k = (W_MAX / 2.0) ** 2
    lap = 2 * np.eye(N) - np.eye(N, k=1) - np.eye(N, k=-1)
    lap[-1, -1] = 1.0
    w2, V = np.linalg.eigh(k * lap)
    M = np.eye(N)
    C = (V * (2 * ZETA_CHAIN * np.sqrt(w2))) @ V.T
    t = np.arange(n) * (T_CHAIN / n)
    ks = k * (1 + MOD * np.cos(2 * np.pi * t[:, None] / T_CHAIN + np.linspace(0, np.pi, N)[None, :]))
    K = np.zeros((n, N, N))
    i = np.arange(N)
    K[:, i, i] += ks                    # spring j ties mass j to mass j - 1 (mass 0 to ground)
    K[:, i[:-1], i[:-1]] += ks[:, 1:]
    K[:, i[:-1], i[1:]] -= ks[:, 1:]
    K[:, i[1:], i[:-1]] -= ks[:, 1:]
    Q = np.zeros((n, N))
    Q[:, -1] = 100 * np.sin(2 * np.pi * t / T_CHAIN)
    Q[:, N // 2] += 50 * np.cos(4 * np.pi * t / T_CHAIN)
    return M, C, K, Q


def scipy_elements(M, C, K, Q):
    """A_k, b_k by scipy.linalg.expm of the augmented zoh matrix, one element at a time."""
    return pvs.scipy_elements(M, C, K, Q, T_CHAIN)


def paper_literal(M, C, K, Q, tol=1e-16):
    """Taylor series per element (Eq. 6, 9-10) and condensation (Eq. 13-16), Python loops; (n, 2N)."""
    return condense_loop(*pvs.paper_elements(M, C, K, Q, T_CHAIN, tol))


def kedfem_chain(M, C, K, Q, budget=256e6):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return periodic.solve(M, C, K, Q, T_CHAIN, hold="zoh", memory_budget=budget)


def rel(a, b):
    return float(np.abs(a - b).max() / np.abs(b).max())


def study_chain(sizes, repeats):
    say("\n== 2. time-varying chain, same zoh discretization: kedfem vs plain SciPy vs the paper's method")
    hdr = (f"{'N':>4} {'n':>5} | {'kedfem s':>8} | {'expm loop':>9} {'+cond s':>8} {'+spsolve s':>10} "
           f"{'scipy ratio':>11} | {'paper s':>8} {'ratio':>6} | {'diff scipy':>10} {'diff paper':>10}")
    say(hdr)
    say("-" * len(hdr))
    out = []
    for N, n in sizes:
        M, C, K, Q = chain(N, n)
        t_k, sol, b_k = timed(lambda: kedfem_chain(M, C, K, Q), repeats)
        Zk = np.concatenate([sol.U, sol.V], axis=1)
        t_loop, (A, b), b_l = timed(lambda: scipy_elements(M, C, K, Q), repeats)
        t_cond, Zc, b_c = timed(lambda: condense_loop(A, b), repeats)
        t_sps, Zs, b_s = timed(lambda: cyclic_spsolve(A, b), repeats)
        t_scipy = t_loop + min(t_cond, t_sps)
        t_p, Zp, b_p = timed(lambda: paper_literal(M, C, K, Q), repeats)
        d_s = max(rel(Zc[:, :N], sol.U), rel(Zs[:, :N], sol.U))
        d_p = rel(Zp[:, :N], sol.U)
        r_s, r_p = t_scipy / t_k, t_p / t_k
        say(f"{N:4d} {n:5d} | {t_k:8.3f} | {t_loop:9.3f} {t_cond:8.3f} {t_sps:10.3f} {r_s:11.1f} | "
            f"{t_p:8.3f} {r_p:6.1f} | {d_s:10.1e} {d_p:10.1e}")
        say(f"{'':10} BLAS threads used: kedfem {b_k}, expm loop {b_l}, condensation {b_c}, spsolve {b_s}, "
            f"paper {b_p}")
        record("chain", f"N={N} n={n}", "kedfem", time_s=t_k)
        record("chain", f"N={N} n={n}", "scipy expm loop + condensation", time_s=t_loop + t_cond,
               ratio=(t_loop + t_cond) / t_k, diff=rel(Zc[:, :N], sol.U))
        record("chain", f"N={N} n={n}", "scipy expm loop + spsolve", time_s=t_loop + t_sps,
               ratio=(t_loop + t_sps) / t_k, diff=rel(Zs[:, :N], sol.U))
        record("chain", f"N={N} n={n}", "paper literal", time_s=t_p, ratio=r_p, diff=d_p)
        del Zk
        out.append(dict(N=N, n=n, t_k=t_k, t_loop=t_loop, t_cond=t_cond, t_sps=t_sps, r_s=r_s, t_p=t_p,
                        r_p=r_p, d_s=d_s, d_p=d_p))
    say("scipy ratio = (expm loop + faster of condensation / spsolve) / kedfem; diff = max |U - U_kedfem| "
        "/ max |U_kedfem|")
    return out


# ================================================================== 3. exciter
def spectral_modal(M, C, K, Q, period):
    """Modal superposition with the DFT of the sampled load (band-limited load, exact per harmonic)."""
    n = Q.shape[0]
    lam, Phi = sla.eigh(K, M)
    c = np.einsum("ij,ik,kj->j", Phi, C, Phi)
    Fh = np.fft.rfft(Q @ Phi, axis=0)
    w = np.arange(Fh.shape[0]) * (2 * math.pi / period)
    H = 1.0 / (lam[None, :] - (w ** 2)[:, None] + 1j * w[:, None] * c[None, :])
    U = np.fft.irfft(Fh * H, n, axis=0) @ Phi.T
    V = np.fft.irfft(Fh * H * (1j * w[:, None]), n, axis=0) @ Phi.T
    return U, V


def study_exciter(targets, repeats):
    say("\n== 3. time-invariant exciter (N = 24): kedfem vs modal superposition at equal accuracy")
    mech = exciter.build()

    def scene(n):
        return kf.Scene(mech, steps=n, effects=("inertia", "coupling", "springs"),
                        damping=kf.ModalDamping(0.02), hold="foh")

    T = mech.period
    tk = np.arange(NE) * (T / NE)
    defl = Deflection(kf.solve(scene(NE)).resample(tk), "beam", 0.5, "frame")
    terms = {}

    def tm(n):
        if n not in terms:
            _mo, _model, asm = assemble_scene(scene(n))
            terms[n] = asm.system()
        return terms[n]

    def inv_solve(n):
        s = tm(n)
        return periodic.solve(s.M[0], s.C[0], s.K[0], s.Q, T, hold="foh")

    n_ref = NE * 64
    wref = defl(inv_solve(n_ref).U)
    peak = float(np.abs(wref).max())

    def err(U):
        return float(np.abs(defl(U) - wref).max() / peak)

    s72 = tm(NE)
    ms_err = err(spectral_modal(s72.M[0], s72.C[0], s72.K[0], s72.Q, T)[0])
    say(f"reference: kedfem foh, n = {n_ref} (constant M, C, K); the spectral modal superposition at "
        f"n = {NE} differs from it by {ms_err:.1e}")
    ladder = [NE * k for k in (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 24, 32)]
    hdr = f"{'target':>7} {'method':48} {'n':>5} {'error':>8} {'time s':>9} {'/ kedfem':>8}"
    say(hdr)
    say("-" * len(hdr))
    out = []
    for tol in targets:
        n_k = next(n for n in ladder if err(inv_solve(n).U) <= tol)
        s = tm(n_k)
        t_inv, sol, _b = timed(lambda: inv_solve(n_k), repeats)
        t_e2e, res, _b = timed(lambda: kf.solve(scene(n_k)), repeats)
        t_msv, (U_msv, _), _b = timed(lambda: modal_superposition(s.M[0], s.C[0], s.K[0], s.Q, T), repeats)
        t_spec, (U_sp, _), _b = timed(lambda: spectral_modal(s72.M[0], s72.C[0], s72.K[0], s72.Q, T),
                                  max(repeats, 5))
        rows = [("kedfem periodic.solve, constant M C K (foh)", n_k, err(sol.U), t_inv),
                ("kedfem kf.solve end to end (assembly + solve)", n_k, err(res.resample(tk).U), t_e2e),
                ("modal superposition, kedfem.analysis.validation (same load)", n_k, err(U_msv), t_msv),
                ("spectral modal superposition (DFT of the load)", NE, err(U_sp), t_spec)]
        for name, n, e, t in rows:
            say(f"{tol:7.0e} {name:48} {n:5d} {e:8.1e} {t:9.4f} {t / t_inv:8.2f}")
            record("exciter", f"target {tol:.0e}", name, n=n, error=e, time_s=t, ratio=t / t_inv)
        out.append(dict(tol=tol, rows=rows))
    say("'/ kedfem' = time / kedfem periodic.solve time (< 1: the method is faster than kedfem)")
    return out


# =============================================================== 4. flop bound
def matmul_rate(batch, m, repeats=3):
    """Best of numpy's batched matmul (BLAS as configured) and a 2-thread split (1 BLAS thread each).

    Returns (best, numpy, split) in flop/s. Matrices above 128 are timed on a
    batch of at most 64 (the product is compute bound there; it keeps the
    measurement short).
    """
    b = batch if m <= 128 else min(batch, 64)
    with _blas(None):
        r1 = flops.batched_matmul_rate(b, m, repeats=repeats, threads=1)
    r2 = flops.batched_matmul_rate(b, m, repeats=repeats, threads=2)
    return max(r1, r2), r1, r2


def study_flops(sizes, repeats):
    say("\n== 4. the flop bound: kedfem periodic.solve on the chain (zoh, all A_k kept) vs flops / matmul rate")
    say("   shipped = BLAS threads as configured; blas1 = the same solve inside threadpool_limits(1)")
    hdr = (f"{'N':>4} {'n':>5} | {'deg':>3} {'sq':>2} {'Gflop':>7} {'exp %':>5} | {'rate ma':>7} "
           f"{'(np / split)':>13} | {'bound s':>8} {'shipped s':>9} {'x bound':>7} | {'blas1 s':>8} "
           f"{'x bound':>7} | {'exp x':>5} {'cond x':>6}")
    say(hdr)
    say("-" * len(hdr))
    out = []
    for N, n in sizes:
        M, C, K, Q = chain(N, n)
        budget = max(256e6, 4.0 * n * (2 * N) ** 2 * 8)  # keep all A_k: one pass

        def run():
            return kedfem_chain(M, C, K, Q, budget)

        with _blas(1):
            sol = run()  # warm-up; the exponentials' actual choices (same matrices, same delta):
            S = np.linalg.solve(M, K)
            D = np.linalg.solve(M, C)
            f0 = Q @ np.linalg.inv(M).T
            _A, _b, info = second_order_transition(S, D, T_CHAIN / n, f0, None, delta=sol.delta,
                                                   approximant="taylor", return_info=True)
            del _A, _b, S
        if info.degree != sol.degree or int(info.squarings.max()) != sol.max_squarings:
            say(f"   note: solver chose degree {sol.degree} / {sol.max_squarings} squarings, the recount "
                f"{info.degree} / {int(info.squarings.max())}")
        cnt = flops.periodic_flops(n, N, "zoh", products=info.products, squarings=info.squarings,
                                   degree=info.degree, mass="constant", damping="constant",
                                   passes=sol.passes)
        m, ma = 2 * N, 2 * N + 1
        # interleave: rate measurement, shipped solve, one-thread solve; the multiples pair them in time
        mult, mult1, ts, t1s, bounds, xe, xc, rates_seen = [], [], [], [], [], [], [], []
        for r in range(repeats):
            rates = {sz: matmul_rate(n, sz) for sz in cnt.sizes()}
            rates_seen.append(rates)
            bound = flops.time_bound(cnt, lambda sz: rates[sz][0])
            with _blas(None):
                t0 = time.perf_counter()
                sol = run()
                t = time.perf_counter() - t0
            with _blas(1):
                t0 = time.perf_counter()
                sol1 = run()
                t1 = time.perf_counter() - t0
            fe, _ = cnt.phases["exponentials"]
            fc, _ = cnt.phases["condensation"]
            tb = min((sol, t), (sol1, t1), key=lambda x: x[1])[0]
            xe.append(tb.timings["exponentials"] / (fe / rates[ma][0]))
            xc.append(tb.timings["condensation"] / (fc / rates[m][0]))
            mult.append(t / bound)
            mult1.append(t1 / bound)
            ts.append(t)
            t1s.append(t1)
            bounds.append(bound)
            if t > 20 or t1 > 20:
                break
        med = statistics.median
        rbest = max(rates_seen, key=lambda rr: rr[ma][0])[ma]
        row = dict(N=N, n=n, deg=info.degree, sq=int(info.squarings.max()), gflop=cnt.total / 1e9,
                   exp_share=cnt.phases["exponentials"][0] / cnt.total, rate=med([rr[ma][0] for rr in rates_seen]) / 1e9,
                   bound=med(bounds), t=med(ts), mult=med(mult), t1=med(t1s), mult1=med(mult1),
                   x_exp=med(xe), x_cond=med(xc))
        say(f"{N:4d} {n:5d} | {row['deg']:3d} {row['sq']:2d} {row['gflop']:7.2f} {100 * row['exp_share']:5.1f} | "
            f"{row['rate']:7.1f} {rbest[1] / 1e9:6.1f}/{rbest[2] / 1e9:<6.1f} | {row['bound']:8.3f} "
            f"{row['t']:9.3f} {row['mult']:7.2f} | {row['t1']:8.3f} {row['mult1']:7.2f} | "
            f"{row['x_exp']:5.2f} {row['x_cond']:6.2f}")
        record("flop bound", f"N={N} n={n}", "kedfem periodic.solve", degree=row["deg"], squarings=row["sq"],
               gflop=row["gflop"], rate_ma_gflops=row["rate"], bound_s=row["bound"], time_s=row["t"],
               multiple=row["mult"], time_blas1_s=row["t1"], multiple_blas1=row["mult1"],
               exp_multiple=row["x_exp"], cond_multiple=row["x_cond"],
               timings=";".join(f"{k}={v:.4f}" for k, v in sol.timings.items()))
        out.append(row)
    say("rate ma: Gflop/s of the batched (n, 2N+1, 2N+1) product (median over the repeats; np = one "
        "np.matmul call, split = 2 threads x 1 BLAS thread, best repeat shown); x bound: medians of "
        "time / bound, each solve paired with the rate measured just before it. exp x / cond x: the "
        "exponential and condensation phases over their own bounds (faster configuration).")
    return out


# ============================================================== 5. default scene
def study_default(repeats):
    say("\n== 5. default scene: kf.solve(kf.default_scene())")
    sc = kf.default_scene()
    out = {}
    for label, thr in (("shipped", None), ("blas1", 1)):
        with _blas(thr):
            res = kf.solve(sc)  # warm-up
            times = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                res = kf.solve(sc)
                times.append(time.perf_counter() - t0)
        out[label] = (statistics.median(times), min(times), res.timings)
    n, N = res.elements, res.U.shape[1]
    rate = matmul_rate(n, 2 * N)[0]
    t_mm = flops.matmul_flops(2 * N) * n / rate
    for label, (t, tmin, tm) in out.items():
        say(f"{label:8}: n = {n}, N = {N}, {res.iterations} periodic solves; median of {repeats}: {t:.3f} s "
            f"(min {tmin:.3f}) = {t / t_mm:.0f} batched ({n}, {2 * N}, {2 * N}) matmuls "
            f"({t_mm * 1e3:.2f} ms each at {rate / 1e9:.1f} Gflop/s); kinematics {tm.kinematics:.3f}, "
            f"assembly {tm.assembly:.3f}, solve {tm.solve:.3f} s")
        record("default scene", "mould oscillator group 1", f"kf.solve ({label})", n=n, N=N, time_s=t,
               matmul_units=t / t_mm, kinematics_s=tm.kinematics, assembly_s=tm.assembly, solve_s=tm.solve)
    t, tmin, tm = out["shipped"]
    return dict(t=t, tmin=tmin, n=n, N=N, units=t / t_mm, t_mm=t_mm, timings=tm, iterations=res.iterations,
                t1=out["blas1"][0], timings1=out["blas1"][2], units1=out["blas1"][0] / t_mm)


# ==================================================================== summary
def machine():
    try:
        import threadpoolctl
        blas = ", ".join(f"{d['internal_api']} {d.get('version', '')} x{d['num_threads']}"
                         for d in threadpoolctl.threadpool_info() if d["user_api"] == "blas")
    except Exception:  # pragma: no cover
        blas = "?"
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, load {load}; "
            f"Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
            f"BLAS {blas}")


def verdict(ok):
    return "PASS" if ok else "FAIL"


def summary(sc, ch, ex, fl, de, quick, wall, info):
    L = []
    L.append(f"## kedfem vs peers ({datetime.date.today().isoformat()}"
             f"{', quick run' if quick else ''})\n")
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    L.append(f"`python benchmarks/peers.py` on {info} (load at the end {load}); wall time {wall:.0f} s. "
             f"Medians of repeats; ratios from times of the same run; each method on its faster BLAS "
             f"configuration (one thread, or the configured threads when they were not slowed down by "
             f"the shared machine at that moment).\n")
    for study in sc:
        L.append(f"### Slider-crank KED, equal accuracy (N = {study['N']}, {100 * study['zeta']:g} % modal "
                 "damping)\n")
        L.append("Error: max over 72 crank positions of the rod's mid-span deflection (relative to the chord) "
                 f"minus the reference's, over its peak ({study['peak'] * 1e3:.3f} mm); reference kedfem radau3 "
                 f"at n = {study['n_ref']} (Gauss-Legendre on as many elements agrees to "
                 f"{study['ref_err']:.0e}). Integrators start from rest and stop when a cycle changes the "
                 "history by less than the target. Ratio = method time / kedfem radau3 time.\n")
        L.append("| target | method | setting | cycles | error | solver [s] | ratio | end to end [s] | ratio |")
        L.append("|---|---|---|---:|---:|---:|---:|---:|---:|")
        for tg in study["targets"]:
            k = tg["rows"][0]
            for name, setting, cyc, err, ts, te in tg["rows"]:
                L.append(f"| {tg['tol']:.0e} | {name} | {setting} | {cyc} | {err:.1e} | {ts:.3f} | "
                         f"{ts / k[4]:.1f} | {te:.3f} | {te / k[5]:.1f} |")
    L.append("\n### Time-varying chain, same zoh discretization\n")
    L.append("| N | n | kedfem [s] | plain SciPy [s] (expm loop + condensation / spsolve) | ratio | "
             "paper's method [s] | ratio | max diff |")
    L.append("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in ch:
        L.append(f"| {r['N']} | {r['n']} | {r['t_k']:.3f} | {r['t_loop'] + r['t_cond']:.3f} / "
                 f"{r['t_loop'] + r['t_sps']:.3f} | {r['r_s']:.1f} | {r['t_p']:.3f} | {r['r_p']:.1f} | "
                 f"{max(r['d_s'], r['d_p']):.0e} |")
    L.append("\n### Time-invariant exciter: modal superposition (time / kedfem `periodic.solve`)\n")
    L.append("| target | method | n | error | time [s] | / kedfem |")
    L.append("|---|---|---:|---:|---:|---:|")
    for tg in ex:
        t0 = tg["rows"][0][3]
        for name, n, e, t in tg["rows"]:
            L.append(f"| {tg['tol']:.0e} | {name} | {n} | {e:.1e} | {t:.4f} | {t / t0:.2f} |")
    L.append("\nFor a time-invariant system the spectral modal superposition (one eigen-decomposition, "
             "one FFT) is faster than kedfem and exact for this single-harmonic load; kedfem's niche is "
             "time-varying M(t), C(t), K(t).\n")
    L.append("### Flop bound (chain, zoh, `periodic.solve`)\n")
    L.append("Bound = flops (`kedfem.lab.flops.periodic_flops`, with the degree and squarings the exponentials "
             "chose) / batched matmul rate at the same sizes, measured just before each solve. shipped: BLAS "
             "threads as configured; blas1: inside `threadpool_limits(1)`. When the other core is busy, "
             "OpenBLAS's threads slow kedfem's main-thread products (condensation) and small LAPACK calls "
             "(Floquet multipliers, condition) by 10-40x; the one-thread column shows the solver without "
             "that effect.\n")
    L.append("| N | n | Taylor degree | squarings | Gflop | rate [Gflop/s] | bound [s] | shipped [s] | x bound | "
             "blas1 [s] | x bound | exponentials x | condensation x |")
    L.append("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in fl:
        L.append(f"| {r['N']} | {r['n']} | {r['deg']} | {r['sq']} | {r['gflop']:.2f} | {r['rate']:.1f} | "
                 f"{r['bound']:.3f} | {r['t']:.3f} | {r['mult']:.2f} | {r['t1']:.3f} | {r['mult1']:.2f} | "
                 f"{r['x_exp']:.2f} | {r['x_cond']:.2f} |")
    L.append(f"\n### Default scene\n\n`kf.solve(kf.default_scene())` (mould oscillator, n = {de['n']}, "
             f"time elements (radau3, three levels for the estimate), N = {de['N']}, {de['iterations']} periodic solves on the last level): median {de['t']:.3f} s (min "
             f"{de['tmin']:.3f} s) = {de['units']:.0f} batched ({de['n']}, {2 * de['N']}, {2 * de['N']}) "
             f"matmuls; kinematics {de['timings'].kinematics:.3f} s, assembly {de['timings'].assembly:.3f} s, "
             f"solve {de['timings'].solve:.3f} s. Inside `threadpool_limits(1)`: {de['t1']:.3f} s "
             f"(assembly {de['timings1'].assembly:.3f} s, solve {de['timings1'].solve:.3f} s).\n")
    # acceptance
    L.append("### Acceptance\n")
    acc = []
    for study in sc:
        for tg in study["targets"]:
            k = tg["rows"][0]
            for name, _s, _c, _e, ts, te in tg["rows"][2:]:
                need = 100.0 if "solve_ivp" in name else (10.0 if tg["tol"] >= 1e-4 else 50.0)
                acc.append((f">= {need:g}x faster than {name} at {tg['tol']:.0e}, zeta {study['zeta']}",
                            te / k[5] >= need, f"end to end {te / k[5]:.1f}x, solver {ts / k[4]:.1f}x; "
                            f"rtol-driven kedfem end to end {te / tg['rows'][1][5]:.1f}x"))
    for r in ch:
        need = 3.0 if r["N"] <= 13 else (1.5 if r["N"] >= 100 else None)
        if need:
            acc.append((f">= {need:g}x faster than plain SciPy at N = {r['N']} (n = {r['n']})",
                        r["r_s"] >= need, f"{r['r_s']:.1f}x"))
    for r in fl:
        if r["N"] >= 100:
            acc.append((f"within 2x of the flop bound at N = {r['N']}", r["mult"] <= 2.0,
                        f"{r['mult']:.2f}x shipped, {r['mult1']:.2f}x with one BLAS thread"))
    acc.append(("default scene < 0.5 s", de["t"] < 0.5,
                f"{de['t']:.3f} s shipped, {de['t1']:.3f} s with one BLAS thread"))
    L.append("| criterion | verdict | measured |")
    L.append("|---|---|---|")
    for text, ok, meas in acc:
        L.append(f"| {text} | {verdict(ok)} | {meas} |")
    return "\n".join(L) + "\n", acc


def write_outputs(md):
    os.makedirs(RESULTS, exist_ok=True)
    with open(os.path.join(RESULTS, "peers.md"), "w") as fh:
        fh.write(md)
    keys = []
    for r in ROWS:
        for k in r:
            if k not in keys:
                keys.append(k)
    with open(os.path.join(RESULTS, "peers.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in ROWS:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke run (< 60 s): small sizes, one target")
    ap.add_argument("--repeats", type=int, default=None, help="timing repeats (default 3, quick 1)")
    ap.add_argument("--no-write", action="store_true", help="do not write benchmarks/results/peers.*")
    args = ap.parse_args(argv)
    q = args.quick
    global TRY_THREADED
    TRY_THREADED = not q
    rep = args.repeats or (1 if q else 3)
    t_start = time.perf_counter()
    info = machine()
    say(info)
    ctx = _blas(1)  # untimed work (ladders, references) on one BLAS thread; timed() tries both
    if q:
        sc = [study_slider_crank([1e-4], 0.02, 384, rep)]
    else:
        sc = [study_slider_crank([1e-4, 1e-6], z, 1536, rep) for z in (0.02, 0.005)]
    stamp("1. slider-crank")
    ch = study_chain([(13, 360), (100, 90)] if q else [(13, 360), (100, 360)], rep)
    stamp("2. chain")
    ex = study_exciter([1e-3] if q else [1e-3, 1e-4], rep)
    stamp("3. exciter")
    fl = study_flops([(13, 90), (50, 90), (100, 45)] if q else [(13, 360), (50, 360), (100, 360), (200, 360)],
                     rep)
    stamp("4. flop bound")
    de = study_default(2 if q else 5)
    stamp("5. default scene")
    ctx.restore_original_limits()
    wall = time.perf_counter() - t_start
    md, _acc = summary(sc, ch, ex, fl, de, q, wall, info)
    say("\n" + md)
    if not args.no_write:
        write_outputs(md)
        say(f"written: {os.path.join(RESULTS, 'peers.md')}, {os.path.join(RESULTS, 'peers.csv')}")
    say(f"total wall time {time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
