"""Flexible slider-crank (Simeon 1996; the Bari IVP test set).

References: ``docs/references.md`` section 5. Rigid crank
``L1 = 0.15 m`` driven at 150 rad/s; flexible connecting rod ``L2 = 0.30 m``,
steel square 8 mm x 8 mm (E = 2.0e11 Pa, rho = 7870 kg/m^3); slider point mass
0.075552 kg on the line of the crank pivot; no gravity.
"""

from __future__ import annotations

import math

import kedfem as kf
from kedfem.catalogue import Preset

DEFAULTS = dict(crank=0.15, rod=0.30, width=0.008, height=0.008, E=2.0e11, rho=7870.0,
                slider_mass=0.075552, speed=150.0, elements=8, crank_angle=0.0,
                mass_matrix="consistent")
#: Preset scene: the linear effects, 2 % modal damping. (Geometric non-linearity,
#: the actual axial forces, moves its peaks by 0.09 %, under the default tolerance.)
PRESET = Preset(effects=("inertia", "coupling", "axial_stiffening"), damping=kf.ModalDamping(0.02))
#: the crank's starting angle may be negative
SIGNED_PARAMETERS = ("crank_angle",)


def build(crank: float = 0.15, rod: float = 0.30, width: float = 0.008, height: float = 0.008,
          E: float = 2.0e11, rho: float = 7870.0, slider_mass: float = 0.075552,
          speed: float = 150.0, elements: int = 8, crank_angle: float = 0.0,
          mass_matrix: str = "consistent") -> kf.Mechanism:
    """Slider-crank with a rigid crank and a flexible connecting rod.

    Parameters
    ----------
    crank, rod : float
        Crank and connecting-rod lengths [m] (rod > crank).
    width, height : float
        Rod cross-section [m] (``height`` in the plane of motion).
    E, rho : float
        Rod material [Pa], [kg/m^3].
    slider_mass : float
        Slider point mass [kg].
    speed : float
        Crank speed [rad/s], + counter-clockwise.
    elements : int
        Frame elements of the rod.
    crank_angle : float
        Crank angle of the reference configuration [rad].
    mass_matrix : {"consistent", "lumped"}
        Element mass matrix of the rod.
    """
    if not (rod > crank > 0):
        raise kf.InputError(f"slider_crank: need rod > crank > 0, got crank={crank}, rod={rod}")
    m = kf.Mechanism("slider-crank")
    ax, ay = crank * math.cos(crank_angle), crank * math.sin(crank_angle)
    m.ground("O", at=(0.0, 0.0))
    m.joint("A", at=(ax, ay))
    m.slider("B", at=(ax + math.sqrt(rod**2 - ay**2), 0.0), axis=(1.0, 0.0))
    m.link("crank", "O", "A", rigid=True)
    m.link("rod", "A", "B", material=kf.Material(E=E, rho=rho),
           section=kf.Section.rectangle(width, height), elements=elements, mass_matrix=mass_matrix)
    m.point_mass("B", slider_mass)
    m.drive("crank", speed=speed)
    return m
