#!/usr/bin/env python
"""kedfem against an independent, geometrically exact reference (ANCF cables, index-3 DAE).

For each mechanism the exact model (``benchmarks/exact``) is marched cycle by
cycle to its periodic steady state on three meshes and three time steps; the
reference histories are Richardson-extrapolated in both (orders 4 and 2, the
observed orders are reported) and given an uncertainty. kedfem is solved
with its effects ``inertia + coupling + axial_stiffening`` and with
``geometric_nonlinearity`` added, and read at the same crank angles. The same
is repeated with the damping coefficient at 0.2x (sensitivity to the
damping model: kedfem's Rayleigh damping acts on its own DOFs, the exact
model's on the strain rates).

Usage::

    python benchmarks/exact_comparison.py            # full (about 15-20 min on 2 cores)
    python benchmarks/exact_comparison.py --quick    # coarse levels, under 2 min
    python benchmarks/exact_comparison.py --cases four_bar,slider_crank

Writes ``benchmarks/results/exact_comparison.md`` and ``.csv`` (``--quick``:
``exact_comparison_quick.*``).
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import time
import warnings

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
for _p in (ROOT, HERE):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import numpy as np  # noqa: E402

import kedfem as kf  # noqa: E402
import mechanisms  # noqa: E402
import exact as ex  # noqa: E402

EFFECT_SETS = {
    "I+C+A": ("inertia", "coupling", "axial_stiffening"),
    "I+C+A+GN": ("inertia", "coupling", "axial_stiffening", "geometric_nonlinearity"),
}

#: case -> mechanism, Rayleigh beta [s] (about 2 % on the first mode), quantities
CASES = {
    "four_bar": dict(beta=1.3708e-4, note="crank, coupler, follower flexible; crank clamped to its drive"),
    "slider_crank": dict(beta=3.0e-5, note="rigid crank, flexible rod, slider mass"),
    "six_bar": dict(beta=6.6e-5, note="two loops, rigid bellcrank body; crank clamped to its drive"),
}

LEVELS = {
    # meshes (elements per link), steps per cycle; the time study runs on meshes[1],
    # the mesh study on steps[1]; low-damping runs on meshes[0] with low_steps
    "full": dict(meshes=(8, 16, 32), steps=(720, 1440, 2880), low_steps=(720, 1440, 2880), tol=1e-7, tol_low=1e-6,
                 ked_elements=8, ked_rtol=1e-5, cases=("four_bar", "slider_crank", "six_bar")),
    "quick": dict(meshes=(2, 4, 8), steps=(180, 360, 720), low_steps=(180, 360), tol=1e-6, tol_low=1e-5,
                  ked_elements=4, ked_rtol=1e-4, cases=("four_bar", "slider_crank")),
}

P_TIME, P_MESH = 2.0, 4.0


# ------------------------------------------------------------------ helpers
def log(msg):
    print(msg, flush=True)


def refined_peak(h):
    """Largest |h| of a periodic sampled history, refined by a parabola through the 3 samples around it."""
    a = np.abs(h)
    k = int(np.argmax(a))
    y0, y1, y2 = a[k - 1], a[k], a[(k + 1) % a.size]
    den = y0 - 2 * y1 + y2
    if den >= 0:
        return float(y1)
    x = 0.5 * (y0 - y2) / den
    return float(y1 - 0.25 * (y0 - y2) * x)


def quantities(mech):
    q = [lk.name for lk in mech.flexible_links]
    d = mech.drives[0]
    if d.member in mech.links and not mech.links[d.member].rigid:
        q.append("tip")
    return q


def sub(h, n_from, n_to):
    """Subsample a history of n_from samples onto n_to samples (n_from a multiple of n_to)."""
    s = n_from // n_to
    assert s * n_to == n_from
    return h[::s]


def kedfem_history(res, mech, quantity):
    if quantity == "tip":
        return res.deflection(mech.drives[0].member, 1.0, relative_to="frame")
    return res.deflection(quantity, 0.5, relative_to="chord")


def kedfem_axial_mid(res, link):
    N = res.axial_force(link)
    ne = N.shape[1]
    if ne % 2:
        return N[:, ne // 2]
    return 0.5 * (N[:, ne // 2 - 1] + N[:, ne // 2])


# ------------------------------------------------------------------ exact runs
class Runs:
    def __init__(self, name, mech_builder, beta, tol, records):
        self.name = name
        self.build = mech_builder
        self.beta = beta
        self.tol = tol
        self.runs = {}
        self.records = records

    def run(self, ne, n, init=None, beta=None, tol=None, tag="", cycles_max=80):
        beta = self.beta if beta is None else beta
        tol = self.tol if tol is None else tol
        key = (ne, n, beta)
        if key in self.runs:
            return self.runs[key]
        mech = self.build()
        r = ex.simulate(mech, elements_per_link=ne, steps_per_cycle=n, beta=beta, tol=tol, init=init,
                        cycles_max=cycles_max)
        self.runs[key] = r
        self.records.append(dict(case=self.name, tag=tag, elements=ne, steps=n, beta=beta, ndof=r.ndof,
                                 ncon=r.ncon, cycles=r.cycles, converged=r.converged,
                                 last_change=r.changes[-1] if r.changes else float("nan"),
                                 newton=r.newton_per_step, max_g=r.max_constraint, wall=r.wall_time))
        log(f"  exact {self.name} {tag:>5} ne={ne:3d} steps={n:5d} beta={beta:.3e}: {r.cycles:2d} cycles "
            f"(change {r.changes[-1] if r.changes else float('nan'):.1e}, converged {r.converged}), "
            f"{r.wall_time:6.1f} s, ndof {r.ndof}, |g| {r.max_constraint:.1e}")
        return r


def richardson(fine, coarse, p):
    return fine + (fine - coarse) / (2.0**p - 1.0)


def build_reference(R: Runs, lv, qs):
    """Reference histories on the steps[1] grid, observed orders and uncertainties."""
    m0, m1, m2 = lv["meshes"]
    s0, s1, s2 = lv["steps"]
    # warm-start chain: cheapest cold start, then neighbours
    a = R.run(m0, s0, tag="start")
    b = R.run(m1, s0, init=a, tag="time")
    c = R.run(m1, s1, init=b, tag="time")
    d = R.run(m0, s1, init=c, tag="mesh")
    e = R.run(m2, s1, init=c, tag="mesh")
    f = R.run(m1, s2, init=c, tag="time")
    ref, info = {}, {}
    for qn in qs:
        h_t0, h_t1, h_t2 = b.history(qn), c.history(qn), f.history(qn)
        # time study on the s0 grid
        d01 = np.max(np.abs(h_t0 - sub(h_t1, s1, s0)))
        d12 = np.max(np.abs(sub(h_t1, s1, s0) - sub(h_t2, s2, s0)))
        p_t = math.log2(d01 / d12) if d12 > 0 and d01 > 0 else float("nan")
        # mesh study on the s1 grid
        hm0, hm1, hm2 = d.history(qn), c.history(qn), e.history(qn)
        e01 = np.max(np.abs(hm0 - hm1))
        e12 = np.max(np.abs(hm1 - hm2))
        p_m = math.log2(e01 / e12) if e12 > 0 and e01 > 0 else float("nan")
        # reference: time-extrapolated (m1, s1 -> s2), plus the mesh correction (m1 -> m2, extrapolated)
        Rt = richardson(sub(h_t2, s2, s1), h_t1, P_TIME)
        corr_m = (hm2 - hm1) * (2**P_MESH / (2**P_MESH - 1))
        href = Rt + corr_m
        # uncertainty: the two time extrapolations (s0,s1) and (s1,s2) compared on the s0 grid,
        # the remaining mesh error (one more level of the observed change), the steady-state tolerance
        Rt_coarse = richardson(sub(h_t1, s1, s0), h_t0, P_TIME)
        u_t = np.max(np.abs(sub(Rt, s1, s0) - Rt_coarse))
        u_m = e12 / (2**P_MESH - 1)
        peak = refined_peak(href)
        u_ss = 2 * R.tol * peak
        ref[qn] = href
        info[qn] = dict(
            peak=peak, u=(u_t + u_m + u_ss), u_t=u_t, u_m=u_m, p_t=p_t, p_m=p_m,
            d01=d01, d12=d12, e01=e01, e12=e12,
            peaks_time=[refined_peak(h) for h in (h_t0, h_t1, h_t2)],
            peaks_mesh=[refined_peak(h) for h in (hm0, hm1, hm2)],
            peak_finest=refined_peak(h_t2),
        )
    axial = {lk: f.axial[lk] for lk in f.axial}
    return c.crank_angle, ref, info, axial, f


def build_low_reference(R: Runs, lv, qs, beta, init, full_info):
    """Low-damping reference on meshes[0]: time-Richardson of the last two of ``low_steps``.

    With three levels the uncertainty is the difference of the two extrapolations (on the
    coarsest grid); with two, the change between the levels / 3 (the error of the finer one).
    The mesh error of meshes[0] is taken from the full-damping mesh study (its change to
    meshes[1]), plus the steady-state tolerance.
    """
    m0 = lv["meshes"][0]
    steps = lv["low_steps"]
    tol = lv["tol_low"]
    runs = []
    prev = init
    for n in steps:
        prev = R.run(m0, n, beta=beta, tol=tol, init=prev, tag="low", cycles_max=150)
        runs.append(prev)
    ref, info = {}, {}
    sa, sb = steps[-2], steps[-1]
    for qn in qs:
        ha, hb = runs[-2].history(qn), runs[-1].history(qn)
        href = richardson(sub(hb, sb, sa), ha, P_TIME)
        peak = refined_peak(href)
        if len(steps) == 3:
            s0 = steps[0]
            h0 = runs[0].history(qn)
            r_coarse = richardson(sub(ha, sa, s0), h0, P_TIME)
            u_t = np.max(np.abs(sub(href, sa, s0) - r_coarse))
        else:
            u_t = np.max(np.abs(ha - sub(hb, sb, sa))) / 3
        u_m = full_info[qn]["e01"]
        ref[qn] = href
        info[qn] = dict(peak=peak, u=u_t + u_m + 2 * tol * peak, u_t=u_t, u_m=u_m,
                        converged=all(r.converged for r in runs))
    return runs[-2].crank_angle, ref, info


# ------------------------------------------------------------------ kedfem runs
def kedfem_solve(mech, effects, beta, rtol, records, case, tag):
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(kf.Scene(mech, effects=effects, damping=kf.Rayleigh(beta=beta), rtol=rtol))
    wall = time.perf_counter() - t0
    est = getattr(res.error, "peak", float("nan"))
    records.append(dict(case=case, tag=tag, effects="+".join(effects), elements=mech.flexible_links[0].elements,
                        rtol=rtol, n=res.n, wall=wall, error_peak=est))
    log(f"  kedfem {case} {tag} {'+'.join(e[:4] for e in effects)}: {res.n} time elements, {wall:.1f} s")
    return res


def compare(ca, ref, res, mech, qs):
    rs = res.resample(crank_angle=ca)
    out = {}
    for qn in qs:
        hk = kedfem_history(rs, mech, qn)
        hr = ref[qn]
        pk, pr = refined_peak(hk), refined_peak(hr)
        out[qn] = dict(ked_peak=pk, ref_peak=pr, dpeak=100 * (pk - pr) / pr,
                       dmax=100 * np.max(np.abs(hk - hr)) / pr,
                       drms=100 * np.sqrt(np.mean((hk - hr) ** 2)) / np.sqrt(np.mean(hr**2)))
    return out, rs


def _failed(qs):
    nan = float("nan")
    return {q: dict(ked_peak=nan, ref_peak=nan, dpeak=nan, dmax=nan, drms=nan) for q in qs}


def kedfem_version():
    """kedfem's git commit (``+dirty`` with uncommitted changes under kedfem/), or its version."""
    import subprocess
    try:
        h = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                           timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", ROOT, "status", "--porcelain", "--", "kedfem"], capture_output=True,
                               text=True, timeout=10).stdout.strip()
        if h:
            return h + ("+dirty (uncommitted changes in kedfem/)" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        pass
    return getattr(kf, "__version__", "unknown")


# ------------------------------------------------------------------ diagnostics
def four_bar_variants():
    """Variants of the four-bar that isolate the source of the kedfem - reference differences.

    ``thickness xk``: sections k x thicker (A x k, EI x k^3), joint masses x k, speed x k and
    beta / k: the linearised problem is nearly invariant (loads / bending stiffness, frequency
    ratios, N / buckling load and the damping ratios are kept; the axial stiffness relative to the
    loads drops by k^2), the deflections stay about the same, so deflection / thickness, the
    measure of the geometric nonlinearity, drops by k.
    """
    D = mechanisms.get("four_bar").DEFAULTS
    out = [("as built", {}, 1.0), ("half speed (100 rpm)", dict(speed=D["speed"] / 2), 1.0),
           ("rigid crank", dict(flexible_crank=False), 1.0), ("no joint masses", dict(joint_mass=0.0), 1.0)]
    for k in (2.0, 4.0):
        out.append((f"thickness x{k:g}", dict(crank_A=D["crank_A"] * k, crank_EI=D["crank_EI"] * k**3,
                                               link_A=D["link_A"] * k, link_EI=D["link_EI"] * k**3,
                                               joint_mass=D["joint_mass"] * k, speed=D["speed"] * k), 1 / k))
    return out


def diagnostics(lv, exact_rec, ked_rec):
    beta0 = CASES["four_bar"]["beta"]
    m0 = lv["meshes"][0]
    s0, s1 = lv["steps"][:2]
    rows = []
    for label, kw, bscale in four_bar_variants():
        beta = beta0 * bscale

        def builder(kw=kw):
            return mechanisms.build("four_bar", **kw)
        mech = builder()
        qs = quantities(mech)
        R = Runs("four_bar " + label, builder, beta, lv["tol"], exact_rec)
        a = R.run(m0, s0, tag="diag")
        b = R.run(m0, s1, init=a, tag="diag")
        km = mechanisms.build("four_bar", elements=lv["ked_elements"], **kw)
        for tag, eff in EFFECT_SETS.items():
            try:
                res = kedfem_solve(km, eff, beta, lv["ked_rtol"], ked_rec, "four_bar " + label, "diag")
                rs = res.resample(crank_angle=a.crank_angle)
            except Exception as exc:
                log(f"  kedfem diag {label} {tag} FAILED: {exc!r}")
                rs = None
            for qn in qs:
                href = richardson(sub(b.history(qn), s1, s0), a.history(qn), P_TIME)
                pr = refined_peak(href)
                if rs is None:
                    rows.append((label, tag, qn, pr, float("nan"), float("nan")))
                    continue
                hk = kedfem_history(rs, km, qn)
                rows.append((label, tag, qn, pr, 100 * (refined_peak(hk) - pr) / pr,
                             100 * np.max(np.abs(hk - href)) / pr))
    return rows


# ------------------------------------------------------------------ validation
def validation():
    """The quick validations of the exact model (also in tests/test_exact_reference.py)."""
    rows = []
    for bc in (("clamp", "free"), ("pin", "pin")):
        for ne in (2, 4, 8, 16):
            m = ex.beam(ne, L=1.0, EA=1e7, EI=1.0, rhoA=1.0, bc=bc)
            w, phi = ex.modal(m, n_modes=m.ndof)
            yd = np.zeros(m.ndof, bool)
            yd[1::2] = True
            bend = [wi for wi, ph in zip(w, phi.T) if np.linalg.norm(ph[yd]) > 0.99 * np.linalg.norm(ph)]
            ref = np.array(ex.EB_ROOTS[bc][:2]) ** 2
            err = np.array(bend[:2]) / ref - 1
            rows.append(("modal", f"{bc[0]}-{bc[1]}", ne, err[0], err[1]))
    stat = []
    for EA in (1e4, 1e7):
        for ne in (4, 8, 16, 32):
            m = ex.beam(ne, L=1.0, EA=EA, EI=1.0, rhoA=1.0, bc=("clamp", "free"))
            M0 = math.pi / 2
            q, _ = ex.static(m, ex.analysis.tip_moment_load(m, "beam", M0), nsteps=8)
            tip = q[m.pdofs["b"]]
            stat.append((EA, ne, float(np.max(np.abs(tip - ex.analysis.arc_tip(M0, EA, 1.0, 1.0))))))
    rot = []
    table = {0: 3.5160, 1: 3.5432, 2: 3.6218, 3: 3.7435, 4: 3.8977, 5: 4.0739}
    m = ex.beam(16, L=1.0, EA=1e8, EI=1.0, rhoA=1.0, bc=("clamp", "free"))
    for g, lam in table.items():
        p, f = ex.rotating_modal(m, float(g))
        s = np.linspace(0, 1.0, 21)
        eps, _ = m.link_strain(p[None], "beam", s)
        N = 1e8 * eps[0]
        Nex = g**2 * (1 - s**2) / 2
        rot.append((g, f[0], lam, np.max(np.abs(N - Nex)) / max(g**2 / 2, 1e-300) if g else np.max(np.abs(N))))
    return rows, stat, rot


# ------------------------------------------------------------------ report
def fmt(x, d=4):
    return f"{x:.{d}f}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="coarse levels (under 2 min)")
    ap.add_argument("--cases", default=None, help="comma-separated subset of " + ", ".join(CASES))
    ap.add_argument("--no-low", action="store_true", help="skip the 0.2x damping runs")
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    ap.add_argument("--diagnostics", action="store_true",
                    help="also run four-bar variants (speed, rigid crank, joint masses, thickness) that "
                         "locate the source of the differences (about 4 min)")
    ap.add_argument("--histories", default=None, metavar="CSV",
                    help="also write the reference histories (long format) to this file")
    args = ap.parse_args(argv)
    mode = "quick" if args.quick else "full"
    lv = LEVELS[mode]
    cases = args.cases.split(",") if args.cases else list(lv["cases"])
    t_all = time.perf_counter()
    ked_version = kedfem_version()
    exact_rec, ked_rec = [], []
    report = {}
    csv_rows = []
    log(f"exact_comparison ({mode}): cases {', '.join(cases)}")
    t0 = time.perf_counter()
    val = validation()
    t_val = time.perf_counter() - t0
    log(f"  validation: {t_val:.1f} s")
    for case in cases:
        cfg = CASES[case]
        beta = cfg["beta"]

        def builder(case=case):
            return mechanisms.build(case)

        mech = builder()
        qs = quantities(mech)
        R = Runs(case, builder, beta, lv["tol"], exact_rec)
        log(f"{case}: reference (beta = {beta:.4e} s)")
        ca, ref, info, axial, finest = build_reference(R, lv, qs)
        kmech = mechanisms.build(case, elements=lv["ked_elements"])
        comps, ked_axial = {}, {}
        for tag, eff in EFFECT_SETS.items():
            try:
                res = kedfem_solve(kmech, eff, beta, lv["ked_rtol"], ked_rec, case, "1x")
                comps[tag], rs = compare(ca, ref, res, kmech, qs)
                rs_f = res.resample(crank_angle=finest.crank_angle)
                ked_axial[tag] = {lk: kedfem_axial_mid(rs_f, lk) for lk in axial}
            except Exception as exc:          # report it and go on with the other solves
                log(f"  kedfem {case} 1x {tag} FAILED: {exc!r}")
                comps[tag] = _failed(qs)
                ked_axial[tag] = {lk: np.full_like(axial[lk], np.nan) for lk in axial}
        low = None
        if not args.no_low:
            bl = 0.2 * beta
            log(f"{case}: low damping (beta = {bl:.4e} s)")
            init = R.runs[(lv["meshes"][0], lv["steps"][0], beta)]
            ca_l, ref_l, info_l = build_low_reference(R, lv, qs, bl, init, info)
            comps_l = {}
            for tag, eff in EFFECT_SETS.items():
                try:
                    res = kedfem_solve(kmech, eff, bl, lv["ked_rtol"], ked_rec, case, "0.2x")
                    comps_l[tag], _ = compare(ca_l, ref_l, res, kmech, qs)
                except Exception as exc:
                    log(f"  kedfem {case} 0.2x {tag} FAILED: {exc!r}")
                    comps_l[tag] = _failed(qs)
            low = (ca_l, ref_l, info_l, comps_l)
        report[case] = dict(qs=qs, info=info, comps=comps, axial=axial, ked_axial=ked_axial, low=low,
                            beta=beta, note=cfg["note"], finest=finest, ca=ca, ref=ref)
        for tag in EFFECT_SETS:
            for qn in qs:
                c = comps[tag][qn]
                csv_rows.append(dict(case=case, damping="1x", beta=beta, effects=tag, quantity=qn,
                                     ref_peak_mm=1e3 * info[qn]["peak"], ref_u_pct=100 * info[qn]["u"] / info[qn]["peak"],
                                     kedfem_peak_mm=1e3 * c["ked_peak"], dpeak_pct=c["dpeak"], dmax_pct=c["dmax"],
                                     drms_pct=c["drms"]))
                if low is not None:
                    c = low[3][tag][qn]
                    il = low[2][qn]
                    csv_rows.append(dict(case=case, damping="0.2x", beta=0.2 * beta, effects=tag, quantity=qn,
                                         ref_peak_mm=1e3 * il["peak"], ref_u_pct=100 * il["u"] / il["peak"],
                                         kedfem_peak_mm=1e3 * c["ked_peak"], dpeak_pct=c["dpeak"],
                                         dmax_pct=c["dmax"], drms_pct=c["drms"]))
    diag = None
    if args.diagnostics:
        log("four_bar variants (diagnostics)")
        diag = diagnostics(lv, exact_rec, ked_rec)
    wall = time.perf_counter() - t_all
    os.makedirs(args.out, exist_ok=True)
    stem = "exact_comparison" + ("_quick" if args.quick else "")
    with open(os.path.join(args.out, stem + ".csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(csv_rows[0]))
        w.writeheader()
        for r in csv_rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    if args.histories:
        with open(args.histories, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["case", "damping", "beta", "crank_angle_rad", "quantity", "reference_m", "u_m"])
            for case, R in report.items():
                sets = [("1x", R["beta"], R["ca"], R["ref"], R["info"])]
                if R["low"] is not None:
                    sets.append(("0.2x", 0.2 * R["beta"], R["low"][0], R["low"][1], R["low"][2]))
                for tag, b, ca_, ref_, inf_ in sets:
                    for qn in R["qs"]:
                        for a_, v_ in zip(ca_, ref_[qn]):
                            w.writerow([case, tag, f"{b:.6g}", f"{a_:.10g}", qn, f"{v_:.10e}", f"{inf_[qn]['u']:.2e}"])
    md = render(mode, lv, report, val, t_val, exact_rec, ked_rec, wall, ked_version, diag)
    with open(os.path.join(args.out, stem + ".md"), "w") as fh:
        fh.write(md)
    log(f"wrote {os.path.join(args.out, stem)}.md/.csv in {wall:.0f} s")


def render(mode, lv, report, val, t_val, exact_rec, ked_rec, wall, ked_version, diag=None):
    L = []
    L.append("# kedfem against a geometrically exact reference (ANCF cables)\n")
    L.append(f"Generated by `python benchmarks/exact_comparison.py{' --quick' if mode == 'quick' else ''}` "
             f"({mode} levels, {wall:.0f} s on this machine). Reference model: `benchmarks/exact/` "
             "(independent of kedfem's formulation; kedfem is only used to read the mechanism and for the "
             "rigid-body state at t = 0).\n")
    L.append("**Reference model.** Planar ANCF cable elements (position and slope vector per node, cubic "
             "Hermite in the reference arc length), exact strains `eps = |r'| - 1`, "
             "`kappa = r' x r'' / |r'|^3`, energy `1/2 int (EA eps^2 + EI kappa^2) ds` by 5-point Gauss "
             "with the exact tangent; constant consistent mass. Damping `beta int (EA eps_dot deps + "
             "EI kappa_dot dkappa) ds` (objective: no damping of rigid-body motion). Joints: shared joint "
             "points (revolute), fixed points (ground pivots), slider lines, the driven crank's root slope "
             "turning at the drive speed (`-sin th x' + cos th y' = 0`), rigid bodies `(X, Y, phi)` pinned "
             "to joint points; Lagrange multipliers (index 3). Generalised-alpha (Arnold & Bruls 2007), "
             "rho_inf = 0.9, fixed step, Newton with a SuperLU-factorised saddle-point matrix; started "
             "from the rigid-body motion and marched cycle by cycle until every tracked history changes "
             f"by less than {lv['tol']:.0e} of its peak over one cycle.\n")
    L.append(f"**Levels.** Elements per link {lv['meshes']}, steps per cycle {lv['steps']}: the time study "
             f"runs on {lv['meshes'][1]} elements, the mesh study on {lv['steps'][1]} steps. Reference "
             f"history = time-Richardson ({lv['steps'][1]} -> {lv['steps'][2]}, order 2) plus the mesh "
             f"correction ({lv['meshes'][1]} -> {lv['meshes'][2]}, extrapolated at order 4), on the "
             f"{lv['steps'][1]}-step grid. Uncertainty u = |time extrapolation from ({lv['steps'][1]}, "
             f"{lv['steps'][2]}) - from ({lv['steps'][0]}, {lv['steps'][1]})| + (mesh change "
             f"{lv['meshes'][1]}->{lv['meshes'][2]})/15 + 2 x steady-state tolerance x peak. Peaks "
             "are refined by a parabola through the three samples around the largest |value|.\n")
    L.append(f"**kedfem** (git {ked_version}). `mechanisms.build(case, elements={lv['ked_elements']})`, "
             f"`kf.Scene(m, effects=..., damping=kf.Rayleigh(beta=...), rtol={lv['ked_rtol']:g})`, read with "
             "`res.resample(crank_angle=...)` at the reference's instants; `deflection(link, 0.5, "
             "relative_to=\"chord\")` and the crank tip `deflection(crank, 1.0, relative_to=\"frame\")`. "
             "I+C+A = inertia + coupling + axial_stiffening; +GN adds geometric_nonlinearity. "
             "dpeak = (kedfem peak - reference peak) / reference peak; dmax = max over the cycle of "
             "|kedfem - reference| / reference peak; drms = rms(kedfem - reference) / rms(reference).\n")
    L.append("\n## Summary: kedfem against the reference\n")
    L.append("Largest |dpeak| and largest dmax over the case's quantities (mid-span chord deflections of "
             "the flexible links and, where the crank is flexible, its tip), in %; u = largest reference "
             "uncertainty / peak, in %.\n")
    L.append("| case | damping | u % | I+C+A max abs dpeak | I+C+A max dmax | I+C+A+GN max abs dpeak | I+C+A+GN max dmax |")
    L.append("|---|---|---|---|---|---|---|")
    for case, R in report.items():
        rows = [("1x", R["comps"], R["info"])]
        if R["low"] is not None:
            rows.append(("0.2x", R["low"][3], R["low"][2]))
        for tag, comps, inf in rows:
            u = max(100 * inf[q]["u"] / inf[q]["peak"] for q in R["qs"])
            cells = []
            for t in EFFECT_SETS:
                qa = max(R["qs"], key=lambda q: abs(comps[t][q]["dpeak"]))
                qm = max(R["qs"], key=lambda q: comps[t][q]["dmax"])
                cells += [f"{comps[t][qa]['dpeak']:+.3f} ({qa})", f"{comps[t][qm]['dmax']:.3f} ({qm})"]
            L.append(f"| {case} | {tag} | {u:.3f} | " + " | ".join(cells) + " |")
    for case, R in report.items():
        qs = R["qs"]
        L.append(f"\n## {case}\n")
        L.append(f"{R['note']}; Rayleigh beta = {R['beta']:.4e} s on the strain rates (alpha = 0).\n")
        L.append("### Convergence of the exact model (peak |deflection|, mm)\n")
        L.append("| level | " + " | ".join(qs) + " |")
        L.append("|---|" + "---|" * len(qs))
        m0, m1, m2 = lv["meshes"]
        s0, s1, s2 = lv["steps"]
        for i, s in enumerate((s0, s1, s2)):
            L.append(f"| {m1} el, {s} steps | " + " | ".join(fmt(1e3 * R['info'][q]['peaks_time'][i], 6) for q in qs) + " |")
        for i, mm in enumerate((m0, m1, m2)):
            L.append(f"| {mm} el, {s1} steps | " + " | ".join(fmt(1e3 * R['info'][q]['peaks_mesh'][i], 6) for q in qs) + " |")
        L.append("| observed time order (max-norm of history changes) | " + " | ".join(fmt(R['info'][q]['p_t'], 2) for q in qs) + " |")
        L.append("| observed mesh order | " + " | ".join(fmt(R['info'][q]['p_m'], 2) for q in qs) + " |")
        L.append(f"| history change {s1}->{s2} steps / peak | " + " | ".join(f"{R['info'][q]['d12'] / R['info'][q]['peak']:.1e}" for q in qs) + " |")
        L.append(f"| history change {m1}->{m2} el / peak | " + " | ".join(f"{R['info'][q]['e12'] / R['info'][q]['peak']:.1e}" for q in qs) + " |")
        L.append("| **reference peak** | " + " | ".join(f"**{1e3 * R['info'][q]['peak']:.6f}**" for q in qs) + " |")
        L.append("| uncertainty u / peak | " + " | ".join(f"{R['info'][q]['u'] / R['info'][q]['peak']:.1e}" for q in qs) + " |")
        L.append("")
        L.append(f"### kedfem against the reference (beta = {R['beta']:.4e} s)\n")
        L.append("| effects | quantity | reference peak [mm] | kedfem peak [mm] | dpeak % | dmax % | drms % |")
        L.append("|---|---|---|---|---|---|---|")
        for tag in EFFECT_SETS:
            for q in qs:
                c = R["comps"][tag][q]
                L.append(f"| {tag} | {q} | {1e3 * c['ref_peak']:.6f} | {1e3 * c['ked_peak']:.6f} | "
                         f"{c['dpeak']:+.3f} | {c['dmax']:.3f} | {c['drms']:.3f} |")
        if R["low"] is not None:
            ca_l, ref_l, info_l, comps_l = R["low"]
            L.append(f"\n### Damping 0.2x (beta = {0.2 * R['beta']:.4e} s)\n")
            ls = lv["low_steps"]
            L.append(f"Reference: {lv['meshes'][0]} elements, time-Richardson of {ls[-2]} and {ls[-1]} steps "
                     f"(steady-state tolerance {lv['tol_low']:.0e}), on the {ls[-2]}-step grid; u = "
                     + ("difference from the extrapolation of the two coarser levels" if len(ls) == 3
                        else "change of the two levels / 3")
                     + f" + the full-damping change {lv['meshes'][0]}->{lv['meshes'][1]} elements "
                     "(this mesh's error) + 2 x steady-state tolerance x peak.\n")
            L.append("| effects | quantity | reference peak [mm] (u/peak) | kedfem peak [mm] | dpeak % | dmax % | drms % |")
            L.append("|---|---|---|---|---|---|---|")
            for tag in EFFECT_SETS:
                for q in qs:
                    c = comps_l[tag][q]
                    L.append(f"| {tag} | {q} | {1e3 * c['ref_peak']:.6f} ({info_l[q]['u'] / info_l[q]['peak']:.0e}"
                             f"{'' if info_l[q]['converged'] else ', NOT periodic'}) | {1e3 * c['ked_peak']:.6f} | "
                             f"{c['dpeak']:+.3f} | {c['dmax']:.3f} | {c['drms']:.3f} |")
            L.append("\nChange of the kedfem - reference peak difference when the damping drops to 0.2x "
                     "(percentage points), a measure of the damping models' difference:\n")
            L.append("| effects | " + " | ".join(qs) + " |")
            L.append("|---|" + "---|" * len(qs))
            for tag in EFFECT_SETS:
                L.append(f"| {tag} | " + " | ".join(f"{comps_l[tag][q]['dpeak'] - R['comps'][tag][q]['dpeak']:+.3f}" for q in qs) + " |")
        L.append("\n### Axial force at mid-span (peak |N|, N)\n")
        L.append("Reference: finest time level, EA (|r'| - 1) at s = L/2 (not extrapolated). kedfem: mean of "
                 "the two element-midpoint values next to mid-span (`res.axial_force`), an O(L_e^2) "
                 "approximation of the mid-span value.\n")
        L.append("| link | reference | " + " | ".join(f"kedfem {t}" for t in EFFECT_SETS) + " | " + " | ".join(f"dmax % {t}" for t in EFFECT_SETS) + " |")
        L.append("|---|---|" + "---|" * (2 * len(EFFECT_SETS)))
        for lk, hN in R["axial"].items():
            pr = np.max(np.abs(hN))
            cells = [f"{np.max(np.abs(R['ked_axial'][t][lk])):.4f}" for t in EFFECT_SETS]
            dm = [f"{100 * np.max(np.abs(R['ked_axial'][t][lk] - hN)) / pr:.3f}" for t in EFFECT_SETS]
            L.append(f"| {lk} | {pr:.4f} | " + " | ".join(cells) + " | " + " | ".join(dm) + " |")
    if diag:
        L.append("\n## Four-bar variants (`--diagnostics`)\n")
        L.append(f"Reference: {lv['meshes'][0]} elements, time-Richardson of {lv['steps'][0]} and "
                 f"{lv['steps'][1]} steps (about 1e-4 of the peak); kedfem as above. `thickness xk`: "
                 "sections k x thicker (A x k, EI x k^3), joint masses x k, speed x k, beta / k: the linearised "
                 "problem is nearly the same (the deflections stay about the same) while deflection / "
                 "thickness, the measure of the geometric nonlinearity, drops by k. dpeak / dmax in %.\n")
        labels = list(dict.fromkeys(r[0] for r in diag))
        qs_all = list(dict.fromkeys(r[2] for r in diag))
        L.append("| variant | effects | " + " | ".join(f"{q} ref [mm] / dpeak / dmax" for q in qs_all) + " |")
        L.append("|---|---|" + "---|" * len(qs_all))
        for lab in labels:
            for tag in EFFECT_SETS:
                cells = []
                for q in qs_all:
                    r = [x for x in diag if x[0] == lab and x[1] == tag and x[2] == q]
                    cells.append(f"{1e3 * r[0][3]:.4f} / {r[0][4]:+.2f} / {r[0][5]:.2f}" if r else "-")
                L.append(f"| {lab} | {tag} | " + " | ".join(cells) + " |")
    L.append("\n## Runs and wall times\n")
    L.append("Exact model (one process, numpy + SuperLU):\n")
    L.append("| case | role | el/link | steps/cycle | beta [s] | DOFs + constraints | cycles | last change | Newton it./step | max abs g | wall [s] |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in exact_rec:
        L.append(f"| {r['case']} | {r['tag']} | {r['elements']} | {r['steps']} | {r['beta']:.3e} | {r['ndof']} + {r['ncon']} | "
                 f"{r['cycles']}{'' if r['converged'] else ' (not periodic)'} | {r['last_change']:.1e} | {r['newton']:.2f} | "
                 f"{r['max_g']:.1e} | {r['wall']:.1f} |")
    L.append("\nkedfem:\n")
    L.append("| case | damping | effects | el/link | rtol | time elements | est. peak error | wall [s] |")
    L.append("|---|---|---|---|---|---|---|---|")
    for r in ked_rec:
        L.append(f"| {r['case']} | {r['tag']} | {r['effects']} | {r['elements']} | {r['rtol']:g} | {r['n']} | "
                 f"{r['error_peak']:.1e} | {r['wall']:.1f} |")
    rows, stat, rot = val
    L.append(f"\n## Validation of the exact model ({t_val:.1f} s; also `tests/test_exact_reference.py`)\n")
    L.append("Beam natural frequencies from the linearisation at the straight configuration (EA L^2/EI = 1e7), "
             "relative error against the Euler-Bernoulli roots (h^4 expected):\n")
    L.append("| beam | elements | mode 1 | mode 2 |")
    L.append("|---|---|---|---|")
    for r in rows:
        L.append(f"| {r[1]} | {r[2]} | {r[3]:.2e} | {r[4]:.2e} |")
    L.append("\nCantilever under a tip moment M = pi/2 EI/L (a quarter circle): tip position error [L] "
             "against the closed form of this extensible model (a circular arc with uniform stretch "
             "eps = M^2/(EA EI - M^2), angle M L (1+eps)^2/EI; the inextensible arc for EA -> inf):\n")
    L.append("| EA L^2/EI | elements | tip error |")
    L.append("|---|---|---|")
    for r in stat:
        L.append(f"| {r[0]:.0e} | {r[1]} | {r[2]:.2e} |")
    L.append("\nRotating cantilever (hub radius 0, 16 elements, EA L^2/EI = 1e8), relative equilibrium and "
             "gyroscopic linearisation in the co-rotating frame: first in-plane frequency parameter against "
             "the table, and the axial force against rhoA w^2 (L^2 - s^2)/2 (max error / root value):\n")
    L.append("| gamma | lambda1 (exact model) | table | rel. diff | axial force error |")
    L.append("|---|---|---|---|---|")
    for g, lam, tab, nerr in rot:
        L.append(f"| {g} | {lam:.5f} | {tab:.4f} | {lam / tab - 1:+.1e} | {nerr:.1e} |")
    L.append("")
    return "\n".join(L)


if __name__ == "__main__":
    main()
