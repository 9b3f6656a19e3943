"""Where a scene file's values are, and the errors that name them.

A scene file's keys are located by line (:class:`_Locator`, a scan of the TOML text: tomllib keeps
no positions), and every value is checked by a typed checker (:func:`_int`, :func:`_float`,
:func:`_str`, :func:`_bool`, :func:`_table`) that raises a :class:`SceneFileError` naming the
file, the line and the dotted key (or the command line, for an override). The parser
(:mod:`kedfem.io.scenefile`) is built on them.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import InputError, did_you_mean
from ..trust import Trust, UntrustedCodeError

__all__ = ["SceneFileError", "UntrustedSceneError"]


class SceneFileError(InputError):
    """A bad scene file or scene dictionary.

    Attributes
    ----------
    key : str or None
        Dotted key of the offending value (``"damping.beta"``); in the
        message, parts that are not bare TOML keys are quoted.
    path : str or None
        File (or ``"command line"``) the value came from.
    line : int or None
        1-based line of the key in the file, when it could be found.
    reason : str
        The message without the location prefix.
    """

    def __init__(self, reason: str, *, key: str | None = None, path: str | None = None,
                 line: int | None = None):
        self.key, self.path, self.line, self.reason = key, path, line, reason
        where = ""
        if path:
            where = f"{path}:{line}: " if line else f"{path}: "
        elif line:
            where = f"line {line}: "
        super().__init__(f"{where}{_keyfmt(key)}: {reason}" if key else f"{where}{reason}")


class UntrustedSceneError(SceneFileError, UntrustedCodeError):
    """A scene names code (a builder file or module) that the user has not trusted
    (:mod:`kedfem.trust`); raised before anything is imported."""


# ------------------------------------------------------------ key locations
_QUOTED = r"""(?:"(?:[^"\\]|\\.)*"|'[^']*')"""
_PART = rf"(?:[A-Za-z0-9_\-]+|{_QUOTED})"
_DOTTED = rf"{_PART}(?:\s*\.\s*{_PART})*"
_HEADER = re.compile(rf"^\s*\[\[?\s*(?P<name>{_DOTTED})\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(rf"^\s*(?P<key>{_DOTTED})\s*=")
_INLINE_KEY = re.compile(rf"(?:[{{,]\s*)(?P<key>{_DOTTED})\s*=")


def _split_dotted(s: str) -> tuple[str, ...]:
    """Parts of a TOML dotted key as written (quoted parts unescaped by tomllib)."""
    try:
        d = tomllib.loads(f"{s} = 0")
    except tomllib.TOMLDecodeError:
        return tuple(p.strip().strip("\"'") for p in s.split("."))
    parts = []
    while isinstance(d, dict) and len(d) == 1:
        k, d = next(iter(d.items()))
        parts.append(k)
    return tuple(parts)


def _keyfmt(key: str) -> str:
    """A dotted key for messages: parts that are not bare TOML keys are quoted and escaped."""
    import json
    return ".".join(p if p and re.fullmatch(r"[A-Za-z0-9_\-]+(\[\d+\])?", p) else json.dumps(p)
                    for p in key.split("."))


class _Locator:
    """Line numbers of dotted keys, found by scanning the TOML text."""

    def __init__(self, text: str):
        self.lines: dict[str, int] = {}
        table: tuple[str, ...] = ()
        arrays: dict[str, int] = {}  # [[name]]: entries so far; its k-th entry is "name[k]"
        for i, raw in enumerate(text.splitlines(), start=1):
            m = _HEADER.match(raw)
            if m:
                table = _split_dotted(m.group("name"))
                self.lines.setdefault(".".join(table), i)
                if raw.lstrip().startswith("[["):
                    name = ".".join(table)
                    arrays[name] = arrays.get(name, -1) + 1
                for name, k in arrays.items():  # a table in the last entry of an array of tables
                    parts = tuple(name.split("."))
                    if table[:len(parts)] == parts:
                        table = parts[:-1] + (f"{parts[-1]}[{k}]",) + table[len(parts):]
                        self.lines.setdefault(".".join(table), i)
                continue
            m = _KEY.match(raw)
            if m:
                key = table + _split_dotted(m.group("key"))
                self.lines.setdefault(".".join(key), i)
                rest = raw[m.end():]
                if rest.lstrip().startswith("{"):
                    for mm in _INLINE_KEY.finditer(rest):
                        self.lines.setdefault(".".join(key + _split_dotted(mm.group("key"))), i)

    def line(self, key: str | None) -> int | None:
        if not key:
            return None
        parts = key.split(".")
        for n in range(len(parts), 0, -1):
            ln = self.lines.get(".".join(parts[:n]))
            if ln is not None:
                return ln
        return None


class _Ctx:
    """Where values come from, to name them in errors."""

    def __init__(self, source: str | None = None, text: str | None = None, overridden=(), trust=None):
        self.source = source
        # a scene file's folder: relative builder files are relative to it, and it is searched for
        # builder modules (searching grants no trust)
        self.folder = str(Path(source).resolve().parent) if source and Path(source).suffix == ".toml" else None
        self.locator = _Locator(text) if text else None
        self.overridden = set(overridden)
        self.trust = Trust.of(trust).searching(self.folder)

    def error(self, key: str | None, reason: str, cls=None) -> SceneFileError:
        cls = cls or SceneFileError
        if key is not None and any(key == o or key.startswith(o + ".") for o in self.overridden):
            return cls(reason, key=key, path="command line")
        line = self.locator.line(key) if self.locator else None
        return cls(reason, key=key, path=self.source, line=line)


_suggest = did_you_mean


def _typename(v) -> str:
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string", list: "an array",
            dict: "a table"}.get(type(v), type(v).__name__)


