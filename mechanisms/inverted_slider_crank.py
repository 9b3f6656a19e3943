"""Inverted slider-crank (Norton's inversion 3): a crank drives a block along an oscillating rocker.

The crank ``O2 A`` turns about ``O2``; the block on its pin ``A`` slides
along the rocker ``O4 E``, which pivots about ``O4`` a distance ``ground``
from ``O2`` and oscillates (``ground > crank``). The rocker is a flexible
steel bar, the crank a stiff flexible one.

``cylinder=True`` builds the oscillating-cylinder form instead: the piston
rod ``P A`` is pinned to the crank pin, its piston ``P`` slides in the barrel
``O4 E`` and is locked in rotation to it (the rod stays on the barrel's
axis); the crank is then rigid. The piston's elastic rotation follows the
barrel's slope under it, whose rate jumps where the piston crosses an
element node, so the time discretisation converges at first order there
(docs/modelling.md, sliding pairs): expect many more time elements.
"""

from __future__ import annotations

import math

import kedfem as kf
from kedfem.catalogue import Preset

DEFAULTS = dict(crank=0.08, ground=0.40, rod=0.25, barrel=0.55, speed=4 * math.pi, E=2.0e11,
                rho=7850.0, rod_width=0.012, rod_height=0.012, barrel_width=0.02, barrel_height=0.03,
                piston_mass=0.5, rod_elements=4, barrel_elements=8, crank_angle=0.0, cylinder=False,
                crank_height=0.03, crank_elements=2)
#: Preset scene: the linear KED effects, 2 % modal damping.
PRESET = Preset(effects=("inertia", "coupling", "axial_stiffening"), damping=kf.ModalDamping(0.02))
SIGNED_PARAMETERS = ("crank_angle", "speed")


def build(crank: float = 0.08, ground: float = 0.40, rod: float = 0.25, barrel: float = 0.55,
          speed: float = 4 * math.pi, E: float = 2.0e11, rho: float = 7850.0, rod_width: float = 0.012,
          rod_height: float = 0.012, barrel_width: float = 0.02, barrel_height: float = 0.03,
          piston_mass: float = 0.5, rod_elements: int = 4, barrel_elements: int = 8,
          crank_angle: float = 0.0, cylinder: bool = False, crank_height: float = 0.03,
          crank_elements: int = 2) -> kf.Mechanism:
    """Inverted slider-crank: a block on the crank pin sliding on a flexible rocker (or a cylinder).

    Parameters
    ----------
    crank : float
        Crank radius ``O2 A`` [m].
    ground : float
        Distance ``O2 O4`` [m] (``O4`` on +x), ``ground > crank``.
    rod : float
        ``cylinder=True`` only: piston rod ``P A`` [m], at most ``ground - crank``
        (the piston stays in the barrel).
    barrel : float
        Rocker (barrel) ``O4 E`` [m], at least ``ground + crank`` (``ground + crank - rod``
        for the cylinder).
    speed : float
        Crank speed [rad/s], + counter-clockwise.
    E, rho : float
        Steel of the rod and barrel [Pa], [kg/m^3].
    rod_width, rod_height, barrel_width, barrel_height : float
        Rectangular sections [m] (``height`` in the plane of motion).
    piston_mass : float
        Mass of the block (the piston) [kg].
    rod_elements, barrel_elements, crank_elements : int
        Frame elements.
    crank_angle : float
        Crank angle of the reference configuration [rad].
    cylinder : bool
        The oscillating-cylinder form (piston rod locked in rotation to the barrel).
    crank_height : float
        In-plane depth of the (square) crank section [m] (block form).
    """
    if not 0.0 < crank < ground:
        raise kf.InputError(f"inverted_slider_crank: need 0 < crank < ground, got crank={crank}, "
                            f"ground={ground}")
    rod = rod if cylinder else 0.0
    if cylinder and not 0.0 < rod <= ground - crank:
        raise kf.InputError(f"inverted_slider_crank: rod={rod} m must be in (0, ground - crank = "
                            f"{ground - crank} m] so that the piston stays in the barrel")
    if not barrel >= ground + crank - rod:
        raise kf.InputError(f"inverted_slider_crank: barrel={barrel} m must be at least ground + crank - rod = "
                            f"{ground + crank - rod} m (the piston's farthest abscissa)")
    steel = kf.Material(E=E, rho=rho)
    m = kf.Mechanism("oscillating-cylinder" if cylinder else "inverted-slider-crank")
    m.ground("O2", at=(0.0, 0.0))
    m.ground("O4", at=(ground, 0.0))
    a = (crank * math.cos(crank_angle), crank * math.sin(crank_angle))
    if cylinder:
        m.joint("A", at=a)
    else:  # the crank pin is the block, sliding on the rocker
        m.slider("A", at=a, on="barrel")
    dx, dy = a[0] - ground, a[1]
    dist = math.hypot(dx, dy)
    ux, uy = dx / dist, dy / dist
    b = dist - rod  # the piston's abscissa on the barrel
    m.joint("E", at=(ground + barrel * ux, barrel * uy))
    section = kf.Section.rectangle(barrel_width, barrel_height)
    if cylinder:
        m.slider("P", at=(ground + b * ux, b * uy), on="barrel", rotation="locked")
        m.link("crank", "O2", "A", rigid=True, mass=0.5)
        m.link("rod", "P", "A", material=steel, section=kf.Section.rectangle(rod_width, rod_height),
               elements=rod_elements)
        m.point_mass("P", piston_mass)
    else:
        m.link("crank", "O2", "A", material=steel, section=kf.Section.rectangle(crank_height, crank_height),
               elements=crank_elements)
        m.point_mass("A", piston_mass)
    m.link("barrel", "O4", "E", material=steel, section=section, elements=barrel_elements)
    m.drive("crank", speed=speed)
    return m
