"""How far a result is from converged in time: two- and three-level estimates.

A periodic solve on ``n`` time elements is compared with the same solve on
fewer elements (same scheme, same output instants). With the values ``q_c``
(coarse, ``n_c`` elements) and ``q_f`` (fine, ``n_f``) of a quantity and the
convergence rate ``p``, Richardson's argument gives the error of the fine
value as::

    e_f ~ SAFETY |q_f - q_c| / ((n_f / n_c)^p - 1)

The rate is *observed* from three levels where they exist (the ratio of
successive differences). Levels in the scheme's asymptotic range (observed
rate at least :data:`ASYMPTOTIC_FRACTION` of the scheme's order for values
read between element ends, e.g. 2.5 for ``radau3``, whose dense output is of
order 4) are credited the observed rate up to that order; levels before it
(irregular convergence: the error of a badly resolved resonance can stall or
change sign, then drop 20-50x at the next doubling) only up to the scheme's
conservative ``assumed_rate`` and at least 1, which over-estimates rather
than under-estimates. A tolerance-driven solve stops on levels in the
asymptotic range, where the estimate is within a small factor of the truth
(``benchmarks/error_estimate.py``: 0.35 .. 7 on the catalogue and four
linkages outside it at the default tolerance), or before it on an estimate far
inside the tolerance (:data:`SETTLED_FRACTION`, :data:`CLEAR_FRACTION`). With two levels the rate is
the scheme's ``assumed_rate``. Errors are relative: a peak's to the peak, a
history's (the largest difference over the cycle) to the history's own peak.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

log = logging.getLogger(__name__)

__all__ = ["LinkError", "ErrorEstimate", "Observables", "estimate", "defect_estimate", "explained", "promising",
           "ASSUMED_RATE", "SAFETY", "ASYMPTOTIC_FRACTION", "HISTORY_FRACTION", "SETTLED_FRACTION",
           "CLEAR_FRACTION", "EXPLAINED", "READ_NOISE"]

#: Factor on every estimate: two levels whose errors have opposite signs differ
#: by less than the coarser one's error, which the rate alone does not see
#: (measured on the flexible four-bar at 100 rpm, 0.5 % damping: a quantity whose
#: error did not fall from 48 to 96 elements while the others fell 10x; estimate /
#: true error 0.26 without it; ``benchmarks/error_estimate.py``).
SAFETY = 1.35
#: Levels are in the asymptotic range when their observed rate reaches this
#: fraction of the scheme's order between element ends (``Scheme.dense_order``).
ASYMPTOTIC_FRACTION = 0.625
#: The histories of levels in the asymptotic range converge at least at this
#: fraction of the order (radau3: 2); below it a resonance is still being
#: resolved and a peak's rate can be a coincidence (measured on an offset
#: slider-crank with a flexible crank and rod; costs nothing on the
#: estimate study's 52 cases).
HISTORY_FRACTION = 0.5
#: Three levels before the asymptotic range whose peaks' estimate (at most the assumed rate) is
#: below this fraction of ``rtol``, and whose histories converge (observed rate at least 1), meet
#: it clearly: the estimate may be off by the 5x the history rate guards against (the offset
#: slider-crank below) and still be 20x inside. The Whitworth at rtol 1e-3: peaks 9e-6 on
#: 96/192/384, histories converging at rate 1.8 (below the 2 that asymptotic asks), refined to
#: 768 elements for a peak error of 3e-7.
CLEAR_FRACTION = 0.01
#: Three levels whose two differences (peaks and histories, times :data:`SAFETY`)
#: both stay below this fraction of ``rtol`` have settled: their rate is read-out
#: noise (a linkage at 1 rpm, whose response is the static one: differences of
#: 1e-12, "rate 1.0", refined to 12288 elements for nothing), and the estimate
#: credited at rate 1 is already far inside the tolerance. A stalled resonance
#: (the danger before the asymptotic range) does not stall twice in a row this
#: far below the tolerance on levels that resolve its mode.
SETTLED_FRACTION = 0.01
#: A one-level defect-corrected estimate (:mod:`kedfem.solvers.defect`) is believed when the
#: coarser of two levels, corrected by its own estimate, is within this fraction of their
#: difference from the finer one, in every link's peak deflection and stress (with
#: :data:`READ_NOISE` for the read-out's round-off): the estimate then explains the change the
#: refinement made. The defect estimate is 0.2 .. 0.7 of the true error before the elements
#: resolve the modes that carry it and 1.0 .. 1.2 after (``benchmarks/defect_probe.py``); a
#: coarse estimate off by more than half leaves more than half the change unexplained.
EXPLAINED = 0.5
#: Relative change of a peak below which two levels' difference is read-out round-off (the
#: peaks of a 1 rpm linkage differ by 1e-12 .. 1e-9 between levels); :func:`explained` allows it,
#: and no more (rtol / 100 at rtol 1e-2 let a crank-rocker pass with half its change unexplained).
READ_NOISE = 1e-7
#: Rate credited to a two-level estimate, per scheme: below the scheme's
#: asymptotic rate for values read between element ends, so that a pair of
#: solves before the asymptotic range is not under-estimated.
ASSUMED_RATE = {"radau3": 3.0, "radau2": 2.0, "gauss3": 3.0, "gauss2": 2.0, "magnus2": 2.0,
                "foh": 1.0, "zoh": 1.0, "fourier": 2.0}


@dataclass(frozen=True)
class Observables:
    """What a level of a solve is judged by: per flexible link, its peaks and histories.

    All levels of a solve are read on the same ``n_out`` output instants.

    Attributes
    ----------
    links : tuple of str
    elements : int
        Time elements of the level.
    deflection : ndarray, shape (n_links,)
        Peak |mid-span deflection relative to the chord| [m].
    deflection_at : ndarray of int, shape (n_links,)
        Output instant nearest to that peak.
    stress : ndarray, shape (n_links,)
        Peak stress [Pa] (0 for links without an extreme-fibre distance).
    stress_at : ndarray of int, shape (n_links,)
        Output instant nearest to that peak.
    stress_station : ndarray of int, shape (n_links,)
        Station (node) of that peak.
    deflection_history : tuple of ndarray, each (n_out,) or (n_out, n_stretches)
        Mid-span deflection relative to the chord [m] (of each stretch of a link passing
        through joints).
    stress_history : tuple of ndarray, each (n_out, n_stations)
        Stress at every station [Pa] (``(n_out, 0)`` without ``c``).
    has_stress : tuple of bool
    axial_history : tuple of ndarray, each (n_out, n_stations)
        Axial force at every station [N]: the bearing loads ride on it, and its error is
        hidden in the stress where bending dominates (a four-bar at 5 rpm on 96 elements:
        stress histories 1e-3, bearing forces 5e-3 off); empty tuple when not read.
    """

    links: tuple[str, ...]
    elements: int
    deflection: np.ndarray
    deflection_at: np.ndarray
    stress: np.ndarray
    stress_at: np.ndarray
    stress_station: np.ndarray
    deflection_history: tuple[np.ndarray, ...]
    stress_history: tuple[np.ndarray, ...]
    has_stress: tuple[bool, ...]
    axial_history: tuple[np.ndarray, ...] = ()


@dataclass(frozen=True)
class LinkError:
    """Estimated relative time-discretisation errors of one flexible link.

    Attributes
    ----------
    link : str
    deflection : float
        Of the peak mid-span deflection (relative to the chord).
    stress : float
        Of the peak stress (0 when the section has no extreme-fibre distance).
    history : float
        Largest error over the cycle of the mid-span deflection and of the
        stress at every station, each relative to its own peak.
    """

    link: str
    deflection: float
    stress: float
    history: float


@dataclass(frozen=True)
class ErrorEstimate:
    """Estimated time-discretisation error of a result (see the module docstring).

    Attributes
    ----------
    links : tuple of LinkError
    levels : tuple of int
        Time elements of the solves compared, finest (the result) last.
    rate : float
        Convergence rate used (the smallest over the quantities).
    observed : bool
        The rate was measured from three levels (else assumed).
    rtol : float or None
        Tolerance the solve was asked to meet.
    history_rate : float
        Convergence rate used for the histories.
    resolved : bool
        The coarser of the two finest levels resolves every mode the drive
        can excite (one element per period of the highest; see
        :meth:`kedfem.analysis.pipeline._Run.resolution`); an L-stable scheme damps the
        resonant response of modes it does not resolve alike at every coarse
        level, and two such levels can agree while both are wrong.
    asymptotic : bool
        The observed rate of the peaks reaches :data:`ASYMPTOTIC_FRACTION` of
        the scheme's order: the estimate is close to the true error (else
        it is an over-estimate).
    settled : bool
        Both differences of the three levels are below :data:`SETTLED_FRACTION`
        of ``rtol``: met whatever their rate (an over-estimate).
    clear : bool
        Before the asymptotic range, the peaks' estimate (credited at most the assumed rate)
        is below :data:`CLEAR_FRACTION` of ``rtol`` and the peaks and every history converge
        (observed rates at least 1): met with a margin that a resonance still being resolved
        does not eat.
    """

    links: tuple[LinkError, ...]
    levels: tuple[int, ...]
    rate: float
    observed: bool
    rtol: float | None = None
    history_rate: float = 0.0
    resolved: bool = True
    asymptotic: bool = False
    settled: bool = False
    clear: bool = False
    #: ``"levels"`` (the differences of two or three levels) or ``"defect"`` (the finest level's
    #: defect correction, checked against the change from the level before: :func:`defect_estimate`)
    method: str = "levels"

    @property
    def peak(self) -> float:
        """Largest estimated relative error of any link's peak deflection or stress."""
        return max((max(e.deflection, e.stress) for e in self.links), default=0.0)

    @property
    def history(self) -> float:
        """Largest estimated relative error of any history over the cycle."""
        return max((e.history for e in self.links), default=0.0)

    @property
    def met(self) -> bool:
        """The peak errors meet ``rtol`` and the estimate can be believed.

        Believed: three levels (a measured rate) whose coarser pair resolves
        the relevant modes, or two whose coarser one's defect correction explains their
        change (``method="defect"``).
        """
        return (self.rtol is None or self.peak <= self.rtol) and self.reliable

    @property
    def reliable(self) -> bool:
        """Three levels with a measured rate (or two levels with an explained defect correction),
        the coarser ones resolving the relevant modes."""
        return self.observed and self.resolved

    def link(self, name: str) -> LinkError:
        """The estimate of one link."""
        for e in self.links:
            if e.link == name:
                return e
        raise InputError(f"no error estimate for link '{name}' "
                         f"(flexible links: {', '.join(e.link for e in self.links)})")

    def describe(self) -> str:
        """One line: peak and history errors and how they were obtained."""
        how = ("defect correction of the finest, explaining the change from the coarser"
               if self.method == "defect" else
               f"observed rates {self.rate:.1f} / {self.history_rate:.1f}"
               f"{'' if self.asymptotic else ', before the asymptotic range: an over-estimate'}"
               if self.observed else f"assumed rate {self.rate:.1f}")
        lv = "/".join(str(n) for n in self.levels)
        tol = f"; tolerance {self.rtol:.0e} {'met' if self.met else 'NOT MET'} on the peaks" if self.rtol else ""
        if self.rtol and self.history > self.rtol:
            # the tolerance is on the peaks: say so where the histories (the axial forces, on which
            # the bearing loads ride) are estimated beyond it (a new user read "met" as all of it)
            tol += f", histories beyond it (bearing loads up to {self.history:.1e} off)"
        rel = "" if self.reliable else "; UNRELIABLE: " + (
            "coarser solve does not resolve the relevant modes" if not self.resolved
            else "the coarser level's defect correction does not explain the change" if self.method == "defect"
            else "needs three levels")
        return (f"peaks {self.peak:.1e}, histories {self.history:.1e} (time elements {lv}, {how}"
                f"{tol}{rel})")


