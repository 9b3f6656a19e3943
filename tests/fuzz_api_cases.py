"""The fuzzer of kedfem's public API and command line (issue 23): strategies and checks.

Used by ``tests/test_fuzz_api.py`` (a few hundred examples in the suite) and by
``benchmarks/fuzz_api.py`` (a long run). Three properties, for every input:

* **builder**: a random program of :class:`kedfem.Mechanism` calls (each argument valid or
  hostile: wrong types, non-finite and extreme numbers, wrong shapes) either builds or raises a
  :class:`kedfem.KedError`; what it builds then moves (kinematics) and solves (a short fixed-step
  solve) or raises a KedError, and every number of a result is finite;
* **functions**: every public function and result accessor, called with hostile arguments on a
  valid mechanism and result, returns finite numbers or raises a KedError;
* **cli**: ``kedfem`` with random options and values (in this process) exits 0, 1, 2 or 3, never
  with an exception, and no file it writes holds NaN or infinity.

Warnings other than ``RuntimeWarning`` (which the suite makes an error: a NaN or an overflow in
numpy) are expected on hostile input and ignored.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import tempfile
import warnings
from pathlib import Path

import numpy as np
from hypothesis import strategies as st

import kedfem as kf

__all__ = ["NASTY", "program", "run_program", "function_call", "run_function", "cli_argv", "run_cli",
           "base_mechanism", "base_result"]

# ------------------------------------------------------------------ hostile values
_FLOATS = st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 1.7e308, 5e-324, -5e-324, 0.0, -0.0,
                           1e-300, 1e300, 1e-12, 1e12, -1.0, 0.5, 2.0])
NASTY = st.one_of(
    st.none(), st.booleans(), st.integers(-2**70, 2**70), st.sampled_from([0, -1, 1, 2, 3, 10**4, 10**6, 2**63]),
    st.floats(allow_nan=True, allow_infinity=True), _FLOATS,
    st.text(max_size=4), st.sampled_from(["", "no", "yes", "true", "pin", "clamp", "free", "locked", "O", "A", "B",
                                          "crank", "rod", "nan", "1e999"]),
    st.lists(_FLOATS, max_size=3).map(tuple), st.lists(st.integers(-3, 3), max_size=3),
    st.lists(st.text(max_size=2), max_size=3),
    st.dictionaries(st.text(max_size=2), st.integers(), max_size=2),
    st.integers(0, 3).map(lambda n: np.full(n, 1.0)), st.just(np.zeros((2, 2))), st.just(np.array([np.nan, 1.0])),
    st.just(object()), st.just(b"x"), st.just(np.float64(np.inf)), st.just(np.int64(-5)),
)


def _arg(*valid):
    """A valid value (more often) or a hostile one."""
    return st.one_of(st.sampled_from(valid), st.sampled_from(valid), NASTY)


STEEL = kf.Material(E=2.1e11, rho=7850.0)
SEC = kf.Section.rectangle(0.008, 0.008)


def base_mechanism() -> kf.Mechanism:
    """An in-line slider-crank with a flexible rod (2 elements), the program's starting point."""
    m = kf.Mechanism("fuzz")
    m.ground("O", (0.0, 0.0))
    m.joint("A", (0.15, 0.0))
    m.slider("B", (0.45, 0.0), axis=(1.0, 0.0))
    m.link("crank", "O", "A", rigid=True, mass=0.2)
    m.link("rod", "A", "B", material=STEEL, section=SEC, elements=2)
    m.point_mass("B", 0.075)
    m.drive("crank", 150.0)
    return m


