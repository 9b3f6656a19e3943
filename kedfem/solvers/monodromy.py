"""The monodromy matrix ``Phi``: Floquet multipliers, the condition of ``I - Phi``, resonance.

:func:`_floquet_multipliers` are the eigenvalues of ``Phi``; :func:`_balanced_condition`
balances ``I - Phi`` and estimates its condition; :func:`_check_resonance` tells a resonance (a
multiplier at 1: :class:`~kedfem.errors.ResonanceError`) from a non-normal, ill-conditioned
``Phi``; :func:`_choose_method` picks condensation or the cyclic LU and warns of a parametric
instability; :func:`_solve_z0` solves ``(I - Phi) z_0 = d``.
"""

from __future__ import annotations

import logging
import math
import warnings

import numpy as np

from ..errors import InstabilityWarning, ResonanceError, user_stacklevel
from .balancing import balance

# the records keep the logger they had before the split (issue 27): a filter on it still works
log = logging.getLogger("kedfem.solvers.periodic")

#: ``I - Phi`` with a condition above ``max_condition`` is a resonance only if a
#: Floquet multiplier lies within this distance of 1; otherwise the size of the
#: condition number comes from the non-normality of ``Phi`` (stiff, undamped
#: high modes) and the cyclic system is solved by sparse LU instead.
RESONANCE_GAP = 1e-6
#: Default largest acceptable condition number of the balanced ``I - Phi``.
MAX_CONDITION = 1e12
#: Spectral radius above ``1 + INSTABILITY_TOL`` counts as parametric instability.
INSTABILITY_TOL = 1e-6


def _floquet_multipliers(Phi: np.ndarray) -> np.ndarray:
    """Eigenvalues of the monodromy ``Phi`` (m, m), shape (m,) complex, by decreasing modulus."""
    mult = np.linalg.eigvals(Phi)
    return mult[np.argsort(-np.abs(mult), kind="stable")]


