#!/usr/bin/env python
"""Non-linear periodic responses of the four-bar preset up to its operating limit (issue 24).

Prints, and writes to ``benchmarks/results/nonlinear_branch.md``:

1. ``kf.solve`` of the four-bar preset (2 % modal damping) and of the same with the Rayleigh
   damping of the exact comparison (beta = 1.3708e-4 s, strain-rate damping in the exact
   model), no knob, at every 25 rpm from 50 rpm up to ``--top``: converged?, how (directly or by
   continuation in speed), the verdict and spectral radius of the orbit, the time;
2. the Rayleigh variant's peak mid-span chord deflections against the geometrically exact model
   (``benchmarks/results/exact_speeds.csv``, from ``benchmarks/exact_speeds.py``) where that
   settles to a 1-periodic state;
3. Newton's convergence at 300 rpm: the corrections of the final level's iteration and its
   number of linear solves;
4. ``kf.continuation`` of both from 200 rpm upward: the first loss of stability of the
   1-periodic branch and its kind, against where the exact model stops settling;
5. the mould oscillator's default scene: its linear solves and Table 3 (unchanged).

Usage::

    python benchmarks/nonlinear_branch.py                 # everything (about an hour on 2 cores)
    python benchmarks/nonlinear_branch.py --parts 1,2,3   # the solves only
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
sys.path.insert(0, os.path.dirname(HERE))

import numpy as np  # noqa: E402

import kedfem as kf  # noqa: E402
from kedfem.catalogue import info  # noqa: E402

RPM = 2 * math.pi / 60
BETA = 1.3708e-4
OUT = os.path.join(HERE, "results", "nonlinear_branch.md")


def scenes():
    e = info("four_bar")
    return {"modal 2 %": lambda w: e.scene({}, speed=w),
            f"Rayleigh beta {BETA:g} s": lambda w: e.scene({}, speed=w, damping=kf.Rayleigh(0.0, BETA))}


def exact_reference():
    path = os.path.join(HERE, "results", "exact_speeds.csv")
    ref = {}
    if not os.path.exists(path):
        return ref
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            if r["level"] == "best" and r["regime"] == "1-periodic" and r["quantity"] != "tip":
                ref.setdefault(float(r["speed_rpm"]), {})[r["quantity"]] = (float(r["peak_mm"]), float(r["u_mm"]))
    return ref


def part_solves(top: float, lines: list, results: dict):
    lines += ["## 1. kf.solve at every 25 rpm, no knob", "",
              "| damping | rpm | converged | reached | verdict | rho | time elements | error estimate | wall [s] |",
              "|---|---|---|---|---|---|---|---|---|"]
    for label, make in scenes().items():
        for rpm in np.arange(50.0, top + 1e-9, 25.0):
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    res = kf.solve(make(rpm * RPM), progress=False)
                    row = (res.converged, "continuation" if res.path else "Newton", res.stability.verdict,
                           f"{res.stability.spectral_radius:.4f}", res.elements,
                           f"{res.error.peak:.1e}" if res.error else "-")
                    results[(label, rpm)] = res
                except kf.KedError as e:
                    row = (False, type(e).__name__, str(e)[:60], "", "", "")
            wall = time.perf_counter() - t0
            lines.append(f"| {label} | {rpm:.0f} | " + " | ".join(str(x) for x in row) + f" | {wall:.1f} |")
            print(lines[-1], flush=True)
    lines.append("")


def part_exact(lines: list, results: dict):
    ref = exact_reference()
    label = f"Rayleigh beta {BETA:g} s"
    lines += ["## 2. Against the geometrically exact model (Rayleigh variant)", "",
              "Peak |mid-span chord deflection| [mm]; exact: best estimate +- u (benchmarks/exact_speeds.md, "
              "16 ANCF elements per link, 720 -> 1440 steps Richardson); kedfem: the preset's 4 elements per "
              "link, tolerance-driven time elements (rtol 1e-3).", "",
              "| rpm | link | exact [mm] | kedfem [mm] | difference % |", "|---|---|---|---|---|"]
    worst = 0.0
    for rpm in sorted(ref):
        if rpm <= 300 or (label, rpm) not in results:
            continue
        res = results[(label, rpm)]
        peaks = {p.link: p.deflection * 1e3 for p in res.peaks()}
        for link, (v, u) in ref[rpm].items():
            d = 100 * (peaks[link] - v) / v
            worst = max(worst, abs(d))
            lines.append(f"| {rpm:.0f} | {link} | {v:.4f} +- {u:.4f} | {peaks[link]:.4f} | {d:+.2f} |")
    lines += ["", f"Largest difference above 300 rpm: {worst:.2f} %.", ""]
    print("\n".join(lines[-3:]))


def part_newton(lines: list):
    sc = scenes()["modal 2 %"](300 * RPM)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(sc, progress=False)
    h = res.history
    lines += ["## 3. Newton at 300 rpm", "",
              f"Final level ({res.elements} elements): {len(h)} linear solves; relative corrections "
              + ", ".join(f"{x:.1e}" for x in h) + f"; path: {res.path or 'Newton from the coarser level'}.", ""]
    print(lines[-2])


def part_continuation(top: float, lines: list, only: str = "", lo: float = 200.0, max_points: int = 2000):
    lines += [f"## 4. kf.continuation from {lo:g} rpm", ""]
    for label, make in scenes().items():
        if only and not label.lower().startswith(only):
            continue
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            br = kf.continuation(make(lo * RPM), lo * RPM, top * RPM, errors=False, max_points=max_points,
                                 progress=False)
        first = br.first_loss_of_stability
        lines += [f"### {label}", "", "```", br.describe(), "```", "",
                  f"First loss of stability: {first.kind + ' at ' + format(first.value / RPM, '.2f') + ' rpm' if first else 'none up to ' + format(top, 'g') + ' rpm'}"
                  f" ({time.perf_counter() - t0:.0f} s).", ""]
        kf.write_branch(br, os.path.join(HERE, "results", "nonlinear_branch_" + label.split()[0].lower()))
        print("\n".join(lines[-6:]), flush=True)


def part_mould(lines: list):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(kf.default_scene(), progress=False)
        rep = kf.table3()
    lines += ["## 5. The mould oscillator's default scene", "",
              f"{res.iterations} linear solves on the final level (converged {res.converged}).", "", "```",
              rep.table(), "```", ""]
    print("\n".join(lines[-6:]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default="1,2,3,4,5")
    ap.add_argument("--top", type=float, default=450.0, help="highest speed of part 1 [rpm]")
    ap.add_argument("--continuation-top", type=float, default=600.0)
    ap.add_argument("--out", default=OUT, help="markdown file written")
    ap.add_argument("--continuation-lo", type=float, default=200.0)
    ap.add_argument("--max-points", type=int, default=2000)
    ap.add_argument("--only", default="", help="part 4 for one damping only: modal or rayleigh")
    a = ap.parse_args(argv)
    parts = {int(p) for p in a.parts.split(",")}
    lines = ["# Non-linear periodic responses of the four-bar preset", "",
             f"Generated by `python benchmarks/nonlinear_branch.py --parts {a.parts}` on "
             f"{time.strftime('%Y-%m-%d')}.", ""]
    results: dict = {}
    t0 = time.perf_counter()
    if parts & {1, 2}:
        part_solves(a.top, lines, results)
    if 2 in parts:
        part_exact(lines, results)
    if 3 in parts:
        part_newton(lines)
    if 4 in parts:
        part_continuation(a.continuation_top, lines, a.only.lower(), a.continuation_lo, a.max_points)
    if 5 in parts:
        part_mould(lines)
    lines.append(f"Total wall time {time.perf_counter() - t0:.0f} s.")
    with open(a.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