def observed_rate(levels, diffs) -> float:
    """Convergence rate from the differences ``diffs = (|q1 - q0|, |q2 - q1|)`` of three levels.

    Solves ``d1 / d2 = (n0^-p - n1^-p) / (n1^-p - n2^-p)`` for ``p`` (bisection on
    ``[0, 16]``); ``nan`` when the differences do not shrink.
    """
    n0, n1, n2 = (float(x) for x in levels)
    d1, d2 = (float(x) for x in diffs)
    if not (d2 > 0.0 and d1 > d2):
        return math.nan

    def f(p):
        return (n0 ** -p - n1 ** -p) / (n1 ** -p - n2 ** -p) - d1 / d2

    lo, hi = 0.0, 16.0
    if f(hi) < 0:
        return hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if f(mid) < 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _peak_differences(fine: Observables, coarse: Observables) -> np.ndarray:
    """Relative change of every link's peak deflection and stress, shape (n_links, 2).

    The larger of the change of the peak value and the largest change of its
    history within half a fine element of the fine peak, so that two levels
    whose peaks agree by coincidence, or whose difference crosses zero at the
    peak, do not pass for converged.
    """
    n_out = fine.deflection_history[0].shape[0] if fine.links else 1
    half = max(1, int(round(n_out / (2.0 * fine.elements))))

    def near(hf, hc, k):
        idx = np.arange(k - half, k + half + 1) % hf.shape[0]
        return float(np.max(np.abs(hf[idx] - hc[idx])))

    out = np.zeros((len(fine.links), 2))
    for i in range(len(fine.links)):
        pk = abs(float(fine.deflection[i]))
        if pk > 0:
            out[i, 0] = max(abs(fine.deflection[i] - coarse.deflection[i]),
                            near(fine.deflection_history[i], coarse.deflection_history[i],
                                 int(fine.deflection_at[i]))) / pk
        pk = abs(float(fine.stress[i]))
        if fine.has_stress[i] and pk > 0:
            j = int(fine.stress_station[i])
            out[i, 1] = max(abs(fine.stress[i] - coarse.stress[i]),
                            near(fine.stress_history[i][:, j], coarse.stress_history[i][:, j],
                                 int(fine.stress_at[i]))) / pk
    return out


