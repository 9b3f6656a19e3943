"""Files for fatigue: the fatigue table and tidy stress histories (CSV, NPZ), SI units.

``fatigue.csv``: one row per link, station and fibre (``link, station_m, fibre, mean_Pa,
alternating_Pa, max_Pa, min_Pa``; a station at a joint the link passes through, ``through=``,
appears twice: the pin's ``a`` side, then its ``b`` side). ``histories.csv``: tidy, one row per crank angle, link,
station and quantity (``crank_angle_deg, link, station_m, quantity, value, unit``) with the
quantities ``stress_top``, ``stress_bottom`` [Pa], ``axial_force`` [N], ``bending_moment`` [N m]
and ``deflection`` [m] (transverse, in the link's frame), each row's unit in ``unit`` (the
table convention of docs/usage.md). ``histories.npz``: the same as arrays,
``<link>/<quantity>_<unit>`` (n, n_st; :data:`QUANTITIES`) plus ``crank_angle_rad`` and
``<link>/stations_m``.
Every file is written whole or not at all (:func:`kedfem.io.export.atomic_path`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..analysis.fatigue import FatigueTable, fibre_stress
from ..errors import KedError
from .export import atomic_path

__all__ = ["write_fatigue_csv", "write_histories"]

#: ``(array of histories.npz, quantity and unit of histories.csv)`` of each history
_TABLE = (("stress_top_Pa", "stress_top", "Pa"), ("stress_bottom_Pa", "stress_bottom", "Pa"),
          ("axial_force_N", "axial_force", "N"), ("bending_moment_Nm", "bending_moment", "N m"),
          ("deflection_m", "deflection", "m"))
#: the arrays of ``histories.npz`` (the name and unit of each)
QUANTITIES = tuple(key for key, _name, _unit in _TABLE)


def write_fatigue_csv(table: FatigueTable, path) -> Path:
    """Write the fatigue table (see the module docstring) to ``path``; return it."""
    bad = [lf.link for lf in table.links if not all(np.isfinite(x).all() for x in (lf.mean, lf.alternating))]
    if bad:
        raise KedError(f"fatigue table: non-finite stresses in {', '.join(bad)}; fatigue.csv not written")
    rows = ["link,station_m,fibre,mean_Pa,alternating_Pa,max_Pa,min_Pa"]
    for lf in table.links:
        for i, x in enumerate(lf.stations):
            for f, fibre in enumerate(("top", "bottom")):
                rows.append(f"{lf.link},{x:.9g},{fibre},{lf.mean[i, f]:.9e},{lf.alternating[i, f]:.9e},"
                            f"{lf.maximum[i, f]:.9e},{lf.minimum[i, f]:.9e}")
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(rows) + "\n")
    return path


def _histories(res, per_element: int) -> dict[str, dict[str, np.ndarray]]:
    out = {}
    for lk in res.model.mech.flexible_links:
        if lk.section.c is None:
            continue
        fs = fibre_stress(res, lk.name, per_element)
        xi = fs.stations / lk.length
        defl = np.stack([res.deflection(lk.name, float(x)) for x in xi], axis=-1)
        out[lk.name] = dict(zip(QUANTITIES, (fs.top, fs.bottom, fs.axial_force, fs.bending_moment, defl)),
                            stations_m=fs.stations)
        bad = [q for q in QUANTITIES if not np.isfinite(out[lk.name][q]).all()]
        if bad:
            raise KedError(f"link '{lk.name}': non-finite {', '.join(bad)}; no histories written")
    return out


def write_histories(res, csv_path, npz_path=None, per_element: int = 1) -> list[Path]:
    """Write the stress, force and deflection histories of every flexible link with a stress.

    Parameters
    ----------
    res : kedfem.analysis.results.PeriodicResult
    csv_path : path or None
        The tidy CSV (None: none).
    npz_path : path, optional
        The same as arrays.
    per_element : int
        Stations per element.

    Returns
    -------
    list of Path
        The files written.
    """
    data = _histories(res, per_element)
    files = []
    if csv_path is not None:
        deg = np.degrees(res.crank_angle) % 360.0
        rows = ["crank_angle_deg,link,station_m,quantity,value,unit"]
        for link, d in data.items():
            for q, name, unit in _TABLE:
                X = d[q]
                for k in range(res.n):  # rows of text: one per instant
                    a = f"{deg[k]:.6f},{link},"
                    rows.extend(f"{a}{x:.9g},{name},{v:.9e},{unit}" for x, v in zip(d["stations_m"], X[k]))
        path = Path(csv_path)
        with atomic_path(path) as tmp:
            tmp.write_text("\n".join(rows) + "\n")
        files.append(path)
    if npz_path is not None:
        arrays = {"crank_angle_rad": res.crank_angle}
        for link, d in data.items():
            arrays.update({f"{link}/{k}": v for k, v in d.items()})
        path = Path(npz_path)
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, **arrays)
        files.append(path)
    return files
