"""Parameter sweeps: a grid of scenes solved on a process pool or a Dask cluster.

A sweep is a *base* scene dictionary (the layout of a TOML scene file, see
:mod:`kedfem.io.scenefile`) and *axes*: dotted keys with lists of values
(``{"speed_rpm": [500, 1000], "mechanism.elements": [4, 8]}``). Every grid
point is a plain, picklable dictionary; a worker validates it with
:func:`kedfem.io.scenefile.scene_from_dict`, solves it and returns a
:class:`PointResult`. A point whose parameters are bad, or whose solve fails,
is recorded with its error message; the others complete.

Executors:

* ``scheduler="processes"`` (default): :class:`concurrent.futures.ProcessPoolExecutor`
  with one worker per core;
* ``executor=``: any :class:`concurrent.futures.Executor` you pass (not shut down);
* ``scheduler="local"``: a ``dask.distributed.LocalCluster`` (one single-threaded
  worker process per core) started and stopped for the sweep;
* ``scheduler="tcp://host:8786"``: an existing Dask scheduler, or ``client=`` a
  ``dask.distributed.Client``;
* ``scheduler="serial"``: in this process, one point after the other.

Workers pin their BLAS/LAPACK thread pools to one thread (threadpoolctl;
``OPENBLAS_NUM_THREADS`` etc. are also set for processes they start):
otherwise two workers on two cores each start several BLAS threads and the
sweep runs slower than serially. Dask's local workers are *spawned* processes,
so scripts that start a sweep need an ``if __name__ == "__main__":`` guard.
"""

from __future__ import annotations

import concurrent.futures as cf
import csv
import logging
import math
import os
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import InputError, KedError
from .export import atomic_path, require
from ..analysis.results import LinkPeaks
from ..solvers.threads import pin_process

__all__ = ["SweepPoint", "PointResult", "SweepTable", "SweepResult", "make_points", "run_point", "run_sweep",
           "parse_axis", "point_rows", "TABLE_COLUMNS", "RETRIES"]

log = logging.getLogger(__name__)

#: Seconds between a worker's checks that the sweep's main process is alive.
WATCHDOG_PERIOD = 1.0


def _init_worker(parent: int | None = None) -> None:
    pin_process()
    if parent is not None:
        _watch_parent(parent)


