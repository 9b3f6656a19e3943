"""Campbell diagram: natural-frequency bands over the cycle against the drive's harmonics.

A linkage's natural frequencies vary over its cycle (the links turn and the
kinetostatic forces change), so each mode occupies a *band* of frequencies at a
given crank speed: its minimum, cycle mean and maximum over the cycle. The
periodic motion excites the harmonics ``k f_c`` of the crank frequency ``f_c =
|speed| / 2 pi``; wherever a harmonic line runs through a band, the drive can
resonate that mode. :func:`campbell` computes the bands at a list of speeds and
flags every such crossing (mode, harmonic, speed range).

The bands come from the undamped modal analysis on the rigid-body motion with
the scene's linear effects (``method="modal"``, the default: the co-moving-frame
``K phi = omega^2 M phi`` of :func:`kedfem.analysis.modal.natural_frequencies`,
no periodic solve; ``geometric_nonlinearity`` is replaced by its linear part,
``axial_stiffening``), or from a periodic solve at each speed
(``method="solve"``: :meth:`PeriodicResult.frequencies`, the tangent stiffness
about the converged response). docs/design.md says why the first is the
default: the same numbers for linear scenes, within 3 % for the four-bar's
geometric non-linearity, 25x cheaper, and defined above the speeds where a
periodic response stops existing.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..checks import choice
from ..errors import InputError
from ..fe.effects import LINEAR_EFFECTS, linear_effects
from ..model.mechanism import Mechanism
from .buckling import BuckledMode, buckled_mode
from .modal import natural_frequencies
from .hooks import hook
from .progress import bar
from .scene import Scene, _int
from ..units import RPM_PER_RAD_S

__all__ = ["Crossing", "CampbellResult", "campbell", "crossings", "linear_effects", "scene_at", "cycle_frequencies",
           "check_speeds", "BAND_STATS"]

log = logging.getLogger(__name__)

#: The three numbers of a band, in the order of the last axis of :attr:`CampbellResult.bands`.
BAND_STATS = ("min", "mean", "max")
#: Campbell methods: modal analysis on the rigid-body motion, or the frequencies of a periodic solve.
METHODS = ("modal", "solve")


def scene_at(source, speed: float, *, effects: Sequence[str] | None = None, owner: str = "campbell") -> Scene:
    """The scene of ``source`` at the drive speed ``speed`` [rad/s].

    Parameters
    ----------
    source : Scene, Mechanism or callable
        A scene (its speed is replaced), a mechanism (a scene with ``effects``,
        default :data:`~kedfem.fe.effects.LINEAR_EFFECTS`, and 2 % modal
        damping), or a builder ``f(speed) -> Scene | Mechanism`` for
        mechanisms whose other parameters follow the speed.
    speed : float
        First drive's speed [rad/s].
    effects : sequence of str, optional
        Replace the scene's effects.
    owner : str
        Function name for messages.
    """
    from ..fe.effects import ModalDamping
    if isinstance(source, Scene):
        sc = dataclasses.replace(source, speed=float(speed))
    elif isinstance(source, Mechanism):
        sc = Scene(source, speed=float(speed), effects=LINEAR_EFFECTS, damping=ModalDamping(0.02))
    elif callable(source):
        import inspect
        try:
            inspect.signature(source).bind(float(speed))
        except TypeError as e:
            raise InputError(f"{owner}: the builder must take one argument, the speed [rad/s] "
                             f"(f(speed) -> Scene | Mechanism): {e}") from None
        except ValueError:  # no signature (a built-in): call it and see
            pass
        built = source(float(speed))
        if isinstance(built, Mechanism):  # at the speed asked, whatever the builder did with it
            sc = Scene(built, speed=float(speed), effects=LINEAR_EFFECTS, damping=ModalDamping(0.02))
        elif isinstance(built, Scene):
            sc = dataclasses.replace(built, speed=float(speed))
        else:
            raise InputError(f"{owner}: the builder must return a kf.Scene or kf.Mechanism, got "
                             f"{type(built).__name__}")
    else:
        raise InputError(f"{owner}: scene must be a kf.Scene, a kf.Mechanism or a builder f(speed [rad/s]) "
                         f"-> Scene | Mechanism, got {type(source).__name__}")
    if effects is not None:
        sc = dataclasses.replace(sc, effects=tuple(effects))
    return sc


def check_speeds(speeds, owner: str, name: str = "speeds_rad_s") -> np.ndarray:
    """Speeds as a float array (n,), finite, > 0 and strictly increasing; else an InputError naming ``name``."""
    try:
        s = np.asarray(speeds, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{owner}: {name} must be numbers [rad/s], got {speeds!r}") from None
    if s.ndim != 1 or s.size < 2:
        raise InputError(f"{owner}: {name} must be a 1-D sequence of at least 2 speeds [rad/s], got shape {s.shape}")
    if not np.all(np.isfinite(s)) or np.any(s <= 0) or np.any(np.diff(s) <= 0):
        raise InputError(f"{owner}: {name} must be finite, > 0 and strictly increasing [rad/s], got {s.tolist()}")
    return s


@dataclass(frozen=True)
class Crossing:
    """A harmonic of the drive running through a mode's frequency band.

    Attributes
    ----------
    mode : int
        Mode number (1 = lowest at each crank position).
    harmonic : int
        ``k`` of the harmonic line ``k f_c`` [-].
    speed_lo, speed_hi : float
        Speed range where ``k f_c`` lies inside the band [rad/s] (equal for a
        band of zero width, a time-invariant structure).
    speed_mean : float
        Speed where ``k f_c`` equals the band's cycle mean [rad/s] (NaN if it
        does not within the range): the resonance a single-frequency model predicts.
    open_lo, open_hi : bool
        The range reaches the first / last speed analysed: it may continue beyond.
    """

    mode: int
    harmonic: int
    speed_lo: float
    speed_hi: float
    speed_mean: float
    open_lo: bool = False
    open_hi: bool = False

    @property
    def rpm_lo(self) -> float:
        """``speed_lo`` [rev/min]."""
        return self.speed_lo * RPM_PER_RAD_S

    @property
    def rpm_hi(self) -> float:
        """``speed_hi`` [rev/min]."""
        return self.speed_hi * RPM_PER_RAD_S

    @property
    def rpm_mean(self) -> float:
        """``speed_mean`` [rev/min]."""
        return self.speed_mean * RPM_PER_RAD_S

    @property
    def frequency_lo(self) -> float:
        """Harmonic frequency at ``speed_lo`` [Hz]."""
        return self.harmonic * self.speed_lo / (2.0 * math.pi)

    @property
    def frequency_hi(self) -> float:
        """Harmonic frequency at ``speed_hi`` [Hz]."""
        return self.harmonic * self.speed_hi / (2.0 * math.pi)

    def describe(self) -> str:
        """One line: mode, harmonic, speed range [rpm], the mean-frequency resonance."""
        mean = f", at the band mean {self.rpm_mean:.1f} rpm" if math.isfinite(self.speed_mean) else ""
        lo = "<=" if self.open_lo else ""
        hi = "+" if self.open_hi else ""
        return (f"mode {self.mode} x harmonic {self.harmonic}: {lo}{self.rpm_lo:.1f} .. {self.rpm_hi:.1f}{hi} rpm "
                f"({self.frequency_lo:.4g} .. {self.frequency_hi:.4g} Hz){mean}")


@dataclass(frozen=True)
class CampbellResult:
    """Natural-frequency bands over the cycle at a list of crank speeds, and the resonance flags.

    Attributes
    ----------
    speeds : ndarray, shape (n_speeds,)
        First drive's speeds [rad/s], increasing.
    bands : ndarray, shape (n_speeds, n_modes, 3)
        Per speed and mode: minimum, cycle mean and maximum of the natural
        frequency over the cycle [Hz] (:data:`BAND_STATS`); a negative value is a
        negative stiffness eigenvalue ``-sqrt(-lambda) / 2 pi`` (buckled).
    harmonics : ndarray of int, shape (n_harmonics,)
        ``k = 1 .. K`` of the harmonic lines ``k f_c``.
    crossings : tuple of Crossing
        Every harmonic line running through a band, by mode then harmonic.
    method : {"modal", "solve"}
        Where the frequencies come from (module docstring).
    effects : tuple of str
        The effects of the stiffness the frequencies are of.
    nodes : int
        Crank positions per cycle the bands are taken over.
    name : str
        Scene or mechanism name, for titles.
    buckling : BuckledMode or None
        Where a band reaches below 0 Hz: the lowest mode at the first buckled speed and the link
        that carries most of it (:func:`kedfem.analysis.buckling.buckled_mode`).
    """

    speeds: np.ndarray
    bands: np.ndarray
    harmonics: np.ndarray
    crossings: tuple[Crossing, ...]
    method: str
    effects: tuple[str, ...]
    nodes: int
    name: str = ""
    buckling: BuckledMode | None = None

    @property
    def rpm(self) -> np.ndarray:
        """Speeds [rev/min], shape (n_speeds,)."""
        return self.speeds * RPM_PER_RAD_S

    @property
    def crank_frequency(self) -> np.ndarray:
        """Crank frequency ``f_c = speed / 2 pi`` [Hz], shape (n_speeds,)."""
        return self.speeds / (2.0 * math.pi)

    @property
    def harmonic_lines(self) -> np.ndarray:
        """``k f_c`` [Hz], shape (n_speeds, n_harmonics)."""
        return self.crank_frequency[:, None] * self.harmonics[None, :]

    @property
    def buckled(self) -> np.ndarray:
        """Speeds at which some crank position has a negative stiffness eigenvalue, shape (n_speeds,) bool."""
        return self.bands[:, 0, 0] < 0

    def band(self, mode: int) -> np.ndarray:
        """Band of mode ``mode`` (1-based): min, mean, max [Hz], shape (n_speeds, 3)."""
        n = self.bands.shape[1]
        if isinstance(mode, bool) or not isinstance(mode, (int, np.integer)) or not 1 <= mode <= n:
            raise InputError(f"CampbellResult.band: mode must be an integer in 1 .. {n}, got {mode!r}")
        return self.bands[:, mode - 1, :]

    def buckled_ranges(self, mode: int) -> list[tuple[float, float]]:
        """Speed ranges [rad/s] (first and last speed analysed) over which mode ``mode``'s band
        reaches below 0 Hz: a negative stiffness eigenvalue at some crank position (buckled)."""
        below = self.band(mode)[:, 0] < 0
        edges = np.flatnonzero(np.diff(np.concatenate([[0], below.astype(int), [0]])))
        return [(float(self.speeds[a]), float(self.speeds[b - 1])) for a, b in zip(edges[::2], edges[1::2])]

    def describe(self) -> str:
        """The crossings, one per line (or that there is none), and the speeds where a mode buckles.

        A crossing over speeds where its mode's band reaches below 0 Hz is marked: there the mode
        has a negative stiffness eigenvalue at some crank position (the linkage buckles under its
        kinetostatic forces), which a crossing of the drive's harmonics does not describe (a new
        user read the slider-crank's buckled speeds as resonance bands)."""
        head = (f"Campbell diagram of {self.name or 'the scene'}: {self.bands.shape[1]} modes, harmonics "
                f"1..{int(self.harmonics[-1])}, {self.rpm[0]:.6g} .. {self.rpm[-1]:.6g} rpm ({self.method})")
        lines = [head]
        ranges = {j: self.buckled_ranges(j) for j in range(1, self.bands.shape[1] + 1)}
        for c in self.crossings:
            over = [(max(a, c.speed_lo), min(b, c.speed_hi)) for a, b in ranges[c.mode]
                    if a <= c.speed_hi and b >= c.speed_lo]
            note = "; ".join(f"{a * RPM_PER_RAD_S:.1f} .. {b * RPM_PER_RAD_S:.1f} rpm" for a, b in over)
            lines.append("  " + c.describe() + (f" (over {note} of it the mode buckles: there the question is "
                                                f"the linkage's stability, not this resonance)" if over else ""))
        if not self.crossings:
            lines.append("  no harmonic of the drive crosses a frequency band")
        top = self.speeds[-1]
        for j, rs in ranges.items():
            if rs:
                spans = ", ".join(f"{a * RPM_PER_RAD_S:.1f} .. {b * RPM_PER_RAD_S:.1f}{'+' if b >= top else ''} rpm"
                                  for a, b in rs)
                who = (f": {self.buckling.describe()} at {rs[0][0] * RPM_PER_RAD_S:.1f} rpm"
                       if j == 1 and self.buckling is not None else "")
                lines.append(f"  mode {j} BUCKLES (a negative stiffness eigenvalue at some crank position; its band "
                             f"reaches below 0 Hz) over {spans} (the speeds analysed; critical_speed(kind="
                             f"'buckling') finds the onset){who}")
        return "\n".join(lines)

    def to_csv(self, path) -> Path:
        """Write the bands: one row per speed and mode (``speed_rad_s``, ``speed_rpm``, ``crank_Hz``,
        ``mode``, ``f_min_Hz``, ``f_mean_Hz``, ``f_max_Hz``); the crossings go to their own table
        (:meth:`crossings_to_csv`). See :func:`kedfem.io.design_plots.write_campbell_csv`."""
        return hook("campbell_csv")(self, path)

    def crossings_to_csv(self, path) -> Path:
        """Write the crossings, one row each (see :func:`kedfem.io.design_plots.write_crossings_csv`)."""
        return hook("crossings_csv")(self, path)

    def plot(self, path) -> Path:
        """Campbell diagram (PNG): Hz vs rpm, shaded bands, harmonic lines, crossings marked
        (:func:`kedfem.io.design_plots.campbell_chart`)."""
        return hook("campbell_chart")(self, path)


