"""Rigid-body kinematics against closed-form position, velocity and acceleration equations."""

import math

import numpy as np
import pytest

import kedfem as kf
import mechanisms


def slider_crank_closed_form(theta, r, l, w):
    """x_B, its derivatives and the rod angle for a centred slider-crank (hand derived)."""
    u, du, ddu = r * np.sin(theta), r * np.cos(theta), -r * np.sin(theta)
    s = np.sqrt(l**2 - u**2)
    ds = -u * du / s
    x = r * np.cos(theta) + s
    dx = -r * np.sin(theta) - u * du / s
    ddx = -r * np.cos(theta) - ((du**2 + u * ddu) / s + (u * du) ** 2 / s**3)
    phi = -np.arcsin(u / l)
    dphi = -du / s
    ddphi = -(ddu * s - du * ds) / s**2
    return x, w * dx, w**2 * ddx, phi, w * dphi, w**2 * ddphi


def test_slider_crank_against_closed_form():
    m = mechanisms.build("slider_crank")
    mo = kf.kinematics(m, steps=360)
    x, v, a, phi, dphi, ddphi = slider_crank_closed_form(mo.crank_angle, 0.15, 0.30, 150.0)
    assert mo.t.shape == (360,) and mo.crank_angle[0] == 0.0
    np.testing.assert_allclose(mo.position("B")[:, 0], x, rtol=0, atol=1e-10)
    np.testing.assert_allclose(mo.position("B")[:, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(mo.velocity("B")[:, 0], v, rtol=0, atol=1e-9 * np.max(np.abs(v)))
    np.testing.assert_allclose(mo.acceleration("B")[:, 0], a, rtol=0, atol=1e-9 * np.max(np.abs(a)))
    np.testing.assert_allclose(mo.angle("rod"), phi, atol=1e-10)
    np.testing.assert_allclose(mo.angular_velocity("rod"), dphi, atol=1e-9 * np.max(np.abs(dphi)))
    np.testing.assert_allclose(mo.angular_acceleration("rod"), ddphi, atol=1e-9 * np.max(np.abs(ddphi)))
    np.testing.assert_allclose(mo.angular_velocity("crank"), 150.0)
    assert mo.residual < 1e-12
    assert mo.t[1] == pytest.approx(2 * math.pi / 150.0 / 360)


def four_bar_closed_form(th2, a, b, c, d, w2):
    """Open-branch positions (circle intersection) and Norton's velocity/acceleration formulas."""
    A = np.stack([a * np.cos(th2), a * np.sin(th2)], -1)
    O4 = np.array([d, 0.0])
    dv = O4 - A
    dist = np.linalg.norm(dv, axis=1)
    x = (b**2 - c**2 + dist**2) / (2 * dist)
    h = np.sqrt(b**2 - x**2)
    n = np.stack([-dv[:, 1], dv[:, 0]], 1) / dist[:, None]
    B = A + x[:, None] * dv / dist[:, None] + h[:, None] * n
    th3 = np.arctan2(B[:, 1] - A[:, 1], B[:, 0] - A[:, 0])
    th4 = np.arctan2(B[:, 1], B[:, 0] - d)
    w3 = a * w2 * np.sin(th4 - th2) / (b * np.sin(th3 - th4))
    w4 = a * w2 * np.sin(th2 - th3) / (c * np.sin(th4 - th3))
    al2 = 0.0
    AA, BB = c * np.sin(th4), b * np.sin(th3)
    CC = (a * al2 * np.sin(th2) + a * w2**2 * np.cos(th2) + b * w3**2 * np.cos(th3)
          - c * w4**2 * np.cos(th4))
    DD, EE = c * np.cos(th4), b * np.cos(th3)
    FF = (a * al2 * np.cos(th2) - a * w2**2 * np.sin(th2) - b * w3**2 * np.sin(th3)
          + c * w4**2 * np.sin(th4))
    al3 = (CC * DD - AA * FF) / (AA * EE - BB * DD)
    al4 = (CC * EE - BB * FF) / (AA * EE - BB * DD)
    return B, th3, th4, w3, w4, al3, al4


def test_four_bar_against_closed_form():
    w2 = 2 * math.pi * 200 / 60
    m = mechanisms.build("four_bar", speed=w2)
    mo = kf.kinematics(m, steps=360)
    B, th3, th4, w3, w4, al3, al4 = four_bar_closed_form(mo.crank_angle, 0.108, 0.2794, 0.2705, 0.254, w2)
    np.testing.assert_allclose(mo.position("B"), B, atol=1e-10)
    np.testing.assert_allclose(np.unwrap(mo.angle("coupler")), np.unwrap(th3), atol=1e-10)
    np.testing.assert_allclose(np.unwrap(mo.angle("follower")), np.unwrap(th4), atol=1e-10)
    for got, exp in ((mo.angular_velocity("coupler"), w3), (mo.angular_velocity("follower"), w4),
                     (mo.angular_acceleration("coupler"), al3), (mo.angular_acceleration("follower"), al4)):
        np.testing.assert_allclose(got, exp, rtol=0, atol=1e-9 * np.max(np.abs(exp)))
    # velocity of B from the follower rotation
    vB = w4[:, None] * np.stack([-(B[:, 1]), B[:, 0] - 0.254], 1)
    np.testing.assert_allclose(mo.velocity("B"), vB, atol=1e-9 * np.max(np.abs(vB)))
    assert mo.residual < 1e-12


def test_reference_configuration_and_branch():
    m = mechanisms.build("four_bar", crank_angle=1.0)
    mo = kf.kinematics(m, steps=90)
    assert mo.crank_angle[0] == pytest.approx(1.0)
    np.testing.assert_allclose(mo.position("B")[0], m.joints["B"].at, atol=1e-12)


def test_clockwise_drive_reverses_the_cycle():
    m1 = mechanisms.build("slider_crank", speed=150.0)
    m2 = mechanisms.build("slider_crank", speed=-150.0)
    a = kf.kinematics(m1, 36)
    b = kf.kinematics(m2, 36)
    np.testing.assert_allclose(b.position("B")[1:], a.position("B")[:0:-1], atol=1e-12)


def non_grashof():
    m = kf.Mechanism("non-grashof")
    m.ground("O2", at=(0, 0))
    m.ground("O4", at=(0.3, 0))
    m.joint("A", at=(0.25, 0))
    m.joint("B", at=(0.275, math.sqrt(0.04 - 0.025**2)))
    m.link("crank", "O2", "A", rigid=True)
    m.link("coupler", "A", "B", rigid=True)
    m.link("follower", "O4", "B", rigid=True)
    m.drive("crank", speed=10.0)
    return m


def test_non_grashof_crank_is_rejected_with_loop_and_angle():
    with pytest.raises(kf.KinematicsError) as exc:
        kf.kinematics(non_grashof(), steps=360)
    msg = str(exc.value)
    # the crank can turn until |A O4| = coupler + follower: cos(theta) = -0.05
    limit = math.degrees(math.acos(-0.05))
    angle = float(msg.split("crank angle ")[1].split(" deg")[0])
    assert abs(angle - limit) < 1.0
    assert "loop" in msg and "O4" in msg and "B" in msg


def test_mobility_mismatch_is_rejected():
    m = non_grashof()
    m.drive("follower", speed=10.0)
    with pytest.raises(kf.MobilityError, match="mobility 1.*2 drive"):
        kf.kinematics(m, steps=36)
    # a five-bar (mobility 2) with one drive
    m5 = kf.Mechanism("five-bar")
    m5.ground("O1", at=(0, 0))
    m5.ground("O2", at=(0.4, 0))
    m5.joint("A", at=(0.1, 0.0))
    m5.joint("C", at=(0.2, 0.25))
    m5.joint("B", at=(0.35, 0.1))
    m5.link("l1", "O1", "A", rigid=True)
    m5.link("l2", "A", "C", rigid=True)
    m5.link("l3", "C", "B", rigid=True)
    m5.link("l4", "B", "O2", rigid=True)
    m5.drive("l1", speed=1.0)
    with pytest.raises(kf.MobilityError, match="mobility 2"):
        kf.kinematics(m5, steps=36)


def test_bad_steps_and_structure_without_drive():
    with pytest.raises(kf.InputError, match="steps"):
        kf.kinematics(mechanisms.build("slider_crank"), steps=2)
    m = kf.Mechanism("cantilever")
    m.ground("O", at=(0, 0), clamped=True)
    m.joint("T", at=(1, 0))
    m.link("b", "O", "T", material=kf.Material(2e11, 7800), section=kf.Section.circle(0.01))
    with pytest.raises(kf.InputError, match="no drive"):
        kf.kinematics(m, steps=36)
    st = kf.static_motion(m)
    assert st.n == 1 and np.all(st.v == 0)


def test_kinematics_at_matches_cycle():
    m = mechanisms.build("four_bar")
    mo = kf.kinematics(m, steps=8)
    one = kf.kinematics_at(m, mo.crank_angle[3])
    np.testing.assert_allclose(one.position("B")[0], mo.position("B")[3], atol=1e-12)
    np.testing.assert_allclose(one.angular_acceleration("coupler")[0],
                               mo.angular_acceleration("coupler")[3], rtol=1e-10)


def test_point_on_member_moves_rigidly():
    m = mechanisms.build("slider_crank")
    mo = kf.kinematics(m, steps=36)
    r, v, a = mo.point("rod", "A", np.array([0.15, 0.0]))  # rod midpoint at reference
    np.testing.assert_allclose(r, 0.5 * (mo.position("A") + mo.position("B")), atol=1e-12)
    np.testing.assert_allclose(v, 0.5 * (mo.velocity("A") + mo.velocity("B")), atol=1e-9)
    np.testing.assert_allclose(a, 0.5 * (mo.acceleration("A") + mo.acceleration("B")), atol=1e-7)


@pytest.mark.parametrize("name", ["four_bar", "six_bar", "whitworth", "inverted_slider_crank"])
def test_strided_coarse_march_equals_the_full_march(name, monkeypatch):
    """The coarse grid marched through every third instant, the rest solved together from the
    Hermite interpolant, is the continuation through every instant to round-off; where the
    instants between do not settle near the interpolant (a stride of 12 on the Whitworth, whose
    block swings the lever by more than the branch-jump guard allows) the full march is used."""
    from kedfem.motion import kinematics as kin
    m = mechanisms.build(name)
    strided = kin.Cycle(m)
    monkeypatch.setattr(kin.Cycle, "STRIDE", 1)
    full = kin.Cycle(m)
    scale = np.abs(full.ydc).max()
    assert np.abs(strided.yc - full.yc).max() < 1e-11
    assert np.abs(strided.ydc - full.ydc).max() < 1e-11 * scale
    monkeypatch.setattr(kin.Cycle, "STRIDE", 12)
    calls = []
    real = kin._march
    monkeypatch.setattr(kin, "_march", lambda model, tt, *a, **k: calls.append(tt.size) or real(model, tt, *a, **k))
    wide = kin.Cycle(m)
    assert np.abs(wide.yc - full.yc).max() < 1e-11
    if name == "whitworth":
        assert calls == [3, 36]  # the marched instants, then the fallback through all of them


def _crank_rocker(a, b, c, d, crank_deg):
    """A rigid crank-rocker (crank a, coupler b, rocker c, ground d) drawn at a crank angle."""
    th0 = math.radians(crank_deg)
    A = np.array([a * math.cos(th0), a * math.sin(th0)])
    O4 = np.array([d, 0.0])
    r = np.linalg.norm(O4 - A)
    x = (b * b - c * c + r * r) / (2 * r)
    e = (O4 - A) / r
    B = A + x * e + math.sqrt(b * b - x * x) * np.array([-e[1], e[0]])
    m = kf.Mechanism("near toggle")
    m.ground("O2", at=(0, 0))
    m.ground("O4", at=(d, 0))
    m.joint("A", at=tuple(A))
    m.joint("B", at=tuple(B))
    m.link("crank", "O2", "A", rigid=True)
    m.link("coupler", "A", "B", rigid=True)
    m.link("follower", "O4", "B", rigid=True)
    m.drive("crank", speed=10.0)
    return m


@pytest.mark.parametrize("lengths", [(0.1, 0.3, 0.101, 0.3), (0.1, 0.25, 0.1503, 0.3)])
def test_the_strided_march_keeps_the_branch_near_toggles(lengths, monkeypatch):
    """Near-change-point crank-rockers (a review's cases): longer continuation steps jumped
    branch at one near-toggle and back at the other (the cycle closed, the motion between was
    the other branch's: the follower at half a cycle 6.509 rad instead of 0.226), or failed to
    close. The strided grid must keep the Jacobian's sign and close, else the full march runs:
    the motion is the full march's."""
    from kedfem.motion import kinematics as kin
    m = _crank_rocker(*lengths, 10.0)
    t = np.linspace(0.0, m.period, 73)
    strided = kin.Cycle(m).at(t)
    monkeypatch.setattr(kin.Cycle, "STRIDE", 1)
    full = kin.Cycle(m).at(t)
    assert np.abs(strided.theta - full.theta).max() < 1e-10


@pytest.mark.parametrize("name", ["four_bar", "inverted_slider_crank", "whitworth"])
def test_a_cycle_at_another_speed_is_that_speed_own(name, monkeypatch):
    """``Cycle.at_speed`` (a continuation in speed follows the assembly branch once) against a
    cycle made at that speed: the same positions at each phase to the loop tolerance, velocities
    and accelerations scaled by the ratio and its square, as a cycle of its own gives them."""
    from kedfem.motion import kinematics
    from kedfem.motion.kinematics import Cycle
    m = mechanisms.build(name)
    fast = m.with_speed(2.7 * m.drives[0].speed)
    base = Cycle(m)
    own, moved = Cycle(fast), base.at_speed(fast)
    t = np.random.default_rng(3).random(40) * own.period

    def no_march(*args, **kw):  # a wrong reuse (rates not scaled: the review's) fell back to it
        raise AssertionError("the batched Newton from the coarse positions did not settle")

    monkeypatch.setattr(kinematics, "_march", no_march)
    a, b = own.at(t), moved.at(t)
    for x, y, scale in ((a.r, b.r, 1.0), (a.theta, b.theta, 1.0), (a.v, b.v, 2.7), (a.omega, b.omega, 2.7),
                        (a.a, b.a, 2.7**2), (a.alpha, b.alpha, 2.7**2), (a.s, b.s, 1.0)):
        assert np.max(np.abs(x - y), initial=0.0) <= 1e-10 * scale * max(np.max(np.abs(x), initial=0.0), 1.0)
    assert moved.period == pytest.approx(m.period / 2.7, rel=1e-14)
    with pytest.raises(kf.InputError, match="at_speed"):
        base.at_speed(m.with_speed(-m.drives[0].speed))  # the other way round: the phases run backwards
