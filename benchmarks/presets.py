"""The catalogue's presets as a user runs them: time, elements, error, and the forecast of it.

Each case is ``kf.solve`` of a scene at its default tolerance (the presets' scene files in
``examples/scenes``, the default scene, and the quasi-static and heavy cases issue 25 names): the
time elements it ends on, its wall time (best of ``--repeats``, one BLAS thread), the forecast the
solve made of its own time (``res.timings.forecast``, after its second level) and the ratio, the
printed error estimate, and issue 25's target for it. Machines are noisy, so every time is also
given in units of a baseline measured in the same run (a batched ``(192, 66, 66)`` LU solve, the
kind of work a level does) and the targets are judged on the times of this run.

Run from the repository root::

    python benchmarks/presets.py              # ~3 min; writes benchmarks/results/presets.md
    python benchmarks/presets.py --heavy      # also the Whitworth with geometric_nonlinearity and
                                              # 32 lever elements (minutes)
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import platform
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))

import kedfem as kf  # noqa: E402
import mechanisms  # noqa: E402
from kedfem.solvers.threads import one_blas_thread  # noqa: E402

RESULTS = os.path.join(HERE, "results")
RPM = 2 * math.pi / 60


def scene_file(name):
    return lambda: kf.load_scene(os.path.join(HERE, "..", "examples", "scenes", f"{name}.toml"))[0]


def preset_scene(name, **build):
    def make():
        pre = mechanisms.get(name).PRESET
        return kf.Scene(mechanisms.build(name, **build), effects=pre.effects, damping=pre.damping)
    return make


def cases(heavy: bool):
    """name -> (scene factory, target [s] or None, what the target is)."""
    out = {
        "four-bar (with geometric_nonlinearity)": (scene_file("four_bar"), 0.3),
        "six-bar": (scene_file("six_bar"), 0.5),
        "default scene (mould oscillator)": (kf.default_scene, 0.4),
        "inverted slider-crank": (scene_file("inverted_slider_crank"), 0.5),
        "Whitworth quick-return": (scene_file("whitworth"), 2.0),
        "oscillating cylinder": (preset_scene("inverted_slider_crank", cylinder=True), 5.0),
        "slider-crank": (scene_file("slider_crank"), None),
        "slider-crank at 1 rpm, with gravity (quasi-static)": (
            lambda: kf.Scene(mechanisms.build("slider_crank", speed=1 * RPM), rtol=1e-3,
                             effects=("inertia", "coupling", "axial_stiffening", "gravity"),
                             damping=kf.ModalDamping(0.02)), 2.0),
        "four-bar at 5 rpm (quasi-static)": (preset_scene("four_bar", speed=5 * RPM), None),
    }
    if heavy:
        def whitworth_gn():
            return kf.Scene(mechanisms.build("whitworth", lever_elements=32), rtol=1e-3,
                            effects=("inertia", "coupling", "geometric_nonlinearity"), damping=kf.ModalDamping(0.02))
        out["Whitworth, geometric_nonlinearity, 32 lever elements"] = (whitworth_gn, 60.0)
    return out


def baseline(repeats: int = 5) -> float:
    """Seconds of one batched LU solve of 192 systems of 66 unknowns with 67 right-hand sides."""
    rng = np.random.default_rng(0)
    A = rng.standard_normal((192, 66, 66)) + 66 * np.eye(66)
    B = rng.standard_normal((192, 66, 67))
    best = math.inf
    with one_blas_thread():
        for _ in range(repeats):
            t0 = time.perf_counter()
            np.linalg.solve(A, B)
            best = min(best, time.perf_counter() - t0)
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--heavy", action="store_true")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    base0 = baseline()
    rows = []
    for name, (make, target) in cases(args.heavy).items():
        best, res = math.inf, None
        for _ in range(args.repeats if name.find("geometric_nonlinearity, 32") < 0 else 1):
            sc = make()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                with one_blas_thread():
                    t0 = time.perf_counter()
                    r = kf.solve(sc, progress=False)
                    w = time.perf_counter() - t0
            if w < best:
                best, res = w, r
        fc = res.timings.forecast
        rows.append(dict(case=name, elements=res.elements, time=best, forecast=fc, target=target,
                         estimate=res.error.peak if res.error is not None else math.nan,
                         levels="/".join(map(str, res.error.levels)) if res.error is not None else "-"))
        print(f"{name:52s} n {res.elements:5d} ({rows[-1]['levels']:>12s}) {best:7.3f} s  forecast "
              f"{fc if fc is not None else math.nan:7.3f} s  est {rows[-1]['estimate']:.1e}  target "
              f"{'-' if target is None else f'{target:g} s'}", flush=True)
    base = min(base0, baseline())
    wall = time.perf_counter() - t_start
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    L = [f"## Presets as a user runs them ({datetime.date.today().isoformat()})", "",
         f"`python benchmarks/presets.py{' --heavy' if args.heavy else ''}` on {platform.machine()}, "
         f"{os.cpu_count()} CPUs, load at the end {load}, one BLAS thread, best of {args.repeats}; "
         f"wall time {wall:.0f} s. Baseline: one batched LU solve of 192 systems of 66 unknowns "
         f"({base * 1e3:.2f} ms in this run); the forecast is the solve's own, made after its second "
         "level.", "",
         "| case | elements (levels) | time [s] | / baseline | forecast [s] | forecast / time | "
         "printed error | issue 25 target | met |",
         "|---|---|---:|---:|---:|---:|---:|---|---|"]
    for r in rows:
        fc, tg, w = r["forecast"], r["target"], r["time"]
        ok = "-" if tg is None else ("yes" if w <= tg else "**no**")
        fcs_ = "-" if fc is None else f"{fc:.3f} | {fc / w:.2f}"
        fcs_ = fcs_ if fc is not None else "- | -"
        tgs = "-" if tg is None else f"< {tg:g} s"
        L.append(f"| {r['case']} | {r['elements']} ({r['levels']}) | {w:.3f} | {w / base:.0f} | {fcs_} | "
                 f"{r['estimate']:.1e} | {tgs} | {ok} |")
    fcs = [r["forecast"] / r["time"] for r in rows if r["forecast"] is not None]
    L += ["", f"Forecast within 2x of the time in {sum(0.5 <= x <= 2 for x in fcs)} of {len(fcs)} cases "
          f"(forecast / time {min(fcs):.2f} .. {max(fcs):.2f})."]
    md = "\n".join(L) + "\n"
    print("\n" + md)
    if not args.no_write:
        os.makedirs(RESULTS, exist_ok=True)
        with open(os.path.join(RESULTS, "presets.md"), "w") as f:
            f.write(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
