"""A graded family of time elements for the tolerance-driven solve: a research probe (not used by kedfem).

Issue 25 asks for time elements where the motion needs them. This probe grades them the simplest
way that keeps the estimates' argument (levels of one family, every element halved):

1. one uniform radau3 level on ``N0`` elements, its defect-corrected solution
   (:mod:`kedfem.solvers.defect`), the largest response error in each element ``e_j``;
2. a density per second ``rho_j = e_j^(1/4) / h_j`` (an element of error ``e`` needs ``e^(1/4)``
   pieces for a given error, the dense output being of order 4), at least an eighth of its largest,
   and at least half its neighbours' (three passes); the time warp ``s(t)`` its normalised integral;
3. every level of ``kf.solve`` on the edges ``t(s)`` of ``n`` uniform ``s``-elements, those snapped
   to the data's kinks in ``s`` (``snapped_edges``) and mapped back, by replacing
   ``_Run.problem`` (the rest of the refinement, its estimates, resolution floor and stability
   floor unchanged: they still count elements, not the longest one);

and compares elements, time (the density's level not counted) and the true error against a
uniform radau3 reference on ``NREF`` elements with the uniform ``kf.solve``.

Measured (2026-11-27): the press at rtol 1e-3 96 graded elements against 192 uniform (true errors
1.6e-6 and 7.4e-7, both far inside rtol) but at 1e-4 1536 against 384; the offset slider-crank at
1e-3 384 against 768 (true 5.9e-5 and 6.9e-6, estimates honest); the Whitworth at 1e-3 768 against
384. So grading by the error density alone helps where the error is local and the resolution
floor does not bind, and costs elements where the longest graded element no longer resolves the
excited modes, which the refinement's rules, counting elements, do not see: a graded family
needs them to read the longest element (and the stability floor the elements' own lengths).

A second family, ``refine`` (2026-11-28), keeps every count the rules read: level ``n`` is the
``n`` uniform elements (snapped to the kinks as ``kf.solve`` snaps them), and each of them whose
part of the cycle carried a large error on the ``N0``-element level is split into ``m`` equal
pieces, ``m`` a power of two with ``m^4`` the ratio of that error to the ``Q`` quantile of the
elements' errors (at most ``CAP``). The longest element stays ``T / n``, so the resolution and
stability floors hold as for uniform elements, and every level halves every element of the one
before. What it measured on the press, the offset slider-crank, the Whitworth and the shaper (a
gain only where the error sits at a load's kinks): docs/performance.md, issue 25's twelfth part.

Run::

    cd /work/main && . .venv/bin/activate
    OPENBLAS_NUM_THREADS=1 python benchmarks/graded_probe.py "press, forming load*" 1e-3,1e-4 3072 48
    OPENBLAS_NUM_THREADS=1 python benchmarks/graded_probe.py "whitworth;offset_slider_crank*" 1e-3 3072 192
    OPENBLAS_NUM_THREADS=1 python benchmarks/graded_probe.py "press, forming load*;whitworth;offset_slider_crank*;shaper, cutting load*" 1e-3,1e-4 3072 48 refine

Arguments: cases (``;``-separated names of ``benchmarks/error_estimate.py``'s cases), rtols
(``,``-separated), ``NREF``, ``N0``, and optionally the family: ``warp`` (the default) or
``refine``.
"""
from __future__ import annotations

import math
import os
import sys
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, ".."))
import kedfem as kf  # noqa: E402
from kedfem.analysis import pipeline  # noqa: E402
from kedfem.analysis.problem import PeriodicProblem, snapped_edges  # noqa: E402
import error_estimate  # noqa: E402
from grading_potential import ORDER, element_errors  # noqa: E402

CAP = 8.0      # largest ratio of the density (warp), most pieces of an element (refine)
Q = 0.7        # refine: the quantile of the elements' errors that the split elements are brought to


def density(scene, n0: int):
    """The uniform level's edges (n0 + 1,) and the time warp's values there (the density's
    normalised integral, 0 .. period)."""
    edges, e, _need = element_errors(scene, n0)
    h = np.diff(edges)
    rho = np.maximum(e, 1e-300) ** (1.0 / ORDER) / h  # pieces per second
    rho = np.maximum(rho, rho.max() / CAP)
    for _ in range(3):  # each element at least half its neighbours' density
        rho = np.maximum(rho, 0.5 * np.maximum(np.roll(rho, 1), np.roll(rho, -1)))
    warp = np.concatenate([[0.0], np.cumsum(rho * h)])
    return edges, warp * (scene.period / warp[-1])


