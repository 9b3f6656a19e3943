"""Four-eccentric-axis mould oscillation mechanism of a slab caster (the paper, section 5).

A planar side view (x towards the outer arc, y up) built only from kedfem's
generic parts. The paper gives the crank (eccentricity) lengths of four
groups (its Table 2) and the natural frequencies (its Table 3) but no masses,
lengths or stiffnesses (its reference [11] is not available), so every other
number below is a plausible choice for a slab caster, stated with its
reasoning. The model is calibrated so that group 1 reproduces the paper's
17.33 Hz.

Substructures (the paper's Fig. 1 numbering):

1, 3. Outer- and inner-arc transmissions with eccentric axes: each eccentric
      is a rigid crank of eccentricity ``e`` pivoting on the frame, driven by
      one motor through a torsionally elastic transmission (``kf.drive(...,
      torsional_stiffness=...)``). Both shafts turn synchronously, in phase.
2.    Oscillation table with the mould: one rigid body.
4, 5. Outer- and inner-arc linkages: flexible steel connecting rods, pinned at
      both ends, from the eccentric pins up to the table.
6.    Guiding leaf springs: two packs of spring-steel leaves, horizontal,
      clamped to the frame and to the table at the inner and the outer edge.
      For the rigid-body kinematics the inner pack acts as a guide link
      pinned at both ends (it closes the loop: two rods plus one guide fix the
      table's three planar DOFs); elastically it is clamped at both ends, so
      the stroke bends it into an S (prescribed end rotations). The outer pack
      is kinematically redundant (``kinematic=False``): it follows the chord
      between its anchor and the table, whose change of length it must take
      elastically. With ``geometric_nonlinearity`` the membrane tension the
      stroke induces in both packs stiffens them: this is what makes the
      natural frequency rise with the stroke (Table 3).

Loads: inertia, gravity, a non-linear (progressive) balance spring carrying
the oscillating weight, and the billet-withdrawal friction on the mould that
opposes the mould's motion relative to the strand (casting speed), with a
tanh-regularised sign.

Geometry from the paper's Table 2: the ratio of outer to inner crank length
is 1.3767 in all four groups, and the outer-arc amplitude sits at the same
fraction 0.6026 of the way from the inner to the outer crank in all four
groups. We read this as the table rotating about the caster's arc centre:
vertical amplitudes are proportional to the distance from that centre, so the
rod spacing ``D`` follows from the caster radius ``R`` of the mould's outer
face: ``R = D (e_i / (e_o - e_i) + 0.6026)``. The guide is horizontal at the
height of the arc centre, so that the table's instantaneous centre of rotation
is the arc centre.

The lowest mode of this model is the first bending mode of the leaf-spring
packs (the softest members); its frequency is calibrated through the leaf
length. The paper does not say which mode its 17.33 Hz is; this is our
interpretation, chosen because it is the mode that the paper's two named
non-linearities (leaf-spring geometric non-linearity, balance spring) can
shift with the stroke.

Default speed: 150 oscillation cycles per minute (2.5 Hz, 15.71 rad/s). The paper
gives no speed. Mechanical oscillators of slab casters run at a few hertz at most;
ranges of roughly 50 to 250 cycles/min with strokes of a few millimetres are the
commonly quoted practice (the oscillation-mark literature, e.g. Takeuchi &
Brimacombe, Metall. Trans. B 1984, studies slab casters in this regime), and the
paper's own strokes (+-3 to +-5 mm) fit it. We found no citable single value in
the references given to this project, so 150 cpm is a documented mid-range choice;
``speed=`` overrides it (and ``kedfem sweep`` scans it, like the paper's Figs. 3-4).
"""

from __future__ import annotations

import math

import kedfem as kf
from kedfem.catalogue import Preset

#: Paper Table 2: (inner, outer) crank lengths [m] and outer-arc amplitude [m]
GROUPS = {
    1: (2.445e-3, 3.366e-3, 3.0e-3),
    2: (2.853e-3, 3.928e-3, 3.5e-3),
    3: (3.260e-3, 4.488e-3, 4.0e-3),
    4: (4.075e-3, 5.610e-3, 5.0e-3),
}
#: Paper Table 3: natural frequencies [Hz], (state-space method, modal superposition)
TABLE3 = {1: (17.33, 17.35), 2: (17.50, 17.55), 3: (17.83, 17.85), 4: (18.33, 18.50)}
#: fraction of the way from the inner to the outer crank where the outer-arc amplitude holds
OUTER_FACE_FRACTION = 0.6026

