"""What accuracy costs: error versus wall time for every accuracy knob.

For each mechanism (the slider-crank, four-bar and six-bar presets, and the
default scene, the mould oscillator) the error of the peak mid-span deflection
and the peak stress of every flexible link (the largest relative error over
the links) is measured against a converged reference: Radau IIA collocation on
many elements, checked by Gauss-Legendre collocation on as many (their
agreement is printed as the reference's uncertainty). Knobs:

1. *time elements per scheme* (``estimate=False``: one solve, the bare cost):
   radau3, radau2, gauss3, gauss2, magnus2 with and without the exact stiff
   split, foh, and fourier where its dense system stays small;
2. *the tolerance* (``rtol`` and the ``accuracy`` presets; the solve with its
   three-level estimate, as a user runs it): elements chosen, time, true and
   estimated error;
3. *elements per link* (mesh), at a converged time discretisation;
4. *Craig-Bampton modes* per link (with the static correction);
5. *the non-linear tolerance* ``eps`` (mould).

Times are wall-clock medians of three runs (one run above 2 s) with BLAS on
one thread (threadpoolctl), on a shared 2-core machine: compare within a run.
Written to ``benchmarks/results/accuracy_cost.{md,csv}`` and
``accuracy_cost.png`` (error versus time per mechanism, one line per scheme).

Run from the repository root::

    python benchmarks/accuracy_cost.py            # ~10 min
    python benchmarks/accuracy_cost.py --quick    # two mechanisms, short ladders, ~30 s
"""

from __future__ import annotations

import argparse
import csv
import datetime
import os
import platform
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))

import kedfem as kf  # noqa: E402
from kedfem.fe.effects import LINEAR_EFFECTS  # noqa: E402
import mechanisms  # noqa: E402
from kedfem.analysis.scene import ACCURACY_PRESETS  # noqa: E402

LINEAR = LINEAR_EFFECTS


def cases(quick: bool):
    """name -> (build(**mech params) -> Mechanism, scene keywords, reference elements)."""
    z2 = kf.ModalDamping(0.02)
    out = {
        "slider-crank": (lambda **p: mechanisms.build("slider_crank", **p), dict(effects=LINEAR, damping=z2), 768),
        "four-bar": (lambda **p: mechanisms.build("four_bar", **p), dict(effects=LINEAR, damping=z2), 1536),
    }
    if not quick:
        from kedfem.analysis.defaults import MOULD_EFFECTS
        out["six-bar"] = (lambda **p: mechanisms.build("six_bar", **p), dict(effects=LINEAR, damping=z2), 1536)
        out["mould oscillator"] = (lambda **p: mechanisms.build("mould_oscillator", **p),
                                   dict(effects=MOULD_EFFECTS, damping=z2, eps=1e-9), 1536)
    return out


def ladders(quick: bool, name: str):
    """scheme label -> (method, scene keywords, element counts)."""
    if quick:
        return {"radau3": ("radau3", {}, (12, 24, 48, 96)), "magnus2+split": ("magnus2", {}, (90, 180, 360))}
    big = name in ("six-bar", "mould oscillator")
    holds = (90, 180, 360, 720, 1440) if big else (90, 180, 360, 720, 1440, 2880)
    out = {
        "radau3": ("radau3", {}, (12, 24, 48, 96, 192, 384)),
        "radau2": ("radau2", {}, (24, 48, 96, 192, 384, 768)),
        "gauss3": ("gauss3", {}, (12, 24, 48, 96, 192, 384)),
        "gauss2": ("gauss2", {}, (24, 48, 96, 192, 384, 768)),
        "magnus2+split": ("magnus2", {}, holds),
        "magnus2": ("magnus2", {"stiff_split": False}, holds),
        "foh": ("foh", {}, holds[:-1]),
    }
    if name == "slider-crank":
        out["fourier"] = ("fourier", {}, (9, 17, 25, 33, 49))
    elif name == "four-bar":
        out["fourier"] = ("fourier", {}, (49, 65, 81, 97))
    return out


def timed(f, repeats=3):
    """(median wall time [s], last result); one run when the first exceeds 2 s."""
    ts, r = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = f()
        ts.append(time.perf_counter() - t0)
        if ts[0] > 2.0:
            break
    return float(np.median(ts)), r


def peaks(res):
    return np.array([[p.deflection, p.stress] for p in res.peaks()])


def error(res, ref):
    v = peaks(res)
    ok = np.isfinite(ref) & (np.abs(ref) > 0)
    return float(np.max(np.abs(v[ok] / ref[ok] - 1)))


def solve(build, kw, **extra):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return kf.solve(kf.Scene(build(), **{**kw, **extra}))


