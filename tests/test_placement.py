"""Assembling a linkage from its lengths (Mechanism.at_angle / at_lengths / at_length_on_line,
kedfem.model.placement) and the check of a stated link length (Mechanism.link(..., length=)).

References: Norton's closed-form positions (R. L. Norton, Design of Machinery, eqs. 4.10 and 4.13
for the four-bar's open and crossed circuits, 4.16-4.17 for the offset slider-crank), and the law
of cosines in the triangle of the dyad.
"""

import logging
import math
import warnings

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem.errors import LengthWarning

A_, B_, C_, D_ = 0.108, 0.2794, 0.2705, 0.254   # crank, coupler, rocker, ground [m]
ANGLES = np.radians(np.arange(0.0, 360.0, 7.5))


def _norton_four_bar(th2, circuit):
    """Coupler and rocker angles of Norton's closed form (open: the minus root)."""
    a, b, c, d = A_, B_, C_, D_
    K1, K2, K3 = d / a, d / c, (a * a - b * b + c * c + d * d) / (2 * a * c)
    K4, K5 = d / b, (c * c - d * d - a * a - b * b) / (2 * a * b)
    A = math.cos(th2) - K1 - K2 * math.cos(th2) + K3
    B = -2 * math.sin(th2)
    C = K1 - (K2 + 1) * math.cos(th2) + K3
    D = math.cos(th2) - K1 + K4 * math.cos(th2) + K5
    E = -2 * math.sin(th2)
    F = K1 + (K4 - 1) * math.cos(th2) + K5
    sgn = -1.0 if circuit == "open" else 1.0
    th4 = 2 * math.atan2(-B + sgn * math.sqrt(B * B - 4 * A * C), 2 * A)
    th3 = 2 * math.atan2(-E + sgn * math.sqrt(E * E - 4 * D * F), 2 * D)
    return th3, th4


def _frame(ground_angle=0.0, origin=(0.0, 0.0), crank=None):
    """Ground pivots O2 and O4 (and the crank pin A at crank angle ``crank`` from the ground line)."""
    m = kf.Mechanism("four-bar from lengths")
    m.ground("O2", at=origin)
    m.ground("O4", at=m.at_angle("O2", D_, ground_angle))
    if crank is not None:
        m.joint("A", at=m.at_angle("O2", A_, ground_angle + crank))
    return m


@pytest.mark.parametrize("circuit", ["open", "crossed"])
def test_four_bar_positions_match_nortons_closed_form(circuit):
    for th2 in ANGLES:
        m = _frame(crank=th2)
        A = np.array(m.joints["A"].at)
        B = np.array(m.at_lengths(("A", B_, "coupler"), ("O4", C_, "rocker"), branch=circuit))
        th3, th4 = _norton_four_bar(th2, circuit)
        np.testing.assert_allclose(A, [A_ * math.cos(th2), A_ * math.sin(th2)], rtol=0, atol=1e-15)
        np.testing.assert_allclose(B, A + B_ * np.array([math.cos(th3), math.sin(th3)]), rtol=0, atol=1e-12)
        np.testing.assert_allclose(B, [D_ + C_ * math.cos(th4), C_ * math.sin(th4)], rtol=0, atol=1e-12)


