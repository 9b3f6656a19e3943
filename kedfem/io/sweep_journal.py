"""The partial table of a running sweep: what survives a kill, and what ``--resume`` reads.

A sweep appends each finished point's rows (the tidy table of
:class:`kedfem.io.sweep.SweepTable`) to a CSV file as soon as the point
completes, in one write followed by ``fsync``. Its first line names the sweep
(a hash of the base scene and the axes), so a partial table is never resumed
into another sweep. Reading it back drops a truncated last point and keeps
every complete one; :meth:`SweepJournal.start` then rewrites the file with
only those, so each point appears in it once.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import logging
import math
import os
from pathlib import Path
from typing import Mapping, Sequence

from ..analysis.accuracy import LinkError
from ..errors import InputError
from ..analysis.results import LinkPeaks
from .sweep import TABLE_COLUMNS, PointResult, SweepPoint, _cell, csv_cells, point_rows

__all__ = ["SweepJournal", "sweep_signature"]

log = logging.getLogger(__name__)

_TAG = "# kedfem sweep "


def sweep_signature(base: Mapping, axes: Mapping[str, Sequence]) -> str:
    """A short hash of a sweep's base scene and axes (what its points are)."""
    text = json.dumps({"base": base, "axes": {k: list(v) for k, v in axes.items()}}, sort_keys=True,
                      default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _float(s: str) -> float:
    return float(s) if s not in ("", None) else float("nan")


def _bool(s: str):
    return {"True": True, "False": False}.get(s)


class SweepJournal:
    """Append-only partial table of one sweep.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    signature : str
        :func:`sweep_signature` of the sweep.
    keys : sequence of str
        The swept keys (the table's axis columns).
    """

    def __init__(self, path, signature: str, keys: Sequence[str]):
        self.path = Path(path)
        self.signature = str(signature)
        self.keys = list(keys)
        self.names = ("point",) + tuple(self.keys) + TABLE_COLUMNS
        self._fh = None

    # ------------------------------------------------------------- reading
    def read(self, points: Sequence[SweepPoint]) -> dict[int, PointResult]:
        """The complete points of the file, by index (empty if there is no file).

        Raises :class:`InputError` if the file is the partial table of
        another sweep.
        """
        if not self.path.is_file():
            return {}
        raw = self.path.read_bytes()
        first_raw, _, body_raw = raw.partition(b"\n")
        first = first_raw.decode("utf-8", errors="replace")
        if not first.startswith(_TAG):
            raise InputError(f"sweep --resume: {self.path} is not a kedfem partial sweep table")
        if first[len(_TAG):].strip() != self.signature:
            raise InputError(f"sweep --resume: {self.path} is the partial table of another sweep (a different "
                             f"scene or axes); remove it or resume that sweep")
        complete = body_raw if body_raw.endswith(b"\n") else body_raw[:body_raw.rfind(b"\n") + 1]
        # line by line: a line that is not UTF-8 (a damaged disk block) costs its point, not the sweep
        lines, bad = [], set()
        for line in complete.splitlines(keepends=True):
            try:
                lines.append(line.decode("utf-8"))
            except UnicodeDecodeError:
                head = line.split(b",", 1)[0]
                if head.isdigit():
                    bad.add(int(head))
                log.warning("sweep --resume: %s: a line that is not UTF-8 text is dropped", self.path)
        rows = list(csv.reader(io.StringIO("".join(lines))))
        if not rows or tuple(rows[0]) != self.names:
            return {}
        by_index = {p.index: p for p in points}
        groups: dict[int, list] = {}
        for r in rows[1:]:
            try:
                i = int(r[0])
            except (ValueError, IndexError):
                continue
            if len(r) != len(self.names):
                bad.add(i)
                continue
            row = dict(zip(self.names, r))
            g = groups.setdefault(i, [])
            same = [x for x in g if x["link"] == row["link"]]
            if same:  # a line written twice: the same point once; a conflicting copy: solve it again
                if any(x != row for x in same):
                    bad.add(i)
                continue
            g.append(row)
        out = {}
        for i, g in groups.items():
            p = by_index.get(i)
            if p is None or i in bad:
                continue
            pv = dict(p.params)
            if any(str(_cell(pv.get(k))) != g[0][k] for k in self.keys):
                raise InputError(f"sweep --resume: point {i} of {self.path} has other parameters than this "
                                 f"sweep's point {i}")
            try:
                r = self._point(p, g)
            except (ValueError, KeyError):  # a damaged number: solve the point again
                r = None
            if r is not None:
                out[i] = r
        return out

    @staticmethod
    def _point(p: SweepPoint, g: list[dict]) -> PointResult | None:
        h = g[0]
        ok = _bool(h["ok"])
        if ok is None:
            return None
        peaks, errors = [], []
        for row in g:
            if not row["link"]:
                continue
            peaks.append(LinkPeaks(row["link"], _float(row["peak_deflection_m"]), _float(row["deflection_angle_rad"]),
                                   _float(row["peak_stress_Pa"]), _float(row["stress_angle_rad"]),
                                   _float(row["stress_station_m"])))
            d, s = _float(row["deflection_time_error"]), _float(row["stress_time_error"])
            if not (math.isnan(d) and math.isnan(s)):
                errors.append(LinkError(row["link"], d, s, float("nan")))
        return PointResult(p.index, p.params, ok, h["error"], _float(h["wall_time_s"]), _bool(h["converged"]),
                           _bool(h["stable"]), int(float(h["iterations"] or 0)), _float(h["spectral_radius"]),
                           _float(h["fundamental_Hz"]), tuple(peaks), "resumed", tuple(errors),
                           _bool(h["error_estimate_met"]))

    # ------------------------------------------------------------- writing
    def start(self, done: Mapping[int, PointResult] | None = None) -> None:
        """(Re)write the file with its header and the ``done`` points, then keep it open for appending."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f".{self.path.name}.tmp-{os.getpid()}")
        with open(tmp, "w", newline="") as f:
            f.write(f"{_TAG}{self.signature}\n")
            w = csv.writer(f)
            w.writerow(self.names)
            for i in sorted(done or {}):
                for row in point_rows(done[i], self.keys):
                    w.writerow(csv_cells(row))
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self.path)
        self._fh = open(self.path, "a", newline="")

    def append(self, r: PointResult) -> None:
        """Add one point's rows in one write, flushed to disk."""
        buf = io.StringIO()
        w = csv.writer(buf)
        for row in point_rows(r, self.keys):
            w.writerow(csv_cells(row))
        self._fh.write(buf.getvalue())
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def close(self, remove: bool = False) -> None:
        """Close the file (and delete it once the sweep's table is published)."""
        if self._fh is not None:
            self._fh.close()
            self._fh = None
        if remove:
            self.path.unlink(missing_ok=True)
