"""The ``kedfem`` command line: the default run end to end, every subcommand, clean errors."""

import csv
import json
import dataclasses
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import kedfem as kf

import kedfem
from kedfem import cli
from kedfem.io.scenefile import MAX_STEPS

ROOT = Path(__file__).resolve().parents[1]
#: wall-time limits are multiplied by this factor (set it on a loaded or slow machine)
TIME_FACTOR = float(os.environ.get("KEDFEM_TIME_FACTOR", "1"))


def kedfem_command():
    exe = Path(sys.executable).parent / "kedfem"
    if exe.exists():
        return [str(exe)]                         # the installed console script
    found = shutil.which("kedfem")
    return [found] if found else [sys.executable, "-m", "kedfem.cli"]


def test_default_run_end_to_end(tmp_path):
    """``kedfem run`` on the built-in default scene: < 20 s, plots + CSV + PVD series + the summary table."""
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    t0 = time.perf_counter()
    out = subprocess.run(kedfem_command() + ["run"], cwd=tmp_path, capture_output=True, text=True, env=env,
                         timeout=300)
    wall = time.perf_counter() - t0
    assert out.returncode == 0, out.stderr
    assert "Traceback" not in out.stderr
    text = out.stdout
    for heading in ("mould oscillator, group 1", "built-in default scene", "natural frequencies over the cycle [Hz]",
                    "state-space", "modal", "peak response per flexible link", "Floquet stability",
                    "spectral radius", "converged:", "residual", "wall time [s]", "kinematics", "solve",
                    "files in kedfem-out/"):
        assert heading in text, heading
    dest = tmp_path / "kedfem-out"
    for name in ("response.csv", "peaks.csv", "frequencies.csv", "fatigue.csv", "histories.csv", "histories.npz",
                 "loads.csv", "loads.png", "result.npz", "displacement.png",
                 "link_response.png", "frequencies.png", "floquet.png", "response/response.pvd", "modes/modes.pvd",
                 "summary.txt", "kedfem-run.json"):
        assert (dest / name).is_file(), name
        assert name in text
    manifest = json.loads((dest / "kedfem-run.json").read_text())  # the crank angles' convention, named
    assert manifest["crank_angle"].startswith("of the crank 'eccentric_outer', absolute")
    with open(dest / "response.csv", newline="") as f:
        n_rows = sum(1 for _ in csv.DictReader(f))
    assert len(list((dest / "response").glob("*.vtu"))) == n_rows >= 360
    assert (dest / "summary.txt").read_text().strip() in text
    # the printed peak table is the CSV's
    with open(dest / "peaks.csv", newline="") as f:
        peaks = list(csv.DictReader(f))
    assert [p["link"] for p in peaks] == ["rod_outer", "rod_inner", "leaf_inner", "leaf_outer"]
    for p in peaks:
        row = next(ln for ln in text.splitlines() if ln.strip().startswith(p["link"] + " "))
        nums = row.split()
        # the summary reads mm and MPa, the files SI; printed to the digits their errors allow:
        # the file's value rounded to them
        for printed, value in ((nums[1], 1e3 * float(p["peak_deflection_m"])),
                               (nums[4], 1e-6 * float(p["peak_stress_Pa"]))):
            mant, _, exp = printed.partition("e")
            place = 10.0 ** (int(exp or 0) - (len(mant.split(".")[1]) if "." in mant else 0))
            assert abs(float(printed) - value) <= 0.5 * place * (1 + 1e-9), (printed, value)
            assert place <= 1e-2 * abs(value)  # at least three digits (the estimates are below 1e-3)
    # the radius printed to the digits its error leaves: the file's value rounded to them
    m = re.search(r"spectral radius ([0-9.]+) \+- ([0-9.e+-]+)", text)
    z = np.load(dest / "result.npz")
    digits = len(m.group(1).split(".")[1]) if "." in m.group(1) else 0
    assert float(m.group(1)) == pytest.approx(np.abs(z["floquet_multipliers"]).max(), abs=0.5 * 10.0**-digits)
    assert 10.0**-digits >= float(m.group(2)) / 10
    conv = re.search(r"converged: (yes|NO)", text).group(1)
    assert (conv == "yes") == bool(z["converged"])
    total = float(re.search(r"total ([0-9.]+)", text).group(1))
    assert total < 20.0 * TIME_FACTOR, f"kedfem run took {total:.1f} s (process {wall:.1f} s)"


def run(capsys, *argv):
    rc = cli.main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def test_small_run_in_process_honours_flags(tmp_path, capsys):
    rc, out, err = run(capsys, "run", "slider-crank", "--steps", "24", "--speed", "600", "--out", str(tmp_path),
                       "--no-vtk", "--no-plots", "--effects", "inertia,coupling", "--hold", "zoh")
    assert rc == 0, err
    assert "zoh, 24 time elements (steps given)" in out and "600 rpm (62.8319 rad/s)" in out
    assert "effects     inertia, coupling" in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fatigue.csv", "frequencies.csv", "histories.csv",
                                                          "histories.npz", "kedfem-run.json", "loads.csv",
                                                          "peaks.csv", "response.csv", "result.npz",
                                                          "summary.txt"]