_NAMES = ("n1", "n2", "O", "A", "B", "crank", "rod")
_MATERIALS = (STEEL, kf.Material(E=7e10, rho=2700.0))
CALLS = {
    "ground": dict(name=_arg("G1", "G2"), at=_arg((0.3, 0.2), (0.6, 0.0)), clamped=_arg(False, True)),
    "joint": dict(name=_arg("J1", "J2"), at=_arg((0.3, 0.1), (0.45, 0.0)), welded=_arg(False, True, ("rod", "crank"))),
    "slider": dict(name=_arg("S1"), at=_arg((0.3, 0.0)), axis=_arg(None, (1.0, 0.0), (0.0, 1.0)),
                   on=_arg(None, "rod"), rotation=_arg("free", "locked"), slide=_arg("free", "locked")),
    "link": dict(name=_arg("l1", "l2"), a=_arg("A", "B", "O"), b=_arg("B", "J1", "G1"), material=_arg(*_MATERIALS, None),
                 section=_arg(SEC, None), elements=_arg(1, 2, 3), rigid=_arg(False, True), ends=_arg(("pin", "pin"), "clamp"),
                 mass=_arg(None, 0.1), J=_arg(None, 1e-3), mass_matrix=_arg("consistent", "lumped"),
                 timoshenko=_arg(False, True), kinematic=_arg(True, False), length=_arg(None, 0.3)),
    "body": dict(name=_arg("b1"), joints=_arg(("A",), ("A", "B")), mass=_arg(0.1, 1.0), J=_arg(1e-3), cm=_arg(None, (0.1, 0.0))),
    "point_mass": dict(joint=_arg("A", "B"), mass=_arg(0.1, 1e3), J=_arg(0.0, 1e-4)),
    "spring": dict(name=_arg("s1"), a=_arg("B", "A"), b=_arg(None, "A"), k=_arg(1e3, 1e5), axis=_arg((0.0, 1.0), (1.0, 0.0)),
                   k3=_arg(0.0, 1e6), preload=_arg(0.0, 10.0)),
    "torsional_spring": dict(name=_arg("t1"), joint=_arg("O", "A"), member=_arg("crank", "rod"), other=_arg(None, "rod"),
                             k=_arg(10.0), preload=_arg(0.0, 1.0)),
    "drive": dict(member=_arg("crank", "rod"), speed=_arg(150.0, 300.0), torsional_stiffness=_arg(None, 1e4)),
    "load": dict(name=_arg("f1"), joint=_arg("B", "A"), force=_arg((10.0, 0.0), (0.0, -5.0))),
    "friction": dict(name=_arg("fr1"), joint=_arg("B"), force=_arg(5.0), axis=_arg(None, (1.0, 0.0)),
                     reference_speed=_arg(0.0, 0.1), smoothing=_arg(1e-3, 0.1), follows=_arg("rigid", "total")),
    "set_gravity": dict(g=_arg((0.0, -9.81), (0.0, 0.0))),
    "at_angle": dict(origin=_arg("O", (0.0, 0.0)), length=_arg(0.1), angle=_arg(0.3)),
    "at_lengths": dict(first=_arg(("A", 0.3), ("O", 0.4)), second=_arg(("B", 0.2), ("O", 0.35)),
                       branch=_arg("open", "left", "right", "crossed")),
    "at_length_on_line": dict(first=_arg(("A", 0.3)), through=_arg("O", (0.0, 0.0)), axis=_arg((1.0, 0.0)),
                              branch=_arg("open", "crossed")),
}


def _required(fn) -> set[str]:
    """Parameters of ``fn`` without a default (a call that leaves one out is Python's TypeError, not
    a question of input values)."""
    import inspect
    return {p.name for p in inspect.signature(fn).parameters.values()
            if p.default is inspect.Parameter.empty and p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)}


def _kwargs(draw, fn, table) -> dict:
    need = _required(fn)
    return {k: draw(v) for k, v in table.items() if k in need or draw(st.integers(0, 3)) > 0}


@st.composite
def program(draw, max_calls: int = 4):
    """A list of (method, kwargs): Mechanism builder calls with valid or hostile arguments."""
    out = []
    for _ in range(draw(st.integers(1, max_calls))):
        name = draw(st.sampled_from(sorted(CALLS)))
        out.append((name, _kwargs(draw, getattr(kf.Mechanism, name), CALLS[name])))
    return out


def _finite(x, what: str) -> None:
    a = np.asarray(x)
    if a.dtype.kind in "fc" and not np.all(np.isfinite(a)):
        raise AssertionError(f"{what}: not finite: {a.ravel()[~np.isfinite(a.ravel())][:5]}")


