"""A result's section forces and stresses by element equilibrium: the nodal displacements'
interpolation plus the forces of each element's distributed loads (from the rotating-frame rates of
its DOFs), on the link's stations (:class:`SectionForces`, a part of
:class:`kedfem.analysis.results.PeriodicResult`; the blocks sliding on a link:
:mod:`kedfem.analysis.block_forces`)."""

from __future__ import annotations

import logging

import numpy as np

from ..model import elements as el
from ..motion.kinetostatics import link_axial_force, link_axial_force_at
from . import recovery
from ..errors import InputError
from .stations import _element_length, _on_stations, _per_element

# a result's read-outs log under the results' name
log = logging.getLogger("kedfem.analysis.results")


def _st(d: np.ndarray) -> np.ndarray:
    """``S^T`` on the translations of local element DOFs (..., 6): ``(u, v) -> (v, -u)``, rotations 0."""
    out = np.zeros_like(d)
    out[..., 0], out[..., 1] = d[..., 1], -d[..., 0]
    out[..., 3], out[..., 4] = d[..., 4], -d[..., 3]
    return out


def _translations(d: np.ndarray) -> np.ndarray:
    """Local element DOFs (..., 6) with the rotations zeroed."""
    out = d.copy()
    out[..., 2] = 0.0
    out[..., 5] = 0.0
    return out


