"""The io wing's writers and readers, as the analysis wing calls them without importing them.

A result is data; the io wing writes it. The analysis wing never imports the io wing
(``tests/test_layout.py``), so where a result offers to write itself (``PeriodicResult.write``,
``PeriodicResult.summary``, ``CampbellResult.to_csv`` / ``crossings_to_csv`` / ``plot``) or an
analysis takes a scene dictionary (``critical_speed``), it hands the work to the function the io
wing provided under that name. ``import kedfem`` provides them (the package's ``__init__``
wires the io wing's functions in, :func:`provide`); the same functions are public in
:mod:`kedfem.io` (``kedfem.io.report.write_result`` and the others).
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["NAMES", "provide", "hook"]

#: what the io wing provides: a result's folder and its summary text (:mod:`kedfem.io.report`),
#: a Campbell result's bands and crossings as CSV and its chart (:mod:`kedfem.io.design_plots`),
#: a scene from a scene file's dictionary (:mod:`kedfem.io.scenefile`)
NAMES = ("write_result", "format_summary", "campbell_csv", "crossings_csv", "campbell_chart",
         "scene_from_dict")

_PROVIDED: dict[str, Callable] = {}


def provide(**functions: Callable) -> None:
    """Register the io wing's functions by name (one of :data:`NAMES`).

    Raises
    ------
    ValueError
        For a name not in :data:`NAMES`, or a value that is not callable.
    """
    for name, fn in functions.items():
        if name not in NAMES:
            raise ValueError(f"hooks.provide: unknown name {name!r} (known: {', '.join(NAMES)})")
        if not callable(fn):
            raise ValueError(f"hooks.provide: {name} must be callable, got {type(fn).__name__}")
        _PROVIDED[name] = fn


def hook(name: str) -> Callable:
    """The function provided under ``name``.

    Raises
    ------
    RuntimeError
        When the io wing has not provided it (only possible if the package's ``__init__`` did
        not run: import ``kedfem``).
    """
    try:
        return _PROVIDED[name]
    except KeyError:
        raise RuntimeError(f"no {name!r} is provided to the analysis wing: import kedfem (its __init__ "
                           "wires the io wing's writers in)") from None
