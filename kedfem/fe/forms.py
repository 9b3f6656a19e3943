"""The affine form of an entity: a translation point or a rotation as a function of ``q``.

Built by :meth:`kedfem.fe.maps.ConstraintMaps.entity_forms` (and, for the blocks of slot
joints, by :mod:`kedfem.fe.slots`), read by the group maps and the assembler. Kept apart
from both so that :mod:`kedfem.fe.slots` needs no import of :mod:`kedfem.fe.maps`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["EntityForm"]


class EntityForm(NamedTuple):
    """Affine form ``x(t) = C(t) q[cols] + p(t)`` of an entity over ``nt`` time nodes.

    ``width`` is the entity's number of components (2 for a translation point, 1 for a
    rotation) and ``k = len(cols)``. Unpacks as ``cols, C, C1, C2, p, p1, p2 = form``.

    Attributes
    ----------
    cols : tuple of int
        Global q columns the entity depends on (fixed over the cycle), length ``k``.
    C : ndarray, shape (nt or 1, width, k)
        Map from ``q[cols]`` to the entity's components: dimensionless between like
        components (translation [m] to translation, rotation [rad] to rotation), a lever
        arm [m/rad] from a rotation to a translation, a slope [rad/m] from a translation
        to a rotation, and per unit of a Craig-Bampton modal coordinate (mass-normalised
        shapes). Leading axis 1 when the map is constant over the cycle.
    C1, C2 : ndarray, shape (nt or 1, width, k), or None
        First and second time derivatives of ``C`` [units of ``C`` per s, per s^2];
        None when ``C`` is constant.
    p : ndarray, shape (nt, width), or None
        Prescribed offset [m or rad] (an elastically clamped end on a kinematic pin, a
        passive link's chord stretch carried into a reduced link); None when there is none.
    p1, p2 : ndarray, shape (nt, width), or None
        First and second time derivatives of ``p`` [m/s or rad/s, m/s^2 or rad/s^2];
        None together with ``p``.
    """

    cols: tuple[int, ...]
    C: np.ndarray
    C1: np.ndarray | None
    C2: np.ndarray | None
    p: np.ndarray | None
    p1: np.ndarray | None
    p2: np.ndarray | None
