"""A beam pumping unit: a walking beam pivoted on its saddle bearing, flexible on both sides.

A conventional (class I) unit. The crank ``O P`` (a rigid body with its counterweights) turns
about ``O``; the rigid pitman ``P B`` rocks the walking beam ``H B`` about the saddle bearing
``S`` on the Samson post, which the beam passes through (``through="S"``: one flexible link with
a mesh node at the pin, its arms ``S H`` to the horse head and ``S B`` to the equalizer bending on
either side). Drawn with the beam level, the pitman vertical and the crank pointing away from
the well. The polished rod hangs from the horse head ``H`` (a vertical force there; the horse
head's arc keeps the rod vertical, and its curvature is left out):

* the rods' weight in the fluid, ``rod_load``, all the time;
* the fluid column, ``fluid_load``, on the up-stroke only: the rods pick it up over the first
  ``pickup`` of the up-stroke (the travelling valve closes and the rods stretch) and hand it
  back over the first ``pickup`` of the down-stroke (``Profile.position`` on the horse head's
  height, one load per stroke, each along an S-curve: the shape of a dynamometer card).

Run::

    python examples/pumping_unit.py                     # solve, print the loads on the machine
    kedfem run examples/pumping_unit.py:build --trust   # the same through the command line

Its hand checks (``tests/test_pinned_beam.py``): the static deflection of the horse head
against the closed form of a beam on a pin with an overhang, ``W A^2 (A + C) / (3 E I)``;
the same unit built with the beam split into two links welded at the saddle; the mean drive
torque against the fluid's work per stroke, from the stroke of a closed-form four-bar.
"""

from __future__ import annotations

import math

import numpy as np

import kedfem as kf

DEFAULTS = dict(head_arm=3.0, rear_arm=2.5, pitman=3.3, crank=0.9, speed=2 * math.pi * 8 / 60,
                rod_load=40e3, fluid_load=30e3, pickup=0.1, beam_elements=11, split=False, gravity=True)

#: The walking beam: a W24x84 steel section (A [m^2], I [m^4], c [m]) and its steel.
BEAM_SECTION = kf.Section(A=0.01594, I=0.9906e-3, c=0.306)
STEEL = kf.Material(E=2.0e11, rho=7850.0)
#: Crank with its counterweights: mass [kg], rotary inertia about the centre of mass [kg m^2] and the
#: centre of mass's distance from O along the crank arm, the pin's way [m] (the rod load lifts the pin
#: through the beam and the pitman; the counterweights pull it down: balanced about the mean rod load)
CRANK_MASS, CRANK_J, COUNTERWEIGHT_ARM = 4000.0, 2000.0, 1.5
PITMAN_MASS = 300.0


def stroke_ends(head_arm: float = 3.0, rear_arm: float = 2.5, pitman: float = 3.3, crank: float = 0.9):
    """Lowest and highest height of the horse head [m] (closed-form four-bar, no kedfem).

    The rocker ``S B`` is at its extremes where the crank and the pitman are in line:
    ``|O B| = pitman -+ crank``; ``B`` is then where the circle about ``S`` of radius
    ``rear_arm`` meets the circle about ``O`` of that radius, and ``H = -(head_arm / rear_arm) B``.
    """
    O = np.array([rear_arm - crank, -pitman])
    heights = []
    for d in (pitman - crank, pitman + crank):
        # circle-circle intersection, S at the origin: the point on the side of the drawing (x > 0)
        D = float(np.hypot(*O))
        a = (rear_arm**2 - d**2 + D**2) / (2 * D)
        h = math.sqrt(rear_arm**2 - a * a)
        u = O / D
        n = np.array([-u[1], u[0]])
        B = max((a * u + h * n, a * u - h * n), key=lambda p: p[0])
        heights.append(-(head_arm / rear_arm) * B[1])
    return min(heights), max(heights)


def build(head_arm: float = 3.0, rear_arm: float = 2.5, pitman: float = 3.3, crank: float = 0.9,
          speed: float = 2 * math.pi * 8 / 60, rod_load: float = 40e3, fluid_load: float = 30e3,
          pickup: float = 0.1, beam_elements: int = 11, split: bool = False,
          gravity: bool = True) -> kf.Mechanism:
    """The pumping unit (see the module docstring).

    Parameters
    ----------
    head_arm, rear_arm : float
        Saddle bearing to the horse head ``S H`` and to the equalizer ``S B`` [m].
    pitman, crank : float
        Pitman ``P B`` and crank radius ``O P`` [m]; ``O`` lies ``rear_arm - crank`` behind
        the saddle and ``pitman`` below it.
    speed : float
        Crank speed [rad/s], + counter-clockwise (8 strokes a minute by default).
    rod_load, fluid_load : float
        The rods' weight in the fluid and the fluid column's weight on the plunger [N].
    pickup : float
        Share of the stroke over which the rods pick up and hand back the fluid load.
    beam_elements : int
        Frame elements of the walking beam (shared between its arms by length).
    split : bool
        Build the beam as two links welded at the saddle (``ground(..., welded=)``) instead of
        one link through it: the same model (a check of the two).
    gravity : bool
        The members' weight (``set_gravity``); False for a check under the rod load alone.
    """
    if not 0.0 < pickup < 0.5:
        raise kf.InputError(f"pumping unit: pickup must lie in (0, 0.5) of the stroke, got {pickup!r}")
    m = kf.Mechanism("pumping unit")
    m.ground("O", at=(rear_arm - crank, -pitman))
    if split:
        m.ground("S", at=(0.0, 0.0), welded=("head", "rear"))
    else:
        m.ground("S", at=(0.0, 0.0))
    m.joint("P", at=(rear_arm, -pitman))
    m.joint("B", at=(rear_arm, 0.0))
    m.joint("H", at=(-head_arm, 0.0))
    cw = (rear_arm - crank + COUNTERWEIGHT_ARM, -pitman)  # the counterweights, on the crank arm
    m.body("crank", ["O", "P"], mass=CRANK_MASS, J=CRANK_J, cm=cw)
    m.link("pitman", "P", "B", rigid=True, mass=PITMAN_MASS)
    if split:
        n_head = round(beam_elements * head_arm / (head_arm + rear_arm))
        m.link("head", "H", "S", material=STEEL, section=BEAM_SECTION, elements=n_head)
        m.link("rear", "S", "B", material=STEEL, section=BEAM_SECTION, elements=beam_elements - n_head)
    else:
        m.link("beam", "H", "B", material=STEEL, section=BEAM_SECTION, elements=beam_elements, through="S")
    m.drive("crank", speed=speed)
    low, high = stroke_ends(head_arm, rear_arm, pitman, crank)
    s = high - low
    up = (0.0, 1.0)
    m.load("rods", "H", force=(0.0, -rod_load))
    m.load("fluid, up-stroke", "H", force=(0.0, -fluid_load),
           profile=kf.Profile.position("H", up, [low, low + pickup * s], [0.0, 1.0], stroke="forward",
                                       smooth=True))
    m.load("fluid, down-stroke", "H", force=(0.0, -fluid_load),
           profile=kf.Profile.position("H", up, [high - pickup * s, high], [0.0, 1.0], stroke="return",
                                       smooth=True))
    if gravity:
        m.set_gravity((0.0, -9.80665))
    return m


def main():
    res = kf.solve(kf.Scene(build()))
    print(res.summary())  # with the loads on the machine (res.loads(): bearing forces, drive torque)
    return res


if __name__ == "__main__":
    main()
