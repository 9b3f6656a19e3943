"""The crank angle's convention, named in every output that shows crank angles.

A driven link's crank angle is its absolute angle (its ``a -> b`` line from +x, counter-clockwise);
a driven body's is its rotation from the drawing (a body has no line of its own). Results,
tables and figures carry the one of their mechanism; these helpers say which in words.
"""

from __future__ import annotations

__all__ = ["crank_angle_convention", "crank_angle_label"]


def crank_angle_convention(mech) -> str:
    """What the crank angles of a mechanism's results are, in words.

    Parameters
    ----------
    mech : Mechanism

    Returns
    -------
    str
        A driven link's absolute angle (its ``a -> b`` line from +x), or a driven body's
        rotation from the drawing, naming the crank; ``"none (no drive)"`` without a drive.
    """
    if not mech.drives:
        return "none (no drive)"
    d = mech.drives[0]
    if d.member in mech.links:
        lk = mech.links[d.member]
        return f"of the crank '{d.member}', absolute (its {lk.a} -> {lk.b} line from +x, counter-clockwise)"
    return f"of the crank '{d.member}', its rotation from the drawing (counter-clockwise)"


def crank_angle_label(mech=None) -> str:
    """An axis label for crank angles in degrees that names the convention.

    Parameters
    ----------
    mech : Mechanism, optional

    Returns
    -------
    str
        ``"crank angle [deg] ('c', absolute)"`` for a driven link ``c``, ``"crank angle [deg]
        ('c', rotation from the drawing)"`` for a driven body; ``"crank angle [deg]"`` without a
        mechanism or a drive.
    """
    if mech is None or not mech.drives:
        return "crank angle [deg]"
    d = mech.drives[0]
    if d.member in mech.links:
        return f"crank angle [deg] ('{d.member}', absolute)"
    return f"crank angle [deg] ('{d.member}', rotation from the drawing)"
