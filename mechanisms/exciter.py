"""Eccentric exciter driving a cantilever through a spring (a vibration test rig).

A rigid crank (an unbalanced exciter shaft) turns at constant speed; a spring
from its pin to the tip of a stationary steel cantilever loads the cantilever
periodically. All flexible parts stand still, so the scene is time-invariant:
its periodic response can be checked against modal superposition.
"""

from __future__ import annotations

import math

import kedfem as kf
from kedfem.catalogue import Preset

DEFAULTS = dict(speed=2 * math.pi * 12.0, eccentricity=0.01, length=0.8, width=0.04, height=0.01,
                spring=2.0e4, elements=8, E=2.0e11, rho=7850.0, tip_mass=0.5)
#: Preset scene: a linear, time-invariant structure loaded through its spring
PRESET = Preset(effects=("inertia", "coupling", "springs"), damping=kf.ModalDamping(0.02))


def build(speed: float = 2 * math.pi * 12.0, eccentricity: float = 0.01, length: float = 0.8,
          width: float = 0.04, height: float = 0.01, spring: float = 2.0e4, elements: int = 8,
          E: float = 2.0e11, rho: float = 7850.0, tip_mass: float = 0.5) -> kf.Mechanism:
    """Cantilever (clamped at the origin, along +x) excited at its tip by a crank-driven spring.

    Parameters
    ----------
    speed : float
        Exciter speed [rad/s].
    eccentricity : float
        Crank radius [m].
    length, width, height : float
        Cantilever [m] (``height`` in plane).
    spring : float
        Stiffness of the vertical spring from the crank pin to the tip [N/m].
    elements : int
        Frame elements of the cantilever.
    E, rho : float
        Steel [Pa], [kg/m^3].
    tip_mass : float
        Point mass at the tip [kg].
    """
    m = kf.Mechanism("exciter")
    m.ground("C", at=(0.0, 0.0), clamped=True)
    m.joint("T", at=(length, 0.0))
    m.ground("X", at=(length, -0.2))
    m.joint("P", at=(length + eccentricity, -0.2))
    m.link("beam", "C", "T", material=kf.Material(E=E, rho=rho), section=kf.Section.rectangle(width, height),
           elements=elements)
    m.link("crank", "X", "P", rigid=True)
    m.point_mass("T", tip_mass)
    m.spring("drive_spring", "P", "T", k=spring, axis=(0.0, 1.0))
    m.drive("crank", speed=speed)
    return m
