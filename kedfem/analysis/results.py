"""Typed results of a KED solve and their post-processing (deflections, section forces, stresses)."""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from ..model import elements as el
from . import recovery
from .hooks import hook
from .peak_search import grid_peak as _grid_peak, parabolic_vertex as _vertex
from .modal import Frequencies, frequencies_over_cycle, modes_at
from ..fe.model import FEModel
from ..checks import choice, floats, integer, name, real
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
        Largest Floquet multiplier modulus of the result's discretisation.
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
            return f"below {abs(rho) + err:.1e}"
        digits = min(10, max(1, math.floor(math.log10(abs(rho))) - math.floor(math.log10(err)) + 1))
        return f"{rho:.{digits}g} +- {err:.0e}"


log = logging.getLogger(__name__)

#: least number of samples per cycle of the dense velocity the accelerations are derived from
ACCELERATION_SAMPLES = 2048
#: Most instants a result is resampled at in one call (a 0.001 degree crank step)
MAX_RESAMPLE = 360_000
#: Most natural frequencies per instant a result reports
MAX_MODES = 100
#: stations per element where peak stresses are sought (with a parabolic vertex between them)
PEAK_STATIONS = 8


def _st(d: np.ndarray) -> np.ndarray:
    """``S^T`` on the translations of local element DOFs (..., 6): ``(u, v) -> (v, -u)``, rotations 0."""
    out = np.zeros_like(d)
    out[..., 0], out[..., 1] = d[..., 1], -d[..., 0]
    out[..., 3], out[..., 4] = d[..., 4], -d[..., 3]
    return out


def _translations(d: np.ndarray) -> np.ndarray:
    """Local element DOFs (..., 6) with the rotations zeroed."""
    out = d.copy()
    out[..., 2] = 0.0
    out[..., 5] = 0.0
    return out


def _per_element(k) -> int:
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= 64:
        raise InputError(f"per_element must be an integer in 1..64, got {k!r}")
    return int(k)


def _on_stations(X: np.ndarray, steps=(), larger: bool = False, sides: bool = False) -> np.ndarray:
    """Element values (n, n_el, k + 1) on the link's stations (n, n_el k + 1), nodes averaged.

    At the nodes ``steps`` (joints the link passes through, where a pin's force
    steps the section forces) ``larger=True`` takes the larger of the two sides
    (a stress) instead of their mean; ``sides=True`` gives both, the ``a`` side
    first (one more station per step node).
    """
    n, ne, k1 = X.shape
    k = k1 - 1
    out = np.empty((n, ne * k + 1))
    out[:, :-1] = X[:, :, :k].reshape(n, ne * k)
    out[:, -1] = X[:, -1, k]
    if ne > 1:
        out[:, k:-1:k] = 0.5 * (X[:, :-1, k] + X[:, 1:, 0])
    steps = np.asarray(steps, dtype=int)
    if larger and steps.size:
        out[:, steps * k] = np.maximum(X[:, steps - 1, k], X[:, steps, 0])
    if sides and steps.size:
        out[:, steps * k] = X[:, steps - 1, k]
        out = np.insert(out, steps * k + 1, X[:, steps, 0], axis=1)
    return out


def _element_length(lk):
    """Element length [m] of a link meshed uniformly (float), else the lengths (n_el,)."""
    return lk.length / lk.elements if not lk.through else lk.element_lengths


