"""Sweeps: identical results on a process pool and a Dask LocalCluster; bad points reported, not fatal."""

import concurrent.futures as cf
import csv
import pickle

import numpy as np
import pytest

import kedfem as kf
from kedfem.io import scenefile as sf
from kedfem.io import sweep
from kedfem.solvers import threads

BASE = {"mechanism": {"name": "slider_crank", "elements": 3}, "steps": 30,
        "effects": ["inertia", "coupling", "axial_stiffening"], "damping": {"model": "modal", "zeta": 0.02}}
#: eight speeds; 0 rpm is a bad point (a periodic response needs a cycle)
AXES = {"speed_rpm": [0.0, 250.0, 500.0, 750.0, 1000.0, 1250.0, 1500.0, 1750.0]}
NUMERIC = ("peak_deflection_m", "deflection_angle_rad", "peak_stress_Pa", "stress_angle_rad", "stress_station_m",
           "fundamental_Hz", "spectral_radius", "iterations")


def check_sweep(res):
    assert len(res.points) == 8 and [p.index for p in res.points] == list(range(8))
    bad, = res.failed
    assert bad.index == 0 and dict(bad.params) == {"speed_rpm": 0.0}
    assert "speed_rpm" in bad.error and "nonzero" in bad.error
    assert all(p.ok and p.peaks and p.converged for p in res.points[1:])
    t = res.table().columns()
    assert list(t["point"]) == list(range(8)) and t["error"][0] and not any(t["error"][1:])


@pytest.fixture(scope="module")
def pool_result():
    return sweep.run_sweep(BASE, AXES, scheduler="processes", max_workers=2, progress=False)


def test_process_pool_and_dask_local_cluster_agree(pool_result):
    pytest.importorskip("distributed")
    check_sweep(pool_result)
    assert pool_result.scheduler.startswith("process pool")
    dres = sweep.run_sweep(BASE, AXES, scheduler="local", max_workers=2, progress=False)
    check_sweep(dres)
    assert dres.scheduler.startswith("dask LocalCluster")
    a, b = pool_result.table().columns(), dres.table().columns()
    for k in NUMERIC:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)   # bit for bit: same code, one BLAS thread
    assert list(a["link"]) == list(b["link"])


def test_points_match_an_independent_in_process_solve(pool_result):
    p = pool_result.points[5]
    scene = sf.scene_from_dict(sweep.make_points(BASE, AXES)[5].scene)
    assert scene.mech.drives[0].speed == pytest.approx(1250.0 * 2 * np.pi / 60, rel=1e-15)
    res = kf.solve(scene)
    ref = res.peaks()[0]
    got = p.peaks[0]
    assert got.link == ref.link == "rod"
    assert got.stress == pytest.approx(ref.stress, rel=1e-9)
    assert got.deflection == pytest.approx(ref.deflection, rel=1e-9)
    assert p.spectral_radius == pytest.approx(np.abs(res.floquet_multipliers).max(), rel=1e-9)
    assert p.fundamental == pytest.approx(res.frequencies(1).fundamental, rel=1e-9)
    # the point carries its time-discretisation error estimate, as the result does
    assert p.errors[0].stress == pytest.approx(res.error.link("rod").stress, rel=1e-9)
    assert p.error_met == res.error.met


def test_csv_and_plot(pool_result, tmp_path):
    path = pool_result.to_csv(tmp_path / "sweep.csv")
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["point", "speed_rpm"] + list(sweep.TABLE_COLUMNS)
    assert len(rows) == 8 and rows[0]["ok"] == "False" and rows[0]["link"] == ""
    for r, p in zip(rows[1:], pool_result.points[1:]):
        assert float(r["peak_stress_Pa"]) == p.peaks[0].stress and float(r["speed_rpm"]) == dict(p.params)["speed_rpm"]
        assert float(r["stress_time_error"]) == p.errors[0].stress and r["error_estimate_met"] == str(p.error_met)
    png = pool_result.plot(tmp_path / "peaks.png")
    assert png.stat().st_size > 1000


def test_user_executor_and_blas_pinning():
    with cf.ProcessPoolExecutor(max_workers=2, initializer=sweep._init_worker,
                                mp_context=sweep._mp_context()) as ex:
        assert {f.result() for f in [ex.submit(threads.thread_count) for _ in range(4)]} == {1}
        pts = sweep.make_points(BASE, {"speed_rpm": [500.0], "mechanism.rod": [0.1, 0.3]})
        res = sweep.run_sweep(None, points=pts, executor=ex, progress=False, frequencies=False)
        assert ex.submit(sum, [1, 2]).result() == 3          # the caller's executor is left running
    bad, good = res.points
    assert not bad.ok and "rod > crank" in bad.error and good.ok and np.isnan(good.fundamental)
    assert res.axes == (("speed_rpm", (500.0,)), ("mechanism.rod", (0.1, 0.3)))


