"""kf.continuation on a forced cubic oscillator built with the public API (a tip mass on a
cantilever, a crank-driven spring and a cubic spring to the frame): the response curve through
both folds against an independent harmonic balance with its own continuation and fold location
(tests/duffing_hb.py, nothing of kedfem), to 1e-4 in amplitude and fold speeds; the middle
branch unstable, the others stable."""

import math

import numpy as np
import pytest

import kedfem as kf
from duffing_hb import Rig

RPM = 2 * math.pi / 60
P = dict(L=0.3, b=0.02, h=0.004, E=2e11, rho=7800.0, mt=1.0, kd=1000.0, k3=3.0e7, e=0.002)
ALPHA = 2.0  # mass-proportional damping [1/s]


def rig(speed=500 * RPM):
    m = kf.Mechanism("duffing rig")
    m.ground("G", (0.0, 0.0), clamped=True)          # a vertical cantilever ...
    m.joint("T", (0.0, P["L"]))
    m.ground("X", (-0.1, P["L"]))                    # ... loaded at its tip by a crank-driven spring
    m.joint("P", (-0.1 + P["e"], P["L"]))
    m.link("beam", "G", "T", material=kf.Material(E=P["E"], rho=P["rho"]),
           section=kf.Section.rectangle(P["b"], P["h"]), elements=1)
    m.link("crank", "X", "P", rigid=True)
    m.point_mass("T", P["mt"])
    m.spring("drive", "P", "T", k=P["kd"], axis=(1.0, 0.0))
    m.spring("cubic", "T", k=0.0, k3=P["k3"], axis=(1.0, 0.0))  # hardening: k3 v^3
    m.drive("crank", speed=speed)
    return m


@pytest.fixture(scope="module")
def branch():
    sc = kf.Scene(rig(), effects=("inertia", "springs"), damping=kf.Rayleigh(alpha=ALPHA, beta=0.0))
    return kf.continuation(sc, 300 * RPM, 900 * RPM, steps=48, errors=False, progress=False)


@pytest.fixture(scope="module")
def reference():
    r = Rig(**P, alpha=ALPHA)
    pts = r.branch(300 * RPM, 900 * RPM)
    ws = np.array([w for _a, w in pts])
    turns = [i for i in range(1, len(ws) - 1) if (ws[i] - ws[i - 1]) * (ws[i + 1] - ws[i]) < 0]
    folds = [r.fold(*pts[i]) for i in turns]
    return r, pts, folds


def tip_peak(res, samples=2048):
    x = res.resample(times=np.arange(samples) * (res.scene.period / samples)).joint_displacement("T")[:, 0]
    return float(np.abs(x).max())


def test_fold_speeds_agree_with_harmonic_balance(branch, reference):
    _r, _pts, folds = reference
    ref = sorted(w for _a, w in folds)
    got = sorted(b.value for b in branch.bifurcations if b.kind == "fold")
    assert len(ref) == 2 and len(got) == 2, (ref, got)
    for a, b in zip(got, ref):
        assert a == pytest.approx(b, rel=1e-4)
    first = branch.first_loss_of_stability
    assert first.kind == "fold" and first.value == pytest.approx(max(ref), rel=1e-4)


def test_amplitudes_agree_and_the_middle_branch_is_unstable(branch, reference):
    r, pts, folds = reference
    w_hi, w_lo = max(w for _a, w in folds), min(w for _a, w in folds)
    hb = [(w, r.peak_v(a), a) for a, w in pts]
    checked = 0
    for p in branch.points[::4]:
        amp = tip_peak(p.result)
        # the harmonic-balance point on the same part of the curve: nearest in (speed, amplitude)
        w0, _amp0, a0 = min(hb, key=lambda q: abs(q[0] - p.value) / p.value + abs(q[1] - amp) / amp)
        a = r.solve(a0, p.value)
        assert amp == pytest.approx(r.peak_v(a), rel=1e-4), p.value / RPM
        checked += 1
    assert checked >= 10
    # stability: the branch is stable up to the upper fold, unstable between the folds on its way
    # back, stable again after the lower fold
    vals, stable = branch.values, branch.stable
    d = np.sign(np.diff(vals))
    i_hi = int(np.argmax(d < 0))                 # the speed turns back at the upper fold ...
    i_lo = i_hi + int(np.argmax(d[i_hi:] > 0))   # ... and forward again at the lower one
    assert vals[i_hi] == pytest.approx(w_hi, rel=1e-4) and vals[i_lo] == pytest.approx(w_lo, rel=1e-3)
    assert stable[:i_hi - 1].all() and not stable[i_hi + 1:i_lo].any() and stable[i_lo + 1:].all()


