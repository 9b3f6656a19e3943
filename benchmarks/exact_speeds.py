#!/usr/bin/env python
"""Geometrically exact reference results for the four-bar over a range of crank speeds.

The shipped four-bar (``mechanisms.build("four_bar", speed=w)``: crank, coupler
and follower flexible, crank clamped to its drive) is marched with the exact
model of ``benchmarks/exact`` (ANCF cables, generalised-alpha, index 3) cycle by
cycle, WITHOUT the reduced-rank extrapolation, at strain-rate damping
beta = 1.3708e-4 s (about 2 % on the first mode, as in exact_comparison.py).

For each speed:

* regime: the march (16 elements, 720 steps per cycle, warm-started from the
  previous speed) runs until the last two revolutions agree to ``tol`` = 1e-6 of
  the peak (1-periodic), or revolution k agrees with k-2 but not with k-1
  (2-periodic: |k - (k-1)| > 1e3 tol), or ``cycles_max`` (300) revolutions
  (then the smallest p <= 6 with |k - (k-p)| < tol is reported, else "other").
  Every other level reports its own regime the same way.
* levels: 16 el at 720 and 1440 steps, 8 el at 1440 (the requested mesh/time
  check), and 8 el at 720 and 360 steps (cheap: the observed time order and
  the uncertainty of the time extrapolation), each warm-started from the one
  before.
* best estimate (1-periodic): the 16-element histories Richardson-extrapolated
  in time, 720 -> 1440 steps at order 2, on the 720-step grid; peaks of
  periodic histories by trigonometric (FFT) interpolation. Uncertainty
  u = u_t + u_m + u_ss: u_t = |peak of the (720, 1440) extrapolation - peak
  of the (360, 720) one| on 8 elements (as exact_comparison.py; if the 8-el
  time levels were skipped, the whole 720 -> 1440 correction), u_m = |16 el -
  8 el| / 15 at 1440 steps (mesh order 4, observed in exact_comparison.py),
  u_ss = last cycle change / (1 - |mu|) x peak (distance to the periodic state).
* multiplier: from the last cycle-to-cycle change vectors X_k - X_{k-1} of the
  tracked histories (each scaled by its peak): the least-squares ratio of
  successive ones (signed: a negative value means alternation, a flip), and,
  where one ratio does not fit, the modulus of a two-term (complex pair) fit.

Usage::

    python benchmarks/exact_speeds.py             # full, about 60-90 min on 2 busy cores
    python benchmarks/exact_speeds.py --quick     # coarse levels, 3 speeds, about 2 min
    python benchmarks/exact_speeds.py --speeds 300,325 --budget 30

Writes ``benchmarks/results/exact_speeds.md`` and ``.csv`` (``--quick``:
``exact_speeds_quick.*``).
"""

from __future__ import annotations

import argparse
import collections
import csv
import math
import os
import sys
import time

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
for _p in (ROOT, HERE):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import numpy as np  # noqa: E402
from scipy.signal import resample  # noqa: E402

import mechanisms  # noqa: E402
import exact as ex  # noqa: E402
from exact.simulate import _Readout  # noqa: E402

BETA = 1.3708e-4
LINKS = ("crank", "coupler", "follower")
SPEEDS_RPM = (200, 250, 300, 325, 350, 375, 400, 425, 450, 475, 500, 550, 600)

LEVELS = {
    # regime level first; then the warm-start chain. role "req": the requested mesh/time check,
    # "extra": cheap 8-el time levels for the order and u_t (skipped first when short of time)
    "full": dict(chain=[("A", 16, 720, "req"), ("B", 16, 1440, "req"), ("C", 8, 1440, "req"),
                        ("D", 8, 720, "extra"), ("E", 8, 360, "extra")],
                 fine=16, coarse=8, s0=360, s1=720, s2=1440, tol=1e-6, cycles_max=300, cycles_max_warm=300,
                 speeds=SPEEDS_RPM, budget=88.0),
    "quick": dict(chain=[("A", 4, 180, "req"), ("B", 4, 360, "req"), ("C", 2, 360, "req"),
                         ("D", 2, 180, "extra"), ("E", 2, 90, "extra")],
                  fine=4, coarse=2, s0=90, s1=180, s2=360, tol=1e-5, cycles_max=60, cycles_max_warm=40,
                  speeds=(200, 400, 600), budget=5.0),
}
P_TIME, P_MESH = 2.0, 4.0
TWO_PER_GAP = 1e3        # 2-periodic: |k - (k-1)| > TWO_PER_GAP * tol while |k - (k-2)| < tol
P_MAX = 6                # longest period looked for at the end of an unsettled run


