"""The inertial-frame (global) equations equal the link-frame equations of docs/theory.md section 2.

The link-frame equation of a frame element is
``m u'' + 2 w m_s u' + (k + a m_s - w^2 m_t) u = f`` with local DOFs ``u = T(theta) x``.
The package assembles derived global matrices (with the terms of the time
derivatives of ``T``); here the link-frame equation is evaluated directly along
a trajectory, with ``T'`` and ``T''`` from differentiating cos and sin, and the
two must agree to round-off.
"""

import math

import numpy as np

import kedfem as kf
import mechanisms
from kedfem.model import elements as el
from kedfem.fe.assembler import Assembler


def dT(theta, order):
    """d^order T / d theta^order, written out from the cos/sin entries."""
    c, s = math.cos(theta), math.sin(theta)
    blocks = {0: np.array([[c, s], [-s, c]]), 1: np.array([[-s, c], [-c, -s]]),
              2: np.array([[-c, -s], [s, -c]])}
    T = np.zeros((6, 6))
    for o in (0, 3):
        T[o:o + 2, o:o + 2] = blocks[order]
        T[o + 2, o + 2] = 1.0 if order == 0 else 0.0
    return T


def test_global_equations_match_link_frame_equations_four_bar():
    # a very soft linkage, so that the coupling terms are not lost in the round-off of k
    m = mechanisms.build("four_bar", elements=3, joint_mass=0.0, speed=2 * math.pi * 3, E=7.1e4,
                         crank_EI=11.472e-6, link_EI=0.616e-6)
    fe = kf.FEModel(m)
    mo = kf.kinematics(m, steps=24)
    asm = Assembler(fe, mo, ("coupling",))
    sysm = asm.system()
    _M, Ks = asm.structural()
    Kc = sysm.K - Ks  # coupling part only: the structural stiffness is the same on both sides
    N = fe.n_dof
    rng = np.random.default_rng(1)
    amp = rng.normal(size=(3, N)) * 1e-3
    w = 2 * math.pi / mo.period
    gm = fe.group_map("beam", mo)
    b = fe.beam
    m_loc = el.consistent_mass(b.L, b.rhoA)
    ms = el.coupling_skew(b.L, b.rhoA)
    worst = 0.0
    for n in range(mo.n):
        t = mo.t[n]
        # smooth periodic trajectory q(t) and exact derivatives
        q = sum(amp[j] * np.sin((j + 1) * w * t + j) for j in range(3))
        q1 = sum(amp[j] * (j + 1) * w * np.cos((j + 1) * w * t + j) for j in range(3))
        q2 = sum(-amp[j] * ((j + 1) * w) ** 2 * np.sin((j + 1) * w * t + j) for j in range(3))
        lhs = sysm.M[n] @ q2 + sysm.C[n] @ q1 + Kc[n] @ q
        rhs = np.zeros(N)
        qp = np.append(q, 0.0)
        q1p = np.append(q1, 0.0)
        q2p = np.append(q2, 0.0)
        for e in range(b.L.size):
            i = mo.member_names.index(b.links[b.link[e]])
            th, om, al = mo.theta[n, i], mo.omega[n, i], mo.alpha[n, i]
            cols = gm.cols[e]
            E = gm.E[min(n, gm.E.shape[0] - 1), e]
            x, x1, x2 = E @ qp[cols], E @ q1p[cols], E @ q2p[cols]
            if gm.E1 is not None:  # moving maps (co-rotating interior nodes): x = E q
                E1, E2 = gm.E1[n, e], gm.E2[n, e]
                x1 = x1 + E1 @ qp[cols]
                x2 = x2 + 2 * E1 @ q1p[cols] + E2 @ qp[cols]
            T0, T1, T2 = dT(th, 0), om * dT(th, 1), al * dT(th, 1) + om**2 * dT(th, 2)
            u, u1, u2 = T0 @ x, T0 @ x1 + T1 @ x, T0 @ x2 + 2 * T1 @ x1 + T2 @ x
            f = m_loc[e] @ u2 + 2 * om * ms[e] @ u1 + (al * ms[e] - om**2 * m_loc[e]) @ u
            fx = T0.T @ f
            np.add.at(rhs, cols[cols < N], (E.T @ fx)[cols < N])
        scale = (np.linalg.norm(sysm.M[n] @ q2) + np.linalg.norm(sysm.C[n] @ q1)
                 + np.linalg.norm(Kc[n] @ q))
        worst = max(worst, np.linalg.norm(lhs - rhs) / scale)
    assert worst < 1e-10


