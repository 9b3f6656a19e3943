"""Output folders published whole: a folder on disk is always one complete run.

A command (``kedfem run``, ``sweep``, ``export``) writes every file into a
fresh hidden staging folder beside its output folder, writes a manifest
(:data:`MANIFEST`: run id, command, kedfem version, time, the files) last, and
then *publishes* the staging folder: on Linux one atomic exchange of the two
directories (``renameat2(RENAME_EXCHANGE)``), elsewhere two renames (a kill
between them leaves no folder at the final path, only the complete old and new
ones beside it). A kill at any moment therefore leaves the output folder as the
complete old run or the complete new one, never a mix; what a killed run left
behind (hidden ``.NAME.staging-PID-*`` / ``.NAME.old-PID-*`` folders of dead
processes) is removed by the next run into the same folder.

A folder is only replaced if kedfem wrote everything in it (its manifest lists
every entry, or, for folders of earlier versions without a manifest, every
entry has a name kedfem writes and its ``summary.txt`` or ``sweep.csv`` is
kedfem's); a folder holding anything else is an input error, so ``--out
~/project`` cannot delete a user's files, not even a ``peaks.csv`` of theirs.
"""

from __future__ import annotations

import ctypes
import datetime
import json
import logging
import os
import re
import secrets
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError

__all__ = ["MANIFEST", "RunFolder", "publish_dir", "clean_leftovers", "check_replaceable"]

log = logging.getLogger(__name__)

#: The manifest a published folder carries (written last into the staging folder).
MANIFEST = "kedfem-run.json"

#: Names kedfem writes into an output folder (a folder without a manifest is
#: replaced only if it holds nothing else).
KNOWN = frozenset({
    "response.csv", "peaks.csv", "frequencies.csv", "result.npz", "summary.txt", "sweep.csv",
    "sweep_peaks.png", "displacement.png", "link_response.png", "frequencies.png", "floquet.png",
    "deformed.png", "response", "response.pvd", "modes", "modes.pvd", MANIFEST,
    "fatigue.csv", "histories.csv", "histories.npz", "loads.csv", "loads.png", "cycle.gif",
    "campbell.csv", "campbell_crossings.csv", "campbell.png", "stability_map.csv", "stability_map.png",
})
_HIDDEN_TMP = re.compile(r"^\..+\.(tmp|old|staging)-\d+-[0-9a-f]+")
#: a killed run's staging or replaced folder, or its writability probe (``report.check_out_dir``)
_LEFTOVER = re.compile(r"^\.(?P<name>.+)\.(staging|old|probe)-(?P<pid>\d+)-[0-9a-z_]+$")


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def clean_leftovers(final: Path) -> list[Path]:
    """Remove the staging and old folders that killed runs into ``final`` left beside it.

    Only folders of processes that no longer run are removed. Returns them.
    """
    final = Path(final)
    parent = final.parent
    gone = []
    if not parent.is_dir():
        return gone
    for p in parent.iterdir():
        m = _LEFTOVER.match(p.name)
        if m and m.group("name") == final.name and not _alive(int(m.group("pid"))):
            shutil.rmtree(p, ignore_errors=True) if p.is_dir() and not p.is_symlink() else p.unlink(missing_ok=True)
            gone.append(p)
    if gone:
        log.info("removed %d folder(s) left by killed runs into %s", len(gone), final)
    return gone


def check_replaceable(final: Path) -> None:
    """Raise :class:`InputError` unless ``final`` is absent, empty or a kedfem output folder."""
    final = Path(final)
    if not final.exists() and not final.is_symlink():
        return
    if final.is_symlink() or not final.is_dir():
        raise InputError(f"--out {final}: is a file, not a folder")
    names = {p.name for p in final.iterdir()}
    if not names:
        return
    listed = None
    man = final / MANIFEST
    if man.is_file():
        try:
            data = json.loads(man.read_text())
            listed = {Path(f).parts[0] for f in data.get("files", [])} | {MANIFEST}
        except (OSError, ValueError, TypeError, IndexError):
            listed = None
    allowed = listed if listed is not None else KNOWN
    foreign = sorted(n for n in names if n not in allowed and not _HIDDEN_TMP.match(n))
    if not foreign and listed is None and not _legacy_run(final):
        # names kedfem writes, but nothing says kedfem wrote them: a user's own peaks.csv is not ours
        foreign = sorted(n for n in names if not _HIDDEN_TMP.match(n))
    if foreign:
        shown = ", ".join(foreign[:4]) + (", ..." if len(foreign) > 4 else "")
        raise InputError(f"--out {final}: the folder holds files kedfem did not write ({shown}); a run "
                         f"replaces its output folder whole, so choose a new or empty folder, or move them")


