"""The accuracy presets and tolerances of a scene."""

import csv
import math

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem import cli
from kedfem.io import scenefile as sf
from kedfem.analysis.scene import ACCURACY_PRESETS


def test_accuracy_presets_resolve_and_explicit_knobs_win():
    m = mechanisms.build("slider_crank", elements=4)
    for name, knobs in ACCURACY_PRESETS.items():
        sc = kf.Scene(m, accuracy=name)
        assert {k: getattr(sc, k) for k in knobs} == knobs and sc.steps is None
    sc = kf.Scene(m, accuracy="tight", steps=100, hold="foh", rtol=1e-4)
    assert (sc.steps, sc.hold, sc.scheme, sc.rtol, sc.eps) == (100, "foh", "foh", 1e-4,
                                                               ACCURACY_PRESETS["tight"]["eps"])
    assert kf.Scene(m).rtol == ACCURACY_PRESETS["default"]["rtol"] == 1e-3 and kf.Scene(m).scheme == "radau3"
    fast = sc.with_accuracy("fast")
    assert fast.rtol == ACCURACY_PRESETS["fast"]["rtol"] and fast.accuracy == "fast"
    with pytest.raises(kf.InputError, match="accuracy must be one of fast, default, tight"):
        kf.Scene(m, accuracy="exact")
    with pytest.raises(kf.InputError, match="contradicts"):
        kf.Scene(m, hold="foh", method="radau3")
    with pytest.raises(kf.InputError, match="rtol"):
        kf.Scene(m, rtol=0.0)


def test_accuracy_presets_in_scene_files_and_cli(tmp_path):
    s = sf.scene_from_dict({"mechanism": "slider_crank", "accuracy": "tight"})
    assert (s.steps, s.rtol, s.scheme) == (None, ACCURACY_PRESETS["tight"]["rtol"], "radau3")
    s = sf.scene_from_dict({"mechanism": "slider_crank", "accuracy": "fast", "steps": 50, "method": "gauss3"})
    assert s.steps == 50 and s.delta == ACCURACY_PRESETS["fast"]["delta"] and s.scheme == "gauss3"
    with pytest.raises(sf.SceneFileError, match="accuracy"):
        sf.scene_from_dict({"mechanism": "slider_crank", "accuracy": "fastest"})
    with pytest.raises(sf.SceneFileError, match="method"):
        sf.scene_from_dict({"mechanism": "slider_crank", "method": "rk4"})
    loaded = cli._load(None, {"accuracy": "fast"})
    assert loaded.scene.rtol == ACCURACY_PRESETS["fast"]["rtol"]
    assert loaded.scene.effects == kf.default_scene().effects


def test_tolerances_are_met_on_the_slider_crank():
    """Each preset's result is within its tolerance of a converged answer, and says so.

    Reference: Gauss-Legendre collocation (a second method) on 384 elements; the
    tightest result agrees with it to 1e-6.
    """
    m = mechanisms.build("slider_crank", elements=4)
    kw = dict(effects=("inertia", "coupling", "axial_stiffening"), damping=kf.ModalDamping(0.02))
    ref = kf.solve(kf.Scene(m, steps=384, method="gauss3", estimate=False, **kw)).peaks()[0]
    for name in ("fast", "default", "tight"):
        res = kf.solve(kf.Scene(m, accuracy=name, **kw))
        p, e = res.peaks()[0], res.error.link("rod")
        true_d = abs(p.deflection / ref.deflection - 1)
        true_s = abs(p.stress / ref.stress - 1)
        assert res.error.met and max(true_d, true_s) <= res.scene.rtol, (name, true_d, true_s)
        # the estimate is not below a third of the true error (Gauss's own error is ~1e-9)
        assert e.deflection >= true_d / 3 and e.stress >= true_s / 3, (name, e, true_d, true_s)


def test_flop_counts_by_hand():
    from kedfem.lab import flops
    assert flops.matmul_flops(10) == 2000.0 and flops.matmul_flops(2, 3, 4) == 48.0
    # 4 exponentials of 6x6, 5 approximant products each, squarings 0, 1, 2, 3 -> 20 + 6 products
    assert flops.expm_flops(6, 5, [0, 1, 2, 3], approximant="taylor") == pytest.approx(26 * 2 * 6 ** 3)
    # Pade adds an LU (2/3 m^3) and an m-column solve (2 m^3) per matrix
    assert flops.expm_flops(6, 5, [0], approximant="pade") == pytest.approx(5 * 432 + 144 + 432)
    with pytest.raises(kf.InputError, match="approximant"):
        flops.expm_flops(6, 5, [0], approximant="chebyshev")
