"""Linkages outside the catalogue, for the benchmarks: built the way a user would build them.

Each ``build(**params)`` returns a :class:`kedfem.Mechanism`; ``CASES`` pairs
them with the effects and damping a study runs them with. None of them is
tuned to kedfem's defaults: they are the kinds of linkage engineers bring
(a steel crank-rocker at 600 rpm, a drag link, a Stephenson six-bar whose
coupler is a welded T, a vertical slider-crank with gravity and a return
spring, an offset slider-crank whose flexible crank and rod meet at a pin, run
with the geometric non-linearity; all members flexible where it matters).
"""

from __future__ import annotations

import math

import numpy as np

import kedfem as kf

STEEL = kf.Material(E=2.06e11, rho=7850.0)
ALUMINIUM = kf.Material(E=7.0e10, rho=2700.0)


def _circle(p, rp, q, rq, upper=True):
    """Intersection of circles (p, rp) and (q, rq), the upper or lower one."""
    d = np.asarray(q, float) - np.asarray(p, float)
    dist = float(np.hypot(*d))
    x = (rp**2 - rq**2 + dist**2) / (2 * dist)
    h = math.sqrt(max(rp**2 - x**2, 0.0))
    n = np.array([-d[1], d[0]]) / dist
    return np.asarray(p, float) + x * d / dist + (h if upper else -h) * n


def crank_rocker(rpm: float = 600.0, elements: int = 4) -> kf.Mechanism:
    """Steel crank-rocker: rigid crank 60 mm, flexible coupler 220 mm and rocker 160 mm (20 x 5 mm)."""
    O2, O4 = np.array([0.0, 0.0]), np.array([0.20, 0.0])
    A = np.array([0.06, 0.0])
    B = _circle(A, 0.22, O4, 0.16)
    m = kf.Mechanism("crank-rocker")
    m.ground("O2", at=tuple(O2))
    m.ground("O4", at=tuple(O4))
    m.joint("A", at=tuple(A))
    m.joint("B", at=tuple(B))
    sec = kf.Section.rectangle(0.020, 0.005)
    m.link("crank", "O2", "A", rigid=True, mass=0.3)
    m.link("coupler", "A", "B", material=STEEL, section=sec, elements=elements)
    m.link("rocker", "O4", "B", material=STEEL, section=sec, elements=elements)
    m.point_mass("B", 0.15)
    m.drive("crank", speed=rpm * 2 * math.pi / 60)
    return m


def drag_link(rpm: float = 300.0, elements: int = 4) -> kf.Mechanism:
    """Drag link (double crank, Grashof with the frame shortest): flexible aluminium coupler and output crank."""
    O2, O4 = np.array([0.0, 0.0]), np.array([0.05, 0.0])
    A = np.array([0.0, 0.12])
    B = _circle(A, 0.16, O4, 0.14, upper=False)
    m = kf.Mechanism("drag-link")
    m.ground("O2", at=tuple(O2))
    m.ground("O4", at=tuple(O4))
    m.joint("A", at=tuple(A))
    m.joint("B", at=tuple(B))
    sec = kf.Section.rectangle(0.025, 0.006)
    m.link("input", "O2", "A", rigid=True, mass=0.4)
    m.link("coupler", "A", "B", material=ALUMINIUM, section=sec, elements=elements)
    m.link("output", "O4", "B", material=ALUMINIUM, section=sec, elements=elements)
    m.point_mass("B", 0.25)
    m.drive("input", speed=rpm * 2 * math.pi / 60)
    return m


