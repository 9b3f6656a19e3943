"""Velocities and accelerations of the rigid-body motion, and the :class:`~kedfem.motion.record.Motion`
at given positions.

The rates of the unknowns come from the linear velocity and acceleration equations of the
loop-closure model (:mod:`kedfem.motion.loops`; no finite differences), solved for all instants at
once; the joints' states follow from the members' along the spanning tree, and a passive link's
angle and rates from the chord between its end joints.
"""

from __future__ import annotations

import math

import numpy as np

from .loops import _LoopModel, _split
from .record import Motion, _S

__all__: list[str] = []  # the motion wing's internals (kinematics imports them)


def _rates(model, theta, s, th_drive_rate, cols):
    """Velocities and accelerations of the unknowns for all nodes at once."""
    n = theta.shape[0]
    w = model.edge_vectors(theta, s)
    J = model.jacobian(theta, s, w)  # (n, neq, nm+ns)
    Ju = J[:, :, cols]
    Jd = J[:, :, model.drive_idx]
    rhs_v = -np.matmul(Jd, th_drive_rate[..., None])[..., 0]
    yd = np.linalg.solve(Ju, rhs_v[..., None])[..., 0]
    omega, sd = _split(model, yd, th_drive_rate)
    # acceleration: J [alpha; s''] = sum_loops D omega_e^2 w_e  (constant drive speed)
    mem = model.edge_member >= 0
    om_e = np.zeros((n, len(model.edges)))
    om_e[:, mem] = omega[:, model.edge_member[mem]]
    quad = np.matmul(model.D, (om_e**2)[..., None] * w)
    sl = model._slot_edges
    if sl.size:  # Coriolis: the slot turns while the block slides, 2 omega s' S u
        cor = np.zeros_like(w)
        cor[:, sl] = 2.0 * (om_e[:, sl] * sd[:, model.edge_slider[sl]])[..., None] \
            * (model.slot_directions(theta) @ _S.T)
        quad = quad - np.matmul(model.D, cor)
    quad = quad.reshape(n, -1)
    rhs_a = np.concatenate([quad, np.zeros((n, len(model.welds)))], axis=1)
    ydd = np.linalg.solve(Ju, rhs_a[..., None])[..., 0]
    alpha, sdd = _split(model, ydd, np.zeros_like(th_drive_rate))
    return omega, sd, alpha, sdd


def _joint_states(model, theta, s, omega, sd, alpha, sdd):
    w = model.edge_vectors(theta, s)
    n = theta.shape[0]
    mem = model.edge_member >= 0
    om_e = np.zeros((n, len(model.edges)))
    al_e = np.zeros((n, len(model.edges)))
    om_e[:, mem] = omega[:, model.edge_member[mem]]
    al_e[:, mem] = alpha[:, model.edge_member[mem]]
    sw = w @ _S.T
    wd = om_e[..., None] * sw
    wdd = al_e[..., None] * sw - (om_e**2)[..., None] * w
    sl = model._fixed_slider_edges
    if sl.size:
        k = model.edge_slider[sl]
        wd[:, sl] = sd[:, k, None] * model.slider_axis[k]
        wdd[:, sl] = sdd[:, k, None] * model.slider_axis[k]
    sl = model._slot_edges
    if sl.size:
        u = model.slot_directions(theta)
        k = model.edge_slider[sl]
        wd[:, sl] += sd[:, k, None] * u
        wdd[:, sl] += sdd[:, k, None] * u + 2.0 * (om_e[:, sl] * sd[:, k])[..., None] * (u @ _S.T)
    r = np.matmul(model.P, w)
    v = np.matmul(model.P, wd)
    a = np.matmul(model.P, wdd)
    return r, v, a


def _unknown_rates(model, theta, s, cols):
    """Rates (n, n_unknowns) of the unknown coordinates at configurations ``theta``, ``s`` (n, ...)."""
    omega, sd, _al, _sdd = _rates(model, theta, s, np.broadcast_to(
        model.drive_speed, (theta.shape[0], model.drive_idx.size)), cols)
    return np.concatenate([omega[:, model.free_members], sd], axis=1)


def _motion(model: _LoopModel, t, crank, y, period):
    th_drive = model.drive_angles(t)
    theta, s = _split(model, y, th_drive)
    cols = model.unknown_columns()
    n = t.size
    if cols.size:
        omega, sd, alpha, sdd = _rates(model, theta, s, np.broadcast_to(model.drive_speed, (n, model.drive_idx.size)), cols)
    else:
        omega = np.zeros_like(theta)
        omega[:, model.drive_idx] = model.drive_speed
        alpha = np.zeros_like(theta)
        sd = sdd = np.zeros_like(s)
    res = model.residual(theta, s)
    resid = float(np.max(np.abs(res))) if res.size else 0.0
    model.check_slots(s, crank)
    r, v, a = _joint_states(model, theta, s, omega, sd, alpha, sdd)
    names, theta, omega, alpha, ref = _with_passive(model, r, v, a, theta, omega, alpha)
    return Motion(model.mech.name, t, crank, period, model.joint_names, names,
                  model.slider_names, r, v, a, theta, omega, alpha, s, sd, sdd, resid, ref)


def _with_passive(model, r, v, a, theta, omega, alpha):
    """Append the chord angle, its rate and acceleration of every passive link."""
    if not model.passive:
        return model.member_names, theta, omega, alpha, model.theta0.copy()
    th, om, al, ref = [], [], [], []
    for name in model.passive:
        lk = model.mech.links[name]
        ia, ib = model.jindex[lk.a], model.jindex[lk.b]
        d, dd, ddd = r[:, ib] - r[:, ia], v[:, ib] - v[:, ia], a[:, ib] - a[:, ia]
        n2 = np.einsum("nd,nd->n", d, d)
        cross1 = d[:, 0] * dd[:, 1] - d[:, 1] * dd[:, 0]
        cross2 = d[:, 0] * ddd[:, 1] - d[:, 1] * ddd[:, 0]
        dot1 = np.einsum("nd,nd->n", d, dd)
        th.append(np.arctan2(d[:, 1], d[:, 0]))
        om.append(cross1 / n2)
        al.append(cross2 / n2 - 2.0 * dot1 * cross1 / n2**2)
        pa, pb = np.array(model.mech.joints[lk.a].at), np.array(model.mech.joints[lk.b].at)
        ref.append(math.atan2(pb[1] - pa[1], pb[0] - pa[0]))
    cat = lambda x, y: np.concatenate([x, np.stack(y, axis=1)], axis=1)  # noqa: E731
    return (model.member_names + model.passive, cat(theta, th), cat(omega, om), cat(alpha, al),
            np.concatenate([model.theta0, ref]))