def _history_differences(fine: Observables, coarse: Observables) -> np.ndarray:
    """Largest relative change over the cycle of every link's histories, shape (n_links,)."""
    out = np.zeros(len(fine.links))
    for i in range(len(fine.links)):
        pairs = [(fine.deflection_history[i], coarse.deflection_history[i])]
        if fine.has_stress[i]:
            pairs.append((fine.stress_history[i], coarse.stress_history[i]))
        if fine.axial_history and coarse.axial_history:
            pairs.append((fine.axial_history[i], coarse.axial_history[i]))
        for hf, hc in pairs:
            scale = float(np.max(np.abs(hf)))
            if scale > 0:
                out[i] = max(out[i], float(np.max(np.abs(hf - hc))) / scale)
    return out


def _rate(n, d1, d2, assumed, order):
    """Credited rate and whether the levels are in the asymptotic range.

    Observed from three levels: up to ``order`` when it reaches
    ``ASYMPTOTIC_FRACTION * order``, else clamped to ``[1, assumed]``.
    """
    if d1 is None:
        return assumed, False
    r = observed_rate(n, (d1, d2))
    if not math.isfinite(r):
        return 1.0, False
    if r >= ASYMPTOTIC_FRACTION * order:
        return min(r, order), True
    return min(max(r, 1.0), assumed), False


