"""Static and modal analyses of the exact model (validation helpers).

* :func:`beam`: a straight beam of ANCF elements with end conditions;
* :func:`static`: Newton's method with load stepping on ``Q(q) = f(q)``, ``g(q) = 0``;
* :func:`modal`: natural frequencies of the linearisation at a configuration;
* :func:`rotating_modal`: relative equilibrium of a beam rotating at constant
  speed about the origin and the frequencies of the gyroscopic linearisation
  about it (in the co-rotating frame).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg as sla

from .model import Builder, Model

__all__ = ["EB_ROOTS", "beam", "static", "modal", "rotating_modal", "tip_moment_load", "tangent", "arc_tip"]

#: Euler-Bernoulli beta_n L for the first modes
EB_ROOTS = {
    ("clamp", "free"): (1.8751040687119611, 4.6940911329741745, 7.8547574382376126),
    ("pin", "pin"): (math.pi, 2 * math.pi, 3 * math.pi),
    ("clamp", "clamp"): (4.730040744862704, 7.853204624095838, 10.995607838001671),
}


def beam(n_el, L=1.0, EA=1e6, EI=1.0, rhoA=1.0, bc=("clamp", "free"), angle=0.0, beta=0.0, ngauss=5,
         gravity=None) -> Model:
    """A straight beam from the origin along ``angle`` with end conditions ``bc`` (clamp / pin / free)."""
    b = Builder()
    e = np.array([math.cos(angle), math.sin(angle)])
    b.point("a", (0.0, 0.0))
    b.point("b", tuple(L * e))
    b.flexible("beam", "a", "b", n_el, EA, EI, rhoA)
    for end, kind in zip(("a", "b"), bc):
        if kind in ("clamp", "pin"):
            b.fix(end)
        if kind == "clamp":
            b.slope("beam", end, angle, 0.0)
    return b.build(beta=beta, ngauss=ngauss, gravity=gravity)


def tangent(model: Model, q):
    """Dense internal force and elastic tangent stiffness at ``q`` (no damping)."""
    n = model.ndof
    Q, Ke, _ = model.internal(q, np.zeros(n))
    K = np.zeros((n, n))
    if Ke is not None:
        idx = model.edofs
        np.add.at(K, (idx[:, :, None], idx[:, None, :]), Ke)
    return Q, K


def tip_moment_load(model: Model, link: str, moment: float):
    """Conservative end moment on ``link``'s end b: ``f = M dphi/dq``, ``phi = atan2(y', x')``."""
    d = model.links[link].nodes[-1, 2:]

    def load(q, lam_load):
        x, y = q[d]
        n2 = x * x + y * y
        f = np.zeros(model.ndof)
        f[d] = moment * lam_load * np.array([-y, x]) / n2
        H = np.array([[2 * x * y, y * y - x * x], [y * y - x * x, -2 * x * y]]) / n2**2
        Kf = np.zeros((model.ndof, model.ndof))
        Kf[np.ix_(d, d)] = moment * lam_load * H          # d f / d q
        return f, Kf
    return load


def static(model: Model, load, q0=None, nsteps=10, tol=1e-12, max_iter=50, t=0.0):
    """Solve ``Q(q) - f(q, lambda) + G^T mu = 0``, ``g(q, t) = 0`` for lambda = 1/nsteps .. 1.

    ``load(q, lam) -> (f, df/dq)`` (dense). Returns ``q, mu``.
    """
    q = model.reference_q() if q0 is None else np.array(q0, float)
    n, m = model.ndof, model.ncon
    mu = np.zeros(m)
    for step in range(1, nsteps + 1):
        lam = step / nsteps
        for it in range(max_iter):
            Q, K = tangent(model, q)
            f, Kf = load(q, lam)
            g, _ = model.constraints_eval(q, t)
            G = model.G(q, t).toarray()
            r = Q - f + G.T @ mu
            A = np.zeros((n + m, n + m))
            A[:n, :n] = K - Kf
            hr, hc, hv = model.constraint_hessian(q, t, mu)
            for i, j, v in zip(hr, hc, hv):
                A[i, j] += v
            A[:n, n:] = G.T
            A[n:, :n] = G
            x = np.linalg.solve(A, -np.concatenate([r, g]))
            q += x[:n]
            mu += x[n:]
            if np.max(np.abs(x[:n])) < tol:
                break
        else:
            raise RuntimeError(f"static: no convergence at load factor {lam}")
    return q, mu