def run(quick: bool):
    rows = []
    for name, (build, kw, n_ref) in cases(quick).items():
        if quick:
            n_ref = 384
        t_ref, r = timed(lambda: solve(build, kw, steps=n_ref, method="radau3", estimate=False), 1)
        ref = peaks(r)
        g = peaks(solve(build, kw, steps=n_ref, method="gauss3", estimate=False))
        ok = np.isfinite(ref) & (ref != 0)
        unc = float(np.max(np.abs(g[ok] / ref[ok] - 1)))
        print(f"\n== {name}: reference radau3 n={n_ref} ({t_ref:.1f} s), Radau vs Gauss {unc:.1e}", flush=True)
        base = dict(mechanism=name, n_ref=n_ref, ref_uncertainty=unc)
        # 1. time elements per scheme
        for label, (method, extra, ns) in ladders(quick, name).items():
            for n in ns:
                try:
                    t, res = timed(lambda: solve(build, kw, steps=n, method=method, estimate=False, **extra))
                except kf.KedError as exc:
                    print(f"  {label:14s} n={n:5d}  failed: {exc}")
                    continue
                e = error(res, ref)
                rows.append(dict(base, knob="elements", setting=label, n=n, time_s=t, true_error=e,
                                 estimate=float("nan"), met=""))
                print(f"  {label:14s} n={n:5d}  {t:7.3f} s  error {e:8.1e}", flush=True)
        # 2. tolerance and presets, with the estimate
        settings = [("rtol=1e-2", dict(rtol=1e-2)), ("default (rtol=1e-3)", {}), ("rtol=1e-4", dict(rtol=1e-4)),
                    ("rtol=1e-5", dict(rtol=1e-5)), ("rtol=1e-6", dict(rtol=1e-6))]
        settings += [(f"accuracy={p}", dict(accuracy=p)) for p in ACCURACY_PRESETS]
        if quick:
            settings = settings[:2]
        for label, extra in settings:
            t, res = timed(lambda: solve(build, kw, **extra))
            e = error(res, ref)
            rows.append(dict(base, knob="tolerance", setting=label, n=res.elements, time_s=t, true_error=e,
                             estimate=float(res.error.peak), met=bool(res.error.met)))
            print(f"  {label:20s} n={res.elements:5d}  {t:7.3f} s  error {e:8.1e}  estimate "
                  f"{res.error.peak:8.1e}  met {res.error.met}", flush=True)
        if quick:
            continue
        # 3. mesh, at the default tolerance tightened to 1e-5 (time converged)
        if name in ("slider-crank", "four-bar"):
            finest = 16
            mesh = {k: timed(lambda: solve(lambda: build(elements=k), kw, rtol=1e-5), 1) for k in (2, 4, 8, finest)}
            fine = peaks(mesh[finest][1])
            for k, (t, res) in mesh.items():
                e = float(np.max(np.abs(peaks(res)[ok] / fine[ok] - 1)))
                rows.append(dict(base, knob="mesh", setting=f"{k} elements per link", n=res.elements, time_s=t,
                                 true_error=e, estimate=float(res.error.peak), met=bool(res.error.met)))
                print(f"  mesh {k:2d} elements/link  {t:7.3f} s  change vs {finest}: {e:8.1e}", flush=True)
        # 4. Craig-Bampton modes (slider-crank: rod with 16 elements)
        if name == "slider-crank":
            full_t, full = timed(lambda: solve(lambda: build(elements=16), kw, rtol=1e-5))
            fp = peaks(full)
            for modes in (1, 2, 4, 8):
                t, res = timed(lambda: solve(lambda: build(elements=16), kw, rtol=1e-5,
                                             reduction=kf.CraigBampton(modes=modes)))
                e = float(np.max(np.abs(peaks(res)[ok] / fp[ok] - 1)))
                rows.append(dict(base, knob="craig-bampton", setting=f"{modes} modes + static correction",
                                 n=res.elements, time_s=t, true_error=e, estimate=float("nan"), met=""))
                print(f"  CB {modes} modes  {t:7.3f} s (full {full_t:.3f} s)  vs full model {e:8.1e}", flush=True)
        # 5. non-linear tolerance
        if name == "mould oscillator":
            for eps in (1e-3, 1e-4, 1e-6, 1e-8):
                t, res = timed(lambda: solve(build, {**kw, "eps": eps}, steps=384, estimate=False))
                e = error(res, ref)
                rows.append(dict(base, knob="eps", setting=f"eps={eps:.0e}", n=384, time_s=t, true_error=e,
                                 estimate=float("nan"), met=str(res.iterations)))
                print(f"  eps {eps:.0e}  {t:7.3f} s  {res.iterations} solves  error {e:8.1e}", flush=True)
    return rows


def cheapest(rows, mech, target):
    """Cheapest single solve (estimate=False) of each scheme under ``target``."""
    out = {}
    for r in rows:
        if r["mechanism"] == mech and r["knob"] == "elements" and r["true_error"] <= target:
            best = out.get(r["setting"])
            if best is None or r["time_s"] < best["time_s"]:
                out[r["setting"]] = r
    return out