def test_scene_file_outputs_and_strict(tmp_path, capsys, monkeypatch):
    scene = tmp_path / "s.toml"
    scene.write_text(f'steps = 24\n[mechanism]\nname = "exciter"\n[output]\ndir = "{tmp_path / "o"}"\n'
                     'plots = false\ncsv = false\nnpz = false\nmodes = 0\nevery = 6\n')
    # a scene file writes below the working folder only: an absolute output.dir is refused
    rc, out, err = run(capsys, "run", str(scene))
    assert rc == 2 and "output.dir" in err and "below the working folder" in err and not (tmp_path / "o").exists()
    scene.write_text(scene.read_text().replace(f'dir = "{tmp_path / "o"}"', 'dir = "o"'))
    monkeypatch.chdir(tmp_path)
    rc, out, err = run(capsys, "run", str(scene), "--strict")
    assert rc == 0, err
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == ["kedfem-run.json", "response", "summary.txt"]
    assert len(list((tmp_path / "o" / "response").glob("*.vtu"))) == 360 // 6  # output instants / every


def one_line_error(rc, err, *words):
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("kedfem: error: "), err
    for w in words:
        assert w in lines[0], (w, err)


def test_errors_are_one_line_exit_2(tmp_path, capsys):
    rc, _, err = run(capsys, "run", "slidercrank")
    one_line_error(rc, err, "'slidercrank'", "did you mean 'slider_crank'")
    bad = tmp_path / "bad.toml"
    bad.write_text('[mechanism]\nname = "exciter"\nelements = 3\ntip_mas = 1.0\n')
    rc, _, err = run(capsys, "run", str(bad))
    one_line_error(rc, err, f"{bad}:4:", "mechanism.tip_mas", "did you mean 'tip_mass'")
    rc, _, err = run(capsys, "export", str(tmp_path / "missing.toml"))
    one_line_error(rc, err, "missing.toml", "cannot read")
    rc, _, err = run(capsys, "sweep", "exciter", "--steps", "12", "--param", "mechanism.lenght=1,2")
    one_line_error(rc, err, "sweep.mechanism.lenght", "mechanism.length")
    rc, _, err = run(capsys, "sweep", "exciter")
    one_line_error(rc, err, "nothing to sweep")
    rc, _, err = run(capsys, "run", "four_bar", "--steps", "12", "--dofs", "nope", "--out", str(tmp_path / "x"),
                     "--no-vtk")
    one_line_error(rc, err, "'nope'")
    (tmp_path / "afile").write_text("x")   # an --out below a file: caught before the solve
    rc, out, err = run(capsys, "run", "four_bar", "--out", str(tmp_path / "afile" / "sub"))
    one_line_error(rc, err, "is a file, not a folder")
    assert "solving" not in out
    # argparse usage errors: exit 2 with usage, no traceback
    rc, _, err = run(capsys, "run", "--steps", str(MAX_STEPS + 1))
    assert rc == 2 and "--steps" in err and "Traceback" not in err
    rc, _, err = run(capsys, "run", "--speed", "nan")
    assert rc == 2 and "--speed" in err


