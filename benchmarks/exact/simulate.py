"""Periodic steady state of a driven flexible linkage by marching cycle after cycle."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .integrator import GeneralizedAlpha
from .model import Model, State, from_mechanism

__all__ = ["ExactResult", "simulate", "initial_state"]


@dataclass
class ExactResult:
    """Last cycle of a run, at the step instants ``t_k = k h``, ``k = 0..n-1``.

    Attributes
    ----------
    crank_angle : ndarray (n,)
        Angle of the driven member's rigid-body line [rad] (``th0 + w t``).
    deflection : dict link -> ndarray (n,)
        Mid-span deflection relative to the chord [m]: signed distance of the
        material point at ``s = L/2`` from the line through the link's current
        end points, + to the left of ``a -> b``.
    tip : ndarray (n,) or None
        Driven flexible link: component of its tip displacement (from the
        rigid crank tip at ``th0 + w t``) perpendicular to the rigid crank [m].
    axial : dict link -> ndarray (n,)
        Axial force ``EA (|r'| - 1)`` at mid-span [N].
    moment : dict link -> ndarray (n,)
        Bending moment ``EI kappa`` at mid-span [N m].
    changes : list of float
        Relative change of the tracked histories from one cycle to the next.
    """

    mechanism: str
    elements_per_link: int | None
    steps_per_cycle: int
    beta: float
    alpha: float
    rho_inf: float
    t: np.ndarray
    crank_angle: np.ndarray
    deflection: dict
    tip: np.ndarray | None
    axial: dict
    moment: dict
    wall_time: float
    cycles: int
    changes: list
    converged: bool
    max_constraint: float
    newton_per_step: float
    ndof: int
    ncon: int
    extrapolations: int = 0
    state: State = field(repr=False, default=None)
    model: Model = field(repr=False, default=None)
    q_cycle: np.ndarray | None = field(repr=False, default=None)

    def peak(self, quantity: str) -> float:
        """Largest absolute value over the cycle of ``"tip"`` or a link's mid-span deflection."""
        h = self.tip if quantity == "tip" else self.deflection[quantity]
        return float(np.max(np.abs(h)))

    def history(self, quantity: str) -> np.ndarray:
        return self.tip if quantity == "tip" else self.deflection[quantity]


def _rigid_motion(mech):
    import kedfem as kf
    mo = kf.kinematics(mech, times=np.array([0.0]))
    r = {j: mo.r[0, i] for i, j in enumerate(mo.joint_names)}
    v = {j: mo.v[0, i] for i, j in enumerate(mo.joint_names)}
    a = {j: mo.a[0, i] for i, j in enumerate(mo.joint_names)}
    om = {m: float(mo.omega[0, i]) for i, m in enumerate(mo.member_names)}
    al = {m: float(mo.alpha[0, i]) for i, m in enumerate(mo.member_names)}
    th = {m: float(mo.theta[0, i]) for i, m in enumerate(mo.member_names)}
    thref = {m: float(mo.theta_ref[i]) for i, m in enumerate(mo.member_names)}
    return mo, r, v, a, om, al, th, thref


def initial_state(model: Model, mech) -> State:
    """The undeformed mechanism in its reference configuration, moving rigidly (t = 0)."""
    mo, r, v, a, om, al, th, thref = _rigid_motion(mech)
    body_phi = {name: th[name] - thref[name] for name in model.bodies}
    return model.rigid_state(r, v, a, om, al, th, 0.0, body_phi, om, al)


class _Readout:
    """Tracked quantities of a model from a cycle of states."""

    def __init__(self, model: Model, mech, info):
        self.model = model
        self.links = list(model.links)
        self.info = info
        self.drive_flex = info["drive"] in model.links
        if self.drive_flex:
            lk = mech.links[info["drive"]]
            g = info["ground"]
            tipj = lk.b if lk.a == g else lk.a
            self.tip_joint = tipj
            self.ground_at = np.array(mech.joints[g].at)
            self.tip_ref = np.array(mech.joints[tipj].at)
            pa, pb = np.array(mech.joints[lk.a].at), np.array(mech.joints[lk.b].at)
            self.th_link0 = math.atan2(pb[1] - pa[1], pb[0] - pa[0])
        self.w = info["w"]

    def __call__(self, Q, tau):
        """``Q`` (n, ndof) states at cycle times ``tau`` (n,) from the cycle start."""
        m = self.model
        defl, axial, moment = {}, {}, {}
        for name in self.links:
            lk = m.links[name]
            defl[name] = m.chord_deflection(Q, name, 0.5)
            eps, kap = m.link_strain(Q, name, [0.5 * lk.length])
            axial[name] = lk.EA * eps[:, 0]
            moment[name] = lk.EI * kap[:, 0]
        tip = None
        if self.drive_flex:
            dth = self.w * tau
            c, s = np.cos(dth), np.sin(dth)
            d0 = self.tip_ref - self.ground_at
            rigid = self.ground_at + np.stack([c * d0[0] - s * d0[1], s * d0[0] + c * d0[1]], -1)
            th = self.th_link0 + dth
            nrm = np.stack([-np.sin(th), np.cos(th)], -1)
            r_tip = Q[:, m.pdofs[self.tip_joint]]
            tip = np.sum(nrm * (r_tip - rigid), -1)
        return defl, tip, axial, moment

    def tracked(self, defl, tip):
        out = dict(defl)
        if tip is not None:
            out["tip"] = tip
        return out


def _rre(starts, model: Model, T: float):
    """Reduced-rank extrapolation of a sequence of cycle-start states to the periodic one.

    Near the steady state the cycle map is affine, ``x_{i+1} - x* = A (x_i - x*)``,
    and the transient lives in the few slowest modes: the combination of the
    iterates with weights summing to one that minimises the norm of the combined
    differences removes them. Driven body angles (``phi = w t``) drift by ``w T`` per
    cycle and are made periodic before combining. Returns None when the weights are
    ill-conditioned.
    """
    from .model import BodyAngle
    drift = [(c.dof, c.w) for c in model.constraints if isinstance(c, BodyAngle)]
    t_last = starts[-1].t

    def qq(st):
        q = st.q.copy()
        for d, w in drift:
            q[d] -= w * (st.t - t_last)
        return q
    qs = [qq(st) for st in starts]
    scale_v = T / (2 * math.pi)
    Y = np.array([np.concatenate([q, scale_v * st.v]) for q, st in zip(qs, starts)])
    U = np.diff(Y, axis=0)
    Gm = U @ U.T
    Gm += np.eye(len(Gm)) * 1e-13 * np.trace(Gm)
    try:
        c = np.linalg.solve(Gm, np.ones(len(Gm)))
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(c)) or abs(c.sum()) < 1e-300:
        return None
    g = c / c.sum()
    if np.sum(np.abs(g)) > 1e3:
        return None
    later = starts[1:]
    q = sum(gi * q for gi, q in zip(g, qs[1:]))
    fields = [sum(gi * getattr(st, f) for gi, st in zip(g, later)) for f in ("v", "vd", "a", "lam")]
    return State(t_last, q, *fields)


