"""A flexible member pinned inside its length: ``link(..., through=)`` and ``ground(..., welded=)``.

The walking beam of a pumping unit (examples/pumping_unit.py) on its saddle bearing: its static
deflection against the closed form of a beam on a pin with an overhang; the beam as one link
through the pin and as two links welded at it (the same model, to round-off); the mean drive
torque against the fluid's work per stroke. A four-bar whose flexible coupler passes the
rocker's pin (the coupler extended beyond it) against the coupler split and welded there.
"""

import math

import numpy as np
import pytest

import kedfem as kf
from kedfem.analysis.fatigue import fatigue_table
from test_examples import load

pu = load("pumping_unit")
W = 50e3  # the polished-rod load of the static check [N]


def deflection_by_hand(head_arm, rear_arm):
    """Tip deflection of a beam on a pin (S) and a support (B) a span ``rear_arm`` apart, with an
    overhang ``head_arm`` carrying ``W`` at its tip: ``W a^2 (L + a) / (3 E I)`` (downwards)."""
    return -W * head_arm**2 * (rear_arm + head_arm) / (3 * pu.STEEL.E * pu.BEAM_SECTION.I)


@pytest.mark.parametrize("split", [False, True])
@pytest.mark.parametrize("arms,elements", [((3.0, 2.5), 11), ((3.05, 2.13), 7)])
def test_horse_head_deflection_is_the_overhanging_beam_closed_form(split, arms, elements):
    """Drawn level, with the pitman vertical: the equalizer's pin is a support, the saddle's a pin.
    Euler-Bernoulli elements reproduce the closed form at the nodes (to round-off; the acceptance
    asks 1e-4); the second case meshes the arms with elements of different lengths."""
    m = pu.build(head_arm=arms[0], rear_arm=arms[1], rod_load=W, fluid_load=0.0, beam_elements=elements,
                 split=split, gravity=False)
    st = kf.static_response(m, effects=("loads",), crank_angle=0.0)  # the drawing
    dx, dy = st.joint_displacement("H")
    want = deflection_by_hand(*arms)
    assert abs(dy / want - 1) < 1e-9 and abs(dx) < 1e-12 * abs(want)
    if not split and arms[1] != 2.5:
        assert len(set(np.round(m.links["beam"].element_lengths, 12))) == 2


def _solve(mech, effects=None, steps=48):
    sc = kf.Scene(mech, steps=steps, estimate=False) if effects is None else \
        kf.Scene(mech, effects=effects, steps=steps, estimate=False)
    return kf.solve(sc)


def _rel(a, b):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(b)))