def log(msg):
    print(msg, flush=True)


def rpm_to_w(rpm):
    return rpm * 2.0 * math.pi / 60.0


# ------------------------------------------------------------------ peaks
def peak_periodic(h, up=32):
    """Largest |h| of a periodic sampled history by trigonometric interpolation: (peak, index in [0, n), signed value)."""
    h = np.asarray(h, float)
    n = h.size
    f = resample(h, n * up)
    k = int(np.argmax(np.abs(f)))
    return float(abs(f[k])), k / up, float(f[k])


def peak_sampled(h):
    """Largest |h| of a (not periodic) sampled history, refined by a parabola: (peak, index, signed value)."""
    a = np.abs(h)
    k = int(np.argmax(a))
    if 0 < k < a.size - 1:
        y0, y1, y2 = a[k - 1], a[k], a[k + 1]
        den = y0 - 2 * y1 + y2
        if den < 0:
            x = 0.5 * (y0 - y2) / den
            return float(y1 - 0.25 * (y0 - y2) * x), k + x, float(np.sign(h[k]) * (y1 - 0.25 * (y0 - y2) * x))
    return float(a[k]), float(k), float(h[k])


def angle_deg(index, n, th0=0.0):
    return (math.degrees(th0 + 2 * math.pi * index / n)) % 360.0


# ------------------------------------------------------------------ marching
class Run:
    """One unaccelerated march of the exact model, keeping the last revolutions' histories."""

    def __init__(self, **kw):
        self.__dict__.update(kw)


def rel_change(a, b):
    """max over quantities of max |a - b| / max |a| (the measure of exact.simulate)."""
    return max(float(np.max(np.abs(a[k] - b[k])) / max(np.max(np.abs(a[k])), 1e-300)) for k in a)


def flatten(cur):
    """Tracked histories scaled by their peaks, concatenated (for the multiplier fits)."""
    return np.concatenate([cur[k] / max(np.max(np.abs(cur[k])), 1e-300) for k in sorted(cur)])


