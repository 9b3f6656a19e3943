"""TOML scene files: a scene as data, validated key by key.

A scene file is read with the standard library's :mod:`tomllib`; it is data
only, nothing in it is executed. It names catalogue mechanisms (installed
entry points); a builder file or module it names runs only where the user
trusts that code (:mod:`kedfem.trust`: ``--trust``, ``trust=``), checked before
anything is imported, and ``sys.path`` is never changed. Every value is checked before anything is
computed, and every problem raises :class:`SceneFileError` (an
:class:`~kedfem.errors.InputError`) whose message names the file, the line
(found by scanning the file text, since :mod:`tomllib` reports no positions
for values) and the key. Unknown keys are errors, with a "did you mean"
suggestion, never silently ignored.

Layout (every key is optional except ``mechanism.name``; units in the key
names or in brackets)::

    name = "slider-crank at 1000 rpm"   # label used in reports
    accuracy = "default"                # "fast" | "default" | "tight": rtol 1e-2 / 1e-3 / 1e-5
    rtol = 1e-3                         # tolerance on every link's peak deflection and stress
    speed_rpm = 1000.0                  # speed of the first drive [rev/min]
    effects = ["inertia", "coupling"]   # or "all"
    # method = "auto"                   # time scheme: auto | radau3 | radau2 | gauss3 | gauss2
                                        #   | magnus2 | foh | zoh (kedfem.solvers.schemes)
    # steps = 180                       # fixed number of time elements, 3 .. MAX_STEPS (experts)
    # hold = "foh"                      # = method for the exponential holds zoh | foh | magnus2

    [mechanism]
    name = "slider_crank"               # mechanisms.available()
    elements = 8                        # any parameter of the mechanism (SI units)

    [[loads]]                           # a process load on the built mechanism (docs/loads.md)
    name = "cutting"
    joint = "D"
    force = [2000.0, 0.0]               # [N], times the profile's factor
    [loads.profile]                     # optional: constant force without it
    of = "position"                     # kedfem.model.profiles.PROFILE_QUANTITIES: the crank's
                                        # angle [deg], a joint's position [m] or velocity [m/s]
    joint = "D"                         # position / velocity: the joint read ...
    axis = [-1.0, 0.0]                  # ... along this direction
    x = [-0.69, -0.67, -0.23, -0.21]    # abscissae, non-decreasing (one given twice: a step)
    y = [0.0, 1.0, 1.0, 0.0]            # factors
    stroke = "forward"                  # "both" | "forward" (moving along +axis) | "return"
    smooth = true                       # S-curves between entries (no kinks: cheap to resolve)

    [damping]
    model = "rayleigh"                  # "rayleigh" | "modal" | "none"
    alpha = 0.0                         # [1/s]
    beta = 3e-5                         # [s]
    # zeta = 0.02                       # modal damping ratio [-]

    [solver]
    eps = 1e-6                          # Eq. 21 tolerance (fraction)
    max_iter = 50
    nonlinear_method = "anderson"       # "newton" (default) | "fixed-point" | "relaxation" | "anderson"
    # delta = 1e-12                     # accuracy of each matrix exponential

    [output]
    dir = "kedfem-out"                  # relative to the working directory
    plots = true
    csv = true
    npz = true
    vtk = true
    render = false
    modes = 4                           # mode shapes exported (0: none)
    scale = "auto"                      # deformation scale of the VTK points
    every = 1                           # write every k-th time node to VTK
    dofs = []                           # DOF labels to plot ([]: automatic)

    [sweep]                             # only read by ``kedfem sweep``
    speed_rpm = [500, 1000, 1500]
    "mechanism.elements" = [4, 8]

The defaults of ``effects``, ``damping``, the solver knobs and ``name`` are
the mechanism's preset scene, which the mechanism declares itself (its
``PRESET``, :class:`kedfem.catalogue.Preset`; ``kedfem list`` prints them); so
are the parameters that may be negative (``SIGNED_PARAMETERS``; every other
numeric parameter must be >= 0). This module asks the catalogue
(:func:`kedfem.catalogue.info`) and names no mechanism. Without ``steps``
the solve picks the number of time elements that meets ``rtol`` (from
``accuracy``, :data:`kedfem.analysis.scene.ACCURACY_PRESETS`); keys given in the file
win over the presets.
"""

from __future__ import annotations