DEFAULTS = dict(
    group=1,
    speed=2 * math.pi * 150 / 60,   # 150 cycles/min [rad/s]
    caster_radius=9.0,              # outer-arc radius of a slab caster [m] (8-12 m is common)
    table_mass=20000.0,             # table + mould + water jackets of a slab mould [kg]
    table_inertia=1.6e4,            # [kg m^2]: ~ m (a^2 + b^2) / 12 with a = 3.0 m, b = 1.0 m
    table_width=3.2,                # x extent of the table; leaf springs clamp at its edges [m]
    rod_length=1.0,                 # eccentric pin to table [m]
    rod_diameter=0.10,              # solid steel connecting rods [m]
    rod_elements=2,
    eccentric_mass=450.0,           # eccentric shaft share of one planar crank [kg]
    eccentric_inertia=45.0,         # shaft + gear + motor share about the shaft axis [kg m^2]
    transmission_stiffness=2.0e6,   # torsional stiffness of each transmission [N m/rad]
    leaf_length=0.99146,            # free length of a leaf-spring pack [m]: calibrated to 17.33 Hz
                                    # (benchmarks/calibrate_mould.py)
    leaf_thickness=3.0e-3,          # one spring-steel leaf [m]
    leaf_width=0.25,                # [m]
    leaf_count=10,                  # leaves per pack
    leaf_elements=4,
    leaf_height=0.2,                # height of the leaf springs above the table's CoM [m]
    balance_stiffness=2.0e7,        # balance spring, linear part [N/m]
    balance_cubic=5.0e11,           # balance spring, progressive part [N/m^3]
    friction_force=10.0e3,          # billet-withdrawal friction on the mould [N]
    casting_speed=1.2 / 60,         # strand withdrawal speed [m/s] (1.2 m/min)
    friction_smoothing=2.0e-3,      # tanh regularisation speed of the friction sign [m/s]
    E=2.06e11, rho=7850.0,          # steel
)
#: The preset scene, which is also kedfem's built-in default scene
#: (:func:`kedfem.analysis.defaults.default_scene`, ``kedfem run``): every effect
#: the model declares, 2 % modal damping, the paper's fixed-point iteration
#: (Newton-like with the tangent terms) to ``eps = 1e-6``; the number of time
#: elements follows from the tolerance.
PRESET = Preset(
    effects=("inertia", "coupling", "axial_stiffening", "geometric_nonlinearity", "gravity", "springs", "loads"),
    damping=kf.ModalDamping(0.02),
    solver=dict(eps=1e-6, nonlinear_method="fixed-point"),
    name="mould oscillator, group {group}",
)
#: heights and the strand's withdrawal speed may be negative (every other parameter is >= 0)
SIGNED_PARAMETERS = ("leaf_height", "casting_speed")


