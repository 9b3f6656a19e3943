"""Files of a continuation branch (:class:`kedfem.analysis.continuation.Branch`): a tidy CSV of its
points, a CSV of its bifurcations and the response curve (PNG).

``branch.csv``: one row per point and flexible link (and the period-2 branch's points, with
``periods = 2``): the parameter (``speed_rad_s`` and ``speed_rpm`` for the speed), the link, its
peak mid-span deflection [m] and peak stress [Pa] with their estimated relative time errors, the
spectral radius and the verdict. ``branch_bifurcations.csv``: kind, located value, bracket,
crossing multiplier, stability before and after.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from ..errors import InputError
from .export import atomic_path
from .sweep import csv_cells

__all__ = ["to_csv", "plot", "write"]

RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)


def _branches(branch):
    return (branch,) + ((branch.subharmonic,) if branch.subharmonic is not None else ())


def _name(branch) -> str:
    return "speed_rad_s" if branch.parameter == "speed" else branch.parameter


def to_csv(branch, path) -> tuple[Path, Path]:
    """Write the points and the bifurcations of ``branch``.

    Parameters
    ----------
    branch : Branch
    path : str or Path
        The points' CSV; the bifurcations go beside it as ``<stem>_bifurcations.csv``.

    Returns
    -------
    (Path, Path)
    """
    path = Path(path)
    speed = branch.parameter == "speed"
    head = ("point", _name(branch)) + (("speed_rpm",) if speed else ()) + (
        "link", "peak_deflection_m", "deflection_time_error", "peak_stress_Pa", "stress_time_error",
        "spectral_radius", "stable", "periods")
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(head)
        for br in _branches(branch):
            for r in br.table():
                row = r[:2] + ((r[1] * RPM_PER_RAD_S,) if speed else ()) + r[2:]
                w.writerow(csv_cells(row))
    bif = path.with_name(path.stem + "_bifurcations.csv")
    with atomic_path(bif) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(("kind", _name(branch)) + (("speed_rpm",) if speed else ()) + (
            "bracket_lo", "bracket_hi", "multiplier_re", "multiplier_im", "stable_before", "stable_after",
            "periods"))
        for br in _branches(branch):
            for b in br.bifurcations:
                w.writerow(csv_cells((b.kind, b.value) + ((b.value * RPM_PER_RAD_S,) if speed else ()) + (
                    b.bracket[0], b.bracket[1], b.multiplier.real, b.multiplier.imag, b.stable_before,
                    b.stable_after, br.periods)))
    return path, bif


def plot(branch, path, quantity: str = "stress") -> Path:
    """The response curve: each link's peak ``quantity`` (``"stress"`` [MPa] or ``"deflection"``
    [mm]) against the parameter; stable parts solid, unstable dashed; bifurcations marked; the
    period-2 branch in grey."""
    from .plots import _figure, _save
    if quantity not in ("stress", "deflection"):
        raise InputError(f"plot: quantity must be 'stress' or 'deflection', got {quantity!r}")
    scale, unit = (1e-6, "MPa") if quantity == "stress" else (1e3, "mm")
    xs, xunit = (RPM_PER_RAD_S, "speed [rev/min]") if branch.parameter == "speed" else (1.0, branch.parameter)
    fig, axes = _figure()
    ax = axes[0, 0]
    colors = {}
    for br in _branches(branch):
        x = br.values * xs
        stable = br.stable
        for link in br.links:
            y = np.array([p.peak(link, quantity) for p in br.points]) * scale
            c = colors.setdefault(link, f"C{len(colors) % 10}")
            for k in range(len(x) - 1):
                solid = stable[k] and stable[k + 1]
                ax.plot(x[k:k + 2], y[k:k + 2], "-" if solid else "--", color=c if br.periods == 1 else "0.5",
                        lw=1.8 if br.periods == 1 else 1.2)
            if br.periods == 1:
                ax.plot([], [], "-", color=c, label=link)
        for b in br.bifurcations:
            mark = {"fold": "o", "flip": "s", "neimark-sacker": "D"}[b.kind]
            ax.axvline(b.value * xs, color="0.6", lw=0.8, ls=":")
            ax.plot([b.value * xs], [ax.get_ylim()[0]], mark, color="k", ms=6, clip_on=False)
    ax.plot([], [], "--", color="0.3", label="unstable")
    if branch.subharmonic is not None:
        ax.plot([], [], "-", color="0.5", label="period 2")
    ax.set_xlabel(xunit)
    ax.set_ylabel(f"peak {quantity} [{unit}]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title(f"response curve (markers: o fold, s flip, D Neimark-Sacker)")
    return _save(fig, path)


def write(branch, folder, plots: bool = True) -> list[Path]:
    """``branch.csv``, ``branch_bifurcations.csv`` and (``plots``) ``response_curve.png`` in ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = list(to_csv(branch, folder / "branch.csv"))
    if plots:
        out.append(plot(branch, folder / "response_curve.png"))
    return out
