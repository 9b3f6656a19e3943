"""``geometric_nonlinearity``: von Karman strains of the links, iterated on the elastic state.

Each element's axial force is ``N = EA eps`` with ``eps = (u2 - u1) / L +
v^T G v / (2 L)``; the tangent stiffness ``EA/L (b b^T - b0 b0^T) + N G`` and
the matching load are evaluated about the trial response (Newton's
linearisation, docs/theory.md section 3). ``N`` is constant on an element; with
``inertia`` among the effects its variation along the element under the link's
own inertia (quadratic) is the kinetostatic force's about its element mean, a
linear term ``int (N_ks - mean N_ks) v'^T v' dx``. Measured on a crank-rocker
with a welded arm and a tip mass (2 -> 16 elements per link): the deflections'
mesh error is 18x smaller with it, but still converges at second order at finite
deflection (the element-constant membrane strain; at fourth order in the
small-deflection limit, E raised 10x). The links' axial forces then come
from the elastic state (``carries_axial_forces``). With Rayleigh ``beta`` the
axial damping acts on the rate of the von Karman strain.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...model import elements as el
from ...motion.kinematics import Motion
from ..structure import objective_rates
from .base import Chunk, Effect, StateTerms

__all__ = ["GeometricNonlinearity"]


@dataclass(frozen=True)
class GeometricNonlinearity(Effect):
    """Von Karman tangent stiffness of the elastic axial forces and large deflections."""

    name: str = "geometric_nonlinearity"
    adds: str = "tangent stiffness of elastic axial forces and large deflection"
    carries_axial_forces = True

    def state_dependent(self, mech) -> bool:
        return bool(mech.flexible_links)

    def element_terms(self, asm, chunk: Chunk) -> None:
        # the elastic N is constant on an element; its variation along it under the link's own
        # inertia is the kinetostatic force's about its mean (a linear term)
        bk = chunk.beam
        if bk is None or "inertia" not in asm.effects:
            return
        N = asm.beam_axial_kinetostatic()[chunk.idx]
        dev = N - np.einsum("...g,g->...", N, el.AXIAL_W)[..., None]
        chunk.acc.add("beam", "K", bk.Tt @ el.geometric_stiffness_varying(asm.model.beam.L, dev) @ bk.T)

    def state_terms(self, asm, motion: Motion, U, V, out: StateTerms) -> None:
        b = asm.model.beam
        if not b.L.size:
            return
        A, Tp, T, gm = asm.local_beam_map(motion)  # d = T (E q + p) = A q + T p
        dq = A.apply(U)  # local element DOFs (nt, n_el, 6) the unknowns carry
        d = dq + Tp if Tp is not None else dq  # total
        G = el.geometric_matrix(b.L)    # (n_el, 4, 4)
        Gv = (G @ d[..., el.V_DOFS, None])[..., 0]
        N_nl = b.EA * np.einsum("tni,tni->tn", d[..., el.V_DOFS], Gv) / (2.0 * b.L)
        N = b.EA * (d[..., 3] - d[..., 0]) / b.L + N_nl
        bvec = np.zeros(d.shape)
        bvec[..., 0] = -1.0
        bvec[..., 3] = 1.0
        bvec[..., el.V_DOFS] = Gv
        b0 = np.zeros(6)
        b0[0], b0[3] = -1.0, 1.0
        D = (b.EA / b.L)[:, None, None] * (bvec[..., :, None] * bvec[..., None, :] - np.outer(b0, b0))
        Knl = D.copy()
        Knl[..., el.V_DOFS[:, None], el.V_DOFS[None, :]] += N[..., None, None] * G
        fnl = np.zeros(d.shape)
        fnl[..., 0] = -N_nl
        fnl[..., 3] = N_nl
        fnl[..., el.V_DOFS] = N[..., None] * Gv
        # linearisation about x_i with the prescribed part p fixed:
        # K_T (E q + p - x_i) + f_int(x_i) = Q  ->  Q_state = -f_nl(x_i) + K_nl (x_i - p)
        Qloc = -fnl + (Knl @ dq[..., None])[..., 0]
        asm.apply_state("beam", A, Knl, Qloc, out.dK, out.dQ)  # A^T Knl A, A^T Qloc
        if asm.objective_beta():
            _strain_rate_damping(asm, motion, T, np.swapaxes(T, -1, -2), D, gm, out)


def _strain_rate_damping(asm, mo, T, Tt, D, gm, out: StateTerms) -> None:
    """``beta D`` (local, (nt, n_el, 6, 6)): the part of ``beta EA eps'`` beyond the linear
    ``beta k``, on the objective local rates ``T x' + T' x``."""
    w = mo.omega[:, asm.beam_member][..., None, None]
    Cx, Kx = objective_rates(asm.objective_beta() * D, T, Tt, w)
    Qx = None
    if gm.p is not None:
        Qx = -((Cx @ gm.p1[..., None])[..., 0] + (Kx @ gm.p[..., None])[..., 0])
    asm.apply_state("beam", gm, Cx, Qx, out.damping(), out.dQ)
    if asm.transport and gm.E1 is not None:
        # x' = E q' + E1 q + p1: the transport of the maps
        asm.apply_state("beam", gm, Cx, None, out.dK, None, right=gm.E1)
    asm.apply_state("beam", gm, Kx, None, out.dK, out.dQ)
