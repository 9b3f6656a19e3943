"""Which code a scene may make kedfem run, and how it is found without changing ``sys.path``.

A scene (a TOML scene file, or a scene dictionary) is data. It names its mechanism:

* a **catalogue name** (``four_bar``): an entry point of a distribution the user installed, or a
  mechanism registered in this process (:func:`kedfem.catalogue.register`). That is code the user
  chose to install or to run; a scene may always name it.
* a **code reference**: ``"path/to/file.py:function"`` or ``"package.module:function"``. That is
  code the scene's author chose. kedfem runs it only when the user *trusts* it:

  - on the command line, ``--trust TARGET`` (repeatable): a ``.py`` file, a folder (every file
    under it), a scene file (the folder it lies in), or a module name (that module and its
    submodules); a builder given as the command's own argument (``kedfem run my.py:build``) is
    trusted;
  - in Python, the ``trust=`` argument of the functions that read scenes
    (:func:`kedfem.load_scene`, :func:`kedfem.scene_from_dict`, :func:`kedfem.io.sweep.run_sweep`,
    :func:`kedfem.stability_map`, :func:`kedfem.critical_speed`): a :class:`Trust`, ``True``
    (everything the scene names: for a dictionary your own code wrote) or the targets as for
    ``--trust``.

Whether a reference is trusted is decided *before anything is imported*: the files an import would
execute (the module and the ``__init__`` of every package above it) are found on disk by
:class:`importlib.machinery.PathFinder`, which reads folders and executes nothing, and every one
must be trusted. A module that is not on the Python path is looked up in the scene's folder and
the working folder and imported from there without adding either to ``sys.path``. After import,
the builder must be a plain Python function whose code lies in trusted code too (a trusted module
that re-exports ``os.abort`` does not make ``os.abort`` trusted).
"""

from __future__ import annotations

import importlib
import importlib.machinery
import importlib.util
import os
import sys
from dataclasses import dataclass
from pathlib import Path

from .errors import InputError

__all__ = ["Trust", "UntrustedCodeError", "Located", "locate", "check", "import_module", "is_module_name"]


class UntrustedCodeError(InputError):
    """A scene names code (a builder file or module) that the user has not trusted."""


def is_module_name(text: str) -> bool:
    """``package.module`` (dotted identifiers)."""
    return bool(text) and all(p.isidentifier() for p in str(text).split("."))


def _inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


