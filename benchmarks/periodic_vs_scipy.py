"""kedfem periodic solver against a SciPy baseline and the paper's literal method.

Run: ``python benchmarks/periodic_vs_scipy.py`` (add ``--quick`` for a smoke run).

System: a time-VARYING mass-spring-damper chain of N masses (every spring's
stiffness is modulated by +-10 % over the period with its own phase, so no two
time elements share an exponential), modal damping 5 % on every mode (so the
chain stays parametrically stable), harmonic loads at two DOFs. Period 1 s,
highest natural frequency 30 rad/s.

Methods, all on the SAME discretization (zero-order hold, the paper's scheme, same
n), so they compute the same discrete periodic solution; their difference is
printed (``diff``) and must be at rounding level for the timing comparison to be
at equal accuracy. Each exponential is accurate to rounding (SciPy) or to the
same backward error (kedfem ``delta`` from :func:`kedfem.solvers.periodic.auto_delta`,
<= 1e-10; Taylor series to 1e-16 per term), far below the zoh discretization
error, which is printed as ``err`` against a converged reference (kedfem magnus2
at n = 14400, second order; its own error, estimated by comparison with n = 7200,
is printed as ``ref err``).

- kedfem: ``periodic.solve(M, C, K, Q, T, hold="zoh")`` (batched exponentials,
  condensation). ``memory_budget`` large enough to keep all A_k (one pass); the
  default 256 MB budget (two passes when A_k do not fit) is timed too.
- scipy: Python loop of ``scipy.linalg.expm`` per time element on the augmented
  matrix ``[[F dt, g dt], [0, 0]]``, then ``scipy.sparse.linalg.spsolve`` of the
  whole block-cyclic system (paper Eq. 12). Run in a child process (timed
  inside it) because SuperLU may crash on the largest case.
- paper: the paper's literal method: Python loop of truncated Taylor series for
  ``A_k`` and ``B_k`` (Eq. 9-10) per element, condensation (Eq. 13-16 with the
  corrected back substitution).

Peak memory: ``n = 20000, N = 100`` with callable (streamed) inputs and the default
256 MB budget, in a fresh subprocess started first, measured as VmHWM (peak RSS of
the process image, ``/proc/self/status``; ``ru_maxrss`` is printed too but on
Linux it survives fork + exec and can report a parent's peak).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from kedfem.solvers import periodic  # noqa: E402

T = 1.0
W_MAX = 30.0
ZETA = 0.05
MOD = 0.1


def chain(N: int):
    """Callables (M, C, K, Q) of node indices for the time-varying chain at n nodes."""
    m = 1.0
    k = (W_MAX / 2.0) ** 2 * m  # highest frequency of the uniform chain ~ 2 sqrt(k/m)
    base = (np.diag(np.full(N, 2.0)) - np.diag(np.ones(N - 1), 1) - np.diag(np.ones(N - 1), -1))
    base[-1, -1] = 1.0  # free end
    w2, V = np.linalg.eigh(k * base / m)
    M = np.eye(N) * m
    C = m * (V * (2 * ZETA * np.sqrt(w2))) @ V.T  # modal damping ZETA on every mode
    ph = np.linspace(0.0, np.pi, N)
    idx = np.arange(N)

    def make(n):
        def K(i):
            t = np.asarray(i) * (T / n)
            kk = k * (1 + MOD * np.cos(2 * np.pi * t[:, None] / T + ph[None, :]))  # spring j
            out = np.zeros((len(t), N, N))
            out[:, idx, idx] += kk                      # spring j ties mass j to j-1 (ground)
            out[:, idx[:-1], idx[:-1]] += kk[:, 1:]
            out[:, idx[:-1], idx[1:]] -= kk[:, 1:]
            out[:, idx[1:], idx[:-1]] -= kk[:, 1:]
            return out

        def Q(i):
            t = np.asarray(i) * (T / n)
            q = np.zeros((len(t), N))
            q[:, -1] = 100 * np.sin(2 * np.pi * t / T)
            q[:, N // 2] += 50 * np.cos(4 * np.pi * t / T)
            return q
        return K, Q
    return M, C, make


def arrays(N, n):
    M, C, make = chain(N)
    K, Q = make(n)
    i = np.arange(n)
    return M, C, K(i), Q(i)


# ------------------------------------------------------------------ baselines
# (also used by benchmarks/peers.py)
def scipy_elements(M, C, K, Q, period=T):
    """A_k, b_k by scipy.linalg.expm of the augmented zoh matrix, one element at a time."""
    n, N = Q.shape
    m, dt = 2 * N, period / n
    A = np.empty((n, m, m))
    b = np.empty((n, m))
    X = np.zeros((m + 1, m + 1))
    X[:N, N:m] = np.eye(N) * dt
    for k in range(n):
        R = np.linalg.solve(M, np.column_stack([K[k], C, Q[k]])) * dt
        X[N:m, :N] = -R[:, :N]
        X[N:m, N:m] = -R[:, N:m]
        X[N:m, m] = R[:, m]
        E = sla.expm(X)
        A[k] = E[:m, :m]
        b[k] = E[:m, m]
    return A, b


def cyclic_spsolve(A, b):
    """The whole block-cyclic system A_k z_k - z_{k+1} = -b_k by scipy.sparse spsolve; (n, m)."""
    n, m = b.shape
    ii = np.arange(n * m).reshape(n, m)
    rows = np.concatenate([np.repeat(ii, m, axis=1).ravel(), ii.ravel()])
    cols = np.concatenate([np.tile(ii, (1, m)).ravel(), np.roll(ii, -1, axis=0).ravel()])
    vals = np.concatenate([A.ravel(), -np.ones(n * m)])
    S = sp.csc_matrix((vals, (rows, cols)), shape=(n * m, n * m))
    return spla.spsolve(S, -b.ravel()).reshape(n, m)


def condense_loop(A, b):
    """Condensation Eq. 13-16 (back substitution z_{k+1} = A_k z_k + b_k) in a Python loop; (n, m)."""
    n, m = b.shape
    Phi, d = np.eye(m), np.zeros(m)
    for k in range(n):
        Phi = A[k] @ Phi
        d = A[k] @ d + b[k]
    z = np.linalg.solve(np.eye(m) - Phi, d)
    Z = np.empty((n, m))
    for k in range(n):
        Z[k] = z
        z = A[k] @ z + b[k]
    return Z


def paper_elements(M, C, K, Q, period=T, tol=1e-16):
    """A_k, b_k by the paper's truncated Taylor series (Eq. 6, 9-10), one element at a time."""
    n, N = Q.shape
    m, dt = 2 * N, period / n
    I = np.eye(m)
    Mi = np.linalg.inv(M)
    G = np.vstack([np.zeros((N, N)), Mi])
    A = np.empty((n, m, m))
    b = np.empty((n, m))
    for k in range(n):
        F = np.block([[np.zeros((N, N)), np.eye(N)], [-Mi @ K[k], -Mi @ C]])
        Ak, Sk, term = I.copy(), I.copy(), I.copy()  # Sk = sum F^i dt^i / (i+1)!
        for i in range(1, 300):
            term = (term @ F) * (dt / i)
            Ak += term
            Sk += term / (i + 1)
            if np.abs(term).max() <= tol * np.abs(Ak).max():
                break
        A[k] = Ak
        b[k] = dt * (Sk @ (G @ Q[k]))
    return A, b