def march(rpm, ne, n, *, init=None, tol=1e-6, cycles_max=300, beta=BETA, label="", progress=25):
    """March the four-bar at ``rpm`` on ``ne`` elements and ``n`` steps per cycle, no extrapolation.

    ``init``: a :class:`Run` (any speed, mesh, step): its last cycle-start state is carried onto
    this mesh (exact Hermite fields), its time reset to 0 (the crank is at its start angle at
    every cycle start) and, for another speed, velocities scaled by w/w0, accelerations and
    multipliers by (w/w0)^2.
    """
    t0 = time.perf_counter()
    w = rpm_to_w(rpm)
    mech = mechanisms.build("four_bar", speed=w)
    model, info = ex.from_mechanism(mech, elements_per_link=ne, beta=beta)
    T = mech.period
    h = T / n
    if init is None:
        st = ex.initial_state(model, mech)
    else:
        st = model.map_state(init.state, init.model)
        s = w / rpm_to_w(init.rpm)
        st.t = 0.0
        st.v = st.v * s
        st.vd = st.vd * s * s
        st.lam = st.lam * s * s
        st.a = st.vd.copy()
    integ = ex.GeneralizedAlpha(model, h, rho_inf=0.9, tol=1e-10)
    read = _Readout(model, mech, info)
    lk = mech.links[info["drive"]]
    pa, pb = np.array(mech.joints[lk.a].at), np.array(mech.joints[lk.b].at)
    th0 = math.atan2(pb[1] - pa[1], pb[0] - pa[0])
    tau = np.arange(n) * h
    Q = np.empty((n, model.ndof))
    hist = collections.deque(maxlen=P_MAX + 1)      # tracked histories of the last revolutions
    flat = collections.deque(maxlen=8)              # their scaled concatenations
    d1s, d2s, status = [], [], "max_cycles"
    failure = None
    cycle = 0
    start = st
    for cycle in range(1, cycles_max + 1):
        start = st
        try:
            for k in range(n):
                Q[k] = st.q
                st = integ.step(st)
        except ex.NewtonFailure as exc:
            failure = str(exc)
            status = "newton_failure"
            st = start            # the last cycle-start state reached
            cycle -= 1
            break
        defl, tip, axial, moment = read(Q, tau)
        cur = read.tracked(defl, tip)
        hist.append(cur)
        flat.append(flatten(cur))
        d1 = rel_change(hist[-1], hist[-2]) if len(hist) >= 2 else float("nan")
        d2 = rel_change(hist[-1], hist[-3]) if len(hist) >= 3 else float("nan")
        d1s.append(d1)
        d2s.append(d2)
        if progress and cycle % progress == 0:
            log(f"      {label} cycle {cycle}: |k-(k-1)| {d1:.2e}  |k-(k-2)| {d2:.2e}  "
                f"({time.perf_counter() - t0:.0f} s)")
        if cycle >= 2 and d1 < tol:
            status = "1-periodic"
            break
        if cycle >= 3 and d2 < tol and d1 > TWO_PER_GAP * tol:
            status = "2-periodic"
            break
    # differences of the last revolution from the p-th one before
    dp = {p: rel_change(hist[-1], hist[-1 - p]) for p in range(1, len(hist))}
    if not d1s:
        d1s, d2s = [float("nan")], [float("nan")]
    regime = status
    if status == "max_cycles":
        settled = [p for p in sorted(dp) if dp[p] < tol]
        regime = f"{settled[0]}-periodic" if settled else "other"
        if settled and settled[0] == 1:
            regime = "1-periodic"
    elif status == "newton_failure":
        regime = "failed"
    wall = time.perf_counter() - t0
    r = Run(rpm=rpm, w=w, ne=ne, n=n, tol=tol, cycles=cycle, d1=d1s, d2=d2s, dp=dp, status=status,
            regime=regime, failure=failure, hist=list(hist), flat=list(flat), state=st, model=model, th0=th0,
            wall=wall, ndof=model.ndof, newton=integ.iterations / max(integ.steps, 1), label=label)
    r.mu = multiplier(r)
    return r


def multiplier(r):
    """Estimate of the largest Floquet multiplier from the last change vectors.

    Returns dict(mu=signed real estimate or nan, mod=modulus estimate, kind, fit=relative residual,
    ratios=last scalar ratios d1_k / d1_{k-1}). For a 2-periodic state the same fits on
    X_k - X_{k-2} give the multiplier of the two-revolution map (kind "2-rev").
    """
    out = dict(mu=float("nan"), mod=float("nan"), kind="-", fit=float("nan"), ratios=[])
    X = r.flat
    lag = 2 if r.regime == "2-periodic" else 1
    D = [X[i] - X[i - lag] for i in range(lag, len(X))]
    if lag == 1:
        seq = [d for d in r.d1 if np.isfinite(d)]
    else:
        seq = [d for d in r.d2 if np.isfinite(d)]
    out["ratios"] = [seq[i] / seq[i - lag] for i in range(max(lag, len(seq) - 4), len(seq)) if seq[i - lag] > 0]
    if r.regime not in ("1-periodic", "2-periodic"):
        return out          # irregular or failed: the changes do not decay, no multiplier
    if lag == 2:
        D = D[::-1][::2][::-1]      # non-overlapping: X_k - X_{k-2}, X_{k-2} - X_{k-4}, ...
    if len(D) < 3:
        return out
    a, b = D[-2], D[-1]
    mu = float(a @ b / (a @ a))
    res = float(np.linalg.norm(b - mu * a) / np.linalg.norm(b))
    out.update(mu=mu, mod=abs(mu), kind="real", fit=res)
    if res > 0.2 and len(D) >= 4:
        # two-term fit D_j = c1 D_{j-1} + c2 D_{j-2} over the available j: the roots are the dominant pair
        rows = [(np.stack([D[j - 1], D[j - 2]], 1), D[j]) for j in range(2, len(D))]
        Am = np.concatenate([x[0] for x in rows])
        bm = np.concatenate([x[1] for x in rows])
        c, *_ = np.linalg.lstsq(Am, bm, rcond=None)
        roots = np.roots([1.0, -c[0], -c[1]])
        j = int(np.argmax(np.abs(roots)))
        res2 = float(np.linalg.norm(Am @ c - bm) / np.linalg.norm(bm))
        if abs(roots[j].imag) > 1e-8:
            out.update(mu=float("nan"), mod=float(abs(roots[j])), kind="complex", fit=res2)
        else:
            out.update(mu=float(roots[j].real), mod=float(abs(roots[j].real)), kind="real2", fit=res2)
    return out