def test_the_beam_through_its_pin_is_the_beam_split_and_welded_there():
    """Same response, stresses, peaks and loads to 1e-10 (the default effects with gravity and the
    fluid load, 2 % modal damping; arms meshed with elements of different lengths)."""
    kw = dict(head_arm=3.05, rear_arm=2.13, beam_elements=13)
    one, two = _solve(pu.build(**kw)), _solve(pu.build(split=True, **kw))
    for j in ("H", "B"):
        assert _rel(one.joint_displacement(j), two.joint_displacement(j)) < 1e-10, j
    s1 = one.stress("beam", 4)
    head, rear = two.stress("head", 4), two.stress("rear", 4)
    s2 = np.concatenate([head[:, :-1], np.maximum(head[:, -1:], rear[:, :1]), rear[:, 1:]], axis=1)
    assert _rel(s1, s2) < 1e-10  # at the saddle: the larger of the two sides (the pin's force steps N)
    p1, p2 = one.peaks()[0], max(two.peaks(), key=lambda p: p.stress)
    assert abs(p1.stress / p2.stress - 1) < 1e-10
    at = p2.stress_station + (kw["head_arm"] if p2.link == "rear" else 0.0)
    assert abs(p1.stress_station - at) < 1e-6
    for h in ("rigid", "elastic"):
        l1, l2 = one.loads(), two.loads()
        assert _rel(l1.torque(response=h), l2.torque(response=h)) < 1e-10, h
        for joint in ("S", "O", "B"):
            assert _rel(l1.force(joint, None, h), l2.force(joint, None, h)) < 1e-10, (h, joint)
    # fatigue: both sides of the saddle's pin (the axial force steps there), as the two links' ends
    f1, f2 = fatigue_table(one), fatigue_table(two)
    r1 = f1.links[0]
    r2 = max(f2.links, key=lambda lf: lf.largest_range)
    assert abs(r1.largest_range / r2.largest_range - 1) < 1e-10
    assert abs(r1.worst_station - (r2.worst_station + (kw["head_arm"] if r2.link == "rear" else 0.0))) < 1e-9
    assert np.count_nonzero(np.isclose(r1.stations, kw["head_arm"])) == 2
    f = 0 if r1.worst_fibre == "top" else 1  # the printed line's mean and alternating are the worst side's
    assert r1.largest_range == pytest.approx(2 * r1.alternating[r1.worst_index, f], rel=1e-12)
    assert f"alternating {r1.alternating[r1.worst_index, f] / 1e6:.4g} MPa" in r1.describe()
    # the peak deflection: of each arm between the pins, relative to its own chord
    assert abs(p1.deflection / max(p.deflection for p in two.peaks()) - 1) < 1e-10
    both = one.stretch_deflections("beam")
    assert _rel(both[:, 0], two.deflection("head", 0.5, relative_to="chord")) < 1e-10
    assert _rel(both[:, 1], two.deflection("rear", 0.5, relative_to="chord")) < 1e-10
    # the saddle bearing carries the beam: its force on the frame balances the head's and the pitman's
    assert np.max(np.abs(one.loads().force("S", None, "rigid"))) > 1e5


def test_the_mean_drive_torque_is_the_fluid_work_per_stroke():
    """Per cycle the drive puts in the work the fluid column takes out (gravity and the rods' weight
    in the fluid do none): ``2 pi mean(T) = F (1 - pickup) S``, the S-curves of the pick-up and
    hand-back each doing half their travel's work; the stroke ``S`` from the closed-form four-bar."""
    F, p = 30e3, 0.1
    low, high = pu.stroke_ends()
    assert 2.0 < high - low < 2.5  # 2.2 m: 2 crank x head_arm / rear_arm, nearly
    res = _solve(pu.build(fluid_load=F, pickup=p), effects=("inertia", "coupling", "gravity", "loads"),
                 steps=768)
    T = res.loads().torque(response="rigid")
    assert abs(2 * math.pi * float(np.mean(T)) / (F * (1 - p) * (high - low)) - 1) < 1e-6
    # the horse head's own travel agrees with the closed form
    y = res.motion.r[:, res.motion.joint_names.index("H"), 1]
    assert abs(y.min() - low) < 1e-3 * (high - low) and abs(y.max() - high) < 1e-3 * (high - low)


def test_the_pumping_unit_example_converges():
    res = pu.main()
    assert res.error.met and res.stable
    assert abs(res.peaks()[0].stress_station - 3.0) < 0.05  # the beam's peak stress: at the saddle


# ------------------------------------------------------------- a pin to another member mid-link
def four_bar(split: bool, elements=(5, 3)):
    """A crank-rocker whose flexible coupler ``A E`` passes the rocker's pin ``B`` (a coupler
    extension, as a straight-line linkage's): one link through B, or two welded at B."""
    steel = kf.Material(E=2.1e11, rho=7850.0)
    sec = kf.Section.rectangle(0.01, 0.02)
    m = kf.Mechanism("extended coupler")
    m.ground("O", (0.0, 0.0))
    m.ground("Q", (0.4, 0.0))
    m.joint("A", (0.0, 0.1))
    m.joint("B", (0.4, 0.3))
    m.joint("E", (0.6, 0.4), welded=False)
    if split:
        m.joints.pop("B")
        m.graph.remove_node("B")
        m.joint("B", (0.4, 0.3), welded=("coupler", "extension"))
        m.link("coupler", "A", "B", material=steel, section=sec, elements=elements[0])
        m.link("extension", "B", "E", material=steel, section=sec, elements=elements[1])
    else:
        m.link("coupler", "A", "E", material=steel, section=sec, elements=sum(elements), through="B")
    m.link("crank", "O", "A", rigid=True, mass=0.5)
    m.link("rocker", "Q", "B", material=steel, section=sec, elements=3)
    m.point_mass("E", 0.3)
    m.drive("crank", 2 * math.pi * 5)
    return m