def test_kedfem_errors_in_a_subprocess_print_no_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("steps = inf\n[mechanism]\nname = 'exciter'\n")
    out = subprocess.run(kedfem_command() + ["run", str(bad)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.strip() == f"kedfem: error: {bad}:1: steps: must be an integer, got a number inf"


def test_help_version_and_list(capsys):
    for argv in (["--help"], ["run", "--help"], ["validate", "--help"], ["sweep", "--help"], ["export", "--help"],
                 ["list", "--help"]):
        rc, out, _ = run(capsys, *argv)
        assert rc == 0 and out.startswith("usage: kedfem"), argv
    rc, out, _ = run(capsys, "--version")
    assert rc == 0 and out.strip() == f"kedfem {kedfem.__version__}"
    rc, out, _ = run(capsys, "list")
    assert rc == 0
    import mechanisms
    for name in mechanisms.available():
        assert f"  {name}: " in out
    for e, eff in kedfem.EFFECTS.items():
        assert e in out and eff.adds in out
    assert "rod_diameter" in out and "[m]" in out and "speed_rpm" in out
    # presets and signed parameters as the mechanisms declare them
    assert "    crank_angle (+-) " in out and "    crank (+-) " not in out
    assert "solver eps = 1e-06, nonlinear_method = 'fixed-point'" in out


@pytest.mark.parametrize("overrides", [{}, {"accuracy": "fast"}, {"method": "foh", "steps": 40},
                                       {"effects": "all", "speed_rpm": 120.0, "rtol": 1e-2}])
def test_the_default_scene_is_the_default_mechanisms_preset(overrides):
    """`kedfem run` without a scene loads the default mechanism's preset like a mechanism name."""
    import dataclasses

    from kedfem.analysis.defaults import DEFAULT_MECHANISM

    def fields(sc):  # the mechanism holds closures (loads): compared by its summary
        return {f.name: getattr(sc, f.name) for f in dataclasses.fields(sc) if f.name not in ("mechanism", "_mech")}

    ld, named = cli._load(None, dict(overrides)), cli._load(DEFAULT_MECHANISM, dict(overrides))
    assert ld.source == "built-in default scene" and fields(ld.scene) == fields(named.scene)
    assert ld.scene.mech.summary() == named.scene.mech.summary()
    assert ld.data == dict(named.data, name="mould oscillator, group 1") and ld.sweep == {}
    if not overrides:
        assert fields(ld.scene) == fields(kedfem.default_scene())


def test_validate(capsys, monkeypatch):
    from kedfem.analysis import validation

    def quick_table3(steps=None, **kw):
        assert steps == 12
        return validation.ValidationReport((validation.FrequencyCheck("mould oscillator, group 1", 17.3, 17.3,
                                                                       17.0, 17.6, 5, True, 17.33, 17.35),))

    monkeypatch.setattr(validation, "table3", quick_table3)
    rc, out, err = run(capsys, "validate", "--steps", "12")
    assert rc == 0, err
    assert "Table 3" in out and "mould oscillator, group 1" in out and "17.33" in out
    assert "modal superposition (foh)" in out and "modal superposition (exact), radau3" in out
    assert "FAIL" not in out and out.count("PASS") == 2
    rc, out, _ = run(capsys, "validate", "--steps", "12", "--skip-table3", "--tol", "1e-30")
    assert rc == 1 and "FAIL" in out and "Table 3" not in out


def test_sweep_and_export_commands(tmp_path, capsys):
    rc, out, err = run(capsys, "sweep", "slider_crank", "--steps", "20", "--param", "speed_rpm=500,1000",
                       "--param", "mechanism.rod=0.1,0.3", "--scheduler", "serial", "--out", str(tmp_path / "s"))
    assert rc == 1                      # two of four points failed, and the sweep says so
    assert out.count("FAILED") == 2 and "rod > crank" in out and "2 of 4 points solved" in out
    assert (tmp_path / "s" / "sweep.csv").is_file() and (tmp_path / "s" / "sweep_peaks.png").is_file()
    pytest.importorskip("pyvista")
    rc, out, err = run(capsys, "export", "exciter", "--steps", "24", "--render", "--modes", "2",
                       "--out", str(tmp_path / "e"))
    assert rc == 0, err
    e = tmp_path / "e"
    assert (e / "response" / "response.pvd").is_file() and len(list((e / "modes").glob("*.vtu"))) == 2
    import matplotlib.image as mpimg
    img = mpimg.imread(str(e / "deformed.png"))[..., :3]
    assert 0.002 < 1.0 - np.all(img > 0.97, axis=-1).mean() < 0.9 and img.std() > 0.02   # not blank


def test_strict_fails_on_the_strength_checks_the_summary_shows():
    """--strict fails on a link above its yield strength and below its fatigue safety factors,
    each named, as well as on convergence, stability and the error."""
    from kedfem.cli import strict_failures
    m = kf.Mechanism("weak slider-crank")
    m.ground("O", at=(0.0, 0.0))
    m.joint("A", at=(0.05, 0.0))
    m.slider("B", at=(0.25, 0.0), axis=(1.0, 0.0))
    m.link("crank", "O", "A", rigid=True, mass=0.2)
    soft = kf.Material(E=2.0e11, rho=7850.0, yield_strength=1e6, ultimate_strength=2e6, endurance_limit=1e6)
    m.link("rod", "A", "B", material=soft, section=kf.Section.rectangle(0.008, 0.008), elements=4)
    m.point_mass("B", 0.5)
    m.drive("crank", speed=150.0)
    res = kf.solve(kf.Scene(m, steps=48, estimate=False, damping=kf.ModalDamping(0.02)))
    failed = strict_failures(res)
    assert any("exceeds the yield strength" in f for f in failed)
    assert any("safety factor against Goodman" in f and "< 1" in f for f in failed)
    strong = kf.Material(E=2.0e11, rho=7850.0, yield_strength=1e9, ultimate_strength=2e9, endurance_limit=5e8)
    m.links["rod"] = dataclasses.replace(m.links["rod"], material=strong)
    assert strict_failures(kf.solve(kf.Scene(m, steps=48, estimate=False, damping=kf.ModalDamping(0.02)))) == []


def test_logged_and_python_warnings_read_alike_on_the_command_line(capsys):
    """``kedfem: warning: ...`` for both (a new user saw ``WARNING:`` and ``warning:`` in one run)."""
    import logging
    from kedfem import cli
    root = logging.getLogger("kedfem")
    before, level = list(root.handlers), root.level
    cli._setup_logging(0)
    try:
        logging.getLogger("kedfem.analysis.pipeline").warning("a logged warning %d", 7)
        err = capsys.readouterr().err
    finally:
        root.handlers[:] = before
        root.setLevel(level)
    assert "kedfem: warning: a logged warning 7" in err and "WARNING" not in err
