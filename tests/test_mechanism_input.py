"""Bad input gets a clear error that names the problem, raised at once."""

import pytest

import kedfem as kf

STEEL = kf.Material(E=2e11, rho=7800)
SEC = kf.Section.rectangle(0.01, 0.01)


def base():
    m = kf.Mechanism("m")
    m.ground("O", at=(0, 0))
    m.joint("A", at=(0.1, 0))
    return m


def test_link_naming_unknown_joint():
    m = base()
    with pytest.raises(kf.InputError, match="link 'rod' names unknown joint 'Q'"):
        m.link("rod", "A", "Q", material=STEEL, section=SEC)


@pytest.mark.parametrize("kw,name", [(dict(E=-1, rho=1), "E"), (dict(E=0, rho=1), "E"),
                                     (dict(E=2e11, rho=0), "rho"), (dict(E=float("nan"), rho=1), "E")])
def test_bad_material(kw, name):
    with pytest.raises(kf.InputError, match=f"Material: {name}"):
        kf.Material(**kw)


def test_a_modulus_in_gpa_is_named_before_the_solve():
    """E = 210 (GPa meant, Pa read) is refused where it is given (a new user's six-bar solved 9 s
    to a 1238 mm deflection); a soft test linkage's 7.1e4 Pa is not."""
    with pytest.raises(kf.InputError, match=r"Material: E = 210 Pa is below 10000 Pa.*210 GPa is 210e9 Pa"):
        kf.Material(E=210.0, rho=7850.0)
    assert kf.Material(E=7.1e4, rho=7850.0).E == 7.1e4


@pytest.mark.parametrize("kw,name", [(dict(A=0, I=1), "A"), (dict(A=1, I=-2), "I"),
                                     (dict(A="x", I=1), "A")])
def test_bad_section(kw, name):
    with pytest.raises(kf.InputError, match=f"Section: {name}"):
        kf.Section(**kw)
    with pytest.raises(kf.InputError, match="h"):
        kf.Section.rectangle(0.01, -0.01)


def test_zero_length_and_bad_elements():
    m = base()
    m.joint("B", at=(0.1, 0))
    with pytest.raises(kf.InputError, match="link 'z': zero length"):
        m.link("z", "A", "B", material=STEEL, section=SEC)
    with pytest.raises(kf.InputError, match="elements"):
        m.link("c", "O", "A", material=STEEL, section=SEC, elements=0)
    with pytest.raises(kf.InputError, match="needs material"):
        m.link("c", "O", "A")


def test_disconnected_graph():
    m = base()
    m.joint("X", at=(1, 1))
    m.joint("Y", at=(2, 1))
    m.link("c", "O", "A", material=STEEL, section=SEC)
    m.link("d", "X", "Y", material=STEEL, section=SEC)
    with pytest.raises(kf.InputError, match=r"disconnected.*\{X, Y\}"):
        kf.FEModel(m)


def test_drive_on_link_without_ground_joint():
    m = base()
    m.joint("B", at=(0.3, 0))
    m.link("c", "O", "A", rigid=True)
    m.link("r", "A", "B", material=STEEL, section=SEC)
    with pytest.raises(kf.InputError, match="drive on 'r'.*ground joint"):
        m.drive("r", speed=1.0)
    with pytest.raises(kf.InputError, match="unknown link or body 'nope'"):
        m.drive("nope", speed=1.0)


def test_duplicates_and_reserved_names():
    m = base()
    with pytest.raises(kf.InputError, match="joint 'A' is defined twice"):
        m.joint("A", at=(0, 1))
    with pytest.raises(kf.InputError, match="reserved"):
        m.joint("ground", at=(0, 1))
    m.link("c", "O", "A", rigid=True)
    with pytest.raises(kf.InputError, match="'c' is used twice"):
        m.link("c", "O", "A", rigid=True)


def test_bad_positions_and_axes():
    m = kf.Mechanism("m")
    with pytest.raises(kf.InputError, match="at"):
        m.joint("A", at=(0, float("inf")))
    with pytest.raises(kf.InputError, match="axis"):
        m.slider("S", at=(0, 0), axis=(0, 0))


def test_unsynchronised_drives():
    m = kf.Mechanism("two")
    m.ground("O1", at=(0, 0))
    m.ground("O2", at=(1, 0))
    m.joint("A", at=(0.1, 0))
    m.joint("B", at=(1.1, 0))
    m.link("c1", "O1", "A", rigid=True)
    m.link("c2", "O2", "B", rigid=True)
    m.drive("c1", speed=10.0)
    with pytest.raises(kf.InputError, match="integer multiple"):
        m.drive("c2", speed=15.0)


def test_a_closed_loop_of_rigid_links_is_rejected_by_name():
    """An all-rigid four-bar has no elastic freedom (issue 12, item 2): a clear error, not spurious DOFs."""
    import math

    import numpy as np

    import kedfem as kf
    m = kf.Mechanism("rigid four-bar")
    m.ground("O2", at=(0.0, 0.0))
    m.ground("O4", at=(0.254, 0.0))
    m.joint("A", at=(0.108, 0.0))
    A, O4 = np.array([0.108, 0.0]), np.array([0.254, 0.0])
    d = O4 - A
    L = float(np.hypot(*d))
    x = (0.2794**2 - 0.2705**2 + L**2) / (2 * L)
    B = A + x * d / L + math.sqrt(0.2794**2 - x**2) * np.array([-d[1], d[0]]) / L
    m.joint("B", at=tuple(B))
    for name, a, b in (("crank", "O2", "A"), ("coupler", "A", "B"), ("follower", "O4", "B")):
        m.link(name, a, b, rigid=True, mass=0.1)
    m.drive("crank", speed=20.0)
    with pytest.raises(kf.InputError, match="close a loop of rigid members.*make at least one link"):
        kf.FEModel(m)


def test_small_api_gaps_give_named_errors():
    """Issue 12, item 8: bad values raise InputError naming the parameter, never a bare ValueError."""
    import math

    import kedfem as kf
    import mechanisms
    with pytest.raises(kf.InputError, match="nu must be a number"):
        kf.Material(E=2e11, rho=7800.0, nu="x")
    with pytest.raises(kf.InputError, match="E must be a number, got True"):
        kf.Material(E=True, rho=7800.0)
    with pytest.raises(kf.InputError, match="crank_angle must be a number"):
        kf.natural_frequencies(mechanisms.build("slider_crank"), crank_angle="zero")
    with pytest.raises(kf.InputError, match="steps must be at most"):
        kf.Scene(mechanisms.build("slider_crank"), steps=10**7)
    m = kf.Mechanism("s")
    m.ground("O", at=(0.0, 0.0))
    m.slider("B", at=(0.4, 0.0), axis=(3e-320, 4e-320))   # subnormal components
    ax = m.joints["B"].axis
    assert ax == pytest.approx((0.6, 0.8), rel=1e-15) and math.hypot(*ax) == pytest.approx(1.0, rel=1e-15)
