"""The resolution floor of a solve: the fewest time elements that resolve the modes the drive
can excite, through the rigid-body motion's harmonics, its friction reversals and its process loads
(:meth:`ResolutionFloor.resolution`, a part of :class:`kedfem.analysis.pipeline._Run`)."""

from __future__ import annotations

import logging
import math
import warnings

import numpy as np

from ..errors import CostWarning, user_stacklevel
from ..fe.assembler import Assembler
from ..fe.effects.loads import load_force

# the steps of a solve log under the pipeline's name (docs/usage.md)
log = logging.getLogger("kedfem.analysis.pipeline")

#: a process load whose harmonics ask for this many times the elements the motion alone asks for
#: is named in a logged warning (:meth:`_Run.resolution`)
LOAD_WARN_FACTOR = 4
#: largest ``omega h`` at which a level counts as resolving a mode (one element per period)
RESOLVE_OMEGA_H = 2.0 * math.pi
#: instants of the cycle where the modal frequency bands are sampled
BAND_INSTANTS = 12
#: most instants the rigid-body motion's harmonics are sampled at (:meth:`ResolutionFloor._motion_band`)
MOTION_SAMPLES = 32768
#: lowest level (of the largest) the motion's harmonics are read at: below it the FFT's round-off
#: reads as harmonics up to the sampling limit (rtol 1e-13 on the four-bar)
MOTION_NOISE = 1e-12


def _harmonic_reach(X: np.ndarray, period: float, level: float, f_low: float = 0.0) -> float:
    """Highest frequency [Hz] of the harmonics of the periodic samples ``X`` (samples, k) above
    ``level`` of each column's largest (the columns below 1e-9 of the largest left out), those
    above ``f_low`` [Hz] weighted by ``(f_low / f)^2`` (0: none); 0 when none is above it."""
    F = np.abs(np.fft.rfft(X - X.mean(axis=0), axis=0))[1:]
    amp = F.max(axis=0)
    keep = amp > 1e-9 * amp.max() if amp.size and amp.max() > 0 else np.zeros(amp.shape, bool)
    if not keep.any():
        return 0.0
    env = (F[:, keep] / amp[keep]).max(axis=1)
    f = np.arange(1, env.size + 1) / period
    if f_low > 0.0:
        env = env * np.minimum(1.0, (f_low / f) ** 2)
    over = np.flatnonzero(env > level)
    return float(f[over.max()]) if over.size else 0.0


#: a tolerance-driven solve that ends on this many times the elements its floors ask for, with
#: process loads whose tables kink or step, says so (:meth:`ResolutionFloor.corner_cost`)
CORNER_FACTOR = 8


