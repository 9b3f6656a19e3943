"""Progress bars for the operations that can take more than a few seconds.

One convention for all of them: tqdm on stderr, shown after ``delay`` seconds
(a quick call prints nothing), left off the screen when done, and on a
terminal only unless asked (``progress=True`` forces it, ``False`` hides it).
"""

from __future__ import annotations

import sys

__all__ = ["bar"]


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
