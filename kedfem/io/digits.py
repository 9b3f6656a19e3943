"""How many significant digits a figure with a known relative error may print.

A printed figure's last digit should not lie below a tenth of its error: a value known to a
relative error ``e`` prints at most ``1 - ceil(log10 e)`` significant digits (1e-3: four, 1.2e-3:
three), never more than a display cap, and a few when its error is not known.
"""

from __future__ import annotations

import math

__all__ = ["significant_digits", "UNKNOWN_DIGITS", "MAX_DIGITS"]

#: Digits of a figure whose error is not estimated
UNKNOWN_DIGITS = 3
#: Largest number of significant digits a table prints
MAX_DIGITS = 5


def significant_digits(rel_error: float | None, cap: int = MAX_DIGITS) -> int:
    """Significant digits (1 .. ``cap``) for a figure of relative error ``rel_error`` (None: unknown).

    Parameters
    ----------
    rel_error : float or None
        Estimated relative error (non-negative); None or not finite when unknown.
    cap : int
        The most digits to print.

    Returns
    -------
    int
        ``min(cap, max(1, 1 - ceil(log10 rel_error)))``; ``cap`` for a zero error and
        :data:`UNKNOWN_DIGITS` (at most ``cap``) for an unknown one.
    """
    if rel_error is None or not math.isfinite(rel_error) or rel_error < 0:
        return min(cap, UNKNOWN_DIGITS)
    if rel_error == 0.0:
        return cap
    return int(min(cap, max(1, 1 - math.ceil(math.log10(rel_error) - 1e-12))))
