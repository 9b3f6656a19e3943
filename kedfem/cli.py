"""Command-line interface of kedfem.

``kedfem run [SCENE.toml | MECHANISM]``
    Solve a scene (default: the built-in mould-oscillator scene), print a
    summary table and write CSV, NPZ, plots and a VTK series.
``kedfem validate``
    The paper's Table 3 and a modal-superposition check.
``kedfem sweep [SCENE.toml | MECHANISM] --param KEY=VALUES ...``
    Parameter sweep on a process pool or a Dask cluster.
``kedfem export [SCENE.toml | MECHANISM] [--render]``
    VTK/PVD series (and mode shapes) for ParaView, optionally a PNG render.
``kedfem continuation [SCENE.toml | MECHANISM] --speeds LO:HI``
    The periodic response followed over speed through folds, its stability
    and bifurcations (and the period-2 response past a flip).
``kedfem list``
    Mechanisms with their parameters, effects with their descriptions.

The library logs; this module prints. A :class:`~kedfem.errors.KedError`
(bad input, a linkage that cannot move, a resonance...) prints one line
``kedfem: error: ...`` on stderr and exits with status 2, without a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import inspect
import logging
import math
import os
import re
import sys
import time
import warnings
from pathlib import Path

from . import __version__
from .errors import InputError, KedError
from . import cli_parser
from .cli_parser import COMMANDS, EXIT_STRICT
from .io.outdir import MANIFEST, check_replaceable
from .units import RAD_S_PER_RPM, RPM_PER_RAD_S

__all__ = ["main", "build_parser"]

log = logging.getLogger(__name__)

EXIT_ERROR = 2


def _overrides(args) -> dict:
    o = {}
    if getattr(args, "steps", None) is not None:
        o["steps"] = args.steps
    if getattr(args, "speed", None) is not None:
        o["speed_rpm"] = args.speed
    if getattr(args, "hold", None):
        o["hold"] = args.hold
    if getattr(args, "method", None):
        o["method"] = args.method
    if getattr(args, "rtol", None) is not None:
        o["rtol"] = args.rtol
    if getattr(args, "accuracy", None):
        o["accuracy"] = args.accuracy
    if getattr(args, "effects", None) is not None:
        o["effects"] = args.effects
    return o


@dataclasses.dataclass(frozen=True)
class _Loaded:
    scene: object
    outputs: object
    data: dict          # scene dictionary (for sweeps)
    sweep: dict
    source: str
    trust: object       # kedfem.trust.Trust: the code the scene may name (sweep workers too)


def _load(target: str | None, overrides: dict, trusted=None) -> _Loaded:
    """Scene from a file, a mechanism name or the built-in default, with command-line overrides.

    The default scene is the preset scene of :data:`kedfem.analysis.defaults.DEFAULT_MECHANISM`,
    loaded like any mechanism name. ``trusted``: the ``--trust`` targets; a builder reference
    given as ``target`` (the command's own argument) is trusted.
    """
    from . import catalogue
    from .analysis.defaults import DEFAULT_MECHANISM
    from .io import scenefile as sf
    from .trust import Trust
    trust = Trust.of(trusted, "--trust")
    if target is not None and Path(target).suffix.lower() == ".py" and Path(target).is_file():
        raise InputError(f"{target!r} is a Python file: name its builder function, e.g. "
                         f"kedfem {' '.join(sys.argv[1:2]) or 'run'} {target}:build")
    if target is not None and Path(target).is_dir():
        raise InputError(f"{target!r} is a folder: give a scene file (.toml) or a mechanism name (kedfem list)")
    if target is not None and (Path(target).suffix.lower() == ".toml" or Path(target).is_file()):
        trust = trust.searching(Path(target).resolve().parent)
        spec = sf.load_spec(Path(target), overrides, trust=trust)
        return _Loaded(spec.scene, spec.outputs, sf.with_overrides(spec.data, overrides), spec.sweep,
                       str(Path(target)), trust)
    key = DEFAULT_MECHANISM if target is None else target
    key = catalogue.canonical(key)  # a file reference with its absolute path (sweep workers load it)
    if target is not None and not catalogue.is_reference(key) and key not in catalogue.available():
        avail = catalogue.available()
        raise InputError(f"no scene file or mechanism named {target!r}{sf._suggest(key, avail)}; "
                         f"mechanisms: {', '.join(avail)} (kedfem list), or 'package.module:function' or "
                         f"'my_file.py:function' for a builder of your own")
    if catalogue.is_reference(key):
        trust = trust | Trust.of_reference(key)  # the user named it on the command line
    data = sf.with_overrides({"mechanism": {"name": key}}, overrides)
    source = "built-in default scene" if target is None else f"mechanism {key}"
    spec = sf.parse_scene(data, source=source, overridden=overrides, trust=trust)
    if target is None:
        return _Loaded(spec.scene, spec.outputs, {"mechanism": None, "name": spec.scene.name, **data}, {}, source,
                       trust)
    # a builder of the user's own that declares no PRESET runs kedfem's default scene for it (a new
    # user's six-bar was said to run a "preset scene" it never declared)
    declared = catalogue.info(key, trust=trust).preset != catalogue.Preset()
    return _Loaded(spec.scene, spec.outputs, data, {},
                   f"{source} ({'preset scene' if declared else 'no PRESET: the default effects and damping'})",
                   trust)


@contextlib.contextmanager
def _report_warnings():
    """Print warnings raised inside as one line each on stderr (once per message)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield caught
        finally:
            seen = set()
            for w in caught:
                msg = f"{w.category.__name__}: {w.message}"
                if msg not in seen:
                    seen.add(msg)
                    print(f"kedfem: warning: {msg}", file=sys.stderr)


def _solve(scene):
    from .analysis.pipeline import solve
    with _report_warnings():
        return solve(scene)


# ------------------------------------------------------------------- run
def _check_dofs(scene, dofs) -> None:
    """A bad plot label is an input error before any work, not after the solve."""
    if not dofs:
        return
    from .fe.model import FEModel
    model = FEModel(scene.mech, reduction=scene.reduction)
    for d in dofs:
        model.dof_index(d, owner="plot: ")


def _cmd_run(args) -> int:
    from .io.report import check_out_dir, format_summary, write_result
    t0 = time.perf_counter()
    ld = _load(args.scene, _overrides(args), args.trust)
    o = ld.outputs
    out_dir = Path(args.out) if args.out else o.dir
    sc = ld.scene
    dofs = tuple(args.dofs.split(",")) if args.dofs else o.dofs
    _check_dofs(sc, dofs)
    check_out_dir(out_dir, "--out" if args.out else "the scene's output.dir")
    check_replaceable(out_dir)
    how = f"{sc.steps} time elements" if sc.steps is not None else f"tolerance {sc.rtol:g}"
    print(f"kedfem {__version__}: solving {sc.name or sc.mech.name} ({sc.scheme}, {how}) ...", flush=True)
    res = _solve(sc)
    want = dict(plots=o.plots and not args.no_plots, csv=o.csv and not args.no_csv,
                npz=o.npz and not args.no_npz, vtk=o.vtk and not args.no_vtk,
                render=(o.render or args.render) and not args.no_render)
    with _report_warnings():
        if any(want.values()):
            text = write_result(res, out_dir, **want, modes=o.modes if args.modes is None else args.modes,
                                scale=args.scale if args.scale else o.scale, every=args.every or o.every,
                                dofs=dofs, n_modes=args.n_modes, mesh_check=not args.no_mesh_check,
                                source=ld.source, command="run", started=t0).summary
        else:
            text = _summary_only(res, args, ld.source, t0, format_summary)
    print()
    print(text)
    if args.strict:
        failed = strict_failures(res)
        if failed:
            print("kedfem: --strict: " + "; ".join(failed), file=sys.stderr)
            return EXIT_STRICT
    return 0


def strict_failures(res) -> list[str]:
    """What ``--strict`` fails on: an iteration that did not converge, a response that is not
    stable, an estimated error above the tolerance, and the checks the summary shows: a link
    out of linear theory (:func:`kedfem.analysis.plausibility.check_result`) or with a safety
    factor below 1 against yield, Goodman or Soderberg (:func:`kedfem.analysis.fatigue.fatigue_table`)."""
    import warnings
    from .analysis.fatigue import fatigue_table
    from .analysis.plausibility import check_result
    out = []
    if not res.converged:
        out.append("the non-linear iteration did not converge")
    if not res.stable:
        out.append(f"the response is not stable ({res.stability.verdict if res.stability else 'unstable'})")
    if res.error is not None and not res.error.met:
        out.append(f"the estimated error {res.error.peak:.1e} exceeds the tolerance")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the solve warned already
        out += check_result(res)
    for lf in fatigue_table(res).links:
        for name, v in (("yield", lf.safety_yield), ("Goodman", lf.safety_goodman),
                        ("Soderberg", lf.safety_soderberg)):
            if v is not None and v < 1.0:
                out.append(f"link '{lf.link}': safety factor against {name} {v:.2f} < 1")
    return out


def _summary_only(res, args, source: str, t0: float, format_summary) -> str:
    """The summary table when no file is written."""
    from .analysis.fatigue import fatigue_table
    freqs = res.frequencies(args.n_modes, nodes=list(range(0, res.n, max(1, res.n // 180))))
    mesh = None
    if not args.no_mesh_check:
        from .analysis.mesh_check import mesh_error
        mesh = mesh_error(res)
    return format_summary(res, freqs, res.peaks(), stages={}, files=[], out_dir=None, source=source,
                          scene_time=time.perf_counter() - t0, mesh=mesh, fatigue=fatigue_table(res),
                          loads=res.loads())


# -------------------------------------------------------------- validate
def _cmd_validate(args) -> int:
    from . import catalogue
    from .analysis.scene import Scene
    from .analysis.validation import table3, validate
    from .fe.effects import Rayleigh
    ok = True
    t0 = time.perf_counter()
    if not args.skip_table3:
        how = f"{args.steps} time elements" if args.steps else "tolerance-driven time elements"
        print(f"Table 3: fundamental frequency of the mould oscillator, crank groups 1-4 "
              f"({how}; state-space = with damping and coupling, modal = undamped)")
        with _report_warnings():
            rep = table3(steps=args.steps)
        print(rep.table())
        print()
    print("modal-superposition check: exciter (time-invariant cantilever, Rayleigh damping)")
    scene = Scene(catalogue.build("exciter"), effects=("inertia", "coupling", "springs"),
                  damping=Rayleigh(0.0, 1e-4), name="exciter")
    with _report_warnings():
        rep = validate(scene, foh_steps=args.steps or 180)
    print(rep.table())
    for r in rep.responses:
        # the solve's own error estimate bounds its difference from the exact answer
        # (within a factor 3); the foh check is exact up to round-off
        bound = args.tol if r.estimate is None else max(args.tol, 3.0 * r.estimate)
        good = r.max_rel_error <= bound
        ok &= good
        print(f"  {r.method}: max. relative difference {r.max_rel_error:.3e} "
              f"{'<=' if good else '>'} {bound:.3g} -> {'PASS' if good else 'FAIL'}")
    if not rep.responses:
        print("  (no response check applied)")
        ok = False
    print(f"\nwall time {time.perf_counter() - t0:.2f} s")
    return 0 if ok else 1


# ----------------------------------------------------------------- sweep
def _short(v) -> str:
    """A sweep value for the console table (the CSV keeps full precision)."""
    if isinstance(v, float):
        return f"{v:.8g}"
    return str(v)


def _cmd_sweep(args) -> int:
    from .io.report import check_out_dir, relative
    from .io import scenefile as sf
    from .io import sweep as sw
    ld = _load(args.scene, _overrides(args), args.trust)
    axes = dict(ld.sweep)
    for text in args.param or ():
        k, v = sw.parse_axis(text)
        axes[k] = v
    if not axes:
        raise InputError("sweep: nothing to sweep: give --param KEY=V1,V2,... (or KEY=START:STOP:NUM), "
                         "or a scene file with a [sweep] table")
    # validate the axis keys against the base scene before starting workers
    sf.parse_scene(dict(ld.data, sweep={k: list(v) for k, v in axes.items()}), source="command line",
                   trust=ld.trust)
    # and every value of every axis, alone on the base scene, before the workers start (a value the
    # builder itself rejects is the point's failure, recorded in the table with the others solved)
    for k, vals in axes.items():
        for v in dict.fromkeys(vals):
            try:
                sf.parse_scene(sf.with_overrides(ld.data, {k: v}), source=f"--param {k}={v!r}", trust=ld.trust,
                               overridden=(k,))
            except sf.SceneFileError as e:
                if e.key != "mechanism":
                    raise
    out_dir = Path(args.out) if args.out else ld.outputs.dir
    check_out_dir(out_dir, "--out" if args.out else "the scene's output.dir")
    check_replaceable(out_dir)
    from .io.outdir import RunFolder
    from .io.sweep_journal import SweepJournal, sweep_signature
    points = sw.make_points(ld.data, axes)
    journal = SweepJournal(out_dir.with_name(out_dir.name + ".partial.csv"), sweep_signature(ld.data, axes),
                           list(axes))
    done = {}
    if args.resume:
        done = journal.read(points)
        done = {i: r for i, r in done.items() if r.ok}
        print(f"resuming from {journal.path}: {len(done)} of {len(points)} points done", flush=True)
    n = len(points) - len(done)
    where = args.scheduler
    print(f"kedfem {__version__}: sweep of {n} points over {', '.join(axes)} on {where} (partial table: "
          f"{journal.path}) ...", flush=True)
    journal.start(done)
    try:
        with _report_warnings():
            res = sw.run_sweep(ld.data, points=points, scheduler=args.scheduler, max_workers=args.workers,
                               progress=False if args.no_progress else None,
                               frequencies=not args.no_frequencies, done=done, on_result=journal.append,
                               trust=ld.trust)
    finally:
        journal.close()
    res = dataclasses.replace(res, axes=tuple(sw._normalize_axes(axes).items()))
    with RunFolder(out_dir, "sweep", dict(scene=ld.source, points=len(points),
                                          failed=len(res.failed))) as rf:
        staged = [res.to_csv(rf.path / "sweep.csv")]
        if not args.no_plots and len(res.failed) < len(res.points):
            staged.append(res.plot(rf.path / "sweep_peaks.png", x=args.x))
        files = [out_dir / Path(f).relative_to(rf.path) for f in staged]
    journal.close(remove=True)
    keys = list(axes)
    print()
    head = "  ".join(f"{k:>14s}" for k in keys)
    print(f"{'point':>5s}  {head}  {'max peak stress [Pa]':>20s} {'max deflection [m]':>18s} "
          f"{'f1 [Hz]':>9s} {'rho':>8s} {'time [s]':>8s}")
    for p in res.points:
        pv = dict(p.params)
        vals = "  ".join(f"{_short(sw._cell(pv.get(k))):>14s}" for k in keys)
        if p.ok:
            s = max((lp.stress for lp in p.peaks if math.isfinite(lp.stress)), default=float("nan"))
            d = max((lp.deflection for lp in p.peaks), default=float("nan"))
            print(f"{p.index:5d}  {vals}  {s:20.4e} {d:18.4e} {p.fundamental:9.3f} {p.spectral_radius:8.4f} "
                  f"{p.wall_time:8.2f}")
        else:
            print(f"{p.index:5d}  {vals}  FAILED: {p.error}")
    print(f"\n{len(res.points) - len(res.failed)} of {len(res.points)} points solved on {res.scheduler} "
          f"in {res.wall_time:.2f} s")
    print(f"files in {out_dir}/")
    for f in files:
        print(f"  {relative(f, out_dir)}")
    print(f"  {MANIFEST} (run {rf.run_id})")
    return 1 if res.failed else 0


# ---------------------------------------------------------------- export
def _cmd_export(args) -> int:
    from .io.report import check_out_dir, relative
    if args.animate is not None and (Path(args.animate).name != args.animate or args.animate.startswith(".")
                                     or not args.animate.lower().endswith(".gif")):
        raise InputError(f"--animate {args.animate}: must be a .gif file name, written into the output folder "
                         f"(give the scene first: kedfem export SCENE --animate [NAME.gif])")
    from .io import export
    from .io.outdir import RunFolder
    ld = _load(args.scene, _overrides(args), args.trust)
    o = ld.outputs
    out_dir = Path(args.out) if args.out else o.dir
    check_out_dir(out_dir, "--out" if args.out else "the scene's output.dir")
    check_replaceable(out_dir)
    sc = ld.scene
    how = f"{sc.steps} time elements" if sc.steps is not None else f"tolerance {sc.rtol:g}"
    print(f"kedfem {__version__}: solving {sc.name or sc.mech.name} ({sc.scheme}, {how}) ...", flush=True)
    t0 = time.perf_counter()
    res = _solve(sc)
    t1 = time.perf_counter()
    with RunFolder(out_dir, "export", dict(scene=ld.source)) as rf:
        series = export.write_vtk_series(res, rf.path, scale=args.scale or o.scale, every=args.every or o.every)
        staged = [series.pvd]
        modes = o.modes if args.modes is None else args.modes
        if modes:
            staged.append(export.write_mode_shapes(res, rf.path, n_modes=modes).pvd)
        t2 = time.perf_counter()
        frame = None
        if args.render or o.render:
            from .io import render as rd
            frame = series.peak_frame if args.frame is None else args.frame
            staged.append(rd.render_series(series, rf.path / "deformed.png", frame=frame))
        if args.animate is not None:
            from .io import render as rd
            staged.append(rd.render_animation(series, rf.path / args.animate))
        files = [out_dir / Path(f).relative_to(rf.path) for f in staged]
    t3 = time.perf_counter()
    print(f"VTK series: {len(series.files)} frames, deformation scale {series.scale:g} "
          f"(point data unscaled, SI units)")
    if frame is not None:
        print(f"rendered frame {frame} (t = {series.times[frame]:.6g} s)")
    print(f"wall time [s]: solve {t1 - t0:.2f}, vtk {t2 - t1:.2f}, render {t3 - t2:.2f}")
    print(f"files in {out_dir}/")
    for f in files:
        print(f"  {relative(f, out_dir)}")
    print(f"  {MANIFEST} (run {rf.run_id})")
    if not res.converged:
        print("kedfem: note: the non-linear iteration did not converge", file=sys.stderr)
    return 0


# ------------------------------------------------------------------ list
def _param_docs(module) -> dict[str, str]:
    """First sentence of each parameter's description (docstring, else DEFAULTS comments)."""
    out: dict[str, str] = {}
    doc = inspect.getdoc(module.build) or ""
    lines = doc.splitlines()
    if "Parameters" in lines:
        groups: list[tuple[list[str], list[str]]] = []
        for line in lines[lines.index("Parameters") + 2:]:
            if not line.strip():
                continue
            if not line.startswith(" "):
                if " : " not in line:
                    break
                groups.append(([n.strip() for n in line.split(" : ")[0].split(",")], []))
                continue
            if groups:
                groups[-1][1].append(line.strip())
        for names, text in groups:
            words = " ".join(text)
            end = re.search(r"\.(\s|$)", words)
            first = words[:end.start() + 1] if end else words
            if len(first) > 160:
                first = first[:157].rstrip() + "..."
            for n in names:
                out.setdefault(n, first)
    try:
        src = inspect.getsource(module)
    except (OSError, TypeError):
        return out
    for m in re.finditer(r"^\s*(\w+)\s*=\s*[^#\n]*#\s*(.+)$", src, re.M):
        out.setdefault(m.group(1), m.group(2).strip())
    return out


def _preset_line(pre) -> str:
    """A mechanism's preset scene in one line (``kedfem list``)."""
    from .io.scenefile import describe_damping
    parts = ["tolerance-driven" if pre.steps is None else f"steps {pre.steps}"]
    if pre.hold is not None:
        parts.append(f"hold {pre.hold}")
    parts.append(f"effects {', '.join(pre.effects)}" if pre.effects is not None
                 else "effects: the linear KED set and what the mechanism declares")
    parts.append(f"damping {describe_damping(pre.damping)}")
    if pre.solver:
        parts.append("solver " + ", ".join(f"{k} = {v!r}" for k, v in pre.solver))
    return "; ".join(parts)


def _cmd_list(args) -> int:
    from . import catalogue
    from .analysis.scene import HOLDS, NONLINEAR_METHODS
    from .fe.effects import EFFECTS
    print("mechanisms (kedfem run NAME; parameters go in the [mechanism] table of a scene file, SI units;")
    print("            the speed is the top-level speed_rpm; (+-): may be negative):")
    for name in catalogue.available():
        entry = catalogue.info(name)
        print(f"\n  {name}: {entry.summary}")
        print(f"    preset: {_preset_line(entry.preset)}")
        docs = _param_docs(entry.source)
        for k, v in entry.parameters.items():
            d = docs.get(k, "")
            if k == "speed":
                d = (d.rstrip(".") + "; " if d else "") + "set it with speed_rpm [rev/min]"
            sign = " (+-)" if k in entry.signed else ""
            print(f"    {k + sign:<24s} = {v!r:<22} {d}")
    print("\neffects (the scene's effects = [...]; nothing else is assembled):")
    for e in EFFECTS.values():
        print(f"  {e.name:<24s} {e.adds}")
    from .solvers.schemes import SCHEMES
    print("\ntime schemes (method = ...; 'auto' is radau3):")
    for sch in SCHEMES.values():
        if sch.name == "fourier":
            print(f"  {sch.name:<10s} spectral, trigonometric collocation over the whole cycle (odd number "
                  "of nodes; small smooth models)")
            continue
        print(f"  {sch.name:<10s} order {sch.order}, {sch.stages} instant(s) per element"
              f"{', L-stable' if sch.l_stable else ''}{' (the paper: exponential hold)' if sch.stages == 1 else ''}")
    print(f"holds (the exponential methods): {', '.join(HOLDS)}; non-linear methods: {', '.join(NONLINEAR_METHODS)}")
    print("damping models: rayleigh (alpha [1/s], beta [s]), modal (zeta [-]), none")
    return 0


# ------------------------------------------------------ design decisions
def _rpm_values(text: str, name: str):
    """``START:STOP:NUM`` or ``V1,V2,...`` [rev/min] -> speeds [rad/s] (an InputError names ``name``)."""
    import numpy as np
    from .io.sweep import parse_axis
    _, vals = parse_axis(f"{name}={text}")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
        raise InputError(f"{name}: speeds must be numbers [rev/min], got {text!r}")
    return np.asarray(vals, dtype=float) * RAD_S_PER_RPM


def _publish(out_dir: Path, command: str, source: str, write) -> None:
    """Write the files of ``write(folder) -> [paths]`` into ``out_dir`` (published whole) and list them."""
    from .io.outdir import RunFolder
    from .io.report import relative
    with RunFolder(out_dir, command, dict(scene=source)) as rf:
        files = [out_dir / Path(f).relative_to(rf.path) for f in write(rf.path)]
    print(f"files in {out_dir}/")
    for f in files:
        print(f"  {relative(f, out_dir)}")
    print(f"  {MANIFEST} (run {rf.run_id})")


def _cmd_campbell(args) -> int:
    from .analysis.campbell import campbell
    from .io.report import check_out_dir
    ld = _load(args.scene, _overrides(args), args.trust)
    speeds = _rpm_values(args.speeds, "--speeds")
    out_dir = Path(args.out) if args.out else ld.outputs.dir
    check_out_dir(out_dir, "--out" if args.out else "the scene's output.dir")
    check_replaceable(out_dir)
    with _report_warnings():
        res = campbell(ld.scene, speeds, n_modes=args.n_modes, harmonics=args.harmonics, nodes=args.nodes,
                       method="solve" if args.from_solve else "modal")
    print(res.describe())

    def write(folder):
        out = [res.to_csv(folder / "campbell.csv"), res.crossings_to_csv(folder / "campbell_crossings.csv")]
        return out + ([] if args.no_plots else [res.plot(folder / "campbell.png")])

    _publish(out_dir, "campbell", ld.source, write)
    return 0


def _cmd_critical(args) -> int:
    from .analysis.critical import critical_speed
    ld = _load(args.scene, _overrides(args), args.trust)
    rpm = RAD_S_PER_RPM
    print(f"kedfem {__version__}: {args.kind} critical speed of {ld.scene.name or ld.scene.mech.name} in "
          f"{args.lo:g} .. {args.hi:g} rpm ...", flush=True)
    with _report_warnings():
        res = critical_speed(ld.scene, args.lo * rpm, args.hi * rpm, rtol=args.tol, kind=args.kind,
                             linear=args.linear, scan=args.scan, max_solves=args.max_solves)
    unit = "rho" if args.kind == "parametric" else "f1 [Hz]"
    print(f"  {'speed [rpm]':>12s} {unit:>12s} {'+-':>8s}")
    for e in res.evaluations:
        print(f"  {e.rpm:12.3f} {e.value:12.6g} {e.error:8.1e}")
    print(res.describe())
    return 0 if res.met else 1


def _cmd_stability_map(args) -> int:
    from .io.design_plots import stability_map
    from .io.report import check_out_dir
    from .io.sweep import parse_axis
    ld = _load(args.scene, _overrides(args), args.trust)
    speeds = _rpm_values(args.speeds, "--speeds")
    key, values = parse_axis(args.param)
    out_dir = Path(args.out) if args.out else ld.outputs.dir
    check_out_dir(out_dir, "--out" if args.out else "the scene's output.dir")
    check_replaceable(out_dir)
    print(f"kedfem {__version__}: stability map of {ld.scene.name or ld.scene.mech.name}, {speeds.size} speeds x "
          f"{len(values)} values of {key} on {args.scheduler} ...", flush=True)
    with _report_warnings():
        smap = stability_map(ld.data, speeds, key, list(values), scheduler=args.scheduler,
                             max_workers=args.workers, progress=False if args.no_progress else None,
                             trust=ld.trust)
    print(f"  {key:>24s}  first onset [rpm]: between two grid speeds (interpolated in log rho; "
          "kedfem critical refines it)")
    rpm = RPM_PER_RAD_S
    for v, s, lo, hi in zip(smap.values, smap.onsets(), *smap.onset_brackets()):
        print(f"  {v:24.6g}  {lo * rpm:.4g} .. {hi * rpm:.4g} (about {s * rpm:.3g})" if math.isfinite(s)
              else f"  {v:24.6g}  none on the grid")
    for v, s, why in smap.failures:
        print(f"  FAILED {key} = {v:g} at {s * RPM_PER_RAD_S:.1f} rpm: {why}")

    def write(folder):
        out = [smap.to_csv(folder / "stability_map.csv")]
        if not args.no_plots and smap.values.size >= 2 and smap.speeds.size >= 2:
            out.append(smap.plot(folder / "stability_map.png"))
        return out

    _publish(out_dir, "stability-map", ld.source, write)
    return 1 if smap.failures else 0


def _cmd_continuation(args) -> int:
    from .analysis.continuation import continuation
    from .io.branch_files import write
    from .io.report import check_out_dir
    ld = _load(args.scene, _overrides(args), args.trust)
    text = args.speeds.strip()
    parts = text.split(":")
    try:
        lo, hi = (float(x) for x in parts)
    except ValueError:
        raise InputError(f"--speeds: give LO:HI [rev/min], got {text!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo > 0 and hi > 0 and lo != hi):
        raise InputError(f"--speeds: LO and HI must be different finite speeds > 0 [rev/min], got {text!r}")
    out_dir = Path(args.out) if args.out else ld.outputs.dir
    check_out_dir(out_dir, "--out" if args.out else "the scene's output.dir")
    check_replaceable(out_dir)
    rpm = RAD_S_PER_RPM
    print(f"kedfem {__version__}: continuation of {ld.scene.name or ld.scene.mech.name} in speed from {lo:g} to "
          f"{hi:g} rpm ...", flush=True)
    with _report_warnings():
        br = continuation(ld.scene, lo * rpm, hi * rpm, steps=args.steps, errors=not args.no_errors,
                          period2=not args.no_period2, max_points=args.max_points,
                          progress=False if args.no_progress else None)
    print(br.describe())
    _publish(out_dir, "continuation", ld.source, lambda folder: write(br, folder, plots=not args.no_plots))
    if "interrupted" in br.end:  # the files hold what was done; the status says it is not all
        print(f"kedfem: interrupted: {br.end}; the files in {out_dir} hold the branch so far", file=sys.stderr)
        return 130
    return 0


# ---------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    """The ``kedfem`` argument parser (:func:`kedfem.cli_parser.build_parser` with this module's commands)."""
    return cli_parser.build_parser({
        "run": _cmd_run, "validate": _cmd_validate, "sweep": _cmd_sweep, "export": _cmd_export,
        "campbell": _cmd_campbell, "critical": _cmd_critical, "stability-map": _cmd_stability_map,
        "continuation": _cmd_continuation, "list": _cmd_list})


class _StderrHandler(logging.StreamHandler):
    """Writes to the ``sys.stderr`` of the moment (a handler bound to the stream of its first call
    wrote into a closed one when ``main`` ran again with stderr redirected)."""

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, _value):
        pass


class _LowerLevel(logging.Formatter):
    """``kedfem: warning: ...`` for a logged warning as for a Python warning (a new user saw both
    ``WARNING:`` and ``warning:`` in one run)."""

    def format(self, record):
        return super().format(logging.makeLogRecord({**record.__dict__, "levelname": record.levelname.lower()}))


def _setup_logging(verbose: int) -> None:
    level = logging.WARNING if verbose <= 0 else logging.INFO if verbose == 1 else logging.DEBUG
    root = logging.getLogger("kedfem")
    if not any(getattr(h, "_kedfem_cli", False) for h in root.handlers):
        h = _StderrHandler()
        h.setFormatter(_LowerLevel("kedfem: %(levelname)s: %(message)s"))
        h._kedfem_cli = True
        root.addHandler(h)
    root.setLevel(level)


def main(argv=None) -> int:
    """Entry point of the ``kedfem`` console script; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    # -v before the command (kedfem -v run ...) means the same as after it
    lead = []
    while argv and re.fullmatch(r"-v+|--verbose", argv[0]):
        lead.append(argv.pop(0))
    if not argv or (argv[0] not in COMMANDS and argv[0] not in ("-h", "--help", "--version")):
        argv = ["run"] + argv
    if argv and argv[0] in COMMANDS:
        argv[1:1] = lead
    else:
        argv = lead + argv
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # argparse: --help / --version (0) or a usage error (2)
        return int(e.code or 0)
    _setup_logging(args.verbose)
    try:
        return int(args.func(args))
    except KedError as e:
        print(f"kedfem: error: {' '.join(str(e).split())}", file=sys.stderr)
        return EXIT_ERROR
    except BrokenPipeError:  # e.g. `kedfem list | head`: stop quietly
        with contextlib.suppress(OSError):
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        return 1
    except OSError as e:
        print(f"kedfem: error: {e.strerror or e}: {e.filename or ''}".rstrip(": "), file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("kedfem: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
