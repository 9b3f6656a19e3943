"""Typed results of a KED solve and their post-processing (deflections, section forces, stresses).

:class:`PeriodicResult` holds the response and its basic read-outs (peaks, resampling, frequencies);
groups of its read-outs are mixins in their own modules: the displacements
(:mod:`kedfem.analysis.displacements`), the section forces and stresses
(:mod:`kedfem.analysis.section_forces`) and those under sliding blocks
(:mod:`kedfem.analysis.block_forces`), and the peaks' refinement between instants and stations
(:mod:`kedfem.analysis.peak_refinement`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..model import elements as el
from .block_forces import BlockForces
from .displacements import Displacements
from .hooks import hook
from ..units import RPM_PER_RAD_S
from .peak_refinement import PEAK_STATIONS, PeakRefinement
from .peak_search import grid_peak as _grid_peak
from .modal import Frequencies, frequencies_over_cycle, modes_at
from .section_forces import SectionForces
from .stations import _abscissa, _on_stations, _per_element
from ..fe.model import FEModel
from ..checks import floats, integer
from ..errors import InputError
from ..motion.kinematics import Motion

__all__ = ["PeriodicResult", "Frequencies", "Timings", "LinkPeaks", "Sampler", "Stability",
           "stability_verdict"]


@dataclass(frozen=True)
class Sampler:
    """Reads a periodic solution at any instants: the motion (exact) and the dense response.

    Attributes
    ----------
    cycle : kedfem.motion.kinematics.Cycle
    discrete : kedfem.solvers.schemes.Discrete
    """

    cycle: object
    discrete: object
    _acc: dict = field(default_factory=dict, repr=False, compare=False)

    def acceleration(self, t) -> np.ndarray:
        """Accelerations of the DOFs (k, N) at instants ``t`` (k,) [s] [m/s^2, rad/s^2].

        The time derivative of the dense velocity: the trigonometric series of
        the velocities on a uniform grid of :data:`ACCELERATION_SAMPLES` per cycle
        or 16 per time element, whichever is finer (read off the grid where ``t``
        falls on it).
        """
        period = self.discrete.period
        if "coef" not in self._acc:
            n_el = int(getattr(self.discrete, "n", 0) or 0)
            F = 1 << int(math.ceil(math.log2(max(ACCELERATION_SAMPLES, 16 * n_el))))
            V = self.discrete.velocities(np.arange(F) * (period / F))
            C = np.fft.rfft(V, axis=0) / F
            k = np.arange(C.shape[0], dtype=float)
            w = np.full(k.size, 2.0)
            w[0] = 1.0
            w[-1] = 0.0  # the Nyquist harmonic of the even grid has no derivative
            # a(t) = Re(sum_k C_k exp(i k w t)): the derivative of the (one-sided) series of V
            C = C * (w * 1j * (2.0 * math.pi / period) * k)[:, None]
            self._acc["coef"] = C
            self._acc["F"] = F
        F, C = self._acc["F"], self._acc["coef"]
        t = np.mod(np.asarray(t, dtype=float), period)
        x = t * (F / period)
        k = np.rint(x)
        if np.all(np.abs(x - k) < 1e-7):
            if "grid" not in self._acc:
                half = np.where(np.arange(C.shape[0]) > 0, 0.5, 1.0)[:, None]
                self._acc["grid"] = np.fft.irfft(C * half * F, n=F, axis=0)
            return self._acc["grid"][k.astype(int) % F]
        M = t.size
        if M >= 8 and np.allclose(np.diff(t), period / M, rtol=1e-9, atol=0.0):
            # a uniform grid: the series folded onto M points (harmonic k onto k mod M, summed in
            # the order of k), one inverse FFT
            kk = np.arange(C.shape[0])
            shifted = C * np.exp(1j * (2.0 * math.pi / period) * t[0] * kk)[:, None]
            rows = -(-kk.size // M) * M
            padded = np.zeros((rows, C.shape[1]), dtype=complex)
            padded[:kk.size] = shifted
            folded = padded.reshape(rows // M, M, C.shape[1]).sum(axis=0)
            return (np.fft.ifft(folded, axis=0) * M).real
        # exp(i k w t) by products of exp(i w t): a quarter of the time of an exponential per
        # entry, within 1e-12 of it over the 1025 harmonics of the default grid
        ph = np.empty((t.size, C.shape[0]), dtype=complex)
        ph[:, 0] = 1.0
        if C.shape[0] > 1:
            ph[:, 1:] = np.exp(1j * (2.0 * math.pi / period) * t)[:, None]
            np.cumprod(ph[:, 1:], axis=1, out=ph[:, 1:])
        return (ph @ C).real

    def at(self, t):
        """Motion and response at instants ``t`` (k,) [s] in ``[0, T)``.

        Returns
        -------
        motion : Motion
        U, V : ndarray, shape (k, N)
        """
        t = np.asarray(t, dtype=float)
        U, V = self.discrete.at(t)
        return self.cycle.at(t), U, V


@dataclass(frozen=True)
class Timings:
    """Wall time [s] of the stages of a solve.

    ``kinematics``: the rigid-body motion at the levels' instants (and the solve's setup);
    ``assembly``: the system terms there; ``solve``: the periodic solves, each non-linear
    iteration's state terms included (not the assembly of the terms); ``total``: all of it,
    with the damping field, the read-outs and the error estimate. ``forecast``: the whole solve's wall time [s] as forecast after its second level (its
    first when it has one; a tolerance-driven solve; None otherwise), to compare with ``total``.
    """

    kinematics: float
    assembly: float
    solve: float
    total: float
    forecast: float | None = None


@dataclass(frozen=True)
class Stability:
    """Floquet stability of the periodic response, with the accuracy of its spectral radius.

    Attributes
    ----------
    spectral_radius : float
        Largest Floquet multiplier modulus of the result's discretisation. An L-stable scheme
        only lowers it, by orders of magnitude on few elements where the verdict is clear
        without more (``describe()`` then prints ``below ...``): read :attr:`upper` for what is
        known of the true one.
    error : float or None
        Estimated absolute error of ``spectral_radius`` from the coarser
        solves of the error estimate (None with a single solve).
    verdict : {"stable", "unstable", "marginal"}
        ``"marginal"`` when ``1`` lies within ``spectral_radius +- error``
        (an undamped scene, or one at the onset of an instability).
    scheme : str
        Time discretisation of the monodromy matrix.
    elements : int
        Its time elements.
    note : str
        Why the verdict needs a caveat: an undamped scene (marginal by
        structure), or too few elements for the scheme's numerical damping of
        the modes that set the spectral radius (empty otherwise).
    """

    spectral_radius: float
    error: float | None
    verdict: str
    scheme: str
    elements: int
    note: str = ""
    conservative: bool = False

    @property
    def upper(self) -> float:
        """Upper bound of the true spectral radius [-]: ``spectral_radius + error`` (inf without an
        estimate; 1 for an undamped scene, whose radius is 1 by structure). A new user read
        ``spectral_radius`` = 1.5e-5 on 48 elements, where the true one is below 3e-2."""
        if self.conservative:
            return 1.0
        if self.error is None or not math.isfinite(self.error):
            return math.inf
        return abs(self.spectral_radius) + self.error

    def describe(self) -> str:
        """One line: spectral radius, its error and the verdict (and its caveat).

        The radius is printed to the digits its error leaves: ``0.2589 +- 5e-05``; ``below
        2.1e-01`` when the error exceeds it (a clear verdict from a number the numerical damping
        lowered by orders of magnitude); four digits without an estimate; for an undamped
        (conservative) scene, 1 by structure with the computed value named as the scheme's.
        """
        note = f" ({self.note})" if self.note else ""
        return f"spectral radius {self.radius_text()} -> {self.verdict}{note}"

    def radius_text(self) -> str:
        """The spectral radius as :meth:`describe` prints it."""
        rho, err = self.spectral_radius, self.error
        if self.conservative:
            return (f"1 by structure (a conservative scene; the computed {rho:.1e} is the scheme's numerical "
                    "damping)")
        if err is None:
            return f"{rho:.4g} (no error estimate)"
        if not math.isfinite(err):
            return f"{rho:.1e}, error not bounded"
        if err >= abs(rho):
            return f"below {self.upper:.1e}"
        digits = min(10, max(1, math.floor(math.log10(abs(rho))) - math.floor(math.log10(err)) + 1))
        return f"{rho:.{digits}g} +- {err:.0e}"


#: least number of samples per cycle of the dense velocity the accelerations are derived from
ACCELERATION_SAMPLES = 2048
#: Most instants a result is resampled at in one call (a 0.001 degree crank step)
MAX_RESAMPLE = 360_000
#: Most natural frequencies per instant a result reports
MAX_MODES = 100


def stability_verdict(rho: float, error: float | None, tol: float = 1e-9) -> str:
    """``"stable"``, ``"unstable"`` or ``"marginal"`` for a spectral radius and its error."""
    margin = max(tol, error or 0.0)
    if rho + margin < 1.0:
        return "stable"
    if rho - margin > 1.0:
        return "unstable"
    return "marginal"


@dataclass(frozen=True)
class LinkPeaks:
    """Peak values of one flexible link over the cycle.

    Attributes
    ----------
    link : str
    deflection : float
        Largest ``|mid-span deflection relative to the chord|`` over the cycle [m] (of a link
        passing through joints, ``through=``: of each stretch between them, relative to its
        own chord, the largest).
    deflection_angle : float
        Crank angle of that peak [rad] (as :attr:`PeriodicResult.crank_angle`), in ``[0, 2 pi)``.
    stress : float
        Largest ``|N|/A + |M| c/I`` over the link and the cycle [Pa] (nan without ``c``).
    stress_angle : float
        Crank angle of that peak [rad], in ``[0, 2 pi)``.
    stress_station : float
        Where along the link, from joint ``a`` [m].
    """

    link: str
    deflection: float
    deflection_angle: float
    stress: float
    stress_angle: float
    stress_station: float


@dataclass(frozen=True)
class PeriodicResult(Displacements, SectionForces, BlockForces, PeakRefinement):
    """Periodic steady-state elastic response of a scene.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Time nodes [s].
    crank_angle : ndarray, shape (n,)
        Angle of the first driven member [rad]: a driven link's absolute angle (its
        ``a -> b`` line from +x), a driven body's rotation from the drawing
        (:func:`kedfem.motion.crank.crank_angle_convention` says which in words).
    U, V : ndarray, shape (n, n_dof)
        Elastic displacements [m, rad] and velocities at the time nodes.
    dof_labels : tuple of str
        Labels of the columns of ``U``.
    floquet_multipliers : ndarray, shape (2 n_dof,)
        Eigenvalues of the monodromy matrix (of the last linear solve).
    stable : bool
        ``stability.verdict == "stable"``: all multipliers inside the unit
        circle by more than the estimated error of the spectral radius.
    converged : bool
        The non-linear iteration met its tolerance (True for linear scenes).
    iterations : int
        Number of linear periodic solves (1 for linear scenes).
    history : tuple of float
        Eq. 21 relative changes per iteration (empty for linear scenes).
    residual : float
        Relative residual of the last block-cyclic system solved.
    timings : Timings
    method : str
        ``"condensation"`` or ``"cyclic-lu"`` (how the block-cyclic system was solved).
    elements : int
        Time elements of the solve (the response is read between them on
        the output instants ``t``).
    scheme : str
        Time discretisation (:data:`kedfem.solvers.schemes.SCHEMES`).
    error : ErrorEstimate or None
        Estimated relative time-discretisation error of each link's peaks and
        histories (:mod:`kedfem.analysis.accuracy`); None if not estimated.
    sampler : Sampler or None
        Reads the response at any instant of the cycle (:meth:`resample`).
    stability : Stability or None
        Spectral radius with its estimated error and the verdict. For a non-linear scene the
        multipliers are those of the orbit: the linearisation (the consistent tangent of the
        state-dependent effects) about the converged response.
    path : str
        How a non-linear response was reached when not directly from the linear response
        ("reached by continuation in speed from 175 rpm ..."); empty otherwise.
    periods : int
        Drive cycles per period of the response (1; 2 for a period-doubled response).
    predicted_change : float or None
        Newton stopped on a last change whose next one its rate (observed on a coarser level)
        predicts below a tenth of ``eps``: that prediction, the response's distance from the
        iteration's solution (relative); None when the last change itself met ``eps``
        (:func:`kedfem.solvers.nonlinear.newton`).
    """

    scene: object
    model: FEModel
    motion: Motion
    t: np.ndarray
    crank_angle: np.ndarray
    U: np.ndarray
    V: np.ndarray
    dof_labels: tuple[str, ...]
    floquet_multipliers: np.ndarray
    stable: bool
    converged: bool
    iterations: int
    history: tuple[float, ...]
    residual: float
    timings: Timings
    method: str = "condensation"
    elements: int = 0
    scheme: str = ""
    error: object = None
    sampler: object = field(default=None, repr=False, compare=False)
    stability: Stability | None = None
    path: str = ""
    periods: int = 1
    predicted_change: float | None = None
    # not an init field: dataclasses.replace(res, U=...) gets an empty cache, not the old
    # result's deflections and stresses
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    # ---------------------------------------------------------------- basics
    def __repr__(self) -> str:
        sc = self.scene
        rpm = abs(sc.mech.drives[0].speed) * RPM_PER_RAD_S if sc.mech.drives else float("nan")
        err = f", error {self.error.peak:.1e}" if getattr(self.error, "peak", None) is not None else ""
        stab = self.stability.verdict if self.stability is not None else ("stable" if self.stable else "UNSTABLE")
        return (f"<PeriodicResult {sc.name or sc.mech.name}: {rpm:.6g} rpm, {self.model.n_dof} DOFs, "
                f"{self.scheme} x {self.elements} time elements{err}, {stab}"
                f"{'' if self.converged else ', NOT converged'}>")

    def summary(self, n_modes: int = 4) -> str:
        """The summary table ``kedfem run`` prints: scene, frequencies over the cycle, peaks with
        their errors, fatigue, stability, iteration (no files; the mesh error where
        :func:`kedfem.mesh_error` was called on this result, its last call)."""
        from .fatigue import fatigue_table
        n_modes = integer("summary", "n_modes", n_modes, 1, MAX_MODES)
        freqs = self.frequencies(n_modes, nodes=list(range(0, self.n, max(1, self.n // 180))))
        return hook("format_summary")(self, freqs, self.peaks(), stages={}, files=[], out_dir=None, source="python",
                              scene_time=self.timings.total, fatigue=fatigue_table(self), loads=self.loads(),
                              mesh=self._cache.get("mesh_error"))

    def loads(self, elastic: bool = True):
        """Bearing forces and drive torques over the cycle, rigid-body and (``elastic``) from the
        elastic response (:func:`kedfem.analysis.loads.machine_loads`; docs/loads.md).

        Returns
        -------
        kedfem.analysis.loads.MachineLoads
        """
        key = ("loads", bool(elastic))
        if key not in self._cache:
            from .loads import machine_loads
            self._cache[key] = machine_loads(self, elastic=elastic)
        return self._cache[key]

    def write(self, out_dir, **options):
        """Write everything ``kedfem run`` writes for this result into the folder ``out_dir``.

        Keyword options as :func:`kedfem.io.report.write_result` (``plots``, ``csv``, ``npz``,
        ``vtk``, ``render``, ``modes``, ``mesh_check``, ``fatigue``, ...). The folder is
        published whole or not at all.

        Returns
        -------
        kedfem.io.report.Report
            The folder, the files and the summary text.
        """
        return hook("write_result")(self, out_dir, **options)

    @property
    def n(self) -> int:
        """Output instants (the time elements are :attr:`elements`)."""
        return int(self.t.size)

    @property
    def period(self) -> float:
        """The cycle's duration [s] (one drive revolution: :attr:`scene`'s period)."""
        return float(self.scene.period)

    def dof(self, label: str) -> np.ndarray:
        """Time history (n,) of one DOF by label."""
        return self.U[:, self.model.dof_index(label)]

    def _local(self, link: str):
        """Local (link-frame) element DOFs (n, n_el_link, 6), total elastic incl. prescribed parts."""
        key = ("local", link)
        if key in self._cache:
            return self._cache[key]
        sl = self.model.link_elements(link)
        x = self._beam_map().apply(self.U, sl, offset=True)
        th = self.motion.angle(link)
        T = el.rotation_blocks(th)[:, None]
        d = (T @ x[..., None])[..., 0]
        self._cache[key] = d
        return d

    def _motion_cache(self) -> dict:
        """The cache of what depends on the motion only: shared by the results a solve reads on one
        output grid (its levels, for the estimate), else the result's own."""
        return self._cache.get("grid", self._cache)

    def _assembler(self):
        """An :class:`~kedfem.fe.assembler.Assembler` of the scene's effects over this result's
        motion, for what the read-out needs of it (the kinetostatic forces, the constraint maps
        and entity forms of the elastic loads; all of the motion only), built once per output grid."""
        cache = self._motion_cache()
        asm = cache.get("assembler")
        if asm is None:
            from ..fe.assembler import Assembler
            asm = cache["assembler"] = Assembler(self.model, self.motion, self.scene.effects)
        return asm

    def _beam_map(self):
        """Constraint map of the beam elements over the cycle (built once per output grid)."""
        cache = self._motion_cache()
        gm = cache.get("beam_map")
        if gm is None:
            gm = cache["beam_map"] = self.model.group_map("beam", self.motion)
        return gm

    def stations(self, link: str, per_element: int = 1, sides: bool = False) -> np.ndarray:
        """Stations (n_el per_element + 1,) along a flexible link, from joint ``a`` [m].

        ``per_element = 1``: the nodes; more divides every element evenly. ``sides=True``:
        a joint the link passes through twice, for the section forces on either side of
        its pin (:meth:`section_forces`).
        """
        lk = self._link(link)
        k = _per_element(per_element)
        if not lk.through:
            return np.linspace(0.0, lk.length, lk.elements * k + 1)
        frac = np.arange(k) / k
        x = np.append((lk.nodes[:-1, None] + frac[None, :] * lk.element_lengths[:, None]).ravel(), lk.length)
        if sides:
            steps = np.array(lk.inner_nodes, dtype=int) * k
            x = np.insert(x, steps + 1, x[steps])
        return x

    def _link(self, link):
        mech = self.model.mech
        if not isinstance(link, str) or link not in mech.links:
            raise InputError(f"unknown link '{link}' (links: {', '.join(mech.links)})")
        lk = mech.links[link]
        if lk.rigid:
            raise InputError(f"link '{link}' is rigid: it has no elastic deflection or stress")
        return lk

    def mode_shapes(self, node: int = 0, n_modes: int = 4):
        """Undamped mode shapes at one time node (co-moving-frame formulation).

        Returns
        -------
        f : ndarray, shape (k,)
            Frequencies [Hz].
        phi : ndarray, shape (N, k)
            Mass-normalised mode shapes (DOF order of ``dof_labels``).
        """
        integer("mode_shapes", "node", node, 0, self.n - 1)
        integer("mode_shapes", "n_modes", n_modes, 1, MAX_MODES)
        return modes_at(self.model, self.motion, self.scene, self.U, self.V, node, n_modes)

    @property
    def peaks_read(self) -> bool:
        """:meth:`peaks` has been read (and is kept)."""
        return "peaks" in self._cache

    def peaks(self) -> list[LinkPeaks]:
        """Peak mid-span deflection and stress of every flexible link.

        Taken over the output instants and, where the result can be read
        between them (:attr:`sampler`), refined around the largest local
        maxima on an 8 times finer local grid with a parabolic vertex (within
        1e-7 of a 32 times finer one on the shipped mechanisms), so that
        a peak between output instants is not cut off. Stresses are sought
        on :data:`PEAK_STATIONS` stations per element with a parabolic vertex
        between them along the link.
        """
        if "peaks" in self._cache:
            return self._cache["peaks"]
        refine = self.sampler is not None and self.n >= 3
        out = self._cache["peaks"] = self._peaks(refine=refine, vertex=not refine)
        return out

    def _peaks(self, refine: bool, vertex: bool) -> list[LinkPeaks]:
        """:meth:`peaks`: refined between the output instants and stations (``refine``), or the
        grid's parabolic vertices (``vertex``), or its largest samples (neither: what an error
        estimate compares between levels read on the same grid, ``|max f - max g| <= max |f - g|``)."""
        links = self.model.mech.flexible_links
        series = []  # (link index, kind, grid values (n,) or (n, stations))
        for i, lk in enumerate(links):
            series.append((i, "deflection", self._peak_deflection(lk)))
            if lk.section.c is not None:
                series.append((i, "stress", self.stress(lk.name, per_element=PEAK_STATIONS)))
                if self._blocks_on(lk):  # under a block, where no station is
                    series.append((i, "block", self.block_stress(lk.name)[0]))
        # the output grid's largest samples; the refinement around them raises them to the vertices
        best = {si: _grid_peak(vals, self.t, vertex=vertex and not refine)
                for si, (i, kind, vals) in enumerate(series)}
        if refine:
            best = self._refine_peaks(links, series, best)
            best = self._polish_stations(links, series, best)
        out = []
        for i, lk in enumerate(links):
            d = next(best[si] for si, s_ in enumerate(series) if s_[0] == i and s_[1] == "deflection")
            sv = [best[si] for si, s_ in enumerate(series) if s_[0] == i and s_[1] == "stress"]
            bv = [best[si] for si, s_ in enumerate(series) if s_[0] == i and s_[1] == "block"]
            ang = self._angle_of
            if sv:
                smax, st, sj = sv[0]
                sst = _abscissa(lk, sj, PEAK_STATIONS)
                if bv and bv[0][0] > smax:  # the peak is under a block: there, at its instant
                    smax, st = bv[0][0], bv[0][1]
                    sst = float(self._block_abscissa_at(lk, st))
                sang = ang(st)
            else:
                smax = sang = sst = float("nan")
            out.append(LinkPeaks(lk.name, d[0], ang(d[1]), smax, sang, sst))
        return out

    def _angle_of(self, t: float) -> float:
        """Crank angle [rad] in ``[0, 2 pi)`` at instant ``t`` (linear in time for a constant-speed drive)."""
        w = self.model.mech.drives[0].speed if self.model.mech.drives else 0.0
        return float(np.mod(self.crank_angle[0] + w * (t - self.t[0]), 2.0 * math.pi))

    def resample(self, times=None, *, crank_angle=None) -> "PeriodicResult":
        """The response read at other instants of the cycle (the scheme's dense output).

        Parameters
        ----------
        times : array_like of float, shape (k,), optional
            Instants [s] in ``[0, T)``.
        crank_angle : array_like of float, shape (k,), optional
            Or crank angles [rad] (absolute, as :attr:`crank_angle`).

        Returns
        -------
        PeriodicResult
            With ``t``, ``crank_angle``, ``U``, ``V`` and the motion at those
            instants (deflections, section forces and stresses follow).
        """
        if self.sampler is None:
            raise InputError("resample: this result has no dense output (it was not made by kf.solve)")
        if (times is None) == (crank_angle is None):
            raise InputError("resample: give either times or crank_angle")
        period = self.scene.period
        if times is None:
            w = self.model.mech.drives[0].speed
            ca = floats("resample", "crank_angle [rad]", crank_angle, max_size=MAX_RESAMPLE)
            times = (ca - self.crank_angle[0]) / w + self.t[0]
        else:
            times = floats("resample", "times [s]", times, max_size=MAX_RESAMPLE)
        t = np.mod(times, period)
        if not np.all(np.isfinite(t)):
            raise InputError("resample: times / crank angles must be finite and of a size the cycle resolves")
        motion, U, V = self.sampler.at(t)
        out = dataclasses.replace(self, motion=motion, t=motion.t, crank_angle=motion.crank_angle, U=U, V=V)
        out._cache["source"] = self._cache.get("source", self)
        return out

    def observables(self, refined: bool = True):
        """Peaks and histories of every flexible link (what the error estimate compares).

        ``refined=False``: the peaks are the output grid's largest samples, not refined between
        the instants and stations (:meth:`peaks`): levels read on the same grid are compared
        alike, at a third of the read-out's cost.

        Returns
        -------
        kedfem.analysis.accuracy.Observables
        """
        from .accuracy import Observables
        links = self.model.mech.flexible_links
        if refined:
            peaks = self.peaks()
        else:
            peaks = self._cache.get("grid_peaks")
            if peaks is None:
                peaks = self._cache["grid_peaks"] = self._peaks(refine=False, vertex=False)
        pk = {p.link: p for p in peaks}
        period = self.scene.period
        w = self.model.mech.drives[0].speed

        def nearest(angle):
            t = (angle - self.crank_angle[0]) / w + self.t[0]
            dist = np.abs(np.mod(self.t - t + 0.5 * period, period) - 0.5 * period)
            return int(np.argmin(dist))

        names, d, da, s, sa, sj, dh, sh, has, nh = [], [], [], [], [], [], [], [], [], []
        for lk in links:
            p = pk[lk.name]
            names.append(lk.name)
            d.append(p.deflection)
            da.append(nearest(p.deflection_angle))
            dh.append(self._mid_deflections(lk))
            c = lk.section.c is not None
            has.append(c)
            s.append(p.stress if c else 0.0)
            sa.append(nearest(p.stress_angle) if c else 0)
            st = self.stations(lk.name, PEAK_STATIONS)
            sj.append(int(np.argmin(np.abs(st - p.stress_station))) if c else 0)
            sh.append(self.stress(lk.name, per_element=PEAK_STATIONS) if c else np.zeros((self.n, 0)))
            nh.append(_on_stations(self._forces(lk.name, PEAK_STATIONS)[1]))
        return Observables(tuple(names), int(self.elements), np.array(d), np.array(da, dtype=int), np.array(s),
                           np.array(sa, dtype=int), np.array(sj, dtype=int), tuple(dh), tuple(sh),
                           tuple(has), tuple(nh))

    # ----------------------------------------------------------- frequencies
    def frequencies(self, n_modes: int = 4, nodes=None) -> Frequencies:
        """Natural frequencies over the cycle at the converged periodic state.

        (The batched eigenproblems run with one BLAS thread: OpenBLAS's own
        threads made them 5-10x slower whenever the other core was busy.)

        The co-moving-frame matrices of the scene's effects (each link in its
        own rotating frame), plus the tangent stiffness of the state-dependent
        effects at the converged response. ``modal``: undamped eigenanalysis;
        ``state_space``: eigenvalues of the state matrix with the damping and
        the Coriolis coupling.

        Parameters
        ----------
        n_modes : int
            Frequencies per time node.
        nodes : array_like of int, optional
            Time nodes to analyse (default all). Equally spaced nodes, e.g.
            ``range(0, n, n // 36)``, give the cycle means of a fine time grid
            at a fraction of the cost (an eigenvalue problem per node).
        """
        from ..solvers.threads import one_blas_thread
        with one_blas_thread():
            return self._frequencies(n_modes, nodes)

    def _frequencies(self, n_modes: int = 4, nodes=None) -> Frequencies:
        """The body of :meth:`frequencies`."""
        n_modes = integer("frequencies", "n_modes", n_modes, 1, MAX_MODES)
        if nodes is None:
            idx = None
            key = ("freq", n_modes)
        else:
            if isinstance(nodes, (str, bytes, dict)):
                raise InputError(f"frequencies: nodes must be time node indices, got {nodes!r}")
            try:
                idx = np.asarray(nodes)
            except (TypeError, ValueError):
                raise InputError(f"frequencies: nodes must be time node indices, got {nodes!r}") from None
            if idx.ndim != 1 or idx.size == 0 or not np.issubdtype(idx.dtype, np.integer) \
                    or idx.min() < 0 or idx.max() >= self.n:
                raise InputError(f"frequencies: nodes must be time node indices in 0..{self.n - 1}, "
                                 f"got {nodes!r}")
            key = ("freq", n_modes, tuple(int(i) for i in idx))
        if key in self._cache:
            return self._cache[key]
        out = frequencies_over_cycle(self.model, self.motion, self.scene, self.U, self.V, n_modes, idx)
        self._cache[key] = out
        return out
