"""How well can two levels say where a tolerance-driven solve ends? (issue 25: the forecast)

For every case and tolerance of the error-estimate study (``benchmarks/error_estimate.py``'s
``cases``, rtol 1e-2 .. 1e-5) it solves as a user does and records, when the solve makes its
forecast after the second level, the level the forecast expects to end on and what the two levels
say (the largest relative differences of their displacements, of their peaks, of their histories
on a common grid); then the level the solve did end on, its wall time and its forecast. It prints
how often the forecast's level is the final one, a level short, two or more short, or long, and the
same for extrapolations of the two levels' differences at other orders (a guide to whether a better
rule exists; the numbers the study's forecast makes are in ``error_estimate.md``).

Run (about 3 min, one BLAS thread)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/forecast_levels.py

The extra reads it makes after the second level are not counted in the forecast's read-out cost
(the solve's own forecast is made before them).
"""

from __future__ import annotations

import math
import os
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))
sys.path.insert(0, HERE)
import kedfem as kf  # noqa: E402
from kedfem.analysis import forecast as fc  # noqa: E402
import error_estimate  # noqa: E402


def _rel(a, b) -> float:
    return float(np.max(np.abs(b - a)) / max(float(np.max(np.abs(b))), 1e-300))


def record_forecasts():
    """Rows of (case, rtol, the forecast's level, the final level, the two levels' differences)."""
    seen: dict = {}
    orig = fc.Forecast.forecast

    def hooked(self, need):
        out = orig(self, need)
        if len(self.levels) == 2 and not seen:
            a, b = self.levels
            g = self.output_steps(self.scheme.refine(b.n))
            oa, ob = self.observe(0, g), self.observe(1, g)
            peaks = [_rel(oa.deflection, ob.deflection)]
            st = ob.stress > 0
            if st.any():
                peaks.append(_rel(oa.stress[st], ob.stress[st]))
            hist = [_rel(x, y) for x, y in zip(oa.stress_history + oa.deflection_history,
                                               ob.stress_history + ob.deflection_history) if y.size]
            t = np.arange(64) * (self.scene.period / 64)
            seen.update(n1=a.n, n2=b.n, target=self.forecast_elements(need), peaks=max(peaks),
                        history=max(hist), disp=_rel(a.discrete.at(t)[0], b.discrete.at(t)[0]))
        return out

    fc.Forecast.forecast = hooked
    rows = []
    try:
        for case, (mech, kw) in error_estimate.cases(False).items():
            for rtol in (1e-2, 1e-3, 1e-4, 1e-5):
                seen.clear()
                t0 = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    res = kf.solve(kf.Scene(mech, rtol=rtol, **kw), progress=False)
                rows.append(dict(case=case, rtol=rtol, final=res.elements, wall=time.perf_counter() - t0,
                                 forecast=res.timings.forecast, **seen))
                print(f"{case:36s} rtol {rtol:7.0e} levels {seen.get('n1')}/{seen.get('n2')} forecast level "
                      f"{seen.get('target')} final {res.elements}", flush=True)
    finally:
        fc.Forecast.forecast = orig
    return rows


def extrapolated(row, diff: float, order: float) -> int:
    """The level at which ``diff`` between the two levels, extrapolated at ``order``, meets rtol
    (at least the third level)."""
    n2, err, n = row["n2"], diff / (2.0 ** order - 1.0), 2 * row["n2"]
    while err * (n2 / n) ** order > row["rtol"] and n < 20000:
        n *= 2
    return max(n, 2 * n2)


def tally(rows, level_of) -> str:
    lr = np.array([math.log2(r["final"] / level_of(r)) for r in rows if "n2" in r])
    return (f"exact {int((lr == 0).sum())}, one level short {int((lr == 1).sum())}, two or more short "
            f"{int((lr >= 2).sum())}, long {int((lr < 0).sum())} (of {lr.size})")


def main():
    rows = record_forecasts()
    print()
    print("the forecast's level:", tally(rows, lambda r: r["target"]))
    for order in (3.0, 4.0, 5.0):
        print(f"peaks and displacements at order {order:g}:",
              tally(rows, lambda r, o=order: extrapolated(r, max(r["peaks"], r["disp"]), o)))
        print(f"histories at order {order:g}:", tally(rows, lambda r, o=order: extrapolated(r, r["history"], o)))
    q = [r["forecast"] / r["wall"] for r in rows if r.get("forecast")]
    print(f"forecast within 2x of the wall time in {sum(0.5 <= x <= 2 for x in q)} of {len(q)}")


if __name__ == "__main__":
    main()