def simulate(mech, *, elements_per_link=None, steps_per_cycle=720, beta=0.0, alpha=0.0, gravity=False,
             cycles_max=60, tol=1e-7, rho_inf=0.9, ngauss=5, newton_tol=1e-10, init=None,
             cycles_min=2, keep_states=False, accelerate=True, rre_k=6, verbose=False) -> ExactResult:
    """Periodic steady state of ``mech`` with the geometrically exact ANCF model.

    Parameters
    ----------
    mech : kedfem.Mechanism
    elements_per_link : int, optional
        ANCF elements per flexible link (default: each link's ``elements``).
    steps_per_cycle : int
        Fixed generalised-alpha steps per drive cycle.
    beta, alpha : float
        Stiffness-proportional damping on the strain rates [s] and
        mass-proportional damping [1/s].
    gravity : bool
        Apply ``mech.gravity``.
    cycles_max : int
        Stop after this many cycles even if not periodic (``converged=False``).
    tol : float
        Steady state when every tracked history (mid-span deflections, crank
        tip) changes over one cycle by less than ``tol`` times its peak.
    rho_inf : float
        Generalised-alpha spectral radius at infinite frequency.
    init : ExactResult, optional
        Start from the last cycle-start state of an earlier run of the same
        mechanism (another mesh or step: carried over by the exact Hermite
        interpolation of the fields).
    keep_states : bool
        Keep the last cycle's states ``q`` (n, ndof) in ``q_cycle``.
    accelerate : bool
        Every ``rre_k + 1`` cycle-start states, jump to their reduced-rank
        extrapolation (only a better start: the steady state is still
        accepted only by the change of the histories over a whole cycle).

    Returns
    -------
    ExactResult
    """
    t_start = time.perf_counter()
    model, info = from_mechanism(mech, elements_per_link=elements_per_link, beta=beta, alpha=alpha,
                                 gravity=gravity, ngauss=ngauss)
    T = mech.period
    n = int(steps_per_cycle)
    h = T / n
    if init is None:
        st = initial_state(model, mech)
    else:
        st = model.map_state(init.state, init.model)
        st.a = st.vd.copy()
    integ = GeneralizedAlpha(model, h, rho_inf=rho_inf, tol=newton_tol)
    read = _Readout(model, mech, info)
    th0 = info["th0"] if info["drive"] in mech.links else 0.0
    if info["drive"] in mech.links:
        lk = mech.links[info["drive"]]
        pa, pb = np.array(mech.joints[lk.a].at), np.array(mech.joints[lk.b].at)
        th0 = math.atan2(pb[1] - pa[1], pb[0] - pa[0])
    tau = np.arange(n) * h
    prev = None
    changes = []
    converged = False
    Q = np.empty((n, model.ndof))
    cycle = 0
    starts = [st.copy()]
    n_extrap = 0
    for cycle in range(1, cycles_max + 1):
        for k in range(n):
            Q[k] = st.q
            st = integ.step(st)
        defl, tip, axial, moment = read(Q, tau)
        cur = read.tracked(defl, tip)
        if prev is not None:
            ch = max(float(np.max(np.abs(cur[k] - prev[k])) / max(np.max(np.abs(cur[k])), 1e-300)) for k in cur)
            changes.append(ch)
            if verbose:
                print(f"  cycle {cycle}: change {ch:.3e}  ({time.perf_counter() - t_start:.1f} s)", flush=True)
            if ch < tol and cycle >= cycles_min:
                converged = True
                break
        prev = cur
        starts.append(st.copy())
        if accelerate and len(starts) >= rre_k + 1 and cycle < cycles_max - 1:
            x = _rre(starts[-(rre_k + 1):], model, T)
            if x is not None:
                st = x
                prev = None
                n_extrap += 1
                if verbose:
                    print(f"  cycle {cycle}: extrapolated", flush=True)
            starts = [st.copy()]
    wall = time.perf_counter() - t_start
    return ExactResult(
        mechanism=mech.name, elements_per_link=elements_per_link, steps_per_cycle=n, beta=beta, alpha=alpha,
        rho_inf=rho_inf, t=tau.copy(), crank_angle=th0 + info["w"] * tau, deflection=defl, tip=tip,
        axial=axial, moment=moment, wall_time=wall, cycles=cycle, changes=changes, converged=converged,
        max_constraint=integ.max_g, newton_per_step=integ.iterations / max(integ.steps, 1),
        ndof=model.ndof, ncon=model.ncon, extrapolations=n_extrap, state=st, model=model, q_cycle=Q.copy() if keep_states else None)