def mu_text(m, lag=1):
    if m["kind"] == "-":
        return "-"
    return _mu_text(m, lag) + (" (poor fit)" if m["fit"] > 0.3 else "")


def _mu_text(m, lag):
    if lag == 2:
        return f"{m['mu']:+.3f} (2-rev map)" if np.isfinite(m["mu"]) else f"|{m['mod']:.3f}| (2-rev map)"
    if m["kind"] == "complex":
        return f"|{m['mod']:.3f}| (complex pair)"
    return f"{m['mu']:+.3f}"


# ------------------------------------------------------------------ per speed
def last_two(r, q):
    """The last two revolutions of quantity ``q`` (previous, last); ``prev`` = ``last`` after one."""
    return r.hist[max(len(r.hist) - 2, 0)][q], r.hist[-1][q]


def level_peaks(r):
    """Peak of each link on the last revolution (and the max over the last two), with its crank angle."""
    out = {}
    if not r.hist:
        nan = float("nan")
        return {q: dict(peak=nan, angle=nan, signed=nan, peak2=nan) for q in LINKS + ("tip",)}
    for q in LINKS + ("tip",):
        prev, last = last_two(r, q)
        if r.regime == "1-periodic":
            p, i, v = peak_periodic(last)
            p2 = p
        elif r.regime == "2-periodic":
            both = np.concatenate([prev, last])
            f = resample(both, both.size * 32)
            half = f.size // 2
            kl = half + int(np.argmax(np.abs(f[half:])))
            p, i, v = float(abs(f[kl])), (kl - half) / 32, float(f[kl])
            p2 = float(np.max(np.abs(f)))
        else:
            p, i, v = peak_sampled(last)
            p2 = max(p, peak_sampled(prev)[0])
        out[q] = dict(peak=p, angle=angle_deg(i, r.n, r.th0), signed=v, peak2=p2)
    return out


def richardson(fine, coarse, p):
    return fine + (fine - coarse) / (2.0**p - 1.0)


def sub(h, n_from, n_to):
    s = n_from // n_to
    assert s * n_to == n_from
    return h[::s]


def best_estimate(runs, lv):
    """Best estimate and uncertainty per link (1-periodic), from the runs of one speed."""
    ok = {t: r for t, r in runs.items() if r.regime == "1-periodic"}
    A, B, C = ok.get("A"), ok.get("B"), ok.get("C")
    D, E = ok.get("D"), ok.get("E")
    s0, s1, s2 = lv["s0"], lv["s1"], lv["s2"]
    out = {}
    for q in LINKS + ("tip",):
        h1 = A.hist[-1][q]
        if B is not None:
            h2 = B.hist[-1][q]
            R = richardson(sub(h2, s2, s1), h1, P_TIME)
            pk, i, v = peak_periodic(R)
            p_fine = peak_periodic(h2)[0]
            pA = peak_periodic(h1)[0]
            # time: difference of the (s1, s2) and (s0, s1) extrapolations on the coarse mesh
            if C is not None and D is not None and E is not None:
                c2, c1, c0 = C.hist[-1][q], D.hist[-1][q], E.hist[-1][q]
                Rc_hi = peak_periodic(richardson(sub(c2, s2, s1), c1, P_TIME))[0]
                Rc_lo = peak_periodic(richardson(sub(c1, s1, s0), c0, P_TIME))[0]
                u_t = abs(Rc_hi - Rc_lo)
                d01 = np.max(np.abs(c0 - sub(c1, s1, s0)))
                d12 = np.max(np.abs(sub(c1, s1, s0) - sub(c2, s2, s0)))
                p_t = math.log2(d01 / d12) if d01 > 0 and d12 > 0 else float("nan")
                ut_kind = "extrapolations"
            else:
                u_t = abs(pk - p_fine)
                p_t = float("nan")
                ut_kind = "correction"
            u_m = abs(p_fine - peak_periodic(C.hist[-1][q])[0]) / (2**P_MESH - 1) if C is not None else float("nan")
            d1 = max(A.d1[-1], B.d1[-1])
            mod = A.mu["mod"] if np.isfinite(A.mu["mod"]) and A.mu["mod"] < 1 else 0.9
            u_ss = d1 / (1 - mod) * pk
            u = u_t + (u_m if np.isfinite(u_m) else 0.0) + u_ss
            out[q] = dict(peak=pk, u=u, u_t=u_t, u_m=u_m, u_ss=u_ss, p_t=p_t, ut_kind=ut_kind,
                          angle=angle_deg(i, s1, A.th0), signed=v, peak_A=pA, peak_B=p_fine, finest="16/1440")
        else:
            pk, i, v = peak_periodic(h1)
            u_m = abs(pk - peak_periodic(C.hist[-1][q])[0]) if C is not None else float("nan")
            out[q] = dict(peak=pk, u=float("nan"), u_t=float("nan"), u_m=u_m, u_ss=float("nan"), p_t=float("nan"),
                          ut_kind="none", angle=angle_deg(i, s1, A.th0), signed=v, peak_A=pk, peak_B=float("nan"),
                          finest="A only")
    return out


