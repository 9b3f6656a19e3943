"""Onset of parametric instability: the default solve's verdict against a converged exponential one.

A linkage running fast enough becomes parametrically unstable: a Floquet
multiplier of its periodic, time-varying equations leaves the unit circle.
For each shipped mechanism (2 % modal damping, the linear effects inertia,
coupling and axial_stiffening: the onset of the linearised KED equations; the
four-bar and six-bar presets add geometric_nonlinearity, whose multipliers are
those of the linearisation about the converged response and are not studied
here) this study finds the onset speed by bisection on the largest multiplier
modulus ``rho = 1``,

(a) from the default, tolerance-driven solve (``kf.solve(kf.Scene(m, ...))``,
    ``res.stability``: Radau IIA collocation on the finest of the three levels
    of the error estimate), and
(b) from a converged exponential computation: the paper's ``magnus2`` hold with
    the exact stiff split on ``n`` elements, and on ``2 n`` as its check,

and prints their relative difference (acceptance: 0.5 %), together with the
verdicts of both at speeds around the onset. A scan of the speed (doubling
from the preset's) first brackets the onset; mechanisms without one below the
scan's end are reported as such. The Mathieu equation's first tongue against
scipy's characteristic values is a test (``tests/test_time_schemes.py``).

Run from the repository root::

    python benchmarks/stability.py            # ~10 min
    python benchmarks/stability.py --quick    # the four-bar only, coarse
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import time
import warnings

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))

import kedfem as kf  # noqa: E402
from kedfem.fe.effects import LINEAR_EFFECTS  # noqa: E402
import mechanisms  # noqa: E402

LINEAR = LINEAR_EFFECTS
RPM = 2 * math.pi / 60


def cases(quick):
    """name -> (build(speed) -> Mechanism, scene keywords, first scan speed [rpm], scan end [rpm], n_exp)."""
    z2 = kf.ModalDamping(0.02)
    out = {"four_bar": (lambda w: mechanisms.build("four_bar", speed=w), dict(effects=LINEAR, damping=z2),
                        200.0, 1600.0, 2880)}
    if not quick:
        out["slider_crank"] = (lambda w: mechanisms.build("slider_crank", speed=w),
                               dict(effects=LINEAR, damping=z2), 1000.0, 16000.0, 1440)
        out["six_bar"] = (lambda w: mechanisms.build("six_bar", speed=w), dict(effects=LINEAR, damping=z2),
                          200.0, 3200.0, 2880)
        out["exciter"] = (lambda w: mechanisms.build("exciter", speed=w),
                          dict(effects=("inertia", "coupling", "springs"), damping=z2), 600.0, 9600.0, 720)
    return out


def rho_default(build, kw, rpm):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(kf.Scene(build(rpm * RPM), **kw))
    return res.stability


def rho_exp(build, kw, rpm, n):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(kf.Scene(build(rpm * RPM), steps=n, method="magnus2", estimate=False, **kw))
    return res.stability.spectral_radius


def bisect(f, lo, hi, rel=2e-4):
    """Speed where ``f(speed) - 1`` changes sign, in [lo, hi] (f(lo) < 1 <= f(hi))."""
    while hi - lo > rel * hi:
        mid = 0.5 * (lo + hi)
        if f(mid) >= 1.0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def run(quick):
    rows = []
    for name, (build, kw, start, end, n_exp) in cases(quick).items():
        t0 = time.perf_counter()
        # bracket with the default solve, doubling the speed
        lo, hi, rpm = None, None, start
        while rpm <= end:
            s = rho_default(build, kw, rpm)
            print(f"{name:13s} {rpm:8.0f} rpm  rho {s.spectral_radius:.5f} +- {s.error or 0:.1e}  {s.verdict}",
                  flush=True)
            if s.spectral_radius >= 1.0:
                hi = rpm
                break
            lo = rpm
            rpm *= 2.0
        if hi is None:
            print(f"{name:13s} no parametric instability up to {end:.0f} rpm", flush=True)
            rows.append(dict(mechanism=name, onset_default_rpm=float("nan"), onset_exp_rpm=float("nan"),
                             onset_exp2_rpm=float("nan"), rel_diff=float("nan"), n_exp=n_exp,
                             verdicts_agree="", note=f"none up to {end:.0f} rpm", time_s=time.perf_counter() - t0))
            continue
        if lo is None:
            lo = hi / 2
        # narrow the bracket with the cheaper converged side first (a scan of eight speeds)
        on_d = bisect(lambda w: rho_default(build, kw, w).spectral_radius, lo, hi)
        a, b = 0.97 * on_d, 1.03 * on_d
        if rho_exp(build, kw, a, n_exp) >= 1.0 or rho_exp(build, kw, b, n_exp) < 1.0:
            a, b = lo, hi
        on_e = bisect(lambda w: rho_exp(build, kw, w, n_exp), a, b)
        on_e2 = bisect(lambda w: rho_exp(build, kw, w, 2 * n_exp), 0.99 * on_e, 1.01 * on_e)
        rel = abs(on_d / on_e2 - 1)
        agree = []
        for f in (0.95, 0.99, 1.01, 1.05):
            w = f * on_e2
            v = rho_default(build, kw, w).verdict
            r = rho_exp(build, kw, w, 2 * n_exp)
            ve = "stable" if r < 1 else "unstable"
            agree.append(v == ve or v == "marginal")
            print(f"{name:13s} {w:8.1f} rpm ({f:.2f} x onset): default {v:9s} exponential rho {r:.5f} ({ve})",
                  flush=True)
        dt = time.perf_counter() - t0
        print(f"{name:13s} onset: default {on_d:.1f} rpm, magnus2+split n={n_exp} {on_e:.1f} rpm, "
              f"n={2 * n_exp} {on_e2:.1f} rpm; difference {100 * rel:.3f} %  ({dt:.0f} s)", flush=True)
        rows.append(dict(mechanism=name, onset_default_rpm=on_d, onset_exp_rpm=on_e, onset_exp2_rpm=on_e2,
                         rel_diff=rel, n_exp=n_exp, verdicts_agree=all(agree), note="", time_s=dt))
    return rows


def write(rows, out, wall):
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, "stability.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    md = ["# Onset of parametric instability", "",
          f"`python benchmarks/stability.py`, {wall:.0f} s. Onset speed by bisection on the largest Floquet "
          "multiplier modulus (relative bracket 2e-4): the default tolerance-driven solve (`res.stability`, "
          "Radau IIA) against the paper's magnus2 hold with the exact stiff split on n and 2n elements. "
          "Verdicts compared at 0.95, 0.99, 1.01 and 1.05 x the onset.", "",
          "| mechanism | onset, default solve [rpm] | magnus2+split n [rpm] | magnus2+split 2n [rpm] | "
          "difference | verdicts agree |", "|---|---|---|---|---|---|"]
    for r in rows:
        if r["note"]:
            md.append(f"| {r['mechanism']} | {r['note']} | | | | |")
        else:
            md.append(f"| {r['mechanism']} | {r['onset_default_rpm']:.1f} | {r['onset_exp_rpm']:.1f} "
                      f"(n={r['n_exp']}) | {r['onset_exp2_rpm']:.1f} | {100 * r['rel_diff']:.3f} % | "
                      f"{r['verdicts_agree']} |")
    with open(os.path.join(out, "stability.md"), "w") as f:
        f.write("\n".join(md) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows = run(args.quick)
    write(rows, args.out, time.perf_counter() - t0)
    return rows


if __name__ == "__main__":
    main()
