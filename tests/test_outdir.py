"""Output folders are published whole: one run per folder, nothing foreign deleted, leftovers cleaned."""

import json
import os

import pytest

from kedfem import cli
from kedfem.errors import InputError
from kedfem.io.outdir import MANIFEST, RunFolder, check_replaceable, clean_leftovers

QUICK = ("--steps", "24", "--no-mesh-check", "--no-plots", "--modes", "0", "--every", "6")


def run(capsys, *argv):
    rc = cli.main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def files_of(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


def test_a_run_folder_is_one_run_and_a_rerun_replaces_it_whole(tmp_path, capsys):
    out = tmp_path / "o"
    rc, text, err = run(capsys, "run", "exciter", *QUICK, "--out", str(out))
    assert rc == 0, err
    man = json.loads((out / MANIFEST).read_text())
    assert man["command"] == "run" and man["run_id"] in text
    assert sorted(man["files"] + [MANIFEST]) == files_of(out)
    assert man["run_id"] in (out / "summary.txt").read_text()
    # the series carries its own index: the .pvd names the frames beside it
    pvd = (out / "response" / "response.pvd").read_text()
    assert pvd.count("<DataSet") == len(list((out / "response").glob("*.vtu"))) == 360 // 6
    # a second run without VTK leaves no VTK of the first (the old run folder mixed the two)
    rc, text, err = run(capsys, "run", "exciter", *QUICK, "--no-vtk", "--out", str(out))
    assert rc == 0, err
    man2 = json.loads((out / MANIFEST).read_text())
    assert man2["run_id"] != man["run_id"] and not (out / "response").exists()
    assert sorted(man2["files"] + [MANIFEST]) == files_of(out)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_a_folder_with_foreign_files_is_refused_before_any_work(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine")
    rc, text, err = run(capsys, "run", "exciter", *QUICK, "--out", str(tmp_path))
    assert rc == 2 and "notes.txt" in err and "solving" not in text
    assert (tmp_path / "notes.txt").read_text() == "mine"
    # a folder of an earlier version (no manifest, only names kedfem writes) is replaced
    old = tmp_path / "old"
    (old / "response").mkdir(parents=True)
    (old / "response.pvd").write_text("stale")
    (old / "summary.txt").write_text("kedfem 0.1.0: slider-crank\n")
    check_replaceable(old)
    # ... but a user's own files that merely share kedfem's names are not replaced
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "peaks.csv").write_text("my,data\n")
    (mine / "summary.txt").write_text("my notes\n")
    with pytest.raises(InputError, match="peaks.csv"):
        check_replaceable(mine)
    # a manifest vouches only for the files it lists
    with RunFolder(tmp_path / "m", "run") as rf:
        (rf.path / "a.csv").write_text("1")
    (tmp_path / "m" / "b.csv").write_text("user's")
    with pytest.raises(InputError, match="b.csv"):
        check_replaceable(tmp_path / "m")


def test_a_failing_run_leaves_the_old_folder_and_no_staging(tmp_path):
    with RunFolder(tmp_path / "o", "run") as rf:
        (rf.path / "a.csv").write_text("old")
    with pytest.raises(RuntimeError):
        with RunFolder(tmp_path / "o", "run") as rf:
            (rf.path / "a.csv").write_text("new")
            raise RuntimeError("disk full")
    assert (tmp_path / "o" / "a.csv").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]


def test_leftovers_of_killed_runs_are_removed_by_the_next_run(tmp_path):
    dead = tmp_path / ".o.staging-999999999-abcdef"      # no such process
    live = tmp_path / f".o.staging-{os.getppid()}-abcdef"  # a running process: not touched
    other = tmp_path / ".p.old-999999999-abcdef"           # another folder's
    for d in (dead, live, other):
        (d / "response").mkdir(parents=True)
    assert clean_leftovers(tmp_path / "o") == [dead]
    assert live.exists() and other.exists() and not dead.exists()