def scipy_baseline(M, C, K, Q, progress=None):
    """Plain SciPy: expm loop, then spsolve of the whole cyclic system; U (n, N)."""
    N = Q.shape[1]
    t0 = time.perf_counter()
    A, b = scipy_elements(M, C, K, Q)
    if progress:
        with open(progress, "w") as fh:
            fh.write(f"{time.perf_counter() - t0}")
    return cyclic_spsolve(A, b)[:, :N]


def paper_literal(M, C, K, Q, tol=1e-16):
    """The paper's method: Taylor series per element and condensation, Python loops; U (n, N)."""
    return condense_loop(*paper_elements(M, C, K, Q, tol=tol))[:, :Q.shape[1]]


def _scipy_child(N, n, repeats, progress):
    M, C, K, Q = arrays(N, n)
    return timed(lambda: scipy_baseline(M, C, K, Q, progress), repeats)


def scipy_isolated(N, n, repeats):
    """The SciPy baseline in a child process: SuperLU can crash the interpreter
    (SciPy 1.17.1 segfaults after "Not enough memory to perform factorization").
    Returns (seconds, U) or (seconds of the expm loop before the crash, message)."""
    ctx = multiprocessing.get_context("spawn")
    with tempfile.TemporaryDirectory() as tmp:
        progress = os.path.join(tmp, "expm_loop_seconds")
        with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as ex:
            try:
                return ex.submit(_scipy_child, N, n, repeats, progress).result()
            except (BrokenProcessPool, MemoryError) as e:
                t_loop = float(open(progress).read()) if os.path.exists(progress) else float("nan")
                return t_loop, f"{type(e).__name__}"