# ------------------------------------------------------------------ main
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="coarse levels, 3 speeds (about 2 min)")
    ap.add_argument("--speeds", default=None, help="comma-separated crank speeds in rpm")
    ap.add_argument("--budget", type=float, default=None, help="wall-time budget in minutes (default 88; quick 5)")
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    args = ap.parse_args(argv)
    mode = "quick" if args.quick else "full"
    lv = LEVELS[mode]
    speeds = [float(s) for s in args.speeds.split(",")] if args.speeds else list(lv["speeds"])
    budget = 60.0 * (args.budget if args.budget is not None else lv["budget"])
    tol = lv["tol"]
    t_all = time.perf_counter()
    log(f"exact_speeds ({mode}): {len(speeds)} speeds, beta = {BETA:.4e} s, tol {tol:.0e}, "
        f"budget {budget / 60:.0f} min")
    results = []
    prevA = None
    per_cycle = {}            # (ne, n) -> seconds per cycle, measured
    for i_s, rpm in enumerate(speeds):
        runs, skipped = {}, []
        left = len(speeds) - i_s - 1
        log(f"{rpm:g} rpm (w = {rpm_to_w(rpm):.3f} rad/s)")
        prev = prevA
        for tag, ne, n, role in lv["chain"]:
            elapsed = time.perf_counter() - t_all
            if tag != "A" and runs["A"].regime == "failed":
                skipped.append(f"{tag} ({ne} el, {n} steps): regime run failed")
                continue
            if tag != "A":
                # keep time for the regime runs of the speeds still to come (A of this speed as a guide)
                reserve = left * 1.2 * runs["A"].wall
                est = 30 * per_cycle.get((ne, n), runs["A"].wall / runs["A"].cycles * n / lv["s1"])
                if runs["A"].regime not in ("1-periodic", "2-periodic"):
                    est = 40 * per_cycle.get((ne, n), runs["A"].wall / runs["A"].cycles * n / lv["s1"])
                if elapsed + est + reserve > budget:
                    skipped.append(f"{tag} ({ne} el, {n} steps): time budget")
                    log(f"    skip {tag} {ne} el {n} steps (elapsed {elapsed:.0f} s, est {est:.0f} s, "
                        f"reserve {reserve:.0f} s)")
                    continue
            init = prev
            cmax = lv["cycles_max"] if tag == "A" else lv["cycles_max_warm"]
            if tag != "A" and runs["A"].regime not in ("1-periodic", "2-periodic"):
                cmax = 40         # irregular: the finer levels only for an indication
            r = march(rpm, ne, n, init=init, tol=tol, cycles_max=cmax, label=f"{rpm:g} rpm {tag}")
            runs[tag] = r
            per_cycle[(ne, n)] = r.wall / max(r.cycles, 1)
            prev = r
            pk = level_peaks(r)
            log(f"    {tag} {ne:2d} el {n:5d} steps: {r.regime:10s} {r.cycles:3d} cycles, "
                f"|k-(k-1)| {r.d1[-1]:.1e}, |k-(k-2)| {r.d2[-1]:.1e}, mu {mu_text(r.mu, 2 if r.regime == '2-periodic' else 1)}, "
                f"peaks " + " ".join(f"{q} {1e3 * pk[q]['peak']:.5f}" for q in LINKS) + f" mm, {r.wall:.0f} s")
            if r.regime == "failed":
                log(f"      {r.failure}")
        if runs["A"].regime != "failed":
            prevA = runs["A"]         # the next speed starts from the last regime run that did not fail
        results.append(dict(rpm=rpm, runs=runs, skipped=skipped,
                            best=best_estimate(runs, lv) if runs["A"].regime == "1-periodic" else None,
                            peaks={t: level_peaks(r) for t, r in runs.items()}))
        write(results, lv, mode, time.perf_counter() - t_all, args.out, final=False)
    wall = time.perf_counter() - t_all
    write(results, lv, mode, wall, args.out, final=True)
    log(f"done in {wall:.0f} s")


