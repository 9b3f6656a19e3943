"""Units kedfem converts between: its numbers are SI (rad/s for speeds), users speak rpm and degrees.

One definition of each factor, used by the scene files, the design studies, the tables and the
CLI alike.
"""

from __future__ import annotations

import math

__all__ = ["RAD_S_PER_RPM", "RPM_PER_RAD_S"]

#: [rad/s] per rpm: a speed in rpm times this is the speed in rad/s
RAD_S_PER_RPM = 2.0 * math.pi / 60.0
#: [rpm] per rad/s
RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)
