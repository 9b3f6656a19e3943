"""Loads on the machine (kedfem.analysis.loads): bearing forces and drive torques, rigid and elastic.

References: Norton's dynamic force analysis of a four-bar (R. L. Norton, Design of Machinery,
section 11.5: the 9 x 9 system for the pin forces and the input torque), coded here from the book
on the closed-form kinematics of tests/test_kinematics.py (Norton's velocity and acceleration
equations); the balance of every pin (Newton's second law of the pin particle), with the pin's
acceleration differentiated here from the result's joint displacement; a drive shaft's spring law
``-k_t phi`` read off the DOF; the mean drive power against the friction's work.
"""

import csv
import math
import os

import numpy as np
import pytest

import kedfem as kf
import mechanisms
from test_kinematics import four_bar_closed_form  # Norton's positions, velocities, accelerations
from kedfem.analysis.loads import CSV_COLUMNS, FRAME, MachineLoads, loads_from_forces, machine_loads
from kedfem.io.loads_files import plot_loads, write_loads_csv

# ------------------------------------------------------------- Norton's four-bar
#: link lengths [m]: crank a, coupler b, rocker c, ground d (a Grashof crank-rocker)
A_, B_, C_, D_ = 0.127, 0.381, 0.254, 0.3048
M2, J2 = 0.5, 0.0021     # crank: mass [kg], J about its centre [kg m^2] (centre at mid-length)
M3, J3 = 1.2, 0.0185     # coupler: centre off the line A-B
M4, J4 = 0.8, 0.0062
G3 = (0.21, 0.035)       # coupler centre in the coupler frame (along A->B, normal to it) [m]
P3 = (0.25, 0.05)        # point of the coupler force F_P3, same frame [m]
FP3 = np.array([40.0, -25.0])   # [N] on the coupler at P3
FP4 = np.array([-15.0, 30.0])   # [N] on the rocker at B (a load on pin B)
T4 = 3.0                 # [N m] external torque on the rocker
W2 = 30.0                # crank speed [rad/s]
TH0 = math.radians(20.0)  # crank angle of the reference configuration


def _norton_forces(th2):
    """Norton's 9 x 9 solution: F12, F32, F43, F14 (each (2,)) and T12 at crank angle ``th2``."""
    a, c = A_, C_
    w2, al2 = W2, 0.0
    kin = four_bar_closed_form(np.array([th2]), A_, B_, C_, D_, W2)  # open circuit, constant speed
    th3, th4, w3, w4, al3, al4 = (float(v[0]) for v in kin[1:])

    def u(th):
        return np.array([math.cos(th), math.sin(th)])

    def n(th):
        return np.array([-math.sin(th), math.cos(th)])

    O2, O4 = np.zeros(2), np.array([D_, 0.0])
    PA = O2 + a * u(th2)
    PB = O4 + c * u(th4)
    # centres and their accelerations (a_P = a_O + alpha x r - w^2 r)
    r2 = 0.5 * a * u(th2)
    g2 = O2 + r2
    a_g2 = al2 * n(th2) * 0.5 * a - w2**2 * r2
    r3 = G3[0] * u(th3) + G3[1] * n(th3)
    g3 = PA + r3
    a_A = al2 * a * n(th2) - w2**2 * a * u(th2)
    a_g3 = a_A + al3 * np.array([-r3[1], r3[0]]) - w3**2 * r3
    r4 = 0.5 * c * u(th4)
    g4 = O4 + r4
    a_g4 = al4 * n(th4) * 0.5 * c - w4**2 * r4
    p3 = PA + P3[0] * u(th3) + P3[1] * n(th3)
    R12, R32 = O2 - g2, PA - g2
    R23, R43, RP3 = PA - g3, PB - g3, p3 - g3
    R34, R14, RP4 = PB - g4, O4 - g4, PB - g4
    # unknowns: F12x F12y F32x F32y F43x F43y F14x F14y T12 (Norton eq. 11.10)
    M = np.zeros((9, 9))
    rhs = np.zeros(9)
    M[0, [0, 2]] = 1
    M[1, [1, 3]] = 1
    M[2, :] = [-R12[1], R12[0], -R32[1], R32[0], 0, 0, 0, 0, 1]
    rhs[0:3] = [M2 * a_g2[0], M2 * a_g2[1], J2 * al2]
    M[3, [2, 4]] = [-1, 1]
    M[4, [3, 5]] = [-1, 1]
    M[5, :] = [0, 0, R23[1], -R23[0], -R43[1], R43[0], 0, 0, 0]
    rhs[3:6] = [M3 * a_g3[0] - FP3[0], M3 * a_g3[1] - FP3[1],
                J3 * al3 - (RP3[0] * FP3[1] - RP3[1] * FP3[0])]
    M[6, [4, 6]] = [-1, 1]
    M[7, [5, 7]] = [-1, 1]
    M[8, :] = [0, 0, 0, 0, R34[1], -R34[0], -R14[1], R14[0], 0]
    rhs[6:9] = [M4 * a_g4[0] - FP4[0], M4 * a_g4[1] - FP4[1],
                J4 * al4 - (RP4[0] * FP4[1] - RP4[1] * FP4[0]) - T4]
    x = np.linalg.solve(M, rhs)
    return x[0:2], x[2:4], x[4:6], x[6:8], x[8]


