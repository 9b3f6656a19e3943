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

from ...errors import InputError, did_you_mean
from ..damping import ModalDamping, Rayleigh
from .axial_stiffening import AxialStiffening
from .base import Effect
from .coupling import Coupling
from .geometric_nonlinearity import GeometricNonlinearity
from .gravity import Gravity
from .inertia import Inertia
from .loads import Loads
from .springs import Springs

__all__ = ["EFFECTS", "LINEAR_EFFECTS", "linear_effects", "declared_items", "default_effects", "unsimulated", "DEFAULT_ZETA", "Effect", "register_effect", "check_effects", "chosen", "Rayleigh",
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


def linear_effects(effects) -> tuple[str, ...]:
    """The effects with ``geometric_nonlinearity`` replaced by its linear part ``axial_stiffening``.

    The von Karman term stiffens the links by their actual axial forces, of which
    the kinetostatic ones (``axial_stiffening``) are what the rigid-body motion
    gives; the modal analysis and the linearised stability questions use those.
    """
    out = ["axial_stiffening" if e == "geometric_nonlinearity" else e for e in effects]
    return tuple(dict.fromkeys(out))


def declared_items(mech) -> dict[str, list[str]]:
    """The effects a mechanism's declared items need, with the items: ``"springs"`` (springs,
    torsional springs; a spring's preload named as such), ``"loads"`` (loads, friction),
    ``"gravity"`` (a gravity vector set with ``set_gravity``). Effects without items are left out."""
    out: dict[str, list[str]] = {}
    sp = [f"spring '{n}'" + (" (its preload)" if getattr(s, "preload", 0.0) else "") for n, s in mech.springs.items()]
    sp += [f"torsional spring '{n}'" + (" (its preload)" if getattr(s, "preload", 0.0) else "")
           for n, s in mech.torsional_springs.items()]
    if sp:
        out["springs"] = sp
    ld = [f"load '{n}'" for n in mech.loads] + [f"friction '{n}'" for n in mech.frictions]
    if ld:
        out["loads"] = ld
    if getattr(mech, "gravity_declared", False) and any(g != 0.0 for g in mech.gravity):  # (0, 0): none
        out["gravity"] = [f"gravity {tuple(mech.gravity)} m/s^2"]
    return out


def unsimulated(mech, effects) -> list[str]:
    """One message per declared item (:func:`declared_items`) that ``effects`` leave out."""
    out = []
    for effect, items in declared_items(mech).items():
        if effect not in effects:
            out += [f"{mech.name}: {item} is declared but the effects ({', '.join(effects)}) leave out "
                    f"'{effect}', so it is not simulated; add '{effect}' to the effects" for item in items]
    return out


def default_effects(mech) -> tuple[str, ...]:
    """The effects of a scene that names none (``kf.Scene(m)``, a builder file without a preset
    on the command line): the linear KED set (:data:`LINEAR_EFFECTS`) and those the mechanism's
    declared items need (:func:`declared_items`: its springs, loads and friction, a gravity set
    with ``set_gravity``)."""
    return LINEAR_EFFECTS + tuple(e for e in declared_items(mech) if e not in LINEAR_EFFECTS)


#: The damping of a scene that names none: 2 % of critical in every mode.
DEFAULT_ZETA = 0.02


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


def _entry_point(name: str) -> Effect | None:
    """The effect registered under ``name`` by an installed package (entry-point group
    ``kedfem.effects``: ``name = "package.module:object"``, an :class:`Effect` instance), or None."""
    from importlib.metadata import entry_points
    for ep in entry_points(group="kedfem.effects"):
        if ep.name == name:
            try:
                obj = ep.load()
            except Exception as e:  # an installed package that cannot be imported
                raise InputError(f"effect {name!r} (entry point {ep.value!r}) cannot be loaded: {e}") from None
            if isinstance(obj, type) and issubclass(obj, Effect):
                obj = obj()
            if not isinstance(obj, Effect) or obj.name != name:
                raise InputError(f"effect {name!r}: entry point {ep.value!r} is not an Effect named {name!r}")
            return register_effect(obj)
    return None


def check_effects(effects) -> tuple[str, ...]:
    """Validate effects; return their names as a tuple in registry order.

    Each item is a registered name, the name of an effect an installed package registers (entry
    point group ``kedfem.effects``), or an :class:`Effect` instance (registered here if its name is
    free). ``"all"`` (alone) stands for the built-in effects, as on the command line and in scene
    files.

    Raises
    ------
    InputError
        An unknown name (the message lists the known ones), an instance whose name another effect
        holds, or a repeat.
    """
    if isinstance(effects, str) and "," in effects:  # "inertia,coupling", as on the command line
        effects = tuple(e.strip() for e in effects.split(",") if e.strip())
    elif isinstance(effects, (str, Effect)):
        effects = tuple(e.name for e in _BUILT_IN) if effects == "all" else (effects,)
    try:
        items = list(effects)
    except TypeError:
        raise InputError(f"effects must be a sequence of names, got {effects!r}") from None
    names = []
    for e in items:
        if isinstance(e, Effect):
            if EFFECTS.get(e.name) is None:
                register_effect(e)
            elif EFFECTS[e.name] != e:
                raise InputError(f"effect {e!r}: the name {e.name!r} is registered for another effect "
                                 f"({EFFECTS[e.name]!r}); give this one a name of its own")
            e = e.name
        if not isinstance(e, str) or (e not in EFFECTS and _entry_point(e) is None):
            raise InputError(f"unknown effect {e!r}{did_you_mean(str(e), EFFECTS)}; known effects: "
                             f"{', '.join(EFFECTS)} (an effect of your own: pass the instance, or "
                             f"register_effect() it, or declare it in the entry-point group kedfem.effects)")
        names.append(e)
    if len(set(names)) != len(names):
        raise InputError(f"effects repeat: {names}")
    return tuple(n for n in EFFECTS if n in names)
