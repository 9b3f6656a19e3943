"""The mechanism catalogue: the core imports no catalogue package; users' mechanisms are found by name."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

import kedfem as kf
from kedfem import catalogue

ROOT = Path(__file__).resolve().parents[1]

USER_MODULE = '''
import kedfem as kf


def rocker(length: float = 0.3, elements: int = 3):
    """A user's crank-rocker: rigid crank, flexible coupler and rocker."""
    m = kf.Mechanism("user-rocker")
    m.ground("O2", at=(0.0, 0.0))
    m.ground("O4", at=(0.3, 0.0))
    m.joint("A", at=(0.0, 0.08))
    m.joint("B", at=(0.3, length))
    m.link("crank", "O2", "A", rigid=True, mass=0.1)
    alu = kf.Material(E=7.0e10, rho=2700.0)
    sec = kf.Section.rectangle(0.02, 0.006)
    m.link("coupler", "A", "B", material=alu, section=sec, elements=elements)
    m.link("rocker", "O4", "B", material=alu, section=sec, elements=elements)
    m.drive("crank", speed=30.0)
    return m
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
    r = run(kedfem_command() + ["sweep", "s.toml", "--param", "mechanism.elements=2,3", "--scheduler",
                                "processes", "--workers", "2", "--no-progress", "--no-plots", "--out", "sw"],
            user_folder)
    assert r.returncode == 0, r.stderr + r.stdout
    assert "2 of 2 points solved" in r.stdout
    r = run(kedfem_command() + ["run", "mylinks:nothing", "--steps", "24"], user_folder)
    assert r.returncode == 2 and "has no 'nothing'" in r.stderr and "Traceback" not in r.stderr


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
