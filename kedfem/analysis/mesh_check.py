"""The mesh's share of a result's error: the same scene on links with half (or twice) the elements.

The error estimate of a solve (:mod:`kedfem.analysis.accuracy`) covers the time
discretisation only. How far the peaks are from mesh convergence is a second
question: :func:`mesh_error` solves the scene again with every flexible link
meshed into half its elements (``e // 2`` when that leaves at least two; links
of one to three elements are meshed into ``2 e`` instead, because the
mid-span deflection of a single cubic element is far off: 20 % on the
slider-crank's rod), on the result's own time elements and scheme, and
extrapolates the change of every link's peak deflection and peak stress at
the rate ``p = 4`` of the cubic elements' nodal displacements, which the
stresses recovered by element equilibrium (:mod:`kedfem.analysis.recovery`) share
(measured on the four-bar, 2 -> 4 -> 8 -> 16 elements: 3.6 - 4.2 for
stresses and deflections; four elements per link are within 3e-4 of
converged there, 2.6e-4 on the default scene's leaf springs; on a crank-rocker
whose rocker carries a welded arm with a tip mass, 3.9 - 4.1 for the
deflections since the geometric stiffness follows the axial force along each
element, where the element's mean force had made it 2.0 and the estimate 0.2x
the truth). Below about 1e-6 of a peak the changes no longer follow the rate
(the welded arm's stresses at the weld: 4e-7 on 8 elements, estimated 3e-8),
and under ``geometric_nonlinearity`` at finite deflection the element-constant
membrane strain makes the welded arm's deflections converge at about 2 (5e-7
of the peak on 8 elements; the four-bar's at 3.6 - 4.4), and a link loaded through its pin by a
strongly deflected one converges slower still: a new user's crank-rocker at 2250 rpm (a 3 mm strip
coupler deflecting 3 % of its length, a tube rocker; 2 -> 16 elements, 192 time elements) had the
coupler's peak deflection at rates 4.0 / 3.2, estimated 0.95x the truth on 4 elements, and the
rocker's at 0.1 / 1.6, estimated 0.05x (3.5e-4 true, 1.8e-5 printed; the largest over the links,
the coupler's, is the honest one)::

    error(e) ~ |q(e) - q(e_c)| / |1 - (e / e_c)^p|

The comparison is one solve without an estimate: about a quarter to a half
of the result's cost when it coarsens, more when it refines short links.
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import math
import re
import warnings
from dataclasses import dataclass

from ..errors import InputError, KedError, NonlinearSolveError

__all__ = ["MeshError", "LinkMeshError", "mesh_error", "coarsened", "comparison_mesh", "MESH_RATE",
           "BLOCK_MESH_RATE"]

log = logging.getLogger(__name__)

#: Convergence rate credited to the peak stresses and deflections under mesh refinement
MESH_RATE = 4.0
#: ... on a link a block slides on: the peak stress sits under the moving contact load, and its
#: recovery converges at second order (the Whitworth lever, 8 -> 16 -> 32 elements: 2.2)
BLOCK_MESH_RATE = 2.0


@dataclass(frozen=True)
class LinkMeshError:
    """Estimated relative mesh error of one flexible link's peaks.

    Attributes
    ----------
    link : str
    elements, comparison_elements : int
        Elements of the result's mesh and of the comparison mesh.
    deflection, stress : float or None
        Estimated relative error of the peak mid-span deflection and the peak
        stress (None: the link has one element, or no stress).
    """

    link: str
    elements: int
    comparison_elements: int
    deflection: float | None
    stress: float | None
    rate: float = MESH_RATE


@dataclass(frozen=True)
class MeshError:
    """Estimated mesh error of a result's peaks (see the module docstring).

    Attributes
    ----------
    links : tuple of LinkMeshError
    rate : float
        Rate credited (:data:`MESH_RATE`).
    rtol : float or None
        The result's tolerance, which :meth:`describe` says the estimate exceeds.
    """

    links: tuple[LinkMeshError, ...]
    rate: float
    rtol: float | None = None

    @property
    def peak(self) -> float:
        """Largest estimated relative mesh error of any link's peaks (nan if none could be estimated)."""
        v = [x for e in self.links for x in (e.deflection, e.stress) if x is not None]
        return max(v) if v else math.nan

    def link(self, name: str) -> LinkMeshError:
        """The estimate of one link."""
        for e in self.links:
            if e.link == name:
                return e
        raise InputError(f"no mesh error estimate for link '{name}' "
                         f"(flexible links: {', '.join(e.link for e in self.links)})")

    def describe(self) -> str:
        """One line: the largest estimated mesh error and how it was obtained."""
        mesh = ", ".join(f"{e.link} {e.elements}/{e.comparison_elements}" for e in self.links)
        other = sorted({f"{e.rate:g} on {e.link}" for e in self.links if e.rate != self.rate})
        # (the command line said it, kf.mesh_error(res).describe() did not: a new user's trial)
        above = (f"; above the tolerance {self.rtol:.0e}: more elements per link lower it"
                 if self.rtol is not None and self.peak > self.rtol else "")
        return (f"peaks {self.peak:.1e} (elements per link, result/comparison: {mesh}; "
                f"rate {self.rate:g} credited{', ' + ', '.join(other) if other else ''}){above}")


