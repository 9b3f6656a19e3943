"""The mechanism catalogue: the core imports no catalogue package; users' mechanisms are found by name."""

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import kedfem as kf
from kedfem import catalogue

ROOT = Path(__file__).resolve().parents[1]

USER_MODULE = '''
import kedfem as kf


def rocker(length: float = 0.3, elements: int = 3, shift: float = 0.0):
    """A user's crank-rocker: rigid crank, flexible coupler and rocker."""
    m = kf.Mechanism("user-rocker")
    m.ground("O2", at=(0.0, 0.0))
    m.ground("O4", at=(0.3 + shift, 0.0))
    m.joint("A", at=(0.0, 0.08))
    m.joint("B", at=(0.3, length))
    m.link("crank", "O2", "A", rigid=True, mass=0.1)
    alu = kf.Material(E=7.0e10, rho=2700.0)
    sec = kf.Section.rectangle(0.02, 0.006)
    m.link("coupler", "A", "B", material=alu, section=sec, elements=elements)
    m.link("rocker", "O4", "B", material=alu, section=sec, elements=elements)
    m.drive("crank", speed=30.0)
    return m


# what scenes of it start from, and the parameter that may be negative
rocker.PRESET = {"effects": ["inertia", "coupling", "axial_stiffening"], "damping": kf.Rayleigh(0.0, 1e-4),
                 "name": "user rocker {length} m"}
rocker.SIGNED_PARAMETERS = ("shift",)
'''


def kedfem_command():
    exe = Path(sys.executable).parent / "kedfem"
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "kedfem.cli"]


def test_the_core_imports_no_catalogue_package():
    """The library reached up into mechanisms/ (an import circle: mechanisms imports kedfem)."""
    for path in (ROOT / "kedfem").rglob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module or ""]
            assert not [n for n in names if n.split(".")[0] == "mechanisms"], (path.name, names)


def test_the_shipped_catalogue_is_found_by_entry_point():
    assert set(catalogue.available()) >= {"mould_oscillator", "slider_crank", "four_bar", "six_bar", "exciter"}
    assert catalogue.build("four-bar").name == "four-bar"
    with pytest.raises(kf.InputError, match="did you mean 'four_bar'"):
        catalogue.get("four_barr")


@pytest.fixture()
def user_folder(tmp_path):
    (tmp_path / "mylinks.py").write_text(USER_MODULE)
    shadow = tmp_path / "mechanisms"  # a user's own package that happens to share the name
    shadow.mkdir()
    (shadow / "__init__.py").write_text("raise ImportError('this is not kedfem's catalogue')\n")
    return tmp_path


def run(cmd, cwd, **kw):
    env = dict(os.environ, MPLBACKEND="Agg")
    env.pop("PYTHONPATH", None)
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=300, env=env, **kw)


def test_a_users_mechanisms_folder_breaks_nothing(user_folder):
    """It broke scene loading and sweeps (`module 'mechanisms' has no attribute 'available'`)."""
    code = ("from kedfem.io.scenefile import scene_from_dict; import kedfem as kf;"
            "s = scene_from_dict({'mechanism': {'name': 'four_bar', 'elements': 2}, 'steps': 24});"
            "print(kf.solve(s).converged)")
    r = run([sys.executable, "-c", code], user_folder)  # '' (the folder) first on sys.path
    assert r.returncode == 0 and r.stdout.strip() == "True", r.stderr


def test_a_users_builder_is_found_by_the_cli_scene_files_and_sweeps(user_folder):
    r = run(kedfem_command() + ["run", "mylinks:rocker", "--steps", "24", "--no-mesh-check", "--no-plots",
                                "--no-vtk", "--out", "o"], user_folder)
    assert r.returncode == 0, r.stderr
    assert "user-rocker" in (user_folder / "o" / "summary.txt").read_text()
    (user_folder / "s.toml").write_text('steps = 24\nspeed_rpm = 300.0\n[mechanism]\nname = "mylinks:rocker"\n'
                                        'length = 0.32\n[output]\nplots = false\nvtk = false\n')
    sweep = ["sweep", "s.toml", "--param", "mechanism.elements=2,3", "--scheduler", "processes", "--workers", "2",
             "--no-progress", "--no-plots", "--out", "sw"]
    r = run(kedfem_command() + sweep, user_folder)  # the scene names code: not without --trust
    assert r.returncode == 2 and "not trusted" in r.stderr and not (user_folder / "sw").exists()
    r = run(kedfem_command() + sweep + ["--trust", "mylinks"], user_folder)
    assert r.returncode == 0, r.stderr + r.stdout
    assert "2 of 2 points solved" in r.stdout
    r = run(kedfem_command() + ["run", "mylinks:nothing", "--steps", "24"], user_folder)
    assert r.returncode == 2 and "has no 'nothing'" in r.stderr and "Traceback" not in r.stderr