def _finite_tree(obj, what: str, depth: int = 0) -> None:
    """Every float, array, and dataclass/tuple field of ``obj`` finite (NaN allowed where a value is
    documented as unknown: the fields named in ``_UNKNOWN``)."""
    import dataclasses
    if depth > 3:
        return
    if isinstance(obj, float):
        if not math.isfinite(obj):
            raise AssertionError(f"{what} = {obj}")
    elif isinstance(obj, np.ndarray):
        _finite(obj, what)
    elif isinstance(obj, (tuple, list)):
        for i, x in enumerate(obj[:64]):
            _finite_tree(x, f"{what}[{i}]", depth + 1)
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        for f in dataclasses.fields(obj):
            if f.name in _UNKNOWN:
                continue
            _finite_tree(getattr(obj, f.name), f"{what}.{f.name}", depth + 1)


#: fields that may be NaN by their documentation (a stress without a fibre distance; an unmeasured rate)
_UNKNOWN = {"stress", "stress_angle", "stress_station", "rate", "history_rate", "error", "damping_ratio"}


def check_result(res, what: str = "result") -> None:
    """Every number a result shows is finite."""
    for name in ("U", "V", "floquet_multipliers", "t", "crank_angle"):
        _finite(getattr(res, name), f"{what}.{name}")
    for p in res.peaks():
        _finite(p.deflection, f"{what}.peaks[{p.link}].deflection")
        if p.stress == p.stress:  # NaN only without a fibre distance
            _finite(p.stress, f"{what}.peaks[{p.link}].stress")
    if res.stability is not None:
        _finite(res.stability.spectral_radius, f"{what}.stability.spectral_radius")


def _quiet():
    """Warnings other than RuntimeWarning ignored (hostile input warns by design)."""
    cm = warnings.catch_warnings()
    cm.__enter__()
    warnings.simplefilter("ignore")
    warnings.simplefilter("error", RuntimeWarning)
    return cm


def run_program(calls, solve: bool = True) -> str:
    """Apply ``calls`` to :func:`base_mechanism`, then move and solve what it built.

    Returns an outcome label; raises AssertionError (or the raw exception) on a violation.
    """
    cm = _quiet()
    try:
        m = base_mechanism()
        for name, kw in calls:
            try:
                getattr(m, name)(**kw)
            except kf.KedError:
                pass
        try:
            motion = kf.kinematics(m, steps=24)
        except kf.KedError:
            return "kinematics error"
        for name in ("r", "v", "a", "theta", "omega", "alpha"):
            _finite(getattr(motion, name), f"motion.{name}")
        model = kf.FEModel(m)
        if not solve or model.n_dof > 120:
            return "moved"
        try:
            res = kf.solve(kf.Scene(m, steps=12, estimate=False, damping=kf.ModalDamping(0.02),
                                    effects=("inertia", "coupling", "axial_stiffening", "springs", "loads",
                                             "gravity")))
        except kf.KedError:
            return "solve error"
        check_result(res)
        return "solved"
    finally:
        cm.__exit__(None, None, None)


# ------------------------------------------------------------------ public functions
_BASE: dict = {}
#: messages of failed sweep points (for the long run's report)
_EVENTS: list = []


def base_result():
    """A solved slider-crank (12 time elements), made once per process."""
    if "res" not in _BASE:
        cm = _quiet()
        try:
            _BASE["res"] = kf.solve(kf.Scene(base_mechanism(), steps=12, effects=("inertia", "coupling"),
                                             damping=kf.ModalDamping(0.02)))
        finally:
            cm.__exit__(None, None, None)
    return _BASE["res"]


