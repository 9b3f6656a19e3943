"""Define a planar linkage in Python and solve its periodic elastic response.

A crank-rocker four-bar: rigid steel crank, flexible coupler and rocker (steel strips).
Run: ``python examples/linkage.py``.
"""

import math

import kedfem as kf


def build(speed_rpm: float = 300.0, elements: int = 4) -> kf.Mechanism:
    steel = kf.Material(E=2.1e11, rho=7850.0)                 # [Pa], [kg/m^3]
    strip = kf.Section.rectangle(0.025, 0.005)              # width, in-plane height [m]
    m = kf.Mechanism("crank-rocker")
    m.ground("O2", at=(0.0, 0.0))                             # crank pivot [m]
    m.ground("O4", at=(0.30, 0.0))                            # rocker pivot [m]
    m.joint("A", at=(0.08, 0.0))                              # crank pin
    m.joint("B", at=(0.22, 0.25))                             # coupler-rocker pin
    m.link("crank", "O2", "A", rigid=True, material=steel, section=kf.Section.rectangle(0.03, 0.01))
    m.link("coupler", "A", "B", material=steel, section=strip, elements=elements)
    m.link("rocker", "O4", "B", material=steel, section=strip, elements=elements)
    m.point_mass("B", 0.2)                                    # [kg]
    m.drive("crank", speed=speed_rpm * 2 * math.pi / 60)      # [rad/s]
    return m


def main(steps: int = 180) -> kf.PeriodicResult:
    scene = kf.Scene(build(), steps=steps, effects=("inertia", "coupling", "axial_stiffening"),
                     damping=kf.ModalDamping(0.02), name="crank-rocker")
    res = kf.solve(scene)
    f = res.frequencies(2)
    print(f"{scene.name}: fundamental {f.fundamental:.2f} Hz, stable {res.stable}")
    for p in res.peaks():
        print(f"  {p.link:8s} peak deflection {p.deflection:.3e} m at {math.degrees(p.deflection_angle):5.1f} deg,"
              f" peak stress {p.stress / 1e6:7.2f} MPa")
    return res


if __name__ == "__main__":
    main()
