"""Peak dynamic stress of a slider-crank's connecting rod against crank speed (paper Figs. 3-4).

Eight speeds solved in parallel: on a process pool (default), or on a Dask cluster:

    python examples/speed_sweep.py                          # process pool
    python examples/speed_sweep.py --scheduler local        # dask.distributed LocalCluster
    python examples/speed_sweep.py --scheduler tcp://scheduler-host:8786

The ``if __name__ == "__main__":`` guard is required: the workers are new
Python processes that import this file.
"""

import argparse
from pathlib import Path

from kedfem.io import sweep

BASE = {
    "mechanism": {"name": "slider_crank", "elements": 6},
    "steps": 120,
    "effects": ["inertia", "coupling", "axial_stiffening"],
    "damping": {"model": "modal", "zeta": 0.02},
}


def main(out="speed-sweep-out", speeds=(250, 500, 750, 1000, 1250, 1500, 1750, 2000), steps=120,
         scheduler="processes", progress=None) -> sweep.SweepResult:
    base = dict(BASE, steps=steps)
    res = sweep.run_sweep(base, {"speed_rpm": list(speeds)}, scheduler=scheduler, progress=progress)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    res.to_csv(out / "sweep.csv")
    res.plot(out / "peak_stress_vs_speed.png")
    for p in res.points:
        rpm = dict(p.params)["speed_rpm"]
        if p.ok:
            print(f"{rpm:6.0f} rpm: peak rod stress {p.peaks[0].stress / 1e6:8.2f} MPa, "
                  f"spectral radius {p.spectral_radius:.3f}")
        else:
            print(f"{rpm:6.0f} rpm: failed: {p.error}")
    print(f"{len(res.points)} points on {res.scheduler} in {res.wall_time:.2f} s -> {out}/")
    return res


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scheduler", default="processes", help="processes, serial, local or tcp://host:port")
    ap.add_argument("--out", default="speed-sweep-out")
    a = ap.parse_args()
    main(out=a.out, scheduler=a.scheduler)
