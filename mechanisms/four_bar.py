"""Flexible four-bar linkage (Sutherland 1976; Kitis et al. 1990).

References: ``docs/references.md`` section 4. Ground 0.254 m,
crank 0.108 m, coupler 0.2794 m, follower 0.2705 m; aluminium (rho = 2714
kg/m^3, E = 7.1e10 Pa); crank A = 1.0774e-4 m^2, EI = 11.472 N m^2; coupler and
follower A = 4.0645e-5 m^2, EI = 0.616 N m^2; lumped masses 0.042 kg at the
start of the coupler (joint A) and at the start of the follower (joint B,
the follower running B -> O4 in the original); crank clamped to its drive
at the ground pivot, follower pinned to ground.

The crank speed is not part of the reference data: the default
``speed = 2 pi * 200 / 60`` rad/s (200 rpm) is this package's choice of a
moderate operating speed, well below the first natural frequency.
"""

from __future__ import annotations

import math

import numpy as np

import kedfem as kf
from kedfem.catalogue import Preset

DEFAULTS = dict(ground=0.254, crank=0.108, coupler=0.2794, follower=0.2705, speed=2 * math.pi * 200 / 60,
                elements=4, crank_angle=0.0, joint_mass=0.042, E=7.1e10, rho=2714.0,
                crank_A=1.0774e-4, crank_EI=11.472, link_A=4.0645e-5, link_EI=0.616, flexible_crank=True,
                coupler_EI=0.0)
#: Preset scene. The flexible links meet at pins, so the axial forces that stiffen
#: them are the actual (elastic) ones, which near resonance differ from the
#: kinetostatic ones: ``geometric_nonlinearity``. Without it the peaks are 1-2.4 %
#: off the geometrically exact model (benchmarks/exact_comparison.py), with it 0.01 %.
PRESET = Preset(effects=("inertia", "coupling", "axial_stiffening", "geometric_nonlinearity"),
                damping=kf.ModalDamping(0.02))
#: the crank's starting angle may be negative
SIGNED_PARAMETERS = ("crank_angle",)


def _coupler_point(A, O4, coupler, follower, crank_angle_name="crank_angle"):
    d = O4 - A
    dist = float(np.hypot(*d))
    if dist > coupler + follower or dist < abs(coupler - follower):
        raise kf.InputError(f"four_bar: the linkage cannot be assembled at the reference "
                            f"{crank_angle_name} (|A-O4| = {dist:.4g} m)")
    x = (coupler**2 - follower**2 + dist**2) / (2 * dist)
    h = math.sqrt(max(coupler**2 - x**2, 0.0))
    n = np.array([-d[1], d[0]]) / dist
    return A + x * d / dist + h * n  # open (upper) branch


def _strip(A: float, EI: float, E: float) -> kf.Section:
    """Section of a rectangular strip of area ``A`` [m^2] and bending stiffness ``EI`` [N m^2]."""
    return kf.Section(A=A, I=EI / E, c=0.5 * math.sqrt(12 * EI / E / A))


def build(ground: float = 0.254, crank: float = 0.108, coupler: float = 0.2794,
          follower: float = 0.2705, speed: float = 2 * math.pi * 200 / 60, elements: int = 4,
          crank_angle: float = 0.0, joint_mass: float = 0.042, E: float = 7.1e10,
          rho: float = 2714.0, crank_A: float = 1.0774e-4, crank_EI: float = 11.472,
          link_A: float = 4.0645e-5, link_EI: float = 0.616,
          flexible_crank: bool = True, coupler_EI: float = 0.0) -> kf.Mechanism:
    """Four-bar linkage with flexible crank, coupler and follower.

    Parameters
    ----------
    ground, crank, coupler, follower : float
        Link lengths [m]; O2 at the origin, O4 at (ground, 0).
    speed : float
        Crank speed [rad/s].
    elements : int
        Frame elements per flexible link.
    crank_angle : float
        Crank angle of the reference configuration [rad] (open branch).
    joint_mass : float
        Lumped mass at joints A and B [kg].
    E, rho : float
        Material [Pa], [kg/m^3].
    crank_A, crank_EI, link_A, link_EI : float
        Sections of the crank and of coupler/follower: area [m^2], EI [N m^2].
    flexible_crank : bool
        False makes the crank rigid.
    coupler_EI : float
        Bending stiffness of the coupler alone [N m^2] (0: ``link_EI``, the default), its area
        staying ``link_A``: to sweep the coupler's stiffness by itself.
    """
    for name, v in (("ground", ground), ("crank", crank), ("coupler", coupler), ("follower", follower)):
        if not v > 0:
            raise kf.InputError(f"four_bar: {name} must be a length > 0 m, got {v!r}")
    if not coupler_EI >= 0:
        raise kf.InputError(f"four_bar: coupler_EI must be a bending stiffness > 0 N m^2 (or 0: link_EI), "
                            f"got {coupler_EI!r}")
    mat = kf.Material(E=E, rho=rho)
    # the published A and EI are those of 25.4 mm wide rectangular strips (h = sqrt(12 I / A):
    # 4.24 mm crank, 1.60 mm coupler and follower); the extreme fibre is at c = h / 2
    sec_crank = _strip(crank_A, crank_EI, E)
    sec_link = _strip(link_A, link_EI, E)
    sec_coupler = _strip(link_A, coupler_EI, E) if coupler_EI > 0 else sec_link
    A = np.array([crank * math.cos(crank_angle), crank * math.sin(crank_angle)])
    O4 = np.array([ground, 0.0])
    B = _coupler_point(A, O4, coupler, follower)
    m = kf.Mechanism("four-bar")
    m.ground("O2", at=(0.0, 0.0))
    m.ground("O4", at=tuple(O4))
    m.joint("A", at=tuple(A))
    m.joint("B", at=tuple(B))
    if flexible_crank:
        m.link("crank", "O2", "A", material=mat, section=sec_crank, elements=elements)
    else:
        m.link("crank", "O2", "A", rigid=True, material=mat, section=sec_crank)
    m.link("coupler", "A", "B", material=mat, section=sec_coupler, elements=elements)
    m.link("follower", "O4", "B", material=mat, section=sec_link, elements=elements)
    if joint_mass > 0:
        m.point_mass("A", joint_mass)
        m.point_mass("B", joint_mass)
    m.drive("crank", speed=speed)
    return m
