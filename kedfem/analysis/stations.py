"""Stations along a flexible link: the per-element count a read-out takes, element values put on
the link's stations (the nodes averaged, or both sides of a joint the link passes through), the
element length and a station's abscissa (helpers of :class:`kedfem.analysis.results.PeriodicResult`)."""

from __future__ import annotations

import numpy as np

from ..errors import InputError


def _per_element(k) -> int:
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= 64:
        raise InputError(f"per_element must be an integer in 1..64, got {k!r}")
    return int(k)


def _on_stations(X: np.ndarray, steps=(), larger: bool = False, sides: bool = False) -> np.ndarray:
    """Element values (n, n_el, k + 1) on the link's stations (n, n_el k + 1), nodes averaged.

    At the nodes ``steps`` (joints the link passes through, where a pin's force
    steps the section forces) ``larger=True`` takes the larger of the two sides
    (a stress) instead of their mean; ``sides=True`` gives both, the ``a`` side
    first (one more station per step node).
    """
    n, ne, k1 = X.shape
    k = k1 - 1
    out = np.empty((n, ne * k + 1))
    out[:, :-1] = X[:, :, :k].reshape(n, ne * k)
    out[:, -1] = X[:, -1, k]
    if ne > 1:
        out[:, k:-1:k] = 0.5 * (X[:, :-1, k] + X[:, 1:, 0])
    steps = np.asarray(steps, dtype=int)
    if larger and steps.size:
        out[:, steps * k] = np.maximum(X[:, steps - 1, k], X[:, steps, 0])
    if sides and steps.size:
        out[:, steps * k] = X[:, steps - 1, k]
        out = np.insert(out, steps * k + 1, X[:, steps, 0], axis=1)
    return out


def _element_length(lk):
    """Element length [m] of a link meshed uniformly (float), else the lengths (n_el,)."""
    return lk.length / lk.elements if not lk.through else lk.element_lengths


def _abscissa(lk, station: float, per_element: int) -> float:
    """Abscissa [m] from joint ``a`` of a (fractional) station index on ``per_element`` stations per element."""
    x = np.clip(station / per_element, 0.0, lk.elements)
    e = min(int(x), lk.elements - 1)
    return float(min(max(lk.nodes[e] + (x - e) * lk.element_lengths[e], 0.0), lk.length))