def test_branch_files(branch, tmp_path):
    files = kf.write_branch(branch, tmp_path)
    names = sorted(f.name for f in files)
    assert names == ["branch.csv", "branch_bifurcations.csv", "response_curve.png"]
    import csv
    rows = list(csv.DictReader(open(tmp_path / "branch_bifurcations.csv")))
    assert [r["kind"] for r in rows] == ["fold", "fold"]
    assert float(rows[0]["speed_rpm"]) == pytest.approx(branch.bifurcations[0].value / RPM)
    # read back: the same points, peaks, verdicts and bifurcations (what the CSV holds)
    back = kf.read_branch(tmp_path)
    assert [p.value for p in back.points] == pytest.approx([p.value for p in branch.points], rel=1e-15)
    assert [p.stable for p in back.points] == [p.stable for p in branch.points]
    assert [p.peak("beam", "deflection") for p in back.points] == pytest.approx(
        [p.peak("beam", "deflection") for p in branch.points], rel=1e-15)
    assert [(b.kind, b.value, b.stable_after) for b in back.bifurcations] == \
        [(b.kind, pytest.approx(b.value, rel=1e-15), b.stable_after) for b in branch.bifurcations]
    assert back.first_loss_of_stability.value == pytest.approx(branch.first_loss_of_stability.value, rel=1e-15)
    with pytest.raises(kf.InputError, match="branch"):
        kf.read_branch(tmp_path / "nowhere")


def _interrupt_after(monkeypatch, steps: int):
    """Ctrl-C (KeyboardInterrupt) in the pseudo-arclength step after ``steps`` of them; returns
    the real step."""
    from kedfem.analysis import branch as br
    calls = {"n": 0}
    advance = br.Tracker.advance

    def interrupted(self, p, t):
        calls["n"] += 1
        if calls["n"] > steps:
            raise KeyboardInterrupt
        return advance(self, p, t)

    monkeypatch.setattr(br.Tracker, "advance", interrupted)
    return advance


def test_a_branch_interrupted_returns_its_points_so_far(monkeypatch, caplog):
    """Ctrl-C while a branch is followed ends it at its last point and returns it (a new user
    killed a 28-minute branch and had nothing), without the per-point errors and the period-2
    branch, which would take as long again."""
    import logging
    _interrupt_after(monkeypatch, 5)
    sc = kf.Scene(rig(), effects=("inertia", "springs"), damping=kf.Rayleigh(alpha=ALPHA, beta=0.0))
    with caplog.at_level(logging.WARNING, logger="kedfem.analysis.continuation"):
        b = kf.continuation(sc, 300 * RPM, 900 * RPM, steps=48, errors=True, progress=False)
    assert b.end.startswith("interrupted at") and "rpm" in b.end
    assert len(b.points) == 7 and all(not p.errors for p in b.points) and b.subharmonic is None
    assert b.values[-1] > b.values[0] and all(p.peaks for p in b.points)
    assert any("the branch so far is returned (7 points)" in r.getMessage() for r in caplog.records)


def test_a_long_branch_says_how_long_at_its_pace(monkeypatch, caplog):
    """The rest of a branch at the pace so far: the range still to cover times the seconds per
    unit covered, from the farthest value reached (a fold turning back does not shorten it);
    said from the third point on and a tenth of the range, when above LONG_BRANCH, and again when
    it has doubled."""
    import logging
    from kedfem.analysis import continuation as cont
    now = {"t": 100.0}
    monkeypatch.setattr(cont.time, "perf_counter", lambda: now["t"])
    pace = cont._Pace(10.0, 20.0, 96, (1.0, "rad/s"), 100.0)
    with caplog.at_level(logging.WARNING, logger="kedfem.analysis.continuation"):
        now["t"] = 130.0
        assert pace(10.5, 2) == ", about 570 s left" and not caplog.records  # 5 % of the range: not said
        now["t"] = 160.0
        assert pace(12.0, 3) == ", about 240 s left"                        # 60 s for 2 of 10
        now["t"] = 190.0
        assert pace(11.0, 4) == ", about 360 s left"  # turned back: still from 12, 90 s for 2
        now["t"] = 400.0
        pace(13.0, 5)  # 300 s for 3 of 10: 700 s left, more than twice 240: said again
        now["t"] = 420.0
        pace(13.2, 6)  # 735 s: not twice 700
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 2 and "about 240 s more at this pace" in said[0] and "96 time elements" in said[0]
    assert "about 700 s more" in said[1]