import copy
import itertools
import logging
import math
import re
import stat
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import catalogue
from ..analysis.scene import ACCURACY_PRESETS, HOLDS, MAX_STEPS, NONLINEAR_METHODS, Scene
from ..catalogue import SOLVER_KEYS, Preset
from ..catalogue import parameters as mechanism_parameters
from ..errors import InputError, KedError
from ..fe.effects import ModalDamping, Rayleigh, check_effects
from ..model.mechanism import MAX_ELEMENTS as _MODEL_MAX_ELEMENTS, Mechanism
from ..trust import UntrustedCodeError
from ..units import RAD_S_PER_RPM as RPM  # [rad/s] per rpm
from .scene_values import (SceneFileError, UntrustedSceneError, _Ctx, _bool, _float, _int, _str, _suggest, _table,
                           _typename, _unknown)
from .scene_values import _keyfmt  # noqa: F401  (how a dotted key is quoted in messages: tests match it)

__all__ = ["SceneFileError", "UntrustedSceneError", "Outputs", "Preset", "SceneSpec", "load_scene", "load_sweep",
           "load_spec", "read_scene_file", "scene_from_dict", "scene_family", "parse_scene", "with_overrides", "mechanism_parameters",
           "preset", "MAX_STEPS", "MAX_ELEMENTS", "MAX_ITER", "MAX_MODES", "MAX_SWEEP_POINTS", "RPM",
           "check_steps", "grid_points", "grid_size", "describe_damping", "scene_summary"]

log = logging.getLogger(__name__)


#: Largest number of frame elements per link (the model's own cap, :data:`kedfem.model.mechanism.MAX_ELEMENTS`).
MAX_ELEMENTS = _MODEL_MAX_ELEMENTS
#: Largest ``solver.max_iter`` (each iteration is a full periodic solve).
MAX_ITER = 1_000
#: Largest number of exported mode shapes.
MAX_MODES = 24
#: Largest number of points of a sweep grid.
MAX_SWEEP_POINTS = 10_000
#: Largest scene file [bytes] (scene files are a few hundred bytes).
MAX_FILE_BYTES = 1_000_000
#: Deepest nesting of tables and arrays in a scene file (the layout needs 3: [sweep] axes of arrays).
MAX_DEPTH = 8


# ------------------------------------------------------------------ presets
def preset(mechanism: str) -> Preset:
    """The preset scene mechanism ``mechanism`` declares (:attr:`kedfem.catalogue.MechanismInfo.preset`).

    Raises
    ------
    InputError
        For an unknown mechanism.
    """
    return catalogue.info(mechanism).preset


# ------------------------------------------------------------------ outputs
@dataclass(frozen=True)
class Outputs:
    """What a run writes, and where (the ``[output]`` table).

    Attributes
    ----------
    dir : Path
        Output folder (relative paths: to the working directory).
    plots, csv, npz, vtk, render : bool
        PNG plots; CSV tables; an NPZ archive; the VTK/PVD series with mode
        shapes; a pyvista PNG render of the deformed mechanism.
    modes : int
        Mode shapes exported to VTK (0: none).
    scale : float or None
        Deformation scale of the VTK points (None: automatic, see
        :func:`kedfem.io.export.auto_scale`).
    every : int
        Write every ``every``-th time node to the VTK series.
    dofs : tuple of str
        DOF labels for the displacement plot (empty: the largest ones).
    """

    dir: Path = Path("kedfem-out")
    plots: bool = True
    csv: bool = True
    npz: bool = True
    vtk: bool = True
    render: bool = False
    modes: int = 4
    scale: float | None = None
    every: int = 1
    dofs: tuple[str, ...] = ()


@dataclass(frozen=True)
class SceneSpec:
    """A parsed scene file: the scene, its outputs and its sweep axes (dotted key -> values)."""

    scene: Scene
    outputs: Outputs
    sweep: dict[str, tuple]
    data: dict


def check_steps(v, key: str = "steps", source: str | None = None) -> int:
    """Validate a number of time nodes (3 .. :data:`MAX_STEPS`) and return it."""
    return _int(_Ctx(source), key, v, 3, MAX_STEPS,
                " (more nodes than this cost time and memory without changing the answer; see "
                "kedfem.io.scenefile.MAX_STEPS)")


# ------------------------------------------------------------------ sections
_TOP_KEYS = ("name", "accuracy", "rtol", "method", "steps", "speed_rpm", "hold", "effects", "mechanism",
             "loads", "damping", "solver", "output", "sweep")
