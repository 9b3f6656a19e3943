"""A scene file runs no code the user has not trusted, by any route (issue 23, section 1).

Every route a scene had to code (``builder =`` or ``name =`` naming a ``.py`` file beside the
scene, behind ``../`` or at an absolute path; ``package.module:function`` beside the scene or
on the Python path, such as ``http.server:test``, ``os:abort`` and ``pdb:set_trace``) is refused
with a named error before anything is imported, through every command that reads a scene
(``run``, ``sweep``, ``export``, ``campbell``, ``critical``, ``stability-map``) and through the
Python API; with ``--trust`` (``trust=``) naming the code, the same scene works. ``sys.path`` is
never extended. Builders must be functions that return a Mechanism (checked before and after the
call), and ``sys.exit`` inside one is a named error.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

import kedfem as kf
from kedfem.io import scenefile as sf
from kedfem.io.sweep import run_sweep
from kedfem.trust import Trust, UntrustedCodeError

#: a builder whose module leaves a mark when it is executed (the mark is the proof of execution)
BUILDER = '''
import pathlib
pathlib.Path(__file__).with_name("IMPORTED-" + pathlib.Path(__file__).stem).write_text("ran")
import kedfem as kf


def build(elements: int = 2, speed: float = 60.0) -> kf.Mechanism:
    pathlib.Path(__file__).with_name("BUILT-" + pathlib.Path(__file__).stem).write_text("ran")
    steel = kf.Material(E=2.1e11, rho=7850.0)
    m = kf.Mechanism("trusted rocker")
    m.ground("O2", (0.0, 0.0))
    m.ground("O4", (0.18, 0.0))
    m.joint("A", (0.05, 0.0))
    m.joint("B", (0.05 + 0.0597222, 0.1907))
    m.link("crank", "O2", "A", rigid=True, mass=0.1)
    m.link("coupler", "A", "B", material=steel, section=kf.Section.rectangle(0.012, 0.006), elements=elements)
    m.link("rocker", "O4", "B", material=steel, section=kf.Section.rectangle(0.012, 0.006), elements=elements)
    m.drive("crank", speed=speed)
    return m
'''

QUICK = ["--steps", "12", "--no-progress"]


def kedfem(args, cwd, timeout=120):
    exe = Path(sys.executable).parent / "kedfem"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "kedfem.cli"]
    env = dict(os.environ, MPLBACKEND="Agg")
    env.pop("PYTHONPATH", None)
    return subprocess.run(cmd + args, cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)


def marks(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if p.name.startswith(("IMPORTED-", "BUILT-")))


@pytest.fixture()
def tree(tmp_path):
    """scenes/ (the scenes), scenes/beside.py, scenes/pkgx/mod.py (a package beside the scene),
    outside.py (behind ../) and elsewhere/absolute.py (an absolute path)."""
    scenes = tmp_path / "scenes"
    (scenes / "pkgx").mkdir(parents=True)
    (scenes / "beside.py").write_text(BUILDER)
    (scenes / "pkgx" / "__init__.py").write_text(
        'import pathlib\npathlib.Path(__file__).with_name("IMPORTED-pkgx").write_text("ran")\n')
    (scenes / "pkgx" / "mod.py").write_text(BUILDER)
    (tmp_path / "outside.py").write_text(BUILDER)
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "absolute.py").write_text(BUILDER)
    return tmp_path


def scene(folder: Path, name: str, key: str = "builder", extra: str = "") -> Path:
    p = folder / "scenes" / f"s{abs(hash((name, key))) % 10**8}.toml"
    p.write_text(f'speed_rpm = 300.0\n[mechanism]\n{key} = "{name}"\n{extra}[output]\nplots = false\nvtk = false\n')
    return p


def routes(tree):
    """(scene reference, key, the --trust target that makes it run)."""
    absolute = tree / "elsewhere" / "absolute.py"
    return [("beside.py:build", "builder", "beside.py"),
            ("beside.py:build", "name", "."),  # the scene's folder
            ("../outside.py:build", "builder", str(tree / "outside.py")),
            (f"{absolute}:build", "builder", str(tree / "elsewhere")),
            ("pkgx.mod:build", "name", "pkgx"),  # a package beside the scene, trusted by module name
            ("pkgx.mod:build", "builder", "SCENE")]  # trusted by naming the scene file


def test_every_file_and_module_route_is_refused_before_import_and_runs_with_trust(tree):
    for ref, key, target in routes(tree):
        path = scene(tree, ref, key)
        before = list(sys.path)
        with pytest.raises(UntrustedCodeError, match="not trusted") as err:
            kf.load_scene(path)
        assert isinstance(err.value, sf.SceneFileError) and f"mechanism.{key}" in str(err.value)
        assert marks(tree) == [], (ref, marks(tree))  # nothing was imported, nothing built
        assert sys.path == before
        # trusted on the command line: it runs
        target = str(path) if target == "SCENE" else target
        r = kedfem(["run", str(path), "--trust", target, "--out", str(tree / "out")] + QUICK[:2] +
                   ["--no-mesh-check"], cwd=path.parent)
        assert r.returncode == 0, (ref, r.stderr)
        assert "trusted rocker" in r.stdout and any(m.startswith("BUILT-") for m in marks(tree))
        for m in tree.rglob("IMPORTED-*"):
            m.unlink()
        for m in tree.rglob("BUILT-*"):
            m.unlink()
        # in Python: trust= the same target
        cwd = os.getcwd()
        os.chdir(path.parent)
        try:
            sc, _ = kf.load_scene(path, trust=target)
        finally:
            os.chdir(cwd)
        assert sc.mech.name == "trusted rocker" and sys.path == before
        for m in list(tree.rglob("IMPORTED-*")) + list(tree.rglob("BUILT-*")):
            m.unlink()


def test_trusting_one_place_does_not_trust_another(tree):
    path = scene(tree, "../outside.py:build")
    with pytest.raises(UntrustedCodeError):
        kf.load_scene(path, trust=path)  # the scene's folder does not hold ../outside.py
    with pytest.raises(UntrustedCodeError):
        kf.load_scene(scene(tree, "os:abort", "name"), trust=tree)  # os lives elsewhere
    assert marks(tree) == []


@pytest.mark.parametrize("ref", ["http.server:test", "os:abort", "pdb:set_trace"])
def test_library_functions_are_refused_by_every_command(tree, ref):
    path = scene(tree, ref, "name", extra="port = 8765\n" if "http" in ref else "")
    for cmd in (["run"], ["sweep", "--param", "speed_rpm=100,200", "--scheduler", "serial"], ["export"],
                ["campbell", "--speeds", "100:200:2"], ["critical", "--lo", "100", "--hi", "200"],
                ["stability-map", "--speeds", "100:200:2", "--param", "damping.zeta=0.01,0.02",
                 "--scheduler", "serial"]):
        argv = [cmd[0], str(path)] + cmd[1:] + ["--out", str(tree / "o")]
        r = kedfem(argv, cwd=tree, timeout=60)  # a listener or a debugger would hang: timeout
        assert r.returncode == 2, (cmd, r.returncode, r.stderr)
        assert ("not trusted" in r.stderr or "library code" in r.stderr) and "Traceback" not in r.stderr, r.stderr
        assert not (tree / "o").exists()


def test_a_trusted_module_does_not_make_a_reexported_library_function_trusted(tree):
    (tree / "scenes" / "reexport.py").write_text("from os import abort as build\n")
    path = scene(tree, "reexport:build", "name")
    with pytest.raises(kf.InputError, match="must be a Python function"):
        kf.load_scene(path, trust=path)
    (tree / "scenes" / "reexport2.py").write_text("from http.server import test as build\n")
    with pytest.raises(UntrustedCodeError, match="defined in .*http"):
        kf.load_scene(scene(tree, "reexport2:build", "name"), trust=path)


def test_python_dictionaries_and_sweeps_need_trust_too(tree):
    ref = f"{tree / 'outside.py'}:build"
    data = {"mechanism": {"builder": ref}, "steps": 12}
    with pytest.raises(UntrustedCodeError):
        kf.scene_from_dict(data)
    res = run_sweep(data, {"speed_rpm": [300.0]}, scheduler="serial", frequencies=False)
    assert not res.points[0].ok and "not trusted" in res.points[0].error
    with pytest.raises(UntrustedCodeError):
        kf.critical_speed(data, 10.0, 20.0)
    with pytest.raises(UntrustedCodeError):
        kf.stability_map(data, [10.0, 20.0], "damping.zeta", [0.02], scheduler="serial")
    assert marks(tree) == []
    assert kf.scene_from_dict(data, trust=True).mech.name == "trusted rocker"
    ok = run_sweep(data, {"speed_rpm": [300.0]}, scheduler="serial", frequencies=False, trust=tree / "outside.py")
    assert ok.points[0].ok, ok.points[0].error


def test_the_command_argument_is_trusted_and_found_without_sys_path(tree):
    """``kedfem run pkgx.mod:build`` from the folder that holds it: the user named it."""
    r = kedfem(["run", "pkgx.mod:build", "--no-mesh-check", "--no-plots", "--no-vtk", "--out", str(tree / "o")]
               + QUICK[:2], cwd=tree / "scenes")
    assert r.returncode == 0, r.stderr
    before = list(sys.path)
    cwd = os.getcwd()
    os.chdir(tree / "scenes")
    try:
        mech = kf.catalogue.build("beside.py:build")  # Python: the caller runs code anyway
    finally:
        os.chdir(cwd)
    assert mech.name == "trusted rocker" and sys.path == before


def test_trust_targets_are_checked():
    with pytest.raises(kf.InputError, match="neither an existing file or folder nor a module name"):
        Trust.of("no/such/folder.py")
    with pytest.raises(kf.InputError, match="must be True"):
        Trust.of(5)
    t = Trust.of(["os", "."])
    assert t.allows_module("os.path") and not t.allows_module("osx") and t.allows_file(Path.cwd() / "x.py")


@pytest.mark.parametrize("body, message", [
    ("def build():\n    return None\n", "must return a kedfem.Mechanism, it returned NoneType"),
    ("def build():\n    return 5\n", "must return a kedfem.Mechanism, it returned int"),
    ("import sys\ndef build():\n    sys.exit(0)\n", r"did not build \(it called sys.exit\(0\)\)"),
    ("import sys\nsys.exit(0)\ndef build():\n    pass\n", r"importing .* failed: it called sys.exit\(0\)"),
    ("def build() -> int:\n    raise AssertionError('called')\n", "declared to return 'int'|declared to return <class 'int'>"),
    ("def build(length):\n    raise AssertionError('called')\n", "cannot take these parameters.*length"),
    ("build = 3\n", "must be a Python function"),
])
def test_builders_that_do_not_build_a_mechanism_are_named_errors(tmp_path, body, message):
    (tmp_path / "b.py").write_text(body)
    (tmp_path / "s.toml").write_text('[mechanism]\nbuilder = "b.py:build"\n')
    with pytest.raises(kf.InputError, match=message):
        kf.load_scene(tmp_path / "s.toml", trust=tmp_path)
    r = kedfem(["run", "s.toml", "--trust", ".", "--out", "o"], cwd=tmp_path, timeout=60)
    assert r.returncode == 2 and "Traceback" not in r.stderr and not (tmp_path / "o").exists(), r.stderr
