"""Plots of periodic results and sweeps (matplotlib, files only).

matplotlib is imported lazily and used through its object-oriented API
(:class:`matplotlib.figure.Figure` rendered by the Agg canvas), never
through ``pyplot``: no window is opened, no global backend is switched, and
the functions work on machines without a display. Every function writes one
PNG (atomically) and returns its path. Axes are labelled with SI units;
crank angles are shown in degrees (accepted for use with the SI) like the
paper's figures.

* :func:`displacement` - elastic displacement of chosen DOFs vs crank angle (paper Fig. 2);
* :func:`link_response` - mid-span deflection and peak dynamic stress of each flexible link;
* :func:`frequencies` - natural frequencies vs crank angle (modal and state-space);
* :func:`floquet` - Floquet multipliers and the unit circle;
* :func:`sweep_peaks` - peak stress vs speed from a sweep table (paper Figs. 3-4);
* :func:`accuracy_vs_cost` - error vs wall time, one curve per knob, log-log (benchmarks).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..errors import InputError
from ..motion.crank import crank_angle_label
from .export import atomic_path, dof_unit, require

__all__ = ["displacement", "link_response", "frequencies", "floquet", "sweep_peaks", "accuracy_vs_cost",
           "columns", "all_plots"]

log = logging.getLogger(__name__)

DPI = 120


def _figure(nrows=1, ncols=1, figsize=(8.0, 4.5), **kw):
    require("matplotlib", None, "plotting")
    from matplotlib.figure import Figure
    fig = Figure(figsize=figsize, layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return fig, axes


def _save(fig, path) -> Path:
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt, dpi=DPI)
    log.info("wrote %s", path)
    return path


def _deg(a):
    return np.degrees(np.asarray(a, float))


def _angle_axis(ax, mech=None):
    ax.set_xlabel(crank_angle_label(mech))
    ax.set_xlim(0, 360)
    ax.set_xticks(np.arange(0, 361, 60))
    ax.grid(True, alpha=0.3)


def _cycle_deg(crank_angle):
    """The crank angle as the tables give it (absolute, in 0..360 deg), sorted, and the order.

    Returns ``x`` (n + 1,) increasing from the smallest angle to that angle +
    360 deg (the response is periodic: the curve closes on its first value)
    and the permutation ``order`` (n,) that :func:`_closed` applies to the
    values, so that a peak sits at the angle ``peaks()`` and the CSV files
    report whatever the reference configuration's crank angle.
    """
    a = np.mod(_deg(np.asarray(crank_angle, float)), 360.0)
    order = np.argsort(a, kind="stable")
    x = a[order]
    return np.append(x, x[0] + 360.0), order


def _closed(y, order):
    """The values in the order of :func:`_cycle_deg`, closed on the first."""
    y = np.asarray(y)[order]
    return np.concatenate([y, y[:1]], axis=0)


# -------------------------------------------------------------- result plots
def auto_dofs(res, n: int = 4) -> tuple[str, ...]:
    """The ``n`` translational DOFs with the largest amplitude over the cycle."""
    labels = [d for d in res.dof_labels if dof_unit(d) == "m"]
    if not labels:
        return tuple(res.dof_labels[:n])
    idx = [res.dof_labels.index(d) for d in labels]
    amp = np.ptp(res.U[:, idx], axis=0)
    order = np.argsort(-amp, kind="stable")[:n]
    return tuple(labels[i] for i in order)


def displacement(res, path, dofs: Sequence[str] | None = None) -> Path:
    """Elastic displacement of chosen DOFs vs crank angle (like the paper's Fig. 2).

    Parameters
    ----------
    res : PeriodicResult
    path : str or Path
        PNG file.
    dofs : sequence of str, optional
        DOF labels (:attr:`PeriodicResult.dof_labels`); default the four
        translations with the largest amplitude. Translations [m] and
        rotations [rad] go to separate axes.
    """
    dofs = tuple(dofs) if dofs else auto_dofs(res)
    for d in dofs:
        res.model.dof_index(d, owner="plot: ")
    groups = [(u, [d for d in dofs if dof_unit(d) == u]) for u in ("m", "rad")]
    groups = [g for g in groups if g[1]]
    fig, axes = _figure(len(groups), 1, figsize=(8.0, 3.6 * len(groups)), sharex=True)
    x, order = _cycle_deg(res.crank_angle)
    for ax, (unit, labels) in zip(axes[:, 0], groups):
        for d in labels:
            ax.plot(x, _closed(res.dof(d), order), label=d)
        ax.set_ylabel(f"elastic {'displacement' if unit == 'm' else 'rotation'} [{unit}]")
        ax.legend(fontsize="small", loc="best")
        _angle_axis(ax, res.model.mech)
    axes[0, 0].set_title(f"{_title(res)}: elastic displacements")
    return _save(fig, path)


def _title(res) -> str:
    return getattr(res.scene, "name", "") or res.model.mech.name


#: line styles of the stretches of a link through joints (one colour per link)
STRETCH_STYLES = ("-", "--", ":", "-.")


def link_response(res, path, links: Sequence[str] | None = None) -> Path:
    """Mid-span deflection (relative to the chord) and dynamic stress of flexible links vs crank angle.

    The stress panel shows, at each crank angle, the largest ``|N|/A + |M| c/I``
    along the link (links whose section has no ``c`` are left out of it).
    """
    flex = [lk.name for lk in res.model.mech.flexible_links]
    links = list(links) if links else flex
    for lk in links:
        if lk not in flex:
            raise InputError(f"plot: {lk!r} is not a flexible link (flexible links: {', '.join(flex)})")
    fig, axes = _figure(2, 1, figsize=(8.0, 7.0), sharex=True)
    x, order = _cycle_deg(res.crank_angle)
    mech = res.model.mech
    any_stress = False
    for i, lk in enumerate(links):
        # a link's colour in both panels (each panel's own cycle gave a link through joints one per
        # stretch above and one below: a new user's six-bar had its coupler in two colours)
        colour = f"C{i % 10}"
        stretches = mech.links[lk].stretches
        d = res.stretch_deflections(lk)
        for k, (ja, jb) in enumerate(stretches):  # a link through joints: each stretch from its chord
            axes[0, 0].plot(x, _closed(1e3 * d[:, k], order), color=colour, linestyle=STRETCH_STYLES[k % 4],
                            label=lk if len(stretches) == 1 else f"{lk} {ja}-{jb}")
        if mech.links[lk].section.c is not None:
            axes[1, 0].plot(x, _closed(1e-6 * res.stress(lk).max(axis=1), order), color=colour, label=lk)
            any_stress = True
    # in the summary's units (a new user read metres and pascals beside its mm and MPa)
    axes[0, 0].set_ylabel("mid-span deflection [mm]")
    axes[0, 0].set_title(f"{_title(res)}: link deflection and dynamic stress")
    axes[0, 0].legend(fontsize="small")
    axes[1, 0].set_ylabel("max. normal stress along link [MPa]")
    if any_stress:
        axes[1, 0].legend(fontsize="small")
    else:
        axes[1, 0].text(0.5, 0.5, "no section with an extreme-fibre distance c", ha="center",
                        transform=axes[1, 0].transAxes)
    for ax in axes[:, 0]:
        _angle_axis(ax, res.model.mech)
    return _save(fig, path)


def frequencies(freqs, path, title: str = "", mech=None) -> Path:
    """Natural frequencies vs crank angle: modal (solid) and state-space (dashed).

    Parameters
    ----------
    freqs : Frequencies
        From :meth:`PeriodicResult.frequencies`.
    path : str or Path
        PNG file.
    title : str
        Title prefix.
    mech : Mechanism, optional
        Names the crank angle's convention on the axis.
    """
    fig, axes = _figure()
    ax = axes[0, 0]
    x, order = _cycle_deg(freqs.crank_angle)
    for j in range(freqs.modal.shape[1]):
        line, = ax.plot(x, _closed(freqs.modal[:, j], order), label=f"mode {j + 1}, modal")
        ax.plot(x, _closed(freqs.state_space[:, j], order), "--", color=line.get_color(),
                label=f"mode {j + 1}, state-space")
    ax.set_ylabel("natural frequency [Hz]")
    ax.set_title(f"{title + ': ' if title else ''}natural frequencies over the cycle")
    ax.legend(fontsize="x-small", ncol=2)
    _angle_axis(ax, mech)
    return _save(fig, path)


def floquet(res, path) -> Path:
    """Floquet multipliers (eigenvalues of the monodromy matrix) with the unit circle."""
    fig, axes = _figure(figsize=(5.5, 5.5))
    ax = axes[0, 0]
    th = np.linspace(0, 2 * math.pi, 361)
    ax.plot(np.cos(th), np.sin(th), "k-", lw=0.8, label="unit circle")
    mu = np.asarray(res.floquet_multipliers)
    rho = float(np.max(np.abs(mu))) if mu.size else float("nan")
    ax.plot(mu.real, mu.imag, "o", ms=4, mfc="none", label="multipliers")
    ax.set_aspect("equal")
    lim = max(1.1, 1.05 * rho if math.isfinite(rho) else 1.1)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_xlabel("Re(mu) [-]")
    ax.set_ylabel("Im(mu) [-]")
    ax.grid(True, alpha=0.3)
    ax.set_title(f"Floquet multipliers: spectral radius {rho:.4g} ({'stable' if res.stable else 'UNSTABLE'})")
    ax.legend(fontsize="small", loc="lower left")
    return _save(fig, path)


def all_plots(res, out_dir, freqs=None, dofs: Sequence[str] | None = None) -> list[Path]:
    """Write every result plot into ``out_dir``; returns the paths."""
    out = Path(out_dir)
    paths = [displacement(res, out / "displacement.png", dofs)]
    if res.model.mech.flexible_links:
        paths.append(link_response(res, out / "link_response.png"))
    if freqs is not None:
        paths.append(frequencies(freqs, out / "frequencies.png", _title(res), res.model.mech))
    paths.append(floquet(res, out / "floquet.png"))
    return paths


# ----------------------------------------------------------- tidy tables
def columns(table) -> dict[str, np.ndarray]:
    """A tidy table as columns.

    Accepts a mapping of column name to sequence, a sequence of mappings or
    dataclass instances (one per row), or an object with a ``columns()``
    method returning such a mapping (e.g. :class:`kedfem.io.sweep.SweepTable`).
    """
    if hasattr(table, "columns") and callable(table.columns):
        table = table.columns()
    if isinstance(table, Mapping):
        cols = {str(k): np.asarray(v) for k, v in table.items()}
    else:
        rows = list(table)
        if not rows:
            return {}
        rows = [dataclasses.asdict(r) if dataclasses.is_dataclass(r) else dict(r) for r in rows]
        keys = list(dict.fromkeys(k for r in rows for k in r))
        cols = {k: np.asarray([r.get(k) for r in rows]) for k in keys}
    n = {len(v) for v in cols.values()}
    if len(n) > 1:
        raise InputError(f"table columns have different lengths: {sorted(n)}")
    return cols


def _col(cols, name, what):
    if name not in cols:
        raise InputError(f"plot: the table has no column {name!r} for {what} (columns: {', '.join(cols)})")
    return cols[name]


def _num(a) -> np.ndarray:
    out = np.full(len(a), np.nan)
    for i, v in enumerate(a):
        try:
            out[i] = float(v)
        except (TypeError, ValueError):
            pass
    return out


def _groups(cols, by: Sequence[str]):
    """Row indices of each combination of the ``by`` columns, in order of first appearance."""
    n = len(next(iter(cols.values()))) if cols else 0
    if not by:
        return [((), np.arange(n))]
    out: dict = {}
    for i in range(n):
        out.setdefault(tuple(cols[b][i].item() if hasattr(cols[b][i], "item") else cols[b][i] for b in by),
                       []).append(i)
    return [(k, np.array(v)) for k, v in out.items()]


def _label(by, key) -> str:
    return ", ".join(f"{v}" if b in ("link", "knob") else f"{b}={v}" for b, v in zip(by, key))


def sweep_peaks(table, path, x: str = "speed_rpm", y: str = "peak_stress_Pa", by: Sequence[str] = ("link",),
                xlabel: str | None = None, ylabel: str | None = None, title: str = "") -> Path:
    """Peak response vs a swept parameter, one curve per group (like the paper's Figs. 3-4).

    Parameters
    ----------
    table
        Tidy table (see :func:`columns`), e.g. :meth:`kedfem.io.sweep.SweepResult.table`.
    x, y : str
        Columns on the axes (default peak stress [Pa] vs speed [rev/min]).
    by : sequence of str
        Columns whose combinations make separate curves.
    """
    cols = columns(table)
    xv, yv = _num(_col(cols, x, "x")), _num(_col(cols, y, "y"))
    by = [b for b in by if b in cols]
    fig, axes = _figure()
    ax = axes[0, 0]
    drawn = 0
    for key, idx in _groups(cols, by):
        ok = idx[np.isfinite(xv[idx]) & np.isfinite(yv[idx])]
        if ok.size == 0:
            continue
        o = ok[np.argsort(xv[ok], kind="stable")]
        ax.plot(xv[o], yv[o], "o-", ms=4, label=_label(by, key) or y)
        drawn += 1
    units = {"speed_rpm": "speed [rev/min]", "peak_stress_Pa": "peak dynamic stress [Pa]",
             "peak_deflection_m": "peak mid-span deflection [m]", "fundamental_Hz": "fundamental frequency [Hz]"}
    ax.set_xlabel(xlabel or units.get(x, x))
    ax.set_ylabel(ylabel or units.get(y, y))
    ax.grid(True, alpha=0.3)
    ax.set_title(title or f"{units.get(y, y).split(' [')[0]} vs {units.get(x, x).split(' [')[0]}")
    if drawn:
        ax.legend(fontsize="small")
    else:
        ax.text(0.5, 0.5, "no finite points", ha="center", transform=ax.transAxes)
    return _save(fig, path)


def accuracy_vs_cost(table, path, *, error: str = "error", cost: str = "wall_time", knob: str = "knob",
                     label: str | None = None, title: str = "", xlabel: str = "wall time [s]",
                     ylabel: str = "relative error [-]") -> Path:
    """Accuracy versus cost: error vs wall time, one curve per knob value, log-log.

    Parameters
    ----------
    table
        Tidy table (see :func:`columns`): one row per run.
    path : str or Path
        PNG file.
    error, cost : str
        Columns of the error (y) and the cost (x); non-positive or non-finite
        values cannot be drawn on log axes and are skipped (logged).
    knob : str
        Column whose values make separate curves (e.g. ``"hold"``); each
        curve is drawn in order of increasing cost.
    label : str, optional
        Column annotating each point (e.g. ``"steps"``).
    """
    cols = columns(table)
    ev, cv = _num(_col(cols, error, "the error")), _num(_col(cols, cost, "the cost"))
    by = [knob] if knob in cols else []
    if knob and not by:
        raise InputError(f"plot: the table has no column {knob!r} for the knob (columns: {', '.join(cols)})")
    lab = _col(cols, label, "point labels") if label else None
    fig, axes = _figure(figsize=(7.0, 5.0))
    ax = axes[0, 0]
    skipped = 0
    drawn = 0
    for key, idx in _groups(cols, by):
        ok = idx[np.isfinite(ev[idx]) & np.isfinite(cv[idx]) & (ev[idx] > 0) & (cv[idx] > 0)]
        skipped += idx.size - ok.size
        if ok.size == 0:
            continue
        o = ok[np.argsort(cv[ok], kind="stable")]
        line, = ax.plot(cv[o], ev[o], "o-", ms=4, label=_label(by, key) or error)
        drawn += 1
        if lab is not None:
            for i in o:
                ax.annotate(str(lab[i]), (cv[i], ev[i]), textcoords="offset points", xytext=(3, 3),
                            fontsize="x-small", color=line.get_color())
    if skipped:
        log.info("accuracy_vs_cost: skipped %d point(s) that cannot be drawn on log axes", skipped)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(title or "accuracy versus cost")
    if drawn:
        ax.legend(fontsize="small", title=knob if by else None)
    return _save(fig, path)
