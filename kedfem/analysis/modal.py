"""Modal analysis: natural frequencies and mode shapes at a crank position or over the cycle.

Frequencies use the co-moving-frame formulation (see
:class:`kedfem.fe.effects.Assembler`, ``frame=True``): each flexible link is
described in its own rotating frame, so the speed-dependent stiffness terms
are the centripetal softening ``-w^2 m_t`` (``coupling``) and the geometric
stiffness of the kinetostatic forces (``axial_stiffening``). The undamped
problem ``K phi = omega^2 M phi`` uses the symmetric part of ``K``.
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..fe.assembly import FEModel
from ..fe.effects import Assembler, check_effects
from ..solvers.eigen import generalised_eigh
from ..errors import InputError
from ..motion.kinematics import Motion, kinematics, kinematics_at, static_motion
from ..model.mechanism import Mechanism

__all__ = ["ModalResult", "GlobalMatrices", "natural_frequencies", "global_matrices", "eig_frequencies"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ModalResult:
    """Natural frequencies (and mode shapes) of a mechanism.

    Attributes
    ----------
    frequencies : ndarray, shape (n_modes,) or (n, n_modes)
        Undamped natural frequencies [Hz], ascending; a negative value
        ``-sqrt(-lambda) / 2 pi`` marks an unstable (buckled) mode.
    shapes : ndarray, shape (N, n_modes) or (n, N, n_modes), or None
        Mass-normalised mode shapes (when requested).
    crank_angle : ndarray, shape () or (n,)
        Crank angle(s) [rad].
    dof_labels : tuple of str
        DOF labels of the rows of ``shapes``.
    """

    frequencies: np.ndarray
    shapes: np.ndarray | None
    crank_angle: np.ndarray
    dof_labels: tuple[str, ...]

    def __array__(self, dtype=None, copy=None):
        return np.asarray(self.frequencies, dtype=dtype)

    def __len__(self):
        return len(self.frequencies)

    def __getitem__(self, i):
        return self.frequencies[i]


@dataclass(frozen=True)
class GlobalMatrices:
    """Global matrices at one crank position (scipy.sparse CSR, SI units).

    ``M`` [kg...], ``C`` [N s/m...], ``K`` [N/m...] of shape (N, N), ``Q`` (N,)
    load [N, N m], with the DOF labels of the rows.
    """

    M: sp.csr_matrix
    C: sp.csr_matrix
    K: sp.csr_matrix
    Q: np.ndarray
    dof_labels: tuple[str, ...]
    crank_angle: float


def _motion_at(mechanism: Mechanism, crank_angle) -> Motion:
    if not mechanism.drives:
        return static_motion(mechanism)
    return kinematics_at(mechanism, float(crank_angle))


def eig_frequencies(M, K, n_modes: int | None = None, shapes: bool = False, name: str = "",
                    labels=None):
    """Undamped frequencies [Hz] of ``K phi = omega^2 M phi``, batched.

    Parameters
    ----------
    M, K : ndarray, shape (..., N, N)
        Mass and stiffness (the symmetric part of ``K`` is used).
    n_modes : int, optional
        Number of lowest modes to return.
    shapes : bool
        Also return mass-normalised mode shapes.
    name : str
        Mechanism name for messages.
    labels : sequence of str, optional
        DOF labels, to name massless DOFs in the error.

    Returns
    -------
    f : ndarray, shape (..., n_modes)
    phi : ndarray, shape (..., N, n_modes), only if ``shapes``.
    """
    lam, _L, Li, V = generalised_eigh(M, K, name, labels)
    # rigid-body modes: round-off of size eps * max|lambda| is zero, not a negative stiffness
    tol = 1e-10 * np.max(np.abs(lam), axis=-1, keepdims=True)
    lam = np.where(np.abs(lam) < tol, 0.0, lam)
    k = lam.shape[-1] if n_modes is None else min(int(n_modes), lam.shape[-1])
    lam = lam[..., :k]
    f = np.sign(lam) * np.sqrt(np.abs(lam)) / (2 * math.pi)
    if not shapes:
        return f
    phi = np.swapaxes(Li, -1, -2) @ V[..., :k]
    return f, phi


def natural_frequencies(mechanism: Mechanism, crank_angle: float = 0.0, n_modes: int = 6,
                        effects=(), modes: bool = False, steps: int | None = None) -> ModalResult:
    """Undamped natural frequencies of a mechanism at a crank position.

    Parameters
    ----------
    mechanism : Mechanism
        The mechanism (a structure without drive is analysed in its reference
        configuration at rest).
    crank_angle : float
        Absolute angle of the first driven member [rad].
    n_modes : int
        Number of lowest modes.
    effects : sequence of str
        Speed-dependent stiffness terms to include: ``"coupling"``
        (centripetal softening ``-w^2 m_t`` in each link's frame),
        ``"axial_stiffening"`` (geometric stiffness of the kinetostatic
        forces), and the load effects ``"gravity"``, ``"springs"``,
        ``"loads"`` whose forces enter the kinetostatics. State-dependent
        ``"geometric_nonlinearity"`` needs a response and is refused here.
    modes : bool
        Also return mass-normalised mode shapes.
    steps : int, optional
        Instead of one crank angle, the frequencies at ``steps`` time nodes
        over the cycle (for a Campbell-like plot).

    Returns
    -------
    ModalResult
        ``frequencies`` [Hz] ascending, shape (n_modes,) or (steps, n_modes).
    """
    eff = check_effects(effects)
    if "geometric_nonlinearity" in eff:
        raise InputError("natural_frequencies: geometric_nonlinearity depends on the elastic response; "
                         "solve the scene and use its frequencies at the converged state")
    if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise InputError(f"natural_frequencies: n_modes must be an integer >= 1, got {n_modes!r}")
    if isinstance(crank_angle, bool) or not isinstance(crank_angle, (int, float, np.integer, np.floating)):
        raise InputError(f"natural_frequencies: crank_angle must be a number [rad], got {crank_angle!r}")
    if not np.isfinite(crank_angle):
        raise InputError(f"natural_frequencies: crank_angle must be finite, got {crank_angle!r}")
    model = FEModel(mechanism)
    if steps is not None:
        motion = kinematics(mechanism, steps=steps)
    else:
        motion = _motion_at(mechanism, crank_angle)
    asm = Assembler(model, motion, eff, damping=None, frame=True)
    terms = asm.system()
    out = eig_frequencies(terms.M, terms.K, n_modes, shapes=modes, name=mechanism.name,
                          labels=model.dof_labels)
    f, phi = (out if modes else (out, None))
    if np.any(f < 0):
        warnings.warn(f"{mechanism.name}: a negative stiffness eigenvalue (buckling or instability) "
                      "appears: its frequency is reported as negative", RuntimeWarning, stacklevel=2)
    if steps is None:
        f = f[0]
        phi = phi[0] if phi is not None else None
        ca = np.asarray(motion.crank_angle[0])
    else:
        ca = motion.crank_angle
    return ModalResult(f, phi, ca, tuple(model.dof_labels))


def global_matrices(mechanism: Mechanism, crank_angle: float = 0.0, effects=(),
                    damping=None) -> GlobalMatrices:
    """Global M, C, K (scipy.sparse CSR) and load Q at one crank position.

    The inertial-frame formulation the response is solved in (all terms of
    the chosen effects), assembled from the element matrices through the
    element DOF map (COO -> CSR).

    Parameters
    ----------
    mechanism : Mechanism
    crank_angle : float
        Absolute angle of the first driven member [rad].
    effects : sequence of str
        Effects (see :data:`kedfem.fe.effects.EFFECTS`); state-dependent ones
        are evaluated at zero elastic displacement.
    damping : Rayleigh or ModalDamping, optional

    Returns
    -------
    GlobalMatrices
    """
    eff = check_effects(effects)
    model = FEModel(mechanism)
    motion = _motion_at(mechanism, crank_angle)
    asm = Assembler(model, motion, eff, damping=damping)
    M, C, K, Q = asm.sparse_system(0)
    dC, dK, dQ = asm.state_terms(np.zeros((1, model.n_dof)), np.zeros((1, model.n_dof)))
    if dK is not None:
        K = K + sp.csr_matrix(dK[0])
        Q = Q + dQ[0]
    if dC is not None:
        C = C + sp.csr_matrix(dC[0])
    return GlobalMatrices(M, C, K, Q, tuple(model.dof_labels), float(motion.crank_angle[0]))