class SectionForces:
    """The section forces and stresses of :class:`kedfem.analysis.results.PeriodicResult` (a mixin:
    it reads the result's local element DOFs, its dense output and its cache)."""

    # ------------------------------------------------------- section forces
    def _axial_fe(self, link: str) -> np.ndarray:
        """Interpolated axial force per element (n, n_el) [N] (plus the membrane term)."""
        lk = self._link(link)
        d = self._local(link)
        Le = _element_length(lk)
        EA = lk.material.E * lk.section.A
        N = EA * (d[..., 3] - d[..., 0]) / Le
        if "geometric_nonlinearity" in getattr(self.scene, "effects", ()):
            vb = d[..., el.V_DOFS]
            if np.ndim(Le) == 0:
                G = el.geometric_matrix([Le])[0]
                N = N + EA / (2 * Le) * np.einsum("...i,ij,...j->...", vb, G, vb)
            else:
                G = el.geometric_matrix(Le)
                N = N + EA / (2 * Le) * np.einsum("...ei,eij,...ej->...e", vb, G, vb)
        return N

    def _local_rates(self, link: str):
        """Rotating-frame rates (n, n_el, 6) of the local element DOFs, or None.

        From the dense velocities and accelerations of the DOFs (:meth:`Sampler.acceleration`)
        through the constraint maps and their time derivatives: with ``x = E q + p``
        (global components) and ``d = T(theta) x``::

            x' = E q' + E' q + p',   x'' = E q'' + 2 E' q' + E'' q + p''
            d' = T x' + w S^T d,     d'' = T x'' + 2 w S^T (T x') + a S^T d - w^2 d

        (``S^T`` and ``w^2`` act on the translations). Without a sampler, spectral
        derivatives of ``d`` on a uniform grid over the cycle, else None.
        """
        key = ("rates", link)
        if key in self._cache:
            return self._cache[key]
        out = None
        if self.sampler is not None:
            sl = self.model.link_elements(link)
            gm = self._beam_map()
            cols = gm.cols[sl]
            pad = np.zeros((self.n, 1))
            acc = self.dof_accelerations()
            Q = [np.concatenate([X, pad], axis=1)[:, cols] for X in (self.U, self.V, acc)]  # (n, ne, m)
            E = gm.E[:, sl]

            def apply(A, q):
                return (A @ q[..., None])[..., 0]

            xd = apply(E, Q[1])
            xdd = apply(E, Q[2])
            if gm.E1 is not None:
                E1, E2 = gm.E1[:, sl], gm.E2[:, sl]
                xd = xd + apply(E1, Q[0])
                xdd = xdd + 2.0 * apply(E1, Q[1]) + apply(E2, Q[0])
            if gm.p is not None:
                xd = xd + gm.p1[:, sl]
                xdd = xdd + gm.p2[:, sl]
            th = self.motion.angle(link)
            w = self.motion.angular_velocity(link)[:, None, None]
            a = self.motion.angular_acceleration(link)[:, None, None]
            T = el.rotation_blocks(th)[:, None]
            d = self._local(link)
            Txd = (T @ xd[..., None])[..., 0]
            dd = Txd + w * _st(d)
            ddd = (T @ xdd[..., None])[..., 0] + 2.0 * w * _st(Txd) + a * _st(d) - w * w * _translations(d)
            out = (dd, ddd)
        elif self._uniform():
            out = recovery.periodic_rates(self._local(link), self.scene.period)
        else:
            log.info("%s: results without dense output on instants that are not a uniform grid: "
                     "section forces without the distributed-load correction", link)
        self._cache[key] = out
        return out

    def _uniform(self) -> bool:
        """The instants are a uniform grid over the whole cycle."""
        return self.n >= 8 and bool(np.allclose(np.diff(self.t), self.scene.period / self.n,
                                                rtol=1e-9, atol=0.0))

    def _forces(self, link: str, per_element: int):
        """Bending moment and axial force (n, n_el, per_element + 1) by element equilibrium."""
        return self._forces_at(link, np.linspace(0.0, 1.0, per_element + 1))

    def _forces_at(self, link: str, xi: np.ndarray):
        """Bending moment and axial force (n, n_el, nx) at fractions ``xi`` (nx,) of every element."""
        lk = self._link(link)
        key = ("forces", link, tuple(np.asarray(xi, float).tolist()))
        if key in self._cache:
            return self._cache[key]
        d = self._local(link)
        Le = _element_length(lk)
        xi = np.asarray(xi, float)
        q, p, N_h = self._element_loads(lk)
        out = recovery.section_forces(d, q, p, L=Le, EA=lk.material.E * lk.section.A,
                                      EI=lk.material.E * lk.section.I, xi=xi, N_h=N_h)
        blocks = self._blocks_on(lk)
        if blocks:
            out = self._with_blocks(lk, blocks, out, xi)
        self._cache[key] = out
        return out

    def _element_loads(self, lk):
        """``(q, p, N_h)`` of the link's elements: the distributed loads at the load points
        (n, n_el, 4) each, or None without rates (:func:`kedfem.analysis.recovery.element_loads`),
        and the interpolated axial force (n, n_el) (computed once)."""
        key = ("element_loads", lk.name)
        if key in self._cache:
            return self._cache[key]
        link = lk.name
        d = self._local(link)
        ne = lk.elements
        Le = _element_length(lk)
        N_h = self._axial_fe(link)
        q = p = None
        sl = self.model.link_elements(link)
        b = self.model.beam
        rates = None if (b.lumped[sl].any() or b.timoshenko[sl].any()) else self._local_rates(link)
        if rates is not None:
            eff = set(getattr(self.scene, "effects", ()))
            mo = self.motion
            th = mo.angle(link)
            c, s = np.cos(th), np.sin(th)

            def local(v):  # R^T v, (n, 2)
                return np.stack([c * v[..., 0] + s * v[..., 1], -s * v[..., 0] + c * v[..., 1]], axis=-1)

            g = None
            if "gravity" in eff:
                g = local(np.broadcast_to(np.asarray(self.model.mech.gravity, float), (self.n, 2)))
            stiff = bool({"axial_stiffening", "geometric_nonlinearity"} & eff)
            q, p = recovery.element_loads(
                d, rates[0], rates[1], L=Le, rhoA=float(b.rhoA[sl][0]), s1=np.arange(ne) * Le if np.ndim(Le) == 0 else lk.nodes[:-1],
                omega=mo.angular_velocity(link), alpha=mo.angular_acceleration(link),
                a_loc=local(mo.a[:, mo.joint_names.index(lk.a)]), g_loc=g,
                N=(N_h if "inertia" not in eff else self._axial_along(lk, Le, N_h, "geometric_nonlinearity" in eff))
                if stiff else None,
                inertia="inertia" in eff, coupling="coupling" in eff)
        out = self._cache[key] = (q, p, N_h)
        return out

    def _axial_along(self, lk, Le, N_h, elastic: bool) -> np.ndarray:
        """The axial force the model's geometric stiffness carries, at the load points of the link's
        elements (n, n_el, 4) [N]: the kinetostatic force (``axial_stiffening``), or the elastic
        mean ``N_h`` plus the kinetostatic force's variation about its element mean
        (``geometric_nonlinearity``); the recovery balances each element with it."""
        mech = self.model.mech
        if not mech.links[lk.name].kinematic:  # a redundant member: no kinetostatic force in the model
            return N_h[..., None] + np.zeros(4) if elastic else np.zeros(N_h.shape + (4,))
        cache = self._motion_cache()  # shared by the levels read on one grid
        key = ("kinetostatic axial force", lk.name, elastic)
        if key not in cache:
            asm = self._assembler()  # one per grid; its joint forces are computed once
            forces, weight = asm.joint_forces(), asm.weight
            s1 = np.asarray(np.arange(lk.elements) * Le if np.ndim(Le) == 0 else lk.nodes[:-1], float)
            L = np.broadcast_to(np.asarray(Le, float), s1.shape)
            N = link_axial_force_at(mech, self.motion, forces, lk.name,
                                    s1[:, None] + L[:, None] * recovery.LOAD_POINTS, gravity=weight,
                                    side=(s1 + 0.5 * L)[:, None])
            if elastic:  # the variation about the element mean
                N = N - link_axial_force(mech, self.motion, forces, lk.name, s1, s1 + L, gravity=weight)[..., None]
            N.flags.writeable = False  # shared by the results read on the grid
            cache[key] = N
        return N_h[..., None] + cache[key] if elastic else cache[key]

    def axial_force(self, link: str) -> np.ndarray:
        """Elastic axial force at the element midpoints (n, n_el) [N], tension positive.

        By element equilibrium (:mod:`kedfem.analysis.recovery`): ``EA (u2 - u1) /
        L_e`` (plus the membrane term ``EA/(2 L_e) int v'^2`` when the scene
        includes ``geometric_nonlinearity``) and the force of the element's
        distributed axial load. Midpoints are at ``stations(link)[:-1] + L_e / 2``.
        """
        return self._forces(link, 2)[1][..., 1]

    def bending_moment(self, link: str, per_element: int = 1) -> np.ndarray:
        """Bending moment ``EI v''`` at the link's stations (n, n_el per_element + 1) [N m].

        By element equilibrium (:mod:`kedfem.analysis.recovery`): the curvature of the
        nodal displacements' interpolation plus the moment of each element's
        distributed loads (rigid-body and elastic inertia, gravity, the
        axial force on the deflection) with its ends clamped; at a node the
        mean of the two elements meeting there. ``per_element`` stations per
        element (:meth:`stations`).
        """
        return _on_stations(self._forces(self._link(link).name, _per_element(per_element))[0])

    def dof_accelerations(self) -> np.ndarray:
        """Elastic DOF accelerations (n, N) [m/s^2, rad/s^2] at the result's instants, from the
        scheme's dense output (computed once)."""
        acc = self._cache.get("acceleration")
        if acc is None:
            acc = self._cache["acceleration"] = self.sampler.acceleration(self.t)
        return acc

    def section_forces(self, link: str, per_element: int = 1, sides: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Axial force ``N`` [N] (tension positive) and bending moment ``M = EI v''`` [N m] at the
        link's stations, each (n, n_el per_element + 1), by element equilibrium (nodes averaged).

        The axial force here is at the stations; :meth:`axial_force` gives it at the element
        midpoints. At a joint the link passes through (``through=``) the pin's force steps
        them: the mean of the two sides, or with ``sides=True`` both (the stations of
        ``stations(link, per_element, sides=True)``).
        """
        lk = self._link(link)
        M, N = self._forces(lk.name, _per_element(per_element))
        return _on_stations(N, lk.inner_nodes, sides=sides), _on_stations(M, lk.inner_nodes, sides=sides)

    def stress(self, link: str, per_element: int = 1) -> np.ndarray:
        """Largest absolute normal stress ``|N|/A + |M| c / I`` at the stations (n, n_el per_element + 1) [Pa].

        ``M`` and ``N`` by element equilibrium (:meth:`bending_moment`).
        Needs the section's extreme-fibre distance ``c``.
        """
        lk = self._link(link)
        sec = lk.section
        if sec.c is None:
            raise InputError(f"link '{link}': its section has no extreme-fibre distance c, "
                             "so the bending stress is unknown (give Section(..., c=...))")
        M, N = self._forces(lk.name, _per_element(per_element))
        return _on_stations(np.abs(N) / sec.A + np.abs(M) * sec.c / sec.I,
                            lk.inner_nodes, larger=True)