# ------------------------------------------------------------- crossings
def _half(g0: np.ndarray, g1: np.ndarray, sign: float) -> tuple[np.ndarray, np.ndarray]:
    """Part ``[t0, t1]`` of ``[0, 1]`` where ``sign * g(t) >= 0``, ``g`` linear from ``g0`` to ``g1``
    (batched; ``t0 > t1`` where it is empty)."""
    a, b = sign * g0, sign * g1
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.clip(a / (a - b), 0.0, 1.0)
    t0 = np.where(a >= 0, 0.0, np.where(b >= 0, r, 2.0))
    t1 = np.where(b >= 0, 1.0, np.where(a >= 0, r, -1.0))
    return t0, t1


def crossings(speeds: np.ndarray, bands: np.ndarray, harmonics: np.ndarray) -> tuple[Crossing, ...]:
    """Where each harmonic line ``k speed / 2 pi`` lies inside each mode's band.

    Bands and lines are taken as linear between the speeds, so a crossing between
    two speeds is found even when no speed lies inside the band.

    Parameters
    ----------
    speeds : ndarray, shape (n,)
        Increasing speeds [rad/s].
    bands : ndarray, shape (n, m, 3)
        Min, mean, max [Hz].
    harmonics : ndarray of int, shape (K,)

    Returns
    -------
    tuple of Crossing
        By mode, then harmonic, then speed.
    """
    h = (speeds / (2.0 * math.pi))[:, None, None] * harmonics[None, None, :]      # (n, 1, K)
    g_lo = h - bands[:, :, 0, None]                                                  # (n, m, K): >= 0 inside
    g_hi = h - bands[:, :, 2, None]                                                  # <= 0 inside
    a0, a1 = _half(g_lo[:-1], g_lo[1:], 1.0)
    b0, b1 = _half(g_hi[:-1], g_hi[1:], -1.0)
    t0, t1 = np.maximum(a0, b0), np.minimum(a1, b1)                                  # (n-1, m, K) per segment
    inside = t0 <= t1
    # segments whose inside parts touch at the speed between them belong to one crossing
    joined = inside[:-1] & inside[1:] & (t1[:-1] >= 1.0) & (t0[1:] <= 0.0)           # (n-2, m, K)
    first = inside.copy()
    first[1:] &= ~joined
    last = inside.copy()
    last[:-1] &= ~joined
    ds = np.diff(speeds)[:, None, None]
    s_lo = speeds[:-1, None, None] + t0 * ds
    s_hi = speeds[:-1, None, None] + t1 * ds
    # where the line meets the band mean, per segment (NaN where it does not)
    g_m = h - bands[:, :, 1, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        r = g_m[:-1] / (g_m[:-1] - g_m[1:])
    meets = (np.sign(g_m[:-1]) != np.sign(g_m[1:])) | (g_m[:-1] == 0)
    s_mean = np.where(meets, speeds[:-1, None, None] + np.nan_to_num(np.clip(r, 0, 1)) * ds, np.nan)
    out = []
    n_seg = inside.shape[0]
    for j in range(bands.shape[1]):
        for q, k in enumerate(harmonics):
            starts = np.flatnonzero(first[:, j, q])
            ends = np.flatnonzero(last[:, j, q])
            for i0, i1 in zip(starts, ends):
                sm = s_mean[i0:i1 + 1, j, q]
                sm = sm[np.isfinite(sm)]
                lo, hi = float(s_lo[i0, j, q]), float(s_hi[i1, j, q])
                slack = 1e-12 * hi  # the mean of a band of zero width is its ends, to round-off
                sm = np.clip(sm[(sm >= lo - slack) & (sm <= hi + slack)], lo, hi)
                out.append(Crossing(j + 1, int(k), lo, hi, float(sm[0]) if sm.size else float("nan"),
                                    open_lo=bool(i0 == 0 and t0[i0, j, q] <= 0.0),
                                    open_hi=bool(i1 == n_seg - 1 and t1[i1, j, q] >= 1.0)))
    return tuple(out)


# --------------------------------------------------------------- the bands
def cycle_frequencies(sc: Scene, n_modes: int, nodes: int) -> np.ndarray:
    """Natural frequencies at ``nodes`` crank positions of the scene's rigid-body motion (nodes, n_modes)."""
    from ..solvers.threads import one_blas_thread
    eff = linear_effects(sc.effects)
    # one BLAS thread: batched small eigenproblems run 10x slower on OpenBLAS's threads when the other core is busy
    with warnings.catch_warnings(), one_blas_thread():
        warnings.simplefilter("ignore", RuntimeWarning)  # negative eigenvalues are reported as such
        return np.asarray(natural_frequencies(sc.mech, n_modes=n_modes, effects=eff, steps=nodes).frequencies)


def _solved_frequencies(sc: Scene, n_modes: int, nodes: int) -> np.ndarray:
    """Modal frequencies at ``nodes`` equally spaced output instants of the scene's periodic solve."""
    from ..errors import InstabilityWarning
    from .pipeline import solve
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InstabilityWarning)
        res = solve(sc)
    if not res.converged:
        log.warning("%s at %.6g rad/s: the non-linear iteration did not converge; its frequencies are "
                    "about an unconverged state", sc.mech.name, sc.mech.drives[0].speed)
    idx = np.unique(np.floor(np.arange(nodes) * (res.n / nodes)).astype(int))
    return np.asarray(res.frequencies(n_modes, nodes=idx).modal)


