#!/usr/bin/env python
"""kedfem's walking beam (a flexible link through its saddle pin) against the exact model.

The pumping unit of ``examples/pumping_unit.py`` (beam through the saddle bearing ``S``, rigid
crank body and pitman) under a constant polished-rod load, no gravity, Rayleigh damping, at its
8 strokes a minute and at a faster, lighter variant. The exact model (``benchmarks/exact``: ANCF
cables, the beam's node at the saddle sharing the pin's point, index-3 generalised-alpha marched
cycle by cycle) on three meshes and three time steps, Richardson-extrapolated; kedfem with
``inertia + coupling + axial_stiffening + loads`` (and ``geometric_nonlinearity``). Compared: the
horse head's vertical elastic displacement over the cycle (exact position minus the rigid-body
one) and the beam's mid-span deflection relative to its chord.

Usage::

    python benchmarks/exact_walking_beam.py            # about 5 min on 2 cores
    python benchmarks/exact_walking_beam.py --quick    # coarse levels

Writes ``benchmarks/results/exact_walking_beam.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import math
import os
import sys
import time
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
# one BLAS thread, the repository and benchmarks/ on the path: exact_comparison's preamble
from exact_comparison import HERE, ROOT, refined_peak, richardson, sub  # noqa: E402

import numpy as np  # noqa: E402

import kedfem as kf  # noqa: E402
import exact as ex  # noqa: E402

_spec = importlib.util.spec_from_file_location("pumping_unit", os.path.join(ROOT, "examples", "pumping_unit.py"))
pu = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(pu)

ROD = 50e3
LIGHT = kf.Section(A=0.0050, I=1.0e-4, c=0.15)   # a lighter beam (W12 size)
#: case -> (strokes per minute, section, Rayleigh beta [s]: about 2 % on the beam's first mode)
CASES = {"unit, 8 spm": (8.0, None, 1.2e-4), "light beam, 20 spm": (20.0, LIGHT, 3.7e-4)}
LEVELS = {"full": dict(meshes=(11, 22, 44), steps=(360, 720, 1440), tol=1e-8),
          "quick": dict(meshes=(11, 22), steps=(180, 360), tol=1e-7)}


def build(spm, section):
    m = pu.build(speed=2 * math.pi * spm / 60, rod_load=ROD, fluid_load=0.0, gravity=False, beam_elements=22)
    if section is not None:
        lk = m.links["beam"]
        m.links["beam"] = dataclasses.replace(lk, section=section, mass=lk.material.rho * section.A * lk.length,
                                              J=lk.material.rho * section.A * lk.length**3 / 12)
    # the exact model takes constant loads only: the rods' weight (the fluid load is zero)
    m.loads = {k: v for k, v in m.loads.items() if v.profile is None}
    return m


def head_elastic(r: ex.ExactResult, mech):
    """Vertical elastic displacement of the horse head over the exact model's last cycle [m]."""
    mo = kf.kinematics(mech, times=r.t)
    rigid = mo.r[:, mo.joint_names.index("H"), 1]
    return r.q_cycle[:, r.model.pdofs["H"][1]] - rigid


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    lv = LEVELS["quick" if a.quick else "full"]
    lines = ["# kedfem's walking beam against the exact model", "",
             "`python benchmarks/exact_walking_beam.py" + (" --quick" if a.quick else "") + "`: "
             f"exact meshes {lv['meshes']} elements on the beam, steps {lv['steps']} per cycle; rod load "
             f"{ROD / 1e3:g} kN at the horse head, no gravity.", "",
             "| case | quantity | exact peak [m] | +- | kedfem I+C+A | diff | max diff | kedfem +GN | diff | max diff |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for case, (spm, section, beta) in CASES.items():
        mech = build(spm, section)
        runs = {}
        t0 = time.perf_counter()
        m_lo, m_hi = lv["meshes"][-2], lv["meshes"][-1]
        s_lo, s_hi = lv["steps"][-2], lv["steps"][-1]
        prev = None
        for ne, n in ((lv["meshes"][0], lv["steps"][0]), (m_hi, s_lo), (m_hi, s_hi), (m_lo, s_hi)):
            if (ne, n) in runs:
                continue
            prev = ex.simulate(mech, elements_per_link=ne, steps_per_cycle=n, beta=beta, tol=lv["tol"],
                               init=prev, cycles_max=60, keep_states=True)
            runs[(ne, n)] = prev
            print(f"  exact {case} ne={ne} steps={n}: {prev.cycles} cycles, converged {prev.converged}, "
                  f"{prev.wall_time:.1f} s", flush=True)
        hist = {}
        for qn in ("head", "beam"):
            def h(r):
                return head_elastic(r, mech) if qn == "head" else r.deflection["beam"]
            fine, coarse = h(runs[(m_hi, s_hi)]), h(runs[(m_hi, s_lo)])
            ref = richardson(sub(fine, s_hi, s_lo), coarse, 2.0)  # on the s_lo grid
            mesh_change = np.max(np.abs(sub(h(runs[(m_lo, s_hi)]), s_hi, s_lo) - sub(fine, s_hi, s_lo)))
            u = np.max(np.abs(ref - coarse)) / 3 + mesh_change / 15
            hist[qn] = (ref, u)
        ca = runs[(m_hi, s_lo)].crank_angle
        ked = {}
        for tag, eff in (("ICA", ("inertia", "coupling", "axial_stiffening", "loads")),
                         ("GN", ("inertia", "coupling", "axial_stiffening", "geometric_nonlinearity", "loads"))):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = kf.solve(kf.Scene(mech, effects=eff, damping=kf.Rayleigh(beta=beta), rtol=1e-6), progress=False)
            rs = res.resample(crank_angle=ca)
            # the beam's mid-span from the whole H-B chord, as the exact model reads it (kedfem's
            # "chord" of a link through joints is the chord of the stretch around the point)
            v = [rs.deflection("beam", xi, relative_to="frame") for xi in (0.0, 0.5, 1.0)]
            ked[tag] = {"head": rs.joint_displacement("H")[:, 1], "beam": v[1] - 0.5 * (v[0] + v[2])}
        for qn in ("head", "beam"):
            ref, u = hist[qn]
            pr = refined_peak(ref)
            row = [case, {"head": "horse head, vertical", "beam": "beam mid-span, from chord"}[qn],
                   f"{pr:.6e}", f"{u / pr:.1e}"]
            for tag in ("ICA", "GN"):
                pk = refined_peak(ked[tag][qn])
                row += [f"{pk:.6e}", f"{pk / pr - 1:+.1e}", f"{float(np.max(np.abs(ked[tag][qn] - ref)) / pr):.1e}"]
            lines.append("| " + " | ".join(row) + " |")
            print(lines[-1], flush=True)
        print(f"  {case}: {time.perf_counter() - t0:.0f} s", flush=True)
    lines += ["", "diff: kedfem's peak / the exact peak - 1; max diff: the largest difference of the histories "
              "over the cycle / the exact peak; +-: the reference's uncertainty (time extrapolation change / 3 "
              "plus the last mesh change / 15), relative to its peak."]
    out = os.path.join(HERE, "results", "exact_walking_beam" + ("_quick" if a.quick else "") + ".md")
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
