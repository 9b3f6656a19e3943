"""A result's section forces under the blocks that slide on a link: the moment and axial force of
each block's contact load in the element under it, and the stress there, where it peaks between the
stations (:class:`BlockForces`, a part of :class:`kedfem.analysis.results.PeriodicResult`)."""

from __future__ import annotations

import numpy as np

from ..model import elements as el
from . import recovery
from ..errors import InputError


class BlockForces:
    """The section forces under sliding blocks of :class:`kedfem.analysis.results.PeriodicResult` (a
    mixin: it reads the result's element loads and contact forces)."""

    def _blocks_on(self, lk) -> list:
        """The slot joints whose blocks slide on link ``lk``."""
        return [j for j in self.model.mech.joints.values() if j.kind == "slot" and j.on == lk.name]

    def block_stress(self, link: str) -> tuple[np.ndarray, np.ndarray]:
        """Normal stress under the blocks sliding on a link, and where, at every instant.

        The section forces by element equilibrium (:meth:`stress`) at each block's own abscissa
        (the apex of the moment's kink under its contact load), the larger of the axial force's
        two sides there (it steps by the contact's axial component).

        Returns
        -------
        stress : ndarray, shape (n,)
            Largest ``|N|/A + |M| c / I`` under a block [Pa] (0 without blocks).
        abscissa : ndarray, shape (n,)
            The block's abscissa along the link [m] (0 without blocks).
        """
        lk = self._link(link)
        key = ("block_stress", lk.name)
        if key in self._cache:
            return self._cache[key]
        from ..fe.slots import block_abscissa, element_at
        sec = lk.section
        if sec.c is None:
            raise InputError(f"link '{link}': its section has no extreme-fibre distance c, "
                             "so the bending stress is unknown (give Section(..., c=...))")
        best = np.zeros(self.n)
        where = np.zeros(self.n)
        for jt in self._blocks_on(lk):
            x = block_abscissa(self.model, jt.name, self.motion)
            e, zeta = element_at(lk, x)
            M, N_left, N_right = self._forces_under(lk, e, zeta)
            sig = np.maximum(np.abs(N_left), np.abs(N_right)) / sec.A + np.abs(M) * sec.c / sec.I
            take = sig > best
            best = np.where(take, sig, best)
            where = np.where(take, x, where)
        self._cache[key] = (best, where)
        return best, where

    def _forces_under(self, lk, e: np.ndarray, zeta: np.ndarray):
        """Bending moment (n,) [N m] and the axial force just before and just after (n,) each [N]
        at element ``e[r]``, fraction ``zeta[r]`` at every instant ``r`` (a point that moves)."""
        d = self._local(lk.name)
        q, p, N_h = self._element_loads(lk)
        L = lk.length / lk.elements
        rows = np.arange(self.n)
        E = lk.material.E
        B = el.shape_curvatures(L, zeta)[0]  # (n, 6)
        M = E * lk.section.I * np.einsum("ri,ri->r", B, d[rows, e])
        N = N_h[rows, e].copy()
        if q is not None:
            W, Wn = recovery.fixed_end_maps(zeta)
            M = M + L * L * np.einsum("rp,rp->r", W, q[rows, e])
            N = N + L * np.einsum("rp,rp->r", Wn, p[rows, e])
        N_left, N_right = N.copy(), N.copy()
        blocks = self._blocks_on(lk)
        if blocks:
            x = zeta * L
            for c0, c1, a, Py, Px, eb in self._contact_terms(lk, blocks):
                c0, c1, a, Py, Px = (v[:, 0] for v in (c0, c1, a, Py, Px))
                on = eb == e
                M = M + np.where(on, c0 + c1 * x + Py * np.maximum(x - a, 0.0), 0.0)
                # the axial force steps at the block: its two sides
                N_left = N_left + np.where(on, Px * np.where(x <= a, (L - a) / L, -a / L), 0.0)
                N_right = N_right + np.where(on, Px * np.where(x < a, (L - a) / L, -a / L), 0.0)
        return M, N_left, N_right

    def _with_blocks(self, lk, blocks, forces, xi):
        """Add the moment and axial force of each block's contact load in the element under it.

        The element's forces by equilibrium are the interpolation's plus, for each load in
        it, those of the element clamped at both ends: for a transverse force ``P`` at ``a``
        ``M = c0 + c1 x + P (x - a)+`` with ``int M = int M x = 0`` (no end slope or
        deflection), for an axial one ``N = P_a b / L`` before ``a`` and ``-P_a a / L`` after.
        """
        M, N = (np.array(f) for f in forces)
        L = lk.length / lk.elements
        x = xi * L
        rows = np.arange(self.n)
        for c0, c1, a, Py, Px, e in self._contact_terms(lk, blocks):
            M[rows, e] += c0 + c1 * x + Py * np.maximum(x - a, 0.0)
            N[rows, e] += Px * np.where(x > a, -a / L, (L - a) / L)
        return M, N

    def _contact_terms(self, lk, blocks) -> list:
        """Per block on link ``lk``: ``(c0, c1, a, Py, Px, e)``, the clamped element's moment
        ``c0 + c1 x + Py (x - a)+`` coefficients (n, 1) each, the contact's abscissa ``a`` in the
        element (n, 1) [m], its transverse and axial components (n, 1) [N] and the element (n,)."""
        from .loads import contact_forces
        from ..fe.slots import block_abscissa, element_at
        contact = self._cache.get("contact")
        if contact is None:
            contact = self._cache["contact"] = contact_forces(self)
        L = lk.length / lk.elements
        th = self.motion.angle(lk.name)
        c, s = np.cos(th), np.sin(th)
        out = []
        for jt in blocks:
            F = -contact[jt.name]  # the pin's force on the link
            Px, Py = c * F[:, 0] + s * F[:, 1], -s * F[:, 0] + c * F[:, 1]
            e, zeta = element_at(lk, block_abscissa(self.model, jt.name, self.motion))
            a = (zeta * L)[:, None]
            b = L - a
            r1 = -Py[:, None] * b**2 / 2
            r2 = -Py[:, None] * (L**3 / 3 - a * L**2 / 2 + a**3 / 6)
            det = L**4 / 12
            c0 = (r1 * L**3 / 3 - r2 * L**2 / 2) / det
            c1 = (r2 * L - r1 * L**2 / 2) / det
            out.append((c0, c1, a, Py[:, None], Px[:, None], e))
        return out

    def _block_abscissa_at(self, lk, t: float) -> float:
        """Abscissa [m] along ``lk`` of the block under which the stress is largest at instant ``t``
        (read on the output grid where ``t`` is one of its instants, as the error estimate's
        grid peaks are: resampling the response there cost a level's read-out a tenth of its time)."""
        T = self.scene.period
        off = np.abs(np.mod(self.t - t + 0.5 * T, T) - 0.5 * T)
        k = int(np.argmin(off))
        if self.sampler is None or off[k] <= 1e-12 * T:
            return float(self.block_stress(lk.name)[1][k])
        return float(self.resample(np.array([np.mod(t, T)])).block_stress(lk.name)[1][0])