def _legacy_run(folder: Path) -> bool:
    """A run folder of a version before the manifest: its summary or sweep table says kedfem wrote it."""
    try:
        summary = folder / "summary.txt"
        if summary.is_file():
            with open(summary, errors="replace") as f:
                return f.readline().startswith("kedfem ")
        table = folder / "sweep.csv"
        if table.is_file():
            with open(table, errors="replace") as f:
                return f.readline().startswith("point,") and "peak_stress_Pa" in table.read_text()[:2000]
        series = [folder / n for n in ("response", "modes") if (folder / n).is_dir()]
        return bool(series) and all(any(p.suffix == ".vtu" for p in d.iterdir()) for d in series)
    except OSError:
        return False


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap two paths (Linux ``renameat2``); False where unsupported."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    r = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if r == 0:
        return True
    err = ctypes.get_errno()
    if err in (22, 38, 95):  # EINVAL, ENOSYS, EOPNOTSUPP: the file system cannot exchange
        return False
    raise OSError(err, f"cannot publish {a} as {b}: {os.strerror(err)}")


def _token() -> str:
    return f"{os.getpid()}-{secrets.token_hex(3)}"


def publish_dir(staging: Path, final: Path) -> None:
    """Make the complete folder ``staging`` appear at ``final`` in one step, replacing it.

    The replaced folder is deleted afterwards (a kill before that leaves it as a
    hidden leftover that :func:`clean_leftovers` removes).
    """
    staging, final = Path(staging), Path(final)
    if not final.exists() and not final.is_symlink():
        try:
            os.rename(staging, final)
            return
        except OSError:
            if not final.exists():
                raise
    if _exchange(staging, final):
        old = staging  # now holds the replaced folder
    else:
        old = final.with_name(f".{final.name}.old-{_token()}")
        os.rename(final, old)
        os.rename(staging, final)
    shutil.rmtree(old, ignore_errors=True)


@dataclass
class RunFolder:
    """Write a run's files into a staging folder and publish it whole at ``final``.

    Use as a context manager: the ``with`` body writes into :attr:`path`; on
    success the manifest is written and the folder published, on an
    exception the staging folder is removed and ``final`` is untouched.

    Attributes
    ----------
    final : Path
        The output folder.
    command : str
        What wrote it (``"run"``, ``"sweep"``, ``"export"``), for the manifest.
    info : dict
        More manifest entries (scene, source).
    path : Path
        The staging folder (valid inside the ``with`` block).
    run_id : str
        Identifier of this run, in the manifest.
    """

    final: Path
    command: str
    info: dict = field(default_factory=dict)
    path: Path | None = None
    run_id: str = ""

    def __post_init__(self):
        self.final = Path(self.final)
        self.run_id = datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%dT%H%M%SZ") + "-" + secrets.token_hex(4)

    def __enter__(self) -> "RunFolder":
        check_replaceable(self.final)
        self.final.parent.mkdir(parents=True, exist_ok=True)
        clean_leftovers(self.final)
        self.path = self.final.with_name(f".{self.final.name}.staging-{_token()}")
        self.path.mkdir()
        return self

    def __exit__(self, et, ev, tb):
        if et is not None:
            shutil.rmtree(self.path, ignore_errors=True)
            return False
        try:
            self._write_manifest()
            check_replaceable(self.final)  # nothing foreign appeared meanwhile
            publish_dir(self.path, self.final)
        except BaseException:
            shutil.rmtree(self.path, ignore_errors=True)
            raise
        log.info("published %s (%s run %s)", self.final, self.command, self.run_id)
        return False

    def _write_manifest(self) -> None:
        from .. import __version__
        files = sorted(str(p.relative_to(self.path)) for p in self.path.rglob("*") if p.is_file())
        data = dict(kedfem=__version__, command=self.command, run_id=self.run_id,
                    created=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                    **self.info, files=files)
        tmp = self.path / (MANIFEST + ".tmp")
        tmp.write_text(json.dumps(data, indent=1) + "\n")
        os.replace(tmp, self.path / MANIFEST)
