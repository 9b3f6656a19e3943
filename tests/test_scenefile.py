"""TOML scene files: valid files build the right scene; every bad value is a clear, located error."""

import math
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import kedfem as kf
import mechanisms
from kedfem.analysis.defaults import default_scene
from kedfem.io import scenefile as sf

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted((ROOT / "examples" / "scenes").glob("*.toml"))

GOOD = """\
name = "test"
steps = 40
speed_rpm = 1000.0
hold = "zoh"
effects = ["inertia", "coupling"]

[mechanism]
name = "slider_crank"
elements = 4
rod = 0.3

[damping]
model = "rayleigh"
alpha = 0.5
beta = 2e-5

[solver]
eps = 1e-7
max_iter = 20
nonlinear_method = "relaxation"

[output]
dir = "out-here"
plots = false
modes = 2
scale = 50.0
every = 2
dofs = ["rod.n1.v"]
"""


def write(tmp_path, text, name="scene.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def error_of(tmp_path, text) -> sf.SceneFileError:
    p = write(tmp_path, text)
    with pytest.raises(sf.SceneFileError) as ei:
        sf.load_scene(p)
    return ei.value


def test_good_file_builds_the_scene(tmp_path):
    scene, out = sf.load_scene(write(tmp_path, GOOD))
    assert scene.name == "test" and scene.steps == 40 and scene.hold == "zoh"
    assert scene.effects == ("inertia", "coupling")
    assert scene.damping == kf.Rayleigh(0.5, 2e-5)
    assert scene.eps == 1e-7 and scene.max_iter == 20 and scene.nonlinear_method == "relaxation"
    assert scene.mech.drives[0].speed == pytest.approx(1000.0 * 2 * math.pi / 60, rel=1e-15)
    assert scene.mech.links["rod"].elements == 4
    assert out == sf.Outputs(dir=Path("out-here"), plots=False, modes=2, scale=50.0, every=2, dofs=("rod.n1.v",))


def test_presets_fill_omitted_keys():
    scene = sf.scene_from_dict({"mechanism": {"name": "exciter"}})
    pre = sf.preset("exciter")
    assert scene.steps == pre.steps and scene.effects == pre.effects and scene.damping == pre.damping
    assert sf.scene_from_dict({"mechanism": "four-bar"}).mech.name == "four-bar"  # string shorthand, '-'


def same_scene(a, b):
    for f in ("steps", "effects", "damping", "hold", "eps", "max_iter", "nonlinear_method", "delta", "name"):
        assert getattr(a, f) == getattr(b, f), f
    assert a.mech.summary() == b.mech.summary()
    assert a.mech.drives[0].speed == pytest.approx(b.mech.drives[0].speed, rel=1e-14)


def test_default_mould_scene_file_is_the_builtin_default():
    d = default_scene()
    same_scene(sf.scene_from_dict({"mechanism": {"name": "mould_oscillator"}}), d)
    scene, out = sf.load_scene(ROOT / "examples" / "scenes" / "mould_oscillator.toml")
    same_scene(scene, d)
    assert out == sf.Outputs()


def test_every_preset_scene_is_the_catalogues():
    """A mechanism name alone is the preset scene the mechanism declares (one definition of each)."""
    from kedfem import catalogue
    for name in catalogue.available():
        same_scene(sf.scene_from_dict({"mechanism": {"name": name}}), catalogue.info(name).scene())
    mould = {"group": 3, "leaf_length": 1.0}
    same_scene(sf.scene_from_dict({"mechanism": {"name": "mould_oscillator", **mould}, "steps": 30}),
               default_scene(steps=30, **mould))


def test_the_parser_names_no_mechanism():
    """Presets and signed parameters were tables in this module; the mechanisms declare them now."""
    import ast

    from kedfem import catalogue
    from kedfem.io import scene_values
    code = []
    for module in (sf, scene_values):  # the parser and its checked values
        tree = ast.parse(Path(module.__file__).read_text())
        docs = {id(n.body[0].value) for n in ast.walk(tree)
                if isinstance(n, (ast.Module, ast.FunctionDef, ast.ClassDef)) and ast.get_docstring(n) is not None}
        code += [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)
                 and id(n) not in docs]
        code += [n.id for n in ast.walk(tree) if isinstance(n, ast.Name)]
    words = set(catalogue.available()) | {"mould", "crank_angle", "o6", "leaf_height", "casting_speed"}
    for text in code:
        for word in words:
            assert word not in text.replace("-", "_").replace(" ", "_"), (word, text)