def kedfem_solve(M, C, K, Q, budget):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an InstabilityWarning would change the method
        return periodic.solve(M, C, K, Q, T, hold="zoh", memory_budget=budget)


def timed(fn, repeats):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def reference(N, n_ref):
    """Converged reference at the nodes of every n dividing n_ref (magnus2)."""
    M, C, make = chain(N)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the reference must be a stable, regular solve
        sol = periodic.solve(M, C, *make(n_ref), T, hold="magnus2", n=n_ref)
        half = periodic.solve(M, C, *make(n_ref // 2), T, hold="magnus2", n=n_ref // 2)
    return sol.U, rel(half.U, sol.U[::2])


MEMORY_CHILD = textwrap.dedent("""
    import resource, sys, time
    sys.path.insert(0, {root!r})
    sys.path.insert(0, {here!r})
    import numpy as np
    from periodic_vs_scipy import chain, T, vm_hwm_mib
    from kedfem.solvers import periodic
    N, n = {N}, {n}
    M, C, make = chain(N)
    K, Q = make(n)
    base = vm_hwm_mib()
    t0 = time.perf_counter()
    sol = periodic.solve(lambda i: np.broadcast_to(M, (len(i), N, N)),
                         lambda i: np.broadcast_to(C, (len(i), N, N)), K, Q, T,
                         hold="zoh", n=n)
    dt = time.perf_counter() - t0
    peak = vm_hwm_mib()
    maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(base, peak, maxrss, dt, sol.passes, sol.n_exponentials, sol.method,
          sol.U.nbytes / 2**20)
""")


def vm_hwm_mib():
    """Peak resident set size of this process image (VmHWM), MiB.

    ``ru_maxrss`` survives fork + exec on Linux (a child started from a big parent
    reports the parent's peak), VmHWM belongs to the address space and does not.
    """
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024
    except OSError:
        pass
    import resource
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def memory_run(N, n):
    here = os.path.dirname(os.path.abspath(__file__))
    code = MEMORY_CHILD.format(root=os.path.join(here, ".."), here=here, N=N, n=n)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    base, peak, maxrss, dt, passes, nexp, method, ubytes = out.stdout.split()
    return (float(base), float(peak), float(maxrss), float(dt), int(passes), int(nexp), method,
            float(ubytes))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sizes only (smoke test)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sizes", default="13x360,13x3600,40x360,40x3600,100x360,100x3600",
                    help="comma-separated NxN_ELEMENTS list")
    ap.add_argument("--no-memory", action="store_true", help="skip the peak-memory run")
    args = ap.parse_args(argv)
    sizes = [tuple(int(v) for v in item.split("x")) for item in args.sizes.split(",")]
    if args.quick:
        sizes = [(13, 360), (40, 360)]
    import threadpoolctl
    info = [(d["internal_api"], d["num_threads"]) for d in threadpoolctl.threadpool_info()]
    print(f"numpy {np.__version__}, scipy {__import__('scipy').__version__}, BLAS {info}, "
          f"{os.cpu_count()} CPUs")
    print("time-varying chain, hold='zoh' for all methods (same discrete system); medians of "
          f"{args.repeats} repeats (1 for runs over 20 s)\n")
    hdr = (f"{'N':>4} {'n':>5} | {'kedfem s':>9} {'(256MB)':>8} | {'scipy s':>8} {'ratio':>6} | "
           f"{'paper s':>8} {'ratio':>6} | {'diff scipy':>10} {'diff paper':>10} | "
           f"{'err zoh':>8} {'ref err':>8} | {'deg':>3} {'j':>2} {'delta':>6}")
    print(hdr)
    print("-" * len(hdr))
    memory_line = ""
    if not (args.quick or args.no_memory):
        # first, before this process grows (its children inherit nothing, but keep it clean)
        N, n = 100, 20000
        base, peak, maxrss, dt, passes, nexp, method, ub = memory_run(N, n)
        memory_line = (
            f"peak memory, N={N} n={n}, streamed callables, fresh subprocess: VmHWM "
            f"{peak:.0f} MiB (after imports {base:.0f} MiB; ru_maxrss {maxrss:.0f} MiB; U alone "
            f"{ub:.0f} MiB); {dt:.1f} s, {passes} passes, {nexp} exponentials, {method}; "
            f"keeping all A_k would need {n * (2 * N) ** 2 * 8 / 2**30:.1f} GiB")
        print(memory_line + "\n", flush=True)
    refs = {}
    notes = []
    for N, n in sizes:
        if N not in refs:
            refs[N] = reference(N, 14400 if not args.quick else 7200)
        Uref, ref_err = refs[N]
        M, C, K, Q = arrays(N, n)
        big = 8e9
        t_k, sol = timed(lambda: kedfem_solve(M, C, K, Q, big), args.repeats)
        t_k256, sol256 = timed(lambda: kedfem_solve(M, C, K, Q, 256e6), 1 if t_k > 20 else args.repeats)
        reps = 1 if t_k * 20 > 20 else args.repeats
        t_s, U_s = scipy_isolated(N, n, reps)
        crashed = isinstance(U_s, str)
        if crashed:
            d_s = float("nan")
            notes.append(f"scipy baseline at N={N}, n={n}: child process died ({U_s}) in "
                         f"spsolve: SuperLU of the {n * 2 * N}-unknown cyclic system "
                         f"({n * (2 * N) ** 2:.3g} nonzeros) ran out of memory and crashed; "
                         f"'scipy s' is its expm loop alone (a lower bound), '>' marks the ratio")
        else:
            d_s = rel(U_s, sol.U)
        t_p, U_p = timed(lambda: paper_literal(M, C, K, Q), reps)
        d_p = rel(U_p, sol.U)
        err = rel(sol.U, Uref[:: (Uref.shape[0] // n)])
        ratio_s = (">" if crashed else "") + f"{t_s / t_k:.1f}"
        print(f"{N:4d} {n:5d} | {t_k:9.3f} {t_k256:8.3f} | {t_s:8.3f} {ratio_s:>6} | "
              f"{t_p:8.3f} {t_p / t_k:6.1f} | {d_s:10.1e} {d_p:10.1e} | {err:8.1e} {ref_err:8.1e} | "
              f"{sol.degree:3d} {sol.max_squarings:2d} {sol.delta:6.0e}", flush=True)
    for note in notes:
        print("note:", note)
    if memory_line:
        print("\n" + memory_line)


if __name__ == "__main__":
    main()
