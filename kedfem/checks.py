"""Argument checks shared by every wing: a value of the right kind, or an :class:`InputError`
that names the function (``owner``) and the argument.

Each check returns the value in its canonical type (a float, an int, a tuple of names, a float
array), so that callers use what was checked and nothing else.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import InputError, did_you_mean

__all__ = ["real", "integer", "flag", "names", "name", "choice", "floats", "pair", "direction"]


def _short(v) -> str:
    r = repr(v)
    return r if len(r) <= 60 else r[:57] + "..."


def _numeric(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def real(owner: str, name: str, value, *, positive: bool = False, nonneg: bool = False,
         limit: float | None = None, unit: str = "") -> float:
    """``value`` as a finite float.

    Parameters
    ----------
    positive, nonneg : bool
        Require ``> 0`` / ``>= 0``.
    limit : float, optional
        The largest magnitude accepted.
    unit : str
        Unit named in the message (``" m"``).
    """
    if not _numeric(value) and not (isinstance(value, np.ndarray) and value.ndim == 0 and _numeric(value.item())):
        raise InputError(f"{owner}: {name} must be a number, got {_short(value)}")
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{owner}: {name} must be a number, got {_short(value)}") from None
    if not math.isfinite(v):
        raise InputError(f"{owner}: {name} must be finite, got {_short(value)}")
    if positive and v <= 0.0:
        raise InputError(f"{owner}: {name} must be > 0, got {_short(value)}")
    if nonneg and v < 0.0:
        raise InputError(f"{owner}: {name} must be >= 0, got {_short(value)}")
    if limit is not None and abs(v) > limit:
        raise InputError(f"{owner}: {name} = {v:.6g}{unit} exceeds the largest magnitude a model may hold, "
                         f"{limit:g}{unit} (a unit mistake?)")
    return v


def integer(owner: str, name: str, value, lo: int | None = None, hi: int | None = None) -> int:
    """``value`` as an int in ``lo .. hi`` (a float, even a whole one, is refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{owner}: {name} must be an integer, got {type(value).__name__} {_short(value)}")
    v = int(value)
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        rng = f"{lo if lo is not None else '-inf'} .. {hi if hi is not None else 'inf'}"
        raise InputError(f"{owner}: {name} must lie in {rng}, got {v}")
    return v


def flag(owner: str, name: str, value) -> bool:
    """``value`` as a bool: only True/False (a string such as ``"no"`` is not read as true)."""
    if isinstance(value, np.bool_):
        return bool(value)
    if not isinstance(value, bool):
        raise InputError(f"{owner}: {name} must be True or False, got {type(value).__name__} {_short(value)}")
    return value


def name(owner: str, what: str, value, known=None) -> str:
    """``value`` as a non-empty string; with ``known`` (a collection), one of them."""
    if not isinstance(value, str) or not value:
        raise InputError(f"{owner}: {what} must be a name (a non-empty string), got {type(value).__name__} "
                         f"{_short(value)}")
    if known is not None and value not in known:
        listed = ", ".join(map(str, known)) or "none"
        raise InputError(f"{owner}: unknown {what} {value!r}{did_you_mean(value, known)} (known: {listed})")
    return value


def choice(owner: str, what: str, value, choices) -> str:
    """``value`` as one of the strings ``choices``."""
    if not isinstance(value, str) or value not in choices:
        raise InputError(f"{owner}: {what} must be one of {', '.join(map(str, choices))}"
                         f"{did_you_mean(value, choices) if isinstance(value, str) else ''}, got {_short(value)}")
    return value


def names(owner: str, what: str, value, *, allow_one: bool = True) -> tuple[str, ...]:
    """``value`` as a tuple of non-empty strings (a single string is one name when ``allow_one``)."""
    if isinstance(value, str) and allow_one:
        value = (value,)
    if isinstance(value, (str, bytes)) or not isinstance(value, (tuple, list)) or \
            not all(isinstance(x, str) and x for x in value):
        raise InputError(f"{owner}: {what} must be a sequence of names (strings), got {_short(value)}")
    return tuple(value)


def floats(owner: str, what: str, value, *, ndim: int = 1, max_size: int = 1_000_000, unit: str = "",
           min_size: int = 1) -> np.ndarray:
    """``value`` as a finite float array of ``ndim`` dimensions (a scalar for ``ndim=1`` is one value)."""
    if isinstance(value, (str, bytes, dict)) or value is None:
        raise InputError(f"{owner}: {what} must be numbers{unit}, got {type(value).__name__} {_short(value)}")
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{owner}: {what} must be numbers{unit}, got {_short(value)}") from None
    if ndim == 1 and a.ndim == 0:
        a = a.reshape(1)
    if a.ndim != ndim or a.size < min_size or a.size > max_size:
        raise InputError(f"{owner}: {what} must be a {ndim}-D array of {min_size} .. {max_size} numbers{unit}, "
                         f"got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{owner}: {what} must be finite numbers{unit}, got {_short(value)}")
    return a


def pair(owner: str, name: str, value, *, limit: float | None = None, unit: str = "") -> tuple[float, float]:
    """Two finite numbers (x, y); with ``limit``, each of magnitude at most ``limit``."""
    if isinstance(value, (str, bytes, dict)) or (isinstance(value, (tuple, list))
                                                 and any(isinstance(x, (str, bytes, bool)) for x in value)):
        raise InputError(f"{owner}: {name} must be a pair of numbers, got {value!r}")
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{owner}: {name} must be a pair of numbers, got {value!r}") from None
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise InputError(f"{owner}: {name} must be two finite numbers (x, y){unit and ' [' + unit.strip() + ']'}, "
                         f"got {value!r}")
    if limit is not None and np.max(np.abs(arr)) > limit:
        raise InputError(f"{owner}: {name} = ({arr[0]:.6g}, {arr[1]:.6g}){unit} exceeds the largest magnitude a "
                         f"model may hold, {limit:g}{unit} (a unit mistake?)")
    return (float(arr[0]), float(arr[1]))


def direction(owner: str, name: str, value) -> tuple[float, float]:
    """A direction, normalised (scaled first, so that huge or subnormal components normalise exactly)."""
    ax = np.asarray(pair(owner, name, value))
    big = float(np.max(np.abs(ax)))
    if big == 0.0:
        raise InputError(f"{owner}: {name} must be a non-zero vector")
    ax = ax / big
    return tuple(float(v) for v in ax / float(np.hypot(*ax)))
