"""Bit-identity of results and files across a refactor (issue 27: the moves change no number).

Solves the presets' scene files (``examples/scenes``) and the default scene at their defaults,
writes each result's folder (``res.write``: CSV, NPZ, VTK, figures, without the mesh check) and
prints one SHA-256 digest per scene over the result's arrays (time, displacements, velocities,
peaks, Floquet multipliers, error estimate) and one per written file, leaving out what records
when or how long (the run record ``kedfem-run.json``, the summary's timings and folder). Run it
before and after a move and compare the two outputs::

    OPENBLAS_NUM_THREADS=1 python benchmarks/identity.py > before.txt
    ... move code ...
    OPENBLAS_NUM_THREADS=1 python benchmarks/identity.py > after.txt
    diff before.txt after.txt          # empty: bit-identical

``--quick`` solves the four-bar and the slider-crank only.
"""
from __future__ import annotations

import argparse
import hashlib
import os
import re
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

import kedfem as kf  # noqa: E402

#: files whose content records the run (times, paths), not the result
SKIP = {"kedfem-run.json"}
#: lines of text files that carry wall times or paths
VOLATILE = re.compile(rb"(\d+(\.\d+)? ?(s|ms)\b|seconds|wall|time \[s\]|elapsed|/tmp/|forecast|\(run \d{8}T)", re.I)


def _digest_arrays(res) -> str:
    h = hashlib.sha256()
    for a in (res.t, res.U, res.V, np.asarray(res.floquet_multipliers)):
        h.update(np.ascontiguousarray(a).tobytes())
    for p in res.peaks():
        h.update(repr(p).encode())
    if res.error is not None:
        h.update(repr(res.error.peak).encode())
        h.update(repr(res.error.history).encode())
    return h.hexdigest()[:16]


def _digest_file(path: Path) -> str:
    data = path.read_bytes()
    if path.suffix in (".txt", ".md", ".csv", ".json", ".pvd"):
        data = b"\n".join(line for line in data.splitlines() if not VOLATILE.search(line))
    return hashlib.sha256(data).hexdigest()[:16]


def scenes(quick: bool):
    folder = HERE.parent / "examples" / "scenes"
    names = ["four_bar", "slider_crank"] if quick else sorted(p.stem for p in folder.glob("*.toml"))
    out = [(name, lambda name=name: kf.load_scene(folder / f"{name}.toml")[0]) for name in names]
    if not quick:
        out.append(("default", kf.default_scene))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    with warnings.catch_warnings(), tempfile.TemporaryDirectory() as tmp:
        warnings.simplefilter("ignore")
        for name, make in scenes(args.quick):
            res = kf.solve(make())
            if hasattr(res, "sweep") or not hasattr(res, "U"):
                print(f"{name}: not a periodic result ({type(res).__name__})")
                continue
            print(f"{name}: arrays {_digest_arrays(res)}")
            out = Path(tmp) / name
            res.write(out, mesh_check=False, vtk=True, plots=True)
            for f in sorted(p for p in out.rglob("*") if p.is_file() and p.name not in SKIP):
                print(f"  {f.relative_to(out)} {_digest_file(f)}")


if __name__ == "__main__":
    main()
