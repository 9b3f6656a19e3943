"""The mechanism catalogue: how kedfem finds a mechanism by name.

A mechanism is anything with ``build(**params) -> kedfem.Mechanism`` (a module,
or a function used as ``build``). Names come from, in this order:

1. ``register(name, obj)`` in this process (a module or a builder function);
2. the entry-point group ``kedfem.mechanisms`` of every installed distribution:
   ``name = "package.module"`` or ``"package.module:function"``. kedfem's own
   catalogue (the top-level ``mechanisms/`` package) is registered there in
   ``pyproject.toml``, and a user's package registers its linkages the same way;
3. a reference ``"package.module:function"`` or ``"path/to/file.py:function"``
   given as the name itself (CLI: ``kedfem run mylinks:hoekens``; scene files:
   ``[mechanism] builder = "mylinks:hoekens"``), imported from the Python path,
   else from the scene file's folder or the working folder (without adding
   either to ``sys.path``). A scene may name such code only where the user
   trusts it (:mod:`kedfem.trust`): that is checked on disk before anything is
   imported, and the builder found must be a Python function in trusted code.

A builder is called through :func:`call_builder`: the parameters are bound to
its signature first, and what it returns must be a :class:`kedfem.Mechanism`.

The core never imports the catalogue package by name: kedfem's own entries are
loaded from their files beside the ``kedfem`` package, so a user's folder that
happens to be called ``mechanisms/`` cannot shadow them.

What kedfem knows of a mechanism comes from the mechanism itself, through
:func:`info` (a :class:`MechanismInfo`): its parameters (``DEFAULTS``, else
the keyword defaults of ``build``), its preset scene (``PRESET``: a
:class:`Preset` or a mapping of its fields) and the parameters that may be
negative (``SIGNED_PARAMETERS``; a parameter whose default is negative is
signed too). ``PRESET`` and ``SIGNED_PARAMETERS`` are read from the module, or
from the builder function as attributes (``hoekens.PRESET = {"effects":
["inertia", "coupling", "axial_stiffening"]}``); a mechanism without them gets
``Preset()`` and only its negative defaults signed. Scene files, the command
line and sweeps ask this registry and name no mechanism.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import logging
import os
import re
import sys
import types
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from .errors import InputError, KedError, did_you_mean
from .fe.effects import DEFAULT_ZETA, ModalDamping
from .trust import Located, Trust, check as check_trust, check_function, locate
from .trust import import_module as import_located

__all__ = ["GROUP", "SOLVER_KEYS", "Preset", "MechanismInfo", "available", "get", "info", "build", "register",
           "call_builder",
           "is_reference", "is_file_reference", "canonical", "reference_of", "for_instance", "parameters"]

log = logging.getLogger(__name__)

#: The entry-point group mechanisms are registered in.
GROUP = "kedfem.mechanisms"
#: Solver arguments of a :class:`~kedfem.analysis.scene.Scene` a preset may set.
SOLVER_KEYS = ("eps", "max_iter", "nonlinear_method", "delta")

_REGISTERED: dict[str, object] = {}
_LOADED: dict[str, object] = {}
_INFO: dict[str, MechanismInfo] = {}


@dataclass(frozen=True)
class Preset:
    """The scene a mechanism's scenes start from: a scene file's keys win over it.

    Parameters
    ----------
    steps : int, optional
        Fixed number of time elements (None: as many as the tolerance needs).
    effects : tuple of str, optional
        Effects to assemble (``kedfem list``); default None, the scene's own default
        (:func:`kedfem.fe.effects.default_effects`): the linear KED set, rigid-body inertia, the
        rigid-elastic coupling and the links' stiffening by their kinetostatic axial forces
        (:data:`kedfem.fe.effects.LINEAR_EFFECTS`), and the effects the mechanism's declared
        springs, loads, friction and gravity need, as ``kf.Scene(m)``.
    damping : Rayleigh or ModalDamping or None
        Damping model (None: undamped).
    hold : str, optional
        One of the paper's exponential holds (None: the default method).
    solver : tuple of (str, value) pairs
        :class:`~kedfem.analysis.scene.Scene` solver arguments (:data:`SOLVER_KEYS`);
        a mapping is accepted.
    name : str, optional
        Scene name, a template formatted with the mechanism's parameters
        (``"mould oscillator, group {group}"``; None: the mechanism's own name).
    """

    steps: int | None = None
    effects: tuple[str, ...] | None = None
    damping: Any = field(default_factory=lambda: ModalDamping(DEFAULT_ZETA))
    hold: str | None = None
    solver: tuple[tuple[str, Any], ...] = ()
    name: str | None = None

    def __post_init__(self):
        effects = (self.effects,) if isinstance(self.effects, str) else self.effects
        if effects is not None:
            if not isinstance(effects, (tuple, list)) or not all(isinstance(e, str) for e in effects):
                raise InputError(f"Preset: effects must be effect names, got {self.effects!r}")
            object.__setattr__(self, "effects", tuple(effects))
        try:
            solver = tuple(dict(self.solver).items())
        except (TypeError, ValueError):
            raise InputError(f"Preset: solver must be a mapping of {', '.join(SOLVER_KEYS)}, "
                             f"got {self.solver!r}") from None
        for k, _ in solver:
            if k not in SOLVER_KEYS:
                raise InputError(f"Preset: unknown solver key {k!r}{did_you_mean(k, SOLVER_KEYS)}; "
                                 f"allowed: {', '.join(SOLVER_KEYS)}")
        object.__setattr__(self, "solver", solver)
        if self.name is not None and not isinstance(self.name, str):
            raise InputError(f"Preset: name must be a string template, got {self.name!r}")

    def scene_arguments(self) -> dict[str, Any]:
        """Keyword arguments of :class:`~kedfem.analysis.scene.Scene` (all but the mechanism and name)."""
        return dict(steps=self.steps, effects=self.effects, damping=self.damping, hold=self.hold,
                    **dict(self.solver))


@dataclass(frozen=True, eq=False)
class MechanismInfo:
    """A catalogue entry: a mechanism's builder and what scenes need to know of it.

    Attributes
    ----------
    name : str
        Catalogue name (or ``"package.module:function"`` reference).
    source : object
        The module (or a module-like wrapper of a builder function).
    build : callable
        ``build(**params) -> kedfem.Mechanism``.
    parameters : dict
        Parameter name -> default (see :func:`parameters`).
    signed : frozenset of str
        Parameters that may be negative; every other numeric parameter must be >= 0.
    preset : Preset
        The mechanism's preset scene.
    """

    name: str
    source: object
    build: Callable
    parameters: dict = field(default_factory=dict)
    signed: frozenset = frozenset()
    preset: Preset = Preset()

    @property
    def summary(self) -> str:
        """First line of the builder's docstring."""
        doc = (inspect.getdoc(self.build) or "").splitlines()
        return doc[0] if doc else ""

    def scene_name(self, params: Mapping[str, Any], mech) -> str:
        """Name of the scene of ``mech`` built with ``params`` (the preset's template, else the mechanism's)."""
        if self.preset.name is None:
            return mech.name
        try:
            return self.preset.name.format_map({**self.parameters, **params})
        except (KeyError, IndexError, ValueError, TypeError) as e:
            log.warning("mechanism %s: preset name %r does not format with %r (%s); using %r", self.name,
                        self.preset.name, dict(params), e, mech.name)
            return mech.name

    def make(self, **params):
        """The mechanism built with keyword ``params``, checked (:func:`call_builder`).

        Returns
        -------
        kedfem.Mechanism
        """
        return call_builder(self.name, self.build, params)

    def scene(self, params: Mapping[str, Any] | None = None, **scene_args):
        """The preset scene of the mechanism built with ``params``.

        Parameters
        ----------
        params : mapping, optional
            Mechanism parameters (SI units).
        **scene_args
            :class:`~kedfem.analysis.scene.Scene` arguments that replace the preset's.

        Returns
        -------
        Scene
        """
        from .analysis.scene import Scene
        params = dict(params or {})
        mech = self.make(**params)
        kw = dict(self.preset.scene_arguments(), name=self.scene_name(params, mech))
        kw.update(scene_args)
        return Scene(mech, **kw)


def canonical(name: str, base_dir=None) -> str:
    """The canonical key of a name: catalogue names with ``_``; a file reference with its path
    made absolute (relative to ``base_dir``, else the working folder)."""
    name = str(name).strip()
    if is_file_reference(name):
        path, _, fn = name.rpartition(":")
        p = Path(path).expanduser()
        if not p.is_absolute():
            p = Path(base_dir or os.getcwd()) / p
        return f"{p.resolve()}:{fn}"
    return name if is_reference(name) else name.replace("-", "_")


def is_file_reference(name: str) -> bool:
    """``"path/to/my_linkage.py:build"`` (a builder in a Python file)."""
    path, sep, fn = str(name).rpartition(":")
    return bool(sep) and path.endswith(".py") and fn.isidentifier()


def is_reference(name: str) -> bool:
    """``"package.module:function"`` or ``"path/to/file.py:function"`` (a builder named by where it lives)."""
    if is_file_reference(name):
        return True
    mod, sep, fn = str(name).partition(":")
    return bool(sep) and bool(mod) and bool(fn) and all(p.isidentifier() for p in mod.split(".")) \
        and fn.isidentifier()


def reference_of(builder) -> str:
    """A reference string to a builder function that other processes can load.

    ``"package.module:function"`` when its module can be imported by name, else
    ``"/abs/path/file.py:function"`` (a function in a script or a file loaded by path).

    Raises
    ------
    InputError
        A lambda, a nested function or a callable without a module or file.
    """
    qual = getattr(builder, "__qualname__", "")
    if not callable(builder) or not qual.isidentifier():
        raise InputError(f"builder {builder!r}: give a module-level function (a lambda or a nested function "
                         "cannot be found by the sweep's worker processes), or 'module:function'")
    mod = getattr(builder, "__module__", None) or ""
    if mod and mod != "__main__" and not mod.startswith(_USER_PREFIX):
        try:
            if importlib.util.find_spec(mod) is not None:
                return f"{mod}:{qual}"
        except (ImportError, ValueError):
            pass
    try:
        path = inspect.getsourcefile(builder)
    except TypeError:
        path = None
    if not path:
        raise InputError(f"builder {builder!r}: its module {mod!r} cannot be imported and it has no file")
    return f"{Path(path).resolve()}:{qual}"


def _entry_points() -> dict:
    out = {}
    for ep in entry_points(group=GROUP):
        out.setdefault(ep.name.replace("-", "_"), ep)
    return out


def available() -> tuple[str, ...]:
    """Names of the registered mechanisms (entry points and :func:`register`), sorted."""
    return tuple(sorted(set(_entry_points()) | set(_REGISTERED)))


def register(name: str, obj) -> None:
    """Make ``obj`` (a module with ``build``, or a builder function) known as ``name`` in this process.

    Sweep workers are other processes: for sweeps, register by entry point or
    name the builder as ``"package.module:function"``. ``PRESET`` and
    ``SIGNED_PARAMETERS`` of ``obj`` (or of its ``build``) are read as for
    any mechanism (see the module docstring).
    """
    key = canonical(name)
    if not key.isidentifier():
        raise InputError(f"catalogue: a mechanism name must be an identifier, got {name!r}")
    _REGISTERED[key] = _as_mechanism(obj, key)
    _LOADED.pop(key, None)
    _INFO.pop(key, None)


def _as_mechanism(obj, name: str):
    """A module-like object with ``build`` (a function is wrapped)."""
    if isinstance(obj, types.ModuleType) or hasattr(obj, "build"):
        if not callable(getattr(obj, "build", None)):
            raise InputError(f"mechanism {name!r}: {getattr(obj, '__name__', obj)!r} has no build(**params) "
                             "function")
        return obj
    if callable(obj):
        return types.SimpleNamespace(build=obj, __doc__=inspect.getdoc(obj) or "",
                                     __name__=getattr(obj, "__qualname__", name))
    raise InputError(f"mechanism {name!r}: {obj!r} is neither a module with build() nor a builder function")


def _shipped_file(module: str) -> Path | None:
    """The file of a module of kedfem's own catalogue, beside the ``kedfem`` package."""
    root = Path(__file__).resolve().parent.parent
    path = root.joinpath(*module.split(".")).with_suffix(".py")
    return path if path.is_file() else None


def _load_file(module: str, path: Path, qual: str | None = None):
    qual = qual or f"kedfem._catalogue.{module}"
    if qual in sys.modules:
        return sys.modules[qual]
    spec = importlib.util.spec_from_file_location(qual, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[qual] = mod
    try:
        spec.loader.exec_module(mod)
    except BaseException:
        sys.modules.pop(qual, None)
        raise
    return mod


def _load_entry(name: str, ep):
    module, _, attr = ep.value.partition(":")
    dist = getattr(getattr(ep, "dist", None), "name", None)
    path = _shipped_file(module.strip()) if dist in (None, "kedfem") else None
    try:
        mod = _load_file(module.strip(), path) if path is not None else importlib.import_module(module.strip())
    except KeyboardInterrupt:
        raise
    except BaseException as e:  # noqa: BLE001 - an installed mechanism that fails (or exits) on import
        raise InputError(f"mechanism {name!r} (entry point {ep.value!r}) cannot be imported: {_what(e)}") from None
    obj = getattr(mod, attr.strip()) if attr.strip() else mod
    return _as_mechanism(obj, name)


_USER_PREFIX = "kedfem_user_"


def _search_folders(base_dir, trust: Trust) -> tuple[str, ...]:
    """Folders a module reference is looked up in when it is not on the Python path."""
    folders = [str(Path(d).resolve()) for d in (base_dir, os.getcwd()) if d is not None]
    return tuple(dict.fromkeys(folders + list(trust.search)))


def _locate_checked(key: str, base_dir, trust: Trust):
    """Find a reference's code on disk, refuse it unless ``trust`` covers it (nothing is run)."""
    target, _, _ = key.rpartition(":")
    if is_file_reference(key):
        if not Path(target).is_file():
            raise InputError(f"mechanism {key!r}: no file {target}")
        check_trust(key, trust)
        return None
    folders = _search_folders(base_dir, trust)
    located = locate(target, folders)
    if located is not None and located.folder is None:
        top = target.split(".")[0]
        shadowed = [Path(f) / (top + ".py") for f in folders if (Path(f) / (top + ".py")).is_file()]
        shadowed += [Path(f) / top for f in folders if (Path(f) / top / "__init__.py").is_file()]
        origin = located.files[0] if located.files else None
        shadowed = [s for s in shadowed if origin is None or s.resolve() not in (origin, origin.parent)]
        if shadowed:
            raise InputError(f"mechanism {key!r}: {shadowed[0]} is shadowed by the module {top!r} of the Python path "
                             f"({origin or 'built in'}): name your builder by its file, "
                             f"'{shadowed[0].name if shadowed[0].suffix else shadowed[0].name + '/...'}:"
                             f"{key.rpartition(':')[2]}', or rename it")
    check_trust(key, trust, located=located)
    if located is None:
        where = " or ".join(_search_folders(base_dir, trust))
        raise InputError(f"mechanism {key!r}: no module {target!r} on the Python path or in {where}")
    return located


def _load_reference(name: str, located: Located | None, trust: Trust):
    """Import a checked reference (``sys.path`` untouched) and return its builder."""
    target, _, attr = name.rpartition(":")
    try:
        if located is None:  # a file
            p = Path(target)
            qual = _USER_PREFIX + re.sub(r"\W", "_", p.stem) + "_" + hashlib.sha1(str(p).encode()).hexdigest()[:8]
            mod = _load_file(qual, p, qual=qual)
        else:
            mod = import_located(located)
    except KeyboardInterrupt:
        raise
    except KedError as e:
        raise InputError(f"mechanism {name!r}: importing {target} failed: {e}") from None
    except BaseException as e:  # noqa: BLE001 - the user's module failed (or exited) on import: say so
        raise InputError(f"mechanism {name!r}: importing {target} failed: {_what(e)}") from None
    fn = getattr(mod, attr, None)
    if fn is None:
        raise InputError(f"mechanism {name!r}: {target!r} has no {attr!r}")
    check_function(name, fn, trust)
    return _as_mechanism(fn, name)


def _what(e: BaseException) -> str:
    """An exception as a message (``sys.exit`` named as such)."""
    if isinstance(e, SystemExit):
        return f"it called sys.exit({e.code!r})"
    return f"{type(e).__name__}: {e}"


def call_builder(name: str, build: Callable, params: Mapping[str, Any]):
    """Call a mechanism's builder with keyword ``params`` and check that it built a Mechanism.

    Before the call, the parameters are bound to the builder's signature (a missing or unknown
    parameter is named without running it) and a return annotation other than ``Mechanism`` is
    refused; a ``sys.exit`` inside the builder, or a return value that is not a
    :class:`kedfem.Mechanism`, is an :class:`InputError` naming the builder.

    Raises
    ------
    InputError
        Parameters that do not fit the signature, an exit, or a result that is not a Mechanism.
    KedError, Exception
        What the builder itself raises on its values (passed on).
    """
    from .model.mechanism import Mechanism
    try:
        sig = inspect.signature(build)
    except (TypeError, ValueError):
        sig = None
    if sig is not None:
        ret = sig.return_annotation
        if ret is not inspect.Signature.empty and ret is not Mechanism and \
                not (isinstance(ret, str) and ret.replace(" ", "").split(".")[-1] == "Mechanism"):
            raise InputError(f"mechanism {name!r}: the builder is declared to return {ret!r}, not a "
                             "kedfem.Mechanism; it is not called")
        try:
            sig.bind(**params)
        except TypeError as e:
            raise InputError(f"mechanism {name!r}: its builder cannot take these parameters ({e})") from None
    try:
        out = build(**params)
    except (KeyboardInterrupt, Exception):
        raise
    except BaseException as e:  # noqa: BLE001 - SystemExit, GeneratorExit in the user's builder
        raise InputError(f"mechanism {name!r}: the builder did not build ({_what(e)})") from None
    if not isinstance(out, Mechanism):
        raise InputError(f"mechanism {name!r}: the builder must return a kedfem.Mechanism, it returned "
                         f"{type(out).__name__} {_short_repr(out)}")
    return out


def _short_repr(v) -> str:
    r = repr(v)
    return r if len(r) <= 60 else r[:57] + "..."


def parameters(source) -> dict[str, Any]:
    """Parameters (name -> default) a mechanism's ``build`` accepts.

    ``DEFAULTS`` when ``source`` (a module with ``build``) has it, else the
    keyword defaults of ``build``.
    """
    d = getattr(source, "DEFAULTS", None)
    if isinstance(d, Mapping):
        return dict(d)
    out = {}
    for p in inspect.signature(source.build).parameters.values():
        if p.default is not inspect.Parameter.empty:
            out[p.name] = p.default
    return out


def _declared(source, attr: str):
    """``attr`` of a mechanism module, else of its builder function (None: not declared)."""
    v = getattr(source, attr, None)
    return getattr(source.build, attr, None) if v is None else v


def _negative(v) -> bool:
    if isinstance(v, (tuple, list)):
        return any(_negative(x) for x in v)
    return isinstance(v, (int, float)) and not isinstance(v, bool) and v < 0


def _info(name: str, source) -> MechanismInfo:
    params = parameters(source)
    pre = _declared(source, "PRESET")
    if pre is None:
        pre = Preset()
    elif isinstance(pre, Mapping):
        known = [f.name for f in fields(Preset)]
        for k in pre:
            if k not in known:
                raise InputError(f"mechanism {name!r}: PRESET has an unknown key {k!r}{did_you_mean(k, known)}; "
                                 f"allowed: {', '.join(known)}")
        pre = Preset(**pre)
    elif not isinstance(pre, Preset):
        raise InputError(f"mechanism {name!r}: PRESET must be a kedfem.catalogue.Preset or a mapping of its "
                         f"fields, got {pre!r}")
    signed = _declared(source, "SIGNED_PARAMETERS") or ()
    signed = (signed,) if isinstance(signed, str) else tuple(signed)
    for k in signed:
        if k not in params:
            raise InputError(f"mechanism {name!r}: SIGNED_PARAMETERS names {k!r}, not one of its parameters"
                             f"{did_you_mean(str(k), params)}; parameters: {', '.join(params)}")
    if pre.name is not None:
        try:
            pre.name.format_map(params)
        except (KeyError, IndexError, ValueError) as e:
            raise InputError(f"mechanism {name!r}: the preset's name {pre.name!r} is not a template of its "
                             f"parameters ({type(e).__name__}: {e})") from None
    signed = frozenset(signed) | {k for k, v in params.items() if _negative(v)}
    return MechanismInfo(name, source, source.build, params, signed, pre)


def for_instance(mech) -> MechanismInfo:
    """A catalogue entry for a built :class:`kedfem.Mechanism` (no parameters, the default preset).

    Scenes and sweeps of a mechanism object can vary the scene (speed, damping, solver), not the
    mechanism's parameters: for those, give its builder.
    """
    def build(**params):
        if params:
            raise InputError(f"mechanism {mech.name!r} is a built Mechanism object: it has no parameters "
                             f"({', '.join(params)}); give its builder function to vary them")
        return mech
    build.__doc__ = f"The built mechanism {mech.name!r}."
    return MechanismInfo(mech.name, types.SimpleNamespace(build=build), build, {}, frozenset(), Preset())


def info(name: str, base_dir=None, *, trust: Trust | None = None) -> MechanismInfo:
    """The catalogue entry of mechanism ``name`` (see :func:`get` for the names, ``base_dir`` and
    ``trust``).

    Raises
    ------
    InputError
        For an unknown name, one that cannot be loaded, or a mechanism whose
        ``PRESET`` or ``SIGNED_PARAMETERS`` is malformed.
    """
    source = get(name, base_dir, trust=trust)
    key = canonical(name, base_dir)
    entry = _INFO.get(key)
    if entry is None or entry.source is not source:
        entry = _INFO[key] = _info(key, source)
    return entry


def get(name: str, base_dir=None, *, trust: Trust | None = None):
    """The mechanism ``name``: an object with ``build(**params)`` (and ``DEFAULTS`` if it has them).

    Parameters
    ----------
    name : str
        A registered name (entry points, :func:`register`), ``"package.module:function"`` or
        ``"path/to/file.py:function"``.
    base_dir : path, optional
        Folder a relative file path is relative to, and searched for a module that is not on the
        Python path (a scene file's folder); the working folder is searched too. ``sys.path`` is
        never changed.
    trust : kedfem.trust.Trust, optional
        The code a reference may run (see :mod:`kedfem.trust`): scenes pass the user's trust;
        None (a call from Python, which runs code anyway) trusts everything.

    Raises
    ------
    InputError
        For an unknown name (listing the known ones) or one that cannot be loaded.
    UntrustedCodeError
        A reference to code that ``trust`` does not cover (checked before anything is imported).
    """
    key = canonical(name, base_dir)
    trust = Trust(everything=True) if trust is None else trust
    located = None
    if key not in _REGISTERED and is_reference(key):
        located = _locate_checked(key, base_dir, trust)  # before the cache: trust is per call
    if key in _LOADED:
        if is_reference(key):
            check_function(key, getattr(_LOADED[key], "build", None), trust)
        return _LOADED[key]
    if key in _REGISTERED:
        out = _REGISTERED[key]
    elif is_reference(key):
        out = _load_reference(key, located, trust)
    else:
        eps = _entry_points()
        if key not in eps:
            raise InputError(f"unknown mechanism {name!r}{did_you_mean(key, available())}; available: "
                             f"{', '.join(available())}, or 'package.module:function' or 'my_file.py:function' "
                             "for a builder of your own")
        out = _load_entry(key, eps[key])
    _LOADED[key] = out
    return out


def build(name: str, **params):
    """Build mechanism ``name`` with keyword parameters (see :func:`call_builder`).

    Returns
    -------
    kedfem.Mechanism
    """
    return call_builder(canonical(name), get(name).build, params)
