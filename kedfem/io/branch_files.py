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
from ..units import RPM_PER_RAD_S

__all__ = ["to_csv", "plot", "write", "read"]



def _branches(branch):
    return (branch,) + ((branch.subharmonic,) if branch.subharmonic is not None else ())


def _name(branch) -> str:
    return "speed_rad_s" if branch.parameter == "speed" else branch.parameter


def _brackets(parameter: str) -> tuple[str, str]:
    """The bifurcation table's bracket columns: with the parameter's unit as a suffix where it has
    one (the speed in rad/s); a scene-file parameter's unit is its key's."""
    return ("bracket_lo_rad_s", "bracket_hi_rad_s") if parameter == "speed" else ("bracket_lo", "bracket_hi")


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
        w.writerow(("kind", _name(branch)) + (("speed_rpm",) if speed else ()) + _brackets(branch.parameter) + (
            "multiplier_re", "multiplier_im", "stable_before", "stable_after", "periods"))
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
            # one line per run of equal stability (a dash pattern restarts on every line: short
            # segments drawn one by one would all look solid)
            seg = stable[:-1] & stable[1:]  # a segment is stable when both its ends are
            cuts = np.flatnonzero(np.diff(seg.astype(int))) + 1
            for a, b in zip(np.r_[0, cuts], np.r_[cuts, seg.size]):
                ax.plot(x[a:b + 1], y[a:b + 1], "-" if seg[a] else "--", color=c if br.periods == 1 else "0.5",
                        lw=1.8 if br.periods == 1 else 1.2)
            if br.periods == 1:
                ax.plot([], [], "-", color=c, label=link)
    marks = ax.get_xaxis_transform()  # x in data, y in axes fraction: the markers sit on the axis
    for br in _branches(branch):
        for b in br.bifurcations:
            mark = {"fold": "o", "flip": "s", "neimark-sacker": "D"}[b.kind]
            ax.axvline(b.value * xs, color="0.6", lw=0.8, ls=":")
            ax.plot([b.value * xs], [0.02], mark, color="k", ms=6, transform=marks, clip_on=False)
    ax.plot([], [], "--", color="0.3", label="unstable")
    if branch.subharmonic is not None:
        ax.plot([], [], "-", color="0.5", label="period 2")
    ax.set_xlabel(xunit)
    ax.set_ylabel(f"peak {quantity} [{unit}]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    cut = f"\n{branch.end}" if "interrupted" in branch.end else ""  # (a branch stopped by Ctrl-C)
    ax.set_title(f"response curve (markers: o fold, s flip, D Neimark-Sacker){cut}")
    return _save(fig, path)


def write(branch, folder, plots: bool = True) -> list[Path]:
    """``branch.csv``, ``branch_bifurcations.csv`` and (``plots``) ``response_curve.png`` in ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = list(to_csv(branch, folder / "branch.csv"))
    if plots:
        out.append(plot(branch, folder / "response_curve.png"))
    return out


def read(folder) -> "Branch":
    """A branch back from the files :func:`write` made in ``folder`` (to plot it again or compare
    it with another, without recomputing it).

    What the CSV does not hold comes back empty: the points' multipliers (their spectral radius
    is kept), the crank angles and stations of the peaks (nan), the results.

    Parameters
    ----------
    folder : str or Path
        Holds ``branch.csv`` and ``branch_bifurcations.csv``.

    Returns
    -------
    Branch

    Raises
    ------
    InputError
        A file missing or not a branch file.
    """
    from ..analysis.continuation import Bifurcation, Branch, BranchPoint
    from ..analysis.accuracy import LinkError
    from ..analysis.results import LinkPeaks
    folder = Path(folder)
    pts_file, bif_file = folder / "branch.csv", folder / "branch_bifurcations.csv"
    try:
        with open(pts_file, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
        with open(bif_file, newline="", encoding="utf-8") as f:
            bifs = list(csv.DictReader(f))
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"read_branch: cannot read the branch files in {folder}: {e}") from None
    if not rows or "point" not in rows[0] or "spectral_radius" not in rows[0]:
        raise InputError(f"read_branch: {pts_file} is not a branch.csv (no rows, or no point/spectral_radius columns)")
    value_key = next(k for k in rows[0] if k not in ("point",))
    parameter = "speed" if value_key == "speed_rad_s" else value_key

    def num(s):
        return float(s) if s not in ("", None) else float("nan")

    try:
        groups: dict = {}
        for r in rows:
            groups.setdefault((int(r["periods"]), int(r["point"])), []).append(r)
        branches = {}
        for (periods, _k), rs in sorted(groups.items()):
            peaks = tuple(LinkPeaks(r["link"], num(r["peak_deflection_m"]), math.nan, num(r["peak_stress_Pa"]),
                                    math.nan, math.nan) for r in rs)
            errs = tuple(LinkError(r["link"], num(r["deflection_time_error"]), num(r["stress_time_error"]), math.nan)
                         for r in rs if r["deflection_time_error"] != "")
            rho = num(rs[0]["spectral_radius"])
            branches.setdefault(periods, []).append(BranchPoint(
                num(rs[0][value_key]), peaks, errs, np.zeros(0, complex), rho, rs[0]["stable"] == "True", periods))
        found: dict = {}
        lo_hi = _brackets(parameter)
        if bifs and lo_hi[0] not in bifs[0]:  # written before the table convention (issue 27)
            lo_hi = _brackets("")
        for b in bifs:
            found.setdefault(int(b["periods"]), []).append(Bifurcation(
                b["kind"], num(b[value_key]), tuple(num(b[k]) for k in lo_hi),
                complex(num(b["multiplier_re"]), num(b["multiplier_im"])), b["stable_before"] == "True",
                b["stable_after"] == "True"))
    except (KeyError, ValueError, StopIteration) as e:
        raise InputError(f"read_branch: {folder} does not hold branch files as kedfem writes them ({e})") from None
    if 1 not in branches:
        raise InputError(f"read_branch: {pts_file} has no 1-periodic points")
    unit = "rad/s" if parameter == "speed" else ""
    sub = None
    if 2 in branches:
        sub = Branch(parameter, unit, tuple(branches[2]), tuple(found.get(2, ())), 0, "", 2)
    return Branch(parameter, unit, tuple(branches[1]), tuple(found.get(1, ())), 0, "", 1, sub,
                  f"read from {folder}")