class ResolutionFloor:
    """The resolution floor of :class:`kedfem.analysis.pipeline._Run` (a mixin: it reads the run's
    ``scene``, ``model`` and ``cycle`` and keeps the modal bands it finds for the stability floor)."""

    def resolution(self) -> tuple[int, float]:
        """Fewest time elements that resolve the modes the drive can excite.

        An L-stable scheme damps the resonant response and the free vibration
        of modes its elements do not resolve, alike at every coarse level, so
        two such levels can agree while both are wrong: the coarser levels of
        an error estimate must resolve (``omega h <= RESOLVE_OMEGA_H``) every
        mode the drive excites. The excitation reaches (a) the highest
        harmonic of the rigid-body motion above ``rtol / 1000`` of its
        largest (the inertia loads and the time variation of ``M, C, K``),
        (b) ``1 / (pi tau)`` of the fastest friction reversal (a regularised
        step of time scale ``tau``), (c) the highest harmonic of the process
        loads (declared loads with a profile) above ``rtol / 1000`` of their
        largest: a kink or a step of a load rings modes far above the
        drive's harmonics (a press's forming force, kinked where the tool
        meets and leaves the part: a 74 nm rod deflection 17 % off on 384
        elements whose three levels agreed to 1e-5). A mode is excited when its frequency
        band (over the cycle) starts within that reach, or within the reach
        of the time variation around an excited mode (its band's top plus
        (a)). Bands come from the co-moving-frame system (the scene's
        effects, no state terms) at :data:`BAND_INSTANTS` instants.

        Returns
        -------
        n : int
            Fewest time elements.
        f : float
            Highest frequency to resolve [Hz].
        """
        from .modal import eig_frequencies
        sc = self.scene
        T = sc.period
        t = np.arange(BAND_INSTANTS) * (T / BAND_INSTANTS)
        asm = Assembler(self.model, self.cycle.at(t), sc.effects, damping=None, frame=True)
        S = asm.system()
        f = eig_frequencies(S.M, S.K, name=sc.mech.name, labels=self.model.dof_labels)
        self._buckled = bool(np.any(f <= 0.0))  # a negative stiffness: growth, not a decaying mode
        f = np.sort(np.abs(f), axis=1)  # (instants, modes), Hz
        lo, hi = f.min(axis=0), f.max(axis=0)
        self._bands = (lo, hi)
        f_kin = self._motion_band(level=1e-3 * sc.rtol)
        f_fr = self._friction_band()
        self._friction_reach = f_fr if f_fr > f_kin else 0.0
        f_ld = self._load_band(level=1e-3 * sc.rtol, f_low=float(lo.min()) if lo.size else 0.0)
        reach = max(f_kin, f_fr, f_ld)

        def elements(reach: float) -> tuple[int, float] | None:
            """Elements and highest frequency [Hz] to resolve for an excitation up to ``reach``
            (None: no mode within it)."""
            excited = lo <= reach
            if not excited.any():
                return None
            excited |= lo <= float(hi[excited].max()) + f_kin  # the time variation mixes an excited
            f_res = float(hi[excited].max())                   # mode into its neighbours
            return int(math.ceil(2.0 * math.pi * f_res * T / RESOLVE_OMEGA_H)), f_res

        found = elements(reach)
        if found is None:
            log.info("%s: no mode within the excitation (%.4g Hz): quasi-static", sc.mech.name, reach)
            return 1, 0.0
        n, f_res = found
        log.info("%s: excitation reaches %.4g Hz, modes to resolve up to %.4g Hz: >= %d elements",
                 sc.mech.name, reach, f_res, n)
        base = max(f_kin, f_fr)
        steps = self._load_steps() if f_ld > base else {}
        if steps:
            # a process load whose profile steps or kinks rings modes far above the drive's
            # harmonics: say so where it multiplies the elements (a new user's one-stroke forming
            # load dropped to zero at the dead centre: 6144 elements and 12 s where 768 did)
            n0 = (elements(base) or (1, 0.0))[0]
            if n >= LOAD_WARN_FACTOR * n0:
                # a Python warning (and the log at info, as the scene's unsimulated effects): a script
                # run without logging set up saw nothing of the one line that said why its solve took
                # 8x its forecast (a new user's toggle press)
                cures = []
                for name, angle in steps.items():
                    prof = sc.mech.loads[name].profile
                    at = f"'{name}' at absolute crank angle {math.degrees(angle) % 360:.1f} deg"
                    if np.any(np.diff(prof.x) == 0):  # a repeated entry: a step smooth=True keeps
                        cures.append(f"{at}: a short ramp for its table's repeated entry, with smooth=True")
                    elif prof.stroke != "both":
                        cures.append(f"{at}: a second load for the other stroke, where it ends at a dead "
                                     f"centre (as examples/press.py)")
                    else:
                        cures.append(f"{at}: smooth=True (S-curves between its table's entries)")
                alone = (f"the motion alone asks for {n0}" if n0 > 1 else
                         "the motion alone is quasi-static")
                msg = (f"{sc.mech.name}: process load(s) {', '.join(repr(x) for x in steps)} step: their "
                       f"harmonics reach {f_ld:.4g} Hz, which asks for >= {n} time elements where {alone}; "
                       f"these cost fewer: {'; '.join(cures)}")
                log.info("%s", msg)
                warnings.warn(msg, CostWarning, stacklevel=user_stacklevel())
                self._cost_said = True
        return n, f_res

    def _motion_band(self, samples: int = 512, level: float = 1e-6) -> float:
        """Highest frequency [Hz] of the rigid-body motion's harmonics above ``level``.

        Sampled at ``samples`` instants, four times as many while the harmonics above ``level``
        reach the upper half of what the samples resolve (up to :data:`MOTION_SAMPLES`): a
        linkage near a toggle or a Grashof change point whips through it in a small part of the
        cycle (a four-bar 1e-5 m from its change point: harmonics to 1295 per cycle, where 512
        samples saw their own limit, 256, and three levels that all missed the whip agreed, 20x
        below the true error). Beyond the last sampling a logged warning says so.
        """
        T = self.scene.period
        level = max(level, MOTION_NOISE)
        while True:
            mo = self._band_motion(samples)
            X = np.concatenate([x.reshape(samples, -1) for x in (mo.a, mo.alpha, mo.omega ** 2, mo.sdd)
                                if x.size], axis=1)
            reach = _harmonic_reach(X, T, level)
            if reach * T <= samples // 4 + 0.5:
                return reach
            if samples * 4 > MOTION_SAMPLES:
                log.warning("%s: the rigid-body motion has harmonics above %.1e of its largest up to %.0f per "
                            "cycle, in the upper half of what %d samples resolve (a toggle or a change point the "
                            "linkage passes close to): the time elements may not resolve it, and the error "
                            "estimate may be low", self.scene.mech.name, level, reach * T, samples)
                return reach
            samples *= 4

    def _load_band(self, level: float, f_low: float = 0.0, samples: int = 16384) -> float:
        """Highest frequency [Hz] of the process loads' harmonics above ``level`` of their largest
        (0 without a process load among the scene's effects), a harmonic above the lowest mode
        ``f_low`` [Hz] weighted by ``(f_low / f)^2``: it drives the stiffer modes there, whose
        response to it is smaller by their stiffness (a pump's smooth stroke load reached 1.9 kHz
        unweighted, 3072 time elements where 384 met the tolerance to 1e-5)."""
        at = self._joint_loads(samples)
        if not at:
            return 0.0
        X = np.concatenate(list(at.values()), axis=1)  # (samples, 2 per joint)
        return _harmonic_reach(X, self.scene.period, level, f_low)

    def _joint_loads(self, samples: int) -> dict[str, np.ndarray]:
        """The process loads (declared with a profile) on each joint together [N] (samples, 2), at
        ``samples`` equally spaced instants (two one-stroke loads on a joint meet); empty without
        one or without ``loads`` among the scene's effects."""
        at: dict[str, np.ndarray] = {}
        for name, F in self._process_loads(samples).items():
            joint = self.scene.mech.loads[name].joint
            at[joint] = at.get(joint, 0.0) + F
        return at

    def _process_loads(self, samples: int) -> dict[str, np.ndarray]:
        """Each process load (declared with a profile) [N] (samples, 2), by name, at ``samples``
        equally spaced instants (computed once); empty without ``loads`` among the scene's effects."""
        cache = self.__dict__.setdefault("_load_cache", {})
        if samples not in cache:
            loads = {name: ld for name, ld in self.scene.mech.loads.items() if ld.profile is not None}
            mo = self._band_motion(samples) if loads and "loads" in self.scene.effects else None
            cache[samples] = {name: load_force(mo, ld) for name, ld in loads.items()} if mo is not None else {}
        return cache[samples]

    def corner_cost(self, n: int, floor: int, seconds: float) -> str | None:
        """What a tolerance-driven solve that ended on ``n`` time elements, at least
        :data:`CORNER_FACTOR` times the ``floor`` the excited modes and the first levels ask for,
        after ``seconds`` [s], may owe to process loads whose tables kink or step (no
        ``smooth=True``), as a message (None: not so, or said already as a step).

        The response's derivatives jump at a table's corners; the levels then converge slowly
        there, and the estimate's rate stays short of the asymptotic range: a new user's wiper
        linkage with a ramped load ended on 3072 elements in 15 s, the same table with
        ``smooth=True`` on 192 in 0.85 s, and nothing said why.
        """
        sc = self.scene
        if sc.steps is not None or "loads" not in sc.effects or getattr(self, "_cost_said", False):
            return None
        corners = [name for name, ld in sc.mech.loads.items()
                   if ld.profile is not None and not ld.profile.smooth and len(ld.profile.x) >= 2]
        if not corners or n < CORNER_FACTOR * floor:
            return None
        names = ", ".join(f"'{c}'" for c in corners)
        return (f"{sc.mech.name}: the solve refined to {n} time elements ({seconds:.1f} s), {n // floor}x the {floor} "
                f"the excited modes ask for; the process load(s) {names} kink or step at their table's entries "
                f"(no smooth=True), where the response converges slowly: smooth=True (S-curves between the "
                f"entries) usually ends on far fewer elements")

    def _load_steps(self, samples: int = 16384, jump: float = 0.2) -> dict[str, float]:
        """The process loads that step, with the absolute crank angle [rad] of the step: where the
        loads on a joint together change by more than ``jump`` of their largest between two of
        ``samples`` instants per cycle (a one-stroke load at a dead centre, a table without
        smoothing; a smooth one, however steep, changes by a sliver per sample), those among them
        that change by more than half of that there on their own (a press's forward and return
        loads that meet at the dead centre step each, not together)."""
        mech, each = self.scene.mech, self._process_loads(samples)
        out = {}
        for joint, F in self._joint_loads(samples).items():
            big = float(np.abs(F).max())
            change = np.abs(np.diff(F, axis=0, append=F[:1])).max(axis=1)
            if not (big > 0 and float(change.max()) > jump * big):
                continue
            k, k1 = int(np.argmax(change)), (int(np.argmax(change)) + 1) % samples
            for name, f in each.items():
                if mech.loads[name].joint == joint and float(np.abs(f[k1] - f[k]).max()) > 0.5 * change[k]:
                    out[name] = float(self._band_motion(samples).crank_angle[k1])
        return out

    def _band_motion(self, samples: int):
        """The rigid-body motion at ``samples`` equally spaced instants (computed once)."""
        cache = self.__dict__.setdefault("_band_cache", {})
        if samples not in cache:
            cache[samples] = self.cycle.at(np.arange(samples) * (self.scene.period / samples))
        return cache[samples]

    def _friction_band(self, samples: int = 512) -> float:
        """``1 / (pi tau)`` [Hz] of the fastest reversal of the mechanism's friction forces.

        A force ``-F tanh((v . axis - v_ref) / s)`` reverses where the
        rigid-body velocity crosses ``v_ref``, over ``tau = s / |a . axis|``
        (``a`` the larger of its values at the two samples around the
        crossing: the acceleration is smooth on the scale of a sample).
        """
        mech = self.scene.mech
        if not mech.frictions or "loads" not in self.scene.effects:
            return 0.0
        mo = self._band_motion(samples)
        out = 0.0
        for fr in mech.frictions.values():
            if fr.axis is None:  # a sliding pair: the block's speed on its member
                k = mo.slider_names.index(fr.joint)
                v, a = mo.sd[:, k] - fr.reference_speed, np.abs(mo.sdd[:, k])
            else:
                ax = np.asarray(fr.axis, dtype=float)
                ax = ax / np.linalg.norm(ax)
                j = mo.joint_names.index(fr.joint)
                v = mo.v[:, j] @ ax - fr.reference_speed
                a = np.abs(mo.a[:, j] @ ax)
            cross = np.flatnonzero(np.sign(v) != np.sign(np.roll(v, -1)))
            if cross.size:
                a_c = np.maximum(a[cross], np.roll(a, -1)[cross])
                out = max(out, float(a_c.max()) / (math.pi * fr.smoothing))
        return out