@pytest.mark.parametrize("name,param,value,ok", [
    ("four_bar", "crank_angle", -0.5, True),
    ("six_bar", "o6", [0.62, -0.05], True),
    ("mould_oscillator", "casting_speed", -0.02, True),
    ("four_bar", "crank", -0.1, False),
    ("exciter", "spring", -1.0, False),
])
def test_signed_parameters_come_from_the_mechanism(name, param, value, ok):
    data = {"mechanism": {"name": name, param: value}, "steps": 12}
    if ok:
        assert sf.parse_scene(data).scene.mech
    else:
        with pytest.raises(sf.SceneFileError, match=">= 0") as ei:
            sf.parse_scene(data)
        assert ei.value.key == f"mechanism.{param}"


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_example_scenes_load(path):
    spec = sf.load_spec(path)
    assert spec.scene.steps is None and spec.scene.rtol == 1e-3 and spec.scene.effects
    if path.stem.endswith("sweep"):
        assert sf.grid_size(spec.sweep) == 8


def test_unknown_key_named_with_line_and_suggestion(tmp_path):
    e = error_of(tmp_path, GOOD.replace("hold = ", "hodl = "))
    assert e.key == "hodl" and e.line == 4 and "did you mean 'hold'" in str(e)
    assert str(e).startswith(f"{tmp_path / 'scene.toml'}:4: hodl:")
    e = error_of(tmp_path, GOOD.replace("rod = 0.3", "rdo = 0.3"))
    assert e.key == "mechanism.rdo" and e.line == 10 and "did you mean 'rod'" in str(e)
    e = error_of(tmp_path, GOOD.replace("beta = 2e-5", "betta = 2e-5"))
    assert e.key == "damping.betta" and e.line == 15


@pytest.mark.parametrize("old,new,key,words", [
    ("steps = 40", "steps = 4.5", "steps", "integer"),
    ("steps = 40", "steps = 2", "steps", "3 .. 20000"),
    ("steps = 40", 'steps = "many"', "steps", "integer"),
    ("speed_rpm = 1000.0", "speed_rpm = nan", "speed_rpm", "finite"),
    ("speed_rpm = 1000.0", "speed_rpm = inf", "speed_rpm", "finite"),
    ("speed_rpm = 1000.0", "speed_rpm = 0", "speed_rpm", "nonzero"),
    ("hold = \"zoh\"", "hold = \"foo\"", "hold", "zoh, foh, magnus2"),
    ('effects = ["inertia", "coupling"]', 'effects = ["inertia", "coriolis"]', "effects", "unknown effect"),
    ('effects = ["inertia", "coupling"]', "effects = 3", "effects", "array"),
    ("elements = 4", "elements = 0", "mechanism.elements", "1 .. 200"),
    ("elements = 4", "elements = 100000", "mechanism.elements", "1 .. 200"),
    ("elements = 4", "elements = true", "mechanism.elements", "integer"),
    ("rod = 0.3", "rod = -0.3", "mechanism.rod", ">= 0"),
    ("rod = 0.3", "rod = -inf", "mechanism.rod", "finite"),
    ("rod = 0.3", 'rod = "long"', "mechanism.rod", "number"),
    ("rod = 0.3", "rod = 0.1", "mechanism", "rod > crank"),
    ("rod = 0.3", "speed = 3.0", "mechanism.speed", "speed_rpm"),
    ('name = "slider_crank"', 'name = "slidercrank"', "mechanism.name", "did you mean 'slider_crank'"),
    ("beta = 2e-5", "beta = -2e-5", "damping.beta", ">= 0"),
    ('model = "rayleigh"', 'model = "viscous"', "damping.model", "rayleigh, modal, none"),
    ("beta = 2e-5", "zeta = 0.1", "damping.zeta", "does not apply"),
    ("eps = 1e-7", "eps = 2.0", "solver.eps", "< 1"),
    ("max_iter = 20", "max_iter = 10000000", "solver.max_iter", "1 .. 1000"),
    ("nonlinear_method = \"relaxation\"", "nonlinear_method = \"newton-raphson\"", "solver.nonlinear_method", "anderson"),
    ("scale = 50.0", "scale = -1.0", "output.scale", "> 0"),
    ("scale = 50.0", 'scale = "big"', "output.scale", "auto"),
    ("modes = 2", "modes = 1000", "output.modes", "0 .. 24"),
    ("plots = false", 'plots = "no"', "output.plots", "true or false"),
    ('dofs = ["rod.n1.v"]', "dofs = [1, 2]", "output.dofs", "labels"),
])
def test_bad_values_name_key_and_line(tmp_path, old, new, key, words):
    assert old in GOOD
    text = GOOD.replace(old, new)
    e = error_of(tmp_path, text)
    assert e.key == key, str(e)
    assert words in str(e), str(e)
    assert isinstance(e, kf.InputError) and isinstance(e, kf.KedError)
    lines = text.splitlines()
    want = lines.index("[mechanism]") + 1 if key == "mechanism" else lines.index(new) + 1
    assert e.line == want, str(e)