# ------------------------------------------------------------------ output
def regime_text(r):
    return r.regime if r.status != "max_cycles" or r.regime == "other" else r.regime + " (at cycles_max)"


def write(results, lv, mode, wall, out_dir, final):
    os.makedirs(out_dir, exist_ok=True)
    stem = "exact_speeds" + ("_quick" if mode == "quick" else "")
    chain = {t: (ne, n) for t, ne, n, _ in lv["chain"]}
    rows = []
    for R in results:
        A = R["runs"]["A"]
        for tag, r in R["runs"].items():
            for q in LINKS + ("tip",):
                p = R["peaks"][tag][q]
                rows.append(dict(speed_rpm=R["rpm"], level=f"{r.ne}el/{r.n}", elements=r.ne, steps=r.n, regime=r.regime,
                                 cycles=r.cycles, d_last_two=r.d1[-1], d_k_k2=r.d2[-1],
                                 mu=r.mu["mu"], mu_modulus=r.mu["mod"], mu_kind=r.mu["kind"], quantity=q,
                                 peak_mm=1e3 * p["peak"], u_mm=float("nan"), peak_last2_mm=1e3 * p["peak2"],
                                 signed_mm=1e3 * p["signed"], angle_deg=p["angle"], wall_s=r.wall))
        if R["best"] is not None:
            for q in LINKS + ("tip",):
                b = R["best"][q]
                rows.append(dict(speed_rpm=R["rpm"], level="best", elements=lv["fine"], steps=f"{lv['s1']}->{lv['s2']}",
                                 regime=A.regime, cycles=A.cycles, d_last_two=A.d1[-1], d_k_k2=A.d2[-1],
                                 mu=A.mu["mu"], mu_modulus=A.mu["mod"], mu_kind=A.mu["kind"], quantity=q,
                                 peak_mm=1e3 * b["peak"], u_mm=1e3 * b["u"], peak_last2_mm=float("nan"),
                                 signed_mm=1e3 * b["signed"], angle_deg=b["angle"], wall_s=float("nan")))
    with open(os.path.join(out_dir, stem + ".csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.7g}" if isinstance(v, float) else v) for k, v in r.items()})
    with open(os.path.join(out_dir, stem + ".md"), "w") as fh:
        fh.write(render(results, lv, mode, wall, final, chain))