def stephenson(rpm: float = 240.0, elements: int = 3) -> kf.Mechanism:
    """Stephenson six-bar: a crank-rocker whose coupler is a welded T driving a second dyad.

    The coupler A-B carries a stem welded at its mid-point E that ends at F;
    F drives the link F-G of an output rocker pivoted at O6. Every link but
    the crank is a flexible steel strip.
    """
    O2, O4, O6 = np.array([0.0, 0.0]), np.array([0.30, 0.0]), np.array([0.10, 0.42])
    A = np.array([0.08, 0.0])
    B = _circle(A, 0.28, O4, 0.20)
    E = 0.5 * (A + B)
    u = (B - A) / np.linalg.norm(B - A)
    F = E + 0.12 * np.array([-u[1], u[0]])
    G = _circle(F, 0.22, O6, 0.18, upper=False)
    m = kf.Mechanism("stephenson-six-bar")
    for name, p in (("O2", O2), ("O4", O4), ("O6", O6)):
        m.ground(name, at=tuple(p))
    for name, p in (("A", A), ("B", B), ("F", F), ("G", G)):
        m.joint(name, at=tuple(p))
    m.joint("E", at=tuple(E), welded=True)
    sec = kf.Section.rectangle(0.020, 0.006)
    m.link("crank", "O2", "A", rigid=True, mass=0.3)
    m.link("coupler_a", "A", "E", material=STEEL, section=sec, elements=elements)
    m.link("coupler_b", "E", "B", material=STEEL, section=sec, elements=elements)
    m.link("stem", "E", "F", material=STEEL, section=sec, elements=elements)
    m.link("rocker", "O4", "B", material=STEEL, section=sec, elements=elements)
    m.link("link", "F", "G", material=STEEL, section=sec, elements=elements)
    m.link("output", "O6", "G", material=STEEL, section=sec, elements=elements)
    m.drive("crank", speed=rpm * 2 * math.pi / 60)
    return m


def vertical_slider_crank(rpm: float = 900.0, elements: int = 4) -> kf.Mechanism:
    """Vertical slider-crank with a flexible crank and rod, gravity and a return spring on the slider."""
    m = kf.Mechanism("vertical-slider-crank")
    m.ground("O", at=(0.0, 0.0))
    m.joint("A", at=(0.05, 0.0))
    B = (0.0, math.sqrt(0.18**2 - 0.05**2))
    m.slider("B", at=B, axis=(0.0, 1.0))
    sec = kf.Section.rectangle(0.012, 0.008)
    m.link("crank", "O", "A", material=STEEL, section=kf.Section.rectangle(0.02, 0.012), elements=elements)
    m.link("rod", "A", "B", material=STEEL, section=sec, elements=elements)
    m.point_mass("B", 0.4)
    m.spring("return", "B", k=2.0e3, axis=(0.0, 1.0), preload=50.0)
    m.set_gravity((0.0, -9.81))
    m.drive("crank", speed=rpm * 2 * math.pi / 60)
    return m


def offset_slider_crank(rpm: float = 150.0 * 60 / (2 * math.pi), elements: int = 4) -> kf.Mechanism:
    """Offset slider-crank with a flexible crank and rod pinned together (a new user's trial linkage)."""
    steel = kf.Material(E=2.0e11, rho=7850.0)
    crank, rod, offset = 0.10, 0.35, 0.03
    m = kf.Mechanism("offset-slider-crank")
    m.ground("O", at=(0.0, 0.0))
    m.joint("A", at=(crank, 0.0))
    m.slider("B", at=(crank + math.sqrt(rod**2 - offset**2), offset), axis=(1.0, 0.0))
    m.link("crank", "O", "A", material=steel, section=kf.Section.rectangle(0.02, 0.008), elements=elements)
    m.link("rod", "A", "B", material=steel, section=kf.Section.rectangle(0.012, 0.006), elements=elements)
    m.point_mass("B", 0.5)
    m.drive("crank", speed=rpm * 2 * math.pi / 60)
    return m


#: name -> (builder, effects, damping)
def strip_crank_rocker(rpm: float = 450.0, coupler_h: float = 0.006, elements: int = 4) -> kf.Mechanism:
    """A new user's crank-rocker (issue 25, ninth round): rigid crank 60 mm (0.15 kg), steel strip
    coupler 250 mm (20 mm x ``coupler_h``), steel tube rocker 180 mm (16 x 1.5 mm), ground 230 mm,
    0.1 kg at the coupler-rocker pin. Not in ``CASES``: the tests use it (a numerically damped
    spectral radius at 450 rpm; the continuation in speed and the mesh check at 2250 rpm with a
    3 mm strip and the geometric non-linearity)."""
    steel = kf.Material(E=2.1e11, rho=7850.0, yield_strength=350e6)
    m = kf.Mechanism("strip crank-rocker")
    m.ground("O2", (0.0, 0.0))
    m.ground("O4", (0.23, 0.0))
    m.joint("A", m.at_angle("O2", 0.06, 0.0))
    m.joint("B", m.at_lengths(("A", 0.25, "coupler"), ("O4", 0.18, "rocker"), branch="open"))
    m.link("crank", "O2", "A", rigid=True, mass=0.15, length=0.06)
    m.link("coupler", "A", "B", material=steel, section=kf.Section.rectangle(0.020, coupler_h),
           elements=elements, length=0.25)
    m.link("rocker", "O4", "B", material=steel, section=kf.Section.tube(0.016, 0.0015), elements=elements,
           length=0.18)
    m.point_mass("B", 0.1)
    m.drive("crank", speed=rpm * 2 * math.pi / 60)
    return m


