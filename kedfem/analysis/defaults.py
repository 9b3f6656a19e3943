"""The built-in default scene: the preset scene of the paper's mould oscillator.

The scene is defined once, by the mechanism itself (the ``PRESET`` of the
catalogue's ``mould_oscillator``: all its effects, 2 % modal damping, the
paper's fixed-point iteration to ``eps = 1e-6``, tolerance-driven time
elements). :func:`default_scene`, ``kedfem run`` without a scene and a scene
file with only ``[mechanism] name = "mould_oscillator"`` all build it from
there (:meth:`kedfem.catalogue.MechanismInfo.scene`, :func:`kedfem.io.scenefile.parse_scene`).
"""

from __future__ import annotations

from .scene import Scene

__all__ = ["DEFAULT_MECHANISM", "default_scene"]  # and MOULD_EFFECTS, resolved on first use

#: Catalogue name of the mechanism whose preset scene is the default scene.
DEFAULT_MECHANISM = "mould_oscillator"


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
        Other parameters of the mould oscillator (its ``DEFAULTS``).

    Returns
    -------
    Scene
        The mechanism's preset scene: all effects of :data:`MOULD_EFFECTS`, 2 %
        modal damping, the default time scheme, the paper's fixed-point
        iteration (Newton-like with the tangent terms) to ``eps = 1e-6``.
    """
    from ..catalogue import info
    scene_args = {} if steps is None else {"steps": steps}
    return info(DEFAULT_MECHANISM).scene(dict(group=group, **mechanism_params), **scene_args)


def __getattr__(name: str):
    # MOULD_EFFECTS: every effect the mould oscillator model declares, read from its
    # preset when first asked for (kept for the code that imports it from here)
    if name == "MOULD_EFFECTS":
        from ..catalogue import info
        return info(DEFAULT_MECHANISM).preset.effects
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