FUNCTIONS = {
    "kinematics": dict(steps=_arg(36, 7), times=_arg(None, (0.0, 0.01))),
    "kinematics_at": dict(crank_angle=_arg(0.0, 1.0)),
    "natural_frequencies": dict(crank_angle=_arg(0.0, 1.0), n_modes=_arg(2, 4), effects=_arg((), ("coupling",)),
                                modes=_arg(False, True), steps=_arg(None, 12)),
    "global_matrices": dict(crank_angle=_arg(0.0), effects=_arg((), ("inertia", "coupling")),
                            damping=_arg(None, kf.ModalDamping(0.02), kf.Rayleigh(0.0, 1e-4))),
    "static_response": dict(effects=_arg(("gravity",), ("gravity", "loads")), crank_angle=_arg(0.0, 0.5)),
    "stroke": dict(joint=_arg("B", "A"), axis=_arg(None, (1.0, 0.0))),
    "Scene": dict(steps=_arg(12, None), effects=_arg(("inertia",), "all"), damping=_arg(kf.ModalDamping(0.02), None),
                  hold=_arg(None, "foh"), speed=_arg(None, 100.0), eps=_arg(None, 1e-6), max_iter=_arg(50, 3),
                  nonlinear_method=_arg("fixed-point", "anderson"), delta=_arg(None, 1e-12), name=_arg("", "x"),
                  accuracy=_arg("default", "fast"), method=_arg("auto", "gauss2"), rtol=_arg(None, 1e-2),
                  estimate=_arg(True, False), stiff_split=_arg(True, False)),
    "campbell": dict(speeds_rad_s=_arg((50.0, 100.0), (10.0, 20.0, 30.0)), n_modes=_arg(2), harmonics=_arg(2, 3),
                     nodes=_arg(8, 12), method=_arg("modal")),
    "Material": dict(E=_arg(2e11), rho=_arg(7800.0), nu=_arg(0.3), yield_strength=_arg(None, 3e8),
                     ultimate_strength=_arg(None, 5e8), endurance_limit=_arg(None, 2e8)),
    "Section": dict(A=_arg(1e-4), I=_arg(1e-9), c=_arg(None, 0.005), kappa=_arg(5 / 6)),
    "Section.rectangle": dict(b=_arg(0.01), h=_arg(0.02)),
    "Section.circle": dict(d=_arg(0.01)),
    "Section.tube": dict(d=_arg(0.02), t=_arg(0.002)),
    "ModalDamping": dict(zeta=_arg(0.02, 0.0)),
    "Rayleigh": dict(alpha=_arg(0.0, 1.0), beta=_arg(1e-4, 0.0)),
    "CraigBampton": dict(modes=_arg(2, 4), links=_arg(None, ("rod",)), static_correction=_arg(True, False)),
    "expm": dict(A=_arg(np.eye(2), np.array([[0.0, 1.0], [-4.0, -0.1]])), delta=_arg(1e-15, 1e-6),
                 balance=_arg(True, False), degree=_arg(None, 6, "auto"), approximant=_arg("pade"),
                 return_info=_arg(False, True)),
    "res.deflection": dict(link=_arg("rod"), xi=_arg(0.5, 0.0, 1.0), relative_to=_arg("frame", "chord")),
    "res.stress": dict(link=_arg("rod"), per_element=_arg(1, 3)),
    "res.section_forces": dict(link=_arg("rod"), per_element=_arg(1, 2)),
    "res.axial_force": dict(link=_arg("rod")),
    "res.bending_moment": dict(link=_arg("rod"), per_element=_arg(1, 2)),
    "res.stations": dict(link=_arg("rod"), per_element=_arg(1, 2)),
    "res.dof": dict(label=_arg("B.ux", "rod.1.v")),
    "res.joint_displacement": dict(joint=_arg("B", "A")),
    "res.link_displacement": dict(link=_arg("rod")),
    "res.link_geometry": dict(link=_arg("rod")),
    "res.frequencies": dict(n_modes=_arg(2, 4), nodes=_arg(None, (0, 3))),
    "res.mode_shapes": dict(node=_arg(0, 3), n_modes=_arg(2)),
    "res.resample": dict(times=_arg(None, (0.0, 0.01)), crank_angle=_arg(None, (0.0, 1.0))),
    "res.summary": dict(n_modes=_arg(2, 4)),
    "mesh_error": dict(factor=_arg(2, 3)),
    "critical_speed": dict(lo=_arg(100.0, 20.0), hi=_arg(200.0, 400.0), rtol=_arg(0.1, 0.2), kind=_arg("parametric", "buckling"),
                           linear=_arg(True, False), scan=_arg(0, 1), max_solves=_arg(4, 5), nodes=_arg(8)),
    "stability_map": dict(base=_arg({"mechanism": {"name": "slider_crank"}, "steps": 12}),
                          speeds=_arg((100.0, 200.0), (150.0, 160.0)), param=_arg("damping.zeta", "mechanism.rod", "steps"),
                          values=_arg((0.01, 0.02), (0.3,), (12, 24)), scheduler=_arg("serial"),
                          max_workers=_arg(None, 1)),
    "run_sweep": dict(base=_arg({"mechanism": {"name": "slider_crank"}, "steps": 12}),
                      axes=_arg({"speed_rpm": [600.0]}, {"mechanism.rod": [0.3, 0.31]}), scheduler=_arg("serial"),
                      frequencies=_arg(False, True), retries=_arg(1, 0)),
}


