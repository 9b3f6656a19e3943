"""Physical effects a scene can ask for: one module per effect, and their registry.

The structure is always assembled (:mod:`kedfem.fe.structure`): beam mass and
stiffness, rigid-member and point masses, the linear stiffness of declared
springs and drive shafts. Each *effect* adds terms on top (docs/theory.md
sections 2-3); an effect not named is never evaluated:

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

Adding an effect is adding a file: subclass :class:`Effect` (the hooks are in
:mod:`kedfem.fe.effects.base`) and add a line to ``_BUILT_IN`` below, or call
:func:`register_effect` from your own package. ``joint_torque.py`` is the
worked example.
"""

from __future__ import annotations

from ...errors import InputError
from ..damping import ModalDamping, Rayleigh
from .axial_stiffening import AxialStiffening
from .base import Effect
from .coupling import Coupling
from .geometric_nonlinearity import GeometricNonlinearity
from .gravity import Gravity
from .inertia import Inertia
from .loads import Loads
from .springs import Springs

__all__ = ["EFFECTS", "LINEAR_EFFECTS", "Effect", "register_effect", "check_effects", "chosen", "Rayleigh",
           "ModalDamping"]

_BUILT_IN = (
    Inertia(),
    Coupling(),
    AxialStiffening(),
    GeometricNonlinearity(),
    Gravity(),
    Springs(),
    Loads(),
)

#: Every effect a scene can name, by name, in the order they are assembled.
EFFECTS: dict[str, Effect] = {e.name: e for e in _BUILT_IN}

#: The linear KED effect set: rigid-body inertia, the rigid-elastic coupling and the links'
#: stiffening by their kinetostatic axial forces.
LINEAR_EFFECTS = ("inertia", "coupling", "axial_stiffening")


def register_effect(effect: Effect) -> Effect:
    """Add an effect to the registry under ``effect.name``, so that scenes and scene files can name it.

    Parameters
    ----------
    effect : Effect
        An instance of an :class:`Effect` subclass that overrides at least one hook.

    Returns
    -------
    Effect
        ``effect``.

    Raises
    ------
    InputError
        Not an effect with hooks of its own, a name that is not an identifier, or a name taken.
    """
    if not isinstance(effect, Effect) or not effect.has_own_terms():
        raise InputError(f"register_effect: {effect!r} is not an Effect with its own terms (it overrides no hook)")
    if not (isinstance(effect.name, str) and effect.name.isidentifier()):
        raise InputError(f"register_effect: the name must be an identifier, got {effect.name!r}")
    if effect.name in EFFECTS:
        raise InputError(f"register_effect: an effect {effect.name!r} is already registered")
    EFFECTS[effect.name] = effect
    return effect


def chosen(names) -> tuple[Effect, ...]:
    """The registered effects named ``names`` (validated with :func:`check_effects`), in registry order."""
    return tuple(EFFECTS[n] for n in check_effects(names))


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