def test_four_bar_positions_by_the_law_of_cosines_in_any_frame():
    """Rotated and moved ground, either order of the anchors: the triangle A-O4-B by the law of cosines."""
    gamma, origin = 2.1, np.array([0.3, -1.7])
    for th2 in ANGLES[::3]:
        m = _frame(gamma, tuple(origin), crank=th2)
        O4 = np.array(m.joints["O4"].at)
        np.testing.assert_allclose(O4, origin + D_ * np.array([math.cos(gamma), math.sin(gamma)]), atol=1e-15)
        A = origin + A_ * np.array([math.cos(th2 + gamma), math.sin(th2 + gamma)])
        np.testing.assert_allclose(m.joints["A"].at, A, atol=1e-15)
        s = np.hypot(*(O4 - A))
        phi = math.acos((B_**2 + s**2 - C_**2) / (2 * B_ * s))  # angle at A between A->O4 and A->B
        base = math.atan2(*(O4 - A)[::-1])
        left = A + B_ * np.array([math.cos(base + phi), math.sin(base + phi)])
        right = A + B_ * np.array([math.cos(base - phi), math.sin(base - phi)])
        for first, second in ((("A", B_), ("O4", C_)), (("O4", C_), ("A", B_))):
            np.testing.assert_allclose(m.at_lengths(first, second, "open"), left, atol=1e-12)
            np.testing.assert_allclose(m.at_lengths(first, second, "crossed"), right, atol=1e-12)
        np.testing.assert_allclose(m.at_lengths(("A", B_), ("O4", C_), "left"), left, atol=1e-12)
        np.testing.assert_allclose(m.at_lengths(("O4", C_), ("A", B_), "left"), right, atol=1e-12)
        np.testing.assert_allclose(m.at_lengths(("A", B_), ("O4", C_), "right"), right, atol=1e-12)


@pytest.mark.parametrize("offset", [0.0, 0.04, -0.03])
def test_slider_crank_positions_match_nortons_closed_form(offset):
    """Offset slider-crank (Norton 4.16-4.17): open (slider ahead of the pin) and crossed."""
    a, b = 0.15, 0.45
    for th2 in ANGLES:
        m = kf.Mechanism("slider-crank from lengths")
        m.ground("O", at=(0.0, 0.0))
        m.joint("A", at=m.at_angle("O", a, th2))
        th3 = math.asin((a * math.sin(th2) - offset) / b)
        th3c = math.asin(-(a * math.sin(th2) - offset) / b) + math.pi
        for branch, th in (("open", th3), ("ahead", th3), ("crossed", th3c), ("behind", th3c)):
            B = m.at_length_on_line(("A", b, "rod"), through=(0.0, offset), axis=(1.0, 0.0), branch=branch)
            np.testing.assert_allclose(B, [a * math.cos(th2) + b * math.cos(th), offset], rtol=0, atol=1e-12)


def test_slider_on_an_inclined_line_through_a_joint():
    m = kf.Mechanism("inclined")
    m.ground("O", at=(1.0, 2.0))
    m.joint("A", at=m.at_angle("O", 0.1, 0.7))
    u = np.array([math.cos(1.1), math.sin(1.1)])
    B = np.array(m.at_length_on_line(("A", 0.4), through="O", axis=tuple(3 * u)))
    O, A = np.array([1.0, 2.0]), np.array(m.joints["A"].at)
    assert abs((B - O)[0] * u[1] - (B - O)[1] * u[0]) < 1e-15      # on the line
    assert np.hypot(*(B - A)) == pytest.approx(0.4, rel=1e-14)      # at the rod's length
    assert (B - A) @ u > 0                                           # ahead


def test_builders_and_reference_agree():
    """The shipped four-bar's open (upper) branch is at_lengths' "open"; a linkage built from
    lengths states them without a warning and runs."""
    m = _frame(crank=0.4)
    B = m.at_lengths(("A", B_), ("O4", C_), "open")
    m.joint("B", at=B)
    with warnings.catch_warnings():
        warnings.simplefilter("error", LengthWarning)
        m.link("crank", "O2", "A", rigid=True, length=A_)
        m.link("coupler", "A", "B", rigid=True, mass=0.1, length=B_)
        m.link("rocker", "O4", "B", rigid=True, mass=0.1, length=C_)
    m.drive("crank", speed=10.0)
    mo = kf.kinematics(m, 24)
    r = mo.r[:, mo.joint_names.index("B")] - mo.r[:, mo.joint_names.index("A")]
    np.testing.assert_allclose(np.hypot(*r.T), B_, rtol=1e-12)
    assert mechanisms.build("four_bar", crank_angle=0.4).joints["B"].at == pytest.approx(B, abs=1e-15)
    assert B[1] > 0.0  # the upper point