def estimate(levels: list[int], obs: list[Observables], *, assumed: float,
             order: float | None = None, rtol: float | None = None) -> ErrorEstimate | None:
    """Error estimate of the finest of the last two or three levels.

    Peaks and histories each get a rate: observed from three levels (the
    largest relative change over all links and quantities, level to level),
    credited up to ``order`` in the asymptotic range and otherwise clamped to
    ``[1, assumed]`` (see the module docstring), or ``assumed`` with two
    levels. A peak's change is the larger of the change of its value and the
    largest change of its history within half a fine element of the peak
    (:func:`_peak_differences`).

    Parameters
    ----------
    levels : list of int
        Time elements, increasing; the last is the result.
    obs : list of Observables
        At the same output instants, one per level.
    assumed : float
        Rate credited to a two-level estimate, and the largest credited
        before the asymptotic range.
    order : float, optional
        Order of the scheme between element ends: the largest rate credited
        (default ``assumed``).
    rtol : float, optional

    Returns
    -------
    ErrorEstimate or None
        None with a single level.
    """
    if len(levels) < 2:
        return None
    n = [float(x) for x in levels[-3:]]
    o = obs[-3:]
    ratio = n[-1] / n[-2]
    pk = _peak_differences(o[-1], o[-2])
    hi = _history_differences(o[-1], o[-2])
    order = assumed if order is None else max(float(order), assumed)
    settled = converging = False
    if len(o) == 3:
        pk1 = _peak_differences(o[1], o[0])
        hi1 = _history_differences(o[1], o[0])
        d1 = float(pk1.max())
        p_pk, asym = _rate(n, d1, float(pk.max()), assumed, order)
        h1 = float(hi1.max())
        largest = SAFETY * max(d1, h1, float(pk.max()), float(hi.max()))
        settled = rtol is not None and largest <= SETTLED_FRACTION * rtol
        p_hi, _ = _rate(n, h1, float(hi.max()), assumed, order)
        r_hi = observed_rate(n, (h1, float(hi.max())))
        r_pk = observed_rate(n, (d1, float(pk.max())))
        # the peaks must converge too: peaks that do not move over three levels (a quasi-static peak
        # of a forming load, read to 1e-11) say nothing of a ringing elsewhere in the cycle that the
        # scheme's numerical damping still holds below them and that outgrows them when resolved
        # (taking such peaks as converged stopped a constructed case 50x outside rtol, estimate 0)
        converging = math.isfinite(r_hi) and r_hi >= 1.0 and math.isfinite(r_pk) and r_pk >= 1.0
        # the peaks' rate alone can look asymptotic by coincidence while a badly resolved resonance
        # still moves the histories at rate ~1 (an offset slider-crank with two flexible links: peak
        # rate 3.8, history rate 1.4, and the next doubling changed the rod's stress 5x more than
        # the estimate): the histories must converge at HISTORY_FRACTION of the order too
        if asym and not (math.isfinite(r_hi) and r_hi >= HISTORY_FRACTION * order):
            asym = False
            p_pk = min(max(p_pk, 1.0), assumed)  # credited as before the asymptotic range
        if settled and not asym:
            # settled before the asymptotic range, where a quantity may stall between the two
            # finest levels: each is credited rate 1 on the larger of its two differences (the
            # estimate stays far inside rtol, and it does not under-state a stall)
            pk, hi = np.maximum(pk, pk1), np.maximum(hi, hi1)
            p_pk = p_hi = 1.0
    else:
        p_pk = p_hi = assumed
        asym = False
    f_pk, f_hi = (ratio ** p_pk - 1.0) / SAFETY, (ratio ** p_hi - 1.0) / SAFETY
    out = tuple(LinkError(link, float(pk[i, 0] / f_pk), float(pk[i, 1] / f_pk), float(hi[i] / f_hi))
                for i, link in enumerate(o[-1].links))
    peak = max((max(e.deflection, e.stress) for e in out), default=0.0)
    clear = bool(converging and not asym and rtol is not None and peak <= CLEAR_FRACTION * rtol)
    return ErrorEstimate(out, tuple(int(x) for x in levels[-3:]), float(p_pk), len(o) == 3, rtol,
                         float(p_hi), asymptotic=bool(asym), settled=bool(settled), clear=clear)


