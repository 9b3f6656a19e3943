"""One set of defaults: kf.Scene(m) and a builder file on the command line simulate the same, and
every declared item a scene's effects leave out is named once."""

import math
import os
import textwrap
import warnings

import numpy as np
import pytest

import kedfem as kf
from kedfem.errors import EffectWarning

BUILDER = textwrap.dedent('''
    import kedfem as kf

    def build():
        m = kf.Mechanism("feeder")
        m.ground("O", at=(0.0, 0.0))
        m.joint("A", at=(0.05, 0.0))
        m.slider("B", at=(0.25, 0.0), axis=(1.0, 0.0))
        m.link("crank", "O", "A", rigid=True, mass=0.2)
        m.link("rod", "A", "B", material=kf.Material(E=2e11, rho=7850.0),
               section=kf.Section.rectangle(0.008, 0.008), elements=4)
        m.point_mass("B", 0.5)
        m.spring("return", "B", k=2e3, axis=(1.0, 0.0), preload=150.0)
        m.load("process", "B", force=(-80.0, 0.0))
        m.set_gravity((0.0, -9.81))
        m.drive("crank", speed=60.0)
        return m
''')


def build(tmp_path):
    path = tmp_path / "feeder.py"
    path.write_text(BUILDER)
    ns = {}
    exec(compile(BUILDER, str(path), "exec"), ns)
    return path, ns["build"]()


def test_python_and_command_line_defaults_agree(tmp_path):
    path, m = build(tmp_path)
    py = kf.Scene(m)
    cli = kf.scene_from_dict({"mechanism": {"builder": f"{path}:build"}}, trust=[str(path)])
    assert py.effects == cli.effects
    assert set(py.effects) >= {"inertia", "coupling", "axial_stiffening", "springs", "loads", "gravity"}
    assert py.damping == cli.damping == kf.ModalDamping(0.02)
    with warnings.catch_warnings():
        warnings.simplefilter("error", EffectWarning)  # nothing declared is left out
        a, b = kf.solve(py), kf.solve(cli)
    assert np.array_equal(a.U, b.U)
    # the preload is in the answer: the rod carries it (compression where the spring pushes B)
    assert np.mean(a.axial_force("rod")) < -100.0


@pytest.mark.parametrize("effects, left_out", [
    (("inertia", "coupling", "loads", "gravity"), ["spring 'return' (its preload)"]),
    (("inertia", "coupling", "springs", "gravity"), ["load 'process'"]),
    (("inertia", "coupling", "springs", "loads"), ["gravity (0.0, -9.81) m/s^2"]),
    (("inertia", "coupling"), ["spring 'return' (its preload)", "load 'process'", "gravity (0.0, -9.81) m/s^2"]),
])
def test_each_declared_item_left_out_warns_once(tmp_path, effects, left_out):
    _path, m = build(tmp_path)
    m.friction("guide", "B", force=5.0, axis=(1.0, 0.0))
    if "loads" not in effects:
        left_out = left_out + ["friction 'guide'"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        kf.solve(kf.Scene(m, effects=effects, steps=24, estimate=False))
    said = [str(w.message) for w in caught if issubclass(w.category, EffectWarning)]
    for item in left_out:
        assert sum(item in s for s in said) == 1, (item, said)
    assert len(said) == len(left_out)


def test_static_response_names_a_declared_item_its_effects_leave_out(tmp_path):
    _path, m = build(tmp_path)
    with pytest.warns(EffectWarning, match=r"spring 'return' \(its preload\) is declared but the effects \(gravity, loads\)"):
        kf.static_response(m, effects=("gravity", "loads"))


def test_a_scene_prints_as_one_line_with_its_knobs_not_its_whole_mechanism():
    """print(scene) dumped every joint and link of the mechanism (2.6 kB for the four-bar; a new
    user's trial): it names the mechanism and shows the effects, damping, tolerances and the knobs
    set away from their defaults."""
    import mechanisms

    sc = kf.Scene(mechanisms.build("four_bar"))
    text = repr(sc)
    assert text == str(sc) and "\n" not in text and len(text) < 200
    assert text.startswith("Scene('four-bar', effects=('inertia', 'coupling', 'axial_stiffening')")
    assert "Joint(" not in text and "steps" not in text
    other = kf.Scene(mechanisms.build("slider_crank"), steps=96, method="radau3", damping=None, accuracy="tight")
    assert "steps=96" in repr(other) and "method='radau3'" in repr(other) and "damping=None" in repr(other)
    assert "rtol=1e-05" in repr(other) and "accuracy" not in repr(other)
