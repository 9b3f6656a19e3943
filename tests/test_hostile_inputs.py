"""Issue 23, sections 2-4: every reproducer of the hostile-user probe ends in a correct answer or a
named one-line error (a non-zero exit status from the CLI), and none hangs.

(Section 1, scene files that run code, is tests/test_trust.py; the fuzzers of the public API and
of the CLI options are tests/test_fuzz_api.py.)
"""

import math
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import kedfem as kf
from kedfem.io import scenefile as sf
from kedfem.io.sweep import parse_axis, run_sweep
from kedfem.io.sweep_journal import SweepJournal, sweep_signature

EXIT_BUILDER = '''
import sys
import kedfem as kf


def build(coupler: float = 0.2, elements: int = 2) -> kf.Mechanism:
    if coupler > 0.205:
        sys.exit(0)
    m = kf.Mechanism("exiting rocker")
    steel = kf.Material(E=2.1e11, rho=7850.0)
    sec = kf.Section.rectangle(0.012, 0.006)
    m.ground("O2", (0.0, 0.0))
    m.ground("O4", (0.18, 0.0))
    m.joint("A", (0.05, 0.0))
    m.joint("B", m.at_lengths(("A", coupler), ("O4", 0.15), branch="open"))
    m.link("crank", "O2", "A", rigid=True, mass=0.1)
    m.link("coupler", "A", "B", material=steel, section=sec, elements=elements)
    m.link("rocker", "O4", "B", material=steel, section=sec, elements=elements)
    m.drive("crank", speed=60.0)
    return m
'''


def cli(args, cwd, timeout=120, **kw):
    exe = Path(sys.executable).parent / "kedfem"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "kedfem.cli"]
    env = dict(os.environ, MPLBACKEND="Agg")
    env.pop("PYTHONPATH", None)
    return subprocess.run(cmd + list(args), cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env,
                          **kw)


def one_line_error(r, status=2):
    assert r.returncode == status, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr and r.stderr.strip().startswith(("kedfem: error:", "usage:")), r.stderr


# ------------------------------------------------------------------ section 2: raw tracebacks
def test_a_deeply_nested_scene_file_is_a_named_error(tmp_path):
    (tmp_path / "deep.toml").write_text("a = " + "[" * 600 + "]" * 600 + "\n")
    with pytest.raises(sf.SceneFileError, match="nested"):
        kf.load_scene(tmp_path / "deep.toml")
    one_line_error(cli(["run", "deep.toml"], tmp_path))


def test_sweep_axes_are_bounded_and_finite_before_any_list_is_built():
    with pytest.raises(kf.InputError, match="NUM = 100000000 exceeds"):
        parse_axis("speed_rpm=1:2:100000000")
    for text in ("speed_rpm=1:inf:3", "speed_rpm=1,nan", "speed_rpm=-inf,2"):
        with pytest.raises(kf.InputError, match="finite"):
            parse_axis(text)
    with pytest.raises(kf.InputError, match="exceed"):
        parse_axis("speed_rpm=" + ",".join(["1"] * 10_001))


def test_resume_reads_a_damaged_partial_table_and_publishes_each_point_once(tmp_path):
    base = {"mechanism": {"name": "exciter"}, "steps": 12}
    axes = {"speed_rpm": [300.0, 600.0, 900.0]}
    from kedfem.io.sweep import make_points
    points = make_points(base, axes)
    res = run_sweep(base, axes, scheduler="serial", frequencies=False)
    j = SweepJournal(tmp_path / "p.csv", sweep_signature(base, axes), list(axes))
    j.start({p.index: p for p in res.points})
    j.close()
    lines = (tmp_path / "p.csv").read_bytes().split(b"\n")
    # point 1 duplicated, point 2 damaged by a byte that is not UTF-8
    head, rows = lines[:2], [ln for ln in lines[2:] if ln]
    p1 = [r for r in rows if r.startswith(b"1,")]
    p2 = [r for r in rows if r.startswith(b"2,")]
    damaged = [p2[0][:-3] + b"\xff\xfe" + p2[0][-1:]] + p2[1:]
    rest = [r for r in rows if not r.startswith((b"1,", b"2,"))]
    (tmp_path / "p.csv").write_bytes(b"\n".join(head + rest + p1 + p1 + damaged) + b"\n")
    done = j.read(points)
    assert sorted(done) == [0, 1]  # 1 once, 2 to solve again
    assert [lp.link for lp in done[1].peaks] == [lp.link for lp in res.points[1].peaks]


def test_a_builder_that_exits_fails_its_sweep_point_and_the_others_complete(tmp_path):
    (tmp_path / "exiting.py").write_text(EXIT_BUILDER)
    sys.path.insert(0, str(tmp_path))
    try:
        import exiting
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for scheduler in ("serial", "processes"):
                res = run_sweep({"steps": 12}, {"mechanism.coupler": [0.19, 0.2, 0.21, 0.2]}, builder=exiting.build,
                                scheduler=scheduler, max_workers=2, frequencies=False)
                assert [p.ok for p in res.points] == [True, True, False, True], scheduler
                assert "sys.exit(0)" in res.points[2].error
    finally:
        sys.path.remove(str(tmp_path))
        sys.modules.pop("exiting", None)
    r = cli(["sweep", "exiting.py:build", "--param", "mechanism.coupler=0.19,0.21", "--scheduler", "serial",
             "--steps", "12", "--no-plots", "--no-progress", "--out", "sw"], tmp_path)
    assert r.returncode == 1 and "1 of 2 points solved" in r.stdout, r.stdout + r.stderr
    assert (tmp_path / "sw" / "sweep.csv").is_file()