_LOAD_KEYS = ("name", "joint", "force", "profile")
_PROFILE_KEYS = ("of", "joint", "axis", "x", "y", "stroke", "smooth")
_DAMPING_KEYS = ("model", "alpha", "beta", "zeta")
_SOLVER_KEYS = SOLVER_KEYS
_OUTPUT_KEYS = ("dir", "plots", "csv", "npz", "vtk", "render", "modes", "scale", "every", "dofs")


def _mechanism(ctx: _Ctx, data: Mapping):
    """The mechanism table: its catalogue entry, the parameters given and the built mechanism."""
    if "mechanism" not in data:
        raise ctx.error("mechanism", "missing: a scene needs a [mechanism] table with name = one of "
                        f"{', '.join(catalogue.available())}, or builder = 'my_linkage.py:build' (run with --trust)")
    m = data["mechanism"]
    if isinstance(m, Mechanism):  # a built mechanism (Python API, sweeps): no parameters
        return catalogue.for_instance(m), {}, m
    if isinstance(m, str):
        m = {"name": m}
    _table(ctx, "mechanism", m)
    if "builder" in m:
        if "name" in m:
            raise ctx.error("mechanism.builder", "give either name (a catalogue mechanism) or builder "
                            "('my_linkage.py:build' or 'package.module:build'), not both")
        m = {"name": m["builder"], **{k: v for k, v in m.items() if k != "builder"}}
        kname = "mechanism.builder"
    else:
        kname = "mechanism.name"
    if "name" not in m:
        raise ctx.error("mechanism.name", "missing: name the mechanism, one of "
                        f"{', '.join(catalogue.available())}, or builder = 'my_linkage.py:build'")
    name = _str(ctx, kname, m["name"])
    head, colon, fn = name.rpartition(":")
    if colon and not fn.strip():
        raise ctx.error(kname, f"{name!r} names no function after ':' (e.g. '{head}:build')")
    if colon and not fn.isidentifier():
        raise ctx.error(kname, f"{name!r}: '{fn}' is not a function name")
    ref = catalogue.is_reference(name)
    key = catalogue.canonical(name, ctx.folder)
    avail = catalogue.available()
    if not ref and key not in avail:
        raise ctx.error(kname, f"unknown mechanism {name!r}{_suggest(key, avail)}; "
                        f"available: {', '.join(avail)}, or builder = 'my_linkage.py:build' "
                        "('package.module:build') for a builder of your own")
    try:
        entry = catalogue.info(key, ctx.folder, trust=ctx.trust)
    except UntrustedCodeError as e:
        raise ctx.error(kname, str(e), cls=UntrustedSceneError) from None
    except KedError as e:
        raise ctx.error(kname, str(e)) from None
    defaults = entry.parameters
    params = {}
    for k, v in m.items():
        if k == "name":
            continue
        pk = f"mechanism.{k}"
        if k == "speed":
            raise ctx.error(pk, "set the speed with the top-level key speed_rpm [rev/min], not in [mechanism]")
        if k not in defaults:
            known = [d for d in defaults if d != "speed"]
            raise ctx.error(pk, f"unknown parameter of {key}{_suggest(k, known)}; known: {', '.join(known)}")
        params[k] = _mech_value(ctx, pk, k, v, defaults[k], k in entry.signed)
    try:
        mech = entry.make(**params)
    except KedError as e:
        # point at the parameter the builder names ("coupler must be a length > 0 m"), else the table
        msg = str(e)
        named = [k for k in params if re.search(rf"\b{re.escape(k)}\b must", msg)]
        raise ctx.error(f"mechanism.{named[0]}" if named else "mechanism", msg) from None
    except Exception as e:  # noqa: BLE001 - a builder's own failure on user values is a scene error
        log.debug("mechanism %s rejected %r", key, params, exc_info=True)
        raise ctx.error("mechanism", f"{key} cannot be built with these parameters "
                        f"({type(e).__name__}: {e})") from None
    return entry, params, mech


