"""Mechanism definitions: each module has ``build(**params) -> kedfem.Mechanism``.

Each also declares what kedfem's scenes need to know of it (read through
:func:`kedfem.catalogue.info`): ``DEFAULTS`` (its parameters), ``PRESET`` (its
preset scene, a :class:`kedfem.catalogue.Preset`) and ``SIGNED_PARAMETERS``
(the parameters that may be negative).

``available()`` lists them; ``get(name)`` returns the module.
"""

from __future__ import annotations

import importlib

from kedfem.errors import InputError

__all__ = ["available", "get", "build"]

_NAMES = ("mould_oscillator", "slider_crank", "four_bar", "six_bar", "exciter", "whitworth",
          "inverted_slider_crank")


def available() -> tuple[str, ...]:
    """Names of the mechanisms shipped with kedfem that are importable."""
    out = []
    for n in _NAMES:
        try:
            importlib.import_module(f"mechanisms.{n}")
        except ModuleNotFoundError:
            continue
        out.append(n)
    return tuple(out)


def get(name: str):
    """The module of mechanism ``name`` (``-`` and ``_`` are interchangeable)."""
    key = str(name).replace("-", "_")
    if key not in available():
        raise InputError(f"unknown mechanism {name!r}; available: {', '.join(available())}")
    return importlib.import_module(f"mechanisms.{key}")


def build(name: str, **params):
    """Build mechanism ``name`` with keyword parameters."""
    return get(name).build(**params)
