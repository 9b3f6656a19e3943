"""Peaks of sampled histories: the parabolic vertex through a sample and its neighbours, and the
largest value of a history over time and stations (the result's peak read-out and the bearing
loads' peaks, :mod:`kedfem.analysis.results` and :mod:`kedfem.analysis.loads`)."""

from __future__ import annotations

import numpy as np

__all__ = ["parabolic_vertex", "smooth_vertex", "grid_peak"]

#: the most the second differences beside a peak sample may differ from its own (as a factor) for
#: the peak to count as smooth: a smooth peak sampled finely has three nearly equal ones
SMOOTH_CURVATURE = 4.0


def parabolic_vertex(y: np.ndarray, k: int, periodic: bool = False) -> tuple[float, float]:
    """Parabolic vertex through ``y[k-1:k+2]`` (wrapping round with ``periodic``): (value, offset
    from ``k`` in samples)."""
    if periodic or 0 < k < y.size - 1:
        ym, yp = y[k - 1], y[(k + 1) % y.size]
        den = ym - 2.0 * y[k] + yp
        if den < 0.0:
            dlt = 0.5 * (ym - yp) / den
            return float(y[k] - 0.25 * (ym - yp) * dlt), float(dlt)
    return float(y[k]), 0.0


def smooth_vertex(y: np.ndarray, k: int, periodic: bool = False) -> tuple[float, float]:
    """:func:`parabolic_vertex` where the peak at ``y[k]`` is smooth, else the sample itself.

    Smooth: the second differences at ``k - 1``, ``k`` and ``k + 1`` are all negative and within
    :data:`SMOOTH_CURVATURE` of each other. A parabola through a step or a kink overshoots: a
    process load stepping up to its peak between two samples made a bearing force's peak read 12 %
    above every sample (a new user's toggle press, at every resolution); at a step the sample just
    after it is the peak. Needs two samples on either side (or ``periodic``).
    """
    n = y.size
    if n < 5 or not (periodic or 2 <= k <= n - 3):
        return float(y[k]), 0.0
    yy = y[np.arange(k - 2, k + 3) % n]
    d2 = yy[:-2] - 2.0 * yy[1:-1] + yy[2:]
    if not (np.all(d2 < 0.0) and d2.min() >= SMOOTH_CURVATURE * d2.max()):
        return float(y[k]), 0.0
    return parabolic_vertex(y, k, periodic=periodic)


def grid_peak(vals: np.ndarray, t: np.ndarray, vertex: bool = True) -> tuple[float, float, float | None]:
    """Largest value of a history (n,) or (n, stations), with parabolic vertices if ``vertex``.

    Returns the value, its instant (vertex in time at the best station) and
    its station as a fractional index (vertex along the stations at the best
    instant; None for a scalar history). Without ``vertex`` the largest sample
    (a lower bound that a refinement may only raise).
    """
    if not vertex:
        flat = vals if vals.ndim == 1 else vals.max(axis=1)
        k = int(np.argmax(flat))
        return float(flat[k]), float(t[k]), (None if vals.ndim == 1 else float(np.argmax(vals[k])))
    if vals.ndim == 1:
        k = int(np.argmax(vals))
        v, dk = parabolic_vertex(vals, k)
        return v, float(t[k] + dk * (t[1] - t[0] if t.size > 1 else 0.0)), None
    flat = vals.max(axis=1)
    k = int(np.argmax(flat))
    j = int(np.argmax(vals[k]))
    v_t, dk = parabolic_vertex(vals[:, j], k)
    v_x, dj = parabolic_vertex(vals[k], j)
    # the two vertices are corrections of the same sample: add them
    return (float(vals[k, j] + (v_t - vals[k, j]) + (v_x - vals[k, j])),
            float(t[k] + dk * (t[1] - t[0] if t.size > 1 else 0.0)), float(j + dj))
