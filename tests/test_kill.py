"""SIGKILL at random moments of ``kedfem run`` and ``kedfem sweep``: a folder is always one whole run.

After every kill the output folder is either absent (before the first run
completed), the complete old run or the complete new one: its manifest lists
exactly the files in it and ``summary.txt`` is of the manifest's run. A killed
sweep's partial table holds each finished point once, and ``--resume`` solves
only the others.
"""

import csv
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from kedfem.io.outdir import MANIFEST

RUN = ("run", "exciter", "--steps", "24", "--no-mesh-check", "--no-plots", "--modes", "0", "--every", "6")
SWEEP = ("sweep", "exciter", "--param", "speed_rpm=300:900:6", "--scheduler", "serial", "--steps", "24",
         "--no-plots", "--no-frequencies", "--no-progress")

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs SIGKILL")


def command():
    exe = Path(sys.executable).parent / "kedfem"
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "kedfem.cli"]


def start(args, out):
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.Popen(command() + list(args) + ["--out", str(out)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, env=env)


def whole(folder: Path):
    """The run id of a complete run folder (None if there is none); fails on a mixed folder."""
    if not folder.exists():
        return None
    man = json.loads((folder / MANIFEST).read_text())
    files = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
    assert sorted(man["files"] + [MANIFEST]) == files, "the folder mixes runs"
    if "summary.txt" in man["files"]:
        assert man["run_id"] in (folder / "summary.txt").read_text()
    pvd = folder / "response" / "response.pvd"
    if pvd.exists():
        assert pvd.read_text().count("<DataSet") == len(list(pvd.parent.glob("*.vtu")))
    return man["run_id"]


def timed(args, out):
    t = time.perf_counter()
    p = start(args, out)
    _, err = p.communicate(timeout=300)
    assert p.returncode in (0, 1), err.decode()
    return time.perf_counter() - t


def test_killed_runs_leave_the_old_run_or_the_new_one(tmp_path):
    out = tmp_path / "o"
    rng = random.Random(12)
    full = None
    ids = []
    for k in range(20):
        if k in (0, 7, 14):  # complete runs between the kills
            full = timed(RUN, out)
            ids.append(whole(out))
            continue
        p = start(RUN, out)
        time.sleep(rng.uniform(0.0, 1.1 * full))
        p.send_signal(signal.SIGKILL)
        p.wait()
        rid = whole(out)
        assert rid == ids[-1] or rid not in ids, (k, rid)  # the old run, or a new complete one
        if rid != ids[-1]:
            ids.append(rid)
    timed(RUN, out)
    whole(out)
    assert [p.name for p in tmp_path.iterdir()] == ["o"]  # the killed runs' leftovers are gone


def test_killed_sweeps_resume_each_point_once(tmp_path):
    out = tmp_path / "s"
    partial = tmp_path / "s.partial.csv"
    rng = random.Random(5)
    full = timed(SWEEP, out)
    first = whole(out)
    assert not partial.exists()
    for _ in range(6):
        p = start(SWEEP, out)
        time.sleep(rng.uniform(0.3, 1.0) * full)
        p.send_signal(signal.SIGKILL)
        p.wait()
        whole(out)
        if partial.exists():
            with open(partial, newline="") as f:
                rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")][1:]
            idx = [int(r[0]) for r in rows]
            assert len(idx) == len(set(idx)), "a point recorded twice"
    # interrupt once more after some points, then resume: only the missing points are solved
    p = start(SWEEP, out)
    deadline = time.time() + 120
    while time.time() < deadline:
        if partial.exists() and sum(1 for _ in open(partial)) >= 4:  # tag, header, 2 points
            break
        time.sleep(0.02)
    p.send_signal(signal.SIGKILL)
    p.wait()
    with open(partial, newline="") as f:
        done = {int(r[0]) for r in list(csv.reader(f))[2:]}
    assert done
    r = subprocess.run(command() + list(SWEEP) + ["--out", str(out), "--resume"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert f"{len(done)} of 6 points done" in r.stdout and f"sweep of {6 - len(done)} points" in r.stdout
    whole(out)
    with open(out / "sweep.csv", newline="") as f:
        pts = [row["point"] for row in csv.DictReader(f)]
    assert sorted(map(int, pts)) == list(range(6)) and not partial.exists()


def _descendants(pid: int) -> set[int]:
    parent = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                parent[int(d.name)] = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                pass
    out, todo = set(), [pid]
    while todo:
        p = todo.pop()
        kids = [c for c, pp in parent.items() if pp == p]
        out.update(kids)
        todo.extend(kids)
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_a_killed_sweep_leaves_no_orphaned_workers(tmp_path):
    """kill -9 of a sweep's main process left its pool workers (and the forkserver) running on."""
    p = start(("sweep", "four_bar", "--param", "speed_rpm=100:300:20", "--scheduler", "processes",
               "--workers", "2", "--no-progress"), tmp_path / "s")
    deadline = time.time() + 60
    kids = set()
    while time.time() < deadline and len(kids) < 3:  # resource tracker, forkserver, workers
        time.sleep(0.2)
        kids = _descendants(p.pid)
    assert len(kids) >= 3, kids
    time.sleep(1.0)
    p.send_signal(signal.SIGKILL)
    p.wait()
    deadline = time.time() + 15
    while time.time() < deadline and any(_alive(k) for k in kids):
        time.sleep(0.2)
    assert not any(_alive(k) for k in kids), [k for k in kids if _alive(k)]