def _reduced(model: Model, q, t=0.0):
    G = model.G(q, t).toarray()
    Z = sla.null_space(G) if G.size else np.eye(model.ndof)
    return Z


def modal(model: Model, q=None, n_modes=6, mu=None):
    """Natural frequencies [rad/s] and mode shapes of the linearisation at ``q`` (default: reference)."""
    q = model.reference_q() if q is None else q
    _, K = tangent(model, q)
    if mu is not None:
        for i, j, v in zip(*model.constraint_hessian(q, 0.0, mu)):
            K[i, j] += v
    M = model.M.toarray()
    Z = _reduced(model, q)
    w2, phi = sla.eigh(Z.T @ K @ Z, Z.T @ M @ Z)
    w = np.sqrt(np.clip(w2, 0.0, None))
    return w[:n_modes], (Z @ phi)[:, :n_modes]


def rotating_modal(model: Model, omega: float, n_modes=4, nsteps=4):
    """Rotating beam (about the origin at speed ``omega``): relative equilibrium and frequencies.

    In the co-rotating frame the ANCF equations read
    ``M p'' + 2 omega M S p' + Q(p) - omega^2 M p + G^T mu = 0`` (the mass
    matrix acts on 2-vectors and commutes with the rotation; Q is objective).

    Returns
    -------
    p : ndarray
        Relative equilibrium coordinates.
    freqs : ndarray
        Frequencies [rad/s] of the linearisation (positive imaginary parts of the
        gyroscopic eigenvalues), ascending.
    """
    if model.bodies:
        raise NotImplementedError("rotating_modal: flexible links only")
    M = model.M.toarray()
    n = model.ndof

    def load(q, lam):
        return lam * omega**2 * (M @ q), lam * omega**2 * M

    p, mu = static(model, load, nsteps=nsteps)
    _, K = tangent(model, p)
    S = np.zeros((n, n))
    for k in range(0, n, 2):
        S[k, k + 1] = -1.0
        S[k + 1, k] = 1.0
    Z = _reduced(model, p)
    Mr = Z.T @ M @ Z
    Gr = Z.T @ (2 * omega * M @ S) @ Z
    Kr = Z.T @ (K - omega**2 * M) @ Z
    r = Mr.shape[0]
    Minv = np.linalg.inv(Mr)
    A = np.block([[np.zeros((r, r)), np.eye(r)], [-Minv @ Kr, -Minv @ Gr]])
    ev = np.linalg.eigvals(A)
    f = np.sort(ev.imag[ev.imag > 1e-9])
    return p, f[:n_modes]


def arc_tip(M0, EA, EI, L):
    """Tip of a cantilever (root at the origin along +x) under an end moment, for this model.

    With ``U = 1/2 int (EA eps^2 + EI kappa^2) ds`` a uniform arc of stretch
    ``eps`` and end angle ``th`` has ``U = L (EA eps^2 + EI th^2 / (L (1+eps))^2) / 2``;
    ``dU/deps = 0`` and ``dU/dth = M0`` give ``eps = M0^2 / (EA EI - M0^2)``,
    ``th = M0 L (1 + eps)^2 / EI`` (``kappa = M0 (1 + eps)/EI``; the inextensible
    ``kappa = M0/EI`` arc for ``EA -> inf``).
    """
    eps = M0**2 / (EA * EI - M0**2)
    th = M0 * L * (1 + eps) ** 2 / EI
    R = L * (1 + eps) / th
    return np.array([R * math.sin(th), R * (1 - math.cos(th))])