def test_missing_keys(tmp_path):
    e = error_of(tmp_path, "steps = 30\n")
    assert e.key == "mechanism" and "missing" in str(e)
    e = error_of(tmp_path, "[mechanism]\nelements = 4\n")
    assert e.key == "mechanism.name" and e.line == 1 and "missing" in str(e)
    e = error_of(tmp_path, "[mechanism]\nname = 'exciter'\n[damping]\n")
    assert e.key == "damping.model" and "missing" in str(e)


def test_huge_steps_rejected_before_any_computation(tmp_path):
    t = time.perf_counter()
    e = error_of(tmp_path, GOOD.replace("steps = 40", "steps = 10000000000"))
    assert time.perf_counter() - t < 1.0
    assert e.key == "steps" and str(sf.MAX_STEPS) in str(e)
    sf.check_steps(sf.MAX_STEPS)
    with pytest.raises(sf.SceneFileError):
        sf.check_steps(sf.MAX_STEPS + 1)


def test_syntax_errors_and_unreadable_files(tmp_path):
    e = error_of(tmp_path, "steps = 30\nspeed_rpm = \n")
    assert e.line == 2 and "invalid TOML" in str(e)
    p = tmp_path / "bin.toml"
    p.write_bytes(b"name = '\xff\xfe'\n")
    with pytest.raises(sf.SceneFileError, match="UTF-8"):
        sf.load_scene(p)
    with pytest.raises(sf.SceneFileError, match="cannot read"):
        sf.load_scene(tmp_path / "missing.toml")
    with pytest.raises(sf.SceneFileError, match="cannot read"):
        sf.load_scene(tmp_path)  # a folder


def test_inline_and_dotted_keys_are_located(tmp_path):
    text = ('steps = 30\ndamping = { model = "rayleigh", beta = -1.0 }\n'
            '[mechanism]\nname = "slider_crank"\n')
    e = error_of(tmp_path, text)
    assert e.key == "damping.beta" and e.line == 2
    text = 'steps = 30\nmechanism.name = "slider_crank"\nmechanism.rod = -2.0\n'
    e = error_of(tmp_path, text)
    assert e.key == "mechanism.rod" and e.line == 3


def test_sweep_table_validation(tmp_path):
    base = "[mechanism]\nname = 'slider_crank'\n[sweep]\n"
    spec = sf.load_spec(write(tmp_path, base + "speed_rpm = [100, 200]\n\"mechanism.elements\" = [2, 4, 6]\n"))
    assert spec.sweep == {"speed_rpm": (100, 200), "mechanism.elements": (2, 4, 6)}
    e = error_of(tmp_path, base + "mechanism.rood = [0.3]\n")
    assert e.key == "sweep.mechanism.rood" and "did you mean 'mechanism.rod'" in str(e) and e.line == 4
    e = error_of(tmp_path, base + "speed_rpm = 100\n")
    assert e.key == "sweep.speed_rpm" and "array" in str(e)
    e = error_of(tmp_path, base + "mechanism.speed = [1.0]\n")
    assert "speed_rpm" in str(e)


def test_overrides_are_named_as_command_line(tmp_path):
    p = write(tmp_path, GOOD)
    scene, _ = sf.load_scene(p, {"steps": 12, "mechanism.elements": 2})
    assert scene.steps == 12 and scene.mech.links["rod"].elements == 2
    with pytest.raises(sf.SceneFileError) as ei:
        sf.load_scene(p, {"hold": "bad"})
    assert ei.value.path == "command line" and ei.value.key == "hold"