def render(results, lv, mode, wall, final, chain):
    L = []
    tol = lv["tol"]
    fine, coarse, s0, s1, s2 = lv["fine"], lv["coarse"], lv["s0"], lv["s1"], lv["s2"]
    L.append("# Four-bar over crank speed: geometrically exact reference (ANCF cables)\n")
    L.append(f"Generated by `python benchmarks/exact_speeds.py{' --quick' if mode == 'quick' else ''}` "
             f"({mode} levels, {wall:.0f} s = {wall / 60:.1f} min on this machine{'' if final else ', INCOMPLETE'}; "
             "one process, OPENBLAS_NUM_THREADS=1). Model: `benchmarks/exact/` (see "
             "exact_comparison.md); mechanism `mechanisms.build(\"four_bar\", speed=rpm * 2 pi / 60)`, crank, "
             f"coupler and follower flexible; strain-rate damping beta = {BETA:.4e} s (about 2 % on the first "
             "mode at 200 rpm); generalised-alpha rho_inf = 0.9, Newton tolerance 1e-10.\n")
    L.append("**Marching.** No reduced-rank extrapolation: plain cycle-by-cycle marching, warm-started "
             "from the previous speed's regime run (state carried over, time reset to the cycle start, "
             "velocities scaled by w/w0, accelerations and multipliers by (w/w0)^2) and, within a speed, "
             "from the previous level. Changes are max over the tracked histories (mid-span chord "
             "deflections of crank, coupler, follower and the crank tip) of max |X_k - X_j| / max |X_k| "
             f"over a revolution. 1-periodic: |k-(k-1)| < {tol:.0e}; 2-periodic: |k-(k-2)| < {tol:.0e} "
             f"with |k-(k-1)| > {TWO_PER_GAP * tol:.0e}; otherwise marched to cycles_max = "
             f"{lv['cycles_max']} (regime run) and the smallest p <= {P_MAX} with |k-(k-p)| < {tol:.0e} "
             "is reported, else \"other\".\n")
    L.append(f"**Levels** (el/link, steps/cycle): A {chain['A']} regime run; B {chain['B']}, C {chain['C']} "
             f"(requested mesh/time check); D {chain['D']}, E {chain['E']} (cheap extra time levels on "
             f"{coarse} el: observed time order and the uncertainty of the time extrapolation). **Best estimate** "
             f"(1-periodic speeds): the {fine}-el histories Richardson-extrapolated in time {s1} -> {s2} "
             f"steps at order 2 on the {s1}-step grid, peak by trigonometric interpolation. u = u_t + u_m + "
             f"u_ss: u_t = |(s1, s2) extrapolation - (s0, s1) extrapolation| of the peak on {coarse} el "
             f"({s0}, {s1}, {s2} steps; where D/E are missing, the whole {s1} -> {s2} correction), u_m = "
             f"|{fine} el - {coarse} el| / 15 at {s2} steps (order 4), u_ss = last change / (1 - |mu|) x peak. "
             "Peak angles are crank angles (deg, crank along the ground line at 0, positive counter-clockwise), "
             "with the sign of the deflection at the peak (+ to the left of the link's a -> b chord: crank "
             "O2 -> A, coupler A -> B, follower O4 -> B).\n")
    L.append("**Multiplier.** From the last change vectors D_k = X_k - X_{k-1} of the regime run (histories "
             "scaled by their peaks): mu = <D_k, D_{k-1}> / |D_{k-1}|^2 (signed; negative: the changes "
             "alternate, a flip); where that fits worse than 20 %, a two-term fit D_k = c1 D_{k-1} + c2 "
             "D_{k-2} and the modulus of its larger root (\"complex pair\"). 2-periodic: the same on "
             "X_k - X_{k-2}, the multiplier of the two-revolution map.\n")
    # ---- summary
    L.append("\n## Summary\n")
    L.append("Peaks of |mid-span chord deflection| [mm] (1-periodic: best estimate +- u; otherwise the "
             "finest level's last revolution, and for 2-periodic the two revolutions' peaks a / b); "
             "angle of each peak [deg] and sign; regime run's last-two-revolution difference "
             "|k-(k-1)| and |k-(k-2)|, cycles; multiplier estimate.\n")
    L.append("| rpm | regime | crank [mm] | coupler [mm] | follower [mm] | peak angles crank / coupler / follower [deg] | "
             "abs(k-(k-1)) | abs(k-(k-2)) | cycles | multiplier |")
    L.append("|---|---|---|---|---|---|---|---|---|---|")
    for R in results:
        A = R["runs"]["A"]
        lag = 2 if A.regime == "2-periodic" else 1
        if R["best"] is not None:
            b = R["best"]
            cells = [f"{1e3 * b[q]['peak']:.5f} +- {1e3 * b[q]['u']:.5f}" if np.isfinite(b[q]["u"])
                     else f"{1e3 * b[q]['peak']:.5f} (A only)" for q in LINKS]
            ang = " / ".join(f"{b[q]['angle']:.1f}{'+' if b[q]['signed'] > 0 else '-'}" for q in LINKS)
        else:
            tag = "B" if "B" in R["runs"] else "A"
            r = R["runs"][tag]
            pk = R["peaks"][tag]
            if r.regime == "2-periodic":
                cells = []
                for q in LINKS:
                    a_ = peak_first_half(r, q)
                    cells.append(f"{1e3 * a_:.4f} / {1e3 * pk[q]['peak']:.4f} ({tag})")
            else:
                cells = [f"{1e3 * pk[q]['peak']:.4f} ({tag}, last rev.)" for q in LINKS]
            ang = " / ".join(f"{pk[q]['angle']:.1f}{'+' if pk[q]['signed'] > 0 else '-'}" for q in LINKS)
        L.append(f"| {R['rpm']:g} | {regime_text(A)} | " + " | ".join(cells) + f" | {ang} | {A.d1[-1]:.1e} | "
                 f"{A.d2[-1]:.1e} | {A.cycles} | {mu_text(A.mu, lag)} |")
    # ---- levels
    L.append("\n## Convergence per speed\n")
    L.append("Peak of |mid-span chord deflection| on the last revolution [mm] per level (2-periodic: "
             "the last revolution; the max over both in the CSV), the level's regime, cycles marched "
             "(warm start), last |k-(k-1)| and wall time.\n")
    L.append("| rpm | level | regime | cycles | abs(k-(k-1)) | abs(k-(k-2)) | crank | coupler | follower | crank tip | wall [s] |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for R in results:
        for tag, r in R["runs"].items():
            pk = R["peaks"][tag]
            L.append(f"| {R['rpm']:g} | {tag}: {r.ne} el, {r.n} | {r.regime} | {r.cycles} | {r.d1[-1]:.1e} | "
                     f"{r.d2[-1]:.1e} | " + " | ".join(f"{1e3 * pk[q]['peak']:.6f}" for q in LINKS + ("tip",))
                     + f" | {r.wall:.0f} |")
        if R["best"] is not None:
            b = R["best"]
            L.append(f"| {R['rpm']:g} | **best** | | | | | " + " | ".join(
                f"**{1e3 * b[q]['peak']:.6f}**" for q in LINKS + ("tip",)) + " | |")
            L.append(f"| {R['rpm']:g} | u_t / u_m / u_ss (1e-3 mm) | | | | | " + " | ".join(
                f"{1e6 * b[q]['u_t']:.2f} / {1e6 * b[q]['u_m']:.2f} / {1e6 * b[q]['u_ss']:.2f}" for q in LINKS + ("tip",))
                + " | |")
            L.append(f"| {R['rpm']:g} | observed time order ({coarse} el, {s0}/{s1}/{s2}) | | | | | " + " | ".join(
                f"{b[q]['p_t']:.2f}" for q in LINKS + ("tip",)) + " | |")
        for s in R["skipped"]:
            L.append(f"| {R['rpm']:g} | {s} skipped | | | | | | | | | |")
    # ---- multipliers
    L.append("\n## Cycle-to-cycle changes of the regime runs\n")
    L.append("Last ratios d_k / d_{k-1} of the scalar changes (2-periodic: d_k / d_{k-2} of |k-(k-2)|), the "
             "fitted multiplier and its relative residual, and the differences |k-(k-p)| of the last "
             "revolution from the p-th before.\n")
    L.append("| rpm | last ratios | multiplier | fit residual | abs(k-(k-p)), p = 1.. |")
    L.append("|---|---|---|---|---|")
    for R in results:
        A = R["runs"]["A"]
        lag = 2 if A.regime == "2-periodic" else 1
        L.append(f"| {R['rpm']:g} | " + ", ".join(f"{x:.3f}" for x in A.mu["ratios"]) + f" | {mu_text(A.mu, lag)} | "
                 f"{A.mu['fit']:.2f} | " + ", ".join(f"{A.dp[p]:.1e}" for p in sorted(A.dp)) + " |")
    L.append("")
    return "\n".join(L)


def peak_first_half(r, q):
    """Peak of the second-to-last revolution of a 2-periodic run (trigonometric, over both revolutions)."""
    both = np.concatenate([r.hist[-2][q], r.hist[-1][q]])
    f = resample(both, both.size * 32)
    return float(np.max(np.abs(f[: f.size // 2])))


if __name__ == "__main__":
    main()