def _abscissa(lk, station: float, per_element: int) -> float:
    """Abscissa [m] from joint ``a`` of a (fractional) station index on ``per_element`` stations per element."""
    x = np.clip(station / per_element, 0.0, lk.elements)
    e = min(int(x), lk.elements - 1)
    return float(min(max(lk.nodes[e] + (x - e) * lk.element_lengths[e], 0.0), lk.length))


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
class PeriodicResult:
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
        rpm = abs(sc.mech.drives[0].speed) * 60.0 / (2.0 * math.pi) if sc.mech.drives else float("nan")
        err = f", error {self.error.peak:.1e}" if getattr(self.error, "peak", None) is not None else ""
        stab = self.stability.verdict if self.stability is not None else ("stable" if self.stable else "UNSTABLE")
        return (f"<PeriodicResult {sc.name or sc.mech.name}: {rpm:.6g} rpm, {self.model.n_dof} DOFs, "
                f"{self.scheme} x {self.elements} time elements{err}, {stab}"
                f"{'' if self.converged else ', NOT converged'}>")

    def summary(self, n_modes: int = 4) -> str:
        """The summary table ``kedfem run`` prints: scene, frequencies over the cycle, peaks with
        their errors, fatigue, stability, iteration (no mesh check, no files)."""
        from .fatigue import fatigue_table
        n_modes = integer("summary", "n_modes", n_modes, 1, MAX_MODES)
        freqs = self.frequencies(n_modes, nodes=list(range(0, self.n, max(1, self.n // 180))))
        return hook("format_summary")(self, freqs, self.peaks(), stages={}, files=[], out_dir=None, source="python",
                              scene_time=self.timings.total, fatigue=fatigue_table(self), loads=self.loads())

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

    def _beam_map(self):
        """Constraint map of the beam elements over the cycle (built once per result)."""
        gm = self._cache.get("beam_map")
        if gm is None:
            gm = self._cache["beam_map"] = self.model.group_map("beam", self.motion)
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

    # ------------------------------------------------------------ deflection
    def deflection(self, link: str, xi: float = 0.5, relative_to: str = "frame") -> np.ndarray:
        """Transverse elastic deflection at fraction ``xi`` of a link's length.

        Parameters
        ----------
        link : str
            Flexible link.
        xi : float
            Position as a fraction of the length from joint ``a`` (0..1).
        relative_to : {"frame", "chord"}
            ``"frame"``: in the link's rigid-body frame (+y is the ``a -> b``
            direction turned +90 deg); ``"chord"``: relative to the chord
            through the deflected end points.

        Returns
        -------
        ndarray, shape (n,)
            Deflection [m] over the cycle.
        """
        lk = self._link(link)
        xi = real("deflection", "xi", xi)
        if not (0.0 <= xi <= 1.0):
            raise InputError(f"deflection: xi must lie in [0, 1], got {xi!r}")
        choice("deflection", "relative_to", relative_to, ("frame", "chord"))
        d = self._local(link)
        ne = lk.elements
        if lk.through:
            e = int(min(max(np.searchsorted(lk.nodes, xi * lk.length, side="right") - 1, 0), ne - 1))
            Le = float(lk.element_lengths[e])
            xe = (xi * lk.length - lk.nodes[e]) / Le
        else:
            e = min(int(xi * ne), ne - 1)
            xe = xi * ne - e
            Le = lk.length / ne
        N = el.shape_functions(Le, [xe])[0, 0]  # (2, 6)
        v = d[:, e] @ N[1]
        if relative_to == "chord" and lk.through:  # the chord of the stretch between the pins around it
            x = xi * lk.length
            cuts = lk.cuts
            k = int(min(np.searchsorted(cuts, x, side="right") - 1, len(cuts) - 2))
            f, c, _le = lk.segments()[k]
            u = (x - cuts[k]) / (cuts[k + 1] - cuts[k])
            v = v - ((1 - u) * d[:, f, 1] + u * d[:, f + c - 1, 4])
        elif relative_to == "chord":
            va = d[:, 0, 1]
            vb = d[:, -1, 4]
            v = v - ((1 - xi) * va + xi * vb)
        return v

    def stretch_deflections(self, link: str) -> np.ndarray:
        """Mid-span deflection of each stretch of a link relative to its chord, (n, n_stretches) [m].

        The stretches run between the link's ends and the joints it passes through
        (``through=``; their joints: ``Link.stretches``); a link without them is one stretch,
        its :meth:`deflection` at ``xi = 0.5`` relative to the chord.
        """
        lk = self._link(link)
        cuts = lk.cuts
        return np.stack([self.deflection(lk.name, 0.5 * (cuts[k] + cuts[k + 1]) / lk.length, relative_to="chord")
                         for k in range(len(cuts) - 1)], axis=-1)

    def _mid_deflections(self, lk) -> np.ndarray:
        """:meth:`stretch_deflections`, (n,) for a link of one stretch."""
        return self.deflection(lk.name, 0.5, relative_to="chord") if not lk.through \
            else self.stretch_deflections(lk.name)

    def _peak_deflection(self, lk) -> np.ndarray:
        """``|mid-span deflection relative to the chord|`` (n,), the largest of a link's stretches."""
        d = np.abs(self._mid_deflections(lk))
        return d if d.ndim == 1 else d.max(axis=-1)

    # ------------------------------------------------------- section forces
    def _axial_fe(self, link: str) -> np.ndarray:
        """Interpolated axial force per element (n, n_el) [N] (plus the membrane term)."""
        lk = self._link(link)
        d = self._local(link)
        Le = _element_length(lk)
        EA = lk.material.E * lk.section.A
        N = EA * (d[..., 3] - d[..., 0]) / Le
        if "geometric_nonlinearity" in getattr(self.scene, "effects", ()):
            vb = d[..., el.V_DOFS]
            if np.ndim(Le) == 0:
                G = el.geometric_matrix([Le])[0]
                N = N + EA / (2 * Le) * np.einsum("...i,ij,...j->...", vb, G, vb)
            else:
                G = el.geometric_matrix(Le)
                N = N + EA / (2 * Le) * np.einsum("...ei,eij,...ej->...e", vb, G, vb)
        return N

    def _local_rates(self, link: str):
        """Rotating-frame rates (n, n_el, 6) of the local element DOFs, or None.

        From the dense velocities and accelerations of the DOFs (:meth:`Sampler.acceleration`)
        through the constraint maps and their time derivatives: with ``x = E q + p``
        (global components) and ``d = T(theta) x``::

            x' = E q' + E' q + p',   x'' = E q'' + 2 E' q' + E'' q + p''
            d' = T x' + w S^T d,     d'' = T x'' + 2 w S^T (T x') + a S^T d - w^2 d

        (``S^T`` and ``w^2`` act on the translations). Without a sampler, spectral
        derivatives of ``d`` on a uniform grid over the cycle, else None.
        """
        key = ("rates", link)
        if key in self._cache:
            return self._cache[key]
        out = None
        if self.sampler is not None:
            sl = self.model.link_elements(link)
            gm = self._beam_map()
            cols = gm.cols[sl]
            pad = np.zeros((self.n, 1))
            acc = self.dof_accelerations()
            Q = [np.concatenate([X, pad], axis=1)[:, cols] for X in (self.U, self.V, acc)]  # (n, ne, m)
            E = gm.E[:, sl]

            def apply(A, q):
                return (A @ q[..., None])[..., 0]

            xd = apply(E, Q[1])
            xdd = apply(E, Q[2])
            if gm.E1 is not None:
                E1, E2 = gm.E1[:, sl], gm.E2[:, sl]
                xd = xd + apply(E1, Q[0])
                xdd = xdd + 2.0 * apply(E1, Q[1]) + apply(E2, Q[0])
            if gm.p is not None:
                xd = xd + gm.p1[:, sl]
                xdd = xdd + gm.p2[:, sl]
            th = self.motion.angle(link)
            w = self.motion.angular_velocity(link)[:, None, None]
            a = self.motion.angular_acceleration(link)[:, None, None]
            T = el.rotation_blocks(th)[:, None]
            d = self._local(link)
            Txd = (T @ xd[..., None])[..., 0]
            dd = Txd + w * _st(d)
            ddd = (T @ xdd[..., None])[..., 0] + 2.0 * w * _st(Txd) + a * _st(d) - w * w * _translations(d)
            out = (dd, ddd)
        elif self._uniform():
            out = recovery.periodic_rates(self._local(link), self.scene.period)
        else:
            log.info("%s: results without dense output on instants that are not a uniform grid: "
                     "section forces without the distributed-load correction", link)
        self._cache[key] = out
        return out

    def _uniform(self) -> bool:
        """The instants are a uniform grid over the whole cycle."""
        return self.n >= 8 and bool(np.allclose(np.diff(self.t), self.scene.period / self.n,
                                                rtol=1e-9, atol=0.0))

    def _forces(self, link: str, per_element: int):
        """Bending moment and axial force (n, n_el, per_element + 1) by element equilibrium."""
        return self._forces_at(link, np.linspace(0.0, 1.0, per_element + 1))

    def _forces_at(self, link: str, xi: np.ndarray):
        """Bending moment and axial force (n, n_el, nx) at fractions ``xi`` (nx,) of every element."""
        lk = self._link(link)
        key = ("forces", link, tuple(np.asarray(xi, float).tolist()))
        if key in self._cache:
            return self._cache[key]
        d = self._local(link)
        Le = _element_length(lk)
        xi = np.asarray(xi, float)
        q, p, N_h = self._element_loads(lk)
        out = recovery.section_forces(d, q, p, L=Le, EA=lk.material.E * lk.section.A,
                                      EI=lk.material.E * lk.section.I, xi=xi, N_h=N_h)
        blocks = self._blocks_on(lk)
        if blocks:
            out = self._with_blocks(lk, blocks, out, xi)
        self._cache[key] = out
        return out

    def _blocks_on(self, lk) -> list:
        """The slot joints whose blocks slide on link ``lk``."""
        return [j for j in self.model.mech.joints.values() if j.kind == "slot" and j.on == lk.name]

    def _element_loads(self, lk):
        """``(q, p, N_h)`` of the link's elements: the distributed loads at the load points
        (n, n_el, 4) each, or None without rates (:func:`kedfem.analysis.recovery.element_loads`),
        and the interpolated axial force (n, n_el) (computed once)."""
        key = ("element_loads", lk.name)
        if key in self._cache:
            return self._cache[key]
        link = lk.name
        d = self._local(link)
        ne = lk.elements
        Le = _element_length(lk)
        N_h = self._axial_fe(link)
        q = p = None
        sl = self.model.link_elements(link)
        b = self.model.beam
        rates = None if (b.lumped[sl].any() or b.timoshenko[sl].any()) else self._local_rates(link)
        if rates is not None:
            eff = set(getattr(self.scene, "effects", ()))
            mo = self.motion
            th = mo.angle(link)
            c, s = np.cos(th), np.sin(th)

            def local(v):  # R^T v, (n, 2)
                return np.stack([c * v[..., 0] + s * v[..., 1], -s * v[..., 0] + c * v[..., 1]], axis=-1)

            g = None
            if "gravity" in eff:
                g = local(np.broadcast_to(np.asarray(self.model.mech.gravity, float), (self.n, 2)))
            stiff = bool({"axial_stiffening", "geometric_nonlinearity"} & eff)
            q, p = recovery.element_loads(
                d, rates[0], rates[1], L=Le, rhoA=float(b.rhoA[sl][0]), s1=np.arange(ne) * Le if np.ndim(Le) == 0 else lk.nodes[:-1],
                omega=mo.angular_velocity(link), alpha=mo.angular_acceleration(link),
                a_loc=local(mo.a[:, mo.joint_names.index(lk.a)]), g_loc=g, N=N_h if stiff else None,
                inertia="inertia" in eff, coupling="coupling" in eff)
        out = self._cache[key] = (q, p, N_h)
        return out

    def block_stress(self, link: str) -> tuple[np.ndarray, np.ndarray]:
        """Normal stress under the blocks sliding on a link, and where, at every instant.

        The section forces by element equilibrium (:meth:`stress`) at each block's own abscissa
        (the apex of the moment's kink under its contact load), the larger of the axial force's
        two sides there (it steps by the contact's axial component).

        Returns
        -------
        stress : ndarray, shape (n,)
            Largest ``|N|/A + |M| c / I`` under a block [Pa] (0 without blocks).
        abscissa : ndarray, shape (n,)
            The block's abscissa along the link [m] (0 without blocks).
        """
        lk = self._link(link)
        key = ("block_stress", lk.name)
        if key in self._cache:
            return self._cache[key]
        from ..fe.slots import block_abscissa, element_at
        sec = lk.section
        if sec.c is None:
            raise InputError(f"link '{link}': its section has no extreme-fibre distance c, "
                             "so the bending stress is unknown (give Section(..., c=...))")
        best = np.zeros(self.n)
        where = np.zeros(self.n)
        for jt in self._blocks_on(lk):
            x = block_abscissa(self.model, jt.name, self.motion)
            e, zeta = element_at(lk, x)
            M, N_left, N_right = self._forces_under(lk, e, zeta)
            sig = np.maximum(np.abs(N_left), np.abs(N_right)) / sec.A + np.abs(M) * sec.c / sec.I
            take = sig > best
            best = np.where(take, sig, best)
            where = np.where(take, x, where)
        self._cache[key] = (best, where)
        return best, where

    def _forces_under(self, lk, e: np.ndarray, zeta: np.ndarray):
        """Bending moment (n,) [N m] and the axial force just before and just after (n,) each [N]
        at element ``e[r]``, fraction ``zeta[r]`` at every instant ``r`` (a point that moves)."""
        d = self._local(lk.name)
        q, p, N_h = self._element_loads(lk)
        L = lk.length / lk.elements
        rows = np.arange(self.n)
        E = lk.material.E
        B = el.shape_curvatures(L, zeta)[0]  # (n, 6)
        M = E * lk.section.I * np.einsum("ri,ri->r", B, d[rows, e])
        N = N_h[rows, e].copy()
        if q is not None:
            W, Wn = recovery.fixed_end_maps(zeta)
            M = M + L * L * np.einsum("rp,rp->r", W, q[rows, e])
            N = N + L * np.einsum("rp,rp->r", Wn, p[rows, e])
        N_left, N_right = N.copy(), N.copy()
        blocks = self._blocks_on(lk)
        if blocks:
            x = zeta * L
            for c0, c1, a, Py, Px, eb in self._contact_terms(lk, blocks):
                c0, c1, a, Py, Px = (v[:, 0] for v in (c0, c1, a, Py, Px))
                on = eb == e
                M = M + np.where(on, c0 + c1 * x + Py * np.maximum(x - a, 0.0), 0.0)
                # the axial force steps at the block: its two sides
                N_left = N_left + np.where(on, Px * np.where(x <= a, (L - a) / L, -a / L), 0.0)
                N_right = N_right + np.where(on, Px * np.where(x < a, (L - a) / L, -a / L), 0.0)
        return M, N_left, N_right

    def _with_blocks(self, lk, blocks, forces, xi):
        """Add the moment and axial force of each block's contact load in the element under it.

        The element's forces by equilibrium are the interpolation's plus, for each load in
        it, those of the element clamped at both ends: for a transverse force ``P`` at ``a``
        ``M = c0 + c1 x + P (x - a)+`` with ``int M = int M x = 0`` (no end slope or
        deflection), for an axial one ``N = P_a b / L`` before ``a`` and ``-P_a a / L`` after.
        """
        M, N = (np.array(f) for f in forces)
        L = lk.length / lk.elements
        x = xi * L
        rows = np.arange(self.n)
        for c0, c1, a, Py, Px, e in self._contact_terms(lk, blocks):
            M[rows, e] += c0 + c1 * x + Py * np.maximum(x - a, 0.0)
            N[rows, e] += Px * np.where(x > a, -a / L, (L - a) / L)
        return M, N

    def _contact_terms(self, lk, blocks) -> list:
        """Per block on link ``lk``: ``(c0, c1, a, Py, Px, e)``, the clamped element's moment
        ``c0 + c1 x + Py (x - a)+`` coefficients (n, 1) each, the contact's abscissa ``a`` in the
        element (n, 1) [m], its transverse and axial components (n, 1) [N] and the element (n,)."""
        from .loads import contact_forces
        from ..fe.slots import block_abscissa, element_at
        contact = self._cache.get("contact")
        if contact is None:
            contact = self._cache["contact"] = contact_forces(self)
        L = lk.length / lk.elements
        th = self.motion.angle(lk.name)
        c, s = np.cos(th), np.sin(th)
        out = []
        for jt in blocks:
            F = -contact[jt.name]  # the pin's force on the link
            Px, Py = c * F[:, 0] + s * F[:, 1], -s * F[:, 0] + c * F[:, 1]
            e, zeta = element_at(lk, block_abscissa(self.model, jt.name, self.motion))
            a = (zeta * L)[:, None]
            b = L - a
            r1 = -Py[:, None] * b**2 / 2
            r2 = -Py[:, None] * (L**3 / 3 - a * L**2 / 2 + a**3 / 6)
            det = L**4 / 12
            c0 = (r1 * L**3 / 3 - r2 * L**2 / 2) / det
            c1 = (r2 * L - r1 * L**2 / 2) / det
            out.append((c0, c1, a, Py[:, None], Px[:, None], e))
        return out

    def axial_force(self, link: str) -> np.ndarray:
        """Elastic axial force at the element midpoints (n, n_el) [N], tension positive.

        By element equilibrium (:mod:`kedfem.analysis.recovery`): ``EA (u2 - u1) /
        L_e`` (plus the membrane term ``EA/(2 L_e) int v'^2`` when the scene
        includes ``geometric_nonlinearity``) and the force of the element's
        distributed axial load. Midpoints are at ``stations(link)[:-1] + L_e / 2``.
        """
        return self._forces(link, 2)[1][..., 1]

    def bending_moment(self, link: str, per_element: int = 1) -> np.ndarray:
        """Bending moment ``EI v''`` at the link's stations (n, n_el per_element + 1) [N m].

        By element equilibrium (:mod:`kedfem.analysis.recovery`): the curvature of the
        nodal displacements' interpolation plus the moment of each element's
        distributed loads (rigid-body and elastic inertia, gravity, the
        axial force on the deflection) with its ends clamped; at a node the
        mean of the two elements meeting there. ``per_element`` stations per
        element (:meth:`stations`).
        """
        return _on_stations(self._forces(self._link(link).name, _per_element(per_element))[0])

    def dof_accelerations(self) -> np.ndarray:
        """Elastic DOF accelerations (n, N) [m/s^2, rad/s^2] at the result's instants, from the
        scheme's dense output (computed once)."""
        acc = self._cache.get("acceleration")
        if acc is None:
            acc = self._cache["acceleration"] = self.sampler.acceleration(self.t)
        return acc

    def section_forces(self, link: str, per_element: int = 1, sides: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Axial force ``N`` [N] (tension positive) and bending moment ``M = EI v''`` [N m] at the
        link's stations, each (n, n_el per_element + 1), by element equilibrium (nodes averaged).

        The axial force here is at the stations; :meth:`axial_force` gives it at the element
        midpoints. At a joint the link passes through (``through=``) the pin's force steps
        them: the mean of the two sides, or with ``sides=True`` both (the stations of
        ``stations(link, per_element, sides=True)``).
        """
        lk = self._link(link)
        M, N = self._forces(lk.name, _per_element(per_element))
        return _on_stations(N, lk.inner_nodes, sides=sides), _on_stations(M, lk.inner_nodes, sides=sides)

    def stress(self, link: str, per_element: int = 1) -> np.ndarray:
        """Largest absolute normal stress ``|N|/A + |M| c / I`` at the stations (n, n_el per_element + 1) [Pa].

        ``M`` and ``N`` by element equilibrium (:meth:`bending_moment`).
        Needs the section's extreme-fibre distance ``c``.
        """
        lk = self._link(link)
        sec = lk.section
        if sec.c is None:
            raise InputError(f"link '{link}': its section has no extreme-fibre distance c, "
                             "so the bending stress is unknown (give Section(..., c=...))")
        M, N = self._forces(lk.name, _per_element(per_element))
        return _on_stations(np.abs(N) / sec.A + np.abs(M) * sec.c / sec.I,
                            lk.inner_nodes, larger=True)

    def link_geometry(self, link: str) -> np.ndarray:
        """Rigid-body positions (n, n_el + 1, 2) [m] of a flexible link's nodes over the cycle."""
        lk = self._link(link)
        a, b = np.array(self.model.mech.joints[lk.a].at), np.array(self.model.mech.joints[lk.b].at)
        e1 = (b - a) / lk.length
        r, _v, _a = self.motion.point(link, lk.a, self.stations(link)[:, None] * e1[None, :])
        return r

    def link_displacement(self, link: str, U: np.ndarray | None = None) -> np.ndarray:
        """Elastic displacement (n, n_el + 1, 2) [m] of a flexible link's nodes, global components.

        Includes prescribed parts (clamped ends on pins, passive-link stretch).
        With ``U`` (n, N) a different DOF history (e.g. a mode shape
        broadcast over time) is mapped instead of the response.
        """
        lk = self._link(link)
        sl = self.model.link_elements(link)
        gm = self._beam_map()
        own = U is None
        U = self.U if own else np.broadcast_to(np.asarray(U, float), self.U.shape)
        x = gm.apply(U, sl, offset=own)
        out = np.empty((self.n, lk.elements + 1, 2))
        out[:, :-1] = x[:, :, 0:2]
        out[:, -1] = x[:, -1, 3:5]
        return out

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

    def joint_displacement(self, joint: str, U: np.ndarray | None = None) -> np.ndarray:
        """Elastic displacement (n, 2) [m] of a joint (global components).

        With ``U`` (n, N) or (N,) a different DOF history (e.g. a mode shape)
        is mapped instead of the response.
        """
        forms = self._cache.get("forms")
        if forms is None:
            forms = self.model.entity_forms(self.motion)["P"]
            self._cache["forms"] = forms
        name("joint_displacement", "joint", joint, self.model.joint_point)
        cols, C, *_rest = forms[self.model.joint_point[joint]]
        if not cols:
            return np.zeros((self.n, 2))
        U = self.U if U is None else np.broadcast_to(np.asarray(U, float), self.U.shape)
        q = U[:, list(cols)]
        return np.einsum("tij,tj->ti", np.broadcast_to(C, (self.n,) + C.shape[1:]), q)

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

    def _polish_stations(self, links, series, best, sub: int = 8):
        """At each stress peak's instant, the peak along the link on stations ``sub`` times finer.

        The vertex through three of :data:`PEAK_STATIONS` stations per element
        is within about 1e-5 of the peak; on ``sub`` times finer stations it is
        within 1e-8. The value replaces the one of the refinement in time.
        """
        idx = [si for si, (_i, kind, _v) in enumerate(series) if kind == "stress"]
        if not idx:
            return best
        period = self.scene.period
        one = self.resample(np.mod([best[si][1] for si in idx], period))
        out = dict(best)
        for r, si in enumerate(idx):
            lk = links[series[si][0]]
            vals = one.stress(lk.name, per_element=PEAK_STATIONS * sub)[r]
            j = int(np.argmax(vals))
            v, dj = _vertex(vals, j)
            if {j - 1, j, j + 1} & {i * PEAK_STATIONS * sub for i in lk.inner_nodes}:
                v, dj = float(vals[j]), 0.0  # the stress steps at a pin the link passes: no parabola across
            # an evaluation at the instant's vertex (the vertices in time and along the link
            # added together over-shoot a peak on a ridge that is not along the axes)
            station = (j + dj) / sub
            h = lk.length / (lk.elements * PEAK_STATIONS * sub)
            if self._blocks_on(lk):
                s_, x = (float(a[r]) for a in one.block_stress(lk.name))
                # the stress is kinked under a block: no parabola there, the apex itself
                if abs(x - j * h) <= 2.0 * h:
                    v, station = max((float(vals[j]), j / sub), (s_, x / (h * sub)))
            out[si] = (v, best[si][1], station)
        return out

    def _block_abscissa_at(self, lk, t: float) -> float:
        """Abscissa [m] along ``lk`` of the block under which the stress is largest at instant ``t``."""
        if self.sampler is None:
            k = int(np.argmin(np.abs(np.mod(self.t - t + 0.5 * self.scene.period, self.scene.period)
                                      - 0.5 * self.scene.period)))
            return float(self.block_stress(lk.name)[1][k])
        return float(self.resample(np.array([np.mod(t, self.scene.period)])).block_stress(lk.name)[1][0])

    def _angle_of(self, t: float) -> float:
        """Crank angle [rad] in ``[0, 2 pi)`` at instant ``t`` (linear in time for a constant-speed drive)."""
        w = self.model.mech.drives[0].speed if self.model.mech.drives else 0.0
        return float(np.mod(self.crank_angle[0] + w * (t - self.t[0]), 2.0 * math.pi))

    def _refine_peaks(self, links, series, best, candidates: int = 2, sub: int = 8):
        """Refine grid peaks on local fine grids around the largest local maxima."""
        period = self.scene.period
        t = self.t
        n = t.size
        windows = []  # (series index, window centre on the grid)
        for si, (i, kind, vals) in enumerate(series):
            flat = vals if vals.ndim == 1 else vals.max(axis=1)
            loc = np.flatnonzero((flat >= np.roll(flat, 1)) & (flat >= np.roll(flat, -1)))
            loc = loc[np.argsort(-flat[loc])][:candidates]
            windows.extend((si, int(k)) for k in loc)
        if not windows:
            return best
        # a link's deflection and stress (and neighbouring links) often peak at the same instant:
        # each window centre is read once
        centres = sorted({k for _si, k in windows})
        where = {k: r for r, k in enumerate(centres)}
        m = 2 * sub + 1
        tw_all = np.array([np.linspace(t[k - 1] if k > 0 else t[-1] - period,
                                       t[k + 1] if k + 1 < n else t[0] + period, m) for k in centres])
        fine = self.resample(np.mod(tw_all.ravel(), period))
        cache = {}
        for si, (i, kind, vals) in enumerate(series):
            name = links[i].name
            cache[si] = (fine._peak_deflection(links[i]) if kind == "deflection"
                         else fine.block_stress(name)[0] if kind == "block"
                         else fine.stress(name, per_element=PEAK_STATIONS))
        out = dict(best)
        for si, k in windows:
            r = where[k]
            tw = tw_all[r]
            vals = cache[si][r * m:(r + 1) * m]
            v, tt, j = _grid_peak(vals, tw)
            if v > out[si][0]:
                out[si] = (v, float(np.mod(tt, period)), j)
        return out

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