def _mech_value(ctx, key, name, v, default, signed: bool):
    if isinstance(default, bool):
        return _bool(ctx, key, v)
    if isinstance(default, int):
        if name == "elements" or name.endswith("_elements"):
            return _int(ctx, key, v, 1, MAX_ELEMENTS, " (kedfem.io.scenefile.MAX_ELEMENTS)")
        return _int(ctx, key, v, -10**6 if signed else 0, 10**6)
    if isinstance(default, float):
        return _float(ctx, key, v, lo=None if signed else 0.0)
    if isinstance(default, str):
        return _str(ctx, key, v)
    if isinstance(default, (tuple, list)):
        if not isinstance(v, list) or len(v) != len(default):
            raise ctx.error(key, f"must be an array of {len(default)} numbers, got {_typename(v)} {v!r}")
        return tuple(_float(ctx, key, x, lo=None if signed else 0.0) for x in v)
    if default is None:
        if isinstance(v, bool) or not isinstance(v, (int, float, str)):
            raise ctx.error(key, f"must be a number or a string, got {_typename(v)} {v!r}")
        return _float(ctx, key, v) if isinstance(v, (int, float)) else v
    raise ctx.error(key, f"cannot be set from a scene file (default {default!r})")


def _floats(ctx, key, v, size=None, unit=""):
    if not isinstance(v, list) or not v or (size is not None and len(v) != size):
        n = f"{size} numbers" if size is not None else "numbers"
        raise ctx.error(key, f"must be an array of {n}{unit}, got {_typename(v)} {v!r:.80}")
    return [_float(ctx, f"{key}[{i}]", x, unit=unit) for i, x in enumerate(v)]


def _loads(ctx, v, mech) -> None:
    """``[[loads]]``: process loads added to the built mechanism (``Mechanism.load``)."""
    from ..model.profiles import PROFILE_QUANTITIES, Profile
    if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
        raise ctx.error("loads", "must be an array of tables ([[loads]] with name, joint, force and profile)")
    for i, ld in enumerate(v):
        pre = f"loads[{i}]."
        _unknown(ctx, ld, _LOAD_KEYS, pre)
        for k in ("name", "joint", "force"):
            if k not in ld:
                raise ctx.error(pre + k, "missing: a load needs name, joint and force = [Fx, Fy] [N]")
        name = _str(ctx, pre + "name", ld["name"])
        joint = _str(ctx, pre + "joint", ld["joint"])
        force = _floats(ctx, pre + "force", ld["force"], 2, " [N]")
        prof = None
        if "profile" in ld:
            p = _table(ctx, pre + "profile", ld["profile"])
            _unknown(ctx, p, _PROFILE_KEYS, pre + "profile.")
            for k in ("of", "x", "y"):
                if k not in p:
                    raise ctx.error(f"{pre}profile.{k}", "missing: a profile needs of, x and y (and joint, axis "
                                    "for a joint's table)")
            of = _str(ctx, pre + "profile.of", p["of"], PROFILE_QUANTITIES)
            try:
                prof = Profile(of, tuple(_floats(ctx, pre + "profile.x", p["x"])),
                               tuple(_floats(ctx, pre + "profile.y", p["y"])),
                               _str(ctx, pre + "profile.joint", p["joint"]) if "joint" in p else None,
                               tuple(_floats(ctx, pre + "profile.axis", p["axis"], 2)) if "axis" in p else None,
                               _str(ctx, pre + "profile.stroke", p.get("stroke", "both")),
                               _bool(ctx, pre + "profile.smooth", p.get("smooth", False)))
            except InputError as e:
                raise ctx.error(pre + "profile", str(e)) from None
        try:
            mech.load(name, joint, force, profile=prof)
        except InputError as e:
            where = ("profile.joint" if "its profile" in str(e) else "joint" if "unknown joint" in str(e)
                     else "name")
            raise ctx.error(pre + where, str(e)) from None


def _effects(ctx, v):
    if v == "all":
        return check_effects("all")
    if isinstance(v, str):
        v = [v]
    if not isinstance(v, list):
        raise ctx.error("effects", f"must be an array of effect names or \"all\", got {_typename(v)} {v!r}")
    for e in v:
        if not isinstance(e, str):
            raise ctx.error("effects", f"must contain effect names (strings), got {_typename(e)} {e!r}")
    try:
        check_effects(v)  # registered, or declared by an installed package (entry points)
    except InputError as err:
        raise ctx.error("effects", str(err)) from None
    return tuple(v)


