"""A result's elastic displacements of its links and joints: the deflection at a point of a link, the
stretches' mid-span deflections, the nodes' rigid-body positions and elastic displacements, and the
joints' (:class:`Displacements`, a part of :class:`kedfem.analysis.results.PeriodicResult`)."""

from __future__ import annotations

import numpy as np

from ..model import elements as el
from ..checks import choice, name, real
from ..errors import InputError


class Displacements:
    """The displacement read-outs of :class:`kedfem.analysis.results.PeriodicResult` (a mixin: it
    reads the result's ``U``, ``motion`` and ``model``, and its local element DOFs)."""

    # ------------------------------------------------------------ deflection
    def deflection(self, link: str, xi: float = 0.5, relative_to: str = "frame") -> np.ndarray:
        """Transverse elastic deflection at fraction ``xi`` of a link's length.

        Parameters
        ----------
        link : str
            Flexible link.
        xi : float
            Position as a fraction of the length from joint ``a`` (0..1).
        relative_to : {"frame", "chord"}
            ``"frame"``: in the link's rigid-body frame (+y is the ``a -> b``
            direction turned +90 deg); ``"chord"``: relative to the chord
            through the deflected end points.

        Returns
        -------
        ndarray, shape (n,)
            Deflection [m] over the cycle.
        """
        lk = self._link(link)
        xi = real("deflection", "xi", xi)
        if not (0.0 <= xi <= 1.0):
            raise InputError(f"deflection: xi must lie in [0, 1], got {xi!r}")
        choice("deflection", "relative_to", relative_to, ("frame", "chord"))
        d = self._local(link)
        ne = lk.elements
        if lk.through:
            e = int(min(max(np.searchsorted(lk.nodes, xi * lk.length, side="right") - 1, 0), ne - 1))
            Le = float(lk.element_lengths[e])
            xe = (xi * lk.length - lk.nodes[e]) / Le
        else:
            e = min(int(xi * ne), ne - 1)
            xe = xi * ne - e
            Le = lk.length / ne
        N = el.shape_functions(Le, [xe])[0, 0]  # (2, 6)
        v = d[:, e] @ N[1]
        if relative_to == "chord" and lk.through:  # the chord of the stretch between the pins around it
            x = xi * lk.length
            cuts = lk.cuts
            k = int(min(np.searchsorted(cuts, x, side="right") - 1, len(cuts) - 2))
            f, c, _le = lk.segments()[k]
            u = (x - cuts[k]) / (cuts[k + 1] - cuts[k])
            v = v - ((1 - u) * d[:, f, 1] + u * d[:, f + c - 1, 4])
        elif relative_to == "chord":
            va = d[:, 0, 1]
            vb = d[:, -1, 4]
            v = v - ((1 - xi) * va + xi * vb)
        return v

    def stretch_deflections(self, link: str) -> np.ndarray:
        """Mid-span deflection of each stretch of a link relative to its chord, (n, n_stretches) [m].

        The stretches run between the link's ends and the joints it passes through
        (``through=``; their joints: ``Link.stretches``); a link without them is one stretch,
        its :meth:`deflection` at ``xi = 0.5`` relative to the chord.
        """
        lk = self._link(link)
        cuts = lk.cuts
        return np.stack([self.deflection(lk.name, 0.5 * (cuts[k] + cuts[k + 1]) / lk.length, relative_to="chord")
                         for k in range(len(cuts) - 1)], axis=-1)

    def _mid_deflections(self, lk) -> np.ndarray:
        """:meth:`stretch_deflections`, (n,) for a link of one stretch."""
        return self.deflection(lk.name, 0.5, relative_to="chord") if not lk.through \
            else self.stretch_deflections(lk.name)

    def _peak_deflection(self, lk) -> np.ndarray:
        """``|mid-span deflection relative to the chord|`` (n,), the largest of a link's stretches."""
        d = np.abs(self._mid_deflections(lk))
        return d if d.ndim == 1 else d.max(axis=-1)

    def link_geometry(self, link: str) -> np.ndarray:
        """Rigid-body positions (n, n_el + 1, 2) [m] of a flexible link's nodes over the cycle."""
        lk = self._link(link)
        a, b = np.array(self.model.mech.joints[lk.a].at), np.array(self.model.mech.joints[lk.b].at)
        e1 = (b - a) / lk.length
        r, _v, _a = self.motion.point(link, lk.a, self.stations(link)[:, None] * e1[None, :])
        return r

    def link_displacement(self, link: str, U: np.ndarray | None = None) -> np.ndarray:
        """Elastic displacement (n, n_el + 1, 2) [m] of a flexible link's nodes, global components.

        Includes prescribed parts (clamped ends on pins, passive-link stretch).
        With ``U`` (n, N) a different DOF history (e.g. a mode shape
        broadcast over time) is mapped instead of the response.
        """
        lk = self._link(link)
        sl = self.model.link_elements(link)
        gm = self._beam_map()
        own = U is None
        U = self.U if own else np.broadcast_to(np.asarray(U, float), self.U.shape)
        x = gm.apply(U, sl, offset=own)
        out = np.empty((self.n, lk.elements + 1, 2))
        out[:, :-1] = x[:, :, 0:2]
        out[:, -1] = x[:, -1, 3:5]
        return out

    def joint_displacement(self, joint: str, U: np.ndarray | None = None) -> np.ndarray:
        """Elastic displacement (n, 2) [m] of a joint (global components).

        With ``U`` (n, N) or (N,) a different DOF history (e.g. a mode shape)
        is mapped instead of the response.
        """
        forms = self._cache.get("forms")
        if forms is None:
            forms = self.model.entity_forms(self.motion)["P"]
            self._cache["forms"] = forms
        name("joint_displacement", "joint", joint, self.model.joint_point)
        cols, C, *_rest = forms[self.model.joint_point[joint]]
        if not cols:
            return np.zeros((self.n, 2))
        U = self.U if U is None else np.broadcast_to(np.asarray(U, float), self.U.shape)
        q = U[:, list(cols)]
        return np.einsum("tij,tj->ti", np.broadcast_to(C, (self.n,) + C.shape[1:]), q)
