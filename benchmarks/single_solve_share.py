"""Where a single solve's time goes: the share of the periodic solver (issue 25: at least half).

The slider-crank (8 rod elements, 2 % modal damping, the linear KED effects), one radau3 solve on
48 time elements without an estimate, repeated; prints the median wall time and the median and
range of ``res.timings.solve / res.timings.total`` (a ratio of one run's own timings, so a busy
machine shifts it less than the times).

Run from the repository root::

    python benchmarks/single_solve_share.py
"""

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import kedfem as kf  # noqa: E402
from kedfem.solvers.threads import one_blas_thread  # noqa: E402
from mechanisms import slider_crank  # noqa: E402


def main(repeats: int = 15):
    m = slider_crank.build(elements=8)
    sc = kf.Scene(m, effects=("inertia", "coupling", "axial_stiffening"), damping=kf.ModalDamping(0.02),
                  method="radau3", steps=48, estimate=False)
    with one_blas_thread():
        kf.solve(sc)
        share, total = [], []
        for _ in range(repeats):
            t = time.perf_counter()
            r = kf.solve(sc)
            total.append(time.perf_counter() - t)
            share.append(r.timings.solve / r.timings.total)
    print(f"slider-crank, one radau3 solve on 48 elements: {1e3 * np.median(total):.1f} ms (median of {repeats}); "
          f"periodic solver {np.median(share):.0%} of it (range {min(share):.0%} .. {max(share):.0%})")


if __name__ == "__main__":
    main()