def _damping(ctx, v, default):
    if v is None:
        return default
    if isinstance(v, str):
        v = {"model": v}
    _table(ctx, "damping", v)
    _unknown(ctx, v, _DAMPING_KEYS, "damping.")
    if "model" in v:
        model = _str(ctx, "damping.model", v["model"], ("rayleigh", "modal", "none"))
    elif "zeta" in v:
        model = "modal"
    elif "alpha" in v or "beta" in v:
        model = "rayleigh"
    else:
        raise ctx.error("damping.model", "missing: give model = \"rayleigh\" (alpha, beta), \"modal\" (zeta) "
                        "or \"none\"")
    allowed = {"rayleigh": ("alpha", "beta"), "modal": ("zeta",), "none": ()}[model]
    for k in v:
        if k != "model" and k not in allowed:
            raise ctx.error(f"damping.{k}", f"does not apply to damping model {model!r} "
                            f"(it takes {', '.join(allowed) or 'no parameters'})")
    if model == "none":
        return None
    if model == "modal":
        if "zeta" not in v:
            raise ctx.error("damping.zeta", "missing: modal damping needs zeta (ratio, 0 <= zeta < 1)")
        return ModalDamping(_float(ctx, "damping.zeta", v["zeta"], lo=0.0, hi=1.0, hi_open=True))
    alpha = _float(ctx, "damping.alpha", v.get("alpha", 0.0), lo=0.0, unit=" [1/s]")
    beta = _float(ctx, "damping.beta", v.get("beta", 0.0), lo=0.0, unit=" [s]")
    return Rayleigh(alpha, beta)


