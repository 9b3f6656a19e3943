"""The mechanism catalogue: how kedfem finds a mechanism by name.

A mechanism is anything with ``build(**params) -> kedfem.Mechanism`` (a module,
or a function used as ``build``). Names come from, in this order:

1. ``register(name, obj)`` in this process (a module or a builder function);
2. the entry-point group ``kedfem.mechanisms`` of every installed distribution:
   ``name = "package.module"`` or ``"package.module:function"``. kedfem's own
   catalogue (the top-level ``mechanisms/`` package) is registered there in
   ``pyproject.toml``, and a user's package registers its linkages the same way;
3. a reference ``"package.module:function"`` given as the name itself (scene
   files: ``[mechanism] name = "mylinks:hoekens"``; CLI: ``kedfem run
   mylinks:hoekens``), imported from ``sys.path`` and then the working folder.

The core never imports the catalogue package by name: kedfem's own entries are
loaded from their files beside the ``kedfem`` package, so a user's folder that
happens to be called ``mechanisms/`` cannot shadow them.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import os
import sys
import types
from importlib.metadata import entry_points
from pathlib import Path

from .errors import InputError, did_you_mean

__all__ = ["GROUP", "available", "get", "build", "register", "is_reference"]

#: The entry-point group mechanisms are registered in.
GROUP = "kedfem.mechanisms"

_REGISTERED: dict[str, object] = {}
_LOADED: dict[str, object] = {}


def _key(name: str) -> str:
    name = str(name).strip()
    return name if is_reference(name) else name.replace("-", "_")


def is_reference(name: str) -> bool:
    """``"package.module:function"`` (a builder named by where it lives)."""
    mod, sep, fn = str(name).partition(":")
    return bool(sep) and bool(mod) and bool(fn) and all(p.isidentifier() for p in mod.split(".")) \
        and fn.isidentifier()


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
    name the builder as ``"package.module:function"``.
    """
    key = _key(name)
    if not key.isidentifier():
        raise InputError(f"catalogue: a mechanism name must be an identifier, got {name!r}")
    _REGISTERED[key] = _as_mechanism(obj, key)
    _LOADED.pop(key, None)


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


def _load_file(module: str, path: Path):
    qual = f"kedfem._catalogue.{module}"
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
    except ImportError as e:
        raise InputError(f"mechanism {name!r} (entry point {ep.value!r}) cannot be imported: {e}") from None
    obj = getattr(mod, attr.strip()) if attr.strip() else mod
    return _as_mechanism(obj, name)


def _load_reference(name: str):
    module, _, attr = name.partition(":")
    try:
        mod = importlib.import_module(module)
    except ModuleNotFoundError as e:
        cwd = os.getcwd()
        if e.name != module.split(".")[0] or cwd in sys.path:
            raise InputError(f"mechanism {name!r}: cannot import {module!r}: {e}") from None
        sys.path.append(cwd)  # the console script does not search the working folder
        try:
            mod = importlib.import_module(module)
        except ModuleNotFoundError:
            raise InputError(f"mechanism {name!r}: no module {module!r} on the Python path or in {cwd}") from None
    fn = getattr(mod, attr, None)
    if fn is None:
        raise InputError(f"mechanism {name!r}: module {module!r} has no {attr!r}")
    return _as_mechanism(fn, name)


def get(name: str):
    """The mechanism ``name``: an object with ``build(**params)`` (and ``DEFAULTS`` if it has them).

    Raises
    ------
    InputError
        For an unknown name (listing the known ones) or one that cannot be loaded.
    """
    key = _key(name)
    if key in _LOADED:
        return _LOADED[key]
    if key in _REGISTERED:
        out = _REGISTERED[key]
    elif is_reference(key):
        out = _load_reference(key)
    else:
        eps = _entry_points()
        if key not in eps:
            raise InputError(f"unknown mechanism {name!r}{did_you_mean(key, available())}; available: {', '.join(available())}, or "
                             f"'package.module:function' for a builder of your own")
        out = _load_entry(key, eps[key])
    _LOADED[key] = out
    return out


def build(name: str, **params):
    """Build mechanism ``name`` with keyword parameters."""
    return get(name).build(**params)
