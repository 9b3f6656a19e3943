"""Files of the loads on the machine: a tidy CSV and a plot of bearing forces and drive torque.

``loads.csv``: ``crank_angle_deg, response, quantity, joint, member, component, value, unit``
(SI); ``loads.png``: one axis of bearing forces, one of drive torques, elastic (solid) and
rigid (dashed), in readable units. Written whole or not at all.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

import logging

from ..errors import KedError
from ..analysis.loads import CSV_COLUMNS, FRAME, MachineLoads
from .export import atomic_path
from .plots import _figure, _save

__all__ = ["write_loads_csv", "plot_loads"]

log = logging.getLogger(__name__)


def write_loads_csv(loads: MachineLoads, path) -> Path:
    """Write the loads as a tidy CSV table (one value a row, SI units), atomically.

    Columns :data:`CSV_COLUMNS`: ``crank_angle_deg`` (in ``[0, 360)``),
    ``response`` (``rigid`` / ``elastic``), ``quantity`` (``bearing_force``
    with components ``x``, ``y``, ``magnitude`` [N]; ``bearing_moment`` ``z``
    [N m] where a pin passes a moment; ``drive_torque`` ``z`` [N m]), ``joint``,
    ``member`` (the body the pin holds, ``frame``, or the driven member),
    ``component``, ``value``, ``unit``.

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    rows = list(loads.rows())
    bad = sorted({(q, j) for _a, _r, q, j, _m, _c, v, _u in rows if not np.isfinite(v)})
    if bad:
        raise KedError(f"loads: non-finite {', '.join(f'{q} at {j}' for q, j in bad[:4])}; loads.csv not written")
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(CSV_COLUMNS)
        for a, resp, q, j, m, comp, v, unit in rows:
            w.writerow((f"{a:.6f}", resp, q, j, m, comp, repr(float(v)), unit))
    log.info("wrote %s", path)
    return path


def _scale(peak: float, unit: str) -> tuple[float, str]:
    """A readable unit for values up to ``peak``: ``unit`` or ``k`` + unit."""
    return (1e3, "k" + unit) if peak >= 1e3 else (1.0, unit)


def plot_loads(loads: MachineLoads, path, *, bearings=None, angle_label: str = "crank angle [deg]") -> Path:
    """Plot bearing force magnitudes and drive torques over the crank angle (PNG, atomically).

    One axis for the forces, one for the torques; elastic solid, rigid
    dashed in the same colour; N or kN, N m or kN m as the values need.

    Parameters
    ----------
    loads : MachineLoads
    path : str or Path
    bearings : sequence of (str, str), optional
        ``(joint, body)`` to draw; default at every joint the body whose
        force peaks highest (the frame at supports).

    Returns
    -------
    pathlib.Path
    """
    main = loads.elastic if loads.elastic is not None else loads.rigid
    if bearings is None:
        bearings = []
        for j in dict.fromkeys(b[0] for b in loads.bearings):
            here = [k for k, b in enumerate(loads.bearings) if b[0] == j]
            frame = [k for k in here if loads.bearings[k][1] == FRAME]
            best = frame[0] if frame else max(here, key=lambda k: main.magnitude[:, k].max())
            bearings.append(loads.bearings[best])
    idx = [loads.bearing_index(j, m) for j, m in bearings]
    deg = np.mod(np.degrees(loads.crank_angle), 360.0)
    order = np.argsort(deg)
    x = deg[order]
    if loads.whole_cycle:  # the whole cycle: close the curves at 360 deg
        order, x = np.append(order, order[0]), np.append(x, x[0] + 360.0)
    fig, axes = _figure(2, 1, figsize=(8.0, 7.0), sharex=True)
    ax_f, ax_t = axes[0, 0], axes[1, 0]
    histories = [h for h in (loads.elastic, loads.rigid) if h is not None]
    fs, fu = _scale(max(float(h.magnitude[:, idx].max()) if idx else 0.0 for h in histories), "N")
    ts, tu = _scale(max(float(np.abs(h.torque).max()) if h.torque.size else 0.0 for h in histories), "N m")
    colours = [f"C{i % 10}" for i in range(max(len(idx), len(loads.drives)))]
    for c, k in zip(colours, idx):
        j, m = loads.bearings[k]
        for h in histories:
            style = "-" if h.response == "elastic" else "--"
            ax_f.plot(x, h.magnitude[order, k] / fs, style, color=c, lw=1.2,
                      label=f"{j} ({m}), {h.response}")
    for c, (k, (m, j)) in zip(colours, enumerate(loads.drives)):
        for h in histories:
            style = "-" if h.response == "elastic" else "--"
            ax_t.plot(x, h.torque[order, k] / ts, style, color=c, lw=1.2, label=f"{m} at {j}, {h.response}")
    ax_f.set_ylabel(f"bearing force magnitude [{fu}]")
    ax_f.set_title(f"{loads.mechanism}: force of each pin on the body it holds")
    ax_t.set_ylabel(f"drive torque [{tu}]")
    ax_t.set_xlabel(angle_label)
    ax_t.axhline(0.0, color="0.6", lw=0.6)
    for ax in (ax_f, ax_t):
        ax.set_xlim(0.0, 360.0)
        ax.grid(True, lw=0.4, alpha=0.5)
        if ax.lines:
            ax.legend(fontsize="small", ncols=2)
    return _save(fig, path)
