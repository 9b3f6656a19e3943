"""A result's report: its summary table and its files, written into a folder published whole.

What ``kedfem run`` writes, and what :meth:`kedfem.analysis.results.PeriodicResult.write` writes for
a result made in Python: ``summary.txt`` (the table :func:`format_summary` makes), CSV, NPZ,
plots, VTK series, a render, and the fatigue table and histories
(:mod:`kedfem.io.fatigue_files`). Files are staged and published as one folder
(:class:`kedfem.io.outdir.RunFolder`): a failure leaves the previous folder as it was.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import time
from pathlib import Path

import numpy as np

from .. import __version__
from .digits import UNKNOWN_DIGITS, significant_digits
from ..errors import InputError
from ..motion.crank import crank_angle_convention, crank_angle_label
from .fatigue_files import write_fatigue_csv, write_histories
from .loads_files import plot_loads, write_loads_csv
from .outdir import MANIFEST, RunFolder, check_replaceable

__all__ = ["Stages", "Report", "format_summary", "write_outputs", "write_result", "check_out_dir", "relative"]


def relative(p: Path, base: Path) -> str:
    try:
        return str(Path(p).relative_to(base))
    except ValueError:
        return str(p)



@dataclasses.dataclass
class Stages:
    """Wall time [s] per named stage: ``with stages("csv"): ...`` adds to ``times["csv"]``."""

    times: dict = dataclasses.field(default_factory=dict)

    @contextlib.contextmanager
    def __call__(self, name):
        t = time.perf_counter()
        try:
            yield
        finally:
            self.times[name] = self.times.get(name, 0.0) + time.perf_counter() - t


def _angle(a: float) -> str:
    return f"{math.degrees(a) % 360:7.1f}" if math.isfinite(a) else "      -"


def _larger(time_error, mesh_error):
    """The error a peak's digits follow: its time error, or the mesh error where that is larger
    (None without a time estimate: a mesh check alone does not bound the peak)."""
    if time_error is None or not math.isfinite(time_error):
        return None
    return max(time_error, mesh_error) if mesh_error is not None and math.isfinite(mesh_error) else time_error


def _members_text(mech) -> str:
    """Which members are flexible (with their elements) and which rigid: a rigid and a stiff flexible
    member answer differently (a Whitworth's ram, 10 % in its elastic displacement)."""
    flex = [f"{lk.name} ({lk.elements} el.)" for lk in mech.flexible_links]
    rigid = [n for n, lk in mech.links.items() if lk.rigid] + list(mech.bodies)
    parts = [f"flexible: {', '.join(flex)}" if flex else "flexible: none"]
    if rigid:
        parts.append(f"rigid: {', '.join(rigid)}")
    return "; ".join(parts)


def format_summary(res, freqs, peaks, *, stages: dict, files: list[Path], out_dir: Path | None,
                   source: str, scene_time: float, mesh=None, fatigue=None, loads=None,
                   mesh_note: str = "") -> str:
    """The summary table of a result (what ``kedfem run`` prints and writes to ``summary.txt``)."""
    from .scenefile import scene_summary
    sc = res.scene
    info = scene_summary(sc)
    L = []
    L.append(f"kedfem {__version__}: {sc.name or sc.mech.name}  [{source}]")
    L.append(f"  mechanism   {info['mechanism']}: {res.model.n_dof} elastic DOFs; {_members_text(sc.mech)}")
    L.append(f"  speed       {info['speed']}")
    how = (f"tolerance {sc.rtol:g} on the peaks" if sc.steps is None else "steps given")
    L.append(f"  solver      {res.scheme}, {res.elements} time elements ({how}), "
             f"{'iterated (' + sc.nonlinear_method + ')' if sc.state_dependent else 'linear'}, "
             f"cyclic system by {res.method}")
    L.append(f"  effects     {info['effects']}")
    L.append(f"  damping     {info['damping']}")
    L.append("")
    L.append("natural frequencies over the cycle [Hz]      mean       min       max")
    for j in range(freqs.modal.shape[1]):
        for kind, arr in (("state-space", freqs.state_space[:, j]), ("modal", freqs.modal[:, j])):
            a = arr[np.isfinite(arr)]
            if a.size:
                L.append(f"  mode {j + 1}  {kind:<29s} {a.mean():9.3f} {a.min():9.3f} {a.max():9.3f}")
            else:
                L.append(f"  mode {j + 1}  {kind:<29s}         -         -         -")
    buckled = np.asarray(freqs.modal) < 0
    if buckled.any():
        share = 100.0 * float(buckled.any(axis=1).mean())
        if "geometric_nonlinearity" in sc.effects:
            # (a new user's Watt six-bar at 2000 rpm, converged and stable under geometric_nonlinearity,
            # read "the linear response there is not what the linkage does" and did not know what to believe)
            L.append(f"  BUCKLED (frozen in time): the tangent stiffness at the response has a negative eigenvalue "
                     f"(shown as a negative modal frequency) over {share:.3g} % of the cycle; the linkage runs "
                     f"post-buckled there, its large deflections carried by geometric_nonlinearity; whether the "
                     f"response holds over the cycle is the Floquet stability below")
        else:
            L.append(f"  BUCKLED: a negative stiffness eigenvalue (shown as a negative modal frequency) over "
                     f"{share:.3g} % of the cycle; the linear response there is not what the linkage does "
                     f"(geometric_nonlinearity follows it past buckling)")
    L.append("")
    err = res.error
    if peaks:
        L.append("peak response per flexible link (+- estimated time-discretisation error)")
        L.append(f"  {'link':<16s} {'deflection [mm]':>15s} {'+-':>7s} {'at [deg]':>8s} {'stress [MPa]':>12s} "
                 f"{'+-':>7s} {'at [deg]':>8s} {'station [mm]':>12s}")

        def pm(x):
            return f"{x:7.1e}" if x is not None else f"{'-':>7s}"

        for p in peaks:
            e = err.link(p.link) if err is not None else None
            me = next((x for x in mesh.links if x.link == p.link), None) if mesh is not None else None
            nd = significant_digits(_larger(e and e.deflection, me and me.deflection))  # digits its error allows
            ns = significant_digits(_larger(e and e.stress, me and me.stress))
            st = f"{p.stress / 1e6:12.{ns}g}" if math.isfinite(p.stress) else f"{'n/a (no c)':>12s}"
            ss = f"{p.stress_station * 1e3:12.2f}" if math.isfinite(p.stress_station) else f"{'-':>12s}"
            de = pm(e.deflection) if e else pm(None)
            se = pm(e.stress) if (e and math.isfinite(p.stress)) else pm(None)
            L.append(f"  {p.link:<16s} {p.deflection * 1e3:15.{nd}g} {de} {_angle(p.deflection_angle):>8s} {st} "
                     f"{se} {_angle(p.stress_angle):>8s} {ss}")
        inner = any(lk.through for lk in res.model.mech.flexible_links)
        L.append("  (deflection: mid-span, relative to the chord" + (" (of each stretch between the pins inside a link, "
                 "the largest)" if inner else "") + "; stress: max |N|/A + |M| c/I; digits: down to a")
        L.append(f"   tenth of the time error (or the mesh error where checked and larger), {UNKNOWN_DIGITS} where "
                 "the time error is not estimated;")
        L.append(f"   angles: {crank_angle_convention(res.model.mech)}; +-: estimated relative error of the peak)")
        if err is not None:
            L.append(f"  time-discretisation error: {err.describe()}")
        else:
            why = ("estimate = false" if not res.scene.estimate
                   else f"{res.elements} time elements given: no coarser level to compare with")
            L.append(f"  time-discretisation error: not estimated ({why})")
        if mesh is not None:
            L.append(f"  mesh error (not in the +- columns): {mesh.describe()}")
            for e in mesh.links:
                if e.deflection is not None:
                    st = f", stress {e.stress:.1e}" if e.stress is not None else ""
                    L.append(f"    {e.link:<16s} deflection {e.deflection:.1e}{st}")
        else:
            L.append(f"  mesh error: not estimated ({mesh_note or 'no mesh check here: kf.mesh_error(res) makes one'})")
    else:
        L.append("peak response: no flexible links")
    history = significant_digits(err.history if err is not None else None, 4)  # loads and fatigue ride on it
    if loads is not None:
        L.append("")
        L.extend(loads.summary(digits=history).splitlines())
    if fatigue is not None and fatigue.links:
        L.append("")
        L.append("fatigue (signed fibre stress N/A -+ M c/I over the cycle; fatigue.csv per station)")
        for lf in fatigue.links:
            L.append(f"  {lf.describe(digits=history)}")
    L.append("")
    mu = np.abs(np.asarray(res.floquet_multipliers))
    rho = float(mu.max()) if mu.size else float("nan")
    if res.stability is not None:
        L.append(f"Floquet stability   {res.stability.describe()}")
    else:
        L.append(f"Floquet stability   spectral radius {rho:.6g} -> {'stable' if res.stable else 'UNSTABLE'}")
    if sc.state_dependent:
        last = f", last change {res.history[-1]:.2e}" if res.history else ""
        if res.history and res.predicted_change is not None:
            last += f", the next predicted below {res.predicted_change:.1e} by Newton's rate"
        L.append(f"iteration           {res.iterations} linear solves ({sc.nonlinear_method}), converged: "
                 f"{'yes' if res.converged else 'NO'} (eps {sc.eps:g}{last})")
        if res.path:
            L.append(f"                    {res.path}")
    else:
        L.append("iteration           none needed (linear scene): 1 periodic solve")
    L.append(f"residual            {res.residual:.3e} (relative, block-cyclic system)")
    tm = res.timings
    parts = [f"solve {tm.total:.2f} (kinematics {tm.kinematics:.2f}, assembly {tm.assembly:.2f}, "
             f"periodic solves {tm.solve:.2f}" + (f"; forecast {tm.forecast:.2f} after its second level)"
                                                  if tm.forecast is not None else ")")]
    parts += [f"{k} {v:.2f}" for k, v in stages.items()]
    L.append(f"wall time [s]       {', '.join(parts)}; total {scene_time:.2f}")
    if files:
        L.append(f"files in {out_dir}/")
        for f in files:
            L.append(f"  {relative(f, out_dir)}")
    else:
        L.append("files               none written")
    return "\n".join(L)


def write_outputs(res, freqs, peaks, out_dir: Path, stage: Stages, *, plots: bool, csv: bool,
                  npz: bool, vtk: bool, render: bool, modes: int, scale, every: int, dofs,
                  mesh=None, fatigue=None, loads=None) -> list[Path]:
    """Write the files of a result into ``out_dir`` (a staging folder); return them.

    CSV (``response.csv``, ``peaks.csv``, ``frequencies.csv``, and with a fatigue table
    ``fatigue.csv`` and the tidy ``histories.csv``), NPZ (``result.npz``, ``histories.npz``),
    PNG plots, a VTK series with mode shapes, and a PNG render.
    """
    from . import export
    files: list[Path] = []
    out_dir.mkdir(parents=True, exist_ok=True)
    if csv:
        with stage("csv"):
            files.append(export.write_response_csv(res, out_dir / "response.csv"))
            files.append(export.write_peaks_csv(res, out_dir / "peaks.csv", peaks, mesh=mesh))
            files.append(export.write_frequencies_csv(freqs, out_dir / "frequencies.csv"))
            if fatigue is not None and fatigue.links:
                files.append(write_fatigue_csv(fatigue, out_dir / "fatigue.csv"))
            if loads is not None:
                files.append(write_loads_csv(loads, out_dir / "loads.csv"))
    if fatigue is not None and fatigue.links and (csv or npz):
        with stage("histories"):
            files.extend(write_histories(res, out_dir / "histories.csv" if csv else None,
                                         out_dir / "histories.npz" if npz else None))
    if npz:
        with stage("npz"):
            files.append(export.write_npz(res, out_dir / "result.npz", freqs))
    if plots:
        from . import plots as pl
        with stage("plots"):
            files.extend(pl.all_plots(res, out_dir, freqs, dofs or None))
            if loads is not None:
                files.append(plot_loads(loads, out_dir / "loads.png", angle_label=crank_angle_label(res.model.mech)))
    series = None
    if vtk or render:
        with stage("vtk"):
            series = export.write_vtk_series(res, out_dir, scale=scale, every=every)
            files.append(series.pvd)
            if modes:
                files.append(export.write_mode_shapes(res, out_dir, n_modes=modes).pvd)
    if render:
        from . import render as rd
        with stage("render"):
            files.append(rd.render_series(series, out_dir / "deformed.png"))
    return files


def check_out_dir(out_dir: Path, label: str = "output folder") -> None:
    """An output folder that cannot be written is an input error before any work (a file is
    created and removed in the nearest existing folder above it, where the run's staging folder
    goes: permissions alone do not tell, e.g. in /proc). Not in the output folder itself: a run
    killed between the two left the probe in the last run's published folder (a kill test), and
    beside it the probe is named as a leftover that :func:`kedfem.io.outdir.clean_leftovers` removes."""
    import tempfile
    p = Path(out_dir).absolute()
    if p.exists() and not p.is_dir():
        raise InputError(f"{label} {out_dir}: {p} is a file, not a folder")
    probe = p.parent
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise InputError(f"{label} {out_dir}: {probe} is a file, not a folder")
    if probe.exists() and not os.access(probe, os.W_OK | os.X_OK):
        raise InputError(f"{label} {out_dir}: folder {probe} is not writable")
    try:
        fd, name = tempfile.mkstemp(prefix=f".{p.name}.probe-{os.getpid()}-", dir=probe)
        os.close(fd)
        os.unlink(name)
    except OSError as e:
        raise InputError(f"{label} {out_dir}: cannot write in {probe} ({e.strerror or e})") from None


@dataclasses.dataclass(frozen=True)
class Report:
    """What :func:`write_result` wrote.

    Attributes
    ----------
    folder : Path
    files : tuple of Path
        Every file written, in the published folder.
    summary : str
        The summary table (also in ``summary.txt``).
    run_id : str
        The run's id in the folder's manifest.
    """

    folder: Path
    files: tuple[Path, ...]
    summary: str
    run_id: str


def write_result(res, out_dir, *, plots: bool = True, csv: bool = True, npz: bool = True, vtk: bool = True,
                 render: bool = False, modes: int = 4, scale=None, every: int = 1, dofs=(),
                 n_modes: int = 4, mesh_check: bool = True, fatigue: bool = True, loads: bool = True,
                 source: str = "python", command: str = "write", started: float | None = None) -> Report:
    """Write everything ``kedfem run`` writes for ``res`` into the folder ``out_dir``.

    Parameters
    ----------
    res : kedfem.analysis.results.PeriodicResult
    out_dir : path
        The folder; replaced whole (a folder kedfem did not write is refused).
    plots, csv, npz, vtk, render : bool
        Which kinds of files.
    modes : int
        Mode shapes in the VTK series (0: none).
    scale : float, optional
        Deformation scale of the VTK series (default: automatic).
    every : int
        Every how many instants a VTK frame is written.
    dofs : sequence of str
        DOF labels to plot.
    n_modes : int
        Natural frequencies over the cycle in the summary.
    mesh_check : bool
        Estimate the mesh error (one more solve on another mesh), as ``kedfem run`` does.
    fatigue : bool
        The fatigue table and the stress histories.
    loads : bool
        Bearing forces and drive torques (``loads.csv``, ``loads.png``, the summary).
    source : str
        Where the scene came from, for the summary.
    command : str
        Recorded in the folder's manifest.
    started : float, optional
        ``time.perf_counter()`` when the work began, for the wall time.

    Returns
    -------
    Report
    """
    t0 = time.perf_counter() if started is None else started
    out_dir = Path(out_dir)
    check_out_dir(out_dir)
    check_replaceable(out_dir)
    for d in dofs:
        res.model.dof_index(d, owner="plot: ")
    stage = Stages()
    with stage("frequencies"):
        # about 2 degrees of crank: the modes vary smoothly over the cycle
        freqs = res.frequencies(n_modes, nodes=list(range(0, res.n, max(1, res.n // 180))))
    with stage("peaks"):
        peaks = res.peaks()
    table = None
    if fatigue:
        from ..analysis.fatigue import fatigue_table
        with stage("fatigue"):
            table = fatigue_table(res)
    machine = None
    if loads:
        with stage("loads"):
            machine = res.loads()
    mesh = res._cache.get("mesh_error")  # one the user made (kf.mesh_error(res)), as res.summary() shows it
    mesh_note = "mesh check off: --no-mesh-check, mesh_check=False"
    if mesh_check:
        from ..analysis.mesh_check import mesh_error
        with stage("mesh check"):
            mesh = mesh_error(res)
        mesh_note = "the comparison mesh's solve failed: see the warning above"
    with RunFolder(out_dir, command, dict(scene=source, crank_angle=crank_angle_convention(res.model.mech))) as rf:
        staged = write_outputs(res, freqs, peaks, rf.path, stage, plots=plots, csv=csv, npz=npz, vtk=vtk,
                               render=render, modes=modes, scale=scale, every=every, dofs=tuple(dofs),
                               mesh=mesh, fatigue=table, loads=machine)
        files = [out_dir / Path(f).relative_to(rf.path) for f in staged]
        text = format_summary(res, freqs, peaks, stages=stage.times, files=files, out_dir=out_dir,
                              source=source, scene_time=time.perf_counter() - t0, mesh=mesh, fatigue=table,
                              loads=machine, mesh_note=mesh_note)
        text += f"\n  summary.txt\n  {MANIFEST} (run {rf.run_id})"
        (rf.path / "summary.txt").write_text(text + "\n")
    return Report(out_dir, tuple(files) + (out_dir / "summary.txt",), text, rf.run_id)