def knuckle_press(rpm: float = 60.0, force: float = 100e3, travel: float = 0.002, smooth: bool = True,
                  elements: int = 4) -> kf.Mechanism:
    """A new user's knuckle-joint (toggle) press (issue 25, thirteenth part): rigid crank 30 mm about
    O = (0.34, 0.12), steel rod 300 mm (20 x 20 mm) to the knee C, upper toggle 200 mm from P = (0, 0.3)
    to C and lower toggle 200 mm from C to the ram B on the line x = 0 (both 30 x 30 mm), 30 kg ram.
    A forming force ``force`` [N] on the ram over the last ``travel`` [m] of its down-stroke and a
    springback over ``travel / 4`` on the way back (S-curves with ``smooth``, else straight ramps).
    Not in ``CASES``: at 60 rpm its refinement is driven by the histories (the ringing of the
    toggles after the springback), 7 levels where the second level's forecast said 4."""
    P, O, r, rod, toggle = np.array([0.0, 0.3]), np.array([0.34, 0.12]), 0.03, 0.3, 0.2

    def knee(theta):
        return _circle(P, toggle, O + r * np.array([math.cos(theta), math.sin(theta)]), rod, upper=False)

    def depth(theta):  # the ram's depth below the origin
        C = knee(theta)
        return -(C[1] - math.sqrt(toggle**2 - C[0] ** 2))

    C = knee(0.0)
    m = kf.Mechanism("knuckle press")
    m.ground("O", at=tuple(O))
    m.ground("P", at=tuple(P))
    m.joint("A", at=tuple(O + np.array([r, 0.0])))
    m.joint("C", at=tuple(C))
    m.slider("B", at=(0.0, -depth(0.0)), axis=(0.0, 1.0))
    m.link("crank", "O", "A", rigid=True, mass=2.0, J=2.0 * r**2 / 12)
    m.link("rod", "A", "C", material=STEEL, section=kf.Section.rectangle(0.02, 0.02), elements=elements)
    m.link("upper", "P", "C", material=STEEL, section=kf.Section.rectangle(0.03, 0.03), elements=elements)
    m.link("lower", "C", "B", material=STEEL, section=kf.Section.rectangle(0.03, 0.03), elements=elements)
    m.point_mass("B", 30.0)
    m.drive("crank", speed=rpm * 2 * math.pi / 60)
    if force:
        bdc = max(depth(th) for th in np.linspace(0.0, 2 * math.pi, 2001))
        down = (0.0, -1.0)
        m.load("forming", "B", force=(0.0, force), profile=kf.Profile.position(
            "B", down, [bdc - travel, bdc], [0.0, 1.0], stroke="forward", smooth=smooth))
        m.load("springback", "B", force=(0.0, force), profile=kf.Profile.position(
            "B", down, [bdc - travel / 4, bdc], [0.0, 1.0], stroke="return", smooth=smooth))
    return m


CASES = {
    "crank_rocker": (crank_rocker, ("inertia", "coupling", "axial_stiffening"), kf.ModalDamping(0.02)),
    "drag_link": (drag_link, ("inertia", "coupling", "axial_stiffening"), kf.ModalDamping(0.02)),
    "stephenson": (stephenson, ("inertia", "coupling", "axial_stiffening"), kf.ModalDamping(0.02)),
    "vertical_slider_crank": (vertical_slider_crank,
                              ("inertia", "coupling", "axial_stiffening", "gravity", "springs"),
                              kf.Rayleigh(alpha=2.0, beta=2e-5)),
    "offset_slider_crank": (offset_slider_crank, ("inertia", "coupling", "geometric_nonlinearity"),
                            kf.ModalDamping(0.02)),
}
