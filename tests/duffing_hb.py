"""An independent reference for the forced cubic oscillator of tests/test_continuation.py: harmonic
balance with many harmonics, pseudo-arclength continuation in the forcing frequency, and folds
located as solutions of the extended system (residual = 0, Jacobian singular along a null vector).

Nothing of kedfem is used: the model is the closed-form Euler-Bernoulli cantilever element
(one element, tip DOFs ``v`` and ``theta``, consistent mass) with a tip mass, a linear drive
spring ``k_d`` excited by a crank of radius ``e`` (force ``k_d e (cos w t - 1)``), a cubic spring
``k3 v^3`` to the frame, and mass-proportional damping ``alpha M``::

    M q'' + alpha M q' + K q + [k3 v^3, 0] = [k_d e (cos w t - 1), 0]

Residuals in the frequency domain by alternating frequency-time (AFT) on ``NT`` samples;
Newton's method with the analytic Jacobian; arclength in ``(coefficients, w)``.
"""

from __future__ import annotations

import math

import numpy as np

H = 15       # harmonics
NT = 128     # time samples of the AFT


class Rig:
    """The oscillator's matrices and forcing (SI)."""

    def __init__(self, L, b, h, E, rho, mt, kd, k3, e, alpha):
        EI = E * b * h ** 3 / 12.0
        m = rho * b * h * L
        self.K = EI / L ** 3 * np.array([[12.0, -6 * L], [-6 * L, 4 * L * L]]) + np.diag([kd, 0.0])
        self.M = m / 420.0 * np.array([[156.0, -22 * L], [-22 * L, 4 * L * L]]) + np.diag([mt, 0.0])
        self.C = alpha * self.M
        self.k3, self.kd, self.e = k3, kd, e
        self.n = 2
        t = np.arange(NT) * (2 * math.pi / NT)
        k = np.arange(H + 1)
        # real Fourier basis: coefficient order (c0, c1, s1, c2, s2, ...) per DOF
        cols = [np.ones(NT)]
        dcols = [np.zeros(NT)]
        for j in range(1, H + 1):
            cols += [np.cos(j * t), np.sin(j * t)]
            dcols += [np.zeros(NT), np.zeros(NT)]
        self.B = np.stack(cols, axis=1)                       # (NT, 2H+1): q(t) = B a
        self.P = np.linalg.pinv(self.B)                       # projection onto the harmonics
        m_ = 2 * H + 1
        D = np.zeros((m_, m_))                                # d/d(wt) on the coefficients
        for j in range(1, H + 1):
            D[2 * j - 1, 2 * j] = j
            D[2 * j, 2 * j - 1] = -j
        self.D = D
        self.m = m_
        f = np.zeros(m_)
        f[0] = -kd * e
        f[1] = kd * e
        self.f = f                                            # forcing on v

    def unpack(self, a):
        return a.reshape(self.n, self.m)

    def residual(self, a, w):
        A = self.unpack(a)                                    # (2, m)
        Dt = self.D.T
        vel = A @ Dt * w
        acc = A @ Dt @ Dt * w * w
        R = self.M @ acc + self.C @ vel + self.K @ A
        v = self.B @ A[0]
        R[0] += self.P @ (self.k3 * v ** 3)
        R[0] -= self.f
        return R.ravel()

    def jacobian(self, a, w):
        n, m = self.n, self.m
        A = self.unpack(a)
        Dt = self.D.T
        I = np.eye(m)
        J = np.zeros((n * m, n * m))
        L = w * w * (Dt @ Dt)
        V = w * Dt
        for i in range(n):
            for j in range(n):
                blk = self.M[i, j] * L.T + self.C[i, j] * V.T + self.K[i, j] * I
                J[i * m:(i + 1) * m, j * m:(j + 1) * m] = blk
        v = self.B @ A[0]
        J[:m, :m] += self.P @ ((3 * self.k3 * v ** 2)[:, None] * self.B)
        return J

    def dR_dw(self, a, w):
        A = self.unpack(a)
        Dt = self.D.T
        return (self.M @ (A @ Dt @ Dt * 2 * w) + self.C @ (A @ Dt)).ravel()

    def solve(self, a0, w, tol=1e-13, it=60):
        a = a0.copy()
        for _ in range(it):
            R = self.residual(a, w)
            da = np.linalg.solve(self.jacobian(a, w), -R)
            a += da
            if np.linalg.norm(da) <= tol * max(np.linalg.norm(a), 1e-30):
                return a
        raise RuntimeError(f"harmonic balance did not converge at w = {w}")

    def linear(self, w):
        return self.solve(np.zeros(self.n * self.m), w)

    def peak_v(self, a, samples=2048):
        """max |v(t)| over the cycle, on ``samples`` instants."""
        t = np.arange(samples) * (2 * math.pi / samples)
        A = self.unpack(a)
        v = A[0, 0] + sum(A[0, 2 * j - 1] * np.cos(j * t) + A[0, 2 * j] * np.sin(j * t) for j in range(1, H + 1))
        return float(np.abs(v).max())

    def branch(self, w_lo, w_hi, ds=0.02, max_points=4000):
        """Pseudo-arclength from ``w_lo`` to ``w_hi``: lists of (a, w)."""
        a = self.linear(w_lo)
        pts = [(a, w_lo)]
        w2 = w_lo * 1.001
        pts.append((self.solve(a, w2), w2))
        while len(pts) < max_points and pts[-1][1] < w_hi:
            (a1, w1), (a2, w2) = pts[-2], pts[-1]
            sa, sw = np.linalg.norm(a2), w2
            t = np.concatenate([(a2 - a1) / sa, [(w2 - w1) / sw]])
            t /= np.linalg.norm(t)
            x = np.concatenate([a2 / sa, [w2 / sw]]) + ds * t
            for _ in range(40):
                a, w = x[:-1] * sa, x[-1] * sw
                R = self.residual(a, w)
                N = t @ (x - np.concatenate([a2 / sa, [w2 / sw]])) - ds
                J = np.zeros((R.size + 1, R.size + 1))
                J[:-1, :-1] = self.jacobian(a, w) * sa
                J[:-1, -1] = self.dR_dw(a, w) * sw
                J[-1] = t
                dx = np.linalg.solve(J, -np.concatenate([R, [N]]))
                x += dx
                if np.linalg.norm(dx) < 1e-13 * np.linalg.norm(x):
                    break
            pts.append((x[:-1] * sa, x[-1] * sw))
        return pts

    def fold(self, a0, w0):
        """The fold near ``(a0, w0)``: R = 0, J phi = 0, |phi| = 1 (Newton on the extended system)."""
        J = self.jacobian(a0, w0)
        _u, _s, vt = np.linalg.svd(J)
        phi = vt[-1]
        c = phi.copy()
        a, w = a0.copy(), w0
        nn = a.size
        for _ in range(60):
            R = self.residual(a, w)
            J = self.jacobian(a, w)
            # derivative of J phi w.r.t. a (only the cubic term depends on a) and w
            v = self.B @ self.unpack(a)[0]
            p0 = self.B @ phi[:self.m]
            dJphi_da = np.zeros((nn, nn))
            dJphi_da[:self.m, :self.m] = self.P @ ((6 * self.k3 * v * p0)[:, None] * self.B)
            h = 1e-7 * w
            dJphi_dw = (self.jacobian(a, w + h) @ phi - self.jacobian(a, w - h) @ phi) / (2 * h)
            G = np.zeros((2 * nn + 1, 2 * nn + 1))
            G[:nn, :nn] = J
            G[:nn, nn] = self.dR_dw(a, w)
            G[nn:2 * nn, :nn] = dJphi_da
            G[nn:2 * nn, nn] = dJphi_dw
            G[nn:2 * nn, nn + 1:] = J
            G[2 * nn, nn + 1:] = c
            F = np.concatenate([R, J @ phi, [c @ phi - 1.0]])
            dx = np.linalg.solve(G, -F)
            a += dx[:nn]
            w += dx[nn]
            phi += dx[nn + 1:]
            if np.linalg.norm(dx) < 1e-12 * (np.linalg.norm(a) + w):
                return a, w
        raise RuntimeError("fold not converged")
