"""The coefficients given to the periodic solvers: constant, sampled or callable, checked.

:class:`_Source` holds one of ``M, C, K`` (a matrix) or ``Q`` (a vector) given as a constant,
sampled at the time nodes or instants, or as a callable of their indices, and checks its type,
shape and values; :func:`check_period` checks the period and :data:`MIN_NODES` is the fewest
time elements a period may have. Shared by the exponential holds (:mod:`kedfem.solvers.periodic`)
and the collocation elements (:mod:`kedfem.solvers.collocation`).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError

#: Minimum number of time elements: a periodic signal needs more than two samples
#: per period to represent even its fundamental harmonic (Nyquist), and the
#: midpoint / linear holds need distinct neighbours ``k - 1, k, k + 1``.
MIN_NODES = 3


class _Source:
    """A coefficient given as constant (N,N), sampled (n,...) or callable."""

    def __init__(self, name: str, value, matrix: bool):
        self.name = name
        self.matrix = matrix
        self.callable = callable(value)
        self.value = value
        self.const = False
        if not self.callable:
            arr = np.asarray(value)
            if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
                raise InputError(f"{name} must be a real numeric array or a callable, "
                                 f"got dtype {arr.dtype}")
            arr = arr.astype(float, copy=False)
            if matrix:
                if arr.ndim == 2:
                    self.const = True
                elif arr.ndim != 3:
                    raise InputError(f"{name} must have shape (N, N) or (n, N, N), got {arr.shape}")
                if arr.shape[-1] != arr.shape[-2]:
                    raise InputError(f"{name} must be square in its last two axes, got {arr.shape}")
            elif arr.ndim != 2:
                raise InputError(f"{name} must have shape (n, N), got {arr.shape}")
            _check_finite(name, arr)
            self.value = arr

    @property
    def n(self) -> int | None:
        if self.callable or self.const:
            return None
        return self.value.shape[0]

    @property
    def N(self) -> int | None:
        if self.callable:
            return None
        return self.value.shape[-1]

    def get(self, idx: np.ndarray | slice, N: int) -> np.ndarray:
        """Values at node indices ``idx`` (an array, or a slice of consecutive nodes: a view of
        sampled data, not a copy): (len, N, N) / (len, N), or (N, N) if constant."""
        if self.const:
            return self.value
        if not self.callable:
            return self.value[idx]
        if isinstance(idx, slice):
            idx = np.arange(idx.start, idx.stop)
        out = np.asarray(self.value(idx), dtype=float)
        want = (len(idx), N, N) if self.matrix else (len(idx), N)
        if out.shape != want:
            raise InputError(f"{self.name}(idx) must return shape {want} for {len(idx)} indices, "
                             f"got {out.shape}")
        bad = ~np.isfinite(out)
        if bad.any():
            pos = np.argwhere(bad)[0]
            node = int(idx[pos[0]])
            raise InputError(f"{self.name} has a non-finite value at time node {node} "
                             f"(entry {tuple(int(i) for i in pos[1:])})")
        return out


def _check_finite(name: str, arr: np.ndarray) -> None:
    bad = ~np.isfinite(arr)
    if bad.any():
        first = tuple(int(i) for i in np.argwhere(bad)[0])
        raise InputError(f"{name} has a non-finite value at index {first}")


def check_period(period) -> float:
    """``period`` [s] as a positive finite float, or an :class:`InputError`."""
    try:
        period = float(period)
    except (TypeError, ValueError):
        raise InputError(f"period must be a positive finite number, got {period!r}") from None
    if not (math.isfinite(period) and period > 0):
        raise InputError(f"period must be a positive finite number, got {period!r}")
    return period