def _proc_state(pid: int) -> tuple[str, str] | None:
    """(state letter, start time) of a process from ``/proc`` (Linux), or None where there is no ``/proc``."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            text = f.read().decode("ascii", "replace")
    except FileNotFoundError:
        return ("X", "")  # gone
    except OSError:
        return None
    rest = text[text.rfind(")") + 2:].split()  # the command name may hold spaces and parentheses
    return (rest[0], rest[19]) if len(rest) > 19 else None


def _parent_gone(parent: int, started: str | None) -> bool:
    """The sweep's main process has ended: gone, a zombie its own parent has not reaped yet (it
    holds no pipes open and will never shut the pool down), or its pid reused by another process."""
    st = _proc_state(parent)
    if st is not None:
        state, start = st
        return state in ("Z", "X", "x") or (started is not None and start != started)
    try:  # no /proc: a signal 0 tells a live (or zombie) process from a missing one
        os.kill(parent, 0)
    except ProcessLookupError:
        return True
    except PermissionError:  # pragma: no cover - another user's process took the pid
        return True
    return False


def _watch_parent(parent: int) -> None:
    """End this worker when the sweep's main process is gone (killed with SIGKILL, it cannot
    shut its pool down; the workers would run on, orphaned, to the end of their points)."""
    import threading
    st = _proc_state(parent)
    started = st[1] if st is not None else None

    def watch():
        while True:
            time.sleep(WATCHDOG_PERIOD)
            if _parent_gone(parent, started):
                os._exit(3)

    threading.Thread(target=watch, name="kedfem-parent-watchdog", daemon=True).start()


def _mp_context():
    """``forkserver`` where available, else ``spawn``; never a plain ``fork``.

    Forking a process whose OpenBLAS (or tqdm, or Dask) threads are running
    can leave a lock held in the child: the worker then hangs forever in
    its first BLAS call. Python 3.14 made ``forkserver`` the default on
    Linux for this reason.
    """
    import multiprocessing as mp
    methods = mp.get_all_start_methods()
    return mp.get_context("forkserver" if "forkserver" in methods else "spawn")


# ---------------------------------------------------------------- the grid
@dataclass(frozen=True)
class SweepPoint:
    """One grid point: its index, its parameter values and the full scene dictionary."""

    index: int
    params: tuple[tuple[str, Any], ...]
    scene: dict


def _normalize_axes(axes: Mapping[str, Sequence]) -> dict[str, tuple]:
    """Axes as ``{str: tuple}``; NumPy arrays and scalars become plain Python values."""
    if not isinstance(axes, Mapping):
        raise InputError(f"sweep: axes must be a mapping of dotted keys to lists of values, got "
                         f"{type(axes).__name__}")
    ax = {}
    for k, v in axes.items():
        if not isinstance(k, str) or not k:
            raise InputError(f"sweep: an axis is named by a dotted scene key (a string), got {k!r}")
        if isinstance(v, (str, bytes, Mapping)) or not isinstance(v, (Sequence, np.ndarray, range)) \
                or len(v) == 0:
            raise InputError(f"sweep: axis {k!r} must be a non-empty list of values, got {v!r}")
        ax[str(k)] = tuple(x.item() if isinstance(x, np.generic) else x for x in v)
    return ax


def make_points(base: Mapping, axes: Mapping[str, Sequence]) -> list[SweepPoint]:
    """Cartesian grid of scene dictionaries (the first axis varies slowest).

    Parameters
    ----------
    base : mapping
        Base scene dictionary (``{"mechanism": {"name": "slider_crank"}}``...).
    axes : mapping of str to sequence
        Dotted keys and their values.

    Returns
    -------
    list of SweepPoint

    Raises
    ------
    InputError
        No axes, an empty axis, or more than
        :data:`kedfem.io.scenefile.MAX_SWEEP_POINTS` points.
    """
    from .scenefile import MAX_SWEEP_POINTS, grid_points, with_overrides
    if not isinstance(base, Mapping):
        raise InputError(f"sweep: base must be a scene dictionary, got {type(base).__name__}")
    if not axes:
        raise InputError("sweep: nothing to sweep (give at least one axis: a dotted key and its values)")
    ax = _normalize_axes(axes)
    n = math.prod(len(v) for v in ax.values())
    if n > MAX_SWEEP_POINTS:
        raise InputError(f"sweep: {n} points exceed the limit of {MAX_SWEEP_POINTS} "
                         "(kedfem.io.scenefile.MAX_SWEEP_POINTS)")
    base = {k: v for k, v in base.items() if k not in ("sweep", "output")}
    return [SweepPoint(i, tuple(p.items()), with_overrides(base, p)) for i, p in enumerate(grid_points(ax))]


def parse_axis(text: str) -> tuple[str, tuple]:
    """Parse a command-line axis ``KEY=V1,V2,...`` or ``KEY=START:STOP:NUM``.

    Values are TOML scalars (``4``, ``0.3``, ``"foh"``, ``true``); a bare word
    is taken as a string. ``START:STOP:NUM`` gives ``NUM`` evenly spaced
    numbers including both ends.

    Raises
    ------
    InputError
    """
    import tomllib
    if "=" not in text:
        raise InputError(f"sweep axis {text!r}: expected KEY=V1,V2,... or KEY=START:STOP:NUM")
    key, _, vals = text.partition("=")
    key = key.strip()
    if not key:
        raise InputError(f"sweep axis {text!r}: missing key before '='")

    def scalar(s):
        s = s.strip()
        try:
            v = tomllib.loads(f"v = {s}")["v"]
        except (tomllib.TOMLDecodeError, RecursionError):
            if s and all(c.isalnum() or c in "_-+." for c in s):
                return s
            raise InputError(f"sweep axis {key!r}: cannot read value {s!r}") from None
        if isinstance(v, float) and not math.isfinite(v):
            raise InputError(f"sweep axis {key!r}: values must be finite, got {s!r}")
        if isinstance(v, (list, dict)):
            raise InputError(f"sweep axis {key!r}: a value must be a number, a string or true/false, got {s!r}")
        return v

    from .scenefile import MAX_SWEEP_POINTS
    parts = vals.split(":")
    if len(parts) == 3:
        a, b, num = scalar(parts[0]), scalar(parts[1]), scalar(parts[2])
        if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (a, b)) or \
                isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise InputError(f"sweep axis {key!r}: START:STOP:NUM needs two numbers and an integer NUM >= 1")
        if num > MAX_SWEEP_POINTS:
            raise InputError(f"sweep axis {key!r}: NUM = {num} exceeds the {MAX_SWEEP_POINTS} points a sweep may "
                             "have (kedfem.io.scenefile.MAX_SWEEP_POINTS)")
        # 12 significant digits: 0.04:0.12:5 gives 0.08, not 0.07999999999999999
        values = tuple(float(f"{x:.12g}") for x in np.linspace(float(a), float(b), num))
        if not all(math.isfinite(v) for v in values):
            raise InputError(f"sweep axis {key!r}: START:STOP:NUM gives values beyond floating point")
        if all(isinstance(x, int) for x in (a, b)) and all(v.is_integer() for v in values):
            values = tuple(int(v) for v in values)
        return key, values
    items = [x for x in vals.split(",") if x.strip()]
    if len(items) > MAX_SWEEP_POINTS:
        raise InputError(f"sweep axis {key!r}: {len(items)} values exceed the {MAX_SWEEP_POINTS} points a sweep may "
                         "have (kedfem.io.scenefile.MAX_SWEEP_POINTS)")
    values = tuple(scalar(x) for x in items)
    if not values:
        raise InputError(f"sweep axis {key!r}: no values")
    return key, values


# ------------------------------------------------------------ one point
@dataclass(frozen=True)
class PointResult:
    """Outcome of one grid point.

    Attributes
    ----------
    index : int
    params : tuple of (str, value)
    ok : bool
        The point was solved (``error`` is empty).
    error : str
        One-line error message of a failed point.
    wall_time : float
        Seconds spent on the point in the worker.
    converged, stable : bool or None
    iterations : int
    spectral_radius : float
        Largest Floquet multiplier modulus [-].
    fundamental : float
        Cycle mean of the lowest state-space natural frequency [Hz] (NaN if not computed).
    peaks : tuple of LinkPeaks
    worker : str
        ``host:pid`` of the process that solved the point.
    errors : tuple of LinkError
        Estimated relative time-discretisation errors of each link's peaks
        (``res.error.links``; empty if not estimated).
    error_met : bool or None
        The estimate met the scene's tolerance (None if not estimated).
    """

    index: int
    params: tuple[tuple[str, Any], ...]
    ok: bool
    error: str = ""
    wall_time: float = float("nan")
    converged: bool | None = None
    stable: bool | None = None
    iterations: int = 0
    spectral_radius: float = float("nan")
    fundamental: float = float("nan")
    peaks: tuple[LinkPeaks, ...] = ()
    worker: str = ""
    errors: tuple = ()
    error_met: bool | None = None


def _worker_id() -> str:
    import socket
    return f"{socket.gethostname()}:{os.getpid()}"


def run_point(point: SweepPoint, frequencies: bool = True, pin: bool = True, trust=None) -> PointResult:
    """Validate, solve and summarise one grid point (runs in a worker).

    ``trust`` (a :class:`kedfem.trust.Trust`) is the code the point's scene may name. Never
    raises for a bad point: errors become ``PointResult(ok=False, error=...)``.
    """
    import warnings

    from ..errors import ConvergenceWarning, InstabilityWarning, PlausibilityWarning
    from ..analysis.pipeline import solve
    from .scenefile import scene_from_dict
    if pin:
        pin_process()
    t0 = time.perf_counter()
    try:
        scene = scene_from_dict(point.scene, trust=trust)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            warnings.simplefilter("ignore", InstabilityWarning)
            # the table has the peaks and the stability; a warning per point from every worker is noise
            warnings.simplefilter("ignore", PlausibilityWarning)
            res = solve(scene, progress=False)  # the sweep has its own bar
        fund = res.frequencies(1).fundamental if frequencies else float("nan")
        mu = np.abs(np.asarray(res.floquet_multipliers))
        return PointResult(point.index, point.params, True, "", time.perf_counter() - t0, bool(res.converged),
                           bool(res.stable), int(res.iterations), float(mu.max()) if mu.size else float("nan"),
                           float(fund), tuple(res.peaks()), _worker_id(),
                           tuple(res.error.links) if res.error is not None else (),
                           bool(res.error.met) if res.error is not None else None)
    except KedError as e:
        msg = str(e)
    except KeyboardInterrupt:
        raise
    except BaseException as e:  # noqa: BLE001 - one bad point (even a sys.exit in its builder) must not end the sweep
        log.debug("sweep point %d failed", point.index, exc_info=True)
        where = traceback.extract_tb(e.__traceback__)
        what = f"it called sys.exit({e.code!r})" if isinstance(e, SystemExit) else f"{type(e).__name__}: {e}"
        msg = f"{what} ({where[-1].name})" if where else what
    return PointResult(point.index, point.params, False, " ".join(msg.split()), time.perf_counter() - t0,
                       worker=_worker_id())


# ---------------------------------------------------------------- tables
#: result columns of the tidy table, after the point index and the axis columns
TABLE_COLUMNS = ("link", "peak_deflection_m", "deflection_angle_rad", "peak_stress_Pa", "stress_angle_rad",
                 "stress_station_m", "deflection_time_error", "stress_time_error", "error_estimate_met",
                 "fundamental_Hz", "spectral_radius", "stable", "converged", "iterations",
                 "wall_time_s", "ok", "error")


def _cell(v):
    if isinstance(v, (list, tuple)):
        return "+".join(str(x) for x in v)
    return v


def point_rows(p: PointResult, keys: Sequence[str]) -> list[tuple]:
    """The rows of one point in the tidy table (see :class:`SweepTable`)."""
    nan = float("nan")
    pv = dict(p.params)
    head = (p.index,) + tuple(_cell(pv.get(k)) for k in keys)
    tail = (p.fundamental, p.spectral_radius, p.stable, p.converged, p.iterations, p.wall_time, p.ok, p.error)
    errs = {e.link: e for e in p.errors}
    met = "" if p.error_met is None else p.error_met
    if not p.peaks:
        return [head + ("", nan, nan, nan, nan, nan, nan, nan, "") + tail]
    out = []
    for lp in p.peaks:
        e = errs.get(lp.link)
        out.append(head + (lp.link, lp.deflection, lp.deflection_angle, lp.stress, lp.stress_angle,
                           lp.stress_station, e.deflection if e else nan, e.stress if e else nan, met) + tail)
    return out


def csv_cells(row: tuple) -> list:
    """A table row as CSV cells (floats with full precision; NaN and infinities, values that are
    not known or beyond floating point, as an empty cell)."""
    return [(repr(float(v)) if math.isfinite(v) else "") if isinstance(v, float) else v for v in row]


@dataclass(frozen=True)
class SweepTable:
    """A tidy table: one row per (grid point, flexible link); failed points have one row.

    Columns ``point``, one per axis (its dotted key), then :data:`TABLE_COLUMNS`.
    """

    names: tuple[str, ...]
    rows: tuple[tuple, ...]

    def columns(self) -> dict[str, np.ndarray]:
        """The table as columns (numeric columns as float arrays)."""
        out = {}
        for j, name in enumerate(self.names):
            vals = [r[j] for r in self.rows]
            if vals and all(isinstance(v, (int, float, np.number)) and not isinstance(v, bool) for v in vals):
                out[name] = np.array(vals, dtype=float)
            else:
                out[name] = np.array(vals, dtype=object)
        return out

    def __len__(self):
        return len(self.rows)

    def to_csv(self, path) -> Path:
        """Write the table as CSV (floats with full precision)."""
        path = Path(path)
        with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(self.names)
            for r in self.rows:
                w.writerow(csv_cells(r))
        return path


@dataclass(frozen=True)
class SweepResult:
    """All points of a sweep, in grid order.

    Attributes
    ----------
    axes : tuple of (str, tuple)
        The swept keys and values.
    points : tuple of PointResult
    wall_time : float
        Seconds for the whole sweep (including starting the workers).
    scheduler : str
        Where it ran.
    """

    axes: tuple[tuple[str, tuple], ...]
    points: tuple[PointResult, ...]
    wall_time: float
    scheduler: str
    _table: list = field(default_factory=list, repr=False, compare=False)

    @property
    def failed(self) -> tuple[PointResult, ...]:
        """The points that could not be solved."""
        return tuple(p for p in self.points if not p.ok)

    def table(self) -> SweepTable:
        """The tidy table (see :class:`SweepTable`)."""
        if self._table:
            return self._table[0]
        keys = [k for k, _ in self.axes]
        names = ("point",) + tuple(keys) + TABLE_COLUMNS
        rows = []
        for p in self.points:
            rows.extend(point_rows(p, keys))
        t = SweepTable(names, tuple(rows))
        self._table.append(t)
        return t

    def to_csv(self, path) -> Path:
        """Write :meth:`table` as CSV."""
        return self.table().to_csv(path)

    def plot(self, path, x: str | None = None, y: str = "peak_stress_Pa") -> Path:
        """Peak stress (or ``y``) vs the axis ``x`` (default ``speed_rpm`` if swept, else the
        first numeric axis), one curve per link and combination of the other axes."""
        from . import plots
        keys = [k for k, _ in self.axes]
        if x is None:
            numeric = [k for k, v in self.axes
                       if all(isinstance(e, (int, float)) and not isinstance(e, bool) for e in v)]
            x = "speed_rpm" if "speed_rpm" in numeric else (numeric[0] if numeric else keys[0])
        if x not in keys:
            raise InputError(f"sweep plot: x must be a swept key ({', '.join(keys)}), got {x!r}")
        by = ["link"] + [k for k in keys if k != x]
        return plots.sweep_peaks(self.table(), path, x=x, y=y, by=by)


# ------------------------------------------------------------- executors
def _progress(total: int, progress: bool | None):
    from tqdm.auto import tqdm
    return tqdm(total=total, desc="sweep", unit="point", file=sys.stderr, disable=None if progress is None
                else not progress, dynamic_ncols=True)


def _failed(p: SweepPoint, e: BaseException) -> PointResult:
    return PointResult(p.index, p.params, False, f"{type(e).__name__}: {' '.join(str(e).split())}")


def _run_futures(submit, points, bar, wait, on_result=None, out=None, lost=None):
    """Submit every point, record each result as it completes; with ``lost`` (a list), points
    whose pool broke (a worker died) go there instead of being recorded as failed."""
    futs = {submit(p): p for p in points}
    out = {} if out is None else out
    for fut in wait(list(futs)):
        p = futs[fut]
        try:
            r = fut.result()
        except cf.process.BrokenProcessPool as e:
            if lost is None:
                r = _failed(p, e)
            else:
                lost.append(p)
                continue
        except Exception as e:  # noqa: BLE001 - e.g. the result could not be unpickled
            r = _failed(p, e)
        _record(out, r, bar, on_result)
    return out


def _record(out, r: PointResult, bar, on_result) -> None:
    out[r.index] = r
    bar.update(1)
    if not r.ok:
        log.info("sweep point %d %s failed: %s", r.index, dict(r.params), r.error)
    if on_result is not None:
        on_result(r)


#: Times a point lost to a dead worker process is solved again before it is
#: recorded as failed (the retry runs it alone in a fresh worker, so the point
#: that kills its worker is told apart from the ones that ran beside it).
RETRIES = 1


def _marked(fn, mark_dir: str, point: SweepPoint):
    """Run ``fn(point)`` with a marker file in ``mark_dir`` while it runs (in a worker)."""
    mark = os.path.join(mark_dir, str(point.index))
    with open(mark, "w"):
        pass
    try:
        return fn(point)
    finally:
        try:
            os.unlink(mark)
        except OSError:
            pass


def _pool_round(fn, points, workers, out, bar, on_result):
    """Solve ``points`` on a fresh pool; returns the points lost to a broken pool."""
    lost = []
    with cf.ProcessPoolExecutor(max_workers=workers, initializer=_init_worker, initargs=(os.getpid(),),
                                mp_context=_mp_context()) as ex:
        _run_futures(lambda p: ex.submit(fn, p), points, bar, cf.as_completed, on_result, out, lost)
    return lost


def _run_pool(fn, points, workers, bar, on_result=None, retries: int = RETRIES):
    """A process pool that survives dead workers.

    When a worker process dies (killed, out of memory), every unfinished
    point of the pool is lost with it. The points that had not started go
    back to a new pool; each point that was running is solved again alone in
    a fresh one-worker pool, up to ``retries`` times, and recorded as failed
    if its worker dies again.
    """
    import tempfile
    out: dict[int, PointResult] = {}
    deaths: dict[int, int] = {}
    queue = list(points)
    with tempfile.TemporaryDirectory(prefix="kedfem-sweep-") as marks:
        import functools
        mfn = functools.partial(_marked, fn, marks)
        while queue:
            lost = _pool_round(mfn, queue, workers, out, bar, on_result)
            queue = []
            if not lost:
                break
            running = {int(n) for n in os.listdir(marks) if n.isdigit()}
            for n in os.listdir(marks):
                os.unlink(os.path.join(marks, n))
            for p in lost:
                if p.index not in running:
                    queue.append(p)  # not started: no blame
                    continue
                log.warning("sweep point %d %s: its worker process died; solving it again alone",
                            p.index, dict(p.params))
                deaths[p.index] = deaths.get(p.index, 0) + 1
                while True:
                    if deaths[p.index] > retries:
                        _record(out, PointResult(
                            p.index, p.params, False,
                            f"its worker process died {deaths[p.index]} times (killed by a signal or out of "
                            f"memory), the last time solving it alone", worker=""), bar, on_result)
                        break
                    if not _pool_round(mfn, [p], 1, out, bar, on_result):
                        break
                    deaths[p.index] += 1
            if queue:
                log.warning("sweep: a worker process died; %d unstarted point(s) go to a new pool", len(queue))
    return out


def run_sweep(base: Mapping | None = None, axes: Mapping[str, Sequence] | None = None, *,
              points: Sequence[SweepPoint] | None = None, builder=None, scheduler: str = "processes", executor: cf.Executor | None = None, client=None,
              max_workers: int | None = None, progress: bool | None = None,
              frequencies: bool = True, done: Mapping[int, PointResult] | None = None,
              on_result=None, retries: int = RETRIES, trust=None) -> SweepResult:
    """Solve a grid of scenes in parallel.

    Parameters
    ----------
    base : mapping, optional
        Base scene dictionary (TOML layout); unused with ``points``. Its ``mechanism`` may be a
        catalogue name, a table, or a built :class:`kedfem.Mechanism` (then only scene keys can
        be swept: the speed, damping, solver).
    axes : mapping of str to sequence
        Swept dotted keys and their values (see :func:`make_points`); ``mechanism.<parameter>``
        for a builder's parameters.
    builder : callable or str, optional
        The mechanism's builder: a module-level function ``build(**params) -> Mechanism``, or
        ``"package.module:function"`` / ``"path/to/file.py:function"``. It replaces ``base``'s
        mechanism name (``base["mechanism"]`` may then hold fixed parameters). Workers load it by
        its module or file (:func:`kedfem.catalogue.reference_of`).
    points : sequence of SweepPoint, optional
        Explicit points instead of a grid (``base`` and ``axes`` are then
        ignored; the table's axis columns are the points' parameter keys).
    scheduler : str
        ``"processes"``, ``"serial"``, ``"local"`` (Dask LocalCluster) or a
        Dask scheduler address ``"tcp://host:port"``; ignored with
        ``executor`` or ``client``.
    executor : concurrent.futures.Executor, optional
        Run on this executor (left running).
    client : dask.distributed.Client, optional
        Run on this Dask client (left running).
    max_workers : int, optional
        Workers of a pool or LocalCluster this function starts (default: CPU count).
    progress : bool, optional
        tqdm progress bar on stderr (default: only on a terminal).
    frequencies : bool
        Also compute each point's fundamental frequency.
    done : mapping of int to PointResult, optional
        Points already solved (by index, e.g. read back from a partial table
        with :class:`kedfem.io.sweep_journal.SweepJournal`): not solved again.
    on_result : callable, optional
        Called in this process with each new :class:`PointResult` as it
        completes (e.g. to append it to a partial table).
    retries : int
        With ``scheduler="processes"``: times a point whose worker process
        died is solved again (alone in a fresh worker) before it is recorded
        as failed; the points that had not started go to a new pool.
    trust : kedfem.trust.Trust, bool or targets, optional
        Code the scenes may name besides catalogue mechanisms (:mod:`kedfem.trust`; ``True``
        for a base your own code wrote). ``builder`` is trusted.

    Returns
    -------
    SweepResult
    """
    import functools

    from ..checks import flag
    from ..trust import Trust
    if not isinstance(scheduler, str):
        raise InputError(f"sweep: scheduler must be 'processes', 'serial', 'local' or a Dask address "
                         f"'tcp://host:port', got {type(scheduler).__name__} {scheduler!r:.60}")
    frequencies = flag("sweep", "frequencies", frequencies)
    trust = Trust.of(trust, "run_sweep: trust")
    if builder is not None:
        base = _with_builder(base, builder)
        trust = trust | Trust.of_reference(base["mechanism"]["name"])
    if points is None:
        if axes is not None and not isinstance(axes, Mapping):
            raise InputError(f"sweep: axes must be a mapping of dotted keys to lists of values, got "
                             f"{type(axes).__name__}")
        points = make_points(base if base is not None else {}, axes or {})
        ax = tuple(_normalize_axes(axes).items())
    else:
        if isinstance(points, (str, bytes, Mapping)) or not isinstance(points, (Sequence, np.ndarray)):
            raise InputError(f"sweep: points must be a sequence of SweepPoint, got {type(points).__name__}")
        points = list(points)
        bad = [p for p in points if not isinstance(p, SweepPoint)]
        if bad:
            raise InputError(f"sweep: points must be SweepPoint objects (kedfem.io.sweep.make_points), got "
                             f"{type(bad[0]).__name__} {bad[0]!r}")
        keys = list(dict.fromkeys(k for p in points for k, _ in p.params))
        ax = tuple((k, tuple(dict.fromkeys(_cell(dict(p.params).get(k)) for p in points))) for k in keys)
    if max_workers is not None and (isinstance(max_workers, bool) or not isinstance(max_workers, int)
                                    or max_workers < 1):
        raise InputError(f"sweep: max_workers must be an integer >= 1, got {max_workers!r}")
    workers = max_workers or os.cpu_count() or 1
    if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
        raise InputError(f"sweep: retries must be an integer >= 0, got {retries!r}")
    fn = functools.partial(run_point, frequencies=frequencies, trust=trust)
    done = {int(k): v for k, v in (done or {}).items()}
    todo = [p for p in points if p.index not in done]
    t0 = time.perf_counter()
    with _progress(len(todo), progress) as bar:
        if executor is not None:
            where = type(executor).__name__
            out = _run_futures(lambda p: executor.submit(fn, p), todo, bar, cf.as_completed, on_result)
        elif client is not None:
            where = f"dask {getattr(getattr(client, 'scheduler', None), 'address', 'client')}"
            out = _run_dask(client, fn, todo, bar, on_result)
        elif scheduler == "serial":
            where = "serial"
            out = {}
            for p in todo:
                _record(out, run_point(p, frequencies=frequencies, pin=False, trust=trust), bar, on_result)
        elif scheduler == "processes":
            where = f"process pool ({workers} workers)"
            out = _run_pool(fn, todo, workers, bar, on_result, retries)
        elif scheduler == "local" or str(scheduler).startswith(("tcp://", "tls://", "ws://", "wss://",
                                                                  "inproc://", "ucx://")):
            dd = require("distributed", "dask", "a Dask sweep")
            if scheduler == "local":
                where = f"dask LocalCluster ({workers} workers)"
                with dd.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                     dashboard_address=None) as cluster, dd.Client(cluster) as cl:
                    out = _run_dask(cl, fn, todo, bar, on_result)
            else:
                where = f"dask {scheduler}"
                try:
                    cl = dd.Client(scheduler, timeout="10s")
                except (OSError, TimeoutError) as e:
                    raise KedError(f"sweep: cannot connect to the Dask scheduler {scheduler}: {e}") from None
                with cl:
                    out = _run_dask(cl, fn, todo, bar, on_result)
        else:
            raise InputError(f"sweep: scheduler must be 'processes', 'serial', 'local' or a Dask address "
                             f"'tcp://host:port', got {scheduler!r}")
    wall = time.perf_counter() - t0
    out.update(done)
    res = tuple(out[p.index] for p in points)
    nf = sum(not r.ok for r in res)
    log.info("sweep: %d points on %s in %.2f s (%d failed)", len(res), where, wall, nf)
    return SweepResult(ax, res, wall, where)


def _with_builder(base: Mapping | None, builder) -> dict:
    """``base`` with its mechanism named by ``builder``'s reference (see :func:`run_sweep`)."""
    from .. import catalogue
    ref = catalogue.canonical(builder) if isinstance(builder, str) else catalogue.reference_of(builder)
    if not catalogue.is_reference(ref):
        raise InputError(f"sweep: builder must be a function or 'module:function' / 'file.py:function', "
                         f"got {builder!r}")
    out = dict(base or {})
    mech = out.get("mechanism")
    params = {k: v for k, v in mech.items() if k not in ("name", "builder")} if isinstance(mech, Mapping) else {}
    if mech is not None and not isinstance(mech, Mapping):
        raise InputError(f"sweep: with builder=, base['mechanism'] may only hold the builder's fixed parameters "
                         f"(a table), got {type(mech).__name__}")
    out["mechanism"] = {"name": ref, **params}
    return out


def _run_dask(client, fn, points, bar, on_result=None):
    from distributed import as_completed
    client.run(pin_process)
    futs = client.map(fn, list(points), pure=False)
    by_key = {f.key: p for f, p in zip(futs, points)}
    out = {}
    for fut in as_completed(futs):
        p = by_key[fut.key]
        try:
            r = fut.result()
        except Exception as e:  # noqa: BLE001 - e.g. KilledWorker
            r = _failed(p, e)
        _record(out, r, bar, on_result)
    return out