def _unknown(ctx: _Ctx, table: Mapping, allowed, prefix: str):
    for k in table:
        if k not in allowed:
            key = f"{prefix}{k}"
            raise ctx.error(key, f"unknown key{_suggest(k, allowed)}; allowed: {', '.join(sorted(allowed))}")


# ----------------------------------------------------------- value checkers
def _int(ctx, key, v, lo, hi, why=""):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
        raise ctx.error(key, f"must be an integer, got {_typename(v)} {v!r}")
    if v < lo or v > hi:
        raise ctx.error(key, f"must lie in {lo} .. {hi}{why}, got {v}")
    return int(v)


def _float(ctx, key, v, *, lo=None, hi=None, lo_open=False, hi_open=False, nonzero=False, unit=""):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ctx.error(key, f"must be a number{unit}, got {_typename(v)} {v!r}")
    v = float(v)
    if not math.isfinite(v):
        raise ctx.error(key, f"must be a finite number{unit}, got {v}")
    bad = ((lo is not None and (v < lo or (lo_open and v == lo)))
           or (hi is not None and (v > hi or (hi_open and v == hi))) or (nonzero and v == 0.0))
    if bad:
        rng = []
        if lo is not None:
            rng.append(f"{'>' if lo_open else '>='} {lo:g}")
        if hi is not None:
            rng.append(f"{'<' if hi_open else '<='} {hi:g}")
        if nonzero:
            rng.append("nonzero")
        raise ctx.error(key, f"must be {' and '.join(rng)}{unit}, got {v:g}")
    return v


def _str(ctx, key, v, choices=None):
    if not isinstance(v, str):
        raise ctx.error(key, f"must be a string, got {_typename(v)} {v!r}")
    if choices is not None and v not in choices:
        raise ctx.error(key, f"must be one of {', '.join(choices)}{_suggest(v, choices)}, got {v!r}")
    return v


def _bool(ctx, key, v):
    if not isinstance(v, bool):
        raise ctx.error(key, f"must be true or false, got {_typename(v)} {v!r}")
    return v


def _table(ctx, key, v):
    if not isinstance(v, dict):
        raise ctx.error(key, f"must be a table ([{key}]), got {_typename(v)} {v!r}")
    return v