# ------------------------------------------------------------------ fuzzing
KNOWN = {
    "": ["name", "steps", "speed_rpm", "hold", "effects", "mechanism", "damping", "solver", "output"],
    "mechanism": ["name", "elements", "crank", "rod", "width", "E", "rho", "slider_mass", "crank_angle",
                  "mass_matrix", "speed"],
    "damping": ["model", "alpha", "beta", "zeta"],
    "solver": ["eps", "max_iter", "nonlinear_method", "delta"],
    "output": ["dir", "plots", "modes", "scale", "every", "dofs"],
}
BASE = {"name": "fuzz", "steps": 24, "speed_rpm": 900.0, "hold": "foh", "effects": ["inertia"],
        "mechanism": {"name": "slider_crank", "elements": 2, "rod": 0.3},
        "damping": {"model": "rayleigh", "beta": 1e-5}, "solver": {"eps": 1e-6}, "output": {"modes": 1}}

scalars = st.one_of(
    st.integers(min_value=-10**12, max_value=10**12), st.floats(allow_nan=True, allow_infinity=True),
    st.booleans(), st.text(max_size=8), st.sampled_from(["foh", "zoh", "modal", "rayleigh", "none", "auto",
                                                         "slider_crank", "exciter", "inertia", "all"]),
    st.sampled_from([0, -1, 1, 3, 2**31, 10**9, 1e300, -0.0, 1e-300]))
values = st.one_of(scalars, st.lists(scalars, max_size=3), st.dictionaries(st.text(max_size=5), scalars, max_size=2))
keys = st.one_of(st.sampled_from(sorted({k for v in KNOWN.values() for k in v})), st.text(min_size=1, max_size=8))
mutation = st.tuples(st.sampled_from(sorted(KNOWN)), keys, st.one_of(st.none(), values))


def mutate(muts, base=None):
    """``base`` (default :data:`BASE`) with the mutations ``(table, key, value or None: remove)``."""
    import copy
    d = copy.deepcopy(BASE if base is None else base)
    for table, key, value in muts:
        t = d if table == "" else d.setdefault(table, {})
        if not isinstance(t, dict):
            continue
        if value is None:
            t.pop(key, None)
        else:
            t[key] = value
    return d


def check_outcome(fn):
    try:
        out = fn()
    except sf.SceneFileError as e:
        assert e.key or e.line or "TOML" in str(e), f"error names no key: {e}"
        if e.key:
            assert sf._keyfmt(e.key) in str(e)
        assert "\n" not in str(e)
        return None
    return out


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(mutation, min_size=1, max_size=4))
def test_fuzz_dicts_only_raise_scene_file_errors(muts):
    d = mutate(muts)
    spec = check_outcome(lambda: sf.parse_scene(d))
    if spec is not None:
        assert isinstance(spec.scene, kf.Scene)
        # no steps: the number of time elements follows from the tolerance
        assert spec.scene.steps is None or 3 <= spec.scene.steps <= sf.MAX_STEPS
        assert 0 < spec.scene.rtol < 1


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').encode("ascii", "backslashreplace")\
            .decode().replace("\\x", "\\u00") + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)


def toml_key(k: str) -> str:
    return k if k and all(c.isalnum() or c in "_-" for c in k) and k.isascii() else toml_value(k)


def to_toml(d) -> str:
    lines = [f"{toml_key(k)} = {toml_value(v)}" for k, v in d.items() if not isinstance(v, dict)]
    for k, v in d.items():
        if isinstance(v, dict):
            lines.append(f"[{toml_key(k)}]")
            lines += [f"{toml_key(kk)} = {toml_value(vv)}" for kk, vv in v.items()]
    return "\n".join(lines) + "\n"


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(st.lists(mutation, min_size=1, max_size=3))
def test_fuzz_files_only_raise_located_errors(tmp_path, muts):
    d = mutate(muts)
    p = tmp_path / "fuzz.toml"
    try:
        text = to_toml(d)
    except TypeError:
        return
    p.write_text(text, encoding="utf-8")
    out = check_outcome(lambda: sf.load_scene(p))
    if out is None:
        with pytest.raises(sf.SceneFileError) as ei:
            sf.load_scene(p)
        e = ei.value
        assert e.path == str(p)
        if e.key and e.key.split(".")[0] in d:
            assert e.line is not None, str(e)


def test_every_mechanism_builds_from_its_parameters():
    for name in mechanisms.available():
        params = sf.mechanism_parameters(mechanisms.get(name))
        data = {"mechanism": {"name": name, **{k: (list(v) if isinstance(v, tuple) else v)
                                                for k, v in params.items() if k != "speed"}}}
        assert sf.scene_from_dict(data).mech.drives
