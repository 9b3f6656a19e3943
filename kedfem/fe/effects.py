"""Physical effects a scene can ask for, and the assembler that applies them.

The structure is always assembled: beam mass and stiffness, rigid-member
and point masses, the linear stiffness of declared springs and drive
shafts. Each *effect* adds terms on top (docs/theory.md sections 2-3); an effect not
named is never evaluated:

============================ ================================================ ===============
effect                       adds                                             state-dependent
============================ ================================================ ===============
``inertia``                  rigid-body inertial loads ``-M r0''``            no
``coupling``                 Coriolis ``2 w m_s``, tangential ``a m_s``,      no
                             centripetal ``-w^2 m_t``, and the terms of the
                             time derivatives of the frame transformations
``axial_stiffening``         geometric stiffness of the kinetostatic forces   no
                             (``k_G(N)`` of links, ``sum F.rho`` of rigid
                             members)
``geometric_nonlinearity``   von Karman tangent stiffness of the elastic      yes
                             axial forces and large deflections
``gravity``                  weight loads (``mechanism.gravity``)             no
``springs``                  spring forces of the rigid-body motion and       if cubic
                             preload; cubic spring laws
``loads``                    declared constant loads and friction forces      if friction
                                                                              follows the
                                                                              total velocity
============================ ================================================ ===============

All terms are computed batched over time nodes and elements and pushed
through the constraint maps of :mod:`kedfem.fe.assembly`.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..model import elements as el
from .assembly import FEModel
from ..errors import InputError, KedError
from ..motion.kinematics import Motion
from ..motion.kinetostatics import JointForces, kinetostatics, link_axial_force, member_centre
from ..model.mechanism import Load
from .modal_damping import modal_damping

__all__ = ["EFFECTS", "LINEAR_EFFECTS", "Effect", "register_effect", "check_effects", "Rayleigh", "ModalDamping", "Assembler",
           "slice_motion", "SystemTerms"]

log = logging.getLogger(__name__)

_S = np.array([[0.0, -1.0], [1.0, 0.0]])
_SHAT = np.zeros((6, 6))
_SHAT[0:2, 0:2] = _S
_SHAT[3:5, 3:5] = _S
_SHAT_T = _SHAT.T.copy()


def _objective_rates(D, T, Tt, w):
    """A local damping ``D`` on an element's objective local rates ``T x' + T' x``.

    Returns the global-frame damping ``T^T D T`` and the stiffness-like term
    ``w T^T D S^T T`` of ``T' x = w S^T (T x)`` (translations turning with the
    element at ``w``), so that a rigid rotation of the element is not damped.
    """
    return Tt @ D @ T, w * (Tt @ D @ _SHAT_T @ T)


def _spring_extension(mech, mo: Motion, s) -> np.ndarray:
    """Extension [m] (nt,) of a linear spring along its axis over the rigid-body motion."""
    n = np.asarray(s.axis)
    d = (mo.r[:, mo.joint_names.index(s.a)] - np.asarray(mech.joints[s.a].at)) @ n
    if s.b is not None:
        d = d - (mo.r[:, mo.joint_names.index(s.b)] - np.asarray(mech.joints[s.b].at)) @ n
    return d


def _rigid_friction(mo: Motion, f) -> np.ndarray:
    """Friction force [N] (nt, 2) on the rigid-body velocity of its joint (tanh-regularised sign)."""
    n = np.asarray(f.axis)
    vrel = mo.v[:, mo.joint_names.index(f.joint)] @ n - f.reference_speed
    return -(f.force * np.tanh(vrel / f.smoothing))[:, None] * n


def _torsional_moment(mo: Motion, t):
    """Moment [N m] (nt,) of a torsional spring over the rigid-body motion, on ``member`` (index i,
    taken negative) and ``other`` (index k or None, taken positive)."""
    i = mo.member_names.index(t.member)
    rel = mo.theta[:, i] - mo.theta_ref[i]
    k = None
    if t.other is not None:
        k = mo.member_names.index(t.other)
        rel = rel - (mo.theta[:, k] - mo.theta_ref[k])
    return i, k, t.preload + t.k * rel


# --------------------------------------------------------------------- damping
@dataclass(frozen=True)
class Rayleigh:
    """Rayleigh damping ``C = alpha M + beta K`` (K: structural stiffness).

    The beam elements take ``beta k`` on their strain rates in their own
    turning frame (objective: a rigid rotation of an element is not damped,
    whichever link's frame its joint DOFs are expressed in); springs and drive
    shafts on the rates of their DOFs; ``alpha M`` on the DOF rates.

    Parameters
    ----------
    alpha : float
        Mass-proportional coefficient [1/s].
    beta : float
        Stiffness-proportional coefficient [s].
    """

    alpha: float = 0.0
    beta: float = 0.0

    def __post_init__(self):
        for name in ("alpha", "beta"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
                    or not np.isfinite(v) or v < 0:
                raise InputError(f"Rayleigh: {name} must be a finite number >= 0, got {v!r}")


@dataclass(frozen=True)
class ModalDamping:
    """Modal damping: every elastic mode of ``(K, M)`` at each time node gets ratio ``zeta``.

    ``C = M Phi diag(2 zeta omega) Phi^T M`` with mass-normalised modes of the
    structural stiffness; zero-frequency (rigid-body) modes get no damping.
    """

    zeta: float = 0.02

    def __post_init__(self):
        v = self.zeta
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
                or not np.isfinite(v) or v < 0 or v >= 1:
            raise InputError(f"ModalDamping: zeta must be a finite number in [0, 1), got {v!r}")


# --------------------------------------------------------------------- registry
@dataclass(frozen=True)
class Effect:
    """An effect of the registry: its name, what it adds, and (for effects in their own
    module) its terms.

    The built-in effects are assembled by :class:`Assembler` (their terms live
    with the element groups they act on). An effect written in its own module
    subclasses this and overrides :meth:`terms`; it joins the registry with
    :func:`register_effect` (``kedfem/fe/joint_torque.py`` is the worked example).
    """

    name: str
    adds: str

    def terms(self, asm: "Assembler", motion: Motion) -> dict | None:
        """q-space terms at the instants of ``motion`` (a slice of the cycle).

        Returns ``None`` (the built-in effects) or a dict with any of ``"M"``,
        ``"C"``, ``"K"`` (nt, N, N) and ``"Q"`` (nt, N) [SI], added to the
        assembled system; ``asm.model`` is the :class:`kedfem.fe.assembly.FEModel`.
        """
        return None

    def state_dependent(self, mech) -> bool:
        """True if this effect makes the equations depend on the elastic state."""
        if self.name == "geometric_nonlinearity":
            return bool(mech.flexible_links)
        if self.name == "springs":
            return any(s.nonlinear for s in mech.springs.values())
        if self.name == "loads":
            return any(f.follows == "total" for f in mech.frictions.values())
        return False


#: The linear KED effect set: rigid-body inertia, the rigid-elastic coupling and the links'
#: stiffening by their kinetostatic axial forces.
LINEAR_EFFECTS = ("inertia", "coupling", "axial_stiffening")

EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Effect("inertia", "rigid-body inertial loads -M r0''"),
    Effect("coupling", "Coriolis, tangential and centripetal rigid-elastic coupling terms"),
    Effect("axial_stiffening", "geometric stiffness of the kinetostatic (rigid-body) forces"),
    Effect("geometric_nonlinearity", "tangent stiffness of elastic axial forces and large deflection"),
    Effect("gravity", "weight loads"),
    Effect("springs", "spring forces of the rigid-body motion and preload; cubic spring laws"),
    Effect("loads", "declared external loads and friction"),
)}


def register_effect(effect: Effect) -> Effect:
    """Add an effect (an :class:`Effect` subclass instance with its own :meth:`Effect.terms`)
    to the registry under ``effect.name``, so that scenes and scene files can name it."""
    if not isinstance(effect, Effect) or type(effect).terms is Effect.terms:
        raise InputError(f"register_effect: {effect!r} is not an Effect with its own terms()")
    if not (isinstance(effect.name, str) and effect.name.isidentifier()):
        raise InputError(f"register_effect: the name must be an identifier, got {effect.name!r}")
    if effect.name in EFFECTS:
        raise InputError(f"register_effect: an effect {effect.name!r} is already registered")
    EFFECTS[effect.name] = effect
    return effect


def check_effects(effects) -> tuple[str, ...]:
    """Validate effect names; return them as a tuple in registry order.

    ``"all"`` (alone) stands for every effect of the registry, as on the
    command line and in scene files.

    Raises
    ------
    InputError
        An unknown name (the message lists the known ones).
    """
    if isinstance(effects, str):
        effects = tuple(EFFECTS) if effects == "all" else (effects,)
    try:
        names = list(effects)
    except TypeError:
        raise InputError(f"effects must be a sequence of names, got {effects!r}") from None
    for e in names:
        if not isinstance(e, str) or e not in EFFECTS:
            raise InputError(f"unknown effect {e!r}; known effects: {', '.join(EFFECTS)}")
    if len(set(names)) != len(names):
        raise InputError(f"effects repeat: {names}")
    return tuple(n for n in EFFECTS if n in names)


def slice_motion(motion: Motion, idx) -> Motion:
    """The motion restricted to time nodes ``idx``."""
    idx = np.asarray(idx)
    fields = {}
    for f in ("t", "crank_angle", "r", "v", "a", "theta", "omega", "alpha", "s", "sd", "sdd"):
        fields[f] = getattr(motion, f)[idx]
    return dataclasses.replace(motion, **fields)


@dataclass
class SystemTerms:
    """Assembled q-space terms at ``nt`` time nodes.

    ``M, C, K``: (nt, N, N); ``Q``: (nt, N).
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    Q: np.ndarray


class _Acc:
    """Per-group x-space accumulator of M, C, K, Q for one chunk."""

    def __init__(self):
        self.data: dict[str, dict[str, np.ndarray]] = {}

    def add(self, g, key, val):
        d = self.data.setdefault(g, {})
        if key in d:
            a = d[key]
            if a.shape != val.shape:
                shape = np.broadcast_shapes(a.shape, val.shape)
                a = np.broadcast_to(a, shape).copy()
            d[key] = a + val
        else:
            d[key] = np.array(val, dtype=float, copy=True)

    def get(self, g, key):
        return self.data.get(g, {}).get(key)


class Assembler:
    """Assemble the effects of a scene at any set of time nodes.

    Parameters
    ----------
    model : FEModel
        DOF map and element groups.
    motion : Motion
        Rigid-body motion over the cycle (all time nodes).
    effects : sequence of str
        Effects to apply (see :data:`EFFECTS`).
    damping : Rayleigh or ModalDamping or None
        Damping model.
    frame : bool
        Co-moving-frame formulation for frequency analysis: each link in its
        own rotating frame (Coriolis ``2 w m_s``, ``a m_s``, ``-w^2 m_t``),
        rigid members in translating frames; the terms of the time
        derivatives of the frame transformations are left out. ``False``
        (default) is the inertial-frame formulation the response is solved in.
    damping_field : kedfem.fe.modal_damping.DampingField, optional
        With :class:`ModalDamping`: ``C(t)`` interpolated over the cycle
        instead of an eigenproblem per instant (built once per solve from the
        same model and cycle).
    """

    def __init__(self, model: FEModel, motion: Motion, effects=(), damping=None, frame=False,
                 damping_field=None):
        self.model = model
        self.mech = model.mech
        self.motion = motion
        self.effects = check_effects(effects)
        if damping is not None and not isinstance(damping, (Rayleigh, ModalDamping)):
            raise InputError(f"damping must be kf.Rayleigh, kf.ModalDamping or None, got {damping!r}")
        self.damping = damping
        self.frame = bool(frame)
        self.damping_field = damping_field
        self.has = set(self.effects)
        self._forces: JointForces | None = None
        self._axial: np.ndarray | None = None
        b = model.beam
        self._beam_member = np.array([motion.member_names.index(b.links[i]) for i in b.link], dtype=int)
        self._beam_joint_a = np.array([motion.joint_names.index(self.mech.links[b.links[i]].a)
                                       for i in b.link], dtype=int)
        if "axial_stiffening" in self.has and "geometric_nonlinearity" in self.has and b.L.size:
            log.info("geometric_nonlinearity carries the axial forces of the links: the links' k_G of "
                     "axial_stiffening is not added twice (rigid members keep theirs)")
        self._k_local = self._beam_stiffness()
        self._m_local = self._beam_mass()
        self._coupling_mats = self._beam_coupling()
        self._full_maps: dict = {}  # group maps over the whole cycle, for the state terms
        self._full_forms = None     # the entity forms they are built from

    # ------------------------------------------------------------- properties
    @property
    def state_dependent(self) -> bool:
        """True if some chosen effect depends on the elastic state (needs iteration)."""
        return any(EFFECTS[e].state_dependent(self.mech) for e in self.effects)

    def _beam_stiffness(self):
        b = self.model.beam
        if not b.L.size:
            return np.zeros((0, 6, 6))
        k = el.frame_stiffness(b.L, b.EA, b.EI)
        if b.timoshenko.any():
            kt = el.timoshenko_stiffness(b.L, b.EA, b.EI, b.GAs)
            k[b.timoshenko] = kt[b.timoshenko]
        return k

    def _beam_mass(self):
        b = self.model.beam
        if not b.L.size:
            return np.zeros((0, 6, 6))
        m = el.consistent_mass(b.L, b.rhoA)
        if b.lumped.any():
            ml = el.lumped_mass(b.L, b.rhoA)
            m[b.lumped] = ml[b.lumped]
        return m

    def _beam_coupling(self):
        """Translational mass m_t and skew coupling m_s of the beam elements.

        Consistent elements use the Hermite/linear fields; lumped elements are
        point masses at the nodes, for which ``m_s = m_t S_hat``.
        """
        b = self.model.beam
        if not b.L.size:
            return np.zeros((0, 6, 6)), np.zeros((0, 6, 6))
        mt = el.consistent_mass(b.L, b.rhoA)
        ms = el.coupling_skew(b.L, b.rhoA)
        if b.lumped.any():
            ml = el.lumped_mass(b.L, b.rhoA)
            ml[:, [2, 5], [2, 5]] = 0.0
            mt[b.lumped] = ml[b.lumped]
            ms[b.lumped] = ml[b.lumped] @ _SHAT
        return mt, ms

    # ------------------------------------------------------------ kinetostatics
    def joint_forces(self) -> JointForces:
        """Kinetostatic joint forces over the whole cycle (computed once)."""
        if self._forces is None:
            mo = self.motion
            loads = None
            moments = None
            if "springs" in self.has or "loads" in self.has:
                loads = np.zeros((mo.n, len(mo.joint_names), 2))
                moments = np.zeros((mo.n, len(mo.member_names)))
                if "springs" in self.has:
                    self._spring_rigid_forces(mo, loads, moments)
                if "loads" in self.has:
                    self._rigid_loads(mo, loads)
            self._forces = kinetostatics(self.mech, mo, inertia=True, gravity="gravity" in self.has,
                                         joint_loads=loads, member_moments=moments)
        return self._forces

    def _spring_rigid_forces(self, mo, loads, moments):
        for s in self.mech.springs.values():
            n = np.asarray(s.axis)
            d = _spring_extension(self.mech, mo, s)
            F = s.preload + s.k * d + s.k3 * d**3
            loads[:, mo.joint_names.index(s.a)] -= F[:, None] * n
            if s.b is not None:
                loads[:, mo.joint_names.index(s.b)] += F[:, None] * n
        for t in self.mech.torsional_springs.values():
            i, k, Mt = _torsional_moment(mo, t)
            moments[:, i] -= Mt
            if k is not None:
                moments[:, k] += Mt

    def _rigid_loads(self, mo, loads):
        for ld in self.mech.loads.values():
            loads[:, mo.joint_names.index(ld.joint)] += np.asarray(ld.force)
        for f in self.mech.frictions.values():
            loads[:, mo.joint_names.index(f.joint)] += _rigid_friction(mo, f)

    def beam_axial_kinetostatic(self) -> np.ndarray:
        """Mean kinetostatic axial force per beam element, shape (n, n_el) [N]."""
        if self._axial is None:
            b = self.model.beam
            forces = self.joint_forces()
            out = np.zeros((self.motion.n, b.L.size))
            for name in b.links:
                if not self.mech.links[name].kinematic:
                    continue  # a redundant member takes no kinetostatic force
                sl = self.model.link_elements(name)
                s1 = b.s1[sl]
                out[:, sl] = link_axial_force(self.mech, self.motion, forces, name, s1, s1 + b.L[sl],
                                              gravity="gravity" in self.has)
            self._axial = out
        return self._axial

    # ------------------------------------------------------------ element terms
    def _beam_kin(self, mo):
        th = mo.theta[:, self._beam_member]
        return (th, mo.omega[:, self._beam_member], mo.alpha[:, self._beam_member],
                mo.a[:, self._beam_joint_a], el.rotation_blocks(th))

    def _objective_beta(self) -> float:
        """Rayleigh's stiffness coefficient when the beams take it on their strain rates.

        In the inertial-frame formulation (not for the co-moving frequency
        analysis, which keeps ``beta K`` on its DOFs).
        """
        d = self.damping
        return float(d.beta) if isinstance(d, Rayleigh) and d.beta and not self.frame else 0.0

    def _beam_terms(self, mo, idx, acc: _Acc):
        b = self.model.beam
        if not b.L.size:
            return
        th, w, al, aa, T = self._beam_kin(mo)
        Tt = np.swapaxes(T, -1, -2)
        acc.add("beam", "M", Tt @ self._m_local @ T)
        acc.add("beam", "K", Tt @ self._k_local @ T)
        beta = self._objective_beta()
        if beta:
            # stiffness-proportional damping of the elements' strain rates in their own
            # turning frame: f = beta k (T x' + T' x), T' x = w S^T (T x) on the translations
            # (the transport of the DOF maps follows in _transform); not of rigid rotation
            Cb, Kb = _objective_rates(beta * self._k_local, T, Tt, w[..., None, None])
            acc.add("beam", "C", Cb)
            acc.add("beam", "K", Kb)
        else:
            acc.add("beam", "Ks", Tt @ self._k_local @ T)
        if "coupling" in self.has:
            mt, ms = self._coupling_mats
            w4 = w[..., None, None]
            a4 = al[..., None, None]
            if self.frame:
                C = 2.0 * w4 * ms
                K = a4 * ms - w4**2 * mt
            else:
                mtS = mt @ _SHAT
                C = 2.0 * w4 * (ms - mtS)
                K = a4 * (ms - mtS) + w4**2 * (mtS @ _SHAT - 2.0 * ms @ _SHAT - mt)
            acc.add("beam", "C", Tt @ C @ T)
            acc.add("beam", "K", Tt @ K @ T)
        if "axial_stiffening" in self.has and "geometric_nonlinearity" not in self.has:
            N = self.beam_axial_kinetostatic()[idx]
            acc.add("beam", "K", Tt @ el.geometric_stiffness(b.L, N) @ T)
        R_T = np.swapaxes(T[..., 0:2, 0:2], -1, -2)  # R(theta)
        if "inertia" in self.has:
            c = np.stack([-(w**2), al], axis=-1)  # (nt, n_el, 2)
            a_loc = np.einsum("tnji,tnj->tni", R_T, aa)  # R^T a_a
            p0 = -b.rhoA[:, None] * (a_loc + b.s1[:, None] * c)
            p1 = -b.rhoA[:, None] * c
            f = el.linear_load(b.L, p0, p1)
            acc.add("beam", "Q", np.einsum("tnji,tnj->tni", T, f))
        if "gravity" in self.has:
            g = np.asarray(self.mech.gravity)
            g_loc = np.einsum("tnji,j->tni", R_T, g)
            f = el.linear_load(b.L, b.rhoA[:, None] * g_loc, np.zeros_like(g_loc))
            acc.add("beam", "Q", np.einsum("tnji,tnj->tni", T, f))

    def _rigid_terms(self, mo, acc: _Acc):
        g = self.model.groups["rigid"]
        if not g.n:
            return
        names = g.meta["members"]
        mass = np.array([self.mech.links[m].mass if m in self.mech.links else self.mech.bodies[m].mass
                         for m in names])
        J = np.array([self.mech.links[m].J if m in self.mech.links else self.mech.bodies[m].J
                      for m in names])
        M = np.zeros((1, g.n, 3, 3))
        M[0, :, 0, 0] = M[0, :, 1, 1] = mass
        M[0, :, 2, 2] = J
        acc.add("rigid", "M", M)
        if "inertia" in self.has or "gravity" in self.has:
            Q = np.zeros((mo.n, g.n, 3))
            for k, m in enumerate(names):
                if "inertia" in self.has:
                    _r, _v, ac = member_centre(self.mech, mo, m)
                    Q[:, k, 0:2] -= mass[k] * ac
                    Q[:, k, 2] -= J[k] * mo.alpha[:, mo.member_names.index(m)]
                if "gravity" in self.has:
                    Q[:, k, 0:2] += mass[k] * np.asarray(self.mech.gravity)
            acc.add("rigid", "Q", Q)

    def _pmass_terms(self, mo, acc: _Acc):
        g = self.model.groups["pmass"]
        if not g.n:
            return
        items = g.meta["items"]
        M = np.zeros((1, g.n, 3, 3))
        for k, p in enumerate(items):
            M[0, k, 0, 0] = M[0, k, 1, 1] = p.mass
            M[0, k, 2, 2] = p.J if g.ids[k, 1] >= 0 else 0.0
        acc.add("pmass", "M", M)
        if "inertia" in self.has or "gravity" in self.has:
            Q = np.zeros((mo.n, g.n, 3))
            for k, p in enumerate(items):
                j = mo.joint_names.index(p.joint)
                if "inertia" in self.has:
                    Q[:, k, 0:2] -= p.mass * mo.a[:, j]
                    rid = g.ids[k, 1]
                    if rid >= 0 and p.J > 0:
                        mem = self.model.rots[rid].member
                        Q[:, k, 2] -= p.J * mo.alpha[:, mo.member_names.index(mem)]
                if "gravity" in self.has:
                    Q[:, k, 0:2] += p.mass * np.asarray(self.mech.gravity)
            acc.add("pmass", "Q", Q)

    def _spring_B(self):
        g = self.model.groups["spring"]
        B = np.zeros((g.n, 4))
        for k, s in enumerate(g.meta["items"]):
            B[k, 0:2] = s.axis
            B[k, 2:4] = -np.asarray(s.axis)
        return B

    def _spring_rigid_extension(self, mo):
        g = self.model.groups["spring"]
        d = np.zeros((mo.n, g.n))
        for k, s in enumerate(g.meta["items"]):
            d[:, k] = _spring_extension(self.mech, mo, s)
        return d

    def _spring_terms(self, mo, acc: _Acc):
        g = self.model.groups["spring"]
        if g.n:
            items = g.meta["items"]
            B = self._spring_B()
            k = np.array([s.k for s in items])
            BB = B[:, :, None] * B[:, None, :]
            acc.add("spring", "K", (k[:, None, None] * BB)[None])
            acc.add("spring", "Ks", (k[:, None, None] * BB)[None])
            if "springs" in self.has:
                d = self._spring_rigid_extension(mo)
                pre = np.array([s.preload for s in items])
                k3 = np.array([s.k3 for s in items])
                F = pre + k * d + k3 * d**3
                acc.add("spring", "Q", -F[..., None] * B)
        g = self.model.groups["tspring"]
        if g.n:
            items = g.meta["items"]
            kt = np.array([it[1].k if it[0] == "spring" else it[1].torsional_stiffness for it in items])
            Kt = kt[:, None, None] * np.array([[1.0, -1.0], [-1.0, 1.0]])
            acc.add("tspring", "K", Kt[None])
            acc.add("tspring", "Ks", Kt[None])
            if "springs" in self.has:
                Q = np.zeros((mo.n, g.n, 2))
                for k, (kind, t) in enumerate(items):
                    if kind != "spring":
                        continue
                    _i, _o, Mt = _torsional_moment(mo, t)
                    Q[:, k, 0] = -Mt
                    Q[:, k, 1] = Mt
                acc.add("tspring", "Q", Q)

    def _load_terms(self, mo, acc: _Acc):
        g = self.model.groups["load"]
        if not g.n or "loads" not in self.has:
            return
        Q = np.zeros((mo.n, g.n, 2))
        for k, it in enumerate(g.meta["items"]):
            if isinstance(it, Load):
                Q[:, k] = it.force
            elif it.follows == "rigid":
                Q[:, k] = _rigid_friction(mo, it)
        acc.add("load", "Q", Q)

    # ----------------------------------------------------------- rigid geometry
    def _rigid_geometric(self, mo, idx):
        """q-space geometric stiffness sum F.rho of rigid member groups, (nt, N, N)."""
        N = self.model.n_dof
        out = np.zeros((mo.n, N, N))
        forces = self.joint_forces()
        for grp in self.model.rigid_groups:
            phi = grp["phi"]
            if phi < 0:
                continue
            q = self.model.rots[phi].cols[0]
            ref = self.model.points[grp["ref"]].loc
            rr, _rv, _ra = self.model._loc_motion(ref, mo) if ref else (np.zeros((mo.n, 2)),) * 3
            val = np.zeros(mo.n)
            for m in grp["members"]:
                for (mem, j), k in zip(forces.pairs, range(len(forces.pairs))):
                    if mem != m:
                        continue
                    rj = mo.r[:, mo.joint_names.index(j)]
                    val += np.einsum("nd,nd->n", forces.force[idx, k], rj - rr)
                mass = self.mech.links[m].mass if m in self.mech.links else self.mech.bodies[m].mass
                rc, _vc, ac = member_centre(self.mech, mo, m)
                own = np.zeros((mo.n, 2))
                if "gravity" in self.has:
                    own += mass * np.asarray(self.mech.gravity)
                if not self.frame:
                    own -= mass * ac
                val += np.einsum("nd,nd->n", own, rc - rr)
            out[:, q, q] += val
        return out

    # -------------------------------------------------------------- transform
    def _transform(self, gname, acc: _Acc, mo, nt):
        model = self.model
        M = acc.get(gname, "M")
        C = acc.get(gname, "C")
        K = acc.get(gname, "K")
        Ks = acc.get(gname, "Ks")
        Q = acc.get(gname, "Q")
        if M is None and C is None and K is None and Q is None:
            return None
        gm = model.group_map(gname, mo, self._forms)
        E = gm.E
        Et = np.swapaxes(E, -1, -2)
        out = {}

        def full(x):
            return np.broadcast_to(x, (nt,) + x.shape[1:])

        if M is not None:
            out["M"] = full(Et @ M @ E)
        Cq = Et @ C @ E if C is not None else None
        Kq = Et @ K @ E if K is not None else None
        if Ks is not None:
            out["Ks"] = full(Et @ Ks @ E)
        transport = "coupling" in self.has and not self.frame and gm.E1 is not None
        if transport:
            if M is not None:
                add = 2.0 * Et @ M @ gm.E1
                Cq = add if Cq is None else Cq + add
                add = Et @ M @ gm.E2
                Kq = add if Kq is None else Kq + add
            if C is not None:
                add = Et @ C @ gm.E1
                Kq = add if Kq is None else Kq + add
        if Cq is not None:
            out["C"] = full(Cq)
        if Kq is not None:
            out["K"] = full(Kq)
        Qx = Q
        if gm.p is not None and not self.frame:
            extra = 0.0
            if K is not None:
                extra = extra + K @ gm.p[..., None]
            if C is not None:
                extra = extra + C @ gm.p1[..., None]
            if M is not None and "inertia" in self.has:
                extra = extra + M @ gm.p2[..., None]
            if not isinstance(extra, float):
                Qx = -extra[..., 0] if Qx is None else Qx - extra[..., 0]
        if Qx is not None:
            out["Q"] = full((Et @ Qx[..., None])[..., 0])
        return out

    def _group_terms(self, idx):
        """q-space element terms of every group at time nodes ``idx``."""
        mo = slice_motion(self.motion, idx)
        nt = idx.size
        acc = _Acc()
        self._beam_terms(mo, idx, acc)
        self._rigid_terms(mo, acc)
        self._pmass_terms(mo, acc)
        self._spring_terms(mo, acc)
        self._load_terms(mo, acc)
        dyn = self.model.has_moving_maps() or self.model.has_offsets()
        self._forms = self.model.entity_forms(mo) if dyn else None
        try:
            out = {g: self._transform(g, acc, mo, nt) for g in self.model.groups}
        finally:
            self._forms = None
        return mo, {g: o for g, o in out.items() if o}

    def system(self, idx=None) -> SystemTerms:
        """Linear (state-independent) terms at time nodes ``idx``.

        Parameters
        ----------
        idx : array_like of int, optional
            Time node indices; default all.

        Returns
        -------
        SystemTerms
            ``M, C, K`` (nt, N, N) and ``Q`` (nt, N) in q-space.
        """
        if idx is None:
            idx = np.arange(self.motion.n)
        idx = np.asarray(idx)
        nt, N = idx.size, self.model.n_dof
        mo, groups = self._group_terms(idx)
        field = self.damping_field if isinstance(self.damping, ModalDamping) else None
        keys = ("M", "C", "K") if field is not None or self.damping is None else ("M", "C", "K", "Ks")
        tot = {k: np.zeros((nt, N, N)) for k in keys}
        Q = np.zeros((nt, N))
        for gname, out in groups.items():
            for key in tot:
                if key in out:
                    self.model.scatter_matrix(gname, out[key], out=tot[key])
            if "Q" in out:
                self.model.scatter_vector(gname, out["Q"], out=Q)
        if "axial_stiffening" in self.has and self.model.rigid_groups:
            tot["K"] += self._rigid_geometric(mo, idx)
        for name in self.has:  # effects in their own modules (register_effect)
            extra = EFFECTS[name].terms(self, mo) if name in EFFECTS else None
            for key, val in (extra or {}).items():
                if key == "Q":
                    Q += val
                elif key in ("M", "C", "K"):
                    tot[key] += val
                else:
                    raise KedError(f"effect {name!r}: terms() returned an unknown key {key!r}")
        if field is not None:
            tot["C"] += field.at(mo.t)
        elif self.damping is not None:
            tot["C"] += self._damping(tot["M"], tot["Ks"])
        return SystemTerms(tot["M"], tot["C"], tot["K"], Q)

    def sparse_system(self, node: int = 0):
        """Terms at one time node as scipy.sparse CSR matrices (COO -> CSR scatter).

        Returns
        -------
        M, C, K : scipy.sparse.csr_matrix, shape (N, N)
        Q : ndarray, shape (N,)
        """
        idx = np.array([node])
        N = self.model.n_dof
        mo, groups = self._group_terms(idx)
        tot = {k: sp.csr_matrix((N, N)) for k in ("M", "C", "K", "Ks")}
        Q = np.zeros(N)
        for gname, out in groups.items():
            for key in tot:
                if key in out:
                    tot[key] = tot[key] + self.model.scatter_sparse(gname, out[key][0])
            if "Q" in out:
                Q += self.model.scatter_vector(gname, out["Q"])[0]
        if "axial_stiffening" in self.has and self.model.rigid_groups:
            tot["K"] = tot["K"] + sp.csr_matrix(self._rigid_geometric(mo, idx)[0])
        if self.damping is not None:
            if isinstance(self.damping, Rayleigh):
                tot["C"] = tot["C"] + self.damping.alpha * tot["M"] + self.damping.beta * tot["Ks"]
            else:
                Cd = self._damping(tot["M"].toarray()[None], tot["Ks"].toarray()[None])[0]
                tot["C"] = tot["C"] + sp.csr_matrix(Cd)
        return tot["M"], tot["C"], tot["K"], Q

    def structural(self, idx=None):
        """Mass and structural stiffness only (no effects), each (nt, N, N)."""
        if idx is None:
            idx = np.arange(self.motion.n)
        idx = np.asarray(idx)
        saved = self.has
        self.has = set()
        try:
            mo = slice_motion(self.motion, idx)
            acc = _Acc()
            self._beam_terms(mo, idx, acc)
            self._rigid_terms(mo, acc)
            self._pmass_terms(mo, acc)
            self._spring_terms(mo, acc)
            dyn = self.model.has_moving_maps() or self.model.has_offsets()
            self._forms = self.model.entity_forms(mo) if dyn else None
            nt, N = idx.size, self.model.n_dof
            M = np.zeros((nt, N, N))
            Ks = np.zeros((nt, N, N))
            for gname in self.model.groups:
                out = self._transform(gname, acc, mo, nt)
                if out and "M" in out:
                    self.model.scatter_matrix(gname, out["M"], out=M)
                if out and "Ks" in out:
                    self.model.scatter_matrix(gname, out["Ks"], out=Ks)
        finally:
            self.has = saved
            self._forms = None
        return M, Ks

    def axial_share(self, idx=None) -> np.ndarray:
        """Share of each DOF's diagonal structural stiffness that the links' axial stiffness carries.

        ``diag(K_axial) / diag(K_structural)`` at time nodes ``idx`` (default
        all), shape (nt, N): near 1 for the directions a link's axial
        stiffness holds (its interior axial translations, a slider's travel,
        a joint translation along a link, a rigid member's rotation resisted
        by links pushing and pulling on it), near 0 for bending.
        """
        if idx is None:
            idx = np.arange(self.motion.n)
        idx = np.asarray(idx)
        b = self.model.beam
        M, Ks = self.structural(idx)
        d_all = np.diagonal(Ks, axis1=-2, axis2=-1)
        if not b.L.size:
            return np.zeros_like(d_all)
        mo = slice_motion(self.motion, idx)
        T = self._beam_kin(mo)[-1]
        ka = el.frame_stiffness(b.L, b.EA, np.zeros_like(b.EI))  # EI = 0: the axial part alone
        Kx = np.swapaxes(T, -1, -2) @ ka @ T
        dyn = self.model.has_moving_maps() or self.model.has_offsets()
        gm = self.model.group_map("beam", mo, self.model.entity_forms(mo) if dyn else None)
        E = gm.E
        Kq = np.broadcast_to(np.swapaxes(E, -1, -2) @ Kx @ E, (idx.size,) + (E.shape[1], E.shape[3], E.shape[3]))
        d_ax = np.diagonal(self.model.scatter_matrix("beam", Kq), axis1=-2, axis2=-1)
        return d_ax / np.where(d_all > 0, d_all, 1.0)

    def _damping(self, M, Ks):
        d = self.damping
        if isinstance(d, Rayleigh):
            return d.alpha * M + d.beta * Ks
        return modal_damping(M, Ks, d.zeta, self.model.mech.name, self.model.dof_labels)

    # ----------------------------------------------------------- state terms
    def _state_map(self, gname, mo):
        """Group map of ``gname`` over ``mo``; kept when ``mo`` is the whole cycle.

        The non-linear iteration evaluates the state terms over the same cycle
        at every iterate: the constraint maps (and the entity forms they are
        built from) depend on the motion only, so they are built once.
        """
        if mo is not self.motion:
            return self.model.group_map(gname, mo)
        gm = self._full_maps.get(gname)
        if gm is None:
            if self._full_forms is None and (self.model.has_moving_maps() or self.model.has_offsets()):
                self._full_forms = self.model.entity_forms(mo)
            gm = self._full_maps[gname] = self.model.group_map(gname, mo, self._full_forms)
        return gm

    def element_state(self, gname, mo, U, V=None):
        """Element DOFs of a group for the trial response ``U, V``.

        Returns ``x = E q + p`` (total elastic, incl. prescribed offsets), its
        rate ``x'`` (None without ``V``), the part ``E q`` that the unknowns
        carry, and the group map; arrays (nt, n_el, d).
        """
        gm = self._state_map(gname, mo)
        xq = gm.apply(U)  # (nt, n_el, d)
        x = xq + gm.p if gm.p is not None else xq
        xd = None
        if V is not None:
            xd = gm.apply(V)
            if gm.E1 is not None:
                xd = xd + gm.apply(U, E=gm.E1)
            if gm.p1 is not None:
                xd = xd + gm.p1
        return x, xd, xq, gm

    def state_terms(self, U, V, idx=None):
        """State-dependent terms for the trial response ``U, V`` (n, N).

        Returns
        -------
        dC : ndarray, shape (n, N, N) or None
            Tangent damping of the state-dependent effects (velocity-dependent friction).
        dK : ndarray, shape (n, N, N) or None
            Tangent stiffness of the state-dependent effects.
        dQ : ndarray, shape (n, N) or None
            Matching load, ``-f_nl(x) + K_nl x + C_nl x'`` so that a fixed point of
            the linear solve satisfies the non-linear equations (Newton's
            linearisation about the trial response).
        """
        if idx is None:
            idx = np.arange(self.motion.n)
            mo = self.motion  # the whole cycle: the group maps are reused across iterates
        else:
            mo = slice_motion(self.motion, idx)
        nt, N = len(idx), self.model.n_dof
        dK = np.zeros((nt, N, N))
        dQ = np.zeros((nt, N))
        dC = None
        used = False
        if "geometric_nonlinearity" in self.has and self.model.beam.L.size:
            used = True
            if self._objective_beta():
                dC = np.zeros((nt, N, N))
            self._von_karman(mo, U, V, dK, dQ, dC)
        if "springs" in self.has and any(s.nonlinear for s in self.mech.springs.values()):
            used = True
            self._cubic_springs(mo, U, dK, dQ)
        if "loads" in self.has and any(f.follows == "total" for f in self.mech.frictions.values()):
            used = True
            dC = np.zeros((nt, N, N)) if dC is None else dC
            self._friction_total(mo, U, V, dC, dQ)
        if not used:
            return None, None, None
        return dC, dK, dQ

    def _apply_state(self, gname, gm, Kx, Qx, dK, dQ):
        E = gm.E
        Et = np.swapaxes(E, -1, -2)
        nt = dQ.shape[0]
        if Kx is not None:
            dK += self.model.scatter_matrix(gname, np.broadcast_to(Et @ Kx @ E, (nt,) + (E.shape[1], E.shape[3], E.shape[3])))
        if Qx is not None:
            dQ += self.model.scatter_vector(gname, np.broadcast_to((Et @ Qx[..., None])[..., 0], (nt,) + (E.shape[1], E.shape[3])))

    def _von_karman(self, mo, U, V, dK, dQ, dC=None):
        """Von Karman tangent stiffness of all flexible links (local frames).

        With Rayleigh ``beta`` the axial damping acts on the rate of the
        von Karman strain, ``beta EA eps'``, ``eps = (u2 - u1) / L + v^T G v /
        (2 L)``: its part beyond the linear ``beta k`` is the damping
        ``beta EA / L (b b^T - b0 b0^T)`` of the local rates (secant in the
        iterate, exact at the fixed point). Without it the axial DOFs that
        take up the chord shortening of a bending link would be damped as
        if they stretched it.
        """
        b = self.model.beam
        x, _xd, xq, gm = self.element_state("beam", mo, U)
        th = mo.theta[:, self._beam_member]
        T = el.rotation_blocks(th)
        d = (T @ x[..., None])[..., 0]  # local element DOFs (nt, n_el, 6), total
        dq = (T @ xq[..., None])[..., 0]  # the part carried by the unknowns
        G = el.geometric_matrix(b.L)    # (n_el, 4, 4)
        vb = d[..., el.V_DOFS]
        Gv = (G @ vb[..., None])[..., 0]
        quad = np.einsum("tni,tni->tn", vb, Gv)
        N_lin = b.EA * (d[..., 3] - d[..., 0]) / b.L
        N_nl = b.EA * quad / (2.0 * b.L)
        N = N_lin + N_nl
        bvec = np.zeros(d.shape)
        bvec[..., 0] = -1.0
        bvec[..., 3] = 1.0
        bvec[..., el.V_DOFS] = Gv
        b0 = np.zeros(6)
        b0[0], b0[3] = -1.0, 1.0
        EAL = (b.EA / b.L)[:, None, None]
        Knl = EAL * (bvec[..., :, None] * bvec[..., None, :] - np.outer(b0, b0))
        Knl[..., el.V_DOFS[:, None], el.V_DOFS[None, :]] += N[..., None, None] * G
        fnl = np.zeros(d.shape)
        fnl[..., 0] = -N_nl
        fnl[..., 3] = N_nl
        fnl[..., el.V_DOFS] = N[..., None] * Gv
        # linearisation about x_i with the prescribed part p fixed:
        # K_T (E q + p - x_i) + f_int(x_i) = Q  ->  Q_state = -f_nl(x_i) + K_nl (x_i - p)
        Qloc = -fnl + (Knl @ dq[..., None])[..., 0]
        Tt = np.swapaxes(T, -1, -2)
        self._apply_state("beam", gm, Tt @ Knl @ T, (Tt @ Qloc[..., None])[..., 0], dK, dQ)
        if dC is not None:
            self._von_karman_damping(mo, T, Tt, EAL * (bvec[..., :, None] * bvec[..., None, :]
                                                       - np.outer(b0, b0)), gm, dC, dK, dQ)

    def _von_karman_damping(self, mo, T, Tt, D, gm, dC, dK, dQ):
        """``beta D`` (local, (nt, n_el, 6, 6)) on the objective local rates ``T x' + T' x``."""
        w = mo.omega[:, self._beam_member][..., None, None]
        Cx, Kx = _objective_rates(self._objective_beta() * D, T, Tt, w)
        Qx = None
        if gm.p is not None:
            Qx = -((Cx @ gm.p1[..., None])[..., 0] + (Kx @ gm.p[..., None])[..., 0])
        self._apply_state("beam", gm, Cx, Qx, dC, dQ)
        if "coupling" in self.has and gm.E1 is not None:
            # x' = E q' + E1 q + p1: the transport of the maps
            Et = np.swapaxes(gm.E, -1, -2)
            dK += self.model.scatter_matrix("beam", np.broadcast_to(
                Et @ Cx @ gm.E1, (dK.shape[0],) + (gm.E.shape[1], gm.E.shape[3], gm.E.shape[3])))
        self._apply_state("beam", gm, Kx, None, dK, dQ)

    def _cubic_springs(self, mo, U, dK, dQ):
        g = self.model.groups["spring"]
        items = g.meta["items"]
        x, _xd, _xq, gm = self.element_state("spring", mo, U)
        B = self._spring_B()
        de = np.einsum("ni,tni->tn", B, x)  # spring ends are points: no prescribed part
        dr = self._spring_rigid_extension(mo)
        k3 = np.array([s.k3 for s in items])
        dt = dr + de
        knl = 3.0 * k3 * dt**2
        fnl = k3 * (dt**3 - dr**3)  # F(dr + de) - F(dr) - k de
        BB = B[:, :, None] * B[:, None, :]
        Kx = knl[..., None, None] * BB
        Qx = (-fnl + knl * de)[..., None] * B
        self._apply_state("spring", gm, Kx, Qx, dK, dQ)

    def _friction_total(self, mo, U, V, dC, dQ):
        """Friction on the total velocity: force and its tangent damping ``c_t n n^T``."""
        g = self.model.groups["load"]
        items = g.meta["items"]
        x, xd, _xq, gm = self.element_state("load", mo, U, V)
        xdq = gm.apply(V)  # the part of x' carried by q'
        Qx = np.zeros(x.shape)
        Cx = np.zeros(x.shape + (x.shape[-1],))
        for k, it in enumerate(items):
            if getattr(it, "follows", None) != "total":
                continue
            j = mo.joint_names.index(it.joint)
            n = np.asarray(it.axis)
            vrel = (mo.v[:, j] + xd[:, k]) @ n - it.reference_speed
            th = np.tanh(vrel / it.smoothing)
            ct = it.force / it.smoothing * (1.0 - th**2)  # d(force)/d(speed) >= 0
            Cx[:, k] = ct[:, None, None] * np.outer(n, n)
            # Newton: F(v_i) + c_t (v - v_i) -> load -F(v_i) + c_t (q'-part of v_i)
            Qx[:, k] = (-(it.force * th) + ct * (xdq[:, k] @ n))[:, None] * n
        self._apply_state("load", gm, Cx, Qx, dC, dQ)
