"""Stresses for fatigue: signed fibre stresses over the cycle, mean and alternating stress per
station, and safety factors against yield and on the Goodman and Soderberg lines.

A flexible link's normal stress at a station is ``sigma = N / A - M y / I`` with ``M = EI v''``
(the bending moment of :meth:`kedfem.analysis.results.PeriodicResult.bending_moment`) and ``y``
the distance from the neutral axis along the link's local +y (the ``a -> b`` direction turned
+90 degrees). The *top* fibre is ``y = +c`` and the *bottom* fibre ``y = -c``:

    sigma_top = N / A - M c / I,      sigma_bottom = N / A + M c / I

(tension positive, [Pa]). Over one cycle each fibre at each station has a largest and a smallest
stress; the mean ``sigma_m = (max + min) / 2`` and the alternating stress ``sigma_a = (max - min) /
2`` (one reversal per cycle: the cycle's range, as a rainflow count gives for a history with one
maximum and one minimum). With a :class:`kedfem.model.materials.Material` that states its
strengths the safety factors per link are (Shigley's forms, normal stress only, shear ignored):

- yield: ``n_y = S_y / max |sigma|`` (with the peak stress refined between stations);
- Goodman: ``1 / n = sigma_a / S_e + sigma_m / S_ut`` for ``sigma_m >= 0``, ``n = S_e / sigma_a``
  for a compressive mean;
- Soderberg: the same with ``S_y`` in place of ``S_ut``.

Each is the smallest over the link's stations and both fibres. The histories keep the result's
time resolution (the scene's tolerance holds for them as for the peaks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

__all__ = ["FibreStress", "LinkFatigue", "FatigueTable", "fibre_stress", "fatigue_table"]


@dataclass(frozen=True)
class FibreStress:
    """Signed normal stress of a link's outer fibres over the cycle.

    Attributes
    ----------
    link : str
    stations : ndarray, shape (n_st,)
        Distance from joint ``a`` [m].
    crank_angle : ndarray, shape (n,)
        [rad].
    top, bottom : ndarray, shape (n, n_st)
        ``N/A - M c/I`` and ``N/A + M c/I`` [Pa], tension positive.
    axial_force, bending_moment : ndarray, shape (n, n_st)
        ``N`` [N] and ``M`` [N m] they are made of.
    """

    link: str
    stations: np.ndarray
    crank_angle: np.ndarray
    top: np.ndarray
    bottom: np.ndarray
    axial_force: np.ndarray
    bending_moment: np.ndarray


@dataclass(frozen=True)
class LinkFatigue:
    """Mean and alternating stress of one link, per station and fibre, and its safety factors.

    Attributes
    ----------
    link : str
    stations : ndarray, shape (n_st,)
        [m] from joint ``a``.
    mean, alternating, maximum, minimum : ndarray, shape (n_st, 2)
        Per station, for the top (column 0) and bottom (column 1) fibre [Pa].
    worst_station : float
        Station [m] of the largest range (``2 sigma_a``) of either fibre.
    worst_fibre : str
        ``"top"`` or ``"bottom"``.
    safety_yield, safety_goodman, safety_soderberg : float or None
        Smallest over the link; None when the material does not state the strengths needed.
    worst_index : int
        Row of ``stations`` of the largest range (a station at a joint the link passes
        through appears twice, its ``a`` side first).
    governing : dict
        ``{"Goodman": (row, fibre), "Soderberg": (row, fibre)}``: where each factor is smallest
        (a tensile mean can make it another station or fibre than the largest range's).
    """

    link: str
    stations: np.ndarray
    mean: np.ndarray
    alternating: np.ndarray
    maximum: np.ndarray
    minimum: np.ndarray
    worst_station: float
    worst_fibre: str
    safety_yield: float | None
    safety_goodman: float | None
    safety_soderberg: float | None
    worst_index: int = -1
    governing: dict = field(default_factory=dict)

    @property
    def largest_range(self) -> float:
        """Largest stress range ``max - min`` over stations and fibres [Pa]."""
        return float(2.0 * self.alternating.max())

    def describe(self, digits: int = 4) -> str:
        """One line in MPa and mm (``digits``: significant digits of the stresses)."""
        f = 0 if self.worst_fibre == "top" else 1
        i = self.worst_index if self.worst_index >= 0 else int(np.argmin(np.abs(self.stations - self.worst_station)))
        g = f".{int(digits)}g"
        parts = [f"{self.link}: largest range {self.largest_range / 1e6:{g}} MPa at {self.worst_station * 1e3:.1f} mm "
                 f"({self.worst_fibre} fibre: mean {self.mean[i, f] / 1e6:{g}} MPa, alternating "
                 f"{self.alternating[i, f] / 1e6:{g}} MPa)"]
        shown = None
        for name, v in (("yield", self.safety_yield), ("Goodman", self.safety_goodman),
                        ("Soderberg", self.safety_soderberg)):
            if v is not None:
                where = self.governing.get(name)
                if where is not None and tuple(where) != (i, f) and tuple(where) == shown:
                    parts.append(f"{name} {v:.3g} (there too)")
                elif where is not None and tuple(where) != (i, f):
                    shown = tuple(where)
                    # the factor's own station and fibre (a new user got 180/46.57 = 3.87 from the
                    # largest range's numbers where the line said Goodman 3.58, the other fibre's)
                    k, h = where
                    parts.append(f"{name} {v:.3g} (at {self.stations[k] * 1e3:.1f} mm, {('top', 'bottom')[h]} fibre: "
                                 f"mean {self.mean[k, h] / 1e6:{g}} MPa, alternating "
                                 f"{self.alternating[k, h] / 1e6:{g}} MPa)")
                else:
                    parts.append(f"{name} {v:.3g}")
        return "; safety ".join(parts[:2]) + (", " + ", ".join(parts[2:]) if len(parts) > 2 else "")


@dataclass(frozen=True)
class FatigueTable:
    """The fatigue table of a periodic result: one :class:`LinkFatigue` per flexible link with a
    stress (its section states ``c``)."""

    links: tuple[LinkFatigue, ...]

    def link(self, name: str) -> LinkFatigue:
        """The entry of link ``name``."""
        for lf in self.links:
            if lf.link == name:
                return lf
        raise InputError(f"fatigue table: no link {name!r} (links: {', '.join(x.link for x in self.links)})")

    def describe(self) -> str:
        """One line per link (MPa, mm)."""
        return "\n".join(lf.describe() for lf in self.links)


def fibre_stress(res, link: str, per_element: int = 1) -> FibreStress:
    """Signed top and bottom fibre stresses of a flexible link over the cycle.

    Parameters
    ----------
    res : kedfem.analysis.results.PeriodicResult
    link : str
        A flexible link whose section states the extreme-fibre distance ``c``.
    per_element : int
        Stations per element (:meth:`~kedfem.analysis.results.PeriodicResult.stations`).

    Returns
    -------
    FibreStress
        Arrays (n, n_el per_element + 1), one station more at each joint the link passes
        through (its pin's two sides).
    """
    N, M = res.section_forces(link, per_element, sides=True)  # both sides of a pin inside the link
    sec = res.model.mech.links[link].section
    if sec.c is None:
        raise InputError(f"link '{link}': its section has no extreme-fibre distance c, so the fibre "
                         "stresses are unknown (give Section(..., c=...))")
    bend = M * sec.c / sec.I
    return FibreStress(link, res.stations(link, per_element, sides=True), res.crank_angle, N / sec.A - bend,
                       N / sec.A + bend, N, M)


def _goodman(sa: np.ndarray, sm: np.ndarray, Se: float, S: float) -> tuple[float, tuple[int, int]]:
    """Smallest ``n`` of ``1/n = sa/Se + max(sm, 0)/S`` (compressive means: ``n = Se/sa``) [-], and
    where it is (row, fibre) of ``sa`` (n_st, 2)."""
    inv = sa / Se + np.maximum(sm, 0.0) / S
    at = np.unravel_index(int(np.argmax(inv)), inv.shape)
    worst = float(inv[at])
    return (math.inf if worst == 0.0 else 1.0 / worst), (int(at[0]), int(at[1]))


def _link_fatigue(fs: FibreStress, material, peak_stress: float = 0.0) -> LinkFatigue:
    both = np.stack([fs.top, fs.bottom], axis=-1)  # (n, n_st, 2)
    hi, lo = both.max(axis=0), both.min(axis=0)
    mean, alt = 0.5 * (hi + lo), 0.5 * (hi - lo)
    i, f = np.unravel_index(int(np.argmax(alt)), alt.shape)
    Sy, Sut, Se = material.yield_strength, material.ultimate_strength, material.endurance_limit
    peak = max(float(np.abs(both).max()), peak_stress if math.isfinite(peak_stress) else 0.0)
    n_y = (math.inf if peak == 0.0 else Sy / peak) if Sy else None
    n_g, at_g = _goodman(alt, mean, Se, Sut) if (Se and Sut) else (None, None)
    n_s, at_s = _goodman(alt, mean, Se, Sy) if (Se and Sy) else (None, None)
    governing = {k: v for k, v in (("Goodman", at_g), ("Soderberg", at_s)) if v is not None}
    return LinkFatigue(fs.link, fs.stations, mean, alt, hi, lo, float(fs.stations[i]),
                       ("top", "bottom")[f], n_y, n_g, n_s, int(i), governing)


def fatigue_table(res, per_element: int = 4) -> FatigueTable:
    """Mean and alternating stress per station and fibre of every flexible link with a stress.

    Parameters
    ----------
    res : kedfem.analysis.results.PeriodicResult
    per_element : int
        Stations per element (default 4: the largest range between nodes, where the moment of
        the distributed inertia load peaks, is not missed as at the nodes alone).

    Returns
    -------
    FatigueTable
        Links whose section has no ``c`` are left out.
    """
    mech = res.model.mech
    out = []
    for lk in mech.flexible_links:
        if lk.section.c is None:
            continue
        peak = next((p.stress for p in res.peaks() if p.link == lk.name), 0.0)  # refined between stations
        out.append(_link_fatigue(fibre_stress(res, lk.name, per_element), lk.material, peak))
    return FatigueTable(tuple(out))
