"""Sliding pairs between moving members: kinematics against closed forms coded here (issue 15).

The closed forms are the vector-loop analyses of Norton (Design of Machinery, sections 4.7
and 6.7, the inverted slider-crank) written independently of kedfem's loop solver: the
block's position on its member, the member's angle, and their first and second derivatives
by hand differentiation.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

import kedfem as kf
from mechanisms import inverted_slider_crank, whitworth


def _cross(a, b):
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


def _slotted_lever(A, Ad, Add, pivot):
    """Angle, rate and acceleration of the line pivot -> A, and the distance |A - pivot| with its rates."""
    rho = A - pivot
    s = np.hypot(rho[:, 0], rho[:, 1])
    sd = np.einsum("nd,nd->n", rho, Ad) / s
    th = np.arctan2(rho[:, 1], rho[:, 0])
    thd = _cross(rho, Ad) / s**2
    sdd = (np.einsum("nd,nd->n", Ad, Ad) + np.einsum("nd,nd->n", rho, Add)) / s - sd**2 / s
    thdd = _cross(rho, Add) / s**2 - 2 * sd * thd / s
    return (th, thd, thdd), (s, sd, sdd)


def _crank_pin(mo, centre, r):
    th, w = mo.crank_angle, mo.angular_velocity("crank")
    e = np.stack([np.cos(th), np.sin(th)], 1)
    return centre + r * e, r * w[:, None] * e @ np.array([[0.0, 1.0], [-1.0, 0.0]]), -r * (w**2)[:, None] * e


def _angle_error(a, b):
    return np.max(np.abs(np.angle(np.exp(1j * (a - b)))))


def test_whitworth_matches_the_closed_form():
    p = dict(crank=0.10, offset=0.05, lever=0.30, link=0.45, speed=2 * math.pi * 3)
    m = whitworth.build(**p, crank_angle=0.3)
    mo = kf.kinematics(m, 97)
    A, Ad, Add = _crank_pin(mo, np.array([0.0, p["offset"]]), p["crank"])
    (th4, w4, a4), (s, sd, sdd) = _slotted_lever(A, Ad, Add, np.zeros(2))
    assert _angle_error(mo.angle("lever"), th4) < 1e-12
    assert np.max(np.abs(mo.angular_velocity("lever") - w4)) < 1e-10 * np.max(np.abs(w4))
    assert np.max(np.abs(mo.angular_acceleration("lever") - a4)) < 1e-10 * np.max(np.abs(a4))
    k = mo.slider_names.index("A")
    assert np.max(np.abs(mo.s[:, k] - (s - s[0]))) < 1e-12
    assert np.max(np.abs(mo.sd[:, k] - sd)) < 1e-10 * np.max(np.abs(sd))
    assert np.max(np.abs(mo.sdd[:, k] - sdd)) < 1e-10 * np.max(np.abs(sdd))
    # the ram: C on the lever, D on the line y = 0 at |CD| = link
    L4, L5 = p["lever"], p["link"]
    c = np.stack([np.cos(th4), np.sin(th4)], 1)
    C, Cd = L4 * c, L4 * w4[:, None] * c[:, ::-1] * [-1, 1]
    Cdd = L4 * (a4[:, None] * c[:, ::-1] * [-1, 1] - (w4**2)[:, None] * c)
    h = -C[:, 1]
    q = np.sqrt(L5**2 - h**2)
    xd = C[:, 0] + q
    vd = Cd[:, 0] + h * Cd[:, 1] / q
    qd = h * Cd[:, 1] / q
    ad = Cdd[:, 0] + (-Cd[:, 1] * Cd[:, 1] + h * Cdd[:, 1]) / q - h * Cd[:, 1] * qd / q**2
    assert np.max(np.abs(mo.position("D")[:, 0] - xd)) < 1e-12
    assert np.max(np.abs(mo.velocity("D")[:, 0] - vd)) < 1e-10 * np.max(np.abs(vd))
    assert np.max(np.abs(mo.acceleration("D")[:, 0] - ad)) < 1e-10 * np.max(np.abs(ad))
    assert np.max(np.abs(mo.position("D")[:, 1])) < 1e-14


def test_whitworth_time_ratio():
    """The ram stops where the lever is horizontal: time ratio (pi + 2 asin(d/r)) / (pi - 2 asin(d/r))."""
    r, d = 0.10, 0.05
    m = whitworth.build(crank=r, offset=d, speed=1.0, crank_angle=math.pi / 2)

    def ram_speed(angle):
        return kf.kinematics_at(m, angle).velocity("D")[0, 0]

    # the two dead centres, bracketed around the closed-form crank angles
    lo = brentq(ram_speed, -0.7, -0.3, xtol=1e-15, rtol=1e-15)       # -asin(d/r) = -0.5236
    hi = brentq(ram_speed, math.pi, math.pi + 0.7, xtol=1e-15, rtol=1e-15)
    assert abs(lo - (-math.asin(d / r))) < 1e-10
    assert abs(hi - (math.pi + math.asin(d / r))) < 1e-10
    ratio = (hi - lo) / (2 * math.pi - (hi - lo))  # the slow arc passes the crank's top (pin far from O4)
    closed = (math.pi + 2 * math.asin(d / r)) / (math.pi - 2 * math.asin(d / r))
    assert abs(ratio - closed) < 1e-10 * closed
    st = kf.stroke(m, "D")
    assert st.length == pytest.approx(2 * 0.30, rel=1e-12)  # the lever's tip C swings 0.30 m each side
    assert st.forward_time + st.return_time == pytest.approx(m.period, rel=1e-14)
    assert kf.stroke(m, "D").time_ratio == pytest.approx(closed, rel=1e-10)


@pytest.mark.parametrize("cylinder", [False, True])
def test_inverted_slider_crank_matches_the_closed_form(cylinder):
    p = dict(crank=0.08, ground=0.40, rod=0.25, barrel=0.55)
    m = inverted_slider_crank.build(**p, cylinder=cylinder, crank_angle=1.1, speed=7.0)
    mo = kf.kinematics(m, 61)
    A, Ad, Add = _crank_pin(mo, np.zeros(2), p["crank"])
    (th4, w4, a4), (dist, dd, ddd) = _slotted_lever(A, Ad, Add, np.array([p["ground"], 0.0]))
    # Norton's inverted slider-crank: the rocker's angle is that of O4 -> A (link 4 through A)
    assert _angle_error(mo.angle("barrel"), th4) < 1e-12
    assert np.max(np.abs(mo.angular_velocity("barrel") - w4)) < 1e-10 * np.max(np.abs(w4))
    assert np.max(np.abs(mo.angular_acceleration("barrel") - a4)) < 1e-10 * np.max(np.abs(a4))
    block = "P" if cylinder else "A"
    k = mo.slider_names.index(block)
    assert np.max(np.abs(mo.sd[:, k] - dd)) < 1e-10 * np.max(np.abs(dd))
    assert np.max(np.abs(mo.sdd[:, k] - ddd)) < 1e-10 * np.max(np.abs(ddd))
    if cylinder:  # the rod turns with the barrel; the piston at |A - O4| - rod along it
        assert _angle_error(mo.angle("rod"), th4) < 1e-12
        assert np.max(np.abs(mo.angular_acceleration("rod") - a4)) < 1e-10 * np.max(np.abs(a4))
        u = np.stack([np.cos(th4), np.sin(th4)], 1)
        P = np.array([p["ground"], 0.0]) + (dist - p["rod"])[:, None] * u
        assert np.max(np.abs(mo.position("P") - P)) < 1e-12


def test_block_running_off_its_link_is_named():
    """The block reaches 0.15 m from O4; on a 0.14 m lever it runs off, and the error says where."""
    steel, sec = kf.Material(E=2e11, rho=7850), kf.Section.rectangle(0.02, 0.02)
    m = kf.Mechanism("too-short")
    m.ground("O2", at=(0.0, 0.05))
    m.ground("O4", at=(0.0, 0.0))
    m.slider("A", at=(0.10, 0.05), on="lever")
    u = np.array([0.10, 0.05]) / math.hypot(0.10, 0.05)
    m.joint("C", at=tuple(0.14 * u))
    m.link("crank", "O2", "A", material=steel, section=sec, elements=1)
    m.link("lever", "O4", "C", material=steel, section=sec, elements=2)
    m.drive("crank", speed=1.0)
    with pytest.raises(kf.KinematicsError, match=r"slider 'A' runs off link 'lever' at crank angle .* outside "
                                                 r"the link \(0 to 0.14 m\)"):
        kf.kinematics(m, 36)
    with pytest.raises(kf.InputError, match="whitworth: lever=0.12"):
        whitworth.build(lever=0.12)


def test_input_errors_name_the_problem():
    steel, sec = kf.Material(E=2e11, rho=7850), kf.Section.rectangle(0.01, 0.02)

    def base():
        m = kf.Mechanism("m")
        m.ground("O2", at=(0.0, 0.05))
        m.ground("O4", at=(0.0, 0.0))
        m.joint("C", at=(0.0, 0.3))
        m.link("lever", "O4", "C", material=steel, section=sec, elements=4)
        return m

    m = base()
    m.slider("A", at=(0.0, 0.15), on="levr")
    m.link("crank", "O2", "A", material=steel, section=sec)
    with pytest.raises(kf.InputError, match="on='levr' is not a link or body"):
        m.validate()
    m = base()
    m.slider("A", at=(0.01, 0.15), on="lever")
    m.link("crank", "O2", "A", material=steel, section=sec)
    with pytest.raises(kf.InputError, match="on flexible link 'lever' the block's line must be the link's axis"):
        m.validate()
    m = base()
    m.slider("A", at=(0.0, 0.35), on="lever")
    m.link("crank", "O2", "A", material=steel, section=sec)
    with pytest.raises(kf.InputError, match="outside the link"):
        m.validate()
    m = base()
    m.slider("A", at=(0.0, 0.15), on="lever")
    m.link("crank", "O2", "A", rigid=True, mass=1.0)
    m.drive("crank", speed=1.0)
    with pytest.raises(kf.InputError, match="rigid member.*'crank' on slider 'A': it is also pinned to the frame"):
        kf.FEModel(m)
    with pytest.raises(kf.InputError, match="rotation must be 'free' or 'locked'"):
        kf.Mechanism("x").slider("A", at=(0, 0), on="lever", rotation="fixed")
    with pytest.raises(kf.InputError, match="applies to a slider on a member"):
        kf.Mechanism("x").slider("A", at=(0, 0), slide="locked")
