"""Whitworth quick-return (a shaper's ram drive): a crank, a slotted lever, a link and a ram.

The crank ``O2 A`` (length ``crank``) turns about ``O2``; its pin ``A``
carries a block that slides in the slotted lever ``O4 C``, pivoted at ``O4``
a distance ``offset`` below ``O2``. Because ``offset < crank`` the lever
turns fully round, slowly while the crank pin is above ``O4`` and fast
below it. The link ``C D`` drives the ram ``D`` along the horizontal line
through ``O4``. The slow (cutting) stroke takes the crank angle
``pi + 2 asin(offset / crank)``, the quick return ``pi - 2 asin(offset /
crank)``; with a counter-clockwise crank (``speed > 0``) the cutting stroke
runs along -x (``examples/shaper.py``).

The lever and the link are flexible steel bars; the crank is a stiff
flexible bar (a block on a slot needs the pin's member to carry elastic
DOFs of its own or through a moving reference, see docs/modelling.md).
"""

from __future__ import annotations

import math

import kedfem as kf
from kedfem.catalogue import Preset

DEFAULTS = dict(crank=0.10, offset=0.05, lever=0.30, link=0.45, ram_mass=2.0, block_mass=0.2,
                speed=4 * math.pi, E=2.0e11, rho=7850.0, lever_width=0.012, lever_height=0.025,
                link_width=0.010, link_height=0.020, crank_height=0.04, lever_elements=16,
                link_elements=4, crank_elements=2, rigid_link=False, crank_angle=math.pi / 2)
#: Preset scene: the linear KED effects, 2 % modal damping.
PRESET = Preset(effects=("inertia", "coupling", "axial_stiffening"), damping=kf.ModalDamping(0.02))
SIGNED_PARAMETERS = ("crank_angle", "speed")


def build(crank: float = 0.10, offset: float = 0.05, lever: float = 0.30, link: float = 0.45,
          ram_mass: float = 2.0, block_mass: float = 0.2, speed: float = 4 * math.pi,
          E: float = 2.0e11, rho: float = 7850.0, lever_width: float = 0.012,
          lever_height: float = 0.025, link_width: float = 0.010, link_height: float = 0.020,
          crank_height: float = 0.04, lever_elements: int = 16, link_elements: int = 4,
          crank_elements: int = 2, rigid_link: bool = False,
          crank_angle: float = math.pi / 2) -> kf.Mechanism:
    """Whitworth quick-return with a flexible slotted lever.

    Parameters
    ----------
    crank : float
        Crank radius ``O2 A`` [m].
    offset : float
        Distance ``O2 O4`` [m], ``0 < offset < crank`` (``O4`` below ``O2``).
    lever : float
        Slotted lever ``O4 C`` [m], longer than ``crank + offset`` (the block's farthest abscissa).
    link : float
        Link ``C D`` [m], longer than ``lever``.
    ram_mass, block_mass : float
        Ram and sliding block masses [kg].
    speed : float
        Crank speed [rad/s], + counter-clockwise.
    E, rho : float
        Steel of all bars [Pa], [kg/m^3].
    lever_width, lever_height, link_width, link_height : float
        Rectangular sections [m] (``height`` in the plane of motion).
    crank_height : float
        In-plane depth of the (square) crank section [m].
    lever_elements, link_elements, crank_elements : int
        Frame elements per bar.
    rigid_link : bool
        A rigid link ``C D`` (its mass kept) between the lever and the ram's slider.
    crank_angle : float
        Crank angle of the reference configuration [rad].
    """
    if not 0.0 < offset < crank:
        raise kf.InputError(f"whitworth: need 0 < offset < crank, got offset={offset}, crank={crank}")
    if not lever > crank + offset:
        raise kf.InputError(f"whitworth: lever={lever} m must exceed crank + offset = {crank + offset} m "
                            "(the block's farthest abscissa on it)")
    if not link > lever:
        raise kf.InputError(f"whitworth: link={link} m must exceed lever={lever} m")
    steel = kf.Material(E=E, rho=rho)
    m = kf.Mechanism("whitworth")
    m.ground("O2", at=(0.0, offset))
    m.ground("O4", at=(0.0, 0.0))
    a = (crank * math.cos(crank_angle), offset + crank * math.sin(crank_angle))
    th4 = math.atan2(a[1], a[0])
    m.slider("A", at=a, on="lever")   # the block on the crank pin, sliding in the lever
    c = (lever * math.cos(th4), lever * math.sin(th4))
    m.joint("C", at=c)
    m.slider("D", at=(c[0] + math.sqrt(link**2 - c[1] ** 2), 0.0), axis=(1.0, 0.0))
    m.link("crank", "O2", "A", material=steel, section=kf.Section.rectangle(crank_height, crank_height),
           elements=crank_elements)
    m.link("lever", "O4", "C", material=steel, section=kf.Section.rectangle(lever_width, lever_height),
           elements=lever_elements)
    m.link("link", "C", "D", material=steel, section=kf.Section.rectangle(link_width, link_height),
           elements=link_elements, rigid=bool(rigid_link))
    m.point_mass("D", ram_mass)
    m.point_mass("A", block_mass)
    m.drive("crank", speed=speed)
    return m
