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
* ``nodes``: the same all-DOF norm at the element ends only (superconvergent, O(h^5)).

"ratio" is est / true; the target for an honest estimate is 1/3 .. 10 wherever the true error
is below 1e-2.

Cost: the time of the main solve (``collocation.solve``), of the estimate as prototyped (a full
second solve plus interpolation and defect), and of a re-solve of the neighbouring problem with
the factorisations of the main solve kept (per-element LU of the stage matrices W_k, the
transitions P_k and the LU of I - Phi: only back-substitutions and two matrix-vector sweeps),
implemented here in ``KeptFactors`` and checked against the full re-solve.

Variant "local7": instead of the quintic Hermite, P on each element is the degree-7 polynomial
through u at the element's 4 points (start + 3 stages) and the 4 points of the next element
(stage values of neighbouring elements), differentiated analytically (C0 only at the ends).

Run (single-threaded, about 1-2 minutes on the shared 2-core machine)::

    cd /work/main && . .venv/bin/activate
    OPENBLAS_NUM_THREADS=1 python benchmarks/defect_probe.py [--quick] [--cases sc2,sc05,fb,sb,res]
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
#: crank speed of the hard case [rad/s]: picked by --scan (see the final report)
RES_SPEED = None  # set below after the scan


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
    x = np.mod(t, T) * (n / T)
    k = np.minimum(np.floor(x).astype(int), n - 1)
    return k, x - k


def nodal_accelerations(sol, M, C, K, Q):
    """a_k at the element starts from the equation of motion at the end stage of element k-1."""
    n = sol.n
    idx = (np.arange(n) - 1) % n * 3 + 2  # end stage of the element before (c_3 = 1)
    rhs = Q[idx] - np.einsum("kij,kj->ki", C[idx], sol.V) - np.einsum("kij,kj->ki", K[idx], sol.U)
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
    """The main solve's factorisations kept, for a re-solve with another load only.

    Built from the same data as ``collocation.solve`` (per-element LU of the stage matrix W_k,
    X_R = W_k^-1 (-R_k), the transitions P_k, the LU of I - Phi); ``resolve(Q)`` then costs
    back-substitutions and matrix-vector sweeps. Only the time of ``resolve`` is reported.
    """

    def __init__(self, M, C, K, T, n):
        tab = co.tableau(SCHEME)
        self.tab, self.n, self.N, self.h = tab, n, M.shape[1], T / n
        s, N, h = tab.s, self.N, self.h
        Ms, Cs, Ks = (X.reshape(n, s, N, N) for X in (M, C, K))
        Is = np.eye(s)
        self.lu = []
        self.P = np.empty((n, 2 * N, 2 * N))
        for k in range(n):
            W = (Is[:, None, :, None] * Ms[k][:, :, None, :] + h * tab.A[:, None, :, None] * Cs[k][:, :, None, :]
                 + h * h * tab.A2[:, None, :, None] * Ks[k][:, :, None, :]).reshape(s * N, s * N)
            lu = sla.lu_factor(W)
            negR = -np.concatenate([Ks[k], Cs[k] + h * tab.c[:, None, None] * Ks[k]], axis=2).reshape(s * N, 2 * N)
            XR = sla.lu_solve(lu, negR).reshape(s, N, 2 * N)
            self.lu.append(lu)
            Pk = np.eye(2 * N)
            Pk[:N, N:] += h * np.eye(N)
            Pk[:N] += h * h * np.einsum("j,jnk->nk", tab.bA, XR)
            Pk[N:] += h * np.einsum("j,jnk->nk", tab.b, XR)
            self.P[k] = Pk
        Phi = np.eye(2 * N)
        for k in range(n):
            Phi = self.P[k] @ Phi
        self.lu_cyc = sla.lu_factor(np.eye(2 * N) - Phi)

    def resolve(self, Q):
        """Element-start states U, V (n, N) of the periodic solve with load Q (n s, N)."""
        tab, n, N, h, s = self.tab, self.n, self.N, self.h, self.tab.s
        Qs = Q.reshape(n, s * N)
        p = np.empty((n, 2 * N))
        for k in range(n):
            aq = sla.lu_solve(self.lu[k], Qs[k], check_finite=False).reshape(s, N)
            p[k, :N] = h * h * (tab.bA @ aq)
            p[k, N:] = h * (tab.b @ aq)
        r = np.zeros(2 * N)
        for k in range(n):
            r = self.P[k] @ r + p[k]
        Z = np.empty((n, 2 * N))
        Z[0] = sla.lu_solve(self.lu_cyc, r, check_finite=False)
        for k in range(n - 1):
            Z[k + 1] = self.P[k] @ Z[k] + p[k]
        return Z[:, :N], Z[:, N:]


