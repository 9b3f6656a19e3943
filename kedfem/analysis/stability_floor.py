"""The stability floor of a solve and its verdict: the fewest time elements whose numerical damping
leaves the spectral radius within ``rtol``, how much the scheme can have lowered the radius on fewer,
and the :class:`~kedfem.analysis.results.Stability` of the finest level
(:class:`StabilityFloor`, a part of :class:`kedfem.analysis.pipeline._Run`)."""

from __future__ import annotations

import math

import numpy as np

from .results import Stability, stability_verdict
from .scene import MAX_STEPS, Scene

#: modes whose per-cycle decay lies within this of the least damped one's (natural logarithm)
#: must keep their multipliers to rtol (:meth:`_Run.stability_floor`)
STAB_MARGIN = 0.25
#: a spectral radius below this, even raised by the most the numerical damping can have lowered
#: it, is stable beyond doubt: the stability floor is not pursued (:meth:`_Run.stable_beyond_doubt`);
#: the verdict needs a margin to 1, not the radius to rtol (the slider-crank at 0.5 % damping:
#: 0.7565 on 48 elements, at most 0.768 by the damping bound, 0.7654 on 192, which the floor
#: asked for at four times the cost); the stated error of the radius includes the bound
CERTAIN_RHO = 0.9
#: below the stability floor a solve stops on its peaks alone when the spectral radius (raised by
#: the damping bound) is below this; between it and CERTAIN_RHO, or when only the modes' physical
#: decay makes the verdict clear, the histories must meet rtol too
HISTORY_FREE_RHO = 0.5


def undamped(scene: Scene) -> bool:
    """The scene dissipates no energy: no damping model (or a zero one) and no friction."""
    from ..fe.effects import ModalDamping, Rayleigh
    d = scene.damping
    if isinstance(d, ModalDamping) and d.zeta > 0:
        return False
    if isinstance(d, Rayleigh) and (d.alpha > 0 or d.beta > 0):
        return False
    if "loads" in scene.effects and scene.mech.frictions:
        return False
    return True


def radius_error(rho, n, rate: float) -> float | None:
    """Error of the finest level's spectral radius ``rho[-1]`` from the levels' radii ``rho`` on
    ``n`` elements (coarse to fine; None with one level).

    The last change extrapolated at ``rate`` (the peaks' observed rate) where the radii contract:
    the last change at most half the one before (or two levels only). Where they do not, the last
    change itself, with no credit: a linkage near its Grashof change point, parametrically
    unstable, gave 1.2e24, 4.0e28 and 1.5e28 on 3072/6144/12288 elements and was printed
    ``1.5e+28 +- 2e+27``.
    """
    if len(rho) < 2:
        return None
    change = abs(rho[-1] - rho[-2])
    if len(rho) >= 3 and change > 0.5 * abs(rho[-2] - rho[-3]):
        return change
    return change / ((n[-1] / n[-2]) ** rate - 1.0)


