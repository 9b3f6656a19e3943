"""Accuracy versus cost: what each solver knob buys, measured (``kedfem bench``).

For three mechanisms -- the slider-crank (linear, rigid crank, one flexible
rod), the four-bar (linear, three flexible links in a closed loop) and the
mould oscillator (the default scene: non-linear, friction) -- the error of
the quantities an engineer reads is measured against a converged reference,
together with the wall time of :func:`kedfem.solve`, while one knob at a time
is varied:

* time elements ``steps`` (36 .. 5760) for each hold (``zoh``, ``foh``,
  ``magnus2``);
* the accuracy ``delta`` asked from each matrix exponential (the paper's
  Table 1 values, 1e-2 .. 1e-16);
* frame elements per link;
* Craig-Bampton modes per link (with and without the static correction);
* the tolerance ``eps`` of the non-linear iteration (mould oscillator).

Quantities and errors
---------------------
``deflection``: mid-span deflection relative to the chord of the chosen links;
``stress``: the largest normal stress over the stations of each chosen link;
``frequency``: the cycle mean of the lowest state-space frequency at the
converged state, over 36 equally spaced crank positions. The error of a peak
is ``|max_k |q(t_k)| - max_k |q_ref(t_k)|| / max |q_ref|`` with both maxima
taken over the SAME time nodes ``t_k`` of the run (the reference is sampled
there), so it measures the solution, not where the grid happens to sample a
peak; the worst link counts. The history error is
``max_k |q(t_k) - q_ref(t_k)| / max |q_ref|``: the deflection and stress at
every crank angle of the run, so it also sees a phase lag, which a peak does
not (``zoh`` lags by half a time element: its peaks converge at second order,
its histories at first). ``err`` is the largest of the peak deflection, peak
stress and frequency errors, ``err_hist`` the larger history error. The CSV also
holds the peak error "as read" (against the reference's peak over its own,
much finer grid, so it includes the sampling of the peak by the grid).

References
----------
Time knobs (steps, hold, delta, eps, presets): the same model solved with
``magnus2`` on the three finest grids ``n/4, n/2, n``; where the observed
order of the differences is consistent (0.7 .. 2.6) the finest two are
Richardson-extrapolated with order 1 or 2 and the size of the correction is
the reference's uncertainty, else the finest solve is the reference and the
last difference its uncertainty. Elements per link: the finest mesh at the
same time grid and hold. Craig-Bampton: the full model at the same mesh, time
grid and hold.

Timing: wall time of :func:`kedfem.solve` (kinematics, assembly, solve),
median of three solves when one takes less than 1.5 s, else one solve; the
machine is measured as it is, so shared-host noise is in the numbers.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime
import logging
import math
import os
import platform
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from .effects import ModalDamping
from .errors import InputError
from .scene import Scene

__all__ = ["Setting", "Measurement", "Reference", "StudyResult", "CASES", "preset_setting",
           "run_study", "write_outputs", "format_summary", "run_cli", "main"]

log = logging.getLogger(__name__)

#: time elements per cycle scanned for every hold (all divide 5760, the reference grid)
N_LIST = (36, 90, 180, 360, 720, 1440, 2880, 5760)
#: the paper's Table 1 accuracies plus the coarse end
DELTAS = (1e-2, 1e-4, 1e-6, 1e-9, 1e-13, 1e-16)
#: error targets of the summary table
TARGETS = (1e-2, 1e-3, 1e-4)
#: frequencies are evaluated at this many equally spaced crank positions
FREQ_NODES = 36
#: a solve faster than this [s] is repeated and the median of three is reported
REPEAT_BELOW = 1.5

LINEAR = ("inertia", "coupling", "axial_stiffening")


# --------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class Setting:
    """One solver configuration of a mechanism's scene.

    Attributes
    ----------
    hold : str
        ``"zoh"``, ``"foh"`` or ``"magnus2"``.
    steps : int
        Time elements per cycle.
    delta : float or None
        Exponential accuracy (``None``: automatic).
    elements : int or None
        Frame elements per flexible link (``None``: the mechanism's default mesh).
    modes : int or None
        Craig-Bampton fixed-interface modes per link (``None``: full model).
    static_correction : bool
        Craig-Bampton static correction vectors (ignored for the full model).
    eps : float or None
        Non-linear tolerance (``None``: the scene's default).
    """

    hold: str = "magnus2"
    steps: int = 360
    delta: float | None = None
    elements: int | None = None
    modes: int | None = None
    static_correction: bool = True
    eps: float | None = None

    @property
    def reduction_label(self) -> str:
        if self.modes is None:
            return "full"
        return f"CB({self.modes}{'+sc' if self.static_correction else ''})"

    def label(self) -> str:
        """Short human-readable description."""
        parts = [f"{self.hold} n={self.steps}"]
        if self.delta is not None:
            parts.append(f"delta={self.delta:.0e}")
        if self.elements is not None:
            parts.append(f"{self.elements} el/link")
        if self.modes is not None:
            parts.append(self.reduction_label)
        if self.eps is not None:
            parts.append(f"eps={self.eps:.0e}")
        return ", ".join(parts)


@dataclass(frozen=True)
class Case:
    """A mechanism of the study: its scene and the links whose quantities count."""

    name: str
    label: str
    deflection_links: tuple[str, ...]
    stress_links: tuple[str, ...]
    default_elements: int
    nonlinear: bool
    why: str

    def scene(self, s: Setting) -> Scene:
        """The scene of setting ``s``."""
        import kedfem as kf
        red = None if s.modes is None else kf.CraigBampton(modes=s.modes, static_correction=s.static_correction)
        if self.name == "mould":
            from .defaults import default_scene
            kw = {}
            if s.elements is not None:
                kw = dict(leaf_elements=s.elements, rod_elements=max(1, s.elements // 2))
            sc = default_scene(steps=s.steps, **kw)
            rep = dict(hold=s.hold, delta=s.delta, reduction=red)
            if s.eps is not None:
                rep["eps"] = s.eps
            return dataclasses.replace(sc, **rep)
        if self.name == "slider_crank":
            from mechanisms import slider_crank as mod
        else:
            from mechanisms import four_bar as mod
        mech = mod.build(elements=s.elements or self.default_elements)
        return Scene(mech, steps=s.steps, effects=LINEAR, damping=ModalDamping(0.02), hold=s.hold,
                     delta=s.delta, reduction=red, name=self.label)


CASES: dict[str, Case] = {c.name: c for c in (
    Case("slider_crank", "slider-crank", ("rod",), ("rod",), 8, False,
         "rigid crank at 150 rad/s, steel rod 0.30 m (8 elements), slider mass; linear effects, "
         "2 % modal damping"),
    Case("four_bar", "four-bar", ("coupler", "follower"), ("crank", "coupler", "follower"), 4, False,
         "crank, coupler and follower flexible (4 elements each), 200 rpm, linear effects, 2 % modal "
         "damping; the crank's mid-span chord deflection (0.09 mm, a twelfth of the others: short and "
         "18x stiffer) is left out, its root stress is in"),
    Case("mould", "mould oscillator", ("leaf_inner", "leaf_outer"),
         ("rod_outer", "rod_inner", "leaf_inner", "leaf_outer"), 4, True,
         "the default scene (kf.default_scene()): all effects, friction, cubic spring, geometric "
         "non-linearity; the rods' mid-span deflection (3e-7 m) is left out, their stress is in"),
)}


# ----------------------------------------------------------------------- quantities
@dataclass(frozen=True)
class Quantities:
    """What the engineer reads, as time histories at the run's nodes."""

    deflection: np.ndarray   # (n, len(deflection_links)) [m]
    stress: np.ndarray       # (n, len(stress_links)) [Pa], max over the link's stations
    frequency: float         # [Hz]

    @property
    def n(self) -> int:
        return int(self.deflection.shape[0])


def quantities(case: Case, res) -> Quantities:
    """Deflection and stress histories and the fundamental frequency of a solved scene."""
    w = np.stack([res.deflection(lk, 0.5, relative_to="chord") for lk in case.deflection_links], axis=1)
    s = np.stack([res.stress(lk).max(axis=1) for lk in case.stress_links], axis=1)
    n = res.n
    step = max(1, n // FREQ_NODES) if n % FREQ_NODES == 0 else 1
    nodes = np.arange(0, n, step)
    f = res.frequencies(1, nodes=nodes).fundamental
    return Quantities(w, s, float(f))


@dataclass(frozen=True)
class Measurement:
    """One timed solve and what it produced."""

    case: str
    knob: str
    setting: Setting
    n_dof: int
    time: float               # median wall time [s]
    times: tuple[float, ...]
    iterations: int
    converged: bool
    q: Quantities


@dataclass(frozen=True)
class Reference:
    """Converged quantities on a reference grid, with an uncertainty estimate."""

    description: str
    deflection: np.ndarray
    stress: np.ndarray
    frequency: float
    uncertainty: dict          # quantity -> relative uncertainty
    order: dict                # quantity -> observed order (nan if not used)

    @property
    def n(self) -> int:
        return int(self.deflection.shape[0])


def _reference_from(m: Measurement, description: str) -> Reference:
    return Reference(description, m.q.deflection, m.q.stress, m.q.frequency,
                     {"deflection": 0.0, "stress": 0.0, "frequency": 0.0}, {})


def _richardson(a4, a2, a1, scale):
    """Extrapolate the finest of three solves with halving steps, if their order is consistent.

    ``a4, a2, a1``: one quantity on the grids ``n/4, n/2, n`` (1-D over time, or
    scalars as length-1 arrays with equal grids). The order ``p`` is observed on
    the coarsest grid from the two differences; if it lies in 0.7 .. 2.6 the
    finest two are extrapolated with ``p = 1`` or ``2`` (the nearer) and the
    size of the correction is the uncertainty, else the finest is kept and the
    last difference is the uncertainty. Returns ``(value on the n/2 grid,
    uncertainty relative to scale, observed order)``.
    """
    c2 = a1.shape[0] // a2.shape[0]
    c4 = a2.shape[0] // a4.shape[0]
    f1 = a1[::c2]                     # finest on the n/2 grid
    d1 = float(np.max(np.abs(a4 - a2[::c4]))) / scale
    d2 = float(np.max(np.abs(a2[::c4] - f1[::c4]))) / scale
    if d2 == 0.0:
        return f1, 0.0, float("nan")
    p_obs = math.log2(d1 / d2) if d1 > 0 else float("nan")
    if math.isfinite(p_obs) and 0.7 <= p_obs <= 2.6:
        p = 1 if p_obs < 1.5 else 2
        val = f1 + (f1 - a2) / (2 ** p - 1)
        return val, float(np.max(np.abs(val - f1))) / scale, p_obs
    return f1, float(np.max(np.abs(a2 - f1))) / scale, p_obs


def time_reference(levels: list[Measurement]) -> Reference:
    """Reference from three ``magnus2`` solves at ``n/4, n/2, n`` (finest last).

    The histories are returned on the grid of ``n/2``.
    """
    m4, m2, m1 = levels
    out, unc, order = {}, {}, {}
    for name in ("deflection", "stress"):
        a4, a2, a1 = (getattr(m.q, name) for m in (m4, m2, m1))
        scale = np.abs(a1).max(axis=0)
        cols, us, ps = [], [], []
        for j in range(a1.shape[1]):
            v, u, p = _richardson(a4[:, j], a2[:, j], a1[:, j], max(float(scale[j]), 1e-300))
            cols.append(v)
            us.append(u)
            ps.append(p)
        out[name] = np.stack(cols, axis=1)
        unc[name] = max(us)
        order[name] = ps
    f = [np.array([m.q.frequency]) for m in (m4, m2, m1)]
    fv, fu, fp = _richardson(*f, abs(m1.q.frequency))
    unc["frequency"] = fu
    order["frequency"] = [fp]
    desc = (f"{m1.setting.hold} n={m1.setting.steps}, Richardson-extrapolated with n={m2.setting.steps} "
            f"where the order observed with n={m4.setting.steps} is consistent")
    return Reference(desc, out["deflection"], out["stress"], float(fv[0]), unc, order)


def errors(q: Quantities, ref: Reference) -> dict:
    """Relative errors of a run's quantities against a reference (see the module docstring)."""
    out = {}
    for name in ("deflection", "stress"):
        a = getattr(q, name)
        r = getattr(ref, name)
        if r.shape[0] % a.shape[0] == 0:
            rs = r[:: r.shape[0] // a.shape[0]]
        elif a.shape[0] % r.shape[0] == 0:  # a run finer than the reference grid
            a = a[:: a.shape[0] // r.shape[0]]
            rs = r
        else:
            raise InputError(f"errors: {a.shape[0]} time nodes do not nest with the reference's {r.shape[0]}")
        scale = np.abs(r).max(axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        peak = np.abs(np.abs(a).max(axis=0) - np.abs(rs).max(axis=0)) / scale
        hist = np.abs(a - rs).max(axis=0) / scale
        read = np.abs(np.abs(a).max(axis=0) - np.abs(r).max(axis=0)) / scale
        out[name] = float(peak.max())
        out[f"hist_{name}"] = float(hist.max())
        out[f"read_{name}"] = float(read.max())
    out["frequency"] = abs(q.frequency - ref.frequency) / abs(ref.frequency)
    out["err"] = max(out["deflection"], out["stress"], out["frequency"])
    out["err_hist"] = max(out["hist_deflection"], out["hist_stress"])
    return out


# ---------------------------------------------------------------------------- plans
@dataclass(frozen=True)
class Plan:
    """Which settings of one mechanism the study measures."""

    steps: dict                       # hold -> tuple of time elements
    reference: tuple                  # magnus2 time elements (n/4, n/2, n) of the reference
    delta_base: Setting | None = None
    deltas: tuple = ()
    elements_base: Setting | None = None
    elements: tuple = ()              # the last one is the reference mesh
    cb_base: Setting | None = None    # mesh and time grid of the Craig-Bampton comparison
    cb_modes: tuple = ()              # with static correction
    cb_plain: tuple = ()              # without
    cb_speed: Setting | None = None   # full model on a fine mesh, timed against CB(4)
    eps_base: Setting | None = None
    eps: tuple = ()
    presets: tuple = ()               # names of ACCURACY_PRESETS to measure


def _plans(quick: bool) -> dict[str, Plan]:
    M = "magnus2"
    if quick:
        return {
            "slider_crank": Plan(
                steps={"zoh": (36, 90), M: (36, 90)}, reference=(90, 180, 360),
                delta_base=Setting(M, 90), deltas=(1e-4, 1e-13),
                elements_base=Setting(M, 90), elements=(2, 4),
                cb_base=Setting(M, 90, elements=4), cb_modes=(2,), presets=("fast",)),
            "four_bar": Plan(steps={M: (36, 90)}, reference=(90, 180, 360), presets=("fast",)),
            "mould": Plan(steps={"foh": (36, 90), M: (36, 90)}, reference=(90, 180, 360),
                          eps_base=Setting(M, 90), eps=(1e-2, 1e-6), presets=("fast",)),
        }
    return {
        "slider_crank": Plan(
            steps={h: N_LIST for h in ("zoh", "foh", M)}, reference=(2880, 5760, 11520),
            delta_base=Setting(M, 1440), deltas=DELTAS,
            elements_base=Setting(M, 720), elements=(1, 2, 4, 8, 16, 32),
            cb_base=Setting(M, 1440), cb_modes=(0, 1, 2, 4, 8), cb_plain=(2, 4, 8),
            cb_speed=Setting(M, 720, elements=32), presets=("fast", "default", "tight")),
        "four_bar": Plan(
            steps={h: N_LIST for h in ("zoh", "foh", M)}, reference=(5760, 11520, 23040),
            delta_base=Setting(M, 1440), deltas=DELTAS,
            elements_base=Setting(M, 1440), elements=(1, 2, 4, 8),
            cb_base=Setting(M, 5760), cb_modes=(1, 2, 4, 8), cb_plain=(4,),
            presets=("fast", "default", "tight")),
        "mould": Plan(
            steps={"zoh": N_LIST[:-2], "foh": N_LIST[:-2], M: N_LIST[:-2]}, reference=(1440, 2880, 5760),
            delta_base=Setting(M, 720), deltas=DELTAS,
            elements_base=Setting(M, 360), elements=(1, 2, 4, 8),
            eps_base=Setting(M, 720), eps=(1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8),
            presets=("fast", "default", "tight")),
    }


def preset_setting(name: str) -> Setting:
    """The :class:`Setting` of the scene preset ``Scene(accuracy=name)``."""
    from .scene import ACCURACY_PRESETS
    p = ACCURACY_PRESETS[name]
    return Setting(p["hold"], p["steps"], delta=p["delta"], eps=p["eps"])


# ---------------------------------------------------------------------------- runner
@dataclass
class StudyResult:
    """Everything a study measured."""

    quick: bool
    rows: list = field(default_factory=list)          # dicts, one per measurement (CSV rows)
    measurements: dict = field(default_factory=dict)  # (case, Setting) -> Measurement
    references: dict = field(default_factory=dict)    # case -> Reference (time-converged)
    notes: list = field(default_factory=list)
    wall: float = 0.0
    machine: str = ""


def machine_info() -> str:
    """numpy/scipy versions, BLAS, CPUs, load, date."""
    import scipy
    try:
        import threadpoolctl
        blas = ", ".join(f"{d['internal_api']} {d.get('version') or ''} x{d['num_threads']}".strip()
                         for d in threadpoolctl.threadpool_info() if d["user_api"] == "blas")
    except Exception:  # pragma: no cover - optional dependency
        blas = "?"
    try:
        load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:  # pragma: no cover
        load = "?"
    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, load {load}; "
            f"Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
            f"BLAS {blas}; {datetime.datetime.now().isoformat(timespec='minutes')}")


def measure(case: Case, knob: str, s: Setting, repeats: bool = True) -> Measurement:
    """Solve the scene of ``s`` (timed) and read its quantities (not timed)."""
    from .pipeline import solve
    scene = case.scene(s)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        res = solve(scene)
        times = [time.perf_counter() - t0]
        if repeats and times[0] < REPEAT_BELOW:
            for _ in range(2):
                t0 = time.perf_counter()
                res = solve(scene)
                times.append(time.perf_counter() - t0)
        q = quantities(case, res)
    return Measurement(case.name, knob, s, res.model.n_dof, float(np.median(times)), tuple(times),
                       int(res.iterations), bool(res.converged), q)


class _Runner:
    def __init__(self, result: StudyResult, progress: Callable[[str], None] | None, repeats: bool):
        self.r = result
        self.progress = progress or (lambda msg: None)
        self.repeats = repeats

    def get(self, case: Case, knob: str, s: Setting) -> Measurement:
        key = (case.name, s)
        m = self.r.measurements.get(key)
        if m is None:
            m = measure(case, knob, s, self.repeats)
            self.r.measurements[key] = m
            log.info("%s %s %s: %.3f s", case.name, knob, s.label(), m.time)
        return m

    def row(self, case: Case, knob: str, m: Measurement, ref: Reference, ref_kind: str):
        e = errors(m.q, ref)
        s = m.setting
        row = dict(mechanism=case.name, knob=knob, hold=s.hold, steps=s.steps,
                   delta="auto" if s.delta is None else f"{s.delta:.0e}",
                   elements=s.elements or case.default_elements, reduction=s.reduction_label,
                   eps="" if not case.nonlinear else ("default" if s.eps is None else f"{s.eps:.0e}"),
                   n_dof=m.n_dof, iterations=m.iterations, converged=m.converged,
                   time_s=m.time, time_min_s=min(m.times), repeats=len(m.times),
                   err=e["err"], err_hist=e["err_hist"], err_deflection=e["deflection"], err_stress=e["stress"],
                   err_frequency=e["frequency"], err_hist_deflection=e["hist_deflection"],
                   err_hist_stress=e["hist_stress"], err_read_deflection=e["read_deflection"],
                   err_read_stress=e["read_stress"], reference=ref_kind,
                   ref_uncertainty=max(ref.uncertainty.values()),
                   peak_deflection_m=float(np.abs(m.q.deflection).max()),
                   peak_stress_Pa=float(np.abs(m.q.stress).max()), fundamental_Hz=m.q.frequency)
        self.r.rows.append(row)
        self.progress(f"{case.label:16s} {knob:9s} {s.label():38s} N={m.n_dof:3d} {1e3 * m.time:9.1f} ms  "
                      f"err {e['err']:.2e} (defl {e['deflection']:.1e}, stress {e['stress']:.1e}, "
                      f"freq {e['frequency']:.1e})")
        return row


def _case_names(mechanisms) -> list[str]:
    """The study's mechanisms (default all); an unknown name is an :class:`InputError`."""
    names = list(CASES) if mechanisms is None else list(mechanisms)
    for nm in names:
        if nm not in CASES:
            raise InputError(f"unknown mechanism {nm!r}; the study knows {', '.join(CASES)}")
    return names


def run_study(quick: bool = False, mechanisms=None, progress: Callable[[str], None] | None = None
              ) -> StudyResult:
    """Run the accuracy-versus-cost study.

    Parameters
    ----------
    quick : bool
        A few knob values per mechanism (a smoke run of some seconds).
    mechanisms : sequence of str, optional
        Subset of :data:`CASES` (default all).
    progress : callable, optional
        Called with one line of text per measurement.

    Returns
    -------
    StudyResult
    """
    names = _case_names(mechanisms)
    plans = _plans(quick)
    res = StudyResult(quick=quick, machine=machine_info())
    run = _Runner(res, progress, repeats=not quick)
    t_start = time.perf_counter()
    for nm in names:
        case, plan = CASES[nm], plans[nm]
        # warm-up (imports, first-use costs), not recorded
        measure(case, "warm-up", Setting("magnus2", 36), repeats=False)
        levels = [run.get(case, "reference", Setting("magnus2", n)) for n in plan.reference]
        ref = time_reference(levels)
        res.references[nm] = ref
        kind = f"time-converged: {ref.description}"
        run.progress(f"{case.label}: reference {ref.description}; uncertainty "
                     + ", ".join(f"{k} {v:.1e}" for k, v in ref.uncertainty.items()))
        for hold, ns in plan.steps.items():
            for n in ns:
                run.row(case, "steps", run.get(case, "steps", Setting(hold, n)), ref, kind)
        for n in plan.reference:
            if n not in plan.steps.get("magnus2", ()):
                run.row(case, "reference", run.get(case, "reference", Setting("magnus2", n)), ref, kind)
        if plan.delta_base is not None:
            for d in plan.deltas + (None,):
                s = dataclasses.replace(plan.delta_base, delta=d)
                run.row(case, "delta", run.get(case, "delta", s), ref, kind)
        if plan.eps_base is not None:
            for e in plan.eps:
                s = dataclasses.replace(plan.eps_base, eps=e)
                run.row(case, "eps", run.get(case, "eps", s), ref, kind)
        for pname in plan.presets:
            s = preset_setting(pname)
            run.row(case, f"preset:{pname}", run.get(case, f"preset:{pname}", s), ref, kind)
        if plan.elements_base is not None:
            meshes = [run.get(case, "elements", dataclasses.replace(plan.elements_base, elements=e))
                      for e in plan.elements]
            top = meshes[-1]
            mref = _reference_from(top, f"finest mesh ({plan.elements[-1]} el/link), same time grid")
            for m in meshes:
                run.row(case, "elements", m, mref, mref.description)
        if plan.cb_base is not None:
            full = run.get(case, "cb", plan.cb_base)
            cref = _reference_from(full, "full model, same mesh and time grid")
            for k in plan.cb_modes:
                m = run.get(case, "cb", dataclasses.replace(plan.cb_base, modes=k))
                run.row(case, "cb", m, cref, cref.description)
            for k in plan.cb_plain:
                m = run.get(case, "cb", dataclasses.replace(plan.cb_base, modes=k, static_correction=False))
                run.row(case, "cb", m, cref, cref.description)
        if plan.cb_speed is not None:
            full = run.get(case, "cb-speed", plan.cb_speed)
            cref = _reference_from(full, "full model, same mesh and time grid")
            run.row(case, "cb-speed", full, cref, cref.description)
            for sc_ in (True, False):
                m = run.get(case, "cb-speed", dataclasses.replace(plan.cb_speed, modes=4, static_correction=sc_))
                run.row(case, "cb-speed", m, cref, cref.description)
    res.wall = time.perf_counter() - t_start
    return res


# ---------------------------------------------------------------------------- outputs
CSV_COLUMNS = ("mechanism", "knob", "hold", "steps", "delta", "elements", "reduction", "eps", "n_dof",
               "iterations", "converged", "time_s", "time_min_s", "repeats", "err", "err_hist", "err_deflection",
               "err_stress", "err_frequency", "err_hist_deflection", "err_hist_stress",
               "err_read_deflection", "err_read_stress", "reference", "ref_uncertainty",
               "peak_deflection_m", "peak_stress_Pa", "fundamental_Hz")

_TIME_KNOBS = ("steps", "reference", "delta", "eps")


def _fmt_ms(t: float) -> str:
    ms = 1e3 * t
    return f"{ms:.0f} ms" if ms >= 10 else f"{ms:.1f} ms"


def _rows(result: StudyResult, case: str, knobs) -> list[dict]:
    return [r for r in result.rows if r["mechanism"] == case and (r["knob"] in knobs or any(
        r["knob"].startswith(k + ":") for k in knobs))]


def _setting_text(r: dict, case: Case) -> str:
    parts = [f"{r['hold']} n={r['steps']}"]
    if r["delta"] != "auto":
        parts.append(f"delta={r['delta']}")
    if r["elements"] != case.default_elements:
        parts.append(f"{r['elements']} el/link")
    if r["reduction"] != "full":
        parts.append(r["reduction"])
    if r["eps"] not in ("", "default"):
        parts.append(f"eps={r['eps']}")
    return ", ".join(parts)


def order_fit(rows: list[dict], floor: float, key: str = "err") -> tuple[float, float, int]:
    """Observed order and the n reaching 1e-6 for one hold's steps scan.

    Returns ``(order, n_1e-6, measured)``: the order fitted (least squares in
    log-log) to the last three errors above ``3 floor``; ``n_1e-6`` is the
    smallest measured n with error <= 1e-6 when there is one (``measured=1``),
    else extrapolated along the fitted line (``measured=0``).
    """
    pts = sorted((r["steps"], r[key]) for r in rows)
    hit = [n for n, e in pts if e <= 1e-6]
    good = [(n, e) for n, e in pts if e > 3 * floor and e > 0]
    order = float("nan")
    if len(good) >= 2:
        g = good[-3:]
        x = np.log([n for n, _ in g])
        y = np.log([e for _, e in g])
        order = float(-np.polyfit(x, y, 1)[0])
    if hit:
        return order, float(hit[0]), 1
    if math.isfinite(order) and order > 0 and good:
        n0, e0 = good[-1]
        return order, float(n0 * (e0 / 1e-6) ** (1.0 / order)), 0
    return order, float("nan"), 0


def format_summary(result: StudyResult) -> str:
    """The markdown report (tables) of a study."""
    L = []
    L.append("# Accuracy versus cost\n")
    L.append(f"Generated by `python benchmarks/accuracy_cost.py{' --quick' if result.quick else ''}` "
             f"(same as `kedfem bench`) in {result.wall:.0f} s on {result.machine}."
             + (" **Quick run: a few knob values, coarse references; not for conclusions.**" if result.quick else ""))
    L.append("")
    L.append("Error (*peaks*): the largest relative error of the peak mid-span deflection (relative to the "
             "chord), the peak stress and the fundamental frequency (cycle mean), peaks taken over the run's own "
             "time nodes in run and reference alike. *History*: the largest error of the deflection and stress "
             "at every crank angle of the run, relative to their peaks; it also sees phase errors, which peaks "
             "do not (zoh lags by half an element). `kedfem/bench.py` explains; the CSV has each part "
             "and the peak \"as read\" against the reference's finer grid. Time: wall time "
             "of `kf.solve` (kinematics + assembly + solve), median of 3 when under 1.5 s, on a 2-core "
             "shared machine (noisy: compare within a run).")
    L.append("")
    # ---------------------------------------------------------------- targets
    L.append("## For 1 %, 0.1 %, 0.01 % error you need ... and it costs ...\n")
    L.append("Cheapest measured setting (time elements, hold, delta, eps, presets; full model, the "
             "mechanism's own mesh) whose error against the time-converged reference is below the target.\n")
    L.append("| mechanism | error of | " + " | ".join(f"{100 * t:g} %" for t in TARGETS) + " |")
    L.append("|---|---|" + "---|" * len(TARGETS))
    for nm, ref in result.references.items():
        case = CASES[nm]
        rows = [r for r in _rows(result, nm, _TIME_KNOBS + ("preset",)) if r["reduction"] == "full"
                and r["elements"] == case.default_elements]
        floor = max(ref.uncertainty.values())
        n_dof = rows[0]["n_dof"] if rows else 0
        for key, what in (("err", "peaks, frequency"), ("err_hist", "histories")):
            cells = []
            for t in TARGETS:
                ok = [r for r in rows if r[key] <= t]
                if t < 3 * floor:
                    cells.append(f"below the reference's uncertainty ({floor:.0e})")
                elif not ok:
                    best = min(rows, key=lambda r: r[key]) if rows else None
                    cells.append("not reached" + (f" (best {best[key]:.1e}: {_setting_text(best, case)}, "
                                                  f"{_fmt_ms(best['time_s'])})" if best else ""))
                else:
                    r = min(ok, key=lambda r: r["time_s"])
                    cells.append(f"{_setting_text(r, case)}: **{_fmt_ms(r['time_s'])}** ({r[key]:.1e})")
            L.append(f"| {case.label} (N={n_dof}) | {what} | " + " | ".join(cells) + " |")
    L.append("")
    # ---------------------------------------------------------------- presets
    prs = [r for r in result.rows if r["knob"].startswith("preset:")]
    if prs:
        L.append("## What the presets deliver (`Scene(accuracy=...)`)\n")
        L.append("| mechanism | preset | setting | deflection | stress | frequency | history | "
                 "peak as read (defl / stress) | iterations | time |")
        L.append("|---|---|---|---|---|---|---|---|---|---|")
        for r in prs:
            case = CASES[r["mechanism"]]
            L.append(f"| {case.label} | {r['knob'].split(':')[1]} | {_setting_text(r, case)} | "
                     f"{r['err_deflection']:.1e} | {r['err_stress']:.1e} | {r['err_frequency']:.1e} | "
                     f"{r['err_hist']:.1e} | {r['err_read_deflection']:.1e} / {r['err_read_stress']:.1e} | {r['iterations']} | "
                     f"{_fmt_ms(r['time_s'])} |")
        L.append("")
    # ---------------------------------------------------------------- steps x hold
    L.append("## Time elements and hold: error of peaks / of histories / time\n")
    ns = sorted({r["steps"] for r in result.rows if r["knob"] == "steps"})
    L.append("| mechanism | hold | " + " | ".join(f"n={n}" for n in ns)
             + " | order (peaks / histories) | n for 1e-6 (peaks / histories) |")
    L.append("|---|---|" + "---|" * (len(ns) + 2))
    for nm, ref in result.references.items():
        case = CASES[nm]
        floor = max(ref.uncertainty["deflection"], ref.uncertainty["stress"])
        for hold in ("zoh", "foh", "magnus2"):
            rows = [r for r in _rows(result, nm, ("steps",)) if r["hold"] == hold]
            if not rows:
                continue
            by = {r["steps"]: r for r in rows}
            cells = [f"{by[n]['err']:.1e} / {by[n]['err_hist']:.1e} / {_fmt_ms(by[n]['time_s'])}" if n in by else ""
                     for n in ns]
            fits = [order_fit(rows, floor, key) for key in ("err", "err_hist")]
            n6s = ["" if not math.isfinite(n6) else (f"{n6:.0f} (measured)" if meas else f"~{n6:.1e} (extrapolated)")
                   for _, n6, meas in fits]
            L.append(f"| {case.label} | {hold} | " + " | ".join(cells)
                     + f" | {fits[0][0]:.2f} / {fits[1][0]:.2f} | {n6s[0]} / {n6s[1]} |")
    L.append("")
    # ---------------------------------------------------------------- delta
    drows = [r for r in result.rows if r["knob"] == "delta"]
    if drows:
        L.append("## Exponential accuracy delta: error / time\n")
        dl = [d for d in ("1e-02", "1e-04", "1e-06", "1e-09", "1e-13", "1e-16", "auto")
              if any(r["delta"] == d for r in drows)]
        L.append("| mechanism | setting | " + " | ".join(f"delta={d}" for d in dl) + " |")
        L.append("|---|---|" + "---|" * len(dl))
        for nm in result.references:
            rows = [r for r in drows if r["mechanism"] == nm]
            if not rows:
                continue
            by = {r["delta"]: r for r in rows}
            L.append(f"| {CASES[nm].label} | {rows[0]['hold']} n={rows[0]['steps']} | "
                     + " | ".join(f"{by[d]['err']:.1e} / {_fmt_ms(by[d]['time_s'])}" if d in by else ""
                                  for d in dl) + " |")
        L.append("")
    # ---------------------------------------------------------------- elements
    erows = [r for r in result.rows if r["knob"] == "elements"]
    if erows:
        L.append("## Elements per link: error against the finest mesh / time\n")
        L.append("(Same time grid and hold for all meshes; the time-discretisation errors of different "
                 "meshes differ, so differences below the time error of that grid are not meaningful.)\n")
        L.append("| mechanism | setting | elements | N | deflection | stress | frequency | time |")
        L.append("|---|---|---|---|---|---|---|---|")
        for r in erows:
            L.append(f"| {CASES[r['mechanism']].label} | {r['hold']} n={r['steps']} | {r['elements']} | {r['n_dof']} | "
                     f"{r['err_deflection']:.1e} | {r['err_stress']:.1e} | {r['err_frequency']:.1e} | "
                     f"{_fmt_ms(r['time_s'])} |")
        L.append("")
    # ---------------------------------------------------------------- Craig-Bampton
    crows = [r for r in result.rows if r["knob"] in ("cb", "cb-speed")]
    if crows:
        L.append("## Craig-Bampton: error against the full model (same mesh and time grid) / time\n")
        L.append("| mechanism | setting | reduction | N | deflection | stress | frequency | time | speed-up |")
        L.append("|---|---|---|---|---|---|---|---|---|")
        for r in crows:
            full = next((x for x in crows if x["mechanism"] == r["mechanism"] and x["knob"] == r["knob"]
                         and x["reduction"] == "full" and x["elements"] == r["elements"]
                         and x["steps"] == r["steps"]), None)
            if full is None:  # the full model of the cb scan is a steps row
                full = next((x for x in result.rows if x["mechanism"] == r["mechanism"] and x["reduction"] == "full"
                             and x["elements"] == r["elements"] and x["steps"] == r["steps"]
                             and x["hold"] == r["hold"] and x["delta"] == "auto"), None)
            spd = f"{full['time_s'] / r['time_s']:.1f}x" if full and r["reduction"] != "full" else ""
            L.append(f"| {CASES[r['mechanism']].label} | {r['hold']} n={r['steps']}, {r['elements']} el/link | "
                     f"{r['reduction']} | {r['n_dof']} | {r['err_deflection']:.1e} | {r['err_stress']:.1e} | "
                     f"{r['err_frequency']:.1e} | {_fmt_ms(r['time_s'])} | {spd} |")
        L.append("")
    # ---------------------------------------------------------------- eps
    prow = [r for r in result.rows if r["knob"] == "eps"]
    if prow:
        L.append("## Non-linear tolerance eps\n")
        L.append("| mechanism | setting | eps | iterations | error | time |")
        L.append("|---|---|---|---|---|---|")
        for r in prow:
            L.append(f"| {CASES[r['mechanism']].label} | {r['hold']} n={r['steps']} | {r['eps']} | {r['iterations']} | "
                     f"{r['err']:.1e} | {_fmt_ms(r['time_s'])} |")
        L.append("")
    # ---------------------------------------------------------------- references
    L.append("## References\n")
    L.append("| mechanism | quantities | reference | uncertainty (deflection / stress / frequency) | observed order |")
    L.append("|---|---|---|---|---|")
    for nm, ref in result.references.items():
        case = CASES[nm]
        u = ref.uncertainty
        orders = "; ".join(f"{k} " + ", ".join(f"{p:.1f}" for p in v) for k, v in ref.order.items()
                           if any(math.isfinite(p) for p in v))
        L.append(f"| {case.label} | {case.why} | {ref.description} | {u['deflection']:.1e} / {u['stress']:.1e} / "
                 f"{u['frequency']:.1e} | {orders} |")
    L.append("")
    for note in result.notes:
        L.append(f"* {note}")
    return "\n".join(L).rstrip() + "\n"


def write_csv(result: StudyResult, path: Path) -> Path:
    """One row per (measurement, reference) pair."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_COLUMNS)
        w.writeheader()
        for r in result.rows:
            out = {}
            for k in CSV_COLUMNS:
                v = r[k]
                out[k] = f"{v:.6g}" if isinstance(v, float) else v
            w.writerow(out)
    return path


_STYLES = {
    ("steps", "zoh"): dict(color="tab:red", marker="o", label="steps, zoh"),
    ("steps", "foh"): dict(color="tab:orange", marker="s", label="steps, foh"),
    ("steps", "magnus2"): dict(color="tab:blue", marker="D", label="steps, magnus2"),
    ("delta", None): dict(color="tab:green", marker="^", label="delta (magnus2, fixed n)"),
    ("elements", None): dict(color="tab:purple", marker="v", label="elements/link (vs finest)"),
    ("cb", True): dict(color="tab:brown", marker="P", label="CB modes + static corr. (vs full)"),
    ("cb", False): dict(color="tab:pink", marker="X", label="CB modes, plain (vs full)"),
    ("eps", None): dict(color="tab:olive", marker="h", label="non-linear eps"),
}


def plot(result: StudyResult, path: Path) -> Path:
    """Pareto plot: error against wall time, one panel per mechanism, one curve per knob."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = [nm for nm in CASES if any(r["mechanism"] == nm for r in result.rows)]
    fig, axes = plt.subplots(1, len(names), figsize=(5.2 * len(names), 4.6), squeeze=False)
    floor_plot = 1e-9
    for ax, nm in zip(axes[0], names):
        case = CASES[nm]
        rows = [r for r in result.rows if r["mechanism"] == nm]

        def draw(sel, style, sort_key="time_s"):
            # the reference run of a mesh or reduction scan has error 0 by construction: not drawn
            sel = sorted((r for r in sel if r["err"] > 0), key=lambda r: r[sort_key])
            if not sel:
                return
            x = [r["time_s"] for r in sel]
            y = [max(r["err"], floor_plot) for r in sel]
            ax.plot(x, y, ms=5, lw=1.2, **style)

        for hold in ("zoh", "foh", "magnus2"):
            sel = [r for r in rows if r["knob"] == "steps" and r["hold"] == hold]
            draw(sel, _STYLES[("steps", hold)], sort_key="steps")
            if sel:  # the same runs, error of the histories (dashed)
                sel = sorted(sel, key=lambda r: r["steps"])
                st = dict(_STYLES[("steps", hold)], label=f"steps, {hold}: histories", ls="--", mfc="none")
                ax.plot([r["time_s"] for r in sel], [max(r["err_hist"], floor_plot) for r in sel], ms=4, lw=1.0,
                        **st)
        draw([r for r in rows if r["knob"] == "delta"], _STYLES[("delta", None)])
        draw([r for r in rows if r["knob"] == "elements"], _STYLES[("elements", None)], sort_key="elements")
        for corr in (True, False):
            draw([r for r in rows if r["knob"] == "cb" and (r["reduction"].endswith("+sc)") == corr)],
                 _STYLES[("cb", corr)])
        draw([r for r in rows if r["knob"] == "eps"], _STYLES[("eps", None)])
        for r in rows:
            if r["knob"].startswith("preset:"):
                ax.plot(r["time_s"], max(r["err"], floor_plot), marker="*", ms=14, color="k", ls="none")
                ax.annotate(r["knob"].split(":")[1], (r["time_s"], max(r["err"], floor_plot)),
                            textcoords="offset points", xytext=(6, 4), fontsize=8)
        u = max((r["ref_uncertainty"] for r in rows if r["reference"].startswith("time-converged")), default=0.0)
        if u > 0:
            ax.axhspan(floor_plot, u, color="0.85", zorder=0, label="reference uncertainty")
        for t in TARGETS:
            ax.axhline(t, color="0.5", ls=":", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("wall time of kf.solve [s]")
        ax.set_title(f"{case.label} (N={rows[0]['n_dof'] if rows else '?'})")
        ax.grid(True, which="major", alpha=0.3)
    axes[0][0].set_ylabel("relative error of peaks and frequency (histories: dashed)")
    handles, labels = [], []
    for ax in axes[0]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels + ["preset candidates (*)"][:0], loc="lower center", ncol=5, fontsize=8,
               frameon=False)
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def read_csv(path: Path) -> StudyResult:
    """A :class:`StudyResult` with the rows of a study's CSV (for re-plotting; no measurements)."""
    ints = ("steps", "elements", "n_dof", "iterations", "repeats")
    out = StudyResult(quick=False)
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            row = dict(r)
            for k in CSV_COLUMNS:
                if k in ints:
                    row[k] = int(row[k])
                elif k.startswith(("time", "err", "peak", "fundamental")) or k == "ref_uncertainty":
                    row[k] = float(row[k])
            row["converged"] = row["converged"] == "True"
            out.rows.append(row)
    return out


def write_outputs(result: StudyResult, out_dir: Path, plot_path: Path | None = None) -> dict:
    """Write ``accuracy_cost.csv``, ``accuracy_cost.md`` and the plot; return their paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = write_csv(result, out_dir / "accuracy_cost.csv")
    md_path = out_dir / "accuracy_cost.md"
    md_path.write_text(format_summary(result))
    png = plot(result, plot_path if plot_path is not None else out_dir / "accuracy_cost.png")
    return {"csv": csv_path, "md": md_path, "plot": png}


def run_cli(quick: bool, out: Path, mechanisms=None, plot_path: Path | None = None) -> int:
    """Run the study, printing one line per measurement and the tables; write the outputs.

    Parameters
    ----------
    quick : bool
        Smoke run (a few knob values).
    out : Path
        Folder of ``accuracy_cost.csv`` and ``accuracy_cost.md`` (and the plot
        unless ``plot_path`` is given).
    mechanisms : sequence of str, optional
        Subset of :data:`CASES`.
    plot_path : Path, optional
        Where to write the Pareto plot.
    """
    _case_names(mechanisms)  # before anything is printed
    print(f"accuracy-versus-cost study{' (quick)' if quick else ''}: {machine_info()}", flush=True)
    res = run_study(quick=quick, mechanisms=mechanisms, progress=lambda msg: print(msg, flush=True))
    paths = write_outputs(res, Path(out), plot_path)
    print()
    print(format_summary(res))
    print(f"wrote {paths['csv']}, {paths['md']}, {paths['plot']} ({res.wall:.0f} s)")
    return 0


def add_arguments(ap) -> None:
    """The study's command-line options (shared by ``kedfem bench`` and the benchmark script)."""
    ap.add_argument("--quick", action="store_true", help="a few knob values (a smoke run of ~15 s)")
    ap.add_argument("--out", metavar="DIR", default=None,
                    help="folder for accuracy_cost.csv/.md/.png (default: kedfem-bench)")
    ap.add_argument("--mechanisms", metavar="M1,M2", default=None,
                    help=f"subset of {','.join(CASES)} (default all)")


def parse_mechanisms(text: str | None):
    """``"a,b"`` -> ``["a", "b"]``; ``None`` or empty -> ``None`` (all)."""
    if not text:
        return None
    return [m.strip() for m in text.split(",") if m.strip()] or None


def main(argv=None, *, default_out: str | None = None, default_plot: str | None = None) -> int:
    """Entry of ``benchmarks/accuracy_cost.py``: parse ``argv`` and :func:`run_cli`."""
    import argparse
    ap = argparse.ArgumentParser(prog="accuracy_cost.py", description=__doc__.split("\n")[0])
    add_arguments(ap)
    ap.add_argument("--replot", action="store_true", help="only redraw the plot from the CSV in the output folder")
    args = ap.parse_args(argv)
    if args.replot:
        out = Path(args.out or default_out or "kedfem-bench")
        png = plot(read_csv(out / "accuracy_cost.csv"),
                   Path(default_plot) if default_plot and not args.out else out / "accuracy_cost.png")
        print(f"wrote {png}")
        return 0
    out = Path(args.out or default_out or "kedfem-bench")
    plot_path = None if args.out or default_plot is None else Path(default_plot)
    return run_cli(args.quick, out, parse_mechanisms(args.mechanisms), plot_path)