def test_errors_name_the_joints_and_lengths():
    m = _frame(crank=0.0)   # |A-O4| = 0.146 m
    with pytest.raises(kf.InputError, match=r"coupler 0\.05 m \+ rocker 0\.06 m = 0\.11 m < distance "
                                            r"\|A-O4\| = 0\.146 m"):
        m.at_lengths(("A", 0.05, "coupler"), ("O4", 0.06, "rocker"))
    with pytest.raises(kf.InputError, match=r"coupler 0\.5 m - rocker 0\.06 m = 0\.44 m > distance \|A-O4\| "
                                            r"= 0\.146 m; one circle lies inside the other"):
        m.at_lengths(("A", 0.5, "coupler"), ("O4", 0.06, "rocker"))
    with pytest.raises(kf.InputError, match=r"0\.05 m from 'A' \+ 0\.06 m from 'O4' = 0\.11 m < distance"):
        m.at_lengths(("A", 0.05), ("O4", 0.06))
    with pytest.raises(kf.InputError, match="joints 'O2' and 'O2' coincide"):
        m.at_lengths(("O2", 0.05), ("O2", 0.06), "left")
    with pytest.raises(kf.InputError, match="branch 'open' is a four-bar circuit.*2 are ground joints"):
        m.at_lengths(("O2", 0.2), ("O4", 0.2))
    with pytest.raises(kf.InputError, match="branch must be one of 'open', 'crossed', 'left', 'right'"):
        m.at_lengths(("A", 0.2), ("O4", 0.2), branch="up")
    with pytest.raises(kf.InputError, match="unknown joint 'Z'"):
        m.at_lengths(("Z", 0.2), ("O4", 0.2))
    with pytest.raises(kf.InputError, match="length from 'A' must be > 0"):
        m.at_lengths(("A", -0.2), ("O4", 0.2))
    with pytest.raises(kf.InputError, match=r"\(joint, length\) or \(joint, length, name\)"):
        m.at_lengths("A", ("O4", 0.2))
    with pytest.raises(kf.InputError, match=r"rod 0\.1 m from 'A' cannot reach the slider's line, which is "
                                            r"0\.3 m from 'A'"):
        m.at_length_on_line(("A", 0.1, "rod"), through=(0.0, 0.3))
    # a toggle (tangent circles) still assembles, on the line A-O4
    d = math.hypot(*(np.array(m.joints["O4"].at) - m.joints["A"].at))
    np.testing.assert_allclose(m.at_lengths(("A", 0.05), ("O4", d - 0.05)), [A_ + 0.05, 0.0], atol=1e-15)


def test_stated_length_warns_when_the_coordinates_differ(caplog):
    m = kf.Mechanism("check")
    m.ground("O", at=(0.0, 0.0))
    m.joint("A", at=(0.3, 0.4))                                      # 0.5 m from O
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m.link("ok", "O", "A", rigid=True, length=0.5 * (1 + 9e-7))  # within 1e-6: silent
    m.joint("B", at=(0.3, 0.0))
    with caplog.at_level(logging.WARNING, logger="kedfem.model.mechanism"):
        with pytest.warns(LengthWarning, match=r"link 'rod': joints 'A' \(0\.3, 0\.4\) and 'B' \(0\.3, 0\.0\) are "
                                               r"0\.4 m apart, not the stated length 0\.41 m \(relative "
                                               r"difference 0\.024\)") as rec:
            m.link("rod", "A", "B", rigid=True, length=0.41)
    assert rec[0].filename == __file__                               # points at the caller's line
    assert any("stated length 0.41 m" in r.getMessage() for r in caplog.records)
    assert m.links["rod"].length == pytest.approx(0.4)               # the coordinates are used
    with pytest.warns(LengthWarning, match="relative difference 2e-06"):
        m.joint("C", at=(0.0, 1.0))
        m.link("c", "O", "C", rigid=True, length=1.0 + 2e-6)
    with pytest.raises(kf.InputError, match="link 'd': length must be > 0"):
        m.link("d", "O", "B", rigid=True, length=0.0)
    assert issubclass(LengthWarning, UserWarning)
