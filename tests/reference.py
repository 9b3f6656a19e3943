"""Independent reference computations shared by the tests (not part of kedfem)."""

import numpy as np
import scipy.linalg as sla


def augmented_transition(F, dt, g0, g1=None, expm=sla.expm):
    """Exact transition of ``z' = F z + g(t)`` over ``dt`` for a constant (``g1=None``) or linear
    ``g0 -> g1`` forcing, from one exponential of the augmented matrix; returns ``(A, b)``."""
    m = F.shape[0]
    if g1 is None:
        X = np.zeros((m + 1, m + 1))
        X[:m, :m] = F * dt
        X[:m, m] = g0 * dt
    else:
        X = np.zeros((m + 2, m + 2))
        X[:m, :m] = F * dt
        X[:m, m] = (g1 - g0) * dt
        X[:m, m + 1] = g0 * dt
        X[m, m + 1] = 1.0
    E = expm(X)
    return E[:m, :m], E[:m, -1]