def promising(coarse: Observables, fine: Observables, *, ratio: float, order: float, rtol: float,
              assumed: float | None = None) -> bool:
    """Two levels whose peaks' change, taken as Richardson's at the scheme's ``order``, is within
    ``rtol``, and (with ``assumed``) whose histories' change at that rate, times :data:`SAFETY`,
    is too (the floor of a defect estimate's histories, :func:`defect_estimate`): the finer
    level may meet it, and a defect estimate is worth its two extra solves."""
    change = float(_peak_differences(fine, coarse).max(initial=0.0))
    if change / (ratio ** order - 1.0) > rtol:
        return False
    if assumed is None:
        return True
    hist = float(_history_differences(fine, coarse).max(initial=0.0))
    return SAFETY * hist / (ratio ** assumed - 1.0) <= rtol


def explained(coarse: Observables, fine: Observables, coarse_corrected: Observables) -> tuple[bool, float]:
    """Does the coarser level's defect correction explain the change of the peaks to the finer
    level? The coarser level corrected by it is within :data:`EXPLAINED` of the change from the
    finer one, in every link's peak deflection and stress, with :data:`READ_NOISE` for the
    read-out's round-off. Returns the verdict and the largest fraction of a change left."""
    return _explained(_peak_differences(fine, coarse), _peak_differences(fine, coarse_corrected))