def _remeshed(mech, elements):
    """A copy of ``mech`` whose flexible links have ``elements(e, link)`` elements (``mech`` unchanged)."""
    new = copy.deepcopy(mech)
    for name, lk in list(new.links.items()):
        if not lk.rigid:
            # at least one element per stretch between the joints the link passes through
            new.links[name] = dataclasses.replace(lk, elements=max(int(elements(lk.elements, lk)),
                                                                   len(lk.through) + 1))
    return new


def coarsened(mech, factor: int = 2):
    """A copy of ``mech`` with every flexible link meshed into ``elements // factor`` (>= 1) elements."""
    return _remeshed(mech, lambda e, _lk: max(1, e // factor))


def comparison_mesh(mech, factor: int = 2):
    """A copy of ``mech`` meshed for the mesh check: ``e // factor`` elements per flexible
    link where that leaves at least two (and one per stretch of a link passing through joints),
    ``e * factor`` otherwise."""
    return _remeshed(mech, lambda e, lk: e // factor if e // factor >= max(2, len(lk.through) + 1)
                     else e * factor)


def mesh_error(res, factor: int = 2) -> MeshError | None:
    """Estimate the mesh error of a result's peaks by a solve on a coarser (or finer) mesh.

    Parameters
    ----------
    res : PeriodicResult
        A result of :func:`kedfem.solve`.
    factor : int
        How many times coarser (or finer) the comparison mesh is: ``e // factor`` elements on a
        link of ``e`` where that leaves at least two, else ``e * factor``
        (:func:`comparison_mesh`; default 2, half the elements).

    Returns
    -------
    MeshError or None
        None when the mechanism has no flexible link, or when the comparison
        model cannot be built or solved (logged).
    """
    from .results import PeriodicResult
    if not isinstance(res, PeriodicResult):
        raise InputError(f"mesh_error: res must be a result of kedfem.solve, got {type(res).__name__}")
    if isinstance(factor, bool) or not isinstance(factor, int) or not 2 <= factor <= 8:
        raise InputError(f"mesh_error: factor must be an integer in 2 .. 8, got {factor!r}")
    res._cache.pop("mesh_error", None)  # (a failed check leaves no earlier one in the summary)
    scene = res.scene
    mech = scene.mechanism
    flex = [lk for lk in mech.links.values() if not lk.rigid]
    if not flex:
        return None
    coarse = comparison_mesh(mech, factor)
    # the comparison's own messages (a continuation in speed, its time left) say whose they are: a
    # new user read the same run-up warnings again after the solve's as the solve starting over
    coarse.name = f"{mech.name} (mesh check: {_mesh_change(flex, coarse)})"
    sc = dataclasses.replace(scene, mechanism=coarse, steps=int(res.elements), method=res.scheme or "auto",
                             hold=None, estimate=False)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rc = _comparison(res, coarse, sc)
    except KedError as exc:
        log.warning("%s: no mesh error estimate (the comparison model failed: %s)", mech.name, exc)
        return None
    fine = {p.link: p for p in res.peaks()}
    out = []
    for p in rc.peaks():
        lk, f = mech.links[p.link], fine[p.link]
        e, ec = lk.elements, coarse.links[p.link].elements
        if ec == e:
            out.append(LinkMeshError(p.link, e, ec, None, None))
            continue
        rate = BLOCK_MESH_RATE if any(j.kind == "slot" and j.on == p.link for j in mech.joints.values()) \
            else MESH_RATE
        div = abs(1.0 - (e / ec) ** rate)

        def rel(a, b):
            return abs(a - b) / abs(a) / div if (math.isfinite(a) and a != 0) else None

        out.append(LinkMeshError(p.link, e, ec, rel(f.deflection, p.deflection), rel(f.stress, p.stress), rate))
    est = MeshError(tuple(out), MESH_RATE, scene.rtol)
    res._cache["mesh_error"] = est  # res.summary() shows the last one (a new user's read "not estimated")
    return est


def _comparison(res, coarse, sc):
    """The comparison mesh's solve on the result's time elements. A non-linear scene's Newton starts
    from the result read on the nodes both meshes share (or from the linear response); where it fails,
    the comparison goes the way the result's own solve did (``_Run(ladder=True)``): the levels from the
    coarsest that resolves the excited modes up, each from the one before, the continuation in speed
    on the coarsest, and on a finer level whose Newton fails from the coarser one from just below the
    coarser one's fold. (It ran the continuation on the result's own elements instead, a Newton solve
    on all of them per step: the six-bar preset at 1600 rpm, past two folds, solved in 103 s on 1536
    elements, then its check took 20 min; this way 90 s, the same estimate.)"""
    from .pipeline import _Run, solve
    from ..solvers.threads import one_blas_thread
    if not sc.state_dependent:
        return solve(sc)
    with one_blas_thread():
        try:
            return _Run(sc, start=_restricted_start(res, coarse, sc), runup=False).run()
        except NonlinearSolveError:
            log.warning("%s: Newton from the result did not converge on %d time elements; solving the "
                        "comparison mesh's levels from the coarsest that resolves the excited modes up, as "
                        "the result's own solve did (it took %.0f s)", sc.mech.name, sc.steps, res.timings.total)
        return _Run(sc, ladder=True).run()


def _mesh_change(flex, coarse) -> str:
    """``"4 -> 2 elements per link"``, or per link where they differ (``"crank 1 -> 2, coupler 6 -> 3"``)."""
    pairs = [(lk.name, lk.elements, coarse.links[lk.name].elements) for lk in flex]
    if len({(e, c) for _n, e, c in pairs}) == 1:
        return f"{pairs[0][1]} -> {pairs[0][2]} elements per link"
    return ", ".join(f"{n} {e} -> {c}" for n, e, c in pairs)


class _RestrictedDiscrete:
    """A solution's dense output read on a subset of its DOFs (the interface
    :func:`kedfem.analysis.homotopy.phase_sample` reads: ``period`` and ``at``)."""

    def __init__(self, discrete, idx):
        self._d, self._idx = discrete, idx
        self.period = discrete.period

    def at(self, t):
        U, V = self._d.at(t)
        return U[:, self._idx], V[:, self._idx]


def _restricted_start(res, coarse, scene):
    """``res`` read on the DOFs of ``coarse`` (the same joints and the nodes both meshes share),
    as the start of the comparison solve of a non-linear scene: Newton from the linear response
    fell back on the continuation in speed there as on the result's own solve (a new user's
    crank-rocker at 2250 rpm: 3.5 s, and a second warning that read as the solve restarting).
    None where the scene is linear, the result has no dense output, or a DOF of the coarse mesh
    has no counterpart (a refined link's new nodes, a reduced link's modal coordinates)."""
    from types import SimpleNamespace

    import numpy as np

    from ..fe.model import FEModel
    if res.sampler is None or not res.scene.state_dependent:
        return None
    fine_mech = res.scene.mechanism
    pos = {lab: i for i, lab in enumerate(res.dof_labels)}
    idx = []
    for lab in FEModel(coarse, reduction=scene.reduction).dof_labels:
        m = re.fullmatch(r"(.+)\.n(\d+)\.(\w+)", lab)
        if m is not None and m.group(1) in coarse.links:
            name, j, comp = m.group(1), int(m.group(2)), m.group(3)
            x, nodes = coarse.links[name].nodes[j], fine_mech.links[name].nodes
            at = np.flatnonzero(np.abs(nodes - x) <= 1e-9 * fine_mech.links[name].length)
            if at.size != 1:
                return None
            lab = f"{name}.n{int(at[0])}.{comp}"
        k = pos.get(lab)
        if k is None:
            return None
        idx.append(k)
    # what _Run reads of a start: its sampler's discrete solution and its model's drive
    discrete = _RestrictedDiscrete(res.sampler.discrete, np.array(idx))
    return SimpleNamespace(model=res.model, sampler=SimpleNamespace(discrete=discrete))
