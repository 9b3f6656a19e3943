"""Materials and cross-sections of flexible links."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..checks import flag, names, real
from ..errors import InputError

__all__ = ["Material", "Section", "MAX_LENGTH", "flag", "names"]

#: Largest coordinate, length or section dimension [m] a model may hold (a planar linkage of
#: a thousand kilometres is a unit mistake; squares and products of lengths then stay finite).
MAX_LENGTH = 1e6
#: Largest Young's modulus [Pa] a material may have (diamond: 1.2e12 Pa; stiff stand-ins for rigid
#: members go to 1e15; beyond, a unit mistake)
MAX_MODULUS = 1e16
#: Largest density [kg/m^3] (osmium: 22.6e3; beyond, a unit mistake)
MAX_DENSITY = 1e5
#: Smallest Young's modulus [Pa] a material may have (soft rubber: 1e6 Pa; a deliberately soft
#: test linkage: 7e4 Pa; below, a modulus given in GPa or kN/mm^2, which ran a new user's solve for
#: 9 s to a result 400 % of its length deflected)
MIN_MODULUS = 1e4


def _positive(owner: str, name: str, value) -> float:
    return real(owner, name, value, positive=True)


def _dimension(owner: str, name: str, value) -> float:
    return real(owner, name, value, positive=True, limit=MAX_LENGTH, unit=" m")


@dataclass(frozen=True)
class Material:
    """Linear elastic isotropic material.

    Parameters
    ----------
    E : float
        Young's modulus [Pa].
    rho : float
        Density [kg/m^3].
    nu : float, optional
        Poisson's ratio (only used by the Timoshenko shear modulus), default 0.3.
    yield_strength : float, optional
        Yield strength ``S_y`` [Pa]: the yield safety factor and the Soderberg line.
    ultimate_strength : float, optional
        Ultimate tensile strength ``S_ut`` [Pa]: the Goodman line.
    endurance_limit : float, optional
        Fully reversed endurance limit ``S_e`` [Pa] (corrected for the part: surface, size,
        reliability...): the Goodman and Soderberg lines.
    """

    E: float
    rho: float
    nu: float = 0.3
    yield_strength: float | None = None
    ultimate_strength: float | None = None
    endurance_limit: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "E", real("Material", "E", self.E, positive=True, limit=MAX_MODULUS, unit=" Pa"))
        if self.E < MIN_MODULUS:
            raise InputError(f"Material: E = {self.E:g} Pa is below {MIN_MODULUS:g} Pa, softer than any solid a "
                             f"linkage is made of: E is in Pa (steel 2.1e11 Pa, aluminium 7e10 Pa; "
                             f"{self.E:g} GPa is {self.E:g}e9 Pa)")
        object.__setattr__(self, "rho", real("Material", "rho", self.rho, positive=True, limit=MAX_DENSITY,
                                             unit=" kg/m^3"))
        if isinstance(self.nu, bool):
            raise InputError(f"Material: nu must be a number, got {self.nu!r}")
        try:
            nu = float(self.nu)
        except (TypeError, ValueError):
            raise InputError(f"Material: nu must be a number, got {self.nu!r}") from None
        if not (-1.0 < nu < 0.5):
            raise InputError(f"Material: nu must lie in (-1, 0.5), got {self.nu!r}")
        object.__setattr__(self, "nu", nu)
        for name in ("yield_strength", "ultimate_strength", "endurance_limit"):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, _positive("Material", name, v))
        if self.yield_strength and self.ultimate_strength and self.yield_strength > self.ultimate_strength:
            raise InputError(f"Material: yield_strength {self.yield_strength:.4g} Pa exceeds ultimate_strength "
                             f"{self.ultimate_strength:.4g} Pa")

    @property
    def G(self) -> float:
        """Shear modulus ``E / (2 (1 + nu))`` [Pa]."""
        return self.E / (2.0 * (1.0 + self.nu))


@dataclass(frozen=True)
class Section:
    """Cross-section of a planar beam (bending in the mechanism's plane).

    Parameters
    ----------
    A : float
        Area [m^2].
    I : float
        Second moment of area about the out-of-plane axis [m^4].
    c : float, optional
        Distance from the neutral axis to the extreme fibre [m], used for the
        bending stress ``M c / I``. ``None`` if unknown (stress then needs it).
    kappa : float, optional
        Shear correction factor (Timoshenko), default 5/6.
    """

    A: float
    I: float  # noqa: E741 - engineering notation
    c: float | None = None
    kappa: float = 5.0 / 6.0

    def __post_init__(self):
        object.__setattr__(self, "A", real("Section", "A", self.A, positive=True, limit=MAX_LENGTH**2,
                                           unit=" m^2"))
        object.__setattr__(self, "I", real("Section", "I", self.I, positive=True, limit=MAX_LENGTH**4,
                                           unit=" m^4"))
        if self.c is not None:
            object.__setattr__(self, "c", _dimension("Section", "c", self.c))
        object.__setattr__(self, "kappa", _positive("Section", "kappa", self.kappa))

    @classmethod
    def rectangle(cls, b: float, h: float) -> "Section":
        """Solid rectangle: width ``b`` out of plane, height ``h`` in plane [m]."""
        b = _dimension("Section.rectangle", "b", b)
        h = _dimension("Section.rectangle", "h", h)
        return cls(A=b * h, I=b * h**3 / 12.0, c=h / 2.0, kappa=5.0 / 6.0)

    @classmethod
    def circle(cls, d: float) -> "Section":
        """Solid circle of diameter ``d`` [m]."""
        d = _dimension("Section.circle", "d", d)
        return cls(A=math.pi * d**2 / 4.0, I=math.pi * d**4 / 64.0, c=d / 2.0, kappa=0.9)

    @classmethod
    def tube(cls, d: float, t: float) -> "Section":
        """Circular tube of outer diameter ``d`` and wall thickness ``t`` [m]."""
        d = _dimension("Section.tube", "d", d)
        t = _dimension("Section.tube", "t", t)
        if 2 * t >= d:
            raise InputError(f"Section.tube: wall thickness t={t} must be < d/2={d / 2}")
        di = d - 2 * t
        return cls(A=math.pi * (d**2 - di**2) / 4.0, I=math.pi * (d**4 - di**4) / 64.0,
                   c=d / 2.0, kappa=0.5)