def test_a_coupler_through_the_rockers_pin_is_the_coupler_split_and_welded_there():
    """The rocker pinned at B stays pinned (only the coupler's two parts are welded): the rocker's
    own rotation at B is free in both models."""
    one, two = _solve(four_bar(False)), _solve(four_bar(True))
    for j in ("B", "E"):
        assert _rel(one.joint_displacement(j), two.joint_displacement(j)) < 1e-10, j
    assert _rel(one.stress("rocker", 2), two.stress("rocker", 2)) < 1e-10
    l1, l2 = one.loads(), two.loads()
    assert _rel(l1.torque(response="elastic"), l2.torque(response="elastic")) < 1e-10
    assert _rel(l1.force("B", "rocker", "elastic"), l2.force("B", "rocker", "elastic")) < 1e-10


# ------------------------------------------------------------------------------- bad input
def _beam_mech():
    m = kf.Mechanism("m")
    m.ground("S", (0.0, 0.0))
    m.joint("H", (-1.0, 0.0))
    m.joint("B", (1.0, 0.0))
    m.joint("X", (0.2, 0.01))
    m.slider("Y", (0.5, 0.0))
    return m


STEEL = kf.Material(E=2.1e11, rho=7850.0)
SEC = kf.Section.rectangle(0.01, 0.02)


@pytest.mark.parametrize("through,kw,says", [
    ("X", {}, "joint 'X' at (0.2, 0.01) is 0.01 m off the link's line"),
    ("H", {}, "through='H' is an end of the link"),
    ("Y", {}, "through='Y' is a slider joint"),
    ("Z", {}, "unknown joint 'Z'"),
    (("S", "S"), {}, "through names a joint twice"),
    ("S", {"elements": 1}, "elements must be at least 2, got 1"),
    ("S", {"kinematic": False}, "cannot pass through a joint"),
])
def test_through_errors_name_the_joint(through, kw, says):
    m = _beam_mech()
    with pytest.raises(kf.InputError, match=None) as e:
        m.link("beam", "H", "B", material=STEEL, section=SEC, elements=kw.get("elements", 4), through=through,
               kinematic=kw.get("kinematic", True))
    assert says in str(e.value) and "link 'beam'" in str(e.value)


def test_a_block_on_a_link_through_a_joint_is_refused_at_validation():
    m = kf.Mechanism("m")
    m.ground("S", (0.0, 0.0))
    m.ground("O", (0.0, -0.5))
    m.joint("H", (-1.0, 0.0))
    m.joint("B", (1.0, 0.0))
    m.slider("K", (0.5, 0.0), on="beam")
    m.link("beam", "H", "B", material=STEEL, section=SEC, elements=4, through="S")
    m.link("crank", "O", "K", rigid=True, mass=1.0)
    with pytest.raises(kf.InputError, match="passes through joint"):
        m.validate()


def test_ground_welded_names_members_welded_to_each_other():
    m = kf.Mechanism("m")
    with pytest.raises(kf.InputError, match="clamped=True welds every member"):
        m.ground("S", (0.0, 0.0), clamped=True, welded=("a", "b"))
    with pytest.raises(kf.InputError, match="two or more different ones"):
        m.ground("S", (0.0, 0.0), welded=("a",))
    with pytest.raises(kf.InputError, match="to weld every member to the frame, give clamped=True"):
        m.ground("S", (0.0, 0.0), welded=True)


