"""A shaper: the Whitworth quick-return of the catalogue cutting on its forward stroke.

With the crank turning counter-clockwise the ram ``D`` runs along -x on the slow cutting stroke
(from ``x = link + lever`` to ``link - lever``) and back along +x on the quick return. The tool
is in the workpiece between ``cut_from`` and ``cut_to`` of the cutting stroke (fractions of it)
and only on that stroke: the cutting force ``cutting_force`` holds the ram back there, reached
over ``entry`` of travel as the tool enters and lost over as much as it leaves, along S-curves
(``Profile.position("D", (-1, 0), ..., stroke="forward", smooth=True)``: positions along -x, the
stroke that moves along it; a straight ramp's kinks would ring the crank's and the lever's modes
and cost thousands of time elements).

Run::

    python examples/shaper.py
    kedfem run examples/shaper.py:build --trust

Its hand check (drive torque and bearing forces of the rigid kinetostatics from the closed-form
quick-return and Newton-Euler in numpy) is in ``tests/test_process_loads.py``.
"""

from __future__ import annotations

import kedfem as kf
import mechanisms

DEFAULTS = dict(cutting_force=2000.0, cut_from=0.1, cut_to=0.9, entry=0.02)


def build(cutting_force: float = 2000.0, cut_from: float = 0.1, cut_to: float = 0.9, entry: float = 0.02,
          **whitworth) -> kf.Mechanism:
    """The shaper (see the module docstring).

    Parameters
    ----------
    cutting_force : float
        Force of the workpiece on the tool, against the cut [N].
    cut_from, cut_to : float
        Where the tool enters and leaves the workpiece, as fractions of the cutting stroke.
    entry : float
        Travel over which the force builds up and falls away [m] (a chamfered edge).
    **whitworth
        Parameters of ``mechanisms.build("whitworth", ...)`` (crank, offset, lever, link, ...).
    """
    m = mechanisms.build("whitworth", **whitworth)
    m.name = "shaper"
    p = {**mechanisms.get("whitworth").DEFAULTS, **whitworth}
    # the lever turns fully round: the ram's x runs between link - lever and link + lever; the
    # cutting stroke's positions along -x run from -(link + lever) to -(link - lever)
    start, stroke = -(p["link"] + p["lever"]), 2 * p["lever"]
    a, b = start + cut_from * stroke, start + cut_to * stroke
    if not (0.0 <= cut_from < cut_to <= 1.0 and 2 * entry < b - a):
        raise kf.InputError(f"shaper: need 0 <= cut_from < cut_to <= 1 and the cut longer than twice the entry "
                            f"({2 * entry} m), got cut_from={cut_from}, cut_to={cut_to}")
    m.load("cutting", "D", force=(cutting_force, 0.0),  # against the cut, along +x
           profile=kf.Profile.position("D", (-1.0, 0.0), [a, a + entry, b - entry, b], [0.0, 1.0, 1.0, 0.0],
                                       stroke="forward", smooth=True))
    return m


def main():
    scene = kf.Scene(build(), effects=("inertia", "coupling", "axial_stiffening", "gravity", "loads"),
                     damping=kf.ModalDamping(0.02))
    res = kf.solve(scene)
    print(res.summary())
    return res


if __name__ == "__main__":
    main()
