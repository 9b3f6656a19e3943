"""``coupling``: the rigid-elastic coupling terms of the beams and of moving constraint maps.

In the inertial frame the response is solved in, a beam element whose frame
turns at ``w`` (angular acceleration ``a``) takes ``C = 2 w (m_s - m_t S)`` and
``K = a (m_s - m_t S) + w^2 (m_t S S - 2 m_s S - m_t)``; in the co-moving frame
of the frequency analysis the classical Coriolis ``2 w m_s``, tangential
``a m_s`` and centripetal ``-w^2 m_t`` terms. The time derivatives of moving
constraint maps ``E(t)`` enter ``C`` and ``K`` too (``transports_maps``;
docs/theory.md section 3).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..structure import SHAT
from .base import Chunk, Effect

__all__ = ["Coupling"]


@dataclass(frozen=True)
class Coupling(Effect):
    """Coriolis, tangential and centripetal terms, and the transport of the constraint maps."""

    name: str = "coupling"
    adds: str = "Coriolis, tangential and centripetal rigid-elastic coupling terms"
    transports_maps = True

    def element_terms(self, asm, chunk: Chunk) -> None:
        bk = chunk.beam
        if bk is None:
            return
        mt, ms = asm.coupling_matrices
        w4 = bk.omega[..., None, None]
        a4 = bk.alpha[..., None, None]
        if asm.frame:
            C = 2.0 * w4 * ms
            K = a4 * ms - w4**2 * mt
        else:
            mtS = mt @ SHAT
            C = 2.0 * w4 * (ms - mtS)
            K = a4 * (ms - mtS) + w4**2 * (mtS @ SHAT - 2.0 * ms @ SHAT - mt)
        chunk.acc.add("beam", "C", bk.Tt @ C @ bk.T)
        chunk.acc.add("beam", "K", bk.Tt @ K @ bk.T)
