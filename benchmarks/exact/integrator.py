"""Generalised-alpha time integration of the index-3 DAE (Arnold & Bruls 2007).

Equations ``M q_dd + Q(q, q_d) + alpha M q_d - f + G(q, t)^T lam = 0``,
``g(q, t) = 0``. With ``a`` the algorithmic acceleration::

    (1 - am) a_{n+1} + am a_n = (1 - af) q_dd_{n+1} + af q_dd_n
    q_{n+1}   = q_n + h q_d_n + h^2 (1/2 - beta) a_n + h^2 beta a_{n+1}
    q_d_{n+1} = q_d_n + h (1 - gamma) a_n + h gamma a_{n+1}

and the equations of motion and the position constraints enforced at
``t_{n+1}``; ``am = (2 rho - 1)/(rho + 1)``, ``af = rho/(rho + 1)``,
``gamma = 1/2 + af - am``, ``beta = (gamma + 1/2)^2 / 4`` (second order,
spectral radius ``rho_inf`` at infinite frequency). Newton's method on
``dq`` with ``d q_dd = beta' dq``, ``d q_d = gamma' dq``; the saddle-point
system is scaled (equations of motion by ``1/beta'``, constraints and
multipliers by a mass scale) and factorised by SuperLU.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from .model import Model, State

__all__ = ["GeneralizedAlpha", "NewtonFailure"]


class NewtonFailure(RuntimeError):
    pass


class GeneralizedAlpha:
    """Fixed-step generalised-alpha integrator for a :class:`Model`.

    Parameters
    ----------
    model : Model
    h : float
        Time step [s].
    rho_inf : float
        Spectral radius at infinite frequency (1: no numerical dissipation).
    tol : float
        Newton stops when the largest increment of ``q`` is below ``tol``
        (positions in m, slopes dimensionless; Newton converges quadratically,
        so the error left is of the order of the square of that increment
        over the one before) and the constraints hold to ``tol``.
    max_iter : int
        Newton iterations per step.
    """

    def __init__(self, model: Model, h: float, rho_inf: float = 0.9, tol: float = 1e-10, max_iter: int = 30):
        self.model = model
        self.h = float(h)
        r = float(rho_inf)
        self.am = (2 * r - 1) / (r + 1)
        self.af = r / (r + 1)
        self.gamma = 0.5 + self.af - self.am
        self.beta = 0.25 * (self.gamma + 0.5) ** 2
        self.bp = (1 - self.am) / (self.h**2 * self.beta * (1 - self.af))
        self.gp = self.gamma / (self.h * self.beta)
        self.tol = float(tol)
        self.max_iter = int(max_iter)
        md = model.mdiag[model.mdiag > 0]
        if model.els is not None:
            md = np.concatenate([md, np.diagonal(model.els.M, axis1=1, axis2=2).ravel()])
        self.sigma = float(np.mean(md)) if md.size else 1.0
        self.iterations = 0
        self.steps = 0
        self.max_g = 0.0

    def step(self, st: State) -> State:
        """One step from ``st`` (not modified); returns the new state."""
        m = self.model
        h, am, af, be, ga = self.h, self.am, self.af, self.beta, self.gamma
        bp, gp, sig = self.bp, self.gp, self.sigma
        t1 = st.t + h
        if st.prev is not None:            # linear extrapolation of q_dd and lam (predictor only)
            vd = 2.0 * st.vd - st.prev[0]
            lam = 2.0 * st.lam - st.prev[1]
        else:
            vd = st.vd.copy()
            lam = st.lam.copy()
        a1 = (af * st.vd - am * st.a + (1 - af) * vd) / (1 - am)
        q = st.q + h * st.v + h * h * ((0.5 - be) * st.a + be * a1)
        v = st.v + h * ((1 - ga) * st.a + ga * a1)
        n = m.ndof
        Me = m.els.M if m.els is not None else None
        alpha = m.alpha
        cmass = 1.0 + alpha * gp / bp
        for it in range(1, self.max_iter + 1):
            Q, Ke, Ce = m.internal(q, v)
            g, Gv = m.constraints_eval(q, t1)
            r = m.M @ (vd + alpha * v) + Q - m.f_ext
            if m.ncon:
                r += np.bincount(m.G_cols, weights=Gv * lam[m.G_rows], minlength=n)
            if Me is not None:
                blk = Me * cmass + Ke * (1.0 / bp)
                if Ce is not None:
                    blk += Ce * (gp / bp)
            else:
                blk = np.zeros(0)
            diag = m.mdiag * cmass
            hr, hc, hv = m.constraint_hessian(q, t1, lam)
            if hr:
                np.add.at(diag, np.asarray(hr), np.asarray(hv) / bp)
            A = m.saddle(blk, diag, Gv, sig)
            rhs = np.concatenate([-r / bp, -sig * g])
            try:
                x = spla.splu(A).solve(rhs)
            except RuntimeError as exc:
                raise NewtonFailure(f"singular iteration matrix at t = {t1:.6g}: {exc}") from exc
            dq = x[:n]
            q += dq
            v += gp * dq
            vd += bp * dq
            lam += bp * sig * x[n:]
            self.iterations += 1
            if not np.all(np.isfinite(dq)):
                raise NewtonFailure(f"Newton diverged at t = {t1:.6g}")
            if np.max(np.abs(dq)) <= self.tol and (not m.ncon or np.max(np.abs(g)) <= self.tol):
                break
        else:
            raise NewtonFailure(f"Newton did not converge in {self.max_iter} iterations at t = {t1:.6g} "
                                f"(|dq| = {np.max(np.abs(dq)):.3g})")
        if m.ncon:
            gfin, _ = m.constraints_eval(q, t1)
            self.max_g = max(self.max_g, float(np.max(np.abs(gfin))))
        a1 = (af * st.vd - am * st.a + (1 - af) * vd) / (1 - am)
        self.steps += 1
        return State(t1, q, v, vd, a1, lam, (st.vd, st.lam))