def _callable(name: str):
    if name == "run_sweep":
        from kedfem.io.sweep import run_sweep
        return run_sweep
    if name.startswith("res."):
        return getattr(kf.PeriodicResult, name[4:])
    if name.startswith("Section."):
        return getattr(kf.Section, name.split(".")[1])
    return getattr(kf, name)


@st.composite
def function_call(draw):
    name = draw(st.sampled_from(sorted(FUNCTIONS)))
    return name, _kwargs(draw, _callable(name), FUNCTIONS[name])


def _returned(out, what: str) -> None:
    if isinstance(out, kf.PeriodicResult):
        check_result(out, what)
    elif isinstance(out, str) and re.search(r"\b(nan|inf)\b", out, re.IGNORECASE):
        raise AssertionError(f"{what} prints a non-finite number: {out!r}")
    else:
        _finite_tree(out, what)


def run_function(name: str, kw: dict) -> str:
    """Call public function ``name`` with ``kw`` (on the base mechanism or result)."""
    cm = _quiet()
    try:
        try:
            if name.startswith("res."):
                out = getattr(base_result(), name[4:])(**kw)
            elif name == "Scene":
                sc = kf.Scene(base_mechanism(), **kw)
                if sc.steps is not None and sc.steps <= 48 and sc.max_iter <= 50:
                    out = kf.solve(sc)
                else:
                    out = None
            elif name == "mesh_error":
                out = kf.mesh_error(base_result(), **kw)
            elif name in ("Material", "Section", "ModalDamping", "Rayleigh", "CraigBampton"):
                out = getattr(kf, name)(**kw)
            elif name.startswith("Section."):
                out = getattr(kf.Section, name.split(".")[1])(**kw)
            elif name == "expm":
                out = kf.expm(**kw)
            elif name == "campbell":
                out = kf.campbell(base_mechanism(), **kw)
            elif name == "critical_speed":
                out = kf.critical_speed(kf.Scene(base_mechanism(), steps=12, damping=kf.ModalDamping(0.02)), **kw)
            elif name == "stability_map":
                out = kf.stability_map(**kw)
            elif name == "run_sweep":
                from kedfem.io.sweep import run_sweep
                res = run_sweep(**kw)
                for p in res.points:  # a failed point's numbers are unknown (NaN, empty cells)
                    if p.ok:
                        _finite_tree((p.peaks, p.spectral_radius, p.wall_time), f"run_sweep.points[{p.index}]")
                    else:
                        assert p.error and "\n" not in p.error, p.error
                        _EVENTS.append(p.error[:200])
                out = None
            else:
                out = getattr(kf, name)(base_mechanism(), **kw)
        except kf.KedError:
            return "named error"
        _returned(out, name)
        if hasattr(out, "describe") and callable(out.describe):
            _returned(out.describe(), f"{name}.describe()")
        return "returned"
    finally:
        cm.__exit__(None, None, None)