def test_make_points_and_parse_axis():
    pts = sweep.make_points(BASE, {"speed_rpm": [100, 200], "mechanism.elements": [2, 4, 6]})
    assert len(pts) == 6
    assert [dict(p.params) for p in pts[:3]] == [{"speed_rpm": 100, "mechanism.elements": e} for e in (2, 4, 6)]
    assert pts[4].scene["mechanism"] == {"name": "slider_crank", "elements": 4}
    assert BASE["mechanism"] == {"name": "slider_crank", "elements": 3}            # base untouched
    assert pickle.loads(pickle.dumps(pts[0])) == pts[0]                           # plain data
    assert sweep.parse_axis("speed_rpm=100:400:4") == ("speed_rpm", (100, 200, 300, 400))
    assert sweep.parse_axis("speed_rpm=1.5:2.5:3") == ("speed_rpm", (1.5, 2.0, 2.5))
    assert sweep.parse_axis("mechanism.rod=0.3,0.4") == ("mechanism.rod", (0.3, 0.4))
    assert sweep.parse_axis("hold=zoh,foh") == ("hold", ("zoh", "foh"))
    assert sweep.parse_axis('hold="magnus2"') == ("hold", ("magnus2",))
    for bad in ("speed_rpm", "=1,2", "speed_rpm=", "speed_rpm=1:2:x", "speed_rpm=1:2:0", "x=[1"):
        with pytest.raises(kf.InputError):
            sweep.parse_axis(bad)
    with pytest.raises(kf.InputError, match="nothing to sweep"):
        sweep.make_points(BASE, {})
    with pytest.raises(kf.InputError, match="non-empty"):
        sweep.make_points(BASE, {"steps": []})
    with pytest.raises(kf.InputError, match="exceed"):
        sweep.make_points(BASE, {"steps": list(range(200)), "speed_rpm": list(range(1, 200))})


def test_serial_sweep_and_bad_scheduler():
    res = sweep.run_sweep(BASE, {"steps": [12, 10**9]}, scheduler="serial", progress=False, frequencies=False)
    ok, bad = res.points
    assert ok.ok and not bad.ok and "steps" in bad.error and "20000" in bad.error
    with pytest.raises(kf.InputError, match="scheduler"):
        sweep.run_sweep(BASE, {"steps": [12]}, scheduler="threads")


# ------------------------------------------------------- dead workers, resume
def _suicidal(point):
    """A worker function: point 2 kills its own process (``once``: only the first time)."""
    import os
    import signal
    from pathlib import Path
    flag = Path(point.scene["dir"]) / f"died-{point.index}"
    if point.index == 2 and not (point.scene["once"] and flag.exists()):
        flag.touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return sweep.PointResult(point.index, point.params, True, wall_time=0.0, worker=str(os.getpid()))


@pytest.mark.parametrize("once", [True, False])
def test_a_dead_worker_costs_no_other_point(tmp_path, once):
    """SIGKILL of one worker broke the whole pool (5 of 8 points lost); now the pool is rebuilt, the
    points that ran beside it are solved again alone, and a point that kills its worker twice is failed."""
    points = [sweep.SweepPoint(i, (("k", i),), {"dir": str(tmp_path), "once": once}) for i in range(8)]
    seen = []

    class Bar:
        def update(self, n):
            pass
    out = sweep._run_pool(_suicidal, points, 2, Bar(), on_result=seen.append)
    assert sorted(out) == list(range(8)) and sorted(r.index for r in seen) == list(range(8))  # each once
    assert all(out[i].ok for i in range(8) if i != 2)
    if once:
        assert out[2].ok
    else:
        assert not out[2].ok and "died 2 times" in out[2].error


def test_partial_table_resumes_only_the_missing_points(tmp_path):
    from kedfem.io.sweep_journal import SweepJournal, sweep_signature
    axes = {"speed_rpm": [250.0, 500.0, 750.0]}
    points = sweep.make_points(BASE, axes)
    res = sweep.run_sweep(BASE, axes, scheduler="serial", progress=False, frequencies=False)
    j = SweepJournal(tmp_path / "s.partial.csv", sweep_signature(BASE, axes), list(axes))
    j.start()
    for r in res.points[:2]:
        j.append(r)
    j.close()
    # a kill in the middle of a write: a truncated last line is dropped with its point
    with open(j.path, "a") as f:
        f.write("2,750.0,rod,0.0012")
    back = SweepJournal(j.path, sweep_signature(BASE, axes), list(axes)).read(points)
    assert sorted(back) == [0, 1]
    for i in (0, 1):
        a, b = back[i], res.points[i]
        assert (a.ok, a.converged, a.iterations, a.spectral_radius) == (b.ok, b.converged, b.iterations,
                                                                        b.spectral_radius)
        assert a.peaks == b.peaks and [e.stress for e in a.errors] == [e.stress for e in b.errors]
    solved = []
    again = sweep.run_sweep(BASE, axes, scheduler="serial", progress=False, frequencies=False, done=back,
                            on_result=solved.append)
    assert [r.index for r in solved] == [2]
    def text(rows):
        return [[repr(v) for v in r] for r in rows]
    assert text(again.table().rows[:2]) == text(res.table().rows[:2])
    # another sweep's partial table is not resumed into this one
    with pytest.raises(kf.InputError, match="another sweep"):
        SweepJournal(j.path, sweep_signature(BASE, {"speed_rpm": [1.0]}), ["speed_rpm"]).read(points)