@dataclass(frozen=True)
class Trust:
    """The code a scene may run, and the folders its module references are looked up in.

    Parameters
    ----------
    paths : tuple of str
        Absolute, resolved ``.py`` files and folders whose code is trusted (a folder: every file
        under it).
    modules : tuple of str
        Module names trusted with their submodules (and the packages an import of them runs).
    everything : bool
        Trust every reference (the Python API's ``trust=True``).
    search : tuple of str
        Absolute folders searched for a module reference that is not on the Python path (a scene
        file's folder, the working folder). Searching grants no trust.
    """

    paths: tuple[str, ...] = ()
    modules: tuple[str, ...] = ()
    everything: bool = False
    search: tuple[str, ...] = ()

    @classmethod
    def of(cls, value, owner: str = "trust") -> "Trust":
        """A :class:`Trust` from the ``trust=`` argument of the Python API.

        Parameters
        ----------
        value : Trust, bool, None, str, path or sequence of str/path
            ``None`` or ``False``: nothing; ``True``: everything; a :class:`Trust`; targets as
            for ``--trust`` (an existing ``.py`` file, a folder, a scene file's folder, or a
            module name).
        owner : str
            Named in the error message.

        Raises
        ------
        InputError
            A target that is neither an existing file or folder nor a module name.
        """
        if value is None or value is False:
            return cls()
        if value is True:
            return cls(everything=True)
        if isinstance(value, Trust):
            return value
        items = [value] if isinstance(value, (str, os.PathLike)) else value
        try:
            items = list(items)
        except TypeError:
            raise InputError(f"{owner}: must be True, a kedfem.trust.Trust, or files, folders and module names "
                             f"to trust, got {type(value).__name__} {value!r}") from None
        paths, modules = [], []
        for t in items:
            if not isinstance(t, (str, os.PathLike)) or not str(t).strip():
                raise InputError(f"{owner}: each target must be a file, a folder or a module name, got {t!r}")
            p = Path(t).expanduser()
            if p.exists():
                p = p.resolve()
                if p.is_file() and p.suffix.lower() != ".py":
                    p = p.parent  # a scene file: the folder it lies in
                paths.append(str(p))
            elif is_module_name(str(t)) and not str(t).endswith(".py"):
                modules.append(str(t))
            else:
                raise InputError(f"{owner}: {str(t)!r} is neither an existing file or folder nor a module name")
        return cls(tuple(paths), tuple(modules))

    @classmethod
    def of_reference(cls, reference: str) -> "Trust":
        """Trust exactly the builder ``reference`` (``"file.py:function"`` with an absolute path,
        or ``"package.module:function"``): a builder given as the command's own argument."""
        target, _, _ = str(reference).rpartition(":")
        if target.endswith(".py"):
            return cls(paths=(str(Path(target).resolve()),))
        return cls(modules=(target,))

    def __or__(self, other: "Trust") -> "Trust":
        def merged(a, b):
            return tuple(dict.fromkeys(a + b))
        return Trust(merged(self.paths, other.paths), merged(self.modules, other.modules),
                     self.everything or other.everything, merged(self.search, other.search))

    def searching(self, *folders) -> "Trust":
        """The same trust, also searching ``folders`` (None entries skipped) for modules."""
        extra = tuple(str(Path(f).resolve()) for f in folders if f is not None)
        return Trust(self.paths, self.modules, self.everything, tuple(dict.fromkeys(self.search + extra)))

    @property
    def empty(self) -> bool:
        """Nothing is trusted."""
        return not (self.everything or self.paths or self.modules)

    def allows_file(self, path) -> bool:
        """Code in ``path`` may run."""
        if self.everything:
            return True
        p = Path(path).resolve()
        return any(_inside(p, Path(t)) for t in self.paths)

    def allows_module(self, name: str) -> bool:
        """Module ``name`` (and the packages above it) may be imported, by its name."""
        return self.everything or any(name == m or name.startswith(m + ".") for m in self.modules)

    def describe(self) -> str:
        """What is trusted, for messages."""
        if self.everything:
            return "everything"
        parts = list(self.paths) + list(self.modules)
        return ", ".join(parts) if parts else "nothing"


@dataclass(frozen=True)
class Located:
    """Where a module reference's code lies, found without executing anything.

    Attributes
    ----------
    module : str
        The module name.
    files : tuple of Path
        The files its import would execute: the ``__init__`` of each package above it and the
        module itself (none for a built-in module).
    folder : Path or None
        The search folder it was found in (None: on the Python path, or already imported).
    """

    module: str
    files: tuple[Path, ...]
    folder: Path | None


def _spec_files(spec) -> list[Path]:
    origin = getattr(spec, "origin", None)
    if origin and origin not in ("built-in", "frozen") and os.path.isfile(origin):
        return [Path(origin).resolve()]
    return []


def _walk(parts: list[str], first_spec, folder) -> Located | None:
    files = _spec_files(first_spec)
    spec = first_spec
    for i in range(1, len(parts)):
        locations = spec.submodule_search_locations
        if locations is None:
            return None  # not a package: it has no submodule parts[i]
        spec = importlib.machinery.PathFinder.find_spec(".".join(parts[: i + 1]), list(locations))
        if spec is None:
            return None
        files += _spec_files(spec)
    return Located(".".join(parts), tuple(files), folder)


def locate(module: str, search=()) -> Located | None:
    """Find the files an import of ``module`` would execute, without executing any.

    Parameters
    ----------
    module : str
        Dotted module name.
    search : sequence of path
        Folders searched when the module is not on the Python path.

    Returns
    -------
    Located or None
        None when it is found nowhere.
    """
    parts = module.split(".")
    if module in sys.modules:  # already imported: its files ran already; report them all the same
        mods = [sys.modules.get(".".join(parts[: i + 1])) for i in range(len(parts))]
        files = tuple(Path(f).resolve() for m in mods if m is not None
                      for f in [getattr(m, "__file__", None)] if f and os.path.isfile(f))
        return Located(module, files, None)
    top = parts[0]
    if top in sys.builtin_module_names:
        return Located(module, (), None) if len(parts) == 1 else None
    try:  # a top-level name: the finders read the Python path (and editable installs) and run nothing
        spec = importlib.util.find_spec(top)
    except (ImportError, ValueError):
        spec = None
    if spec is not None:
        return _walk(parts, spec, None)
    for folder in search:
        spec = importlib.machinery.PathFinder.find_spec(top, [str(folder)])
        if spec is not None:
            return _walk(parts, spec, Path(folder))
    return None


