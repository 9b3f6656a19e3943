"""Craig-Bampton on the four-bar at converged time discretisation (issue 6 acceptance).

Run: ``python benchmarks/cb_four_bar.py`` (~6 min on 2 cores; ``--steps 5760 11520`` to
choose the grids). The four-bar (``mechanisms/four_bar.py``, 8 elements per link, linear
effects, 2 % modal damping, magnus2) converges slowly in time: the full model's coupler stress
moves 14 % from 5760 to 11520 time elements and 1.2 % from 11520 to 23040, so the reduced
model (4 fixed-interface modes per link plus the static correction) is compared with the full
model at 23040 elements. Prints the peak stresses and mid-span deflections of both, their
relative differences and the wall times.
"""

import argparse
import os
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import kedfem as kf  # noqa: E402
from mechanisms import four_bar  # noqa: E402


def peaks(res):
    s = np.array([res.stress(lk).max() for lk in ("crank", "coupler", "follower")])
    w = np.array([np.abs(res.deflection(lk, 0.5, relative_to="chord")).max() for lk in ("coupler", "follower")])
    return s, w


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, nargs="+", default=[23040], help="time elements (default 23040)")
    ap.add_argument("--elements", type=int, default=8, help="elements per link (default 8)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    m = four_bar.build(elements=args.elements)
    for n in args.steps:
        out = {}
        for label, red in (("full", None), ("CB(4)+sc", kf.CraigBampton(modes=4))):
            sc = kf.Scene(m, steps=n, effects=("inertia", "coupling", "axial_stiffening"),
                          damping=kf.ModalDamping(0.02), hold="magnus2", reduction=red)
            t0 = time.perf_counter()
            res = kf.solve(sc)
            dt = time.perf_counter() - t0
            out[label] = (peaks(res), dt)
            (s, w) = out[label][0]
            print(f"n={n:6d} {label:9s} N={res.model.n_dof:3d} {dt:7.1f} s  stress crank/coupler/follower "
                  f"{s[0] / 1e6:.4f} / {s[1] / 1e6:.4f} / {s[2] / 1e6:.4f} MPa  deflection coupler/follower "
                  f"{w[0] * 1e3:.5f} / {w[1] * 1e3:.5f} mm", flush=True)
        (sf, wf), tf = out["full"]
        (sr, wr), tr = out["CB(4)+sc"]
        fmt = lambda a: " / ".join(f"{x:.1e}" for x in a)  # noqa: E731
        print(f"n={n:6d} CB vs full: stress {fmt(np.abs(sr / sf - 1))}, deflection {fmt(np.abs(wr / wf - 1))}; "
              f"speed-up {tf / tr:.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
