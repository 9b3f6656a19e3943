"""The argument checks the builder's methods share: a point or vector (two finite numbers, within
the model's largest length by default), a direction (normalised) and a finite number
(:mod:`kedfem.checks`, through :mod:`kedfem.model.materials`).
"""

from __future__ import annotations

from ..checks import direction, pair
from .materials import MAX_LENGTH, real

__all__: list[str] = []  # the model wing's internals (the builder's modules import them)


def _vec2(owner: str, name: str, value, limit: float | None = MAX_LENGTH, unit: str = " m") -> tuple[float, float]:
    """Two finite numbers (x, y); with ``limit``, each of magnitude at most ``limit``
    (:func:`kedfem.checks.pair`)."""
    return pair(owner, name, value, limit=limit, unit=unit)


_unit = direction  # a normalised direction (kedfem.checks.direction)


_number = real  # the finite-number check of materials.py