class StabilityFloor:
    """The stability floor and verdict of :class:`kedfem.analysis.pipeline._Run` (a mixin: it reads
    the run's ``scene``, ``scheme``, ``levels`` and the modal bands of its resolution floor)."""

    def stability_floor(self) -> tuple[int, float]:
        """Fewest time elements whose numerical damping leaves the spectral radius within ``rtol``.

        An L-stable scheme damps every mode a little per element (Radau IIA:
        ``-ln|R(i y)| ~ y^6 / 7200`` at ``y = omega h``), so a mode with many
        periods per cycle loses ``n (omega T / n)^6 / 7200`` of its multiplier's
        modulus on ``n`` elements even when the response is resolved (a
        105 Hz mode of a linkage at 300 rpm on 48 elements: a factor 5). The
        scheme only lowers multipliers, so the spectral radius is right to
        ``rtol`` when the modes that set it lose less than that: the modes
        whose physical decay per cycle ``exp(-zeta omega T)`` lies within
        :data:`STAB_MARGIN` (in its logarithm) of the least damped one, with
        ``zeta`` from the scene's damping (modal ratio; Rayleigh ``alpha /
        (2 omega) + beta omega / 2``). Returns the elements and the highest such
        frequency [Hz]; ``(0, 0)`` for schemes without numerical damping and for
        undamped scenes (whose verdict is ``marginal`` by structure).
        """
        from ..fe.effects import ModalDamping, Rayleigh
        sc, scheme = self.scene, self.scheme
        if not scheme.l_stable or self._bands is None or undamped(sc):
            return 0, 0.0
        lo, hi = self._bands
        T = sc.period
        w_lo, w_hi = 2.0 * math.pi * lo, 2.0 * math.pi * hi
        d = sc.damping
        if isinstance(d, ModalDamping):
            zeta = np.full(lo.shape, float(d.zeta))
        elif isinstance(d, Rayleigh):
            zeta = d.alpha / (2.0 * np.maximum(w_lo, 1e-300)) + d.beta * w_lo / 2.0
        else:
            zeta = np.zeros(lo.shape)
        decay = -zeta * w_lo * T  # ln of the physical multiplier modulus per cycle
        self._stab_decay = float(decay[w_lo > 0].max()) if (w_lo > 0).any() else 0.0
        keep = (w_lo > 0) & (decay >= decay.max() - STAB_MARGIN)
        if not keep.any():
            return 0, 0.0
        theta = w_hi[keep] * T
        tol = sc.rtol if sc.rtol is not None else 1e-3
        tab = scheme.tableau

        def loss(n):
            y = theta / n
            z = 1j * y[:, None, None]
            s_ = tab.A.shape[0]
            stage = np.linalg.solve(np.eye(s_)[None] - z * tab.A[None], np.ones((y.size, s_, 1)))[..., 0]
            Rz = 1.0 + z[:, 0, 0] * (stage @ tab.b)
            return float(np.max(-n * np.log(np.abs(Rz))))

        self._stab_loss = loss
        lo_n, n = 1, max(scheme.min_elements, 8)
        while loss(n) > tol and n < MAX_STEPS:
            lo_n, n = n, 2 * n
        while n - lo_n > 1:  # the fewest: bisection (the loss falls monotonically with n)
            mid = (lo_n + n) // 2
            lo_n, n = (lo_n, mid) if loss(mid) <= tol else (mid, n)
        return n, float(hi[keep].max())

    def damping_bound(self) -> float:
        """Bound [-] on how much the finest level's numerical damping lowers the spectral radius:
        the true one is at most ``rho (1 + bound)`` (0 once the stability floor is met)."""
        n = self.levels[-1].n
        if not self._stab_need or n >= self._stab_need or self._stab_loss is None:
            return 0.0
        loss = self._stab_loss(n)
        return math.expm1(loss) if loss < 700.0 else math.inf  # a very slow crank: no bound

    def stable_beyond_doubt(self) -> bool:
        """The finest level's spectral radius, raised by the most its numerical damping can have
        lowered it, is still below :data:`CERTAIN_RHO`: more elements would sharpen a number
        whose verdict is not in doubt (a linkage at rho 0.01 refined to 768 elements for it)."""
        rho = self.levels[-1].discrete.spectral_radius
        if not np.isfinite(rho):
            return False
        return self._raised_rho() < CERTAIN_RHO or (self.quasi_static_decay() and rho < CERTAIN_RHO)

    def _raised_rho(self) -> float:
        """The finest level's spectral radius raised by the most its numerical damping can have
        lowered it (inf when that is not bounded)."""
        rho, bound = self.levels[-1].discrete.spectral_radius, self.damping_bound()
        return rho * (1.0 + bound) if (np.isfinite(rho) and math.isfinite(bound)) else math.inf

    def clearly_stable(self) -> bool:
        """The finest level's spectral radius, raised by the most the numerical damping can have
        lowered it, is below :data:`HISTORY_FREE_RHO`: a verdict so clear that the solve stops on
        its peaks alone below the stability floor."""
        return self._raised_rho() < HISTORY_FREE_RHO

    def quasi_static_decay(self) -> bool:
        """No mode within the drive's excitation (:meth:`resolution` said quasi-static) and every
        mode's physical decay over a cycle below :data:`CERTAIN_RHO`: the multipliers are those
        decays (a slowly varying system), and a parametric resonance, which would need a mode
        within the motion's harmonics, cannot raise them to 1. The damping bound says nothing
        here: at 1 rpm the modes decay by ``e^-1500`` per cycle and the scheme's damping
        underflows the computed radius to 0 (the floor asked for 32768 elements)."""
        return (self._need <= 1 and not self._buckled and self._stab_decay < 0.0
                and self._stab_decay < math.log(CERTAIN_RHO) - STAB_MARGIN)

    def _raised_at(self, n: int) -> float:
        """The last level's spectral radius raised by the most the numerical damping of ``n``
        elements can lower it (inf when not finite or not bounded)."""
        rho = self.levels[-1].discrete.spectral_radius
        loss = self._stab_loss(n) if self._stab_loss is not None else math.inf
        return rho * math.exp(loss) if (np.isfinite(rho) and loss < 700.0) else math.inf

    def _clear_at(self, n: int) -> bool:
        """The last level's verdict would be clear on ``n`` elements (:meth:`clearly_stable`)."""
        return self._raised_at(n) < HISTORY_FREE_RHO

    def _doubt_cleared(self, n: int) -> bool:
        """The last level's verdict would be beyond doubt on ``n`` elements (see
        :meth:`stable_beyond_doubt`)."""
        rho = self.levels[-1].discrete.spectral_radius
        if not np.isfinite(rho):
            return False
        if self.quasi_static_decay() and rho < CERTAIN_RHO:
            return True
        return self._raised_at(n) < CERTAIN_RHO

    def stability(self, error=None) -> Stability:
        """Spectral radius of the finest level, its error from the coarser ones, the verdict."""
        rho = [lv.discrete.spectral_radius for lv in self.levels[-3:]]
        err = radius_error(rho, [lv.n for lv in self.levels[-3:]], error.rate) if error is not None else None
        bound = self.damping_bound()
        if bound and self.stable_beyond_doubt():
            # the stability floor was not needed for the verdict: the error is what the damping
            # may hide (with fewer elements given than a clear verdict needs, the note says it)
            hidden = rho[-1] * bound if math.isfinite(bound) else math.inf
            if self.quasi_static_decay():  # the modes' own decay bounds the radius
                hidden = min(hidden, math.exp(self._stab_decay + STAB_MARGIN))
            err = max(err or 0.0, hidden)
        verdict = stability_verdict(rho[-1], err)
        if (verdict == "marginal" and len(rho) >= 2 and rho[-1] > 1.0 + 1e-9
                and (min(rho[-2:]) > 1.0 + 1e-9 or rho[-1] >= rho[-2])
                and self.scheme.name.startswith("radau")):
            # Radau's numerical damping lowers the multipliers, the less the finer the level:
            # growth on the two finest levels, or growth that rises with refinement, is real
            # (a buckling rod: 1e51 on 48 elements, its change from 24 as large)
            verdict = "unstable"
        note = ""
        if undamped(self.scene) and verdict != "unstable":
            verdict = "marginal"
            note = ("undamped: the multipliers of a conservative scene lie on the unit circle unless a "
                    "parametric resonance makes them grow; the scheme's numerical damping can hide a weak one")
        elif self._stab_need and self.levels[-1].n < self._stab_need:
            why = ("in its error; not needed for a verdict this clear" if self.stable_beyond_doubt()
                   else "not in its error: give more elements")
            by = (f"by at most {100.0 * bound:.2g} %" if math.isfinite(bound) and bound < 1.0
                  else f"by at most a factor {1.0 + bound:.2g}" if math.isfinite(bound) and bound < 9.0
                  else "by orders of magnitude")
            note = (f"{self.levels[-1].n} time elements damp the modes up to {self._stab_f:.4g} Hz numerically "
                    f"by more than {self.scene.rtol or 1e-3:.0e} per cycle: the spectral radius is too low, "
                    f"{by} ({why}; a resolved radius needs about {self._stab_need} elements: "
                    f"Scene(steps={self._stab_need}) or more)")
        return Stability(rho[-1], err, verdict, self.scheme.name, self.levels[-1].n, note,
                         conservative=bool(undamped(self.scene) and verdict == "marginal"))
