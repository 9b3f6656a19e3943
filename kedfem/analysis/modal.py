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

from ..fe.model import FEModel
from ..fe.assembler import Assembler
from ..fe.effects import check_effects
from ..solvers.eigen import generalised_eigh
from ..checks import flag, integer, real
from ..errors import InputError, user_stacklevel
from ..motion.kinematics import Motion, kinematics, kinematics_at, static_motion
from ..model.mechanism import Mechanism, require_mechanism

__all__ = ["ModalResult", "GlobalMatrices", "Frequencies", "natural_frequencies", "global_matrices", "eig_frequencies",
           "frequencies_over_cycle", "modes_at"]

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


@dataclass(frozen=True)
class Frequencies:
    """Natural frequencies over the cycle at the (converged) periodic state.

    Attributes
    ----------
    crank_angle : ndarray, shape (n,)
        [rad].
    modal : ndarray, shape (n, k)
        Undamped modal eigenanalysis ``K phi = omega^2 M phi`` [Hz].
    state_space : ndarray, shape (n, k)
        ``|lambda| / 2 pi`` of the eigenvalues of the state matrix ``F`` with
        damping and Coriolis coupling [Hz].
    damping_ratio : ndarray, shape (n, k)
        ``-Re(lambda) / |lambda|`` of the same eigenvalues.
    """

    crank_angle: np.ndarray
    modal: np.ndarray
    state_space: np.ndarray
    damping_ratio: np.ndarray

    @property
    def fundamental(self) -> float:
        """Cycle mean of the lowest state-space frequency [Hz]."""
        return float(np.mean(self.state_space[:, 0]))

    @property
    def fundamental_modal(self) -> float:
        """Cycle mean of the lowest modal frequency [Hz]."""
        return float(np.mean(self.modal[:, 0]))


def _motion_at(mechanism: Mechanism, crank_angle) -> Motion:
    crank_angle = real("crank position", "crank_angle [rad]", crank_angle)
    if not mechanism.drives:
        return static_motion(mechanism)
    return kinematics_at(mechanism, crank_angle)


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
    require_mechanism(mechanism, "natural_frequencies")
    modes = flag("natural_frequencies", "modes", modes)
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
                      "appears: its frequency is reported as negative", RuntimeWarning, stacklevel=user_stacklevel())
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
    require_mechanism(mechanism, "global_matrices")
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


def _about_state(model: FEModel, motion: Motion, scene, U, V, idx):
    """Co-moving-frame system at the cycle's nodes ``idx`` (None: all), its stiffness with the
    tangent of the state-dependent effects about the response ``U, V`` (n, N)."""
    S = Assembler(model, motion, scene.effects, damping=scene.damping, frame=True).system(idx)
    K = S.K
    if scene.state_dependent:
        glob = Assembler(model, motion, scene.effects, damping=scene.damping)
        Ui, Vi = (U, V) if idx is None else (U[idx], V[idx])
        _dC, dK, _dQ = glob.state_terms(Ui, Vi, idx)
        if dK is not None:
            K = K + dK
    return S, K


def modes_at(model: FEModel, motion: Motion, scene, U, V, node: int, n_modes: int):
    """Undamped mode shapes at one time node of a periodic response (co-moving frame).

    Parameters
    ----------
    model, motion, scene
        Of the periodic result.
    U, V : ndarray, shape (n, N)
        The response [m, rad] and its rate, about which state-dependent effects are linearised.
    node : int
        Time node.
    n_modes : int

    Returns
    -------
    f : ndarray, shape (k,)
        Frequencies [Hz].
    phi : ndarray, shape (N, k)
        Mass-normalised mode shapes.
    """
    idx = np.array([node])
    n_modes = integer("mode_shapes", "n_modes", n_modes, 1)
    S, K = _about_state(model, motion, scene, U, V, idx)
    f, phi = eig_frequencies(S.M, K, min(n_modes, model.n_dof), shapes=True)
    return f[0], phi[0]


def frequencies_over_cycle(model: FEModel, motion: Motion, scene, U, V, n_modes: int = 4,
                           idx=None) -> Frequencies:
    """Natural frequencies at the time nodes ``idx`` (None: all) of a periodic response.

    Undamped modal frequencies of ``(K, M)`` and the state-space frequencies and
    damping ratios of ``F = [[0, I], [-M^-1 K, -M^-1 C]]`` (co-moving frame), with
    the state-dependent effects linearised about ``U, V`` (n, N).

    Returns
    -------
    Frequencies
        Arrays (nt, k) [Hz].
    """
    from ..solvers.periodic import state_matrix
    n_modes = integer("frequencies", "n_modes", n_modes, 1)
    S, K = _about_state(model, motion, scene, U, V, idx)
    k = min(n_modes, model.n_dof)
    fm = eig_frequencies(S.M, K, k)
    Minv = np.linalg.inv(S.M)
    lam = np.linalg.eigvals(state_matrix(Minv @ K, Minv @ S.C))
    # oscillatory eigenvalues (one of each conjugate pair), lowest |lambda| first
    tol = 1e-9 * np.abs(lam).max(axis=1, keepdims=True)
    mag = np.where(lam.imag > tol, np.abs(lam), np.inf)
    order = np.argsort(mag, axis=1)[:, :k]
    sel = np.take_along_axis(lam, order, axis=1)
    ok = np.isfinite(np.take_along_axis(mag, order, axis=1))
    fs = np.where(ok, np.abs(sel) / (2 * math.pi), np.nan)
    zs = np.where(ok, -sel.real / np.where(ok, np.abs(sel), 1.0), np.nan)
    return Frequencies(motion.crank_angle if idx is None else motion.crank_angle[idx], fm, fs, zs)
