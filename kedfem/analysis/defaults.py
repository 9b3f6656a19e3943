"""The built-in default scene: the paper's mould oscillator, group 1, nominal speed, all its effects."""

from __future__ import annotations

from ..fe.effects import ModalDamping
from .scene import Scene

__all__ = ["MOULD_EFFECTS", "default_scene"]

#: every effect the mould oscillator model declares
MOULD_EFFECTS = ("inertia", "coupling", "axial_stiffening", "geometric_nonlinearity", "gravity", "springs",
                 "loads")


def default_scene(group: int = 1, steps: int | None = None, **mechanism_params) -> Scene:
    """Mould oscillator (paper section 5) of crank group ``group`` at its nominal 150 cycles/min.

    Parameters
    ----------
    group : int
        Crank group 1..4 (paper Table 2).
    steps : int, optional
        Fixed number of time elements (default: as many as the scene's
        tolerance, 1e-3 on every link's peaks, needs).
    **mechanism_params
        Overrides of :data:`mechanisms.mould_oscillator.DEFAULTS`.

    Returns
    -------
    Scene
        All effects of :data:`MOULD_EFFECTS`, 2 % modal damping, the default
        time scheme, the paper's fixed-point iteration (Newton-like with the
        tangent terms) to ``eps = 1e-6``.
    """
    from ..catalogue import build
    mech = build("mould_oscillator", group=group, **mechanism_params)
    return Scene(mech, steps=steps, effects=MOULD_EFFECTS, damping=ModalDamping(0.02),
                 eps=1e-6, nonlinear_method="fixed-point", name=f"mould oscillator, group {group}")
