"""Critical speeds against fine scans, and the four-bar's stability chart for the README.

1. **Fine scans** (the reference). The slider-crank and the four-bar presets with the
   linear effects (inertia, coupling, axial_stiffening; 2 % modal damping; the
   four-bar's geometric non-linearity does not converge above ~275 rpm, see
   ``kedfem/analysis/critical.py``), default tolerance: a 1 % scan of the speed over
   the whole range lists every crossing of ``rho = 1``; a 0.04 % scan over the 1 %
   cell of the first one pins the onset (the reference is the midpoint of its last
   stable and first unstable speed, +-0.02 %).
2. **critical_speed** (``rtol=5e-3``, default tolerance per solve) from the bracket a
   5 % chart gives (the grid speeds ``lo0 * 1.05^k`` either side of the onset), and
   from the whole range with and without a scan: the onset found, the solves used,
   the difference to the fine scan (acceptance: within 0.5 %, fewer than 15 solves).
3. **Stability chart** of the four-bar over speed x ``mechanism.coupler_EI`` (rtol 1e-2
   per point, on the process pool) with the refined onsets marked:
   ``docs/img/four_bar_stability_map.png``; and its Campbell diagram
   ``docs/img/four_bar_campbell.png``.

Writes ``benchmarks/results/stability_map.md`` and ``.csv`` (the chart's grid).

Run from the repository root::

    python benchmarks/stability_map.py            # ~8 min on 2 cores
    python benchmarks/stability_map.py --quick    # coarse, the slider-crank only (~1 min)
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))

import numpy as np  # noqa: E402

from kedfem.analysis.campbell import campbell  # noqa: E402
from kedfem.analysis.critical import critical_speed  # noqa: E402
from kedfem.fe.effects import LINEAR_EFFECTS  # noqa: E402
from kedfem.io.design_plots import stability_map  # noqa: E402
from kedfem.io.scenefile import scene_from_dict  # noqa: E402

RPM = 2 * math.pi / 60
IMG = os.path.join(HERE, "..", "docs", "img")
#: mechanism -> (range of the scans [rpm], previous onset from benchmarks/stability.py [rpm])
CASES = {"slider_crank": ((3000.0, 9000.0), 6064.9), "four_bar": ((300.0, 900.0), 592.7)}
LINK_EI = 0.616


def base(name: str, accuracy: str = "default") -> dict:
    return {"mechanism": {"name": name}, "effects": list(LINEAR_EFFECTS), "accuracy": accuracy}


def row(name, speeds_rpm, accuracy="default"):
    """Spectral radius at each speed: a one-row stability map (process pool)."""
    m = stability_map(base(name, accuracy), np.asarray(speeds_rpm) * RPM, "damping.zeta", [0.02], progress=False)
    return m.spectral_radius[0], m


def crossings(rpm, rho):
    """Speeds [rpm] where rho crosses 1 (linear in log rho), with their direction."""
    g = np.log(rho)
    out = []
    for i in np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:])):
        x = rpm[i] + g[i] / (g[i] - g[i + 1]) * (rpm[i + 1] - rpm[i])
        out.append((float(x), "onset" if g[i] < 0 else "end"))
    return out


def fine_scan(name, lo, hi, quick):
    t0 = time.perf_counter()
    step = 1.03 if quick else 1.01
    coarse = lo * step ** np.arange(int(math.log(hi / lo) / math.log(step)) + 1)
    rho, _ = row(name, coarse)
    cross = crossings(coarse, rho)
    first = next(x for x, kind in cross if kind == "onset")
    i = int(np.searchsorted(coarse, first))
    fine = np.linspace(coarse[i - 1], coarse[i], 11 if quick else 26)  # 0.04 % steps over the 1 % cell
    rho_f, _ = row(name, fine)
    j = int(np.argmax(rho_f >= 1.0))
    ref = 0.5 * (fine[j - 1] + fine[j])
    half = 0.5 * (fine[j] - fine[j - 1]) / ref
    print(f"{name}: scan {len(coarse)} + {len(fine)} speeds, crossings "
          + ", ".join(f"{x:.1f} ({k})" for x, k in cross) + f"; first onset {ref:.2f} rpm +- {100 * half:.3f} %  "
          f"({time.perf_counter() - t0:.0f} s)", flush=True)
    return dict(ref=ref, half=half, crossings=cross, n=len(coarse) + len(fine), time=time.perf_counter() - t0)


def refine(name, lo, hi, ref, scan=0):
    t0 = time.perf_counter()
    r = critical_speed(base(name), lo * RPM, hi * RPM, scan=scan)
    dt = time.perf_counter() - t0
    diff = r.rpm / ref - 1
    print(f"  critical_speed [{lo:.1f}, {hi:.1f}] rpm, scan {scan}: {r.rpm:.2f} rpm in {r.solves} solves "
          f"(bracket {r.bracket_rpm[0]:.2f} .. {r.bracket_rpm[1]:.2f}), {100 * diff:+.3f} % from the fine scan, "
          f"{dt:.1f} s", flush=True)
    return dict(lo=lo, hi=hi, scan=scan, rpm=r.rpm, solves=r.solves, diff=diff, met=r.met, time=dt,
                bracket=r.bracket_rpm)


def chart(quick, marks):
    t0 = time.perf_counter()
    speeds = np.linspace(450.0, 750.0, 21 if quick else 41) * RPM
    values = LINK_EI * np.geomspace(0.5, 4.0, 4 if quick else 9)
    smap = stability_map(base("four_bar", "fast"), speeds, "mechanism.coupler_EI", values.tolist(),
                         progress=False)
    os.makedirs(IMG, exist_ok=True)
    smap.to_csv(os.path.join(HERE, "results", "stability_map.csv"))
    smap.plot(os.path.join(IMG, "four_bar_stability_map.png"), marks=marks,
              title="four-bar (linear effects, 2 % modal damping): spectral radius over speed x coupler EI",
              ylabel="coupler EI [N m^2] (link_EI = 0.616)")
    dt = time.perf_counter() - t0
    print(f"four-bar chart: {smap.spectral_radius.size} points on {smap.scheduler} in {dt:.0f} s "
          f"({len(smap.failures)} failed)", flush=True)
    return smap, dt


def campbell_chart(quick):
    t0 = time.perf_counter()
    sc = scene_from_dict(base("four_bar"))
    res = campbell(sc, np.linspace(50.0, 900.0, 35 if quick else 171) * RPM, n_modes=4, harmonics=10)
    res.plot(os.path.join(IMG, "four_bar_campbell.png"))
    dt = time.perf_counter() - t0
    print(f"four-bar Campbell diagram: {res.speeds.size} speeds, {len(res.crossings)} crossings, {dt:.1f} s",
          flush=True)
    return res, dt


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    t_all = time.perf_counter()
    md = ["# Critical speeds and stability maps", ""]
    marks = []
    results = {}
    for name, ((lo, hi), previous) in CASES.items():
        if args.quick and name != "slider_crank":
            continue
        fs = fine_scan(name, lo, hi, args.quick)
        ref = fs["ref"]
        k = math.floor(math.log(ref / lo) / math.log(1.05))
        runs = [refine(name, lo * 1.05 ** k, lo * 1.05 ** (k + 1), ref)]
        if not args.quick:
            runs += [refine(name, lo, hi, ref), refine(name, lo, hi, ref, scan=8)]
        results[name] = (fs, runs, previous)
        if name == "four_bar":
            marks.append((runs[0]["rpm"] * RPM, LINK_EI, f"critical_speed: {runs[0]['rpm']:.1f} rpm"))
    smap, t_map = chart(args.quick, marks) if not args.quick else (None, 0.0)
    camp, t_camp = campbell_chart(args.quick) if not args.quick else (None, 0.0)
    wall = time.perf_counter() - t_all
    md += [f"`python benchmarks/stability_map.py{' --quick' if args.quick else ''}`, {wall:.0f} s on "
           f"{os.cpu_count()} cores. Preset scenes with the linear effects (inertia, coupling, axial_stiffening), "
           "2 % modal damping, default tolerance (rtol 1e-3) per solve.", "",
           "## Onset of parametric instability: critical_speed against a fine scan", "",
           "Fine scan: 1 % steps over the range (every crossing of rho = 1 listed, interpolated on that grid), "
           "then 0.04 % steps over the "
           "1 % cell of the first onset; reference = midpoint of its last stable and first unstable speed. "
           "critical_speed: rtol 5e-3 on the speed, ITP in log(speed) on log(rho).", "",
           "| mechanism | crossings of rho = 1 in the range [rpm] | fine-scan onset [rpm] | bracket given [rpm] | "
           "scan | critical_speed [rpm] | solves | difference | time [s] |", "|---|---|---|---|---|---|---|---|---|"]
    for name, (fs, runs, previous) in results.items():
        cr = ", ".join(f"{x:.1f} {k}" for x, k in fs["crossings"])
        for j, r in enumerate(runs):
            head = (f"| {name} | {cr} | {fs['ref']:.2f} +- {100 * fs['half']:.2f} % ({fs['n']} solves, "
                    f"{fs['time']:.0f} s) ") if j == 0 else "| | | "
            md.append(f"{head}| {r['lo']:.1f} .. {r['hi']:.1f} | {r['scan']} | {r['rpm']:.2f} | {r['solves']} | "
                      f"{100 * r['diff']:+.3f} % | {r['time']:.1f} |")
    md += ["", "The first row of each mechanism is the acceptance (the bracket a 5 % chart gives, lo0 x 1.05^k "
           "either side of the onset). The whole range holds several crossings (tongues of instability with "
           "stable speeds between them), and then the search finds one of them, not necessarily the lowest; "
           "`scan` evaluates speeds upward first. `benchmarks/stability.py` (bisection from a doubling scan) "
           "reported " + ", ".join(f"{n} {p:.1f} rpm ("
                                   + ("the first onset" if abs(p / fs["ref"] - 1) < 5e-3 else
                                      "a later crossing: its bisection stepped over the tongue below")
                                   + ")" for n, (fs, _, p) in results.items()) + "."]
    if smap is not None:
        on = smap.onsets() / RPM
        md += ["", "## Four-bar stability chart (README)", "",
               f"{smap.spectral_radius.size} points ({smap.speeds.size} speeds 450-750 rpm x "
               f"{smap.values.size} coupler EI), rtol 1e-2 per point, {smap.scheduler}, {t_map:.0f} s; "
               f"{len(smap.failures)} failed. `docs/img/four_bar_stability_map.png`, grid in "
               "`benchmarks/results/stability_map.csv`.", "",
               "| coupler EI [N m^2] | first onset on the grid [rpm] |", "|---|---|"]
        md += [f"| {v:.4g} | {o:.1f} |" if math.isfinite(o) else f"| {v:.4g} | none in 450-750 |"
               for v, o in zip(smap.values, on)]
        md += ["", f"Campbell diagram (`docs/img/four_bar_campbell.png`): {camp.speeds.size} speeds, "
               f"{len(camp.crossings)} crossings of harmonics 1-10 with modes 1-4, {t_camp:.1f} s (modal analysis "
               "over 36 crank positions per speed, no periodic solve)."]
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    out = os.path.join(HERE, "results", "stability_map_quick.md" if args.quick else "stability_map.md")
    with open(out, "w") as f:
        f.write("\n".join(md) + "\n")
    print(f"wrote {out} ({wall:.0f} s)")
    return results


if __name__ == "__main__":
    main()
