"""Process loads (kf.Profile): the table, the instants of its kinks, and machines that work
against them, checked against hand analyses.

The press (examples/press.py) and the shaper (the Whitworth quick-return with a cutting force
on its forward stroke): drive torque and bearing forces of the rigid kinetostatics against a
Newton-Euler analysis written here in numpy, on closed-form positions differentiated by a
five-point stencil (no kedfem kinematics), to 1e-6 of the largest force.
"""

import math
import os
import sys

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from kedfem.fe.effects.loads import load_breaks

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "examples"))
import press  # noqa: E402

G = np.array([0.0, -9.80665])
RIGID = ("inertia", "coupling", "gravity", "loads")


def cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def derivatives(f, t, h):
    """Value, first and second time derivative of ``f(t)`` (arrays) by five-point stencils."""
    f2, f1, f0, g1, g2 = (f(t + k * h) for k in (2, 1, 0, -1, -2))
    d1 = (-f2 + 8 * f1 - 8 * g1 + g2) / (12 * h)
    d2 = (-f2 + 16 * f1 - 30 * f0 + 16 * g1 - g2) / (12 * h * h)
    return f0, d1, d2


def S(u):
    """The S-curve of a smooth profile's segment, of the fraction u in [0, 1]."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10 - 15 * u + 6 * u * u)


def stroke_weight(v, stroke):
    """The share of a one-stroke load: 1 on its stroke, 0 on the other, 1/2 at a dead centre."""
    return 0.5 * (1 + np.sign(v)) if stroke == "forward" else 0.5 * (1 - np.sign(v))


# --------------------------------------------------------------------------- the table
def test_profile_table_steps_kinks_and_periodic_angles():
    p = kf.Profile.position("B", (0, -2), [1.0, 2.0, 2.0, 3.0], [0.0, 1.0, 3.0, 3.0])
    assert p.axis == (0.0, -1.0)
    q = np.array([0.0, 1.5, 1.999, 2.0, 2.5, 9.0])
    assert np.allclose(p.table(q), [0.0, 0.5, 0.999, 3.0, 3.0, 3.0])
    assert np.allclose(p.levels, [1.0, 2.0])  # the kink at 1, the step at 2 (flat on from it)
    a = kf.Profile.crank_angle([90, 270], [1.0, 3.0])  # periodic: back down from 270 to 90 + 360
    assert np.allclose(a.table(np.array([90, 180, 270, 360, 450, -90])), [1, 2, 3, 2, 1, 3])
    assert np.allclose(a.levels, [90, 270])


@pytest.mark.parametrize("bad, says", [
    (lambda: kf.Profile.position("B", (0, 0), [0, 1], [0, 1]), "axis"),
    (lambda: kf.Profile.position("B", (1, 0), [1, 0], [0, 1]), "must not decrease"),
    (lambda: kf.Profile.position("B", (1, 0), [0, 0, 0], [0, 1, 2]), "three times"),
    (lambda: kf.Profile.position("B", (1, 0), [0, 1], [0, 1, 2]), "as many factors"),
    (lambda: kf.Profile.crank_angle([0, 400], [0, 1]), "0 .. 360"),
    (lambda: kf.Profile.velocity("B", (1, 0), [0, 1], [0, 1]).__class__("velocity", (0, 1), (0, 1), "B",
                                                                       (1, 0), "forward"), "stroke="),
    (lambda: kf.Profile.position("B", (1, 0), [0, float("nan")], [0, 1]), "not finite"),
])
def test_profile_errors_name_the_problem(bad, says):
    with pytest.raises(kf.InputError, match=says):
        bad()


def test_a_profile_on_an_unknown_joint_is_refused_by_the_load():
    m = press.build()
    with pytest.raises(kf.InputError, match="unknown joint 'Q'"):
        m.load("x", "B", (0, 1), profile=kf.Profile.position("Q", (1, 0), [0, 1], [0, 1]))
    with pytest.raises(kf.InputError, match="kf.Profile"):
        m.load("y", "B", (0, 1), profile=[0, 1])


def linear_press():
    """The press with straight ramps (kinks where the tool meets and leaves the part)."""
    m = press.build()
    m.loads.clear()
    down, bdc = (0.0, -1.0), 0.3
    m.load("forming", "B", (0.0, 40e3), profile=kf.Profile.position("B", down, [bdc - 0.01, bdc], [0, 1],
                                                                      stroke="forward"))
    m.load("springback", "B", (0.0, 40e3), profile=kf.Profile.position("B", down, [bdc - 0.002, bdc], [0, 1],
                                                                         stroke="return"))
    return m


def test_breaks_are_where_the_motion_reaches_the_table_kinks():
    """The press with straight ramps: contact on the down-stroke, the bottom dead centre, the end
    of the springback on the way up, each at the instant the closed-form slider-crank gives; with
    S-curves (the example's) only the dead centre, where each stroke's load starts or stops."""
    assert np.allclose(load_breaks(press.build(), kf.Cycle(press.build()), 1.0), [0.5], atol=1e-12)
    m = linear_press()
    r, l, w = 0.05, 0.25, 2 * math.pi
    bdc = r + l
    t = load_breaks(m, kf.Cycle(m), m.period)

    def depth(tt):  # the ram's depth below O, crank drawn up
        th = math.pi / 2 + w * tt
        return -(r * np.sin(th) - np.sqrt(l**2 - (r * np.cos(th)) ** 2))

    assert t.size == 3
    assert np.allclose(depth(t), [bdc - 0.01, bdc, bdc - 0.002], atol=1e-12)
    assert np.isclose(t[1], m.period / 2, atol=1e-12)


# --------------------------------------------------------------------------- the press
def press_by_hand(t, r=0.05, l=0.25, w=2 * math.pi, m_c=3.0, m_B=20.0, rhoA=7850.0 * 0.03 * 0.03,
                  F=40e3, travel=0.01, springback=0.002):
    """Drive torque and pin forces of the rigid press, Newton-Euler, per instant."""
    m_r = rhoA * l
    J_c, J_r = m_c * r**2 / 12, m_r * l**2 / 12

    def A(tt):
        th = math.pi / 2 + w * tt
        return np.stack([r * np.cos(th), r * np.sin(th)], -1)

    def B(tt):
        th = math.pi / 2 + w * tt
        return np.stack([np.zeros_like(tt), r * np.sin(th) - np.sqrt(l**2 - (r * np.cos(th)) ** 2)], -1)

    h = 1e-3
    (a_, va, aa), (b_, vb, ab) = derivatives(A, t, h), derivatives(B, t, h)
    d, dd = b_ - a_, ab - aa
    alpha_r = cross(d, dd) / l**2
    depth, vdepth = -b_[:, 1], -vb[:, 1]
    bdc = r + l
    share = (S((depth - (bdc - travel)) / travel) * stroke_weight(vdepth, "forward")
             + S((depth - (bdc - springback)) / springback) * stroke_weight(vdepth, "return"))
    load = share[:, None] * np.array([0.0, F])
    out = []
    for k in range(t.size):
        # unknowns: P_Oc (2), P_Ac (2), P_Br (2), N, T  (forces on the bodies; pin A massless)
        E, rhs = np.zeros((8, 8)), np.zeros(8)
        # pin B with the ram: m_B a_B = -P_Br + (N, 0) + load + m_B g
        E[0:2, 4:6] = -np.eye(2)
        E[0, 6] = 1.0
        rhs[0:2] = m_B * ab[k] - load[k] - m_B * G
        # rod: m_r a_G = -P_Ac + P_Br + m_r g;  J_r alpha = (A - G) x (-P_Ac) + (B - G) x P_Br
        gr = 0.5 * (a_[k] + b_[k])
        E[2:4, 2:4] = -np.eye(2)
        E[2:4, 4:6] = np.eye(2)
        rhs[2:4] = m_r * 0.5 * (aa[k] + ab[k]) - m_r * G
        ra, rb = a_[k] - gr, b_[k] - gr
        E[4, 2:4] = [ra[1], -ra[0]]        # (ra x -P) = -(ra_x P_y - ra_y P_x)
        E[4, 4:6] = [-rb[1], rb[0]]
        rhs[4] = J_r * alpha_r[k]
        # crank: m_c a_G = P_Oc + P_Ac + m_c g;  about O: T + A x P_Ac + (A/2) x m_c g = 0
        E[5:7, 0:2] = np.eye(2)
        E[5:7, 2:4] = np.eye(2)
        rhs[5:7] = m_c * 0.5 * aa[k] - m_c * G
        E[7, 2:4] = [-a_[k][1], a_[k][0]]
        E[7, 7] = 1.0
        rhs[7] = -cross(0.5 * a_[k], m_c * G)
        out.append(np.linalg.solve(E, rhs))
    x = np.array(out)
    return dict(T=x[:, 7], P_Oc=x[:, 0:2], P_Ac=x[:, 2:4], P_Br=x[:, 4:6], N=x[:, 6])


def test_press_rigid_kinetostatics_against_a_hand_analysis():
    m = press.build()
    res = kf.solve(kf.Scene(m, effects=RIGID, damping=kf.ModalDamping(0.02), steps=48, estimate=False))
    loads = res.loads()
    hand = press_by_hand(res.t)
    scale = float(np.abs(hand["P_Ac"]).max())
    assert scale > 3e4  # the forming force is there
    checks = [(loads.torque(response="rigid"), hand["T"], "drive torque [N m] / 0.05 m"),
              (loads.force("O", "crank", "rigid"), hand["P_Oc"], "O on crank"),
              (loads.force("O", None, "rigid"), -hand["P_Oc"], "O on frame"),
              (loads.force("A", "crank", "rigid"), hand["P_Ac"], "A on crank"),
              (loads.force("A", "rod", "rigid"), -hand["P_Ac"], "A on rod"),
              (loads.force("B", "rod", "rigid"), hand["P_Br"], "B on rod"),
              (loads.force("B", None, "rigid")[:, 0], -hand["N"], "B on frame (guide)")]
    for got, want, what in checks:
        s = scale * (0.05 if "torque" in what else 1.0)
        err = float(np.max(np.abs(np.asarray(got) - want))) / s
        assert err < 1e-6, (what, err)


# --------------------------------------------------------------------------- the shaper
import shaper  # noqa: E402


def shaper_by_hand(t, F=2000.0, cut_from=0.1, cut_to=0.9, entry=0.02):
    """Drive torque and pin forces of the rigid Whitworth shaper, Newton-Euler, per instant."""
    p = mechanisms.get("whitworth").DEFAULTS
    r, e, L4, l, w, rho = p["crank"], p["offset"], p["lever"], p["link"], p["speed"], p["rho"]
    m_c = rho * p["crank_height"] ** 2 * r
    m_l = rho * p["lever_width"] * p["lever_height"] * L4
    m_k = rho * p["link_width"] * p["link_height"] * l
    m_b, m_D = p["block_mass"], p["ram_mass"]
    J_c, J_l, J_k = m_c * r**2 / 12, m_l * L4**2 / 12, m_k * l**2 / 12
    O2 = np.array([0.0, e])

    def A(tt):
        th = p["crank_angle"] + w * tt
        return np.stack([r * np.cos(th), e + r * np.sin(th)], -1)

    def C(tt):
        a = A(tt)
        return L4 * a / np.linalg.norm(a, axis=-1, keepdims=True)

    def D(tt):
        c = C(tt)
        return np.stack([c[..., 0] + np.sqrt(l**2 - c[..., 1] ** 2), np.zeros_like(tt)], -1)

    h = 1e-4
    (a_, _va, aa), (c_, _vc, ac), (d_, vd, ad) = (derivatives(f, t, h) for f in (A, C, D))
    u = c_ / L4
    n = np.stack([-u[:, 1], u[:, 0]], -1)
    alpha_l = cross(c_, ac) / L4**2          # |C| = L4: C x C'' / L4^2
    dk = d_ - c_
    alpha_k = cross(dk, ad - ac) / l**2
    # the cutting stroke runs along -x (the slow one, counter-clockwise crank), from x = l + L4
    xa, xb = (l + L4) - cut_from * 2 * L4, (l + L4) - cut_to * 2 * L4
    p_ = -d_[:, 0]
    share = (S((p_ + xa) / entry) - S((p_ + xb + entry) / entry)) * stroke_weight(-vd[:, 0], "forward")
    load = share[:, None] * np.array([F, 0.0])
    out = []
    for k in range(t.size):
        # unknowns (forces on the bodies): P_O2c 0:2, T 2, P_Ac 3:5, N 5, P_O4l 6:8, P_Cl 8:10, P_Dk 10:12, R 12
        E, rhs = np.zeros((13, 13)), np.zeros(13)
        gc, gl, gk = 0.5 * (O2 + a_[k]), 0.5 * c_[k], 0.5 * (c_[k] + d_[k])
        # crank: m_c a_G = P_O2c + P_Ac + m_c g;  about O2: T + (A - O2) x P_Ac + (G - O2) x m_c g = 0
        E[0:2, 0:2] = np.eye(2)
        E[0:2, 3:5] = np.eye(2)
        rhs[0:2] = m_c * 0.5 * aa[k] - m_c * G
        ra = a_[k] - O2
        E[2, 2] = 1.0
        E[2, 3:5] = [-ra[1], ra[0]]
        rhs[2] = -cross(gc - O2, m_c * G)
        # pin A with the block: m_b a_A = -P_Ac + N n + m_b g
        E[3:5, 3:5] = -np.eye(2)
        E[3:5, 5] = n[k]
        rhs[3:5] = m_b * aa[k] - m_b * G
        # lever: m_l a_G = P_O4l - N n + P_Cl + m_l g;  J alpha = sum of (x - G) x F
        E[5:7, 6:8] = np.eye(2)
        E[5:7, 5] = -n[k]
        E[5:7, 8:10] = np.eye(2)
        rhs[5:7] = m_l * 0.5 * ac[k] - m_l * G
        r0, r1, r2 = -gl, a_[k] - gl, c_[k] - gl
        E[7, 6:8] = [-r0[1], r0[0]]
        E[7, 5] = -cross(r1, n[k])
        E[7, 8:10] = [-r2[1], r2[0]]
        rhs[7] = J_l * alpha_l[k]
        # link: m_k a_G = -P_Cl + P_Dk + m_k g
        E[8:10, 8:10] = -np.eye(2)
        E[8:10, 10:12] = np.eye(2)
        rhs[8:10] = m_k * 0.5 * (ac[k] + ad[k]) - m_k * G
        s1, s2 = c_[k] - gk, d_[k] - gk
        E[10, 8:10] = [s1[1], -s1[0]]
        E[10, 10:12] = [-s2[1], s2[0]]
        rhs[10] = J_k * alpha_k[k]
        # pin D with the ram: m_D a_D = -P_Dk + (0, R) + load + m_D g
        E[11:13, 10:12] = -np.eye(2)
        E[12, 12] = 1.0
        rhs[11:13] = m_D * ad[k] - load[k] - m_D * G
        out.append(np.linalg.solve(E, rhs))
    x = np.array(out)
    return dict(T=x[:, 2], P_O2c=x[:, 0:2], P_Ac=x[:, 3:5], lever_at_A=-x[:, 5:6] * n, P_O4l=x[:, 6:8],
                P_Cl=x[:, 8:10], P_Dk=x[:, 10:12], R=x[:, 12], share=share)


def test_shaper_rigid_kinetostatics_against_a_hand_analysis():
    m = shaper.build()
    res = kf.solve(kf.Scene(m, effects=RIGID, damping=kf.ModalDamping(0.02), steps=48, estimate=False))
    loads = res.loads()
    hand = shaper_by_hand(res.t)
    assert 0.3 < float(np.mean(hand["share"] > 0.99)) < 0.6  # cutting over most of the slow stroke
    scale = float(max(np.abs(hand[k]).max() for k in ("P_Ac", "P_O4l", "P_Cl", "P_Dk")))
    checks = [(loads.torque(response="rigid"), hand["T"], "drive torque [N m] / 0.1 m"),
              (loads.force("O2", "crank", "rigid"), hand["P_O2c"], "O2 on crank"),
              (loads.force("A", "crank", "rigid"), hand["P_Ac"], "A on crank"),
              (loads.force("A", "lever", "rigid"), hand["lever_at_A"], "A on lever"),
              (loads.force("O4", "lever", "rigid"), hand["P_O4l"], "O4 on lever"),
              (loads.force("C", "lever", "rigid"), hand["P_Cl"], "C on lever"),
              (loads.force("C", "link", "rigid"), -hand["P_Cl"], "C on link"),
              (loads.force("D", "link", "rigid"), hand["P_Dk"], "D on link"),
              (loads.force("D", None, "rigid")[:, 1], -hand["R"], "D on frame (guide)")]
    for got, want, what in checks:
        s = scale * (0.1 if "torque" in what else 1.0)
        err = float(np.max(np.abs(np.asarray(got) - want))) / s
        assert err < 1e-6, (what, err)


# --------------------------------------------------------------------------- scene files
SCENES = os.path.join(os.path.dirname(__file__), "..", "examples", "scenes")


def test_the_shaper_scene_file_is_the_shaper_example():
    scene, _out = kf.load_scene(os.path.join(SCENES, "shaper.toml"))
    ld = scene.mech.loads["cutting"]
    want = shaper.build().loads["cutting"]
    assert ld.joint == want.joint and np.allclose(ld.force, want.force)
    assert ld.profile.stroke == want.profile.stroke and np.allclose(ld.profile.axis, want.profile.axis)
    assert ld.profile.smooth and want.profile.smooth
    assert np.allclose(ld.profile.x, want.profile.x, atol=1e-12) and np.allclose(ld.profile.y, want.profile.y)


@pytest.mark.parametrize("entry, says", [
    ({"name": "c", "joint": "D"}, r"loads\[0\]\.force.*missing"),
    ({"name": "c", "joint": "Q", "force": [1.0, 0.0]}, "unknown joint 'Q'"),
    ({"name": "c", "joint": "D", "force": [1.0]}, r"loads\[0\]\.force.*2 numbers"),
    ({"name": "c", "joint": "D", "force": [1.0, 0.0], "profile": {"of": "position", "x": [0, 1], "y": [0, 1]}},
     "needs the joint"),
    ({"name": "c", "joint": "D", "force": [1.0, 0.0], "profile": {"of": "angle", "x": [0, 1], "y": [0, 1]}},
     "crank_angle"),
    ({"name": "c", "joint": "D", "force": [1.0, 0.0], "profile": {"of": "crank_angle", "x": [0, 90],
                                                                   "y": [0, 1], "spline": True}},
     r"loads\[0\]\.profile\.spline.*unknown key"),
])
def test_scene_file_loads_errors_name_the_key(entry, says):
    data = {"mechanism": {"name": "whitworth"}, "effects": ["inertia", "loads"], "loads": [entry]}
    with pytest.raises(kf.InputError, match=says):
        kf.scene_from_dict(data)


# --------------------------------------------------------------------------- elastic response
def test_press_elastic_response_converges_with_an_honest_estimate():
    """The tolerance-driven solve of the press (kinks where the tool meets and leaves the part):
    its peaks within rtol of a solve on four times the elements, the estimate not below a third
    of that difference."""
    m = press.build()
    eff = ("inertia", "coupling", "axial_stiffening", "gravity", "loads")
    res = kf.solve(kf.Scene(m, effects=eff, damping=kf.ModalDamping(0.02), rtol=1e-3))
    ref = kf.solve(kf.Scene(m, effects=eff, damping=kf.ModalDamping(0.02), steps=4 * res.elements,
                            estimate=False))
    p, q = res.peaks()[0], ref.peaks()[0]
    true = abs(p.stress / q.stress - 1)
    est = res.error.links[0].stress
    assert res.error.met and true <= 1e-3
    assert est >= true / 3
    # the forming force is in the answer: the rod's peak stress is its compression under it
    assert abs(q.stress - 40e3 / 0.03**2) / q.stress < 0.05


def test_a_load_whose_table_lies_outside_the_travel_is_named():
    """A table on the wrong side of the axis (positions along +x where the joint's are negative
    along it) never acts: the solve says so instead of adding nothing silently."""
    m = press.build()
    m.loads.clear()
    m.load("wrong sign", "B", (0.0, 40e3), profile=kf.Profile.position("B", (0.0, 1.0), [0.29, 0.3], [0, 1]))
    with pytest.warns(kf.EffectWarning, match=r"load 'wrong sign' never acts.*-0\.3 to -0\.2 m.*0\.29 to 0\.3 m"):
        kf.solve(kf.Scene(m, effects=RIGID, steps=24, estimate=False))


def test_crank_angles_that_look_like_radians_warn():
    with pytest.warns(UserWarning, match="in degrees and all lie within 2 pi"):
        kf.Profile.crank_angle([0.0, math.pi], [0.0, 1.0])


def test_a_load_that_steps_at_a_dead_centre_is_named_before_the_solve():
    """A one-stroke forming load whose table ends at the bottom dead centre drops to zero there in
    one step, which rings modes far above the drive's harmonics and multiplies the time elements
    (a new user's toggle press: 6144 elements, 12 s, where its two-stroke version took 768). The
    resolution step warns (kf.CostWarning: a script without logging set up sees it) that says so and
    what costs fewer; the two-stroke version (forming, then springback on the return stroke, as
    examples/press.py) gets none."""
    import warnings
    from kedfem.analysis import pipeline

    def scene(both):
        m = mechanisms.build("slider_crank", elements=4)
        x = kf.kinematics(m, 720).position("B")[:, 0]
        bdc = float(x.max())
        m.load("forming", "B", force=(-200.0, 0.0), profile=kf.Profile.position(
            "B", (1.0, 0.0), [bdc - 0.01, bdc], [0.0, 1.0], stroke="forward", smooth=True))
        if both:
            m.load("springback", "B", force=(-200.0, 0.0), profile=kf.Profile.position(
                "B", (1.0, 0.0), [bdc - 0.003, bdc], [0.0, 1.0], stroke="return", smooth=True))
        return kf.Scene(m, effects=("inertia", "coupling", "axial_stiffening", "loads"),
                        damping=kf.ModalDamping(0.02))

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        n_step, _f = pipeline._Run(scene(False)).resolution()
        stepped = [str(w.message) for w in caught if issubclass(w.category, kf.CostWarning)]
        caught.clear()
        n_smooth, _f = pipeline._Run(scene(True)).resolution()
        smooth = [str(w.message) for w in caught if issubclass(w.category, kf.CostWarning)]
    # names the load, where it steps (the slider's outer dead centre: the crank along +x) and the cure
    assert stepped and "process load(s) 'forming' step" in stepped[0] and not smooth
    assert ("'forming' at absolute crank angle 0.0 deg: a second load for the other stroke, where it ends at a "
            "dead centre") in stepped[0]
    assert n_step > n_smooth
    # a crank-angle table's repeated entry on the same joint as two smooth loads of 0 N: the table is
    # named, with the cure for a repeated entry (a new reviewer: every load on the joint was named)
    m = press.build(forming_force=0.0)
    m.load("step", "B", force=(0.0, 40e3), profile=kf.Profile.crank_angle([0, 100.3, 100.3, 140, 360],
                                                                           [0, 0, 1, 0, 0], smooth=True))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pipeline._Run(kf.Scene(m, effects=("inertia", "coupling", "axial_stiffening", "loads"))).resolution()
    said = [str(w.message) for w in caught if issubclass(w.category, kf.CostWarning)]
    assert len(said) == 1 and "process load(s) 'step' step" in said[0] and "'forming'" not in said[0]
    assert "'step' at absolute crank angle 190.3 deg: a short ramp for its table's repeated entry" in said[0]


def catalogue_scene(name):
    from kedfem import catalogue
    return catalogue.info(name).scene()


def test_a_load_peak_at_a_step_is_not_overshot_and_a_smooth_peak_keeps_its_vertex():
    """A force that steps up to its largest value between two output instants: the bearing forces'
    peaks are the largest samples, not a parabola through the step (a new user's toggle press read
    12 % above every sample), checked against the largest of the same loads' samples on 20 times the
    instants; a smooth peak between samples is read from the dense output (the four-bar preset),
    and a parabola's vertex where the samples are all there is (a cosine's peak to 1 % of its
    sampled error)."""
    from kedfem.analysis.peak_search import smooth_vertex
    m = press.build(forming_force=0.0)
    m.load("step", "B", force=(0.0, 40e3), profile=kf.Profile.crank_angle([0, 100.3, 100.3, 140, 360],
                                                                           [0, 0, 1, 0, 0]))
    res = kf.solve(kf.Scene(m, effects=RIGID, steps=48, estimate=False), progress=False)
    coarse = res.loads().peaks("rigid")
    fine = res.resample(np.arange(20 * res.n) * (res.period / (20 * res.n))).loads().history("rigid")
    truth = np.concatenate([fine.magnitude.max(axis=0), np.abs(fine.torque).max(axis=0)])
    assert len(coarse) == truth.size
    for c, f in zip(coarse, truth):
        assert f * (1 - 0.01) <= c.peak <= f * (1 + 1e-3), (c, f)  # the step's, no overshoot
    # a smooth elastic peak between the samples (the four-bar preset's bearing forces, whose axial
    # ringing the samples cut short): the peaks read from the dense output, to 1e-4 of a 32x grid
    res = kf.solve(catalogue_scene("four_bar"), progress=False)
    fine = res.resample(np.arange(32 * res.n) * (res.period / (32 * res.n))).loads().history("elastic")
    for c, f in zip(res.loads().peaks("elastic"), fine.magnitude.max(axis=0)):
        assert abs(c.peak / f - 1) < 1e-4, (c, f)
    # a smooth peak between samples: the vertex, not the sample
    t = np.arange(36) * (2 * math.pi / 36)
    y = np.cos(t - 0.05)
    k = int(np.argmax(y))
    v, dk = smooth_vertex(y, k, periodic=True)
    assert abs(v - 1.0) < 0.01 * (1.0 - y[k])
    assert abs(t[k] + dk * t[1] - 0.05) < 1e-3


def test_a_solve_past_its_forecast_says_what_refines_it_and_its_bar_keeps_count(caplog, capsys, monkeypatch):
    """Each level past the third says what drives the refinement on (the link, the quantity, its
    estimate) and the elements it is now forecast to end on, and the progress bar's count of levels
    follows (a new user's toggle press showed '100 % 3/3' then 4/4, 5/5, 6/6). The press at its
    defaults goes a level past its second level's forecast; the re-forecast names the level it
    ends on."""
    import logging
    import re
    import tqdm.auto
    real = tqdm.auto.tqdm

    def shown(*args, **kw):  # the bar at once (a quick solve is otherwise below its delay)
        kw["delay"] = 0.0
        return real(*args, **kw)
    monkeypatch.setattr(tqdm.auto, "tqdm", shown)
    scene = kf.Scene(press.build(), effects=("inertia", "coupling", "axial_stiffening", "gravity", "loads"),
                     damping=kf.ModalDamping(0.02))
    with caplog.at_level(logging.INFO, logger="kedfem"):
        res = kf.solve(scene, progress=True)
    msgs = [r.getMessage() for r in caplog.records]
    levels = [int(x) for m in msgs for x in re.findall(r"level n=(\d+) \(", m)]
    said = [m for m in msgs if "refining to" in m]
    assert levels[-1] == res.elements and len(levels) >= 4
    # one line per level from the third to the last but one, naming the link and the next level
    assert len(said) == len(levels) - 3
    for lv, m in zip(levels[2:-1], said):
        assert f"level n={lv}: refining to {2 * lv} time elements" in m and "'rod'" in m
    # the last re-forecast ends where the solve ended
    assert said[-1].endswith(f"(up to {res.elements} elements)")
    bar = [(int(a), int(b)) for a, b in re.findall(r"(\d+)/(\d+) levels", capsys.readouterr().err)]
    assert bar and all(a <= b for a, b in bar)
    assert max(b for _a, b in bar) == len(levels)  # the count ends where the solve did


def test_a_solve_that_a_kinked_load_table_made_long_says_so():
    """A tolerance-driven solve that ends on 8x the elements its floors ask for, with a process load
    whose table kinks (no smooth=True), names the load and the remedy (kf.CostWarning; a new user's
    wiper linkage: a ramped load ended on 3072 elements in 15 s, smooth=True on 192 in 0.85 s);
    a smooth table, a shorter solve or steps given say nothing."""
    from kedfem.analysis import pipeline

    def run(smooth, **kw):
        m = press.build(forming_force=0.0)
        m.load("ramp", "B", force=(0.0, 40e3), profile=kf.Profile.crank_angle(
            [0, 100, 140, 180, 360], [0, 0, 1, 0, 0], smooth=smooth))
        return pipeline._Run(kf.Scene(m, effects=("inertia", "coupling", "gravity", "loads"), **kw))

    said = run(False).corner_cost(1536, 48, 12.0)
    assert said is not None and "'ramp'" in said and "smooth=True" in said and "32x the 48" in said
    assert run(True).corner_cost(1536, 48, 12.0) is None
    assert run(False).corner_cost(192, 48, 1.0) is None
    assert run(False, steps=1536).corner_cost(1536, 48, 12.0) is None