def _solver(ctx, v):
    v = _table(ctx, "solver", v if v is not None else {})
    _unknown(ctx, v, _SOLVER_KEYS, "solver.")
    out = {}
    if "eps" in v:
        out["eps"] = _float(ctx, "solver.eps", v["eps"], lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    if "max_iter" in v:
        out["max_iter"] = _int(ctx, "solver.max_iter", v["max_iter"], 1, MAX_ITER,
                               " (each iteration is a full periodic solve)")
    if "nonlinear_method" in v:
        out["nonlinear_method"] = _str(ctx, "solver.nonlinear_method", v["nonlinear_method"], NONLINEAR_METHODS)
    if "delta" in v:
        out["delta"] = _float(ctx, "solver.delta", v["delta"], lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    return out


def _outputs(ctx, v) -> Outputs:
    v = _table(ctx, "output", v if v is not None else {})
    _unknown(ctx, v, _OUTPUT_KEYS, "output.")
    kw = {}
    if "dir" in v:
        d = _str(ctx, "output.dir", v["dir"])
        if not d.strip() or "\0" in d:
            raise ctx.error("output.dir", f"must be a folder name, got {d!r}")
        pd = Path(d)
        if ctx.source is not None and "output.dir" not in ctx.overridden and (
                pd.is_absolute() or ".." in pd.parts or d.startswith("~") or pd == Path(".")):
            raise ctx.error("output.dir", f"a scene file writes below the working folder only (a relative path "
                            f"without '..'), got {d!r}; to write elsewhere, give --out on the command line")
        kw["dir"] = pd
    for k in ("plots", "csv", "npz", "vtk", "render"):
        if k in v:
            kw[k] = _bool(ctx, f"output.{k}", v[k])
    if "modes" in v:
        kw["modes"] = _int(ctx, "output.modes", v["modes"], 0, MAX_MODES)
    if "scale" in v:
        s = v["scale"]
        if s == "auto":
            kw["scale"] = None
        else:
            if isinstance(s, str):
                raise ctx.error("output.scale", f"must be \"auto\" or a number > 0, got {s!r}")
            kw["scale"] = _float(ctx, "output.scale", s, lo=0.0, lo_open=True, hi=1e12)
    if "every" in v:
        kw["every"] = _int(ctx, "output.every", v["every"], 1, MAX_STEPS)
    if "dofs" in v:
        d = v["dofs"]
        if not isinstance(d, list) or not all(isinstance(x, str) for x in d):
            raise ctx.error("output.dofs", f"must be an array of DOF labels (strings), got {d!r}")
        kw["dofs"] = tuple(d)
    return Outputs(**kw)


_SWEEPABLE_TOP = ("accuracy", "steps", "speed_rpm", "hold", "effects", "name")


def _flatten(d: Mapping, prefix=""):
    for k, v in d.items():
        if isinstance(v, dict):
            yield from _flatten(v, f"{prefix}{k}.")
        else:
            yield f"{prefix}{k}", v


def _sweep(ctx, v, params: Mapping[str, Any]) -> dict[str, tuple]:
    if v is None:
        return {}
    _table(ctx, "sweep", v)
    axes = {}
    n = 1
    for path, values in _flatten(v):
        key = f"sweep.{path}"
        head, _, rest = path.partition(".")
        ok = ((not rest and head in _SWEEPABLE_TOP)
              or (head == "mechanism" and rest in params and rest != "speed")
              or (head == "damping" and rest in _DAMPING_KEYS)
              or (head == "solver" and rest in _SOLVER_KEYS))
        if not ok:
            choices = list(_SWEEPABLE_TOP) + [f"mechanism.{p}" for p in params if p != "speed"] + \
                [f"damping.{k}" for k in _DAMPING_KEYS] + [f"solver.{k}" for k in _SOLVER_KEYS]
            hint = " (the speed is swept as speed_rpm)" if path == "mechanism.speed" else _suggest(path, choices)
            if head == "mechanism" and not params and rest != "speed":
                hint = (" (the scene's mechanism is a built Mechanism object: it has no parameters; give its "
                        "builder to sweep them)")
            raise ctx.error(key, f"cannot sweep {path!r}{hint}; sweepable: steps, speed_rpm, hold, effects, "
                            "mechanism.<parameter>, damping.<key>, solver.<key>")
        if not isinstance(values, list) or not values:
            raise ctx.error(key, f"must be a non-empty array of values, got {_typename(values)} {values!r}")
        n *= len(values)
        if n > MAX_SWEEP_POINTS:
            raise ctx.error(key, f"the grid has more than {MAX_SWEEP_POINTS} points (MAX_SWEEP_POINTS)")
        axes[path] = tuple(values)
    return axes


def parse_scene(data: Mapping, *, source: str | None = None, text: str | None = None,
                overridden=(), trust=None) -> SceneSpec:
    """Validate a scene dictionary (a parsed scene file) and build its scene.

    Parameters
    ----------
    data : mapping
        Parsed TOML (see the module docstring for the layout).
    source : str, optional
        File name used in error messages.
    text : str, optional
        The file's text, to find the line of an offending key.
    overridden : iterable of str
        Dotted keys whose values came from the command line (named so in errors).
    trust : kedfem.trust.Trust, bool or targets, optional
        The code the scene may name (:meth:`kedfem.trust.Trust.of`); default: none, the scene
        names catalogue mechanisms only.

    Returns
    -------
    SceneSpec

    Raises
    ------
    SceneFileError
        Any bad, missing or unknown key; a mechanism that cannot be built.
    UntrustedSceneError
        The mechanism is a code reference that ``trust`` does not cover (nothing was imported).
    """
    ctx = _Ctx(source, text, overridden, trust)
    if not isinstance(data, Mapping):
        raise ctx.error(None, f"a scene must be a table, got {_typename(data)}")
    _unknown(ctx, data, _TOP_KEYS, "")
    entry, params, mech = _mechanism(ctx, data)
    if "loads" in data:
        _loads(ctx, data["loads"], mech)
    # the mechanism's preset scene; an accuracy preset replaces its number of time
    # elements, hold and tolerances, a method its hold (keys given in the file still win)
    kw: dict[str, Any] = entry.preset.scene_arguments()
    accuracy = _str(ctx, "accuracy", data["accuracy"], tuple(ACCURACY_PRESETS)) if "accuracy" in data else None
    if accuracy is not None:
        kw["accuracy"] = accuracy
        for k in ("steps", "hold", "eps", "delta"):
            kw.pop(k, None)
    if "rtol" in data:
        kw["rtol"] = _float(ctx, "rtol", data["rtol"], lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    if "method" in data:
        from ..solvers.schemes import names as scheme_names
        kw["method"] = _str(ctx, "method", data["method"], scheme_names())
        kw.pop("hold", None)
    if "steps" in data:
        kw["steps"] = _int(ctx, "steps", data["steps"], 3, MAX_STEPS,
                           " (the cost grows linearly with it; rtol picks the number of elements a "
                           "result needs; see kedfem.analysis.scene.MAX_STEPS)")
    if "speed_rpm" in data:
        kw["speed"] = _float(ctx, "speed_rpm", data["speed_rpm"], nonzero=True, unit=" [rev/min]") * RPM
    # a method given on the command line replaces the file's hold
    hold_dropped = "method" in ctx.overridden and "hold" not in ctx.overridden
    if "hold" in data and not hold_dropped:
        kw["hold"] = _str(ctx, "hold", data["hold"], HOLDS)
    if "effects" in data:
        kw["effects"] = _effects(ctx, data["effects"])
    kw["damping"] = _damping(ctx, data.get("damping"), kw["damping"])
    kw.update(_solver(ctx, data.get("solver")))
    kw["name"] = _str(ctx, "name", data["name"]) if "name" in data else entry.scene_name(params, mech)
    outputs = _outputs(ctx, data.get("output"))
    sweep = _sweep(ctx, data.get("sweep"), entry.parameters)
    try:
        scene = Scene(mech, **kw)
    except KedError as e:
        # name the key the Scene's check is about (the cycle: the speed; else the mechanism)
        msg = str(e)
        key = ("speed_rpm" if ("speed_rpm" in data and ("cycle" in msg or "speed" in msg) and "no drive" not in msg)
               else "mechanism")
        raise ctx.error(key, msg) from None
    clean = {k: copy.deepcopy(v) for k, v in data.items() if k not in ("output", "sweep")}
    return SceneSpec(scene, outputs, sweep, clean)


def scene_family(base: Mapping, key: str, *, trust=None):
    """The scene of a dictionary as a function of one dotted key's value: ``f(value) -> Scene``
    (for :func:`kedfem.continuation` over a parameter other than the speed).

    Parameters
    ----------
    base : mapping
        Scene dictionary (TOML layout).
    key : str
        Dotted key (``"mechanism.coupler_EI"``, ``"damping.zeta"``).
    trust
        Code the dictionary may name (:mod:`kedfem.trust`).

    Returns
    -------
    callable
    """
    if not isinstance(base, Mapping):
        raise InputError(f"scene_family: base must be a scene dictionary, got {type(base).__name__}")
    if not isinstance(key, str) or not key or key in ("speed_rpm", "speed"):
        raise InputError(f"scene_family: key must be a dotted scene key other than the speed, got {key!r}")
    parse_scene(with_overrides(base, {}), source="scene_family", trust=trust)  # the base alone, checked now

    def scene_of(value):
        return scene_from_dict(with_overrides(base, {key: value}), source=f"scene_family ({key} = {value!r})",
                               trust=trust)

    return scene_of


def scene_from_dict(data: Mapping, *, source: str | None = None, trust=None) -> Scene:
    """The :class:`~kedfem.analysis.scene.Scene` of a scene dictionary (see :func:`parse_scene`;
    ``trust=True`` lets a dictionary your own code wrote name a builder reference)."""
    return parse_scene(data, source=source, trust=trust).scene


def read_scene_file(path) -> tuple[dict, str]:
    """Read and parse a TOML scene file.

    Returns
    -------
    data : dict
        The parsed TOML (not yet validated).
    text : str
        The file's text.

    Raises
    ------
    SceneFileError
        Unreadable file, not UTF-8, too large, or invalid TOML (with its line).
    """
    p = Path(path)
    src = str(path)
    try:
        st = p.stat()
        if not stat.S_ISREG(st.st_mode):  # a FIFO or a device would block or never end
            raise SceneFileError("cannot read the scene file: not a regular file (a folder, pipe or device); "
                                 "give a .toml file", path=src)
        size = st.st_size
        if size > MAX_FILE_BYTES:
            raise SceneFileError(f"file is {size} bytes; scene files are limited to {MAX_FILE_BYTES}", path=src)
        text = p.read_bytes().decode("utf-8")
    except SceneFileError:
        raise
    except UnicodeDecodeError as e:
        raise SceneFileError(f"not UTF-8 text ({e.reason} at byte {e.start})", path=src) from None
    except OSError as e:
        raise SceneFileError(f"cannot read the scene file ({e.strerror or e})", path=src) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        m = re.search(r"at line (\d+)", str(e))
        raise SceneFileError(f"invalid TOML: {e}", path=src, line=int(m.group(1)) if m else None) from None
    except RecursionError:
        raise SceneFileError(f"invalid scene: arrays or tables nested deeper than Python's parser can follow "
                             f"(scene files nest at most {MAX_DEPTH} levels)", path=src) from None
    depth = _depth(data)
    if depth > MAX_DEPTH:
        raise SceneFileError(f"invalid scene: values nested more than {MAX_DEPTH} levels deep (scene files "
                             f"nest at most {MAX_DEPTH})", path=src)
    return data, text


def _depth(v, level: int = 0) -> int:
    """Nesting depth of tables and arrays (stops counting past :data:`MAX_DEPTH`)."""
    if level > MAX_DEPTH:
        return level
    if isinstance(v, dict):
        return max((_depth(x, level + 1) for x in v.values()), default=level + 1)
    if isinstance(v, list):
        return max((_depth(x, level + 1) for x in v), default=level + 1)
    return level


def load_scene(path, overrides: Mapping[str, Any] | None = None, *, trust=None) -> tuple[Scene, Outputs]:
    """Load a TOML scene file.

    Parameters
    ----------
    path : str or Path
        The ``.toml`` file.
    overrides : mapping, optional
        Dotted keys set before validation (``{"steps": 60}``), e.g. from the
        command line; errors name them as such.
    trust : kedfem.trust.Trust, bool or targets, optional
        Code the scene may name besides catalogue mechanisms (:mod:`kedfem.trust`): a ``.py``
        file, a folder, the scene file itself (its folder), a module name, or ``True``.
        Default: none; a scene that names a builder file or module raises
        :class:`UntrustedSceneError` before anything is imported.

    Returns
    -------
    scene : Scene
    outputs : Outputs

    Raises
    ------
    SceneFileError
    UntrustedSceneError
    """
    spec = load_spec(path, overrides, trust=trust)
    return spec.scene, spec.outputs


def load_spec(path, overrides: Mapping[str, Any] | None = None, *, trust=None) -> SceneSpec:
    """Like :func:`load_scene`, returning the whole :class:`SceneSpec` (with the sweep axes)."""
    data, text = read_scene_file(path)
    overrides = dict(overrides or {})
    if overrides:
        data = with_overrides(data, overrides)
    return parse_scene(data, source=str(path), text=text, overridden=overrides, trust=trust)


def load_sweep(path, *, trust=None) -> tuple[dict, dict[str, tuple]]:
    """Base scene dictionary and sweep axes of a scene file with a ``[sweep]`` table."""
    spec = load_spec(path, trust=trust)
    return spec.data, spec.sweep


def with_overrides(data: Mapping, overrides: Mapping[str, Any]) -> dict:
    """A deep copy of ``data`` with dotted keys set (``"mechanism.elements": 4``).

    A string value for ``mechanism`` is expanded to ``{"name": ...}`` first.
    """
    out = copy.deepcopy(dict(data))
    if isinstance(out.get("mechanism"), str):
        out["mechanism"] = {"name": out["mechanism"]}
    for path, value in overrides.items():
        parts = str(path).split(".")
        d = out
        for p in parts[:-1]:
            nxt = d.get(p)
            if not isinstance(nxt, dict):
                nxt = {}
                d[p] = nxt
            d = nxt
        d[parts[-1]] = copy.deepcopy(value)
    return out


def grid_size(axes: Mapping[str, tuple]) -> int:
    """Number of points of a sweep grid."""
    return math.prod(len(v) for v in axes.values()) if axes else 0


def grid_points(axes: Mapping[str, tuple]):
    """Cartesian product of the axes, as dicts dotted key -> value (first axis slowest)."""
    keys = list(axes)
    for combo in itertools.product(*(axes[k] for k in keys)):
        yield dict(zip(keys, combo))


def describe_damping(d) -> str:
    """One-line description of a damping model."""
    if d is None:
        return "none (undamped)"
    if isinstance(d, ModalDamping):
        return f"modal, zeta = {d.zeta:g}"
    if isinstance(d, Rayleigh):
        return f"Rayleigh, alpha = {d.alpha:g} 1/s, beta = {d.beta:g} s"
    return repr(d)


def scene_summary(scene: Scene) -> dict[str, str]:
    """Human-readable fields of a scene (for reports)."""
    sp = scene.mech.drives[0].speed
    return {
        "mechanism": scene.mech.name,
        "speed": f"{sp / RPM:.6g} rpm ({sp:.6g} rad/s), period {scene.period:.6g} s",
        "steps": "tolerance-driven" if scene.steps is None else str(scene.steps),
        "method": scene.scheme,
        "rtol": f"{scene.rtol:g}",
        "effects": ", ".join(scene.effects),
        "damping": describe_damping(scene.damping),
    }

