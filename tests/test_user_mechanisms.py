"""A user's own mechanism works everywhere a catalogue name does: the CLI (file and module
references), scene files (``builder = ...``, relative to the scene file), sweeps over a builder on
the process pool and on Dask (the same table), sweeps of a built Mechanism object, and
``res.write``."""

import csv
import importlib.util
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import kedfem as kf
from kedfem.io import scenefile as sf
from kedfem.io.sweep import run_sweep

LINKAGE = '''
import math
import kedfem as kf


def build(crank=0.05, coupler=0.2, rocker=0.15, ground=0.18, speed=2 * math.pi * 10, elements=2):
    steel = kf.Material(E=2.1e11, rho=7850.0)
    sec = kf.Section.rectangle(0.012, 0.006)
    m = kf.Mechanism("my crank-rocker")
    m.ground("O2", (0.0, 0.0))
    m.ground("O4", (ground, 0.0))
    d = ground - crank
    a = (coupler**2 - rocker**2 + d**2) / (2 * d)
    m.joint("A", (crank, 0.0))
    m.joint("B", (crank + a, math.sqrt(coupler**2 - a**2)))
    m.link("crank", "O2", "A", rigid=True, mass=0.1)
    m.link("coupler", "A", "B", material=steel, section=sec, elements=elements)
    m.link("rocker", "O4", "B", material=steel, section=sec, elements=elements)
    m.drive("crank", speed=speed)
    return m
'''


@pytest.fixture()
def folder(tmp_path):
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "my_linkage.py").write_text(LINKAGE)
    return tmp_path


def kedfem_cli(args, cwd):
    exe = Path(sys.executable).parent / "kedfem"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "kedfem.cli"]
    env = dict(os.environ, MPLBACKEND="Agg")
    env.pop("PYTHONPATH", None)
    return subprocess.run(cmd + args, cwd=cwd, capture_output=True, text=True, timeout=300, env=env)


def _peaks(path):
    with open(path, newline="") as f:
        return {r["link"]: float(r["peak_stress_Pa"]) for r in csv.DictReader(f)}


def test_cli_runs_a_builder_file_and_a_scene_file_names_one_relative_to_itself(folder):
    quick = ["--steps", "24", "--no-mesh-check", "--no-plots", "--no-vtk"]
    r = kedfem_cli(["run", "lib/my_linkage.py:build", "--out", "a"] + quick, folder)
    assert r.returncode == 0, r.stderr
    assert "my crank-rocker" in r.stdout
    (folder / "lib" / "scene.toml").write_text('speed_rpm = 600\n[mechanism]\nbuilder = "my_linkage.py:build"\n')
    refused = kedfem_cli(["run", str(folder / "lib" / "scene.toml"), "--out", str(folder / "b")] + quick, "/")
    assert refused.returncode == 2 and "not trusted" in refused.stderr and not (folder / "b").exists()
    r = kedfem_cli(["run", str(folder / "lib" / "scene.toml"), "--trust", str(folder / "lib" / "scene.toml"),
                    "--out", str(folder / "b")] + quick, "/")
    assert r.returncode == 0, r.stderr
    # the same mechanism and speed (the builder's default is 600 rpm): the same peaks
    a, b = _peaks(folder / "a" / "peaks.csv"), _peaks(folder / "b" / "peaks.csv")
    assert a.keys() == {"coupler", "rocker"} and all(a[k] == pytest.approx(b[k], rel=1e-12) for k in a)
    bad = kedfem_cli(["run", "lib/nope.py:build"] + quick, folder)
    assert bad.returncode == 2 and "no file" in bad.stderr


def _load(folder):
    spec = importlib.util.spec_from_file_location("users_linkage", folder / "lib" / "my_linkage.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.build


def _table(res, path):
    res.to_csv(path)
    with open(path, newline="") as f:
        return [{k: v for k, v in r.items() if k not in ("wall_time_s", "worker")} for r in csv.DictReader(f)]


def test_a_sweep_over_a_builder_gives_the_same_table_on_the_pool_and_on_dask(folder):
    pytest.importorskip("distributed")
    build = _load(folder)
    axes = {"speed_rpm": [300, 600, 900, 1200], "mechanism.coupler": [0.19, 0.2, 0.21, 0.22]}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pool = run_sweep({"steps": 24}, axes, builder=build, frequencies=False, max_workers=2)
        dask = run_sweep({"steps": 24}, axes, builder=build, scheduler="local", max_workers=2, frequencies=False)
    assert len(pool.points) == 16 and all(p.ok for p in pool.points)
    a, b = _table(pool, folder / "pool.csv"), _table(dask, folder / "dask.csv")
    assert a == b
    # and each point is the direct solve of the builder's mechanism
    p = pool.points[5]
    params = dict(p.params)
    direct = kf.solve(kf.Scene(build(coupler=params["mechanism.coupler"], speed=params["speed_rpm"] * np.pi / 30),
                               steps=24, effects=("inertia", "coupling", "axial_stiffening"),
                               damping=kf.ModalDamping(0.02)))  # a builder's default preset: the linear set
    assert {pk.link: pk.stress for pk in p.peaks} == pytest.approx({pk.link: pk.stress for pk in direct.peaks()},
                                                                   rel=1e-12)


def test_a_built_mechanism_sweeps_over_the_scene_and_says_what_it_cannot(folder):
    m = _load(folder)()
    res = run_sweep({"mechanism": m, "steps": 24}, {"speed_rpm": [300, 600]}, scheduler="serial",
                    frequencies=False)
    assert [p.ok for p in res.points] == [True, True]
    assert res.points[0].peaks[0].stress < res.points[1].peaks[0].stress
    with pytest.raises(kf.InputError, match="no parameters"):
        sf.scene_from_dict({"mechanism": m, "steps": 24, "sweep": {"mechanism.coupler": [0.2]}})


def test_res_write_writes_what_the_cli_writes(folder):
    build = _load(folder)
    res = kf.solve(kf.Scene(build(), steps=24, effects=("inertia", "coupling"), damping=kf.ModalDamping(0.02)))
    rep = res.write(folder / "out", vtk=False, plots=False)
    names = sorted(p.name for p in rep.files)
    assert names == sorted(["response.csv", "peaks.csv", "frequencies.csv", "fatigue.csv", "histories.csv",
                            "histories.npz", "loads.csv", "result.npz", "summary.txt"])
    assert all(p.is_file() for p in rep.files)
    assert "my crank-rocker" in (folder / "out" / "summary.txt").read_text()
    assert len(repr(res)) < 300 and "my crank-rocker" in repr(res)
