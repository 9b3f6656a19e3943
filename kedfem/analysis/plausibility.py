"""Checks that a scene stays within the model's theory: before a solve, and on its result.

- Before: a ``kinematic=False`` (redundant) link takes up the mismatch of its loop as a
  prescribed stretch of its chord. A strain of more than :data:`MAX_PASSIVE_STRAIN` means the
  link is not redundant in this linkage (or its joints are placed wrong): an error that names
  the link, not a stress of tens of GPa.
- After: linear theory holds for small deflections and elastic stresses. A peak deflection of
  more than :data:`MAX_DEFLECTION_RATIO` of a link's length, or a stress above its material's
  yield strength, gives a :class:`~kedfem.errors.PlausibilityWarning` naming the link.
"""

from __future__ import annotations

import logging
import math
import warnings

import numpy as np

from ..errors import InputError, PlausibilityWarning, user_stacklevel

__all__ = ["MAX_PASSIVE_STRAIN", "MAX_DEFLECTION_RATIO", "check_passive_links", "check_result"]

log = logging.getLogger(__name__)

#: largest chord strain [-] a ``kinematic=False`` link may take up over the cycle
MAX_PASSIVE_STRAIN = 1e-3
#: peak deflection relative to the link's length [-] beyond which linear theory is doubtful
MAX_DEFLECTION_RATIO = 0.02
#: a link whose largest deflection and stress on the output instants stay below this fraction of
#: the limits is not read further: its peaks between the instants (within about 1 % of the grid's
#: maxima at 8 instants per element) cannot reach them, and the refinement costs a single solve
#: a quarter of its time (the peaks are read when asked for)
SCREEN = 0.8


def check_passive_links(model, motion) -> None:
    """InputError if a ``kinematic=False`` link's chord stretches by more than the limit.

    Parameters
    ----------
    model : kedfem.fe.model.FEModel
    motion : kedfem.motion.kinematics.Motion
        The rigid-body motion over the cycle.
    """
    for lk in model.mech.links.values():
        if lk.kinematic or lk.rigid:
            continue
        p = model.chord_stretch(lk.name, motion)[0]
        strain = np.linalg.norm(p, axis=1) / lk.length
        k = int(np.argmax(strain))
        if strain[k] > MAX_PASSIVE_STRAIN:
            raise InputError(
                f"link '{lk.name}' is kinematic=False (a redundant member that follows the others), but the "
                f"motion stretches its chord by {np.linalg.norm(p[k]) * 1e3:.4g} mm (strain {strain[k]:.3g} > "
                f"{MAX_PASSIVE_STRAIN:g}) at crank angle {math.degrees(motion.crank_angle[k]) % 360:.1f} deg: "
                "it is not redundant in this linkage, or its joints are not where the other links put them; "
                "make it kinematic (the default) or correct the geometry")


def check_result(res) -> list[str]:
    """Warn (:class:`PlausibilityWarning`) where the result leaves linear theory; return the messages."""
    out = []
    mech = res.model.mech
    for p in _near_limits(res):
        lk = mech.links[p.link]
        ratio = p.deflection / lk.length
        if not math.isfinite(ratio) or ratio > MAX_DEFLECTION_RATIO:
            if "geometric_nonlinearity" in res.scene.effects:  # (a new user read "small-deflection" with it on)
                theory = ("the von Karman strains of geometric_nonlinearity assume moderate rotations of the "
                          "elements: check it on a finer mesh (kf.mesh_error), and the units: lengths in m, E in Pa")
            else:
                theory = ("small-deflection (linear) theory is doubtful: add geometric_nonlinearity, or check "
                          "the units: lengths in m, E in Pa")
            out.append(f"link '{p.link}': peak deflection {p.deflection * 1e3:.4g} mm is {100 * ratio:.3g} % of its "
                       f"length (> {100 * MAX_DEFLECTION_RATIO:g} %): {theory}")
        Sy = lk.material.yield_strength
        if Sy and math.isfinite(p.stress) and p.stress > Sy:
            out.append(f"link '{p.link}': peak stress {p.stress / 1e6:.4g} MPa exceeds the yield strength "
                       f"{Sy / 1e6:.4g} MPa: the link yields, linear elasticity no longer holds")
    for msg in out:
        warnings.warn(msg, PlausibilityWarning, stacklevel=user_stacklevel())
    return out


def _near_limits(res) -> list:
    """The peaks (:meth:`~kedfem.analysis.results.PeriodicResult.peaks`) of the links whose
    largest deflection or stress on the output instants come within :data:`SCREEN` of the limits
    (every link's when the peaks were read already)."""
    from .results import PEAK_STATIONS
    if res.peaks_read:
        return res.peaks()
    near = set()
    for lk in res.model.mech.flexible_links:
        d = float(np.max(np.abs(res.deflection(lk.name, 0.5, relative_to="chord"))))
        Sy = lk.material.yield_strength
        s = (float(np.max(res.stress(lk.name, per_element=PEAK_STATIONS)))
             if Sy and lk.section.c is not None else 0.0)
        if not (d <= SCREEN * MAX_DEFLECTION_RATIO * lk.length and (not Sy or s <= SCREEN * Sy)):
            near.add(lk.name)
    return [p for p in res.peaks() if p.link in near] if near else []
