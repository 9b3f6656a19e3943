"""From a linkage to a design decision: Campbell diagrams, stability maps, their tables.

* :func:`campbell_chart`, :func:`write_campbell_csv`, :func:`write_crossings_csv`: the files of a
  :class:`~kedfem.analysis.campbell.CampbellResult` (its ``plot``, ``to_csv`` and
  ``crossings_to_csv`` call them);
* :func:`stability_map`: the largest Floquet multiplier modulus over a grid of crank
  speed x one scene parameter (a ``[mechanism]`` parameter such as the four-bar's
  ``mechanism.coupler_EI``, or a scene knob such as ``damping.zeta``), solved in parallel
  by :func:`kedfem.io.sweep.run_sweep`; a :class:`StabilityMap` with ``to_csv`` and
  ``plot`` (:func:`stability_chart`: speed on x, the parameter on y, colour = spectral
  radius, the unstable region hatched, the ``rho = 1`` contour).

Plots use matplotlib's object-oriented API through :mod:`kedfem.io.plots` (no pyplot,
no display); every file is written atomically and no table holds NaN (an empty cell).
"""

from __future__ import annotations

import logging
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..analysis.campbell import RPM_PER_RAD_S, check_speeds
from ..errors import InputError, PlausibilityWarning
from . import plots
from .sweep import SweepTable

__all__ = ["campbell_chart", "write_campbell_csv", "write_crossings_csv", "StabilityMap", "stability_map",
           "stability_chart", "CROSSING_COLUMNS"]

log = logging.getLogger(__name__)

#: Columns of the crossings table.
CROSSING_COLUMNS = ("mode", "harmonic", "speed_lo_rad_s", "speed_hi_rad_s", "speed_at_mean_rad_s", "speed_lo_rpm",
                    "speed_hi_rpm", "speed_at_mean_rpm", "frequency_lo_Hz", "frequency_hi_Hz", "open_lo", "open_hi")


def _table(path, names: Sequence[str], rows: Sequence[tuple]) -> Path:
    """Write a tidy table (floats with full precision, NaN as an empty cell), atomically."""
    return SweepTable(tuple(names), tuple(rows)).to_csv(path)


# ------------------------------------------------------------------ Campbell
def write_campbell_csv(res, path) -> Path:
    """Bands of a Campbell result: one row per speed and mode.

    Columns ``speed_rad_s``, ``speed_rpm``, ``crank_Hz``, ``mode``, ``f_min_Hz``, ``f_mean_Hz``,
    ``f_max_Hz``.
    """
    n, m, _ = res.bands.shape
    s = np.repeat(res.speeds, m)
    rows = zip(s.tolist(), (s * RPM_PER_RAD_S).tolist(), (s / (2 * math.pi)).tolist(), np.tile(np.arange(1, m + 1), n).tolist(),
               *res.bands.reshape(n * m, 3).T.tolist())
    return _table(path, ("speed_rad_s", "speed_rpm", "crank_Hz", "mode", "f_min_Hz", "f_mean_Hz", "f_max_Hz"),
                  list(rows))


def write_crossings_csv(res, path) -> Path:
    """Crossings of a Campbell result, one row each (:data:`CROSSING_COLUMNS`)."""
    rows = [(c.mode, c.harmonic, c.speed_lo, c.speed_hi, c.speed_mean, c.rpm_lo, c.rpm_hi, c.rpm_mean, c.frequency_lo,
             c.frequency_hi, c.open_lo, c.open_hi) for c in res.crossings]
    return _table(path, CROSSING_COLUMNS, rows)