# ------------------------------------------------- a crank with a counterweight arm past its pivot
def crank_with_arm(split: bool, kt=None):
    """A slider-crank whose flexible crank ``C A`` carries a counterweight arm past its driven
    pivot O: one link through O, or two links welded there (``ground(welded=)``)."""
    steel, sec = kf.Material(E=2.1e11, rho=7850.0), kf.Section(A=2e-4, I=6.67e-9, c=0.01)
    m = kf.Mechanism("crank with arm")
    m.ground("O", (0.0, 0.0), welded=("arm", "crank") if split else None)
    m.joint("C", (-0.1, 0.0))
    m.joint("A", (0.15, 0.0))
    m.slider("S", (0.6, 0.0), axis=(1, 0))
    if split:
        m.link("arm", "C", "O", material=steel, section=sec, elements=2)
        m.link("crank", "O", "A", material=steel, section=sec, elements=3)
    else:
        m.link("crank", "C", "A", material=steel, section=sec, elements=5, through="O")
    m.link("rod", "A", "S", material=steel, section=sec, elements=4)
    m.point_mass("C", 0.5)
    m.point_mass("S", 1.0)
    m.drive("crank", 2 * math.pi * 10, torsional_stiffness=kt)
    return m, steel, sec


def test_a_driven_crank_through_its_pivot_is_the_crank_welded_to_its_arm():
    """The arm is a cantilever from the driven pivot (static tip load against ``P a^3 / 3EI``);
    running, with and without a shaft's stiffness, the two builds agree, drive torque included."""
    for split in (False, True):
        m, steel, sec = crank_with_arm(split)
        m.load("P", "C", force=(0.0, -10.0))
        st = kf.static_response(m, effects=("loads",), crank_angle=0.0)
        assert abs(st.joint_displacement("C")[1] / (-10.0 * 0.1**3 / (3 * steel.E * sec.I)) - 1) < 1e-9, split
    for kt in (None, 500.0):
        one, two = _solve(crank_with_arm(False, kt)[0]), _solve(crank_with_arm(True, kt)[0])
        for j in ("C", "A", "S"):
            assert _rel(one.joint_displacement(j), two.joint_displacement(j)) < 1e-10, (kt, j)
        for h in ("rigid", "elastic"):
            assert _rel(one.loads().torque(response=h), two.loads().torque(response=h)) < 1e-10, (kt, h)


@pytest.mark.parametrize("elements", [3, 4, 6, 20, 40])
def test_the_stretches_share_exactly_the_elements_given(elements):
    """Two pins near the ends: the short stretches get one element each, the long one the rest."""
    m = kf.Mechanism("m")
    m.ground("S1", (-0.95, 0.0))
    m.ground("S2", (0.95, 0.0))
    m.joint("H", (-1.0, 0.0))
    m.joint("B", (1.0, 0.0))
    lk = m.link("beam", "H", "B", material=STEEL, section=SEC, elements=elements, through=("S1", "S2"))
    assert sum(c for _f, c, _le in lk.segments()) == lk.element_lengths.size == elements
    assert lk.nodes[lk.node_of("S1")] == pytest.approx(0.05) and lk.nodes[lk.node_of("S2")] == pytest.approx(1.95)
    assert np.isclose(lk.element_lengths.sum(), 2.0)


def test_a_link_through_a_joint_keeps_one_colour_in_both_panels_of_the_link_plot(tmp_path, monkeypatch):
    """A new user's six-bar: the link-response plot drew the coupler through the rocker's pin in one
    colour per stretch above and another colour below (each panel's own colour cycle)."""
    import matplotlib.colors as mcolors

    from kedfem.io import plots

    res = kf.solve(kf.Scene(four_bar(split=False), steps=48, estimate=False))
    seen = {}

    def keep(fig, path):
        seen["fig"] = fig
        return path

    monkeypatch.setattr(plots, "_save", keep)
    plots.link_response(res, tmp_path / "link_response.png")
    top, bottom = seen["fig"].axes[:2]
    colour = {}
    for line in top.get_lines():
        colour.setdefault(line.get_label().split()[0], set()).add(mcolors.to_hex(line.get_color()))
    below = {line.get_label(): mcolors.to_hex(line.get_color()) for line in bottom.get_lines()}
    assert set(below) == {"coupler", "rocker"} and len(colour["coupler"]) == 1
    for name in below:
        assert colour[name] == {below[name]}
    assert len(set(below.values())) == 2
    styles = {line.get_linestyle() for line in top.get_lines() if line.get_label().startswith("coupler")}
    assert len(styles) == 2  # its two stretches told apart by line style