# ------------------------------------------------------------------ command line
_VALUE = st.sampled_from(["", "0", "-1", "1", "3", "12", "1e-3", "nan", "inf", "-inf", "1e308", "abc", "1:2:3",
                          "1:inf:3", "a=b", "speed_rpm=100,200", "damping.zeta=0.01,0.02", "..", "/", "x.gif",
                          "B.ux", "rod.1.v", "fast", "all", "inertia,coupling", "foh", "radau3", "\u00e9", "10000"])
_OPTS = {
    "common": ["--speed", "--rtol", "--accuracy", "--method", "--steps", "--hold", "--effects", "--trust"],
    "run": ["--no-plots", "--no-vtk", "--no-csv", "--no-npz", "--no-mesh-check", "--strict", "--scale", "--every",
            "--modes", "--n-modes", "--dofs"],
    "export": ["--scale", "--every", "--modes", "--frame", "--animate"],
    "sweep": ["--param", "--x", "--no-plots", "--no-frequencies", "--resume"],
    "campbell": ["--speeds", "--n-modes", "--harmonics", "--nodes", "--no-plots"],
    "critical": ["--lo", "--hi", "--kind", "--tol", "--scan", "--max-solves"],
    "stability-map": ["--speeds", "--param", "--no-plots"],
    "list": [],
}
_FLAGS = {"--no-plots", "--no-vtk", "--no-csv", "--no-npz", "--no-mesh-check", "--strict", "--no-frequencies",
          "--resume"}
#: what keeps a CLI example cheap (a few seconds at most): fixed time elements, serial schedulers
_CHEAP = {"run": ["--steps", "12", "--no-mesh-check"], "export": ["--steps", "12"],
          "sweep": ["--steps", "12", "--scheduler", "serial", "--no-progress", "--param", "speed_rpm=600,900"],
          "campbell": ["--speeds", "300:900:3", "--nodes", "12"],
          "critical": ["--steps", "12", "--lo", "300", "--hi", "900", "--max-solves", "4"],
          "stability-map": ["--steps", "12", "--scheduler", "serial", "--no-progress", "--speeds", "300:900:2",
                            "--param", "damping.zeta=0.01,0.02"], "list": []}


@st.composite
def cli_argv(draw):
    cmd = draw(st.sampled_from(sorted(_CHEAP)))
    argv = [cmd]
    if cmd != "list":
        argv.append(draw(st.sampled_from(["slider_crank", "exciter", "slider-crank", "nope", "x.toml", "f.py:build"])))
    argv += list(_CHEAP[cmd])
    pool = _OPTS[cmd] + ([] if cmd == "list" else _OPTS["common"])
    for opt in draw(st.lists(st.sampled_from(pool), max_size=3, unique=True)) if pool else []:
        argv.append(opt)
        if opt not in _FLAGS:
            argv.append(draw(_VALUE))
    return argv


_BAD_NUMBER = re.compile(r"(?<![A-Za-z_])(nan|[+-]?inf)(?![A-Za-z_])", re.IGNORECASE)


def run_cli(argv) -> int:
    """Run ``kedfem`` in this process in a fresh folder; checks the exit status and the files."""
    from kedfem.cli import main
    cwd = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="kedfem-fuzz-") as d:
        os.chdir(d)
        out, err = io.StringIO(), io.StringIO()
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                rc = main(list(argv) + ["--out", "o"] if argv[0] != "list" and "--out" not in argv else list(argv))
        finally:
            os.chdir(cwd)
        assert rc in (0, 1, 2, 3), (argv, rc, err.getvalue()[-500:])
        assert "Traceback" not in err.getvalue(), (argv, err.getvalue()[-2000:])
        assert "RuntimeWarning" not in err.getvalue(), (argv, err.getvalue()[-2000:])
        for p in Path(d).rglob("*"):
            if p.suffix in (".csv", ".txt", ".json") and p.is_file():
                text = p.read_text(errors="replace")
                m = _BAD_NUMBER.search(text)
                assert m is None, (argv, str(p.relative_to(d)), text[max(0, m.start() - 80):m.end() + 40])
        return rc