def _norton_mechanism():
    """The same four-bar, built from its lengths (open circuit at TH0)."""
    m = kf.Mechanism("norton-four-bar")
    m.ground("O2", at=(0.0, 0.0))
    m.ground("O4", at=m.at_angle("O2", D_, 0.0))
    m.joint("A", at=m.at_angle("O2", A_, TH0))
    m.joint("B", at=m.at_lengths(("A", B_, "coupler"), ("O4", C_, "rocker"), branch="open"))
    A, B = np.array(m.joints["A"].at), np.array(m.joints["B"].at)
    e = (B - A) / B_
    nrm = np.array([-e[1], e[0]])
    m.joint("P", at=tuple(A + P3[0] * e + P3[1] * nrm))
    m.link("crank", "O2", "A", rigid=True, mass=M2, J=J2, length=A_)
    m.body("coupler", ("A", "B", "P"), mass=M3, J=J3, cm=tuple(A + G3[0] * e + G3[1] * nrm))
    m.link("rocker", "O4", "B", rigid=True, mass=M4, J=J4, length=C_)
    m.load("F_P3", "P", tuple(FP3))
    m.load("F_P4", "B", tuple(FP4))
    m.drive("crank", speed=W2)
    return m


@pytest.fixture(scope="module")
def norton():
    m = _norton_mechanism()
    angles = np.radians(np.arange(0.0, 360.0, 15.0)) + 0.1
    times = np.mod(angles - TH0, 2 * math.pi) / W2
    mo = kf.kinematics(m, times=times)
    loads = np.zeros((mo.n, len(mo.joint_names), 2))
    loads[:, mo.joint_names.index("P")] = FP3
    loads[:, mo.joint_names.index("B")] = FP4
    moments = np.zeros((mo.n, len(mo.member_names)))
    moments[:, mo.member_names.index("rocker")] = T4
    jf = kf.kinetostatics(m, mo, joint_loads=loads, member_moments=moments)
    ref = [_norton_forces(th) for th in angles]
    return m, mo, jf, angles, ref