def _explained(change: np.ndarray, left: np.ndarray) -> tuple[bool, float]:
    """:func:`explained` from the peaks' change and what the correction left of it (n_links, 2)."""
    ok = bool(np.all(left <= EXPLAINED * change + READ_NOISE))
    return ok, float(np.max(left / np.maximum(change, 1e-300), initial=0.0))


def defect_estimate(levels: tuple[int, int], coarse: Observables, fine: Observables,
                    coarse_corrected: Observables, fine_corrected: Observables, *,
                    assumed: float, order: float, rtol: float) -> ErrorEstimate:
    """Error estimate of the finer of two levels from its defect-corrected solution.

    Each level's defect correction (:mod:`kedfem.solvers.defect`) estimates its error at every
    instant. The finer level's peak errors (its peaks' differences from its corrected solution's,
    times :data:`SAFETY`) are believed when the coarser level's estimate explains the change of
    the peaks from the coarser to the finer level: the coarser level corrected by it is within
    :data:`EXPLAINED` of that change from the finer one, in every link's peak deflection and
    stress. Where it does not (before the asymptotic range, or a coarser level that does not
    resolve a mode the finer does), the estimate is returned not ``observed`` (not
    :attr:`ErrorEstimate.reliable`). The histories take the larger of their defect estimate and
    the two levels' difference at the ``assumed`` rate: over a cycle they include the stiff
    axial modes that an L-stable scheme does not resolve (the four-bar's coupler force, 10 %
    from 48 to 96 elements), where the defect correction sees the scheme's own quasi-static
    response and no error.

    Parameters
    ----------
    levels : (int, int)
        Time elements of the two levels, coarser first.
    coarse, fine : Observables
        The levels, on the same output instants.
    coarse_corrected, fine_corrected : Observables
        Their defect-corrected solutions, on the same instants.
    assumed : float
        Rate credited to the two levels' difference of the histories.
    order : float
        The scheme's order between element ends (the largest rate credited).
    rtol : float
        The tolerance.

    Returns
    -------
    ErrorEstimate
        With ``method="defect"``; ``rate`` is the one the peaks' change and estimate imply.
    """
    change = _peak_differences(fine, coarse)
    ok, left = _explained(change, _peak_differences(fine, coarse_corrected))
    pk = _peak_differences(fine, fine_corrected)
    ratio = levels[1] / levels[0]
    hi = np.maximum(_history_differences(fine, fine_corrected),
                    _history_differences(fine, coarse) / (ratio ** assumed - 1.0))
    out = tuple(LinkError(link, float(SAFETY * pk[i, 0]), float(SAFETY * pk[i, 1]), float(SAFETY * hi[i]))
                for i, link in enumerate(fine.links))
    big, small = float(change.max(initial=0.0)), float(pk.max(initial=0.0))
    rate = math.log(1.0 + big / small) / math.log(ratio) if small > 0 and big > 0 else float(order)
    rate = min(max(rate, 1.0), float(order))
    log.debug("defect estimate %d/%d: peaks changed %.2e, %.2e of it left after the coarser level's correction, "
              "estimate %.2e%s", levels[0], levels[1], big, left, SAFETY * small, "" if ok else " (not explained)")
    return ErrorEstimate(out, (int(levels[0]), int(levels[1])), float(rate), ok, rtol, float(assumed),
                         asymptotic=ok, method="defect")
