"""Every example script runs (with small parameters) and every example scene file solves."""

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

import kedfem as kf
from kedfem.io import scenefile as sf

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_example_is_tested():
    tested = {"linkage", "speed_sweep", "export_render", "press", "shaper",  # the two: also test_process_loads
              "pumping_unit"}  # in test_pinned_beam
    assert {p.stem for p in EXAMPLES.glob("*.py")} == tested


def test_linkage(capsys):
    res = load("linkage").main(steps=48)
    assert res.converged and res.stable
    peaks = res.peaks()
    assert [p.link for p in peaks] == ["coupler", "rocker"]
    assert all(np.isfinite(p.stress) and p.stress > 0 for p in peaks)
    assert "crank-rocker: fundamental" in capsys.readouterr().out


def test_speed_sweep(tmp_path, capsys):
    res = load("speed_sweep").main(out=tmp_path, speeds=(500, 1000, 1500), steps=24, scheduler="serial",
                                   progress=False)
    assert not res.failed
    stress = [p.peaks[0].stress for p in res.points]
    assert stress[0] < stress[1] < stress[2]          # inertial loads grow with the square of the speed
    assert (tmp_path / "sweep.csv").is_file() and (tmp_path / "peak_stress_vs_speed.png").is_file()


def test_export_render(tmp_path):
    pytest.importorskip("pyvista")
    series, modes, png = load("export_render").main(out=tmp_path, steps=24)
    assert series.pvd.is_file() and len(series.files) >= 360 and len(modes.files) == 3
    import matplotlib.image as mpimg
    img = mpimg.imread(str(png))[..., :3]
    assert img.std() > 0.02 and (1.0 - np.all(img > 0.97, axis=-1).mean()) > 0.002


@pytest.mark.parametrize("path", sorted((EXAMPLES / "scenes").glob("*.toml")), ids=lambda p: p.stem)
def test_example_scene_solves(path):
    scene, outputs = sf.load_scene(path, {"steps": 24})
    res = kf.solve(scene)
    assert res.elements == 24 and res.U.shape == (res.n, res.model.n_dof) and res.n >= 360
    assert np.isfinite(res.U).all()
    assert res.stable and outputs.dir.name


def test_press(capsys):
    """The press's main: a tolerance-driven solve; the forming force is in its loads."""
    res = load("press").main()
    out = capsys.readouterr().out
    assert res.error.met and "Loads on the machine" in out and "drive crank at O" in out
    assert 3.5e4 < res.loads().magnitude("B", "rod", "rigid").max() < 4.5e4  # 40 kN at the bottom dead centre


def test_shaper():
    """The shaper cuts on its slow stroke: the cutting force raises the drive's mean torque by the
    cutting work per cycle over 2 pi (its main is a tolerance-driven solve of about a minute)."""
    mod = load("shaper")
    eff = ("inertia", "coupling", "gravity", "loads")
    mean = []
    for force in (0.0, 2000.0):
        res = kf.solve(kf.Scene(mod.build(cutting_force=force), effects=eff, steps=96, estimate=False))
        mean.append(res.loads(elastic=False).torque(response="rigid").mean())
    # cutting work: 2 kN over the cut less the two ramps' halves (S-curves: half the entry each)
    work = 2000.0 * (0.8 * 0.6 - 0.02)
    assert (mean[1] - mean[0]) == pytest.approx(work / (2 * math.pi), rel=2e-3)