def campbell_chart(res, path, title: str = "") -> Path:
    """Campbell diagram (PNG): frequency [Hz] vs crank speed [rpm].

    Each mode's band over the cycle is shaded (minimum to maximum) with its cycle
    mean as a line; the harmonic lines ``k f_c`` are dashed and labelled ``kx``; the
    stretches of a harmonic line inside a band are drawn thick red and the speed
    where it meets the band's mean is marked.
    """
    fig, axes = plots._figure(figsize=(8.5, 5.5))
    ax = axes[0, 0]
    rpm = res.rpm
    for j in range(res.bands.shape[1]):
        lo, mean, hi = res.bands[:, j, 0], res.bands[:, j, 1], res.bands[:, j, 2]
        color = f"C{j % 10}"
        ax.fill_between(rpm, lo, hi, color=color, alpha=0.25, lw=0)
        ax.plot(rpm, mean, color=color, lw=1.3, label=f"mode {j + 1} (cycle min/mean/max)")
    top = 1.08 * float(np.max(res.bands[:, :, 2]))
    bottom = min(0.0, 1.08 * float(np.min(res.bands[:, :, 0])))
    lines = res.harmonic_lines
    for q, k in enumerate(res.harmonics):
        ax.plot(rpm, lines[:, q], "--", color="0.45", lw=0.8)
        x_top = top / k * 60.0  # rpm where the line leaves the plot
        x, y = (x_top, top) if x_top <= rpm[-1] else (rpm[-1], lines[-1, q])
        ax.annotate(f"{k}x", (x, y), xytext=(2, -10 if x_top <= rpm[-1] else 0), textcoords="offset points",
                    fontsize="small", color="0.3")
    label = "harmonic inside a band (resonance)"
    for c in res.crossings:
        seg = np.array([c.rpm_lo, c.rpm_hi])
        ax.plot(seg, seg * c.harmonic / 60.0, "-", color="red", lw=3.0, solid_capstyle="round", label=label,
                zorder=4)
        label = None
        if math.isfinite(c.rpm_mean):
            ax.plot([c.rpm_mean], [c.rpm_mean * c.harmonic / 60.0], "o", mfc="white", mec="red", ms=5, zorder=5)
    if np.any(res.buckled):
        ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlim(rpm[0], rpm[-1])
    ax.set_ylim(bottom, top)
    ax.set_xlabel("crank speed [rev/min]")
    ax.set_ylabel("frequency [Hz]")
    ax.grid(True, alpha=0.3)
    ax.set_title(title or f"Campbell diagram: {res.name} ({res.method} analysis over {res.nodes} crank positions)",
                 fontsize="medium")
    ax.legend(fontsize="x-small", loc="upper left")
    return plots._save(fig, path)


# ------------------------------------------------------------- stability map
@dataclass(frozen=True)
class StabilityMap:
    """Largest Floquet multiplier modulus over crank speed x one scene parameter.

    Attributes
    ----------
    param : str
        The swept dotted scene key (``"mechanism.coupler_EI"``, ``"damping.zeta"``).
    values : ndarray, shape (n_values,)
        Its values (SI units of the parameter).
    speeds : ndarray, shape (n_speeds,)
        First drive's speeds [rad/s].
    spectral_radius : ndarray, shape (n_values, n_speeds)
        Largest Floquet multiplier modulus [-] of the tolerance-driven solve (NaN
        where a point failed or its non-linear iteration did not converge).
    stable : ndarray of bool, shape (n_values, n_speeds)
        The solve's verdict was ``"stable"`` (``res.stability``).
    failures : tuple of (float, float, str)
        ``(value, speed [rad/s], message)`` of every point without a spectral radius.
    name : str
        Scene name.
    wall_time : float
        Seconds for the sweep.
    scheduler : str
        Where it ran.
    """

    param: str
    values: np.ndarray
    speeds: np.ndarray
    spectral_radius: np.ndarray
    stable: np.ndarray
    failures: tuple[tuple[float, float, str], ...]
    name: str = ""
    wall_time: float = float("nan")
    scheduler: str = ""

    @property
    def rpm(self) -> np.ndarray:
        """Speeds [rev/min], shape (n_speeds,)."""
        return self.speeds * RPM_PER_RAD_S

    def onsets(self) -> np.ndarray:
        """First speed at which the spectral radius crosses 1 from below, per parameter value.

        Linear interpolation of ``log rho`` between grid speeds (the first crossing from below,
        also after an unstable stretch at the low speeds); NaN where the grid shows none
        (stable throughout, unstable throughout, or failed points in between).

        Returns
        -------
        ndarray, shape (n_values,)
            [rad/s].
        """
        with np.errstate(divide="ignore", invalid="ignore"):
            g = np.log(self.spectral_radius)                              # (nv, ns)
            up = (g[:, :-1] < 0) & (g[:, 1:] >= 0)                        # crossings from below
            r = g[:, :-1] / (g[:, :-1] - g[:, 1:])
        has = up.any(axis=1)
        i = np.argmax(up, axis=1)
        rows = np.arange(g.shape[0])
        s = self.speeds[i] + r[rows, i] * (self.speeds[np.minimum(i + 1, self.speeds.size - 1)] - self.speeds[i])
        return np.where(has, s, np.nan)

    def onset_brackets(self) -> tuple[np.ndarray, np.ndarray]:
        """The grid speeds around each of :meth:`onsets`: the onset lies between them, and the
        interpolated value is only as good as the grid (``log rho`` is far from linear near an
        onset; :func:`kedfem.critical_speed` refines it between them).

        Returns
        -------
        lo, hi : ndarray, shape (n_values,)
            [rad/s], NaN where the grid shows no onset.
        """
        with np.errstate(divide="ignore", invalid="ignore"):
            g = np.log(self.spectral_radius)
            up = (g[:, :-1] < 0) & (g[:, 1:] >= 0)
        has = up.any(axis=1)
        i = np.argmax(up, axis=1)
        lo = np.where(has, self.speeds[i], np.nan)
        hi = np.where(has, self.speeds[np.minimum(i + 1, self.speeds.size - 1)], np.nan)
        return lo, hi

    def to_csv(self, path) -> Path:
        """One row per grid point: the parameter, ``speed_rad_s``, ``speed_rpm``, ``spectral_radius``,
        ``stable``, ``ok``, ``error`` (a failed point's radius and verdict empty: not computed)."""
        nv, ns = self.spectral_radius.shape
        why = {(v, s): m for v, s, m in self.failures}
        rows = []
        for i in range(nv):
            for j in range(ns):
                v, s = float(self.values[i]), float(self.speeds[j])
                msg = why.get((v, s), "")
                rows.append((v, s, s * RPM_PER_RAD_S, float(self.spectral_radius[i, j]),
                             "" if msg else bool(self.stable[i, j]), not msg, msg))
        return _table(path, (self.param, "speed_rad_s", "speed_rpm", "spectral_radius", "stable", "ok", "error"),
                      rows)

    def plot(self, path, *, marks: Sequence[tuple[float, float, str]] = (), log_y: bool | None = None,
             title: str = "", ylabel: str = "") -> Path:
        """Stability chart (PNG); see :func:`stability_chart`."""
        return stability_chart(self, path, marks=marks, log_y=log_y, title=title, ylabel=ylabel)