def _balanced_condition(ImP: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Balance ``I - Phi`` and estimate its condition relative to the data ``I`` and ``Phi``.

    The condition is ``(1 + ||Phi||_2) / sigma_min(I - Phi)`` in balanced
    coordinates. Scale-free measures such as ``sigma_max / sigma_min`` miss
    ``I - Phi ~ 0`` (all multipliers 1).

    Parameters
    ----------
    ImP : ndarray, shape (m, m)
        ``I - Phi``.

    Returns
    -------
    Bal : ndarray, shape (m, m)
        ``D^-1 (I - Phi) D``.
    dsc : ndarray, shape (m,)
        The diagonal of ``D``.
    condition : float
        Condition estimate (``inf`` when singular).
    """
    Bal, dsc = balance(ImP)
    try:
        smin = float(np.linalg.svd(Bal, compute_uv=False)[-1])
        pnorm = float(np.linalg.norm(np.eye(ImP.shape[0]) - Bal, 2))
        condition = (1.0 + pnorm) / smin if smin > 0 else math.inf
    except np.linalg.LinAlgError:
        condition = math.inf
    return Bal, dsc, condition


def _check_resonance(mult: np.ndarray, condition: float, max_condition: float) -> bool:
    """Whether ``I - Phi`` is ill-conditioned but not singular; a ResonanceError if singular.

    A condition above ``max_condition`` with every multiplier farther than
    :data:`RESONANCE_GAP` from 1 is not singularity: it comes from ``Phi``'s
    non-normality (stiff modes with ``omega dt >> 1`` that no diagonal scaling
    balances together). Condensation would lose digits in ``z_0``; the sparse LU
    of the whole cyclic system is backward stable.

    Parameters
    ----------
    mult : ndarray, shape (m,)
        Floquet multipliers.
    condition : float
        Condition estimate of ``I - Phi`` (:func:`_balanced_condition`).
    max_condition : float
        Largest acceptable condition.

    Returns
    -------
    bool
        ``True`` when ``I - Phi`` is ill-conditioned but not singular.

    Raises
    ------
    ResonanceError
        Condition infinite, or above ``max_condition`` with a multiplier within
        :data:`RESONANCE_GAP` of 1.
    """
    near = mult[np.argmin(np.abs(mult - 1.0))]
    if math.isfinite(condition) and condition > max_condition and abs(near - 1.0) > RESONANCE_GAP:
        log.info("I - Phi has condition %.3g but no Floquet multiplier near 1 (nearest at |mu - 1| = %.3g): "
                 "solving the whole cyclic system by sparse LU", condition, abs(near - 1.0))
        return True
    if not math.isfinite(condition) or condition > max_condition:
        raise ResonanceError(
            f"I - Phi is numerically singular (condition number {condition:.3g} > {max_condition:.3g}): "
            f"Floquet multiplier {near.real:.15g}{near.imag:+.3g}j lies at |mu - 1| = "
            f"{abs(near - 1):.3g} from 1. The system has no unique periodic response: undamped "
            f"forcing at resonance, a free rigid-body mode (K singular with no damping), or an "
            f"incompletely constrained mechanism.", multiplier=complex(near), condition=condition)
    return False


#: a multiplier whose imaginary part is below this fraction of its modulus is real
REAL_TOL = 1e-6


def instability_kind(mu: complex) -> str:
    """How a Floquet multiplier ``mu`` outside the unit circle makes the response grow, in words.

    Over one period of the problem: a real negative multiplier changes the growth's sign from one
    period to the next (period doubling, a flip: a principal parametric resonance), a real
    positive one grows in step with the period (a divergence: a link buckling, or a resonance
    locked to the drive; a fold on a non-linear branch), a complex pair at a frequency locked to
    no harmonic of the drive (a combination resonance; a Neimark-Sacker crossing on a non-linear
    branch).
    """
    mu = complex(mu)
    if abs(mu.imag) <= REAL_TOL * abs(mu):
        return ("real negative: period doubling (a flip), the growth changes sign from one period to the next"
                if mu.real < 0 else "real positive: a divergence, growth in step with the period (buckling, "
                "or a resonance locked to the drive)")
    return "a complex pair: growth at a frequency locked to no harmonic of the drive (a combination resonance)"


def _choose_method(method: str, rho: float, ill_conditioned: bool, mu: complex | None = None) -> str:
    """``"condensation"`` or ``"cyclic-lu"``; warns of a parametric instability.

    Parameters
    ----------
    method : str
        Requested method; ``"auto"`` picks cyclic LU when the spectral radius
        ``rho`` exceeds ``1 + INSTABILITY_TOL`` or ``ill_conditioned``.
    rho : float
        Largest Floquet multiplier modulus.
    ill_conditioned : bool
        From :func:`_check_resonance`.
    mu : complex, optional
        The largest multiplier, whose kind the warning names (:func:`instability_kind`).

    Returns
    -------
    str
    """
    unstable = rho > 1.0 + INSTABILITY_TOL
    if method == "auto":
        method = "cyclic-lu" if (unstable or ill_conditioned) else "condensation"
    if unstable:  # stacklevel: the caller of solve_cyclic
        kind = f" ({instability_kind(mu)})" if mu is not None else ""
        warnings.warn(f"parametric instability: largest Floquet multiplier |mu| = {rho:.6g} > 1{kind}; "
                      f"the periodic solution exists but is not attracting (solved by {method})",
                      InstabilityWarning, stacklevel=user_stacklevel())
    return method


def _solve_z0(ImP: np.ndarray, Bal: np.ndarray, dsc: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Solve ``(I - Phi) z_0 = d`` in balanced coordinates with one step of iterative refinement.

    Parameters
    ----------
    ImP : ndarray, shape (m, m)
        ``I - Phi``.
    Bal, dsc : ndarray, shapes (m, m) and (m,)
        Its balanced form and scaling (:func:`_balanced_condition`).
    d : ndarray, shape (m,)
        Particular part.

    Returns
    -------
    ndarray, shape (m,)
        The periodic state at ``t = 0`` (DOF units, per s for velocities).
    """
    z0 = dsc * np.linalg.solve(Bal, d / dsc)
    r = d - ImP @ z0
    return z0 + dsc * np.linalg.solve(Bal, r / dsc)