def build(group: int = 1, **overrides) -> kf.Mechanism:
    """Mould oscillation mechanism for crank group 1..4 of the paper's Table 2.

    Parameters
    ----------
    group : int
        Crank group 1..4 (eccentricities of the paper's Table 2).
    **overrides
        Any key of :data:`DEFAULTS` (SI units), e.g. ``speed=`` [rad/s],
        ``leaf_length=`` [m], ``friction_force=`` [N].

    Returns
    -------
    kedfem.Mechanism
    """
    unknown = set(overrides) - set(DEFAULTS)
    if unknown:
        raise kf.InputError(f"mould_oscillator: unknown parameter(s) {', '.join(sorted(unknown))}; "
                            f"known: {', '.join(sorted(DEFAULTS))}")
    if group not in GROUPS:
        raise kf.InputError(f"mould_oscillator: group must be one of 1, 2, 3, 4 (paper Table 2), got {group!r}")
    p = dict(DEFAULTS)
    p.update(overrides)
    p["group"] = group
    e_in, e_out, _amp = GROUPS[group]
    steel = kf.Material(E=p["E"], rho=p["rho"])
    # rod spacing from the caster radius (see the module docstring); group 1 fixes the geometry
    e1_in, e1_out, _ = GROUPS[1]
    D = p["caster_radius"] / (e1_in / (e1_out - e1_in) + OUTER_FACE_FRACTION)
    yt = -0.3                         # rod tops, below the table's CoM
    yg = p["leaf_height"]             # leaf springs (and arc centre) height
    x_in, x_out = -D / 2, D / 2
    yo = yt - p["rod_length"]         # eccentric shaft axes
    half = p["table_width"] / 2
    if half <= D / 2:
        raise kf.InputError("mould_oscillator: table_width must exceed the rod spacing "
                            f"{D:.3f} m derived from caster_radius")
    m = kf.Mechanism(f"mould-oscillator-g{group}")
    # eccentric shafts (frame pivots) and eccentric pins, at mid-stroke (crank horizontal)
    m.ground("O3", at=(x_in - e_in, yo))
    m.ground("O1", at=(x_out - e_out, yo))
    m.joint("H", at=(x_in, yo))
    m.joint("D", at=(x_out, yo))
    # table attachment joints
    m.joint("F", at=(x_in, yt))
    m.joint("E", at=(x_out, yt))
    m.joint("T1", at=(-half, yg))
    m.joint("T2", at=(half, yg))
    x_face = x_in + OUTER_FACE_FRACTION * D
    m.joint("M", at=(x_face, 0.5))   # mould, outer-arc face
    m.joint("S", at=(0.0, yt))        # balance spring seat under the table
    # leaf-spring anchors on the frame
    L = p["leaf_length"]
    m.ground("G1", at=(-half - L, yg))
    m.ground("G2", at=(half + L, yg))
    m.body("table", ("F", "E", "T1", "T2", "M", "S"), mass=p["table_mass"], J=p["table_inertia"],
           cm=(0.0, 0.0))
    # 1, 3: eccentrics on torsionally elastic transmissions, one motor: same speed and phase
    Je = p["eccentric_inertia"]
    m.link("eccentric_inner", "O3", "H", rigid=True, mass=p["eccentric_mass"], J=Je)
    m.link("eccentric_outer", "O1", "D", rigid=True, mass=p["eccentric_mass"], J=Je)
    m.drive("eccentric_outer", speed=p["speed"], torsional_stiffness=p["transmission_stiffness"])
    m.drive("eccentric_inner", speed=p["speed"], torsional_stiffness=p["transmission_stiffness"])
    # 4, 5: connecting rods
    rod = kf.Section.circle(p["rod_diameter"])
    m.link("rod_outer", "D", "E", material=steel, section=rod, elements=p["rod_elements"])
    m.link("rod_inner", "H", "F", material=steel, section=rod, elements=p["rod_elements"])
    # 6: guiding leaf-spring packs (n leaves bending independently: A and I add up)
    n, b, h = p["leaf_count"], p["leaf_width"], p["leaf_thickness"]
    leaf = kf.Section(A=n * b * h, I=n * b * h**3 / 12.0, c=h / 2.0)
    m.link("leaf_inner", "G1", "T1", material=steel, section=leaf, elements=p["leaf_elements"],
           ends=("clamp", "clamp"))
    m.link("leaf_outer", "T2", "G2", material=steel, section=leaf, elements=p["leaf_elements"],
           ends=("clamp", "clamp"), kinematic=False)
    # balance spring: carries the oscillating weight in the reference position, progressive
    weight = (p["table_mass"] + 0.5 * (m.links["rod_outer"].mass + m.links["rod_inner"].mass)) * 9.80665
    m.spring("balance", "S", k=p["balance_stiffness"], k3=p["balance_cubic"], axis=(0.0, 1.0),
             preload=-weight)
    # billet-withdrawal friction on the mould: opposes the motion relative to the strand
    m.friction("billet", "M", force=p["friction_force"], axis=(0.0, 1.0),
               reference_speed=-p["casting_speed"], smoothing=p["friction_smoothing"], follows="total")
    return m