def bands_of(freqs: np.ndarray) -> np.ndarray:
    """Min, mean and max over the cycle (axis -2) of frequencies (..., nodes, m): shape (..., m, 3)."""
    return np.stack([freqs.min(axis=-2), freqs.mean(axis=-2), freqs.max(axis=-2)], axis=-1)


def campbell(scene, speeds_rad_s, n_modes: int = 4, harmonics: int = 6, nodes: int = 36, *,
             method: str = "modal", effects: Sequence[str] | None = None,
             progress: bool | None = None) -> CampbellResult:
    """Campbell diagram: the natural-frequency bands over the cycle at each speed, and the resonances.

    Parameters
    ----------
    scene : Scene, Mechanism or callable
        The scene (its speed is replaced by each of ``speeds_rad_s``), a mechanism
        (linear effects), or a builder ``f(speed [rad/s]) -> Scene | Mechanism``.
    speeds_rad_s : array_like, shape (n_speeds,)
        First drive's speeds [rad/s], > 0, strictly increasing (at least 2).
    n_modes : int
        Lowest modes per crank position.
    harmonics : int
        Harmonic lines ``k f_c``, ``k = 1 .. harmonics``.
    nodes : int
        Crank positions per cycle (equally spaced in time, from the reference
        configuration) the bands are taken over, >= 3.
    method : {"modal", "solve"}
        ``"modal"``: undamped modal analysis on the rigid-body motion with the
        scene's linear effects (:func:`linear_effects`), no periodic solve.
        ``"solve"``: a periodic solve per speed, modal frequencies about the
        converged response (:meth:`PeriodicResult.frequencies`; nodes at the
        nearest output instants).
    effects : sequence of str, optional
        Replace the scene's effects.
    progress : bool, optional
        A progress bar on stderr, one step per speed (default: on a terminal, after 2 s).

    Returns
    -------
    CampbellResult
        ``bands`` (n_speeds, n_modes, 3) [Hz] and the ``crossings``.

    Raises
    ------
    InputError
        Bad speeds, counts or method (the message names the parameter).
    """
    owner = "campbell"
    s = check_speeds(speeds_rad_s, owner)
    n_modes = _int(owner, "n_modes", n_modes, 1)
    harmonics = _int(owner, "harmonics", harmonics, 1)
    nodes = _int(owner, "nodes", nodes, 3)
    choice(owner, "method", method, METHODS)
    freq = cycle_frequencies if method == "modal" else _solved_frequencies
    per_speed = []
    sc = None
    with bar("campbell", "speed", s.size, progress) as b:
        for w in s:  # one modal analysis (or solve) per speed
            sc = scene_at(scene, float(w), effects=effects, owner=owner)
            per_speed.append(freq(sc, n_modes, nodes))
            log.debug("campbell: %s at %.6g rad/s done", sc.mech.name, w)
            b.update(1)
    k = min(f.shape[1] for f in per_speed)
    if k < n_modes:
        log.warning("campbell: %s has %d elastic modes; %d asked", sc.mech.name, k, n_modes)
    bands = bands_of(np.stack([f[:, :k] for f in per_speed]))
    ks = np.arange(1, harmonics + 1)
    eff = linear_effects(sc.effects) if method == "modal" else sc.effects
    buckling = None
    if np.any(bands[:, 0, 0] < 0):  # which link buckles, at the first buckled speed
        first = float(s[int(np.argmax(bands[:, 0, 0] < 0))])
        bsc = scene_at(scene, first, effects=effects, owner=owner)
        buckling = buckled_mode(bsc.mech, bsc.effects, nodes)
    res = CampbellResult(s, bands, ks, crossings(s, bands, ks), method, eff, nodes, sc.name or sc.mech.name,
                         buckling)
    log.info("campbell: %s, %d speeds, %d modes: %d crossings", res.name, s.size, k, len(res.crossings))
    return res
