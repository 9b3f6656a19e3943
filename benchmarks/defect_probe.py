"""One-level error estimate of the Radau IIA collocation solve by defect correction: is it honest?

Research prototype (not used by kedfem). The tolerance-driven solve estimates its discretisation
error from three levels (n/4, n/2, n). This probe measures whether Zadunaisky's "neighbouring
problem" gives an honest estimate from ONE level, for ``kedfem.solvers.collocation.solve`` with
scheme ``"radau3"`` (order 5 at the element ends, stage order 3, dense output O(h^4)):

1. solve ``M u'' + C u' + K u = Q`` on n elements -> nodal u_k, v_k; nodal accelerations a_k from
   the equation of motion at the element end (the last Radau stage, c_3 = 1);
2. P(t): the piecewise quintic Hermite interpolant through (u_k, v_k, a_k) (C2);
3. defect at the collocation instants, d_j = M_j P''(t_j) + C_j P'(t_j) + K_j P(t_j) - Q_j
   (P solves the neighbouring problem with load Q + d exactly);
4. solve the neighbouring problem with the same scheme on the same elements -> u~;
   estimated error e_est(t) = u~(t) - P(t).

It is compared with the true error u(t) - y(t), y a radau3 reference on N_REF elements (its
distance to gauss3 on as many elements is printed), on 360 output instants per cycle:

* ``all DOFs``: max over instants and DOFs of |e|, divided by max |y| (rotations and
  displacements mixed, as the solver sees them);
* per flexible link: its mid-span deflection relative to its chord (linear in U through the
  constraint maps at each output instant), max over the cycle / peak deflection;
* ``nodes``: the same all-DOF norm at the element ends only (superconvergent, O(h^5));
* ``axial DOFs``: the DOFs the links' axial stiffness holds (axial share >= 0.9 all through the
  cycle: the stiff modes the L-stable scheme does not resolve), each relative to its own peak:
  the worst true error, and the range of est / true over those with a true error < 1e-2.

"ratio" is est / true; the target for an honest estimate is 1/3 .. 10 wherever the true error
is below 1e-2.

Cost (hermite5): kinematics + assembly at the 3n instants, the main solve (``collocation.solve``),
the estimate as prototyped (a full second solve, plus interpolant, defect and read-out), and a
re-solve of the neighbouring problem with the main solve's element operators kept
(:class:`KeptFactors`: W_k^-1, P_k, LU of I - Phi; batched matrix-vector products and two sweeps),
checked against the full re-solve.

Variants:

``hermite5``
    the proposal above;
``hermite5+k``
    k more defect-correction sweeps: the interpolant is rebuilt from the corrected nodal states
    u_k - e_est(t_k), v_k - e_est'(t_k) and the neighbouring problem solved again; the last
    e_est is reported (k + 1 extra solves);
``local7``
    P on each element: the degree-7 polynomial through u at 8 points (the previous element's
    middle stage, the element's start and 3 stages, the next element's 3 stages), differentiated
    analytically (only C0 between elements).

Cases: ``sc2``/``sc05`` slider-crank (``build(elements=8)``, 150 rad/s) with 2 % / 0.5 % modal
damping; ``fb`` four-bar and ``sb`` six-bar at their defaults with the linear effects and their
presets' 2 % modal damping; ``res`` the slider-crank at 410.5 rad/s with 0.5 % (the largest peak of
``--scan``, 173 mm mid-span deflection, a real Floquet multiplier 0.972), ``res2`` at 314 rad/s
(the second peak, 28.6 mm). All with effects inertia, coupling, axial_stiffening.

Run (single-threaded, about 75 s on the shared 2-core machine)::

    cd /work/main && . .venv/bin/activate
    OPENBLAS_NUM_THREADS=1 python benchmarks/defect_probe.py            # all cases and variants
    OPENBLAS_NUM_THREADS=1 python benchmarks/defect_probe.py --quick    # n <= 96, reference 768
    OPENBLAS_NUM_THREADS=1 python benchmarks/defect_probe.py --cases sb --variants hermite5 \
        --levels 32,40,48,64,80,96,128,160,240,320 --nref 1920           # the six-bar's transition
    OPENBLAS_NUM_THREADS=1 python benchmarks/defect_probe.py --scan 300,310,400,410,420  # speed scan
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import scipy.linalg as sla

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)
import kedfem as kf  # noqa: E402
from kedfem.fe.assembler import Assembler  # noqa: E402
from kedfem.fe.model import FEModel  # noqa: E402
from kedfem.model import elements as el  # noqa: E402
from kedfem.motion.kinematics import Cycle  # noqa: E402
from kedfem.solvers import collocation as co  # noqa: E402
from mechanisms import four_bar, six_bar, slider_crank  # noqa: E402

LINEAR = ("inertia", "coupling", "axial_stiffening")
LEVELS = (12, 24, 48, 96, 192, 384)
N_REF = 1536
N_OUT = 360
SCHEME = "radau3"
#: crank speed of the hard case [rad/s]: the largest peak of ``--scan`` over 100..450 rad/s
RES_SPEED = 410.5


# ----------------------------------------------------------------------------- cases
class Case:
    """A mechanism with its effects and damping: assembly at any instants, deflection maps."""

    def __init__(self, label, mech, links, damping, effects=LINEAR):
        self.label = label
        self.mech = mech
        self.links = links
        self.effects = effects
        self.damping = damping
        self.T = mech.period
        self.cycle = Cycle(mech)
        self.model = FEModel(mech)
        self.N = self.model.n_dof
        self.t_out = np.arange(N_OUT) * (self.T / N_OUT)
        self._W = None
        # DOFs held by the links' axial stiffness all through the cycle (the stiff ones)
        share = Assembler(self.model, self.cycle.at(np.arange(72) * (self.T / 72)), (), damping=None).axial_share()
        self.axial = share.min(axis=0) >= 0.9

    def system(self, scheme, n):
        """M, C, K (n s, N, N) and Q (n s, N) at the collocation instants of n elements."""
        ti = co.instants(scheme, n, self.T).ravel()
        sy = Assembler(self.model, self.cycle.at(ti), self.effects, damping=self.damping).system()
        return sy.M, sy.C, sy.K, sy.Q

    def deflection_maps(self):
        """Per link: W (N_OUT, N) with mid-span deflection rel. to the chord = sum_i W[:, i] U[:, i]."""
        if self._W is None:
            motion = self.cycle.at(self.t_out)
            gm = self.model.group_map("beam", motion)
            self._W = {}
            for link in self.links:
                sl = self.model.link_elements(link)
                ne = self.mech.links[link].elements
                assert ne % 2 == 0
                T = el.rotation_blocks(motion.angle(link))[:, None]
                W = np.empty((N_OUT, self.N))
                for i in range(self.N):
                    U = np.zeros((N_OUT, self.N))
                    U[:, i] = 1.0
                    d = (T @ gm.apply(U, sl)[..., None])[..., 0]  # (nt, ne, 6) local, linear part
                    W[:, i] = d[:, ne // 2, 1] - 0.5 * (d[:, 0, 1] + d[:, -1, 4])
                self._W[link] = W
        return self._W


def make_cases(res_speed):
    sc = slider_crank.build(elements=8)
    out = {
        "sc2": lambda: Case("slider-crank, 2 % modal", sc, ("rod",), kf.ModalDamping(0.02)),
        "sc05": lambda: Case("slider-crank, 0.5 % modal", sc, ("rod",), kf.ModalDamping(0.005)),
        "fb": lambda: Case("four-bar, linear effects, 2 % modal", four_bar.build(),
                           ("crank", "coupler", "follower"), four_bar.PRESET.damping),
        "sb": lambda: Case("six-bar, linear effects, 2 % modal", six_bar.build(),
                           ("crank", "coupler", "link", "rocker"), six_bar.PRESET.damping),
        "res": lambda: Case(f"slider-crank at {res_speed:g} rad/s (near resonance), 0.5 % modal",
                            slider_crank.build(elements=8, speed=res_speed), ("rod",), kf.ModalDamping(0.005)),
        "res2": lambda: Case("slider-crank at 314 rad/s (second peak of the scan), 0.5 % modal",
                             slider_crank.build(elements=8, speed=314.0), ("rod",), kf.ModalDamping(0.005)),
    }
    return out


# ----------------------------------------------------------------------------- interpolants
def _hermite5_coefficients():
    """Monomial coefficients (6 basis functions x 6 powers) of the quintic Hermite basis on [0, 1].

    Basis order: u0, v0 (times h), a0 (times h^2), u1, v1 (times h), a1 (times h^2).
    """
    rows = []
    for x in (0.0, 1.0):
        for d in range(3):  # value, first, second derivative of sum c_p x^p
            r = np.zeros(6)
            for p in range(d, 6):
                r[p] = math.factorial(p) / math.factorial(p - d) * x ** (p - d)
            rows.append(r)
    return np.linalg.inv(np.array(rows))  # column j: coefficients of basis j


H5 = _hermite5_coefficients()


def _powers(theta, d):
    """d-th derivative of theta^p, p = 0..5, shape (k, 6)."""
    out = np.zeros((theta.size, 6))
    for p in range(d, 6):
        out[:, p] = math.factorial(p) / math.factorial(p - d) * theta ** (p - d)
    return out


def locate(t, n, T):
    """(element, fraction in [0, 1)) of instants t on n uniform elements of the period T."""
    x = np.mod(t, T) * (n / T)
    k = np.minimum(np.floor(x).astype(int), n - 1)
    return k, x - k


def nodal_accelerations(sol, M, C, K, Q, U=None, V=None):
    """a_k at the element starts from the equation of motion at the end stage of element k-1
    (with the solution's nodal states, or given ones U, V (n, N))."""
    n = sol.n
    U = sol.U if U is None else U
    V = sol.V if V is None else V
    idx = (np.arange(n) - 1) % n * 3 + 2  # end stage of the element before (c_3 = 1)
    rhs = Q[idx] - np.einsum("kij,kj->ki", C[idx], V) - np.einsum("kij,kj->ki", K[idx], U)
    return np.linalg.solve(M[idx], rhs[..., None])[..., 0]


def stage_points(n):
    """(element, fraction) of the collocation instants, element by element."""
    c = co.tableau(SCHEME).c
    return np.repeat(np.arange(n), c.size), np.tile(c, n)


def hermite_eval(U, V, A, T, where, d=0):
    """d-th time derivative of the quintic Hermite interpolant through (U, V, A) at the element
    starts, at ``where = (element, fraction)`` (see :func:`locate`)."""
    n = U.shape[0]
    h = T / n
    k, th = where
    k1 = (k + 1) % n
    B = _powers(th, d) @ H5 / h ** d  # (k, 6) basis derivatives in t
    return (B[:, 0:1] * U[k] + B[:, 1:2] * h * V[k] + B[:, 2:3] * h * h * A[k]
            + B[:, 3:4] * U[k1] + B[:, 4:5] * h * V[k1] + B[:, 5:6] * h * h * A[k1])


def local7_eval(sol, T, where, d=0):
    """d-th derivative of the degree-7 polynomial through u at 8 points around each element: the
    previous element's middle stage, the element's start and 3 stages, the next element's 3 stages."""
    n = sol.n
    h = T / n
    c = co.tableau(SCHEME).c  # c_3 = 1: the end stage is the next element's start
    # 8 distinct abscissae in units of h from the element's start: the previous element's
    # middle stage, the start, the 3 stages, the next element's 3 stages
    nodes = np.concatenate([[-1.0 + c[1]], [0.0], c, 1.0 + c])
    V8 = np.vander(nodes, 8, increasing=True)
    coef = np.linalg.inv(V8)  # column j: monomial coefficients of the Lagrange basis j
    k, th = where
    P = np.zeros((th.size, 8))
    for p in range(d, 8):
        P[:, p] = math.factorial(p) / math.factorial(p - d) * th ** (p - d)
    L = P @ coef / h ** d  # (k, 8)
    km, kp = (k - 1) % n, (k + 1) % n
    vals = [sol.stage_U[km, 1], sol.U[k], sol.stage_U[k, 0], sol.stage_U[k, 1], sol.stage_U[k, 2],
            sol.stage_U[kp, 0], sol.stage_U[kp, 1], sol.stage_U[kp, 2]]
    return sum(L[:, j:j + 1] * vals[j] for j in range(8))


# ----------------------------------------------------------------------------- kept factorisations
class KeptFactors:
    """The main solve's element operators kept, for a re-solve with another load only.

    Built from the same data as ``collocation.solve``: the inverse stage matrices W_k^-1 (batched;
    the solver computes ``W_k^-1 [-R_k | q_k]`` by a batched solve instead), the transitions P_k
    and the LU of I - Phi. ``resolve(Q)`` then costs one batched matrix-vector product per
    element (W_k^-1 q_k), two matrix-vector sweeps over the elements and the stage states.
    ``t_build``: seconds to build all this here (the main solve forms the same P_k and Phi);
    ``t_inverse`` / ``t_solve``: the batched inverse of the W_k against the solver's batched solve
    with its 2N + 1 right-hand sides (what keeping the factorisation would add to the main solve).
    """

    def __init__(self, M, C, K, T, n):
        t0 = time.perf_counter()
        tab = co.tableau(SCHEME)
        self.tab, self.n, self.N, self.h = tab, n, M.shape[1], T / n
        s, N, h = tab.s, self.N, self.h
        Ms, Cs, Ks = (X.reshape(n, s, N, N) for X in (M, C, K))
        Is = np.eye(s)
        W = (Is[None, :, None, :, None] * Ms[:, :, :, None, :]
             + h * tab.A[None, :, None, :, None] * Cs[:, :, :, None, :]
             + h * h * tab.A2[None, :, None, :, None] * Ks[:, :, :, None, :]).reshape(n, s * N, s * N)
        negR = -np.concatenate([Ks, Cs + h * tab.c[None, :, None, None] * Ks], axis=3).reshape(n, s * N, 2 * N)
        rhs = np.concatenate([negR, np.zeros((n, s * N, 1))], axis=2)
        t1 = time.perf_counter()
        np.linalg.solve(W, rhs)  # what the solver does (timed only)
        t2 = time.perf_counter()
        self.Winv = np.linalg.inv(W)
        t3 = time.perf_counter()
        self.t_solve, self.t_inverse = t2 - t1, t3 - t2
        self.XR = XR = (self.Winv @ negR).reshape(n, s, N, 2 * N)
        P = np.zeros((n, 2 * N, 2 * N))
        P[:, :N] = h * h * np.einsum("j,kjnm->knm", tab.bA, XR)
        P[:, N:] = h * np.einsum("j,kjnm->knm", tab.b, XR)
        P += np.eye(2 * N)
        P[:, :N, N:] += h * np.eye(N)
        self.P = P
        Phi = np.eye(2 * N)
        for k in range(n):
            Phi = P[k] @ Phi
        self.lu_cyc = sla.lu_factor(np.eye(2 * N) - Phi)
        self.t_build = time.perf_counter() - t0 - (t2 - t1)

    def resolve(self, Q):
        """Element-start states U, V (n, N) and stage states (n, s, N) of the periodic solve with load Q."""
        tab, n, N, h, s = self.tab, self.n, self.N, self.h, self.tab.s
        aq = np.einsum("kij,kj->ki", self.Winv, Q.reshape(n, s * N)).reshape(n, s, N)
        p = np.concatenate([h * h * np.einsum("j,kjn->kn", tab.bA, aq), h * np.einsum("j,kjn->kn", tab.b, aq)], axis=1)
        r = np.zeros(2 * N)
        for k in range(n):
            r = self.P[k] @ r + p[k]
        Z = np.empty((n, 2 * N))
        Z[0] = sla.lu_solve(self.lu_cyc, r, check_finite=False)
        for k in range(n - 1):
            Z[k + 1] = self.P[k] @ Z[k] + p[k]
        # stage states (for the dense output): a = W^-1 (-R) z_k + W^-1 q
        acc = np.einsum("kjnm,km->kjn", self.XR, Z) + aq
        u0, v0 = Z[:, None, :N], Z[:, None, N:]
        SV = v0 + h * np.einsum("jl,kln->kjn", tab.A, acc)
        SU = u0 + h * tab.c[None, :, None] * v0 + h * h * np.einsum("jl,kln->kjn", tab.A2, acc)
        return Z[:, :N], Z[:, N:], SU, SV


# ----------------------------------------------------------------------------- the probe
def rel(e, y):
    return float(np.abs(e).max() / np.abs(y).max())


def defect(M, C, K, Q, P0, P1, P2):
    return np.einsum("kij,kj->ki", M, P2) + np.einsum("kij,kj->ki", C, P1) + np.einsum("kij,kj->ki", K, P0) - Q


def estimate(var, sol, M, C, K, Q, T, t_out):
    """One-level error estimate of ``sol``: dense on t_out and at the element starts.

    ``var``: ``"hermite5"`` (the proposal), ``"hermite5+k"`` (k further defect-correction
    iterations: the interpolant rebuilt from the corrected nodal states u - e_est each time),
    ``"local7"``. Returns (e_out, e_nodes, seconds of the extra solves, seconds of the rest,
    relative size of the first defect).
    """
    n = sol.n
    ws, wo = stage_points(n), locate(t_out, n, T)
    t_solves = t_rest = 0.0
    if var == "local7":
        te = time.perf_counter()
        d = defect(M, C, K, Q, *(local7_eval(sol, T, ws, k) for k in range(3)))
        t_rest += time.perf_counter() - te
        ts = time.perf_counter()
        nb = co.solve(M, C, K, Q + d, T, SCHEME, workers=1)
        t_solves += time.perf_counter() - ts
        e_out = nb.at(t_out)[0] - local7_eval(sol, T, wo)
        e_nodes = nb.U - local7_eval(sol, T, locate(sol.t, n, T))
        return e_out, e_nodes, t_solves, t_rest, rel(d, Q)
    iters = int(var.split("+")[1]) if "+" in var else 0
    U, V = sol.U, sol.V
    d_first = None
    for it in range(iters + 1):
        te = time.perf_counter()
        A = nodal_accelerations(sol, M, C, K, Q, U, V)
        d = defect(M, C, K, Q, *(hermite_eval(U, V, A, T, ws, k) for k in range(3)))
        if it == 0:
            d_first = rel(d, Q)
        t_rest += time.perf_counter() - te
        ts = time.perf_counter()
        nb = co.solve(M, C, K, Q + d, T, SCHEME, workers=1)
        t_solves += time.perf_counter() - ts
        te = time.perf_counter()
        e_out = nb.at(t_out)[0] - hermite_eval(U, V, A, T, wo)
        e_nodes, e_vel = nb.U - U, nb.V - V
        U, V = sol.U - e_nodes, sol.V - e_vel  # corrected nodal states for the next iteration
        t_rest += time.perf_counter() - te
    return e_out, e_nodes, t_solves, t_rest, d_first


def probe_case(case: Case, levels, n_ref, variants=("hermite5",)):
    T = case.T
    t_out = case.t_out
    t0 = time.perf_counter()
    ref = co.solve(*case.system(SCHEME, n_ref), T, SCHEME, workers=1)
    gref = co.solve(*case.system("gauss3", n_ref), T, "gauss3", workers=1)
    y, _ = ref.at(t_out)
    yg, _ = gref.at(t_out)
    Wmaps = case.deflection_maps()
    wy = {lk: np.einsum("ti,ti->t", W, y) for lk, W in Wmaps.items()}
    print(f"\n## {case.label}: N = {case.N} DOFs, T = {T * 1e3:.2f} ms, reference {SCHEME} n = {n_ref} "
          f"(rho = {ref.spectral_radius:.4f}); |radau3 - gauss3| on {n_ref} elements: all DOFs "
          f"{rel(y - yg, y):.1e}, " + ", ".join(
              f"{lk} {rel(np.einsum('ti,ti->t', W, y - yg), wy[lk]):.1e}" for lk, W in Wmaps.items())
          + "; peak deflection " + ", ".join(f"{lk} {np.abs(w).max() * 1e3:.3f} mm" for lk, w in wy.items())
          + f"  [{time.perf_counter() - t0:.1f} s]")
    rows = []
    for n in levels:
        ts = time.perf_counter()
        M, C, K, Q = case.system(SCHEME, n)
        t_asm = time.perf_counter() - ts
        ts = time.perf_counter()
        sol = co.solve(M, C, K, Q, T, SCHEME, workers=1)
        t_main = time.perf_counter() - ts
        e_true = sol.at(t_out)[0] - y
        yn = ref.U[::n_ref // n]
        e_true_nodes = sol.U - yn
        for var in variants:
            e_est, e_est_nodes, t_second, t_rest, dsize = estimate(var, sol, M, C, K, Q, T, t_out)
            row = dict(n=n, var=var, true=rel(e_true, y), est=rel(e_est, y),
                       ntrue=rel(e_true_nodes, yn), nest=rel(e_est_nodes, yn),
                       t_main=t_main, t_asm=t_asm, t_second=t_second, t_rest=t_rest, d=dsize)
            pk = np.abs(y[:, case.axial]).max(axis=0)
            tr = np.abs(e_true[:, case.axial]).max(axis=0) / pk
            es = np.abs(e_est[:, case.axial]).max(axis=0) / pk
            ok = tr < 1e-2
            row["ax_true"] = float(tr.max()) if tr.size else float("nan")
            row["ax_lo"] = float((es / tr)[ok].min()) if ok.any() else float("nan")
            row["ax_hi"] = float((es / tr)[ok].max()) if ok.any() else float("nan")
            for lk, W in Wmaps.items():
                row["true_" + lk] = rel(np.einsum("ti,ti->t", W, e_true), wy[lk])
                row["est_" + lk] = rel(np.einsum("ti,ti->t", W, e_est), wy[lk])
            if var == "hermite5":
                A = nodal_accelerations(sol, M, C, K, Q)
                d = defect(M, C, K, Q, *(hermite_eval(sol.U, sol.V, A, T, stage_points(n), k) for k in range(3)))
                kept = KeptFactors(M, C, K, T, n)
                ts = time.perf_counter()
                Uk, _Vk, SUk, _SVk = kept.resolve(Q + d)
                row["t_kept"] = time.perf_counter() - ts
                nb = co.solve(M, C, K, Q + d, T, SCHEME, workers=1)
                row["kept_check"] = max(rel(Uk - nb.U, nb.U), rel(SUk - nb.stage_U, nb.stage_U))
                row["t_build"], row["t_inv"], row["t_bsolve"] = kept.t_build, kept.t_inverse, kept.t_solve
            rows.append(row)
    print_table(case, rows, variants)
    return rows


def _r(est, true):
    return est / true if true > 0 else float("nan")


def print_table(case, rows, variants):
    links = case.links
    for var in variants:
        print(f"\n{var}: relative max errors on {N_OUT} output instants (true | estimate | est/true)")
        hdr = f"{'n':>4} | {'all DOFs true':>13} {'est':>8} {'ratio':>6} | {'nodes true':>10} {'est':>8} {'ratio':>6}"
        for lk in links:
            hdr += f" | {lk + ' true':>13} {'est':>8} {'ratio':>6}"
        hdr += " | axial DOFs: worst true, ratios"
        print(hdr)
        for r in (r for r in rows if r["var"] == var):
            line = (f"{r['n']:>4} | {r['true']:13.2e} {r['est']:8.2e} {_r(r['est'], r['true']):6.2f} | "
                    f"{r['ntrue']:10.2e} {r['nest']:8.2e} {_r(r['nest'], r['ntrue']):6.2f}")
            for lk in links:
                t, e = r["true_" + lk], r["est_" + lk]
                line += f" | {t:13.2e} {e:8.2e} {_r(e, t):6.2f}"
            line += f" | {r['ax_true']:.1e}, {r['ax_lo']:.2f}..{r['ax_hi']:.2f}"
            print(line)
    if "hermite5" not in variants:
        return
    print("\ncost [ms] (hermite5): kinematics+assembly | main solve | second solve (full, x main) | "
          "interpolant+defect+read | re-solve with kept operators (x main; check) | building them "
          "| batched inverse of W vs the solver's batched solve")
    for r in (r for r in rows if r["var"] == "hermite5"):
        print(f"{r['n']:>4} | {r['t_asm'] * 1e3:7.1f} | {r['t_main'] * 1e3:7.1f} | {r['t_second'] * 1e3:7.1f} "
              f"({r['t_second'] / r['t_main']:.2f}x) | {r['t_rest'] * 1e3:5.1f} | {r['t_kept'] * 1e3:6.1f} "
              f"({r['t_kept'] / r['t_main']:.2f}x; {r['kept_check']:.0e}) | {r['t_build'] * 1e3:6.1f} | "
              f"{r['t_inv'] * 1e3:6.1f} vs {r['t_bsolve'] * 1e3:6.1f}")


def scan_speeds(speeds, n=96):
    """Peak mid-span deflection of the slider-crank rod (0.5 % damping) over crank speeds."""
    print("speed [rad/s] | peak rod deflection rel. chord [mm] | peak / (speed/150)^2 | rho")
    for w in speeds:
        case = Case("", slider_crank.build(elements=8, speed=w), ("rod",), kf.ModalDamping(0.005))
        sol = co.solve(*case.system(SCHEME, n), case.T, SCHEME, workers=1)
        u, _ = sol.at(case.t_out)
        pk = np.abs(np.einsum("ti,ti->t", case.deflection_maps()["rod"], u)).max()
        print(f"{w:8.1f} | {pk * 1e3:9.4f} | {pk * 1e3 / (w / 150) ** 2:9.4f} | {sol.spectral_radius:.4f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="levels 12..96, reference on 768 elements")
    ap.add_argument("--cases", default="sc2,sc05,fb,sb,res,res2")
    ap.add_argument("--variants", default="hermite5,hermite5+1,hermite5+2,local7")
    ap.add_argument("--scan", default="", help="comma-separated crank speeds: scan the peak deflection only")
    ap.add_argument("--speed", type=float, default=RES_SPEED, help="crank speed of the hard case")
    ap.add_argument("--levels", default="", help="comma-separated element counts (divisors of --nref)")
    ap.add_argument("--nref", type=int, default=0, help="elements of the reference")
    a = ap.parse_args(argv)
    if a.scan:
        scan_speeds([float(x) for x in a.scan.split(",")])
        return
    levels = tuple(int(x) for x in a.levels.split(",")) if a.levels else (LEVELS[:4] if a.quick else LEVELS)
    n_ref = a.nref or (768 if a.quick else N_REF)
    if any(n_ref % n for n in levels):
        ap.error(f"every level must divide the reference's {n_ref} elements")
    cases = make_cases(a.speed)
    t0 = time.perf_counter()
    for key in a.cases.split(","):
        probe_case(cases[key](), levels, n_ref, tuple(a.variants.split(",")))
        print(f"[{time.perf_counter() - t0:.0f} s]")


if __name__ == "__main__":
    main()
