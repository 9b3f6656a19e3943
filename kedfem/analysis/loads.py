"""Loads on the machine: bearing (joint) forces and drive torques over the cycle.

What sizes bearings and motors, from a periodic result, twice:

* **rigid**: the kinetostatic joint forces of the rigid-body motion with the
  scene's loads (inertia, and the ``gravity``, ``springs`` and ``loads``
  effects), exactly those the assembler computes
  (:meth:`kedfem.fe.assembler.Assembler.joint_forces`);
* **elastic**: the forces of the periodic elastic response. A flexible
  link's pin force is its section forces at the end (axial force, shear,
  bending moment, recovered by element equilibrium,
  :mod:`kedfem.analysis.recovery`) turned to global components; a driven
  flexible link's drive torque is its root bending moment, a drive through a
  torsional spring ``-k_t`` times the elastic twist; the forces on rigid
  members, the frame reactions and the remaining drive torques follow from
  the joint equilibrium with the elastic accelerations
  (:func:`kedfem.motion.kinetostatics.kinetostatics` with
  :class:`~kedfem.motion.kinetostatics.KnownForces`).

Conventions (docs/loads.md): a bearing is a pin and a body it holds (a
member, ``"frame"`` at ground and slider joints, or the member a block
slides on); its force is **the force the pin exerts on that body**, in global components [N]; moments and
torques are counter-clockwise positive [N m]; a drive torque is the torque
the drive exerts on its member.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import InputError
from ..fe.effects.springs import spring_extension
from ..fe.effects.loads import rigid_friction
from ..fe.structure import spring_axes
from ..model.mechanism import Mechanism
from ..motion.kinematics import Motion
from ..motion.kinetostatics import JointForces, KnownForces, kinetostatics
from .recovery import periodic_rates
from .peak_search import smooth_vertex

__all__ = ["FRAME", "LoadHistory", "LoadPeak", "MachineLoads", "machine_loads", "loads_from_forces", "CSV_COLUMNS"]

log = logging.getLogger(__name__)

#: The body name of the frame in :attr:`MachineLoads.bearings`.
FRAME = "frame"
#: Columns of :func:`write_loads_csv`.
CSV_COLUMNS = ("crank_angle_deg", "response", "quantity", "joint", "member", "component", "value", "unit")
#: Stations per element where the end forces are read: the bending moment of an element by
#: element equilibrium is a polynomial of degree 5 along it, so 7 stations give its slope exactly
_STATIONS = 6
#: instants from a sample before a load's largest one to a sample after it where its peak is read
#: from the dense output (16 intervals: a peak within 1/8 of a sample spacing, then its vertex)
NEAR_POINTS = 17


@dataclass(frozen=True)
class LoadHistory:
    """Bearing forces and drive torques of one model (rigid or elastic) over the cycle.

    Attributes
    ----------
    response : {"rigid", "elastic"}
        Rigid-body kinetostatics, or the periodic elastic response.
    force : ndarray, shape (n, n_bearings, 2)
        Force the pin exerts on the body of each bearing [N], global components.
    moment : ndarray, shape (n, n_bearings)
        Moment the pin exerts on the body [N m], counter-clockwise positive
        (zero but at welded joints and elastically clamped ends).
    torque : ndarray, shape (n, n_drives)
        Torque of each drive on its member [N m], counter-clockwise positive.
    residual : float
        Rigid: relative residual of the kinetostatic equations. Elastic: the
        largest imbalance of a pin (or of a rigid member) left by the recovered
        section forces, relative to the largest force; it is the share of the
        damping forces, which are not part of the section forces (docs/loads.md).
    """

    response: str
    force: np.ndarray
    moment: np.ndarray
    torque: np.ndarray
    residual: float

    @property
    def magnitude(self) -> np.ndarray:
        """Magnitude of every bearing force, shape (n, n_bearings) [N]."""
        return np.hypot(self.force[..., 0], self.force[..., 1])


@dataclass(frozen=True)
class LoadPeak:
    """The peak of one load over the cycle.

    Attributes
    ----------
    quantity : {"bearing_force", "drive_torque"}
    joint : str
        The pin (a drive's ground joint for a torque).
    member : str
        The body the pin holds (``"frame"``), or the driven member.
    response : {"rigid", "elastic"}
    peak : float
        Largest magnitude over the cycle [N or N m] (a parabolic vertex between the instants
        where the peak is smooth; the largest sample at a step or kink).
    crank_angle : float
        Crank angle of the peak [rad], in ``[0, 2 pi)``.
    rms : float
        Root mean square over the cycle [N or N m] (a motor's thermal load).
    """

    quantity: str
    joint: str
    member: str
    response: str
    peak: float
    crank_angle: float
    rms: float


@dataclass(frozen=True)
class MachineLoads:
    """Bearing forces and drive torques over the cycle, rigid and elastic.

    Attributes
    ----------
    mechanism : str
        Name of the mechanism.
    t : ndarray, shape (n,)
        Instants [s].
    crank_angle : ndarray, shape (n,)
        Angle of the first driven member [rad] (absolute, as the result's).
    bearings : tuple of (str, str)
        ``(joint, body)``: every member at every joint, and ``"frame"`` at
        ground and slider joints, in the mechanism's joint order.
    drives : tuple of (str, str)
        ``(member, ground joint)`` of every drive.
    rigid : LoadHistory
        Rigid-body kinetostatics.
    elastic : LoadHistory or None
        The elastic response (None when not computed).
    period : float
        Cycle period [s].
    speed : float
        Speed of the first drive [rad/s].
    near : dict, optional
        ``{response: (values, crank_angles)}``, each of shape ``(n_bearings + n_drives, w)``: every
        load's magnitude on :data:`NEAR_POINTS` instants spanning a sample either side of its
        largest one, read from the result's dense output (:func:`machine_loads`); the peaks are
        taken there.
    """

    mechanism: str
    t: np.ndarray
    crank_angle: np.ndarray
    bearings: tuple[tuple[str, str], ...]
    drives: tuple[tuple[str, str], ...]
    rigid: LoadHistory
    elastic: LoadHistory | None
    period: float
    speed: float
    #: response -> (values (q, w), crank angles (q, w)) of every peak's neighbourhood read from the
    #: result's dense output (:func:`machine_loads`); None: the peaks are read on the instants alone
    near: dict | None = None

    @property
    def n(self) -> int:
        """Number of instants."""
        return int(self.t.size)

    def history(self, response: str = "elastic") -> LoadHistory:
        """The :class:`LoadHistory` of ``"rigid"`` or ``"elastic"``."""
        if response == "rigid":
            return self.rigid
        if response != "elastic":
            raise InputError(f"machine loads: response must be 'rigid' or 'elastic', got {response!r}")
        if self.elastic is None:
            raise InputError("machine loads: the elastic loads were not computed "
                             "(machine_loads(result, elastic=True))")
        return self.elastic

    def bearing_index(self, joint: str, member: str | None = None) -> int:
        """Index of the bearing ``(joint, member)`` in :attr:`bearings` (``member``: as in :meth:`force`)."""
        here = [b for b in self.bearings if b[0] == joint]
        if not here:
            known = ", ".join(dict.fromkeys(b[0] for b in self.bearings))
            raise InputError(f"machine loads: unknown joint '{joint}' (joints: {known})")
        if member is None:
            frame = [b for b in here if b[1] == FRAME]
            return self.bearings.index(frame[0] if frame else here[0])
        if (joint, member) not in self.bearings:
            raise InputError(f"machine loads: no bearing of '{member}' at joint '{joint}' "
                             f"(bodies there: {', '.join(b[1] for b in here)})")
        return self.bearings.index((joint, member))

    def force(self, joint: str, member: str | None = None, response: str = "elastic") -> np.ndarray:
        """Force (n, 2) [N] the pin at ``joint`` exerts on ``member``.

        ``member`` defaults to ``"frame"`` at ground and slider joints, else
        to the first member at the joint.
        """
        return self.history(response).force[:, self.bearing_index(joint, member)]

    def magnitude(self, joint: str, member: str | None = None, response: str = "elastic") -> np.ndarray:
        """Magnitude (n,) [N] of :meth:`force`."""
        return self.history(response).magnitude[:, self.bearing_index(joint, member)]

    def torque(self, member: str | None = None, response: str = "elastic") -> np.ndarray:
        """Torque (n,) [N m] of the drive of ``member`` (default the first drive) on it."""
        names = [d[0] for d in self.drives]
        if not names:
            raise InputError(f"machine loads: {self.mechanism} has no drive")
        member = names[0] if member is None else member
        if member not in names:
            raise InputError(f"machine loads: '{member}' is not driven (drives: {', '.join(names)})")
        return self.history(response).torque[:, names.index(member)]

    def peaks(self, response: str = "elastic") -> list[LoadPeak]:
        """Peak and rms of every bearing force magnitude and drive torque over the cycle."""
        h = self.history(response)
        out = []
        for k, (j, m) in enumerate(self.bearings):
            out.append(self._peak("bearing_force", j, m, response, h.magnitude[:, k], k))
        for k, (m, j) in enumerate(self.drives):
            out.append(self._peak("drive_torque", j, m, response, h.torque[:, k], len(self.bearings) + k))
        return out

    def _peak(self, quantity, joint, member, response, values, q) -> LoadPeak:
        y = np.abs(values)
        k = int(np.argmax(y))
        rms = float(np.sqrt(np.mean(y * y)))
        if self.near is not None and response in self.near:
            # the neighbourhood read from the dense output: its largest value (a vertex where smooth)
            w, ang = self.near[response][0][q], self.near[response][1][q]
            j = int(np.argmax(w))
            value, shift = smooth_vertex(w, j)
            if value >= y[k]:
                step = float(ang[1] - ang[0]) if w.size > 1 else 0.0
                angle = float(np.mod(ang[j] + shift * step, 2.0 * math.pi))
                return LoadPeak(quantity, joint, member, response, value, angle, rms)
        # periodic parabolic vertex through the largest sample and its neighbours, where smooth (a
        # process load's step or kink: the sample)
        value, shift = smooth_vertex(y, k, periodic=True) if self.whole_cycle else (float(y[k]), 0.0)
        step = self.speed * self.period / self.n if self.whole_cycle else 0.0
        angle = float(np.mod(self.crank_angle[k] + shift * step, 2.0 * math.pi))
        return LoadPeak(quantity, joint, member, response, value, angle, rms)

    @property
    def whole_cycle(self) -> bool:
        """The instants are a uniform grid over the whole cycle."""
        return (self.n >= 3 and math.isfinite(self.period)
                and bool(np.allclose(np.diff(self.t), self.period / self.n, rtol=1e-9, atol=0.0)))

    def summary(self, digits: int = 4) -> str:
        """Peak bearing forces and drive torques, elastic beside rigid, as text lines.

        ``digits``: significant digits of the forces and torques (those the response's error allows).
        """
        g = f".{int(digits)}g"
        both = self.elastic is not None
        what = "elastic response; rigid-body kinetostatics in brackets" if both else "rigid-body kinetostatics"
        lines = [f"Loads on the machine ({what}):"]
        first = self.peaks("elastic" if both else "rigid")
        second = self.peaks("rigid") if both else [None] * len(first)
        for p, r in zip(first, second):
            unit = "N" if p.quantity == "bearing_force" else "N m"
            where = (f"bearing {p.joint} ({p.member})" if p.quantity == "bearing_force"
                     else f"drive {p.member} at {p.joint}")
            text = (f"  {where:<28} peak {p.peak:10{g}} {unit:<3} at {_deg(p.crank_angle):5.1f} deg, "
                    f"rms {p.rms:{g}} {unit}")
            if r is not None:
                text += f"  [{r.peak:{g}} {unit} at {_deg(r.crank_angle):.1f} deg, rms {r.rms:{g}}]"
            lines.append(text)
        if both:
            lines.append(f"  pin balance of the elastic loads: {self.elastic.residual:.1e} of the largest force "
                         "(the damping forces' share, docs/loads.md)")
        return "\n".join(lines)

    def rows(self):
        """The tidy table of :func:`write_loads_csv`: tuples in :data:`CSV_COLUMNS` order (SI units)."""
        deg = np.mod(np.degrees(self.crank_angle), 360.0)
        for h in (self.rigid, self.elastic):
            if h is None:
                continue
            mag = h.magnitude
            for k, (j, m) in enumerate(self.bearings):
                comps = [("x", h.force[:, k, 0]), ("y", h.force[:, k, 1]), ("magnitude", mag[:, k])]
                for comp, vals in comps:
                    for a, v in zip(deg, vals):
                        yield (float(a), h.response, "bearing_force", j, m, comp, float(v), "N")
                if np.any(h.moment[:, k]):
                    for a, v in zip(deg, h.moment[:, k]):
                        yield (float(a), h.response, "bearing_moment", j, m, "z", float(v), "N m")
            for k, (m, j) in enumerate(self.drives):
                for a, v in zip(deg, h.torque[:, k]):
                    yield (float(a), h.response, "drive_torque", j, m, "z", float(v), "N m")


def _deg(angle: float) -> float:
    """An angle [rad] in degrees rounded to 0.1, in ``[0, 360)``."""
    return round(math.degrees(angle), 1) % 360.0


# ----------------------------------------------------------------- building
def _bearings(mech: Mechanism, pairs) -> tuple[tuple[str, str], ...]:
    """Every (joint, member) pair of ``pairs`` and ``(joint, "frame")`` at supports, by joint."""
    pairs = set(pairs)
    out = []
    for j, jt in mech.joints.items():
        out.extend((j, m) for m in mech.members_at(j) if (m, j) in pairs)
        if jt.kind in ("ground", "slider"):
            out.append((j, FRAME))
        elif jt.kind == "slot":  # the block's pin on the member it slides on
            out.append((j, jt.on))
    return tuple(out)


def _history(response: str, bearings, forces: JointForces) -> LoadHistory:
    n = forces.force.shape[0]
    F = np.zeros((n, len(bearings), 2))
    M = np.zeros((n, len(bearings)))
    for k, (j, m) in enumerate(bearings):
        if m == FRAME:  # the pin on the frame: the frame's reaction on the pin, reversed
            F[:, k] = -forces.frame_reaction[j]
            M[:, k] = -forces.frame_moment.get(j, 0.0)
        elif (m, j) in forces.pairs:
            i = forces.pairs.index((m, j))
            F[:, k] = forces.force[:, i]
            M[:, k] = forces.moment[:, i]
        elif j in forces.contact:  # a slot: the pin pushes the member it slides on
            F[:, k] = -forces.contact[j]
            M[:, k] = -forces.contact_moment.get(j, 0.0)
        # else: a redundant member, which takes no kinetostatic force
    return LoadHistory(response, F, M, forces.drive_torque, float(forces.residual))


def loads_from_forces(mech: Mechanism, motion: Motion, rigid: JointForces,
                      elastic: JointForces | None = None) -> MachineLoads:
    """:class:`MachineLoads` from joint forces (of :func:`~kedfem.motion.kinetostatics.kinetostatics`).

    Parameters
    ----------
    mech : Mechanism
    motion : Motion
        The motion the forces were computed on (``n`` instants).
    rigid : JointForces
        Rigid-body kinetostatic forces.
    elastic : JointForces, optional
        Forces of the elastic response (with every flexible link's pairs).

    Returns
    -------
    MachineLoads
    """
    pairs = list(rigid.pairs) + (list(elastic.pairs) if elastic is not None else [])
    bearings = _bearings(mech, pairs)
    speed = float(mech.drives[0].speed) if mech.drives else 0.0
    return MachineLoads(mech.name, np.asarray(motion.t, float), np.asarray(motion.crank_angle, float), bearings,
                        tuple((d.member, d.ground_joint) for d in mech.drives),
                        _history("rigid", bearings, rigid),
                        None if elastic is None else _history("elastic", bearings, elastic),
                        float(motion.period), speed)


def machine_loads(result, elastic: bool = True, near: bool = True) -> MachineLoads:
    """Bearing forces and drive torques of a periodic result, rigid and elastic.

    Parameters
    ----------
    result : kedfem.analysis.results.PeriodicResult
        A solved scene (at its output instants ``result.t``).
    elastic : bool
        Also the loads of the elastic response (else only the rigid-body
        kinetostatics).
    near : bool
        Read every load's peak from the dense output around its largest sample
        (:attr:`MachineLoads.near`; a result on a whole-cycle grid that has one).

    Returns
    -------
    MachineLoads

    Notes
    -----
    The method and the sign conventions are in docs/loads.md.
    """
    mech, mo = result.model.mech, result.motion
    asm = result._assembler()
    rigid = asm.joint_forces()
    forces = _elastic_forces(result, asm) if elastic else None
    loads = loads_from_forces(mech, mo, rigid, forces)
    if near and result.sampler is not None and loads.whole_cycle:
        loads = _near_peaks(result, loads)
    return loads


def _magnitudes(h: LoadHistory) -> np.ndarray:
    """Every bearing force's magnitude and every drive torque's, shape (n, n_bearings + n_drives)."""
    return np.concatenate([h.magnitude, np.abs(h.torque)], axis=1)


def _near_peaks(result, loads: MachineLoads) -> MachineLoads:
    """``loads`` with every load's neighbourhood of its largest sample read from the dense output.

    :data:`NEAR_POINTS` instants from a sample before to a sample after it, for every load and
    response at once (one resampled result): the peak between two samples, a smooth one or one at
    a process load's step, which a parabola through the samples overshoots (a new user's toggle
    press: 12 % above every sample) and a coarse grid undercuts (the four-bar preset's elastic
    coupler force, whose axial ringing the 1-degree samples cut 0.2 % short).
    """
    responses = ("rigid",) + (("elastic",) if loads.elastic is not None else ())
    step = loads.period / loads.n
    offsets = np.linspace(-step, step, NEAR_POINTS)
    centres = np.concatenate([loads.t[np.argmax(_magnitudes(loads.history(r)), axis=0)] for r in responses])
    # the loads of a joint peak on the same sample (a pin's force on a link and on the frame): one
    # neighbourhood per distinct sample
    unique, which = np.unique(centres, return_inverse=True)
    fine = machine_loads(result.resample(np.mod(unique[:, None] + offsets, loads.period).ravel()),
                         elastic=loads.elastic is not None, near=False)
    q = centres.size // len(responses)
    near = {}
    for i, r in enumerate(responses):
        vals = _magnitudes(fine.history(r)).reshape(unique.size, NEAR_POINTS, q)
        rows = which.ravel()[i * q:(i + 1) * q]
        ang = fine.crank_angle.reshape(unique.size, NEAR_POINTS)[rows]
        near[r] = (vals[rows, :, np.arange(q)], np.unwrap(ang, axis=1))
    return dataclasses.replace(loads, near=near)


# ------------------------------------------------------- the elastic response
@lru_cache(maxsize=1)
def _slope_weights() -> tuple[np.ndarray, np.ndarray]:
    """Weights giving ``dM/dxi`` at ``xi = 0`` and ``1`` from M on ``_STATIONS + 1`` equal stations."""
    xi = np.linspace(0.0, 1.0, _STATIONS + 1)
    V = np.vander(xi, increasing=True)
    k = np.arange(_STATIONS + 1, dtype=float)

    def slope(x0):
        d = k * np.where(k > 0, x0, 1.0) ** np.maximum(k - 1, 0)
        return np.linalg.solve(V.T, d)

    return slope(0.0), slope(1.0)


def _holds_moment(mech: Mechanism, link, k: int) -> bool:
    """The end ``k`` (0: ``a``, 1: ``b``) of a flexible link is elastically clamped to something."""
    joint = link.joints[k]
    jt = mech.joints[joint]
    return link.ends[k] == "clamp" or jt.welds(link.name) or (jt.kind == "slider" and jt.rotation == "locked")


def _end_forces(result, link) -> dict:
    """Force (n, 2) and moment (n,) the pins exert on a flexible link's ends, by its section forces.

    In the link frame, at end ``a``: ``(-N(0), M'(0) - N_e v'(0))`` and moment
    ``-M(0)``; at end ``b``: ``(N(L), -(M'(L) - N_e v'(L)))`` and ``M(L)``
    (``M = EI v''``, ``M' = dM/dx`` from the element's polynomial moment;
    ``N_e v'`` only where the recovery puts the axial force on the deflection).
    At a joint the link passes through (``through=``), the sum of the two
    elements' end forces there.
    """
    name = link.name
    M, N = result._forces(name, _STATIONS)  # (n, n_el, stations), element by element
    d = result._local(name)
    Le = link.element_lengths
    w0, w1 = _slope_weights()
    slope_a = M @ w0 / Le  # dM/dx at each element's start and end, (n, n_el)
    slope_b = M @ w1 / Le
    sl = result.model.link_elements(name)
    b = result.model.beam
    eff = set(getattr(result.scene, "effects", ()))
    loaded = not (b.lumped[sl].any() or b.timoshenko[sl].any()) and result._local_rates(name) is not None
    if loaded and {"axial_stiffening", "geometric_nonlinearity"} & eff:
        Ne = result._axial_fe(name)
        slope_a = slope_a - Ne * d[..., 2]
        slope_b = slope_b - Ne * d[..., 5]
    # the pins' forces on the elements' starts and ends (n, n_el, 2), and moments (n, n_el)
    start = np.stack([-N[:, :, 0], slope_a], axis=-1)
    end = np.stack([N[:, :, -1], -slope_b], axis=-1)
    th = result.motion.angle(name)
    c, s = np.cos(th)[:, None], np.sin(th)[:, None]

    def glob(f):
        return np.concatenate([c * f[:, :1] - s * f[:, 1:], s * f[:, :1] + c * f[:, 1:]], axis=1)

    out = {(name, link.a): (glob(start[:, 0]), -M[:, 0, 0]), (name, link.b): (glob(end[:, -1]), M[:, -1, -1])}
    for t, i in zip(link.through, link.inner_nodes):  # a pin inside: the two elements meeting at its node
        out[(name, t)] = (glob(end[:, i - 1] + start[:, i]), M[:, i - 1, -1] - M[:, i, 0])
    return out


def _accelerations(result, asm, gname: str) -> np.ndarray:
    """Elastic accelerations (n, n_el, d) of the entities of group ``gname`` (global components).

    ``x'' = E q'' + 2 E' q' + E'' q + p''`` from the dense accelerations of the
    DOFs; without them the spectral derivative on a uniform grid over the cycle.
    """
    mo, U, V = result.motion, result.U, result.V
    x, _xd, _xq, gm = asm.element_state(gname, mo, U, V)
    if result.sampler is not None:
        acc = gm.apply(result.dof_accelerations())
        if gm.E1 is not None:
            acc = acc + 2.0 * gm.apply(V, E=gm.E1) + gm.apply(U, E=gm.E2)
        return acc + gm.p2 if gm.p2 is not None else acc
    if result._uniform():
        return periodic_rates(x, result.scene.period)[1]
    log.info("machine loads: %s without dense output on instants that are not a uniform grid: "
             "the elastic accelerations of rigid members and point masses are left out", result.model.mech.name)
    return np.zeros_like(x)


def _elastic_known(result, asm, skip=frozenset()) -> KnownForces:
    """The forces the elastic response fixes: flexible links' ends, drive torques, accelerations.

    The links in ``skip`` are left unknown (their balance rows stay).
    """
    mech, mo, model = result.model.mech, result.motion, result.model
    force, moment, torque = {}, {}, {}
    moment_pairs, frame_moments = set(), set()
    rigid = [m for m, lk in mech.links.items() if lk.rigid] + list(mech.bodies)
    for lk in mech.flexible_links:
        if lk.name in skip:
            continue
        ends = _end_forces(result, lk)
        drive = mech.driven(lk.name)
        for t in lk.through:  # a pin inside the link: its force, its moment where welded or driven
            force[(lk.name, t)], M = ends[(lk.name, t)]
            root = drive is not None and drive.ground_joint == t
            if root and drive.torsional_stiffness is None:
                torque[lk.name] = M
            if mech.joints[t].welds(lk.name):
                moment[(lk.name, t)] = M
                if mech.joints[t].clamped:
                    frame_moments.add(t)
        for k, j in enumerate(lk.joints):
            F, M = ends[(lk.name, j)]
            force[(lk.name, j)] = F
            root = drive is not None and drive.ground_joint == j
            if root and drive.torsional_stiffness is None:
                torque[lk.name] = M
            welded = mech.joints[j].welds(lk.name)
            if (root and not welded) or not _holds_moment(mech, lk, k):
                continue  # a free end, or a root whose moment is the drive's
            moment[(lk.name, j)] = M
            if welded:
                continue
            if mech.joints[j].kind in ("ground", "slider"):  # a clamped root, or a crosshead
                frame_moments.add(j)
            else:  # tied to the rotation of the rigid member pivoting here (kedfem.fe.dofs)
                moment_pairs.update((m, j) for m in [m for m in mech.members_at(j) if m in rigid][:1])
    g = model.groups["tspring"]
    if g.n:
        phi = asm.element_state("tspring", mo, result.U)[0]
        for k, (kind, item) in enumerate(g.meta["items"]):
            if kind == "drive":  # the shaft's spring on the member: -k_t (elastic twist)
                torque[item.member] = -item.torsional_stiffness * phi[:, k, 0]
    acc = {}
    for gname in ("rigid", "pmass"):
        acc[gname] = _accelerations(result, asm, gname) if model.groups[gname].n else None
    n, nm, nj = mo.n, len(mo.member_names), len(mo.joint_names)
    m_acc, m_alpha = np.zeros((n, nm, 2)), np.zeros((n, nm))
    for k, m in enumerate(model.groups["rigid"].meta.get("members", ())):
        i = mo.member_names.index(m)
        m_acc[:, i], m_alpha[:, i] = acc["rigid"][:, k, :2], acc["rigid"][:, k, 2]
    j_acc, j_alpha = np.zeros((n, nj, 2)), np.zeros((n, nj))
    for k, p in enumerate(model.groups["pmass"].meta.get("items", ())):
        i = mo.joint_names.index(p.joint)
        j_acc[:, i], j_alpha[:, i] = acc["pmass"][:, k, :2], acc["pmass"][:, k, 2]
    return KnownForces(force, moment, torque, frozenset(moment_pairs), frozenset(frame_moments),
                       m_acc, m_alpha, j_acc, j_alpha)


def _elastic_loads(result, asm) -> tuple[np.ndarray, np.ndarray]:
    """Loads on the pins (n, n_joints, 2) and moments on the members (n, n_members) of the response.

    The chosen effects' loads on the rigid-body motion, plus what the elastic
    state adds: the springs' linear stiffness on the elastic extension (always
    assembled), their cubic law (``springs``), friction on the total velocity (``loads``).
    """
    mech, mo, U = result.model.mech, result.motion, result.U
    loads = np.zeros((mo.n, len(mo.joint_names), 2))
    moments = np.zeros((mo.n, len(mo.member_names)))
    for e in asm.chosen:
        e.joint_loads(asm, mo, loads, moments)
    eff = set(asm.effects)
    g = result.model.groups["spring"]
    if g.n:
        items = g.meta["items"]
        de = np.einsum("si,tsi->ts", spring_axes(items), asm.element_state("spring", mo, U)[0])
        for k, s in enumerate(items):
            dF = s.k * de[:, k]
            if "springs" in eff and s.k3:
                dr = spring_extension(mech, mo, s)
                dF = dF + s.k3 * ((dr + de[:, k]) ** 3 - dr**3)
            loads[:, mo.joint_names.index(s.a)] -= dF[:, None] * np.asarray(s.axis)
            if s.b is not None:
                loads[:, mo.joint_names.index(s.b)] += dF[:, None] * np.asarray(s.axis)
    g = result.model.groups["tspring"]
    if g.n:
        phi = asm.element_state("tspring", mo, U)[0]
        for k, (kind, t) in enumerate(g.meta["items"]):
            if kind == "spring":
                dM = t.k * (phi[:, k, 0] - phi[:, k, 1])
                moments[:, mo.member_names.index(t.member)] -= dM
                if t.other is not None:
                    moments[:, mo.member_names.index(t.other)] += dM
    total = [f for f in mech.frictions.values() if f.follows == "total"]
    if total and "loads" in eff:
        g = result.model.groups["load"]
        _x, xd, _xq, _gm = asm.element_state("load", mo, U, result.V)
        for k, it in enumerate(g.meta["items"]):
            if getattr(it, "follows", None) == "total":
                loads[:, mo.joint_names.index(it.joint)] += rigid_friction(mo, it, xd[:, k]) - rigid_friction(mo, it)
    return loads, moments


def contact_forces(result) -> dict:
    """Force (n, 2) [N] each slotted member exerts on its block's pin in the elastic response.

    From the balance of the pins (the members at the block with their section
    forces, the block's inertia and loads), with the slotted members' own end
    forces left unknown, so that their section forces can use the result
    (:meth:`~kedfem.analysis.results.PeriodicResult.bending_moment`).

    Parameters
    ----------
    result : kedfem.analysis.results.PeriodicResult

    Returns
    -------
    dict
        Slot joint name -> (n, 2) global components.
    """
    mech = result.model.mech
    slotted = frozenset(j.on for j in mech.joints.values() if j.kind == "slot")
    if not slotted:
        return {}
    asm = result._assembler()
    known = _elastic_known(result, asm, skip=slotted)
    loads, moments = _elastic_loads(result, asm)
    out = kinetostatics(mech, result.motion, inertia="inertia" in asm.effects, gravity=asm.weight,
                        joint_loads=loads, member_moments=moments, known=known,
                        pair_loads=asm.pair_loads(result.motion))
    return out.contact


def _elastic_forces(result, asm) -> JointForces:
    """Joint forces of the elastic response (see the module docstring)."""
    known = _elastic_known(result, asm)
    loads, moments = _elastic_loads(result, asm)
    out = kinetostatics(result.model.mech, result.motion, inertia="inertia" in asm.effects,
                        gravity=asm.weight, joint_loads=loads, member_moments=moments, known=known,
                        pair_loads=asm.pair_loads(result.motion))
    log.info("machine loads of %s: elastic pin balance %.1e of the largest force", result.model.mech.name,
             out.residual)
    return out


# ------------------------------------------------------------------ outputs