def test_rotating_cantilever_mode_is_free_motion_of_global_equations():
    """A link-frame eigenmode, rotated into the inertial frame, solves the global equations."""
    sec = kf.Section.rectangle(0.01, 0.01)
    m = kf.Mechanism("rotor")
    m.ground("O", at=(0, 0), clamped=True)
    m.joint("T", at=(1.0, 0))
    m.link("b", "O", "T", material=kf.Material(2e11, 7800), section=sec, elements=6)
    Om = 40.0
    m.drive("b", speed=Om)
    fe = kf.FEModel(m, corotate=False)  # global components: the test maps link-frame modes
    mo = kf.kinematics(m, steps=16)
    eff = ("coupling", "axial_stiffening")
    fr = Assembler(fe, mo, eff, frame=True).system([0])
    N = fe.n_dof
    A = np.block([[np.zeros((N, N)), np.eye(N)],
                  [-np.linalg.solve(fr.M[0], fr.K[0]), -np.linalg.solve(fr.M[0], fr.C[0])]])
    lam, V = np.linalg.eig(A)
    i = int(np.argmin(np.where(lam.imag > 1e-6, lam.imag, np.inf)))
    lam0, phi = lam[i], V[:N, i]
    gl = Assembler(fe, mo, eff).system()
    worst = 0.0
    for k in range(mo.n):
        th = mo.theta[k, 0]
        R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
        S = np.array([[0, -1.0], [1.0, 0]])
        P, P1, P2 = np.eye(N), np.zeros((N, N)), np.zeros((N, N))
        for j, lbl in enumerate(fe.dof_labels):
            if lbl.endswith(".ux"):
                P[j:j + 2, j:j + 2] = R
                P1[j:j + 2, j:j + 2] = Om * R @ S
                P2[j:j + 2, j:j + 2] = -Om**2 * R
        ul = phi * np.exp(lam0 * mo.t[k])
        u = P @ ul
        u1 = P1 @ ul + P @ (lam0 * ul)
        u2 = P2 @ ul + 2 * P1 @ (lam0 * ul) + P @ (lam0**2 * ul)
        r = gl.M[k] @ u2 + gl.C[k] @ u1 + gl.K[k] @ u
        worst = max(worst, np.linalg.norm(r) / np.linalg.norm(gl.M[k] @ u2))
    assert worst < 1e-9


def test_pivoting_rigid_member_coupling_and_stiffening_cancel():
    """J_O phi'' + k_t phi = 0 exactly for a rigid crank on a drive shaft spring (global frame)."""
    m = kf.Mechanism("shaft")
    m.ground("O", at=(0, 0))
    m.joint("A", at=(0.2, 0.05))
    m.link("crank", "O", "A", rigid=True, mass=3.0)
    m.drive("crank", speed=30.0, torsional_stiffness=5.0e3)
    fe = kf.FEModel(m)
    mo = kf.kinematics(m, steps=8)
    full = Assembler(fe, mo, ("coupling", "axial_stiffening", "inertia")).system()
    L = math.hypot(0.2, 0.05)
    JO = 3.0 * L**2 / 3
    np.testing.assert_allclose(full.M[:, 0, 0], JO, rtol=1e-12)
    np.testing.assert_allclose(full.K[:, 0, 0], 5.0e3, rtol=1e-9)
    np.testing.assert_allclose(full.C[:, 0, 0], 0.0, atol=1e-9)
    np.testing.assert_allclose(full.Q, 0.0, atol=1e-9)
    # coupling alone leaves the centripetal softening -m w^2 |rho_c|^2
    cpl = Assembler(fe, mo, ("coupling",)).system()
    np.testing.assert_allclose(cpl.K[:, 0, 0], 5.0e3 - 3.0 * 30.0**2 * (L / 2) ** 2, rtol=1e-9)
