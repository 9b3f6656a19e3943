"""Rigid-body kinematics of planar linkages by loop closure.

Every member (link or rigid body) is a rigid body with one unknown angle;
every slider has one unknown travel along its line. The joint graph (joints
plus the frame) is spanned by a tree grown from the frame; each chord (an
edge not in the tree) closes one independent loop and gives two loop
closure equations ``sum of member vectors around the loop = 0``. Welded
joints and clamped ground joints add angle equations. Drives prescribe the
angles of driven members, ``theta = theta_0 + speed * t``.

Positions come from Newton's method with continuation from time node to
time node (a second-order Taylor predictor, step halving on failure);
velocities and accelerations from the linear velocity and acceleration
equations (no finite differences), solved for all time nodes at once.

This module solves for the positions and holds :class:`Cycle` and the public functions; the
:class:`~kedfem.motion.record.Motion` record is in :mod:`kedfem.motion.record`, the loop-closure
model (tree, loops, residuals, Jacobian) in :mod:`kedfem.motion.loops`, and the velocity and
acceleration equations in :mod:`kedfem.motion.rates`.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from ..errors import InputError, KinematicsError, MobilityError
from ..model.materials import real
from ..model.mechanism import Mechanism
from .loops import _LoopModel, _split
from .rates import _motion, _rates, _unknown_rates, _with_passive
from .record import Motion, slot_direction

__all__ = ["Motion", "Cycle", "kinematics", "kinematics_at", "static_motion", "slot_direction"]

log = logging.getLogger(__name__)

#: Most instants of one kinematics call (a 0.005 degree crank step; the solver's own limit is far below)
MAX_NODES = 100_000


def _newton(model, y, th_drive, cols, tol, max_iter=12):
    """Newton on the loop equations at one time node; returns (y, ok, resnorm, cond)."""
    res_norm = np.inf
    for _ in range(max_iter):
        theta, s = _split(model, y, th_drive)
        w = model.edge_vectors(theta, s)
        res = model.residual(theta, s, w)
        res_norm = float(np.max(np.abs(res))) if res.size else 0.0
        J = model.jacobian(theta, s, w)[:, cols]
        if res_norm <= tol:
            return y, True, res_norm, J
        try:
            dy = np.linalg.solve(J, -res)
        except np.linalg.LinAlgError:
            return y, False, res_norm, None
        y = y + dy
    return y, False, res_norm, None


class Cycle:
    """Rigid-body motion of a driven mechanism at any instants of its cycle.

    The assembly branch is followed once, by continuation on a coarse grid
    (36 steps, about 10 degrees of crank, with step halving); positions at
    any instants then start from a cubic Hermite interpolation of the coarse
    solution and its exact rates and are corrected by Newton's method for
    all instants at once. Build one and call :meth:`at` as often as needed
    (the time discretisations of a solve, its output grid).

    Parameters
    ----------
    mechanism : Mechanism
        A driven single-degree-of-freedom linkage.

    Raises
    ------
    MobilityError, KinematicsError
        As :func:`kinematics`.
    """

    #: steps of the coarse continuation grid
    COARSE = 36
    #: the continuation marches through every STRIDE-th instant of the coarse grid; the others
    #: are solved together from the marched ones (:func:`_coarse_march`)
    STRIDE = 3

    def __init__(self, mechanism: Mechanism):
        model = _LoopModel(mechanism)
        if not mechanism.drives:
            raise InputError(f"{mechanism.name}: has no drive, so it has no cycle; "
                             "use static_motion() for a structure")
        self.mechanism = mechanism
        self.model = model
        self.period = period = mechanism.period
        model.check_mobility()
        self.tol = tol = 1e-14 * model.scale()
        _check_reference(model, tol)
        self.y0 = y0 = np.concatenate([model.theta0[model.free_members],
                                       np.zeros(len(model.slider_names))])
        cols = model.unknown_columns()
        n_c = self.COARSE
        self.h = h = period / n_c
        self.tc = tc = np.arange(n_c + 1) * h
        yc = _coarse_march(model, tc, y0, tol, cols, self.STRIDE)
        self.yc = yc
        if cols.size:
            theta, sl = _split(model, yc, model.drive_angles(tc))
            model.check_slots(sl, model.drive_angles(tc)[:, 0])
            self.ydc = _unknown_rates(model, theta, sl, cols)
        else:
            self.ydc = np.zeros_like(yc)
        # close the cycle: continuing to t = T must return to the reference configuration
        if not _closes(model, y0, yc[-1]):
            raise KinematicsError(f"{mechanism.name}: the motion does not return to the reference "
                                  "configuration after one cycle (the linkage switched assembly branch)")

    def at_speed(self, mechanism: Mechanism) -> "Cycle":
        """The cycle of ``mechanism``, the same linkage at another drive speed (every drive scaled
        alike, as :meth:`~kedfem.model.mechanism.Mechanism.with_speed` makes it, turning the same
        way): the coarse positions at each phase are this cycle's, their rates scaled by the speed
        ratio, so the continuation of the assembly branch is not made again (a continuation in
        speed makes a cycle at every step). Positions at any instants are then corrected by
        Newton's method as in a cycle of its own.

        Raises
        ------
        InputError
            The drives do not turn at this cycle's speeds times one positive ratio.
        """
        ratio = mechanism.drives[0].speed / self.mechanism.drives[0].speed if mechanism.drives else 0.0
        mine = [(d.member, d.ground_joint) for d in self.mechanism.drives]
        if not (ratio > 0.0 and [(d.member, d.ground_joint) for d in mechanism.drives] == mine
                and all(math.isclose(d.speed, ratio * e.speed, rel_tol=1e-12)
                        for d, e in zip(mechanism.drives, self.mechanism.drives))):
            raise InputError(f"{mechanism.name}: at_speed needs the same drives at one positive ratio of the speeds")
        new = object.__new__(Cycle)
        new.mechanism, new.model = mechanism, _LoopModel(mechanism)
        new.period = mechanism.period
        new.tol, new.y0 = self.tol, self.y0
        new.h = new.period / self.COARSE
        new.tc = np.arange(self.COARSE + 1) * new.h
        new.yc, new.ydc = self.yc, self.ydc * ratio
        return new

    def positions(self, t: np.ndarray) -> np.ndarray:
        """Unknown coordinates (free angles, slider travels) at instants ``t`` in ``[0, T]``."""
        model, tol, y0 = self.model, self.tol, self.y0
        cols = model.unknown_columns()
        n = t.size
        if cols.size == 0:
            return np.broadcast_to(y0, (n, y0.size)).copy()
        k = np.clip((t / self.h).astype(int), 0, self.COARSE - 1)
        guess = _hermite(self.tc, self.yc, self.ydc, k, t)
        thd = model.drive_angles(t)
        y, ok = _newton_all(model, guess, thd, cols, tol)
        if ok and np.max(np.abs(y - guess)) < 1e-3:
            J = model.jacobian(*_split(model, y, thd))[:, :, cols]
            cond = np.linalg.cond(J)
            bad = np.flatnonzero(~np.isfinite(cond) | (cond > 1e10))
            if bad.size:
                _fail(model, y[bad[0]], thd[bad[0]], t[bad[0]], 0.0, toggle=True)
            return y
        log.debug("kinematics: batched Newton did not settle; marching through all %d instants", n)
        order = np.argsort(t, kind="stable")
        ys = np.empty((n, y0.size))
        ys[order] = _march(model, t[order], y0, tol)
        return ys

    def at(self, times) -> Motion:
        """Motion at instants ``times`` [s] in ``[0, T]`` (``T`` is the reference again).

        Parameters
        ----------
        times : array_like of float, shape (n,)

        Returns
        -------
        Motion
        """
        period = self.period
        try:
            t = np.asarray(times, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"kinematics: times must be an array of instants [s], got {times!r:.80}") from None
        if t.size > MAX_NODES:
            raise InputError(f"kinematics: at most {MAX_NODES} instants, got {t.size}")
        if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)) \
                or t.min() < 0.0 or t.max() > period * (1 + 1e-12):
            raise InputError(f"kinematics: times must be a non-empty 1-D array of instants in "
                             f"[0, {period:.6g}] s (one cycle), got {np.asarray(times)!r:.80}")
        end = t >= period
        y = self.positions(np.where(end, 0.0, t))
        y[end] = self.yc[-1]  # the end of the cycle (angles continued, not wrapped)
        crank = self.model.drive_angles(t)[:, 0]
        return _motion(self.model, t, crank, y, period)


def _hermite(tk, yk, ydk, k, t):
    """Cubic Hermite interpolant (n, n_unknowns) at instants ``t`` (n,) of positions ``yk`` and
    rates ``ydk`` on the equally spaced instants ``tk``, ``t`` in the interval ``k`` (n,)."""
    h = tk[1] - tk[0]
    u = ((t - tk[k]) / h)[:, None]
    return ((2 * u**3 - 3 * u**2 + 1) * yk[k] + (u**3 - 2 * u**2 + u) * h * ydk[k]
            + (-2 * u**3 + 3 * u**2) * yk[k + 1] + (u**3 - u**2) * h * ydk[k + 1])


def _newton_all(model, y, thd, cols, tol, max_iter: int = 8):
    """Newton's method on the loop equations at all instants at once from ``y`` (n, n_unknowns).

    Returns the positions and whether every residual met ``tol`` (False also when a Jacobian
    is singular).
    """
    for _ in range(max_iter):
        theta, s = _split(model, y, thd)
        w = model.edge_vectors(theta, s)
        res = model.residual(theta, s, w)
        if np.max(np.abs(res)) <= tol:
            return y, True
        J = model.jacobian(theta, s, w)[:, :, cols]
        try:
            y = y + np.linalg.solve(J, -res[..., None])[..., 0]
        except np.linalg.LinAlgError:
            return y, False
    return y, False


def _closes(model, y0, yT) -> bool:
    """The positions ``yT`` after a cycle are the reference ``y0`` (free angles up to whole turns)."""
    nfree = model.free_members.size
    wrap = yT.copy()
    wrap[:nfree] = y0[:nfree] + np.round((yT[:nfree] - y0[:nfree]) / (2 * math.pi)) * 2 * math.pi
    return bool(np.max(np.abs(yT - wrap), initial=0.0) <= 1e-8)


def _coarse_march(model, tc, y0, tol, cols, stride):
    """Positions (n_c + 1, n_unknowns) on the coarse grid ``tc`` (``tc[0] = 0`` at ``y0``).

    The continuation (:func:`_march`, with its step halving and its guards against toggles and
    branch jumps) goes through every ``stride``-th instant; the instants between are solved
    together by Newton's method from the cubic Hermite interpolant of the marched positions and
    their exact rates. Where that does not settle to the tolerance close to the interpolant
    (within the branch-jump guard of a continuation step), at a well-conditioned configuration,
    the continuation goes through every instant instead.
    """
    n_c = tc.size - 1

    def full():
        return np.vstack([y0[None], _march(model, tc[1:], y0, tol)])

    if stride <= 1 or not cols.size or n_c % stride:
        return full()
    tm = tc[::stride]
    try:  # longer steps near a toggle may jump branch (or fail) where the full march does not
        ym = np.vstack([y0[None], _march(model, tm[1:], y0, tol)])
    except KinematicsError:
        return full()
    ydm = _unknown_rates(model, *_split(model, ym, model.drive_angles(tm)), cols)
    # the instants between: cubic Hermite guesses from the marched interval they are in
    j = np.arange(1, n_c)
    j = j[j % stride != 0]
    k = j // stride
    guess = _hermite(tm, ym, ydm, k, tc[j])
    thd = model.drive_angles(tc[j])
    y, ok = _newton_all(model, guess, thd, cols, tol)
    yc = np.empty((n_c + 1, y0.size))
    yc[::stride] = ym
    if ok:
        yc[j] = y
        nf = model.free_members.size
        step = np.max(np.abs(ym[k + 1, :nf] - ym[k, :nf]), axis=1, initial=0.0)
        jump = np.max(np.abs(y - guess), axis=1)
        J = model.jacobian(*_split(model, yc, model.drive_angles(tc)))[:, :, cols]
        cond = np.linalg.cond(J)
        # one assembly branch all through the cycle: the Jacobian's determinant keeps its sign
        # (the branches meet where it vanishes, at a toggle); a march that jumped branch near a
        # toggle and back at another closes the cycle with a wrong motion between
        sign = np.sign(np.linalg.det(J))
        ok = bool(np.all(jump <= 0.05 + 0.5 * step) and np.all(np.isfinite(cond)) and np.all(cond <= 1e10)
                  and np.all(sign == sign[0]) and sign[0] != 0 and _closes(model, y0, yc[-1]))
    if not ok:
        log.debug("kinematics: the coarse grid from the marched instants is not one settled branch; "
                  "marching through all of it")
        return full()
    return yc


def _march(model, targets_t, y0, tol, max_depth=8):
    """Continuation of the positions through the times ``targets_t``."""
    cols = model.unknown_columns()
    ys = np.empty((targets_t.size, y0.size))
    y = y0.copy()
    t_prev = 0.0
    yd_prev = None
    for k, t in enumerate(targets_t):
        y, t_prev, yd_prev = _advance(model, y, t_prev, t, yd_prev, cols, tol, max_depth)
        ys[k] = y
    return ys


def _advance(model, y, t0, t1, yd0, cols, tol, max_depth):
    """Advance the solution from t0 to t1 with a Taylor predictor and step halving."""
    if t1 == t0:
        thd = model.drive_angles(np.array(t1))
        y2, ok, res, J = _newton(model, y, thd, cols, tol)
        if not ok:
            _fail(model, y, thd, t1, res)
        return y2, t1, yd0
    stack = [(t0, t1, 0)]
    cur_t, cur_y = t0, y
    while stack:
        a, b, depth = stack.pop()
        thd = model.drive_angles(np.array(b))
        pred = cur_y
        if model.drive_idx.size and cols.size:
            theta, s = _split(model, cur_y, model.drive_angles(np.array(a)))
            omega, sd, alpha, sdd = _rates(model, theta[None], s[None], model.drive_speed[None], cols)
            vel = np.concatenate([omega[0, model.free_members], sd[0]])
            acc = np.concatenate([alpha[0, model.free_members], sdd[0]])
            h = b - a
            pred = cur_y + vel * h + 0.5 * acc * h * h
        y2, ok, res, J = _newton(model, pred, thd, cols, tol)
        if ok:
            # guard against branch jumps: the correction must be small against the step
            step = np.max(np.abs(y2[: model.free_members.size] - cur_y[: model.free_members.size]),
                          initial=0.0)
            jump = np.max(np.abs(y2 - pred), initial=0.0)
            if jump > 0.05 + 0.5 * step and depth < max_depth:
                ok = False
        if ok:
            cond = np.linalg.cond(J) if J is not None and J.size else 1.0
            if not np.isfinite(cond) or cond > 1e10:
                ok = False
                if depth >= max_depth:
                    _fail(model, y2, thd, b, res, toggle=True)
        if ok:
            cur_t, cur_y = b, y2
            continue
        if depth >= max_depth:
            _fail(model, cur_y, thd, b, res)
        mid = 0.5 * (a + b)
        stack.append((mid, b, depth + 1))
        stack.append((a, mid, depth + 1))
    return cur_y, cur_t, None


def _fail(model, y, thd, t, res, toggle=False):
    theta, s = _split(model, y, thd)
    r = model.residual(theta, s)
    nc = len(model.chords)
    worst = ""
    if nc:
        per_loop = np.abs(r[: 2 * nc]).reshape(nc, 2).max(axis=1)
        worst = model.loop_names[int(np.argmax(per_loop))]
    crank = None
    if model.drive_idx.size:
        crank = math.degrees(float(model.drive_angles(np.array(t))[0]))
    where = f" at crank angle {crank:.3f} deg" if crank is not None else ""
    what = ("reaches a toggle (dead-centre or limit) position" if toggle
            else "cannot be assembled")
    raise KinematicsError(
        f"{model.mech.name}: the linkage {what}{where}: loop {worst or '(none)'} does not close "
        f"(residual {res:.3g} m); a crank of a non-Grashof linkage cannot rotate fully, "
        "and a linkage through a toggle position has no unique motion")


def _check_reference(model, tol):
    """Positions of the reference configuration must satisfy the loops."""
    theta = model.theta0.copy()
    s = np.zeros(len(model.slider_names))
    res = model.residual(theta, s)
    scale = model.scale()
    bad = np.flatnonzero(np.abs(res) > 1e-9 * scale)
    if bad.size:
        nc = len(model.chords)
        i = int(bad[0])
        if i < 2 * nc:
            where = f"loop {model.loop_names[i // 2]}"
        else:
            where = model.welds[i - 2 * nc][3]
        raise KinematicsError(f"{model.mech.name}: the reference configuration (the at= positions) "
                              f"does not close {where} (residual {abs(res[i]):.3g})")
    J = model.jacobian(theta, s)[:, model.unknown_columns()]
    if J.size:
        sv = np.linalg.svd(J, compute_uv=False)
        if sv[-1] < 1e-10 * max(sv[0], 1.0):
            raise MobilityError(f"{model.mech.name}: the loop equations are singular in the reference "
                                "configuration (a redundant constraint, a free member, or a toggle position)")


def kinematics(mechanism: Mechanism, steps: int = 360, *, times=None) -> Motion:
    """Rigid-body motion over one cycle of the first drive.

    Parameters
    ----------
    mechanism : Mechanism
        A single-degree-of-freedom linkage (one drive, or several
        synchronised drives matching its mobility).
    steps : int
        Number of time nodes ``n`` (>= 3); ``t_k = k T / n``, ``k = 0..n-1``.
    times : array_like of float, shape (n,), optional
        Instead of ``steps``: any instants of the cycle [s], in ``[0, T]``
        (the collocation instants of a time discretisation, a fine output
        grid); ``T`` itself is the reference configuration again. For many
        calls on one mechanism build a :class:`Cycle` once.

    Returns
    -------
    Motion
        Positions, velocities and accelerations of all joints and members.

    Raises
    ------
    MobilityError
        The mobility does not match the drives.
    KinematicsError
        The linkage cannot complete the cycle (names the loop and crank angle).
    """
    if times is None:
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 3 <= steps <= MAX_NODES:
            raise InputError(f"kinematics: steps must be an integer in 3 .. {MAX_NODES}, got {steps!r}")
    cyc = Cycle(mechanism)
    if times is None:
        times = np.arange(steps) * (cyc.period / steps)
    mo = cyc.at(times)
    log.debug("kinematics of %s: %d instants, residual %.3g m", mechanism.name, mo.n, mo.residual)
    return mo


def kinematics_at(mechanism: Mechanism, crank_angle: float) -> Motion:
    """Rigid-body state at one crank angle (continuation from the reference).

    Parameters
    ----------
    mechanism : Mechanism
        A driven linkage.
    crank_angle : float
        Absolute angle of the first driven member [rad]; the branch is the
        one reached by turning the crank from the reference configuration in
        its direction of rotation.

    Returns
    -------
    Motion
        With a single time node.
    """
    model = _LoopModel(mechanism)
    crank_angle = real("kinematics_at", "crank_angle [rad]", crank_angle)
    if not mechanism.drives:
        return static_motion(mechanism)
    model.check_mobility()
    tol = 1e-14 * model.scale()
    _check_reference(model, tol)
    w = mechanism.drives[0].speed
    if w == 0.0:
        raise InputError(f"{mechanism.name}: the first drive's speed is zero")
    period = mechanism.period
    dth = (float(crank_angle) - model.theta0[model.drive_idx[0]]) * np.sign(w)
    dth = dth % (2 * math.pi)
    t_target = dth / abs(w)
    n_sub = max(1, int(math.ceil(dth / math.radians(5.0))))
    ts = np.linspace(0.0, t_target, n_sub + 1)[1:]
    y0 = np.concatenate([model.theta0[model.free_members], np.zeros(len(model.slider_names))])
    y = _march(model, ts, y0, tol)[-1:] if ts.size else y0[None]
    t = np.array([t_target])
    crank = model.drive_angles(t)[:, 0]
    return _motion(model, t, crank, y, period)


def static_motion(mechanism: Mechanism) -> Motion:
    """The reference configuration at rest (a structure, or a linkage stopped).

    Returns
    -------
    Motion
        One time node, all velocities and accelerations zero.
    """
    model = _LoopModel(mechanism)
    theta = model.theta0[None].copy()
    s = np.zeros((1, len(model.slider_names)))
    z = np.zeros_like(theta)
    zs = np.zeros_like(s)
    r = np.array([[mechanism.joints[j].at for j in model.joint_names]])
    zero = np.zeros_like(r)
    crank = theta[:, model.drive_idx[0]] if model.drive_idx.size else np.zeros(1)
    names, theta, z, z2, ref = _with_passive(model, r, zero, zero, theta, z, z.copy())
    return Motion(mechanism.name, np.zeros(1), crank, math.inf, model.joint_names, names,
                  model.slider_names, r, zero, zero.copy(), theta, z, z2, s, zs, zs.copy(), 0.0, ref)
