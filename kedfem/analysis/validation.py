"""Self-validation: state-space versus modal frequencies, modal superposition, direct integration.

* :func:`table3` reproduces the paper's Table 3 comparison for the mould
  oscillator's four crank groups: the natural frequency from the state
  matrices (with damping and coupling) versus undamped modal eigenanalysis,
  both at the converged periodic state.
* :func:`modal_superposition` is an independent periodic solver for
  time-invariant systems with classical damping: modal decomposition
  (``scipy.linalg.eigh``) and, per mode, the exact frequency response to the
  piecewise-linear load through its Fourier series (no matrix exponentials,
  no block-cyclic condensation). It is what the ``foh`` hold discretises
  exactly, so the two agree to round-off.
* :func:`validate` runs the checks that apply to a scene.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..fe.assembler import Assembler
from ..errors import KedError
from .pipeline import solve
from .scene import Scene

__all__ = ["FrequencyCheck", "ResponseCheck", "ValidationReport", "modal_superposition", "validate",
           "table3"]



@dataclass(frozen=True)
class FrequencyCheck:
    """Fundamental frequency of a scene at its converged periodic state [Hz].

    ``state_space`` and ``modal`` are cycle means of the lowest frequency;
    ``paper_*`` the published values where there are some.
    """

    label: str
    state_space: float
    modal: float
    minimum: float
    maximum: float
    iterations: int
    converged: bool
    paper_state_space: float | None = None
    paper_modal: float | None = None

    @property
    def difference(self) -> float:
        """Relative difference state-space versus modal."""
        return abs(self.state_space - self.modal) / self.modal


@dataclass(frozen=True)
class ResponseCheck:
    """Largest relative difference of the periodic response against a second method.

    ``estimate``: the solve's own estimate of its history error (None when it
    has none), which the difference should not exceed by much.
    """

    label: str
    method: str
    max_rel_error: float
    n: int
    estimate: float | None = None


@dataclass(frozen=True)
class ValidationReport:
    """Results of :func:`validate` or :func:`table3`."""

    frequencies: tuple[FrequencyCheck, ...] = ()
    responses: tuple[ResponseCheck, ...] = ()

    def table(self) -> str:
        """Plain-text table of all checks."""
        lines = []
        if self.frequencies:
            lines.append(f"{'scene':28s} {'state-space':>11s} {'modal':>9s} {'diff':>7s} "
                         f"{'min..max over cycle':>19s} {'iter':>4s} {'paper ss':>8s} {'paper modal':>11s}")
            for f in self.frequencies:
                pss = f"{f.paper_state_space:8.2f}" if f.paper_state_space else " " * 8
                pm = f"{f.paper_modal:11.2f}" if f.paper_modal else " " * 11
                lines.append(f"{f.label:28s} {f.state_space:9.3f}Hz {f.modal:7.3f}Hz {100 * f.difference:6.3f}% "
                             f"{f.minimum:8.3f}..{f.maximum:<8.3f}Hz {f.iterations:4d} {pss} {pm}")
        if self.responses:
            lines.append(f"{'scene':28s} {'second method':38s} {'n':>6s} {'max rel. difference':>20s} "
                         f"{'own estimate':>12s}")
            for r in self.responses:
                est = f"{r.estimate:12.1e}" if r.estimate is not None else f"{'-':>12s}"
                lines.append(f"{r.label:28s} {r.method:38s} {r.n:6d} {r.max_rel_error:20.3e} {est}")
        return "\n".join(lines)


def modal_superposition(M, C, K, Q, period: float, harmonics: int = 4000, load: str = "linear"):
    """Periodic response of a time-invariant system by modal superposition.

    Parameters
    ----------
    M, C, K : ndarray, shape (N, N)
        Constant mass, damping and stiffness; ``C`` must be classical
        (diagonal in the undamped modes).
    Q : ndarray, shape (n, N)
        Load at ``t_k = k T / n``.
    period : float
        Period [s].
    harmonics : int
        Aliases per DFT bin summed for ``load="linear"`` (the truncated tail
        decays as ``1/m^4``).
    load : {"linear", "trigonometric"}
        How the load varies between the nodes: piecewise linear (what the
        ``foh`` hold discretises exactly), or the trigonometric interpolant
        of the samples (exact for a load with harmonics below ``n / 2``: the
        exact periodic response of a band-limited load).

    Returns
    -------
    U, V : ndarray, shape (n, N)
        Displacements and velocities at the nodes.

    Raises
    ------
    KedError
        Non-classical damping, or an undamped zero-frequency mode.
    """
    M = np.asarray(M, float)
    K = np.asarray(K, float)
    C = np.asarray(C, float)
    Q = np.asarray(Q, float)
    n, N = Q.shape
    lam, Phi = sla.eigh(0.5 * (K + K.T), 0.5 * (M + M.T))
    Cm = Phi.T @ C @ Phi
    off = Cm - np.diag(np.diag(Cm))
    if np.max(np.abs(off), initial=0.0) > 1e-8 * max(np.max(np.abs(Cm)), 1e-300):
        raise KedError("modal_superposition: damping is not classical (not diagonal in the undamped modes)")
    w2 = np.clip(lam, 0.0, None)
    c = np.diag(Cm)
    if np.any((w2 <= 1e-12 * w2.max()) & (c <= 0)):
        raise KedError("modal_superposition: an undamped zero-frequency mode has no periodic response")
    F = Q @ Phi                       # modal loads (n, N)
    Fh = np.fft.fft(F, axis=0) / n    # DFT bins r = 0..n-1
    r = np.fft.fftfreq(n, 1.0 / n)    # signed bin numbers
    Om = 2 * math.pi / period
    if load == "trigonometric":
        if n % 2 == 0:
            raise KedError("modal_superposition: a trigonometric load needs an odd number of samples "
                           "(the Nyquist harmonic of an even number is not determined by them)")
        w = r * Om
        H = 1.0 / (w2[None, :] - (w**2)[:, None] + 1j * w[:, None] * c[None, :])
        eta = np.fft.ifft(Fh * H, axis=0) * n
        etad = np.fft.ifft(Fh * (1j * w)[:, None] * H, axis=0) * n
        return (eta.real @ Phi.T), (etad.real @ Phi.T)
    if load != "linear":
        raise KedError(f"modal_superposition: load must be 'linear' or 'trigonometric', got {load!r}")
    l = np.arange(-harmonics, harmonics + 1)
    m = r[:, None] + n * l[None, :]   # (n, L) harmonic numbers
    x = math.pi * m / n
    sinc2 = np.where(m == 0, 1.0, (np.sin(x) / np.where(m == 0, 1.0, x)) ** 2)
    w = m * Om
    # H(w) = 1 / (w_j^2 - w^2 + i w c_j), per mode j: shape (n, L, N)
    H = 1.0 / (w2[None, None, :] - (w**2)[..., None] + 1j * w[..., None] * c[None, None, :])
    G = np.sum(sinc2[..., None] * H, axis=1)                    # (n, N)
    Gv = np.sum((sinc2 * 1j * w)[..., None] * H, axis=1)
    eta = np.fft.ifft(Fh * G, axis=0) * n
    etad = np.fft.ifft(Fh * Gv, axis=0) * n
    return (eta.real @ Phi.T), (etad.real @ Phi.T)


def _time_invariant(terms) -> bool:
    def flat(A):
        return np.max(np.ptp(A, axis=0)) <= 1e-12 * max(np.max(np.abs(A)), 1e-300)
    return flat(terms.M) and flat(terms.C) and flat(terms.K)


def frequency_check(result, label: str, paper=None) -> FrequencyCheck:
    """Fundamental frequency (state-space and modal) of a solved scene."""
    f = result.frequencies(2)
    pss, pm = paper if paper else (None, None)
    return FrequencyCheck(label, f.fundamental, f.fundamental_modal, float(np.min(f.modal[:, 0])),
                          float(np.max(f.modal[:, 0])), result.iterations, result.converged, pss, pm)


def validate(scene: Scene, label: str | None = None, foh_steps: int | None = None) -> ValidationReport:
    """Run the checks that apply to a scene.

    Always: fundamental frequency from the state matrices versus modal
    eigenanalysis at the converged state. For a time-invariant scene with
    classical damping, the periodic response against modal superposition,
    twice: the scene's own solve (its scheme and tolerance) against the exact
    response to the load's trigonometric interpolant on 361 instants (the
    difference should be within the solve's error estimate), and the paper's
    ``foh`` hold on ``foh_steps`` (default ``scene.steps``, else 180) elements
    against modal superposition of the piecewise-linear load it discretises
    exactly (round-off).

    Returns
    -------
    ValidationReport
    """
    from ..motion.kinematics import kinematics
    label = label or scene.name or scene.mech.name
    res = solve(scene)
    freqs = (frequency_check(res, label),)
    responses = []
    if not scene.state_dependent:
        n_ex = 361
        ex = res.resample(np.arange(n_ex) * (scene.period / n_ex))
        terms = Assembler(res.model, ex.motion, scene.effects, damping=scene.damping).system()
        if _time_invariant(terms):
            try:
                U, _V = modal_superposition(terms.M[0], terms.C[0], terms.K[0], terms.Q, scene.period,
                                            load="trigonometric")
            except KedError:
                U = None
            if U is not None:
                err = float(np.max(np.abs(ex.U - U)) / max(np.max(np.abs(U)), 1e-300))
                est = res.error.history if res.error is not None else None
                responses.append(ResponseCheck(label, f"modal superposition (exact), {res.scheme}", err,
                                               res.elements, est))
                n = foh_steps or scene.steps or 180
                mo = kinematics(scene.mech, steps=n)
                tq = Assembler(res.model, mo, scene.effects, damping=scene.damping).system()
                Ul, _ = modal_superposition(tq.M[0], tq.C[0], tq.K[0], tq.Q, scene.period)
                foh = solve(dataclasses.replace(scene, hold="foh", method="auto", steps=n, estimate=False))
                Uf = foh.resample(mo.t).U
                err = float(np.max(np.abs(Uf - Ul)) / max(np.max(np.abs(Ul)), 1e-300))
                responses.append(ResponseCheck(label, "modal superposition (foh)", err, n))
    return ValidationReport(freqs, tuple(responses))


def table3(steps: int | None = None, **overrides) -> ValidationReport:
    """The paper's Table 3 for the mould oscillator's crank groups 1..4.

    Each group is :func:`kedfem.analysis.defaults.default_scene` (all the mould's
    effects, 2 % modal damping) solved to its converged periodic state; the
    fundamental frequency from the state matrices (with damping and Coriolis
    coupling) is compared with undamped modal eigenanalysis, both as cycle
    means, next to the paper's values.

    Parameters
    ----------
    steps : int, optional
        Fixed number of time elements (default: what the scene's tolerance needs).
    **overrides
        Parameters of :func:`mechanisms.mould_oscillator.build`.

    Returns
    -------
    ValidationReport
        One :class:`FrequencyCheck` per group, with the paper's values.
    """
    from ..catalogue import get
    mo = get("mould_oscillator")

    from .defaults import default_scene
    checks = []
    for g in (1, 2, 3, 4):
        res = solve(default_scene(group=g, steps=steps, **overrides))
        checks.append(frequency_check(res, f"mould oscillator, group {g}", mo.TABLE3[g]))
    return ValidationReport(tuple(checks), ())