def check(reference: str, trust: Trust, *, located: Located | None = None) -> None:
    """Raise :class:`UntrustedCodeError` unless the code ``reference`` names is trusted.

    Parameters
    ----------
    reference : str
        ``"/abs/file.py:function"`` or ``"package.module:function"``.
    trust : Trust
    located : Located, optional
        For a module reference, where it lies (:func:`locate`); None: not found (then only a
        module-name trust allows it, and the import will say it is missing).
    """
    if trust.everything:
        return
    target, _, fn = reference.rpartition(":")
    head = (f"the scene names code to run, {reference!r}: ")
    tail = ("A scene runs catalogue mechanisms only (kedfem list) unless you trust its code (docs/usage.md, "
            "section 2.5)")
    if target.endswith(".py"):
        if trust.allows_file(target):
            return
        raise UntrustedCodeError(
            f"{head}the file {target}, which you have not trusted (trusted: {trust.describe()}). {tail}: "
            f"--trust {target} (or its folder) on the command line, or trust=... in Python")
    if trust.allows_module(target):
        return
    files = located.files if located is not None else ()
    untrusted = [f for f in files if not trust.allows_file(f)]
    if files and not untrusted:
        return
    if located is not None and located.folder is None and _installed(files):
        raise UntrustedCodeError(
            f"{head}the installed module {target!r} ({files[-1]}), library code on this machine, not a builder "
            f"shipped with the scene. {tail}; a builder of your own is named by its file: "
            "builder = 'my_linkage.py:build'")
    where = f" ({untrusted[0]}{', run by the import' if untrusted[0] != files[-1] else ''})" if untrusted else ""
    raise UntrustedCodeError(
        f"{head}the module {target!r}{where}, which you have not trusted (trusted: {trust.describe()}). {tail}: "
        f"--trust {target.split('.')[0]} (the package), or the folder that holds it, on the command line; "
        "trust=... in Python")


def _installed(files) -> bool:
    """The files lie in the Python installation (the standard library or site-packages)."""
    import sysconfig
    roots = {Path(p).resolve() for k in ("stdlib", "platstdlib", "purelib", "platlib")
             for p in [sysconfig.get_paths().get(k)] if p}
    roots |= {Path(p).resolve() for p in (sys.base_prefix, sys.prefix)}
    return bool(files) and all(any(_inside(Path(f), r) for r in roots) for f in files)


def check_function(reference: str, fn, trust: Trust) -> None:
    """After import: the builder is a plain Python function whose code is trusted.

    Raises
    ------
    InputError
        Not a Python function (a class, a built-in, another callable).
    UntrustedCodeError
        A function defined in code that is not trusted (re-exported from elsewhere).
    """
    import inspect
    if not inspect.isfunction(fn):
        raise InputError(f"mechanism {reference!r}: the builder must be a Python function "
                         f"build(**params) -> kedfem.Mechanism, got {type(fn).__name__} {fn!r}")
    if trust.everything:
        return
    code_file = getattr(getattr(fn, "__code__", None), "co_filename", "")
    if code_file and os.path.isfile(code_file) and trust.allows_file(code_file):
        return
    if trust.allows_module(getattr(fn, "__module__", "") or ""):
        return
    raise UntrustedCodeError(f"mechanism {reference!r}: the function is defined in {code_file or fn.__module__}, "
                             f"which you have not trusted (trusted: {trust.describe()})")


def import_module(located: Located):
    """Import a located module; one found in a search folder is imported from there without
    adding the folder to ``sys.path`` (its top-level package is loaded from the folder and
    registered, so its submodules and relative imports resolve through the package)."""
    if located.folder is None:
        return importlib.import_module(located.module)
    top = located.module.split(".")[0]
    if top not in sys.modules:
        spec = importlib.machinery.PathFinder.find_spec(top, [str(located.folder)])
        mod = importlib.util.module_from_spec(spec)
        sys.modules[top] = mod
        try:
            spec.loader.exec_module(mod)
        except BaseException:
            sys.modules.pop(top, None)
            raise
    return importlib.import_module(located.module)