def write(rows, out_dir, wall, quick):
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, "accuracy_cost.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    mechs = list(dict.fromkeys(r["mechanism"] for r in rows))
    md = ["# Accuracy versus cost", "",
          f"Generated by `python benchmarks/accuracy_cost.py{' --quick' if quick else ''}` in {wall:.0f} s on "
          f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, numpy "
          f"{np.__version__}; BLAS on one thread; {datetime.datetime.now().isoformat(timespec='minutes')}. "
          "Error: largest relative error of the peak mid-span deflection and peak stress over the flexible "
          "links, against Radau IIA on the reference's elements (its agreement with Gauss-Legendre on as "
          "many is the reference's uncertainty). Times: wall time of `kf.solve` (kinematics, assembly, "
          "solve, peaks), median of 3.", "",
          "## Cheapest single solve below each error (`steps=n, estimate=False`)", "",
          "| mechanism | scheme | 1 % | 0.1 % | 1e-4 | 1e-5 | 1e-6 |", "|---|---|---|---|---|---|---|"]
    for m in mechs:
        labels = list(dict.fromkeys(r["setting"] for r in rows if r["mechanism"] == m and r["knob"] == "elements"))
        for lab in labels:
            cells = []
            for tgt in (1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
                c = cheapest(rows, m, tgt).get(lab)
                cells.append(f"n={c['n']}: {1e3 * c['time_s']:.0f} ms" if c else "-")
            md.append(f"| {m} | {lab} | " + " | ".join(cells) + " |")
    md += ["", "## Tolerance-driven solves (what a user gets, with the three-level estimate)", "",
           "| mechanism | setting | elements | time | true error | estimate | met |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["knob"] == "tolerance":
            md.append(f"| {r['mechanism']} | {r['setting']} | {r['n']} | {1e3 * r['time_s']:.0f} ms | "
                      f"{r['true_error']:.1e} | {r['estimate']:.1e} | {r['met']} |")
    other = [r for r in rows if r["knob"] in ("mesh", "craig-bampton", "eps")]
    if other:
        md += ["", "## Mesh, Craig-Bampton modes, non-linear tolerance", "",
               "| mechanism | knob | setting | time | error | note |", "|---|---|---|---|---|---|"]
        for r in other:
            note = {"mesh": "change of the peaks against 16 elements per link (rtol 1e-5)",
                    "craig-bampton": "against the full model, 16-element rod (rtol 1e-5)",
                    "eps": f"{r['met']} linear solves, 384 elements"}[r["knob"]]
            md.append(f"| {r['mechanism']} | {r['knob']} | {r['setting']} | {1e3 * r['time_s']:.0f} ms | "
                      f"{r['true_error']:.1e} | {note} |")
    md += ["", "## Every single solve", "", "| mechanism | scheme | n | time | error |", "|---|---|---|---|---|"]
    for r in rows:
        if r["knob"] == "elements":
            md.append(f"| {r['mechanism']} | {r['setting']} | {r['n']} | {1e3 * r['time_s']:.0f} ms | "
                      f"{r['true_error']:.1e} |")
    md.append("")
    md.append("Reference uncertainties: " + ", ".join(
        f"{m} {next(r['ref_uncertainty'] for r in rows if r['mechanism'] == m):.0e}" for m in mechs) + ".")
    with open(os.path.join(out_dir, "accuracy_cost.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    plot(rows, mechs, os.path.join(out_dir, "accuracy_cost.png"))


def plot(rows, mechs, path):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(5.0 * len(mechs), 4.2))
    FigureCanvasAgg(fig)
    for i, m in enumerate(mechs):
        ax = fig.add_subplot(1, len(mechs), i + 1)
        labels = list(dict.fromkeys(r["setting"] for r in rows if r["mechanism"] == m and r["knob"] == "elements"))
        for lab in labels:
            pts = sorted((r["time_s"], max(r["true_error"], 1e-12)) for r in rows
                         if r["mechanism"] == m and r["knob"] == "elements" and r["setting"] == lab)
            ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-", ms=3, label=lab)
        tol = [(r["time_s"], max(r["true_error"], 1e-12)) for r in rows
               if r["mechanism"] == m and r["knob"] == "tolerance"]
        if tol:
            ax.loglog([p[0] for p in tol], [p[1] for p in tol], "k*", ms=9, label="rtol-driven (with estimate)")
        ax.set_title(m)
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel("relative error of the peaks")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two mechanisms, short ladders")
    ap.add_argument("--out", default=os.path.join(HERE, "results"), help="output folder")
    args = ap.parse_args(argv)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover
        threadpool_limits = None
    t0 = time.perf_counter()
    if threadpool_limits is not None:
        with threadpool_limits(1):
            rows = run(args.quick)
    else:
        rows = run(args.quick)
    write(rows, args.out, time.perf_counter() - t0, args.quick)
    print(f"\nwritten to {args.out} in {time.perf_counter() - t0:.0f} s")
    return rows


if __name__ == "__main__":
    main()