def test_kinetostatics_matches_nortons_four_bar(norton):
    """Pin forces and input torque of a rigid four-bar with masses, offset centre, loads: Norton, 1e-8."""
    m, mo, jf, angles, ref = norton
    F12, F32, F43, F14, T12 = (np.array([r[k] for r in ref]) for k in range(5))
    scale = max(np.abs(x).max() for x in (F12, F32, F43, F14))
    cases = {("crank", "O2"): F12, ("crank", "A"): F32, ("coupler", "A"): -F32, ("coupler", "B"): F43,
             ("rocker", "B"): -F43 + FP4, ("rocker", "O4"): F14, ("coupler", "P"): np.tile(FP3, (len(ref), 1))}
    for pair, expected in cases.items():
        np.testing.assert_allclose(jf.on(*pair), expected, rtol=0, atol=1e-8 * scale, err_msg=str(pair))
    np.testing.assert_allclose(jf.drive_torque[:, 0], T12, rtol=0, atol=1e-8 * np.abs(T12).max())
    np.testing.assert_allclose(jf.frame_reaction["O2"], F12, rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(jf.frame_reaction["O4"], F14, rtol=0, atol=1e-8 * scale)
    assert np.abs(F12).max() > 50.0 and np.abs(T12).max() > 5.0  # inertia matters at 30 rad/s


def test_machine_loads_from_kinetostatics(norton):
    """MachineLoads: bearings (pin on body, frame = minus its reaction), torque, peaks with their angle."""
    m, mo, jf, angles, ref = norton
    L = loads_from_forces(m, mo, jf)
    assert isinstance(L, MachineLoads) and L.elastic is None
    # by joint; at a joint, links before bodies
    assert L.bearings == (("O2", "crank"), ("O2", FRAME), ("O4", "rocker"), ("O4", FRAME), ("A", "crank"),
                          ("A", "coupler"), ("B", "rocker"), ("B", "coupler"), ("P", "coupler"))
    F12 = np.array([r[0] for r in ref])
    np.testing.assert_allclose(L.force("O2", response="rigid"), -F12, atol=1e-8 * np.abs(F12).max())
    np.testing.assert_allclose(L.magnitude("O2", "crank", "rigid"), np.hypot(*F12.T), rtol=1e-9)
    np.testing.assert_allclose(L.torque(response="rigid"), [r[4] for r in ref], rtol=1e-9)
    peaks = {(p.quantity, p.joint, p.member): p for p in L.peaks("rigid")}
    p = peaks[("bearing_force", "O2", FRAME)]
    k = int(np.argmax(np.hypot(*F12.T)))
    assert p.peak == pytest.approx(np.hypot(*F12[k]))            # not a uniform grid: the largest sample
    assert p.crank_angle == pytest.approx(angles[k] % (2 * math.pi))
    assert p.rms == pytest.approx(np.sqrt(np.mean(np.sum(F12**2, axis=1))))
    with pytest.raises(kf.InputError, match="not computed"):
        L.force("O2")
    with pytest.raises(kf.InputError, match="no bearing of 'rocker' at joint 'A'"):
        L.force("A", "rocker", "rigid")
    with pytest.raises(kf.InputError, match="unknown joint 'Q'"):
        L.force("Q", response="rigid")


# ---------------------------------------------------------- elastic responses
def _four_bar(speed=None, damping=None):
    pre = mechanisms.get("four_bar").PRESET
    m = mechanisms.build("four_bar", **({} if speed is None else {"speed": speed}))
    return kf.solve(kf.Scene(m, effects=pre.effects, damping=pre.damping if damping is None else damping))


def _rel_difference(L):
    """Largest |elastic - rigid| of the bearing forces and of the torque, relative to the rigid peaks."""
    df = np.abs(L.elastic.force - L.rigid.force).max() / np.abs(L.rigid.force).max()
    dt = np.abs(L.elastic.torque - L.rigid.torque).max() / np.abs(L.rigid.torque).max()
    return df, dt


def test_elastic_loads_tend_to_rigid_at_low_speed():
    """Four-bar preset: at 5 rpm the elastic loads are the kinetostatic ones; at 200 rpm they differ."""
    slow = machine_loads(_four_bar(speed=2 * math.pi * 5 / 60))
    df, dt = _rel_difference(slow)
    assert df < 2e-3 and dt < 2e-3, (df, dt)       # measured 8.3e-4, 3.2e-4
    fast = machine_loads(_four_bar())
    df, dt = _rel_difference(fast)
    assert df > 0.05 and dt > 0.05, (df, dt)       # measured 0.16, 0.19 (the elastic vibration)
    # the peak drive torque of the flexible crank: its root bending moment
    assert fast.peaks()[-1].quantity == "drive_torque"
    assert fast.peaks()[-1].peak > 1.1 * fast.peaks("rigid")[-1].peak


def _pin_imbalance(res, L, joint, mass):
    """|sum of the forces the pin exerts on its members + m a| over the cycle, and the largest force."""
    u = res.joint_displacement(joint)
    n, T = res.n, res.scene.period
    k = np.fft.rfftfreq(n, d=T / n) * 2 * math.pi
    k[-1] = 0.0 if n % 2 == 0 else k[-1]
    acc = np.fft.irfft(np.fft.rfft(u, axis=0) * (-(k**2))[:, None], n=n, axis=0)
    a = res.motion.acceleration(joint) + acc
    members = [b for b in L.bearings if b[0] == joint and b[1] != FRAME]
    total = sum(L.force(j, m) for j, m in members) + mass * a
    return total, max(np.abs(L.force(j, m)).max() for j, m in members)


def test_pin_balance_of_the_elastic_loads():
    """Four-bar: at the moving pins the forces on the members plus m a vanish, up to the damping share."""
    out = {}
    for beta in (1e-4, 1e-5):
        res = _four_bar(damping=kf.Rayleigh(0.0, beta))
        L = machine_loads(res)
        imb = []
        for joint in ("A", "B"):
            total, peak = _pin_imbalance(res, L, joint, 0.042)
            imb.append(np.abs(total).max() / peak)
        out[beta] = max(imb)
        assert L.elastic.residual == pytest.approx(out[beta], rel=0.5)  # the reported balance
    assert out[1e-5] < 1e-3, out                    # measured 3.5e-4
    assert out[1e-4] > 4.0 * out[1e-5], out         # it is the damping's share (measured 8.3e-3)


def test_slider_crank_elastic_loads():
    """Slider-crank preset: slider balance along the axis, the guide's force normal to it, crank torque."""
    pre = mechanisms.get("slider_crank").PRESET
    m = mechanisms.build("slider_crank")
    res = kf.solve(kf.Scene(m, effects=pre.effects, damping=pre.damping))
    L = machine_loads(res)
    axis = np.asarray(m.joints["B"].axis)
    total, peak = _pin_imbalance(res, L, "B", m.point_masses[0].mass)
    total = total + L.force("B", FRAME)  # the guide takes the normal component
    assert np.abs(total @ axis).max() < 2e-3 * peak                    # measured 5.7e-4
    assert np.abs(L.force("B", FRAME) @ axis).max() < 1e-9 * peak      # a guide pushes normal to itself
    # the crank is rigid and massless: the drive balances the pin at A about O
    arm = res.motion.position("A") - res.motion.position("O")
    FA = L.force("A", "crank")
    np.testing.assert_allclose(L.torque("crank"), -(arm[:, 0] * FA[:, 1] - arm[:, 1] * FA[:, 0]),
                               atol=1e-9 * np.abs(L.torque("crank")).max())
    np.testing.assert_allclose(L.force("A", "crank"), -L.force("A", "rod"), atol=1e-9 * peak)


def test_torsional_drives_and_rigid_bodies():
    """Mould oscillator: drive torque = -k_t (elastic twist) of each shaft; the table balances; the
    drives' mean power (the friction's work per cycle) is the rigid model's."""
    pre = mechanisms.get("mould_oscillator").PRESET
    m = mechanisms.build("mould_oscillator")
    res = kf.solve(kf.Scene(m, effects=pre.effects, damping=pre.damping, steps=pre.steps))
    L = machine_loads(res)
    for d in m.drives:
        twist = res.dof(f"{d.member}.phi")
        np.testing.assert_allclose(L.torque(d.member), -d.torsional_stiffness * twist, rtol=1e-12)
    # steady state: the mean drive power balances the billet friction (and the damping)
    power = {r: sum(d.speed * L.torque(d.member, r).mean() for d in m.drives) for r in ("rigid", "elastic")}
    assert power["elastic"] == pytest.approx(power["rigid"], rel=0.03)  # measured 1.1 %
    assert L.elastic.residual < 3e-3  # measured 1.7e-3, the damping share (4.6e-4 at zeta = 0.005)
    # a pin between a flexible rod and the rigid table: equal and opposite (no pin mass there)
    np.testing.assert_allclose(L.force("E", "table"), -L.force("E", "rod_outer"), atol=1e-6)


def test_rigid_loads_are_the_assemblers(tmp_path):
    """machine_loads(elastic=False): the assembler's kinetostatics; the CSV and the plot."""
    res = _four_bar()
    L = machine_loads(res, elastic=False)
    assert L.elastic is None
    jf = kf.fe.assembler.Assembler(res.model, res.motion, res.scene.effects).joint_forces()
    np.testing.assert_array_equal(L.force("A", "coupler", "rigid"), jf.on("coupler", "A"))
    L = machine_loads(res)
    path = write_loads_csv(L, tmp_path / "loads.csv")
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == CSV_COLUMNS
    body = rows[1:]
    n = res.n
    per = 2 * (len(L.bearings) * 3 + len(L.drives))  # two responses; x, y, magnitude; torques
    assert len(body) == n * per                      # no moments: the four-bar's pins are free
    k = 7
    want = L.force("B", "follower")[k, 1]
    got = [r for r in body if r[1:6] == ["elastic", "bearing_force", "B", "follower", "y"]][k]
    assert float(got[6]) == want and got[7] == "N"
    assert float(got[0]) == pytest.approx(math.degrees(res.crank_angle[k]) % 360.0, abs=1e-6)
    torque = [r for r in body if r[2] == "drive_torque" and r[1] == "rigid"]
    assert len(torque) == n and {r[3] for r in torque} == {"O2"} and {r[7] for r in torque} == {"N m"}
    png = plot_loads(L, tmp_path / "loads.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["loads.csv", "loads.png"]  # nothing left over
    text = L.summary()
    assert "bearing O2 (frame)" in text and "drive crank at O2" in text and "pin balance" in text


def test_kinetostatic_condition_estimate_tracks_the_svd():
    """The probe estimate of the kinetostatic equations' condition number (two solves with
    random signs instead of an inverse) is within a small factor of the SVD's, from well-posed
    matrices to ones a toggle position makes nearly singular."""
    from kedfem.motion.kinetostatics import _probes, condition_estimate
    rng = np.random.default_rng(3)
    n = 30
    U, _ = np.linalg.qr(rng.standard_normal((n, n)))
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    smallest = np.logspace(0, -14, 40)
    s = np.linspace(1.0, 10.0, n)[None].repeat(smallest.size, 0)
    s[:, -1] = smallest
    A = np.einsum("ij,kj,lj->kil", U, s, V)
    A = A + 1e-3 * rng.standard_normal(A.shape) * smallest[:, None, None]  # not an exact construction
    probes = _probes(n)
    Y = np.linalg.solve(A, np.broadcast_to(probes, (A.shape[0],) + probes.shape))
    est = condition_estimate(A, Y, probes)
    exact = np.linalg.cond(A)
    ratio = est / exact
    assert np.all(ratio > 0.1) and np.all(ratio < 10 * np.sqrt(n)), ratio
    # the flag the kinetostatics raises at 1e12 comes on with the exact condition number
    assert np.array_equal(est[exact < 1e10] > 1e12, np.zeros((exact < 1e10).sum(), bool))
    assert np.all(est[exact > 1e14] > 1e12)


def test_kinetostatics_flags_two_equations_that_nearly_coincide():
    """A redundant support makes two rows of the kinetostatic equations nearly equal: a null
    direction with two entries of equal size, orthogonal to many a vector of random signs (a
    review helper's counter-example: 66 of 272 such four-bar systems returned forces of 1e15
    with random-sign probes). Every one is flagged, as by the inverse before."""
    from kedfem.analysis import pipeline
    from kedfem.errors import KedError
    from kedfem.motion import kinetostatics as ks
    sc = kf.load_scene(os.path.join(os.path.dirname(__file__), "..", "examples", "scenes", "four_bar.toml"))[0]
    mo = pipeline._Run(sc).cycle.at(np.array([0.01]))
    lay = ks._Layout(sc.mech, mo, None)
    A0, b = ks._equations(sc.mech, mo, lay, True, False, None, None, None, None)
    A0, b = A0[0], b[0]
    n = A0.shape[0]
    x, _rel = ks._solve_square(sc.mech, A0[None], b[None], n, n)  # the mechanism itself is well posed
    assert np.all(np.isfinite(x))
    rng = np.random.default_rng(0)
    flagged = 0
    pairs = [(i, j) for i in range(n) for j in range(n) if i != j]
    for i, j in pairs:
        A = A0.copy()
        A[j] = A[i] + 1e-15 * np.abs(A0).max() * rng.standard_normal(n)
        with pytest.raises(KedError, match="ill-conditioned|singular"):
            ks._solve_square(sc.mech, A[None], b[None], n, n)
        flagged += 1
    assert flagged == len(pairs)