def stability_chart(smap: StabilityMap, path, *, marks: Sequence[tuple[float, float, str]] = (),
                    log_y: bool | None = None, title: str = "", ylabel: str = "", rho_max: float = 3.0) -> Path:
    """Stability chart: crank speed [rpm] on x, the parameter on y, colour = spectral radius.

    Parameters
    ----------
    smap : StabilityMap
        At least 2 speeds and 2 parameter values.
    path : path-like
        PNG to write.
    marks : sequence of (speed [rad/s], value, label)
        Points to mark (e.g. critical speeds refined by
        :func:`kedfem.analysis.critical.critical_speed`).
    log_y : bool, optional
        Logarithmic parameter axis (default: when the values are positive and span
        more than a factor 5).
    title, ylabel : str
        Default: the map's scene name, the parameter's key.
    rho_max : float
        Spectral radius at the top of the colour scale (larger ones share its colour).

    Returns
    -------
    Path
    """
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.patches import Patch
    from matplotlib.lines import Line2D
    nv, ns = smap.spectral_radius.shape
    if nv < 2 or ns < 2:
        raise InputError(f"stability_chart: a chart needs at least 2 speeds and 2 values of {smap.param}, "
                         f"got {ns} and {nv}")
    vals = np.asarray(smap.values, dtype=float)
    if log_y is None:
        log_y = bool(np.all(vals > 0) and vals.max() / vals.min() > 5)
    rho = smap.spectral_radius
    finite = rho[np.isfinite(rho)]
    lo = float(min(finite.min(), 0.99)) if finite.size else 0.0
    hi = float(max(min(finite.max(), rho_max), 1.01)) if finite.size else 2.0
    fig, axes = plots._figure(figsize=(8.5, 5.5))
    ax = axes[0, 0]
    ax.set_facecolor("0.8")  # failed points show grey
    X, Y = np.meshgrid(smap.rpm, vals)
    mesh = ax.pcolormesh(X, Y, np.clip(rho, None, hi), shading="nearest", cmap="RdBu_r",
                         norm=TwoSlopeNorm(vmin=lo, vcenter=1.0, vmax=hi))
    cb = fig.colorbar(mesh, ax=ax, extend="max" if finite.size and finite.max() > hi else "neither")
    cb.set_label("spectral radius rho [-] (largest |Floquet multiplier|)")
    handles = []
    if finite.size and finite.max() > 1.0 and finite.min() < 1.0:
        Z = np.where(np.isfinite(rho), rho, np.nan)
        ax.contourf(X, Y, Z, levels=[1.0, np.inf], colors="none", hatches=["///"])
        ax.contour(X, Y, Z, levels=[1.0], colors="k", linewidths=1.5)
        handles += [Patch(facecolor="none", edgecolor="k", hatch="///", label="unstable (rho > 1)"),
                    Line2D([], [], color="k", lw=1.5, label="rho = 1")]
    for speed, value, label in marks:
        ax.plot([speed * RPM_PER_RAD_S], [value], "o", mfc="yellow", mec="k", ms=7, zorder=5)
        if label:
            ax.annotate(label, (speed * RPM_PER_RAD_S, value), xytext=(6, 4), textcoords="offset points", fontsize="x-small",
                        bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="none", alpha=0.8))
    if smap.failures:
        handles.append(Patch(facecolor="0.8", edgecolor="none", label=f"no result ({len(smap.failures)} points)"))
    if log_y:
        from matplotlib.ticker import NullFormatter, ScalarFormatter
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(ScalarFormatter())
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.set_yticks(vals[:: max(1, vals.size // 8)])
    ax.set_xlabel("crank speed [rev/min]")
    ax.set_ylabel(ylabel or smap.param)
    ax.set_title(title or f"stability map: {smap.name}", fontsize="medium")
    if handles:
        ax.legend(handles=handles, fontsize="x-small", loc="upper right", framealpha=0.9)
    return plots._save(fig, path)


def stability_map(base: Mapping, speeds, param: str, values: Sequence, *, scheduler: str = "processes",
                  max_workers: int | None = None, executor=None, client=None,
                  progress: bool | None = None, builder=None, trust=None) -> StabilityMap:
    """Spectral radius over a grid of crank speed x one scene parameter, solved in parallel.

    Parameters
    ----------
    base : mapping
        Base scene dictionary in the TOML layout (``{"mechanism": {"name": "four_bar"},
        "effects": ["inertia", "coupling", "axial_stiffening"], "accuracy": "fast"}``).
    speeds : array_like, shape (n_speeds,)
        First drive's speeds [rad/s], > 0 and increasing (become ``speed_rpm``).
    param : str
        Dotted scene key of the other axis (``"mechanism.coupler_EI"``, ``"damping.zeta"``).
    values : sequence of numbers, shape (n_values,)
        Its values.
    scheduler, max_workers, executor, client, progress, builder, trust
        As :func:`kedfem.io.sweep.run_sweep` (``"processes"``, ``"serial"``, ``"local"``
        or a Dask address; ``builder``: the mechanism's builder function or reference, trusted;
        ``trust``: code the base may name, :mod:`kedfem.trust`).

    Returns
    -------
    StabilityMap

    Raises
    ------
    InputError
        Bad speeds, ``param`` not a scene key (or ``speed_rpm``), values that are not
        numbers or that the scene rejects.
    """
    from . import scenefile
    from .sweep import _with_builder, run_sweep
    from ..trust import Trust
    trust = Trust.of(trust, "stability_map: trust")
    if builder is not None:
        base = _with_builder(base, builder)
        trust = trust | Trust.of_reference(base["mechanism"]["name"])
    if not isinstance(base, Mapping):
        raise InputError(f"stability_map: base must be a scene dictionary, got {type(base).__name__}")
    s = check_speeds(speeds, "stability_map", "speeds")
    if not isinstance(param, str) or not param or param in ("speed_rpm", "speed"):
        raise InputError(f"stability_map: param must be a dotted scene key other than the speed (e.g. "
                         f"'mechanism.coupler_EI', 'damping.zeta'), got {param!r}")
    if isinstance(values, (str, bytes)) or not isinstance(values, (Sequence, np.ndarray)) or len(values) == 0 \
            or not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                       and math.isfinite(v) for v in values):
        raise InputError(f"stability_map: values must be a non-empty sequence of finite numbers, got {values!r}")
    vals = [v.item() if isinstance(v, np.generic) else v for v in values]
    rpm = [float(x) for x in s * RPM_PER_RAD_S]
    scene = None
    for v in vals:  # every value against the scene before any worker starts
        scene = scenefile.scene_from_dict(scenefile.with_overrides(base, {param: v, "speed_rpm": rpm[0]}),
                                          source=f"stability_map ({param} = {v!r})", trust=trust)
    with warnings.catch_warnings():  # deep in a tongue the response is huge: that is the map's finding
        warnings.simplefilter("ignore", PlausibilityWarning)
        res = run_sweep(base, {param: vals, "speed_rpm": rpm}, scheduler=scheduler, max_workers=max_workers,
                        executor=executor, client=client, progress=progress, frequencies=False, trust=trust)
    nv, ns = len(vals), s.size
    rho = np.full(nv * ns, np.nan)
    stable = np.zeros(nv * ns, dtype=bool)
    failures = []
    for p in res.points:  # grid order: the parameter varies slowest
        i = p.index
        if p.ok and p.converged:
            rho[i], stable[i] = p.spectral_radius, bool(p.stable)
        else:
            why = p.error if not p.ok else "the non-linear iteration did not converge"
            failures.append((float(vals[i // ns]), float(s[i % ns]), why))
    if failures:
        log.warning("stability_map: %d of %d points without a spectral radius (first: %s)", len(failures),
                    nv * ns, failures[0][2])
    return StabilityMap(param, np.asarray(vals, dtype=float), s, rho.reshape(nv, ns), stable.reshape(nv, ns),
                        tuple(failures), scene.name or scene.mech.name, res.wall_time, res.scheduler)
