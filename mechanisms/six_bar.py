"""Watt-II six-bar linkage: a crank-rocker four-bar drives a second four-bar through a bellcrank.

Exercises a second independent kinematic loop and a rigid body with three
attachments. Crank O2-A, coupler A-B and the output links C-D, O6-D are
flexible steel strips; the bellcrank O4-B-C is a rigid body pivoting on the
frame at O4 (a stout casting). Dimensions are this package's choice, picked
so that the crank rotates fully (loop 1 is a Grashof crank-rocker) and loop 2
stays away from its toggle positions over the bellcrank's swing.
"""

from __future__ import annotations

import math

import numpy as np

import kedfem as kf
from kedfem.catalogue import Preset

DEFAULTS = dict(speed=2 * math.pi * 5, elements=4, crank=0.10, coupler=0.30, ground=0.35,
                arm_b=0.20, arm_c=0.18, link=0.30, rocker=0.22, o6=(0.62, 0.05),
                E=2.0e11, rho=7850.0, width=0.02, height=0.006, bellcrank_mass=1.5,
                bellcrank_inertia=6.0e-3, crank_angle=0.0)
#: Preset scene: like the four-bar's, with ``geometric_nonlinearity`` (pinned flexible
#: links; without it the peaks are 0.1 % off the geometrically exact model).
PRESET = Preset(effects=("inertia", "coupling", "axial_stiffening", "geometric_nonlinearity"),
                damping=kf.ModalDamping(0.02))
#: the crank's starting angle and the rocker pivot's coordinates may be negative
SIGNED_PARAMETERS = ("crank_angle", "o6")


def _circle_intersection(p, rp, q, rq, upper=True):
    d = np.asarray(q, float) - np.asarray(p, float)
    dist = float(np.hypot(*d))
    if dist > rp + rq or dist < abs(rp - rq):
        raise kf.InputError(f"six_bar: cannot assemble (|pq| = {dist:.4g} m with radii {rp}, {rq})")
    x = (rp**2 - rq**2 + dist**2) / (2 * dist)
    h = math.sqrt(max(rp**2 - x**2, 0.0))
    n = np.array([-d[1], d[0]]) / dist
    return np.asarray(p, float) + x * d / dist + (h if upper else -h) * n


def build(speed: float = 2 * math.pi * 5, elements: int = 4, crank: float = 0.10,
          coupler: float = 0.30, ground: float = 0.35, arm_b: float = 0.20, arm_c: float = 0.18,
          link: float = 0.30, rocker: float = 0.22, o6=(0.62, 0.05), E: float = 2.0e11,
          rho: float = 7850.0, width: float = 0.02, height: float = 0.006,
          bellcrank_mass: float = 1.5, bellcrank_inertia: float = 6.0e-3,
          crank_angle: float = 0.0) -> kf.Mechanism:
    """Watt-II six-bar linkage (two loops).

    Parameters
    ----------
    speed : float
        Crank speed [rad/s].
    elements : int
        Frame elements per flexible link.
    crank, coupler, ground : float
        First loop: crank O2-A, coupler A-B, frame O2-O4 [m].
    arm_b, arm_c : float
        Bellcrank arms O4-B and O4-C [m] (C is 90 degrees ahead of B).
    link, rocker : float
        Second loop: link C-D and output rocker O6-D [m].
    o6 : (float, float)
        Output pivot [m].
    E, rho, width, height : float
        Steel strips of the flexible links [Pa, kg/m^3, m, m] (``height`` in plane).
    bellcrank_mass, bellcrank_inertia : float
        Rigid bellcrank [kg], [kg m^2] about its centre of mass.
    crank_angle : float
        Crank angle of the reference configuration [rad].
    """
    for name, v in (("crank", crank), ("coupler", coupler), ("ground", ground), ("arm_b", arm_b),
                    ("arm_c", arm_c), ("link", link), ("rocker", rocker)):
        if not v > 0:
            raise kf.InputError(f"six_bar: {name} must be a length > 0 m, got {v!r}")
    O2, O4 = np.array([0.0, 0.0]), np.array([ground, 0.0])
    A = crank * np.array([math.cos(crank_angle), math.sin(crank_angle)])
    B = _circle_intersection(A, coupler, O4, arm_b)
    ub = (B - O4) / arm_b
    C = O4 + arm_c * np.array([-ub[1], ub[0]])  # 90 deg ahead of B
    D = _circle_intersection(C, link, o6, rocker, upper=False)
    mat = kf.Material(E=E, rho=rho)
    sec = kf.Section.rectangle(width, height)
    m = kf.Mechanism("six-bar")
    m.ground("O2", at=tuple(O2))
    m.ground("O4", at=tuple(O4))
    m.ground("O6", at=tuple(o6))
    for name, p in (("A", A), ("B", B), ("C", C), ("D", D)):
        m.joint(name, at=tuple(p))
    m.link("crank", "O2", "A", material=mat, section=sec, elements=elements)
    m.link("coupler", "A", "B", material=mat, section=sec, elements=elements)
    m.body("bellcrank", ("O4", "B", "C"), mass=bellcrank_mass, J=bellcrank_inertia,
           cm=tuple((O4 + B + C) / 3))
    m.link("link", "C", "D", material=mat, section=sec, elements=elements)
    m.link("rocker", "O6", "D", material=mat, section=sec, elements=elements)
    m.drive("crank", speed=speed)
    return m