def test_an_unstable_non_linear_response_is_not_called_parametric(branch):
    """A solve started on the branch's unstable middle part (between the folds) converges there
    and warns of an unstable periodic response of the non-linear scene, not of a parametric
    instability (the linear solve of Newton's last step says that; a new user read it as the
    linear machine's). A critical speed of a non-linear scene says so too."""
    import dataclasses
    from kedfem.analysis.critical import CriticalSpeed
    mid = next(p for p in branch.points if not p.stable)
    sc = kf.Scene(rig(mid.value), effects=("inertia", "springs"), damping=kf.Rayleigh(alpha=ALPHA, beta=0.0),
                  steps=48, estimate=False)
    with pytest.warns(kf.InstabilityWarning) as caught:
        res = kf.solve(sc, start=mid.result)
    assert not res.stable
    text = " ".join(str(w.message) for w in caught if issubclass(w.category, kf.InstabilityWarning))
    assert "unstable non-linear periodic response" in text and "parametric" not in text, text
    c = CriticalSpeed("parametric", 100.0, (99.9, 100.1), 6, 1e-3, True, 0.9, 1.1, "onset", (), ("inertia",))
    assert "parametric instability at" in c.describe()
    assert "instability of the non-linear periodic response at" in dataclasses.replace(c, nonlinear=True).describe()


def test_an_interrupted_branch_on_the_command_line_is_written_and_exits_130(monkeypatch, tmp_path, capsys):
    """``kedfem continuation`` stopped by Ctrl-C writes the branch so far and says so by its exit
    status (130) and a line on stderr (the review's: it exited 0 with files that did not say the
    branch was cut), and the plot's title names where. Ctrl-C during the error estimates keeps
    every point, those not reached without their errors."""
    import logging
    from kedfem import cli
    from kedfem.analysis import continuation as cont
    advance = _interrupt_after(monkeypatch, 3)
    scene = tmp_path / "rig.py"
    scene.write_text("import sys\nsys.path.insert(0, %r)\nfrom test_continuation import rig\n"
                     "def build():\n    return rig()\n" % str(__import__("pathlib").Path(__file__).parent))
    root = logging.getLogger("kedfem")
    before, level = list(root.handlers), root.level
    try:
        code = cli.main(["continuation", f"{scene}:build", "--trust", str(scene), "--speeds", "300:900",
                         "--steps", "48", "--no-errors", "--no-period2", "--no-progress", "--out", str(tmp_path / "out"),
                         "--effects", "inertia,springs"])
    finally:
        root.handlers[:] = before
        root.setLevel(level)
    err = capsys.readouterr().err
    assert code == 130 and "kedfem: interrupted: interrupted at" in err, err
    assert (tmp_path / "out" / "branch.csv").exists()
    # Ctrl-C in the error estimates: 5 points tracked, the estimates stopped after the second
    from kedfem.analysis.branch import Tracker
    monkeypatch.setattr(Tracker, "advance", advance)
    read = cont._read
    done = {"n": 0}

    def stop_reading(scene_of, point, n, errors, periods):
        if errors:
            done["n"] += 1
            if done["n"] > 2:
                raise KeyboardInterrupt
        return read(scene_of, point, n, errors, periods)

    monkeypatch.setattr(cont, "_read", stop_reading)
    sc = kf.Scene(rig(), effects=("inertia", "springs"), damping=kf.Rayleigh(alpha=ALPHA, beta=0.0))
    b = kf.continuation(sc, 300 * RPM, 900 * RPM, steps=48, errors=True, max_points=5, progress=False)
    assert len(b.points) == 5 and [bool(p.errors) for p in b.points] == [True, True, False, False, False]
    assert "error estimates interrupted after 2 of 5 points" in b.end
