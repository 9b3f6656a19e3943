"""The ``kedfem`` command line's grammar: its commands, their arguments, the checks of each
argument's value, and the help texts. The commands themselves are :mod:`kedfem.cli`'s.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Mapping
from pathlib import Path

from . import __version__

__all__ = ["build_parser", "COMMANDS", "EXIT_STRICT"]

COMMANDS = ("run", "validate", "sweep", "export", "list", "campbell", "critical", "stability-map", "continuation")
#: exit status of ``kedfem run --strict`` when the result is not one to trust
EXIT_STRICT = 3


# ------------------------------------------------------------ arg helpers
def _number(parse, check, requirement: str, unit: str = ""):
    """An argparse type: ``parse`` (int or float) the text, then ``check`` the value."""
    kind = "an integer" if parse is int else "a number"

    def f(s: str):
        try:
            v = parse(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {kind}{unit}, got {s!r}") from None
        if not check(v):
            raise argparse.ArgumentTypeError(f"must {requirement}, got {s!r}")
        return v
    return f


def _steps_arg(s: str) -> int:
    from .analysis.scene import MAX_STEPS
    return _number(int, lambda v: 3 <= v <= MAX_STEPS,
                   f"lie in 3 .. {MAX_STEPS} (see kedfem.analysis.scene.MAX_STEPS)")(s)


_rtol_arg = _number(float, lambda v: 0 < v < 1, "lie in (0, 1) (a relative error, e.g. 1e-3)")
_speed_arg = _number(float, lambda v: math.isfinite(v) and v != 0, "be a finite nonzero speed [rev/min]",
                     " [rev/min]")
_positive_float = _number(float, lambda v: math.isfinite(v) and v > 0, "be a finite number > 0")


def _out_arg(s: str) -> str:
    """An output folder: a name, not empty and not the working folder itself (it is replaced whole)."""
    if not s.strip():
        raise argparse.ArgumentTypeError("must name a folder, got an empty string")
    if Path(s).resolve() == Path.cwd().resolve() or Path(s).resolve() == Path(Path(s).anchor or "/").resolve():
        raise argparse.ArgumentTypeError(f"must name a folder of its own (it is replaced whole on every run), "
                                         f"not the working folder or the root, got {s!r}")
    if "\0" in s:
        raise argparse.ArgumentTypeError("must be a path without NUL characters")
    return s


def _int_range(lo: int, hi: int):
    return _number(int, lambda v: lo <= v <= hi, f"lie in {lo} .. {hi}")


def _scheme_names():
    from .solvers.schemes import names
    return names()


def _effects_arg(s: str):
    s = s.strip()
    if s == "all":
        return "all"
    return [e.strip() for e in s.split(",") if e.strip()]


def build_parser(commands: Mapping[str, Callable]) -> argparse.ArgumentParser:
    """The ``kedfem`` argument parser; ``commands`` maps each command of :data:`COMMANDS` to the
    function that runs it (``func(args) -> exit status``, :mod:`kedfem.cli`)."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-v", "--verbose", action="count", default=0, help="log more (-v info, -vv debug)")

    scene = argparse.ArgumentParser(add_help=False)
    scene.add_argument("scene", nargs="?", metavar="SCENE.toml | MECHANISM",
                       help="scene file or mechanism name (default: the built-in mould-oscillator scene)")
    scene.add_argument("--out", metavar="DIR", type=_out_arg,
                       help="output folder (default: the scene's output.dir, kedfem-out)")
    scene.add_argument("--speed", type=_speed_arg, metavar="RPM", help="speed of the first drive [rev/min]")
    scene.add_argument("--rtol", type=_rtol_arg, metavar="TOL",
                       help="tolerance on every link's peak deflection and stress (default 1e-3)")
    scene.add_argument("--accuracy", choices=("fast", "default", "tight"),
                       help="accuracy preset: rtol 1e-2 / 1e-3 / 1e-5, eps, delta (explicit --rtol wins)")
    scene.add_argument("--method", choices=_scheme_names(),
                       help="time discretisation (default auto: Radau IIA collocation; the paper's "
                       "exponential holds magnus2, foh, zoh)")
    scene.add_argument("--steps", type=_steps_arg, metavar="N",
                       help="fixed number of time elements (experts; default: what --rtol needs)")
    scene.add_argument("--hold", choices=("zoh", "foh", "magnus2"), help="= --method for the exponential holds")
    scene.add_argument("--effects", type=_effects_arg, metavar="E1,E2,...",
                       help="effects to simulate, comma-separated, or 'all' (kedfem list)")
    scene.add_argument("--trust", action="append", metavar="FILE|FOLDER|MODULE",
                       help="let the scene file run the builder code it names when that code lies in this .py "
                       "file, folder (a scene file: its folder) or module (repeatable); without it a scene names "
                       "catalogue mechanisms only. A builder given as SCENE itself is trusted.")

    p = argparse.ArgumentParser(
        prog="kedfem", description="Kineto-ElastoDynamics of planar elastic linkages: periodic steady-state "
        "elastic response by the state-space closed-form method.",
        epilog="With no command, 'kedfem' runs 'kedfem run'. Errors exit with status 2.")
    p.add_argument("--version", action="version", version=f"kedfem {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    r = sub.add_parser("run", parents=[common, scene], help="solve a scene, print a summary, write outputs",
                       description="Solve a scene and write CSV, NPZ, plots and a VTK series. Without SCENE, "
                       "runs the built-in default scene (mould oscillator, paper section 5).")
    r.add_argument("--no-plots", action="store_true", help="do not write PNG plots")
    r.add_argument("--no-vtk", action="store_true", help="do not write the VTK series")
    r.add_argument("--no-csv", action="store_true", help="do not write CSV tables")
    r.add_argument("--no-npz", action="store_true", help="do not write result.npz")
    r.add_argument("--render", action="store_true", help="also render deformed.png with pyvista (off-screen)")
    r.add_argument("--no-render", action="store_true", help="do not render even if the scene file asks")
    r.add_argument("--scale", type=_positive_float, metavar="S", help="VTK deformation scale (default: auto)")
    r.add_argument("--every", type=_int_range(1, 10**6), metavar="K", help="write every K-th time node to VTK")
    r.add_argument("--modes", type=_int_range(0, 24), metavar="N", help="mode shapes to export (0: none)")
    r.add_argument("--n-modes", type=_int_range(1, 24), default=4, metavar="N",
                   help="natural frequencies reported (default 4)")
    r.add_argument("--dofs", metavar="L1,L2", help="DOF labels for the displacement plot")
    r.add_argument("--no-mesh-check", action="store_true",
                   help="do not estimate the mesh error (a second solve with half the elements per link)")
    r.add_argument("--strict", action="store_true",
                   help=f"exit with status {EXIT_STRICT} if the iteration did not converge, the response is "
                   "unstable, the estimated error exceeds the tolerance, a link leaves linear theory "
                   "(deflection, yield) or a safety factor (yield, Goodman, Soderberg) is below 1")
    r.set_defaults(func=commands["run"])

    v = sub.add_parser("validate", parents=[common], help="Table 3 and a modal-superposition check",
                       description="Reproduce the paper's Table 3 (mould oscillator, four crank groups) and "
                       "check the periodic solver against modal superposition on the exciter.")
    v.add_argument("--steps", type=_steps_arg, metavar="N",
                   help="fixed time elements for Table 3 and of the foh check (default: tolerance-driven; 180)")
    v.add_argument("--skip-table3", action="store_true", help="only the modal-superposition check")
    v.add_argument("--tol", type=_positive_float, default=1e-6, help="pass threshold of the response check")
    v.set_defaults(func=commands["validate"])

    s = sub.add_parser("sweep", parents=[common, scene], help="parameter sweep on a process pool or Dask",
                       description="Solve a grid of scenes in parallel and write a tidy CSV table and a peak "
                       "stress plot. Axes: --param KEY=V1,V2,... or KEY=START:STOP:NUM (repeatable), where KEY "
                       "is a scene-file key: speed_rpm, steps, hold, mechanism.<parameter>, damping.<key>, "
                       "solver.<key>; plus the [sweep] table of a scene file.")
    s.add_argument("--param", action="append", metavar="KEY=VALUES", help="a sweep axis (repeatable)")
    s.add_argument("--scheduler", default="processes", metavar="WHERE",
                   help="processes (default), serial, local (Dask LocalCluster) or a Dask address tcp://host:port")
    s.add_argument("--workers", type=_int_range(1, 1024), metavar="N", help="workers to start (default: CPUs)")
    s.add_argument("--x", metavar="KEY", help="axis on the plot's x axis (default speed_rpm or the first numeric)")
    s.add_argument("--no-plots", action="store_true", help="no plot")
    s.add_argument("--no-frequencies", action="store_true", help="skip the fundamental frequency of each point")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    s.add_argument("--resume", action="store_true",
                   help="continue an interrupted sweep from its partial table OUT.partial.csv (the points in it "
                        "are not solved again; its failed points are)")
    s.set_defaults(func=commands["sweep"])

    e = sub.add_parser("export", parents=[common, scene], help="VTK/PVD series for ParaView, optional PNG render",
                       description="Solve a scene and write the deformed mechanism over the cycle as a .pvd "
                       "collection of .vtu files, its mode shapes, and with --render a PNG (pyvista, off-screen).")
    e.add_argument("--scale", type=_positive_float, metavar="S", help="deformation scale (default: auto)")
    e.add_argument("--every", type=_int_range(1, 10**6), metavar="K", help="write every K-th time node")
    e.add_argument("--modes", type=_int_range(0, 24), metavar="N", help="mode shapes to export (0: none)")
    e.add_argument("--render", action="store_true", help="render deformed.png off-screen")
    e.add_argument("--frame", type=_int_range(0, 10**6), metavar="K",
                   help="written frame to render (default: largest displacement)")
    e.add_argument("--animate", nargs="?", const="cycle.gif", metavar="PATH",
                   help="also write the deformed cycle as an animated GIF (off-screen, at most 60 frames, "
                        "one colour range); PATH: a .gif file name in the output folder (default cycle.gif)")
    e.set_defaults(func=commands["export"])

    c = sub.add_parser("campbell", parents=[common, scene], help="Campbell diagram: frequency bands vs speed, resonances",
                       description="Natural-frequency bands over the cycle (min, mean, max per mode) at each speed "
                       "against the harmonics k x crank frequency; lists where a harmonic crosses a band and writes "
                       "campbell.csv, campbell_crossings.csv and campbell.png.")
    c.add_argument("--speeds", required=True, metavar="START:STOP:NUM",
                   help="crank speeds [rev/min]: START:STOP:NUM or V1,V2,...")
    c.add_argument("--n-modes", type=_int_range(1, 24), default=4, metavar="N", help="modes (default 4)")
    c.add_argument("--harmonics", type=_int_range(1, 100), default=6, metavar="K", help="harmonic lines (default 6)")
    c.add_argument("--nodes", type=_int_range(3, 100_000), default=36, metavar="N",
                   help="crank positions per cycle (default 36)")
    c.add_argument("--from-solve", action="store_true",
                   help="frequencies of a periodic solve per speed (default: modal analysis on the rigid-body motion)")
    c.add_argument("--no-plots", action="store_true", help="no plot")
    c.set_defaults(func=commands["campbell"])

    k = sub.add_parser("critical", parents=[common, scene], help="critical speed: onset of instability or buckling",
                       description="Bracket and refine the speed where the largest Floquet multiplier crosses 1 "
                       "(parametric) or the lowest modal eigenvalue over the cycle crosses 0 (buckling). Exit 1 if "
                       "the tolerance was not met within --max-solves.")
    k.add_argument("--lo", type=_positive_float, required=True, metavar="RPM", help="lower end of the bracket [rev/min]")
    k.add_argument("--hi", type=_positive_float, required=True, metavar="RPM", help="upper end of the bracket [rev/min]")
    k.add_argument("--kind", choices=("parametric", "buckling"), default="parametric",
                   help="parametric: the largest Floquet multiplier crosses 1; buckling: the lowest stiffness "
                   "eigenvalue over the cycle crosses 0 (default parametric)")
    k.add_argument("--tol", type=_rtol_arg, default=5e-3, metavar="TOL",
                   help="relative tolerance on the critical speed (default 5e-3)")
    k.add_argument("--scan", type=_int_range(0, 1000), default=0, metavar="N",
                   help="speeds scanned upward inside the bracket first (finds the lowest crossing)")
    k.add_argument("--max-solves", type=_int_range(3, 1000), default=14, metavar="N", help="most solves (default 14)")
    k.add_argument("--linear", action="store_true",
                   help="ask the linearised equations (geometric_nonlinearity -> axial_stiffening; default: the "
                   "scene's own effects, the stability of the non-linear orbit)")
    k.set_defaults(func=commands["critical"])

    m = sub.add_parser("stability-map", parents=[common, scene], help="spectral radius over speed x a parameter",
                       description="The largest Floquet multiplier over a grid of crank speed x one scene key, "
                       "solved in parallel; writes stability_map.csv and stability_map.png (unstable region "
                       "hatched, the rho = 1 contour).")
    m.add_argument("--speeds", required=True, metavar="START:STOP:NUM", help="crank speeds [rev/min]")
    m.add_argument("--param", required=True, metavar="KEY=VALUES",
                   help="the other axis: a scene key and its values (mechanism.coupler_EI=0.3:2.4:8, damping.zeta=...)")
    m.add_argument("--scheduler", default="processes", metavar="WHERE",
                   help="processes (default), serial, local (Dask LocalCluster) or a Dask address tcp://host:port")
    m.add_argument("--workers", type=_int_range(1, 1024), metavar="N", help="workers to start (default: CPUs)")
    m.add_argument("--no-plots", action="store_true", help="no plot")
    m.add_argument("--no-progress", action="store_true", help="no progress bar")
    m.set_defaults(func=commands["stability-map"])

    co = sub.add_parser("continuation", parents=[common, scene],
                        help="the periodic response followed over speed: folds, stability, bifurcations",
                        description="Follow the periodic response from LO to HI rev/min by pseudo-arclength continuation "
                        "(through folds of the response curve), with each point's Floquet multipliers and peaks; locate "
                        "and classify where the stability changes (fold, flip, Neimark-Sacker); past a flip, the "
                        "period-2 response. Writes branch.csv, branch_bifurcations.csv and response_curve.png.")
    co.add_argument("--speeds", required=True, metavar="LO:HI", help="speed range [rev/min]; the branch starts at LO")
    co.add_argument("--no-errors", action="store_true", help="skip each point's time-discretisation error estimate")
    co.add_argument("--no-period2", action="store_true", help="do not compute the period-2 response past a flip")
    co.add_argument("--max-points", type=_int_range(3, 5000), default=300, metavar="N", help="most points (default 300)")
    co.add_argument("--no-plots", action="store_true", help="no plot")
    co.add_argument("--no-progress", action="store_true", help="no progress bar")
    co.set_defaults(func=commands["continuation"])

    li = sub.add_parser("list", parents=[common], help="mechanisms, their parameters, and effects",
                        description="List the mechanisms with their parameters and preset scenes, and the effects.")
    li.set_defaults(func=commands["list"])
    return p