def test_builder_api_calls_with_wrong_types_are_named():
    m = kf.Mechanism("x")
    m.ground("O", (0.0, 0.0))
    m.joint("A", (1.0, 0.0))
    for call, what in [(lambda: m.joint("B", (2.0, 0.0), welded=5), "welded"),
                       (lambda: m.link("l", "O", "A", ends=None), "ends"),
                       (lambda: m.body("b", joints=5, mass=1.0, J=1.0), "joints"),
                       (lambda: kf.Section.rectangle(1e200, 1e200), "b = 1e\\+200 m exceeds"),
                       (lambda: kf.natural_frequencies(None), "natural_frequencies: expected a kedfem.Mechanism"),
                       (lambda: kf.static_response(None), "static_response: expected a kedfem.Mechanism"),
                       (lambda: kf.mesh_error("x"), "mesh_error: res must be"),
                       (lambda: run_sweep(points=[1, 2]), "SweepPoint"),
                       (lambda: kf.campbell(lambda speed, other: None, [10.0, 20.0]), "one argument, the speed"),
                       (lambda: m.link("big", "O", "A", material=kf.Material(E=2e11, rho=7800.0),
                                       section=kf.Section.rectangle(0.01, 0.01), elements=10**4), "1 .. 200")]:
        with pytest.raises(kf.InputError, match=what):
            call()


# ------------------------------------------------------------------ section 3: hangs
def test_a_fifo_scene_file_is_refused_at_once(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    os.mkfifo(tmp_path / "x.toml")
    with pytest.raises(sf.SceneFileError, match="not a regular file"):
        kf.load_scene(tmp_path / "x.toml")
    one_line_error(cli(["run", "x.toml"], tmp_path, timeout=30))


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs SIGKILL")
def test_communicate_returns_after_a_running_sweep_is_killed(tmp_path):
    """proc.kill(); proc.communicate() never returned: the killed main process is a zombie until
    communicate reaps it, and its workers, holding the pipes, saw the zombie as alive."""
    exe = Path(sys.executable).parent / "kedfem"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "kedfem.cli"]
    p = subprocess.Popen(cmd + ["sweep", "four_bar", "--param", "speed_rpm=100:300:20", "--scheduler", "processes",
                                "--workers", "2", "--no-progress", "--out", str(tmp_path / "s")],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=dict(os.environ, MPLBACKEND="Agg"))
    deadline = time.time() + 60
    while time.time() < deadline and not (tmp_path / "s.partial.csv").exists():
        time.sleep(0.2)
    time.sleep(1.5)  # the workers are solving
    p.kill()
    p.communicate(timeout=30)  # TimeoutExpired is the hang
    assert p.returncode == -signal.SIGKILL


# ------------------------------------------------------------------ section 4: silently wrong
def test_flags_and_geometry_are_read_as_given():
    m = kf.Mechanism("x")
    m.ground("O", (0.0, 0.0))
    m.joint("A", (1.0, 0.0))
    steel, sec = kf.Material(E=2e11, rho=7800.0), kf.Section.rectangle(0.01, 0.01)
    with pytest.raises(kf.InputError, match="rigid must be True or False, got str 'no'"):
        m.link("l", "O", "A", rigid="no")
    with pytest.raises(kf.InputError, match="timoshenko must be True or False"):
        m.link("l", "O", "A", material=steel, section=sec, timoshenko="no")
    with pytest.raises(kf.InputError, match="clamped must be True or False"):
        m.ground("G", (3.0, 0.0), clamped="no")
    s = m.spring("s", "A", k=1.0, axis=(1.7e308, 1.7e308))
    assert s.axis == pytest.approx((math.sqrt(0.5), math.sqrt(0.5)), rel=1e-15)
    with pytest.raises(kf.InputError, match="exceeds the largest magnitude"):
        m.at_lengths(("O", 1e308), ("A", 1e308), branch="left")
    m.link("l", "O", "A", rigid=True)
    with pytest.raises(kf.InputError, match="to itself"):
        m.torsional_spring("t", "O", "l", "l", k=1.0)


def test_a_heavy_point_mass_is_not_called_massless():
    """A 1e12 kg slider block on a slider-crank: 'massless DOFs' before; now it solves, and its
    answer is the limit of ever heavier blocks (the block stands still)."""
    import mechanisms
    out = []
    for mass in (1e9, 1e12):
        m = mechanisms.build("slider_crank")
        m.point_mass("B", mass)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = kf.solve(kf.Scene(m, effects=("inertia", "coupling"), damping=kf.ModalDamping(0.02), steps=48))
        out.append(res.peaks()[0].stress)
        assert np.isfinite(out[-1])
    assert out[1] == pytest.approx(out[0], rel=1e-4)


def test_steps_too_few_to_coarsen_say_there_is_no_estimate(tmp_path):
    with pytest.warns(kf.AccuracyWarning, match="no error estimate: 3 time elements"):
        res = kf.solve(kf.Scene(kf.catalogue.build("exciter"), steps=3, effects=("inertia",)))
    assert res.error is None
    r = cli(["run", "exciter", "--steps", "3", "--no-plots", "--no-vtk", "--no-mesh-check", "--out", "o"], tmp_path)
    assert r.returncode == 0 and "no error estimate" in r.stderr
    assert "no coarser level to compare with" in (tmp_path / "o" / "summary.txt").read_text()
    one_line_error(cli(["run", "exciter", "--out", ""], tmp_path))


def test_no_inf_in_a_sweep_table(tmp_path):
    from kedfem.io.sweep import csv_cells
    assert csv_cells((1, math.inf, -math.inf, math.nan, 0.5, "x")) == [1, "", "", "", "0.5", "x"]