def assert_no_nan(folder):
    import csv

    import meshio
    import numpy as np
    checked = 0
    for p in folder.rglob("*"):
        if p.suffix in (".csv", ".txt", ".json", ".pvd"):
            text = p.read_text()
            if p.suffix == ".csv":
                cells = [c.strip().lower() for row in csv.reader(text.splitlines()) for c in row]
                assert "nan" not in cells, p
        elif p.suffix == ".npz":
            z = np.load(p)
            for k in z.files:
                if z[k].dtype.kind in "fc":
                    assert np.all(np.isfinite(z[k])), (p, k)
        elif p.suffix == ".vtu":
            m = meshio.read(p)
            arrays = list(m.point_data.items()) + [(k, np.concatenate(v)) for k, v in m.cell_data.items()]
            for k, a in arrays:
                assert np.all(np.isfinite(np.asarray(a, dtype=float))), (p, k)
        else:
            continue
        checked += 1
    return checked


def test_no_nan_in_any_file_a_user_reads(tmp_path, capsys):
    """Rigid parts' section forces and mode files were NaN in the VTK, a sweep without frequencies
    wrote nan cells; overdamped modes are named, not nan (issue 12)."""
    rc, text, err = run(capsys, "run", "slider_crank", "--steps", "24", "--no-mesh-check", "--no-plots",
                        "--every", "20", "--modes", "2", "--out", str(tmp_path / "r"))
    assert rc == 0, err
    assert assert_no_nan(tmp_path / "r") > 8
    import meshio
    frame = meshio.read(next((tmp_path / "r" / "response").glob("*.vtu")))
    flag = frame.point_data["section_forces_computed"]
    assert 0 < flag.sum() < flag.size  # the rigid crank has none, the rod has them
    rc, text, err = run(capsys, "sweep", "exciter", "--param", "speed_rpm=300,600", "--scheduler", "serial",
                        "--steps", "24", "--no-plots", "--no-frequencies", "--no-progress",
                        "--out", str(tmp_path / "s"))
    assert rc == 0, err
    assert assert_no_nan(tmp_path / "s") >= 2


def test_overdamped_modes_are_named_not_nan(tmp_path):
    import numpy as np

    import kedfem as kf
    import mechanisms
    from kedfem.io import export
    res = kf.solve(kf.Scene(mechanisms.build("exciter"), effects=("inertia", "coupling", "springs"),
                            damping=kf.Rayleigh(alpha=0.0, beta=0.05), steps=24, estimate=False))
    f = res.frequencies(6, nodes=[0, 1])
    assert np.isnan(f.state_space).any()  # beta = 0.05 s overdamps the stiffer modes
    text = export.write_frequencies_csv(f, tmp_path / "f.csv").read_text()
    # the tidy table says which modes do not oscillate (their state-space cells empty), never nan
    rows = [line.split(",") for line in text.splitlines()[1:]]
    still = [r for r in rows if r[5] == "False"]
    assert still and all(r[3] == r[4] == "" for r in still) and "nan" not in text.lower()
    z = np.load(export.write_npz(res, tmp_path / "r.npz", f))
    assert np.all(np.isfinite(z["state_space"])) and not z["oscillating"].all()


def test_the_writability_probe_goes_beside_the_output_folder(tmp_path, monkeypatch):
    """``check_out_dir`` probes the folder the run's staging folder goes into, not the output folder:
    a kill between creating and removing the probe left it in the last run's published folder (a
    kill test found the folder mixing runs), and beside it the probe is named as a leftover that
    ``clean_leftovers`` recognises."""
    from kedfem.io import outdir, report
    out = tmp_path / "o"
    out.mkdir()
    (out / "summary.txt").write_text("run x")
    monkeypatch.setattr(report.os, "unlink", lambda *a, **k: None)  # as if killed before the unlink
    report.check_out_dir(out)
    assert [p.name for p in out.iterdir()] == ["summary.txt"]
    left = [p for p in tmp_path.iterdir() if p.name != "o"]
    assert len(left) == 1 and outdir._LEFTOVER.match(left[0].name).group("name") == "o"
