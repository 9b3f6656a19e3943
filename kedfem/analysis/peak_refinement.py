"""The refinement of a result's peaks between its output instants and its stations: local fine
grids in time around the largest local maxima, then finer stations along the link at each stress
peak's instant (:class:`PeakRefinement`, a part of :class:`kedfem.analysis.results.PeriodicResult`)."""

from __future__ import annotations

import numpy as np

from .peak_search import grid_peak as _grid_peak, parabolic_vertex as _vertex

#: stations per element where peak stresses are sought (with a parabolic vertex between them)
PEAK_STATIONS = 8


class PeakRefinement:
    """The peak refinement of :class:`kedfem.analysis.results.PeriodicResult` (a mixin: it reads the
    result again through :meth:`~kedfem.analysis.results.PeriodicResult.resample`)."""

    def _polish_stations(self, links, series, best, sub: int = 8):
        """At each stress peak's instant, the peak along the link on stations ``sub`` times finer.

        The vertex through three of :data:`PEAK_STATIONS` stations per element
        is within about 1e-5 of the peak; on ``sub`` times finer stations it is
        within 1e-8. The value replaces the one of the refinement in time.
        """
        idx = [si for si, (_i, kind, _v) in enumerate(series) if kind == "stress"]
        if not idx:
            return best
        period = self.scene.period
        one = self.resample(np.mod([best[si][1] for si in idx], period))
        out = dict(best)
        for r, si in enumerate(idx):
            lk = links[series[si][0]]
            vals = one.stress(lk.name, per_element=PEAK_STATIONS * sub)[r]
            j = int(np.argmax(vals))
            v, dj = _vertex(vals, j)
            if {j - 1, j, j + 1} & {i * PEAK_STATIONS * sub for i in lk.inner_nodes}:
                v, dj = float(vals[j]), 0.0  # the stress steps at a pin the link passes: no parabola across
            # an evaluation at the instant's vertex (the vertices in time and along the link
            # added together over-shoot a peak on a ridge that is not along the axes)
            station = (j + dj) / sub
            h = lk.length / (lk.elements * PEAK_STATIONS * sub)
            if self._blocks_on(lk):
                s_, x = (float(a[r]) for a in one.block_stress(lk.name))
                # the stress is kinked under a block: no parabola there, the apex itself
                if abs(x - j * h) <= 2.0 * h:
                    v, station = max((float(vals[j]), j / sub), (s_, x / (h * sub)))
            out[si] = (v, best[si][1], station)
        return out

    def _refine_peaks(self, links, series, best, candidates: int = 2, sub: int = 8):
        """Refine grid peaks on local fine grids around the largest local maxima."""
        period = self.scene.period
        t = self.t
        n = t.size
        windows = []  # (series index, window centre on the grid)
        for si, (i, kind, vals) in enumerate(series):
            flat = vals if vals.ndim == 1 else vals.max(axis=1)
            loc = np.flatnonzero((flat >= np.roll(flat, 1)) & (flat >= np.roll(flat, -1)))
            loc = loc[np.argsort(-flat[loc])][:candidates]
            windows.extend((si, int(k)) for k in loc)
        if not windows:
            return best
        # a link's deflection and stress (and neighbouring links) often peak at the same instant:
        # each window centre is read once
        centres = sorted({k for _si, k in windows})
        where = {k: r for r, k in enumerate(centres)}
        m = 2 * sub + 1
        tw_all = np.array([np.linspace(t[k - 1] if k > 0 else t[-1] - period,
                                       t[k + 1] if k + 1 < n else t[0] + period, m) for k in centres])
        fine = self.resample(np.mod(tw_all.ravel(), period))
        cache = {}
        for si, (i, kind, vals) in enumerate(series):
            name = links[i].name
            cache[si] = (fine._peak_deflection(links[i]) if kind == "deflection"
                         else fine.block_stress(name)[0] if kind == "block"
                         else fine.stress(name, per_element=PEAK_STATIONS))
        out = dict(best)
        for si, k in windows:
            r = where[k]
            tw = tw_all[r]
            vals = cache[si][r * m:(r + 1) * m]
            v, tt, j = _grid_peak(vals, tw)
            if v > out[si][0]:
                out[si] = (v, float(np.mod(tt, period)), j)
        return out
