"""Progress bars for the operations that can take more than a few seconds.

One convention for all of them: tqdm on stderr, shown after ``delay`` seconds
(a quick call prints nothing), left off the screen when done, and on a
terminal only unless asked (``progress=True`` forces it, ``False`` hides it).
"""

from __future__ import annotations

import sys

__all__ = ["bar", "Reminder"]


def bar(desc: str, unit: str, total: int | None = None, progress: bool | None = None, delay: float = 2.0):
    """A tqdm bar on stderr.

    Parameters
    ----------
    desc : str
        What is being done (``"campbell"``, ``"critical speed"``).
    unit : str
        What one step is (``"speed"``, ``"solve"``).
    total : int, optional
        Steps expected (an upper bound is fine: the bar closes where the work ends).
    progress : bool, optional
        None: on a terminal only; True: always; False: never.
    delay : float
        Seconds [s] before the bar appears.
    """
    from tqdm.auto import tqdm
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, delay=delay, leave=False,
                dynamic_ncols=True, disable=None if progress is None else not progress)


class Reminder:
    """When a forecast of the seconds left is worth a logged warning: above ``threshold`` [s],
    and again each time it has doubled since it was last said, ``times`` times at most (a pace
    that slows toward a resonance makes a forecast said once, as it crosses the threshold,
    read "about 10 s more" where 60 s followed)."""

    def __init__(self, threshold: float, times: int = 3):
        self.threshold, self.times = float(threshold), int(times)
        self.said, self.count = 0.0, 0

    def due(self, left: float | None) -> bool:
        """Say ``left`` [s] now? (Counts it as said when so.)"""
        if left is None or self.count >= self.times or left <= max(self.threshold, 2.0 * self.said):
            return False
        self.said, self.count = left, self.count + 1
        return True
