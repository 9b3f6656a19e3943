"""The accuracy-versus-cost study (``kedfem bench``) and the accuracy presets of a scene."""

import csv
import math

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem import bench, cli
from kedfem import scenefile as sf
from kedfem.scene import ACCURACY_PRESETS


@pytest.fixture(scope="module")
def quick_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    assert cli.main(["bench", "--quick", "--out", str(out)]) == 0
    with open(out / "accuracy_cost.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return out, rows


def test_quick_study_writes_csv_table_and_plot(quick_study, capsys):
    out, rows = quick_study
    assert set(bench.CSV_COLUMNS) == set(rows[0])
    assert {r["mechanism"] for r in rows} == set(bench.CASES)
    assert {"steps", "delta", "elements", "cb", "eps", "preset:fast"} <= {r["knob"] for r in rows}
    for r in rows:
        for k in ("time_s", "err", "err_hist", "err_deflection", "err_stress", "err_frequency", "err_hist_stress"):
            assert math.isfinite(float(r[k])) and float(r[k]) >= 0, (r["knob"], k)
        # err and err_hist are the worst of their parts
        parts = [float(r[k]) for k in ("err_deflection", "err_stress", "err_frequency")]
        assert float(r["err"]) == pytest.approx(max(parts), rel=1e-5)
        hist = [float(r[k]) for k in ("err_hist_deflection", "err_hist_stress")]
        assert float(r["err_hist"]) == pytest.approx(max(hist), rel=1e-5)
    md = (out / "accuracy_cost.md").read_text()
    assert "For 1 %, 0.1 %, 0.01 % error you need" in md and "| slider-crank" in md
    png = out / "accuracy_cost.png"
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_quick_study_errors_fall_with_time_elements(quick_study):
    """Against the Richardson reference built from finer solves, more elements give less error."""
    _, rows = quick_study
    for mech in ("slider_crank", "mould"):
        e = {int(r["steps"]): float(r["err"]) for r in rows
             if r["mechanism"] == mech and r["knob"] == "steps" and r["hold"] == "magnus2"}
        assert e[90] < 0.5 * e[36], (mech, e)
    # slider-crank: magnus2 is second order (36 -> 90 elements cut the error >= 4x); zoh's
    # histories only first order (half-element lag), so magnus2's history error is far smaller
    sc = [r for r in rows if r["mechanism"] == "slider_crank" and r["knob"] == "steps"]
    e = {int(r["steps"]): float(r["err"]) for r in sc if r["hold"] == "magnus2"}
    assert e[90] < e[36] / 4
    hz = {int(r["steps"]): float(r["err_hist"]) for r in sc if r["hold"] == "zoh"}
    hm = {int(r["steps"]): float(r["err_hist"]) for r in sc if r["hold"] == "magnus2"}
    assert hz[90] > 0.6 * hz[36] / 2.5 and hm[90] < hz[90] / 10, (hz, hm)
    cb = [r for r in rows if r["knob"] == "cb"]
    assert cb and all(float(r["err"]) < 1e-2 for r in cb)


def test_bench_rejects_unknown_mechanism(capsys):
    assert cli.main(["bench", "--quick", "--mechanisms", "slider,four_bar"]) == 2
    assert "unknown mechanism 'slider'" in capsys.readouterr().err


def test_accuracy_presets_resolve_and_explicit_knobs_win():
    m = mechanisms.build("slider_crank", elements=4)
    for name, knobs in ACCURACY_PRESETS.items():
        sc = kf.Scene(m, accuracy=name)
        assert {k: getattr(sc, k) for k in knobs} == knobs
    sc = kf.Scene(m, accuracy="tight", steps=100, hold="foh")
    assert (sc.steps, sc.hold, sc.eps) == (100, "foh", ACCURACY_PRESETS["tight"]["eps"])
    assert kf.Scene(m).steps == ACCURACY_PRESETS["default"]["steps"]
    fast = sc.with_accuracy("fast")
    assert fast.steps == ACCURACY_PRESETS["fast"]["steps"] and fast.accuracy == "fast"
    with pytest.raises(kf.InputError, match="accuracy must be one of fast, default, tight"):
        kf.Scene(m, accuracy="exact")


def test_accuracy_presets_in_scene_files_and_cli(tmp_path):
    s = sf.scene_from_dict({"mechanism": "slider_crank", "accuracy": "tight"})
    assert (s.steps, s.hold) == (ACCURACY_PRESETS["tight"]["steps"], ACCURACY_PRESETS["tight"]["hold"])
    s = sf.scene_from_dict({"mechanism": "slider_crank", "accuracy": "fast", "steps": 50})
    assert s.steps == 50 and s.delta == ACCURACY_PRESETS["fast"]["delta"]
    with pytest.raises(sf.SceneFileError, match="accuracy"):
        sf.scene_from_dict({"mechanism": "slider_crank", "accuracy": "fastest"})
    loaded = cli._load(None, {"accuracy": "fast"})
    assert loaded.scene.steps == ACCURACY_PRESETS["fast"]["steps"]
    assert loaded.scene.effects == kf.default_scene().effects


def test_accuracy_presets_rank_on_the_slider_crank():
    """fast > default > tight in error against a finer magnus2 solve (history of the rod deflection)."""
    m = mechanisms.build("slider_crank", elements=4)
    kw = dict(effects=("inertia", "coupling", "axial_stiffening"), damping=kf.ModalDamping(0.02))
    ref = kf.solve(kf.Scene(m, steps=5760, hold="magnus2", **kw)).deflection("rod", 0.5, relative_to="chord")
    errs = {}
    for name in ("fast", "default", "tight"):
        w = kf.solve(kf.Scene(m, accuracy=name, **kw)).deflection("rod", 0.5, relative_to="chord")
        errs[name] = np.abs(w - ref[:: len(ref) // len(w)]).max() / np.abs(ref).max()
    assert errs["fast"] > errs["default"] > errs["tight"], errs
    assert errs["fast"] < 0.05 and errs["tight"] < 1e-4, errs


def test_flop_counts_by_hand():
    from kedfem import flops
    assert flops.matmul_flops(10) == 2000.0 and flops.matmul_flops(2, 3, 4) == 48.0
    # 4 exponentials of 6x6, 5 approximant products each, squarings 0, 1, 2, 3 -> 20 + 6 products
    assert flops.expm_flops(6, 5, [0, 1, 2, 3], approximant="taylor") == pytest.approx(26 * 2 * 6 ** 3)
    # Pade adds an LU (2/3 m^3) and an m-column solve (2 m^3) per matrix
    assert flops.expm_flops(6, 5, [0], approximant="pade") == pytest.approx(5 * 432 + 144 + 432)
    with pytest.raises(kf.InputError, match="approximant"):
        flops.expm_flops(6, 5, [0], approximant="chebyshev")