def graded_edges(n: int, T: float, edges0, warp, breaks) -> np.ndarray:
    """``n`` elements uniform in the warped time, snapped to the kinks there, mapped back."""
    b = np.mod(np.asarray(breaks, dtype=float), T)
    s = snapped_edges(n, T, np.interp(b, edges0, warp))
    if s is None:
        s = np.arange(n + 1) * (T / n)
    t = np.interp(s, warp, edges0)
    t[0], t[-1] = 0.0, T
    for x in b:  # the kinks' own values (the problem's left-limit stages look them up)
        j = int(np.argmin(np.abs(t - x)))
        if abs(t[j] - x) < 1e-9 * T:
            t[j] = x
    return t


def pieces(scene, n0: int) -> np.ndarray:
    """refine: the pieces (n0,) each part ``[j, j + 1) T / n0`` of the cycle splits its elements
    into, from the defect-corrected error of one uniform level on ``n0`` elements."""
    _edges, e, _need = element_errors(scene, n0)
    m = np.clip((e / np.quantile(e, Q)) ** (1.0 / ORDER), 1.0, CAP)
    return (2 ** np.ceil(np.log2(m) - 1e-9)).astype(int)


def refined_edges(n: int, T: float, m, breaks) -> np.ndarray:
    """refine: ``n`` uniform elements, snapped to the kinks, each split into the pieces ``m`` of
    the part of the cycle its midpoint lies in (``sum`` of them elements in all)."""
    e = snapped_edges(n, T, breaks)
    if e is None:
        e = np.arange(n + 1) * (T / n)
    part = np.minimum((0.5 * (e[:-1] + e[1:]) / T * m.size).astype(int), m.size - 1)
    k = m[part]
    kk = np.repeat(k, k)  # each piece's element's piece count
    frac = (np.arange(kk.size) - np.repeat(np.cumsum(k) - k, k)) / kk  # its index within the element / count
    return np.append(np.repeat(e[:-1], k) + frac * np.repeat(np.diff(e), k), T)


def solve_graded(scene, edges0=None, warp=None, m=None):
    """``kf.solve`` with every level on the graded family (``_Run.problem`` replaced): the warp's
    (``edges0``, ``warp``) or the refinement's (``m``)."""
    original = pipeline._Run.problem

    def problem(self, n):
        T = self.scene.period
        e = graded_edges(n, T, edges0, warp, self.breaks()) if m is None else refined_edges(n, T, m, self.breaks())
        ne = e.size - 1  # (refine: more elements than the count the rules read)
        ti = self.scheme.instants(ne, T, e)
        return ti, PeriodicProblem(self.scene, self.model, self.cycle, self.scheme, ne,
                                   damping_field=self.damping_field(ne, True), stiff=self.stiff, edges=e,
                                   kinks=self.breaks(), chord=True)

    pipeline._Run.problem = problem
    try:
        t0 = time.perf_counter()
        res = kf.solve(scene)
        return res, time.perf_counter() - t0
    finally:
        pipeline._Run.problem = original


def true_errors(res, ref):
    """Largest true relative error of the peaks, and the smallest estimate / true above 1e-7."""
    pairs = []
    for p, r in zip(res.peaks(), ref.peaks()):
        e = res.error.link(p.link)
        for est, a, b in ((e.deflection, p.deflection, r.deflection), (e.stress, p.stress, r.stress)):
            pairs.append((abs(a - b) / abs(b), est))
    big = [est / t for t, est in pairs if t > 1e-7]
    return max(t for t, _ in pairs), (min(big) if big else math.inf)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    names, rtols, n_ref, n0 = argv[0].split(";"), [float(x) for x in argv[1].split(",")], int(argv[2]), int(argv[3])
    family = argv[4] if len(argv) > 4 else "warp"
    if family not in ("warp", "refine"):
        raise SystemExit(f"family must be warp or refine, not {family!r}")
    cases = error_estimate.cases(False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in names:
            mech, kw = cases[name]
            ref = kf.solve(kf.Scene(mech, steps=n_ref, estimate=False, **kw))
            for rtol in rtols:
                sc = kf.Scene(mech, rtol=rtol, **kw)
                t0 = time.perf_counter()
                uni = kf.solve(sc)
                tu = time.perf_counter() - t0
                if family == "warp":
                    gr, tg = solve_graded(sc, *density(sc, n0))
                else:
                    m = pieces(sc, n0)
                    gr, tg = solve_graded(sc, m=m)
                    print(f"  refine: {n0} parts, pieces up to {m.max()}, {m.sum() / m.size - 1:+.0%} elements", flush=True)
                eu, ru = true_errors(uni, ref)
                eg, rg = true_errors(gr, ref)
                print(f"{name[:22]:22s} {rtol:.0e} uniform {uni.elements:5d} {tu:6.2f} s true {eu:.1e} est/true >= "
                      f"{ru:.2f} | graded {gr.elements:5d} {tg:6.2f} s true {eg:.1e} est/true >= {rg:.2f} "
                      f"(levels {'/'.join(map(str, gr.error.levels))})", flush=True)


if __name__ == "__main__":
    main()