def test_a_mechanism_registered_by_entry_point_works_like_the_shipped_ones(user_folder):
    """The CLI, scene files, sweeps and `kedfem list` take its preset and signed parameters from it."""
    site = user_folder / "site"
    dist = site / "mylinks-0.1.dist-info"
    dist.mkdir(parents=True)
    (user_folder / "mylinks.py").rename(site / "mylinks.py")
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: mylinks\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[{catalogue.GROUP}]\nuser-rocker = mylinks:rocker\n")
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(site))

    def kedfem(*argv):
        return subprocess.run(kedfem_command() + list(argv), cwd=user_folder, capture_output=True, text=True,
                              timeout=300, env=env)

    r = kedfem("list")
    assert r.returncode == 0, r.stderr
    assert "  user_rocker: A user's crank-rocker" in r.stdout and "shift (+-)" in r.stdout
    assert "damping Rayleigh, alpha = 0 1/s, beta = 0.0001 s" in r.stdout
    r = kedfem("run", "user-rocker", "--steps", "24", "--no-mesh-check", "--no-plots", "--no-vtk", "--out", "o")
    assert r.returncode == 0, r.stderr
    text = (user_folder / "o" / "summary.txt").read_text()
    assert "user rocker 0.3 m" in text and "axial_stiffening" in text and "Rayleigh" in text
    (user_folder / "s.toml").write_text('steps = 24\n[mechanism]\nname = "user_rocker"\nshift = -0.01\n'
                                        '[output]\nplots = false\nvtk = false\n')
    r = kedfem("sweep", "s.toml", "--param", "mechanism.shift=-0.02,0.01", "--scheduler", "processes",
               "--workers", "2", "--no-progress", "--no-plots", "--out", "sw")
    assert r.returncode == 0, r.stderr + r.stdout
    assert "2 of 2 points solved" in r.stdout
    (user_folder / "bad.toml").write_text('[mechanism]\nname = "user_rocker"\nlength = -0.3\n')
    r = kedfem("run", "bad.toml")
    assert r.returncode == 2 and "bad.toml:3: mechanism.length: must be >= 0" in r.stderr, r.stderr


def test_register_in_process(monkeypatch):
    def tiny(rpm: float = 600.0):
        return kf.Mechanism  # never built here

    monkeypatch.setattr(catalogue, "_REGISTERED", {})
    monkeypatch.setattr(catalogue, "_LOADED", {})
    catalogue.register("tiny_user_linkage", tiny)
    assert "tiny_user_linkage" in catalogue.available()
    assert catalogue.get("tiny_user_linkage").build is tiny
    with pytest.raises(kf.InputError, match="identifier"):
        catalogue.register("not a name", tiny)


def test_a_builder_declares_its_preset_and_signed_parameters(monkeypatch):
    from kedfem.io.scenefile import SceneFileError, scene_from_dict

    def lever(length: float = 0.5, offset: float = -0.1, angle: float = 0.0):
        """A lever."""
        m = kf.Mechanism("lever")
        m.ground("O", at=(offset, 0.0))
        m.joint("A", at=(offset + length, 0.0))
        m.link("arm", "O", "A", material=kf.Material(E=2e11, rho=7850.0), section=kf.Section.rectangle(0.02, 0.01),
               elements=2)
        m.drive("arm", speed=10.0)
        return m

    monkeypatch.setattr(catalogue, "_REGISTERED", {})
    monkeypatch.setattr(catalogue, "_LOADED", {})
    catalogue.register("lever", lever)
    entry = catalogue.info("lever")
    # nothing declared: the fallback preset; a parameter with a negative default is signed
    assert entry.preset == catalogue.Preset() and entry.signed == {"offset"}
    assert entry.parameters == {"length": 0.5, "offset": -0.1, "angle": 0.0}
    assert scene_from_dict({"mechanism": "lever"}).name == "lever"

    lever.PRESET = {"effects": ("inertia",), "damping": None, "solver": {"max_iter": 7},
                    "name": "lever of {length} m"}
    lever.SIGNED_PARAMETERS = ("angle",)
    catalogue.register("lever", lever)
    entry = catalogue.info("lever")
    assert entry.signed == {"offset", "angle"}
    sc = scene_from_dict({"mechanism": {"name": "lever", "angle": -0.2, "length": 0.4}})
    assert (sc.effects, sc.damping, sc.max_iter, sc.name) == (("inertia",), None, 7, "lever of 0.4 m")
    same = entry.scene({"angle": -0.2, "length": 0.4})
    assert (same.effects, same.damping, same.max_iter, same.name) == (sc.effects, sc.damping, 7, sc.name)
    with pytest.raises(SceneFileError, match="must be >= 0"):
        scene_from_dict({"mechanism": {"name": "lever", "length": -0.4}})


@pytest.mark.parametrize("attr,value,words", [
    ("PRESET", {"efects": ["inertia"]}, "unknown key 'efects' (did you mean 'effects'?)"),
    ("PRESET", {"solver": {"epss": 1e-6}}, "unknown solver key 'epss' (did you mean 'eps'?)"),
    ("PRESET", {"name": "lever {lenght}"}, "not a template of its parameters"),
    ("PRESET", 3, "must be a kedfem.catalogue.Preset or a mapping"),
    ("SIGNED_PARAMETERS", ("angel",), "names 'angel', not one of its parameters (did you mean 'angle'?)"),
])
def test_a_malformed_declaration_is_a_clear_error(monkeypatch, attr, value, words):
    def lever(length: float = 0.5, angle: float = 0.0):
        return kf.Mechanism("lever")

    setattr(lever, attr, value)
    monkeypatch.setattr(catalogue, "_REGISTERED", {})
    monkeypatch.setattr(catalogue, "_LOADED", {})
    catalogue.register("lever", lever)
    with pytest.raises(kf.InputError, match=re.escape(words)):
        catalogue.info("lever")


def test_the_shipped_mechanisms_declare_their_presets():
    from kedfem.analysis import defaults
    assert catalogue.info("four_bar").signed == {"crank_angle"}
    assert catalogue.info("six_bar").signed == {"crank_angle", "o6"}
    assert catalogue.info("exciter").signed == frozenset()
    assert "geometric_nonlinearity" in catalogue.info("four_bar").preset.effects
    mould = catalogue.info(defaults.DEFAULT_MECHANISM)
    assert defaults.MOULD_EFFECTS == mould.preset.effects and len(mould.preset.effects) == 7
    assert kf.default_scene(group=2).name == "mould oscillator, group 2"
