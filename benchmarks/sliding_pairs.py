"""Sliding pairs: convergence of the flexible Whitworth quick-return in time and mesh (issue 15).

The Whitworth preset (``mechanisms/whitworth.py``: the crank pin's block slides along a
flexible slotted lever; inertia, coupling, axial_stiffening; 2 % modal damping; 120 rpm):

1. **Time**: the preset mesh (lever 16 elements) at the default tolerance (``rtol = 1e-3``) and
   at ``rtol = 1e-7``; the actual error of every link's peak deflection and stress against the
   tight solve, next to the estimate the default solve states.
2. **Mesh**: the lever in 4, 8, 16, 32 elements (the other links as preset) at ``rtol = 1e-5``;
   the lever's peaks against the Richardson limit of the 16/32 pair at the observed rate, and
   the mesh check's estimate (``kf.mesh_error``: the same scene on half the elements, rate 2
   credited on a link carrying a block).
3. **The oscillating cylinder** (``inverted_slider_crank(cylinder=True)``: a locked piston): the
   time elements the default tolerance takes (first-order convergence, see docs/modelling.md).

Writes ``benchmarks/results/sliding_pairs.md``. Run from the repository root::

    python benchmarks/sliding_pairs.py      # ~6 min on 2 cores
"""

from __future__ import annotations

import math
import os
import sys
import time
import warnings

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))

import kedfem as kf  # noqa: E402
from mechanisms import inverted_slider_crank, whitworth  # noqa: E402

EFFECTS = ("inertia", "coupling", "axial_stiffening")


def solve(mech, rtol):
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = kf.solve(kf.Scene(mech, effects=EFFECTS, damping=kf.ModalDamping(0.02), rtol=rtol))
    return res, time.perf_counter() - t0


def main():
    lines = ["# Sliding pairs: the flexible Whitworth quick-return in time and mesh", "",
             "`python benchmarks/sliding_pairs.py`; preset scene (inertia, coupling, axial_stiffening, "
             "2 % modal damping, 120 rpm).", ""]
    # 1. time
    res, wall = solve(whitworth.build(), 1e-3)
    ref, wall_ref = solve(whitworth.build(), 1e-7)
    lines += ["## 1. Time discretisation (lever 16 elements)", "",
              f"Default tolerance: {res.elements} time elements, {wall:.1f} s; reference rtol 1e-7: "
              f"{ref.elements} time elements, {wall_ref:.1f} s.", "",
              "| link | peak deflection [mm] | actual error | stated +- | peak stress [MPa] | actual error "
              "| stated +- |", "|---|---|---|---|---|---|---|"]
    rp = {p.link: p for p in ref.peaks()}
    for p in res.peaks():
        e = res.error.link(p.link)
        r = rp[p.link]
        lines.append(f"| {p.link} | {p.deflection * 1e3:.6g} | {abs(p.deflection / r.deflection - 1):.1e} | "
                     f"{e.deflection:.1e} | {p.stress / 1e6:.6g} | {abs(p.stress / r.stress - 1):.1e} | "
                     f"{e.stress:.1e} |")
        print(lines[-1], flush=True)
    # 2. mesh
    lines += ["", "## 2. Mesh (the slotted lever)", "",
              "| lever elements | peak deflection [mm] | peak stress [MPa] | stress vs limit | "
              "mesh check estimate (stress) | wall [s] |", "|---|---|---|---|---|---|"]
    rows = []
    for ne in (4, 8, 16, 32):
        r, w = solve(whitworth.build(lever_elements=ne), 1e-5)
        est = kf.mesh_error(r).link("lever").stress if ne > 4 else math.nan
        p = {x.link: x for x in r.peaks()}["lever"]
        rows.append((ne, p.deflection, p.stress, est, w))
        print(ne, p.stress, est, w, flush=True)
    s16, s32 = rows[2][2], rows[3][2]
    s8 = rows[1][2]
    rate = math.log2(abs(s8 - s16) / abs(s16 - s32))
    limit = s32 + (s32 - s16) / (2**rate - 1)
    for ne, d, s, est, w in rows:
        lines.append(f"| {ne} | {d * 1e3:.6g} | {s / 1e6:.6g} | {abs(s / limit - 1):.1e} | {est:.1e} | {w:.1f} |")
    lines += ["", f"Observed rate of the peak stress (8/16/32): {rate:.2f}; Richardson limit "
              f"{limit / 1e6:.6g} MPa.", ""]
    # 3. the cylinder
    cyl, wc = solve(inverted_slider_crank.build(cylinder=True), 1e-3)
    lines += ["## 3. Oscillating cylinder (locked piston on a flexible barrel)", "",
              f"Default tolerance: {cyl.elements} time elements, {wc:.1f} s; error estimate "
              f"{cyl.error.peak:.1e}.", ""]
    out = os.path.join(HERE, "results", "sliding_pairs.md")
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