# ----------------------------------------------------------------------------- the probe
def rel(e, y):
    return float(np.abs(e).max() / np.abs(y).max())


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
          + f"; peak deflection " + ", ".join(f"{lk} {np.abs(w).max() * 1e3:.3f} mm" for lk, w in wy.items())
          + f"  [{time.perf_counter() - t0:.1f} s]")
    yn_all = {}  # reference at the nodes of each level
    rows = []
    for n in levels:
        ts = time.perf_counter()
        M, C, K, Q = case.system(SCHEME, n)
        t_asm = time.perf_counter() - ts
        ts = time.perf_counter()
        sol = co.solve(M, C, K, Q, T, SCHEME, workers=1)
        t_main = time.perf_counter() - ts
        u, _ = sol.at(t_out)
        e_true = u - y
        step = n_ref // n
        yn = ref.U[::step]
        e_true_nodes = sol.U - yn
        for var in variants:
            te = time.perf_counter()
            ti = stage_points(n)
            if var == "hermite5":
                A = nodal_accelerations(sol, M, C, K, Q)
                P0, P1, P2 = (hermite_eval(sol.U, sol.V, A, T, ti, d) for d in range(3))
            else:
                P0, P1, P2 = (local7_eval(sol, T, ti, d) for d in range(3))
            d = (np.einsum("kij,kj->ki", M, P2) + np.einsum("kij,kj->ki", C, P1)
                 + np.einsum("kij,kj->ki", K, P0) - Q)
            t_interp = time.perf_counter() - te
            ts = time.perf_counter()
            nb = co.solve(M, C, K, Q + d, T, SCHEME, workers=1)
            t_second = time.perf_counter() - ts
            te = time.perf_counter()
            ut, _ = nb.at(t_out)
            wo = locate(t_out, n, T)
            Pout = hermite_eval(sol.U, sol.V, A, T, wo) if var == "hermite5" else local7_eval(sol, T, wo)
            e_est = ut - Pout
            Pn = sol.U if var == "hermite5" else local7_eval(sol, T, locate(sol.t, n, T))
            e_est_nodes = nb.U - Pn
            t_interp += time.perf_counter() - te
            row = dict(n=n, var=var, true=rel(e_true, y), est=rel(e_est, y),
                       ntrue=rel(e_true_nodes, yn), nest=rel(e_est_nodes, yn),
                       t_main=t_main, t_asm=t_asm, t_second=t_second, t_interp=t_interp, d=rel(d, Q))
            for lk, W in Wmaps.items():
                row["true_" + lk] = rel(np.einsum("ti,ti->t", W, e_true), wy[lk])
                row["est_" + lk] = rel(np.einsum("ti,ti->t", W, e_est), wy[lk])
            if var == variants[0]:
                kept = KeptFactors(M, C, K, T, n)
                ts = time.perf_counter()
                Uk, _Vk = kept.resolve(Q + d)
                row["t_kept"] = time.perf_counter() - ts
                row["kept_check"] = rel(Uk - nb.U, nb.U)
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
        print(hdr)
        for r in (r for r in rows if r["var"] == var):
            line = (f"{r['n']:>4} | {r['true']:13.2e} {r['est']:8.2e} {_r(r['est'], r['true']):6.2f} | "
                    f"{r['ntrue']:10.2e} {r['nest']:8.2e} {_r(r['nest'], r['ntrue']):6.2f}")
            for lk in links:
                t, e = r["true_" + lk], r["est_" + lk]
                line += f" | {t:13.2e} {e:8.2e} {_r(e, t):6.2f}"
            print(line)
    print(f"\ncost [ms]: kinematics+assembly | main solve | second solve (full) | interpolant+defect+read | "
          f"kept-factor re-solve (check vs full)")
    for r in (r for r in rows if r["var"] == variants[0]):
        print(f"{r['n']:>4} | {r['t_asm'] * 1e3:8.1f} | {r['t_main'] * 1e3:8.1f} | {r['t_second'] * 1e3:8.1f} ({r['t_second'] / r['t_main']:.2f}x) | "
              f"{r['t_interp'] * 1e3:6.1f} | {r['t_kept'] * 1e3:7.1f} ({r['t_kept'] / r['t_main']:.2f}x, "
              f"{r['kept_check']:.0e})")


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
    ap.add_argument("--cases", default="sc2,sc05,fb,sb,res")
    ap.add_argument("--variants", default="hermite5,local7")
    ap.add_argument("--scan", default="", help="comma-separated crank speeds: scan the peak deflection only")
    ap.add_argument("--speed", type=float, default=RES_SPEED_DEFAULT, help="crank speed of the hard case")
    a = ap.parse_args(argv)
    if a.scan:
        scan_speeds([float(x) for x in a.scan.split(",")])
        return
    levels = LEVELS[:4] if a.quick else LEVELS
    n_ref = 768 if a.quick else N_REF
    cases = make_cases(a.speed)
    t0 = time.perf_counter()
    for key in a.cases.split(","):
        probe_case(cases[key](), levels, n_ref, tuple(a.variants.split(",")))
        print(f"[{time.perf_counter() - t0:.0f} s]")


RES_SPEED_DEFAULT = 410.5

if __name__ == "__main__":
    main()
