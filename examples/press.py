"""A crank press forming a part: a process load over the last 10 % of the ram's down-stroke.

The crank ``O A`` (rigid) turns about ``O``; the flexible connecting rod ``A B`` drives the ram
``B`` along the vertical line through ``O``, below it. Drawn at the top dead centre (crank up).
Over the last ``forming_travel`` of the down-stroke (10 % of the stroke) the ram forms the part:
the part's force on it rises from nothing where the tool meets the part to ``forming_force`` at
the bottom dead centre; on the way back it falls to nothing over the part's and the frame's
springback, ``springback`` of travel, each along an S-curve of the travel (``smooth=True``: no
kink where the tool meets or leaves the part, which would ring the rod's axial modes and cost
thousands of time elements). Two loads on the ram, one for each stroke
(``Profile.position(..., stroke="forward")`` and ``"return"``), which meet at the bottom dead
centre.

Run::

    python examples/press.py                        # solve, print the loads on the machine
    kedfem run examples/press.py:build --trust      # the same through the command line

Its hand check (drive torque and bearing forces of the rigid kinetostatics from the closed-form
slider-crank and Newton-Euler in numpy) is in ``tests/test_process_loads.py``.
"""

from __future__ import annotations

import math

import kedfem as kf

DEFAULTS = dict(crank=0.05, rod=0.25, speed=2 * math.pi, ram_mass=20.0, crank_mass=3.0,
                forming_force=40e3, forming_travel=0.01, springback=0.002, rod_width=0.03, rod_height=0.03,
                rod_elements=8)


def build(crank: float = 0.05, rod: float = 0.25, speed: float = 2 * math.pi, ram_mass: float = 20.0,
          crank_mass: float = 3.0, forming_force: float = 40e3, forming_travel: float = 0.01,
          springback: float = 0.002, rod_width: float = 0.03, rod_height: float = 0.03,
          rod_elements: int = 8) -> kf.Mechanism:
    """The press (see the module docstring).

    Parameters
    ----------
    crank, rod : float
        Crank radius ``O A`` and rod length ``A B`` [m] (stroke ``2 crank``).
    speed : float
        Crank speed [rad/s], + counter-clockwise (60 strokes a minute by default).
    ram_mass, crank_mass : float
        [kg]; the crank is a uniform bar.
    forming_force : float
        Force of the part on the ram while it is formed [N].
    forming_travel : float
        Travel before the bottom dead centre over which the part is formed [m].
    springback : float
        Travel after the bottom dead centre over which the force falls to nothing [m].
    rod_width, rod_height : float
        Steel rod's rectangular section [m] (height in the plane).
    rod_elements : int
        Frame elements of the rod.
    """
    m = kf.Mechanism("press")
    m.ground("O", at=(0.0, 0.0))
    m.joint("A", at=(0.0, crank))
    m.slider("B", at=(0.0, crank - rod), axis=(0.0, 1.0))
    m.link("crank", "O", "A", rigid=True, mass=crank_mass, J=crank_mass * crank**2 / 12)
    m.link("rod", "A", "B", material=kf.Material(E=2.1e11, rho=7850.0),
           section=kf.Section.rectangle(rod_width, rod_height), elements=rod_elements)
    m.point_mass("B", ram_mass)
    m.drive("crank", speed=speed)
    # the ram's depth below O: rod - crank at the top dead centre, rod + crank at the bottom
    bdc = rod + crank
    down = (0.0, -1.0)  # the ram's depth below O is its position along -y
    m.load("forming", "B", force=(0.0, forming_force),
           profile=kf.Profile.position("B", down, [bdc - forming_travel, bdc], [0.0, 1.0], stroke="forward",
                                       smooth=True))
    m.load("springback", "B", force=(0.0, forming_force),
           profile=kf.Profile.position("B", down, [bdc - springback, bdc], [0.0, 1.0], stroke="return",
                                       smooth=True))
    return m


def main():
    scene = kf.Scene(build(), effects=("inertia", "coupling", "axial_stiffening", "gravity", "loads"),
                     damping=kf.ModalDamping(0.02))
    res = kf.solve(scene)
    print(res.summary())  # with the loads on the machine (res.loads(): bearing forces, drive torque)
    return res


if __name__ == "__main__":
    main()
