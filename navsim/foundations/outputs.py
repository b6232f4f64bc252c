"""Output folders: every file written under a temporary name and renamed, and a manifest of
what navsim wrote, so that a rerun removes its own earlier files and nothing else.

An :class:`OutputFolder` is the folder of one command's results (``reports/<name>`` by
default). Its manifest ``.navsim-files.json`` lists the plain file names written there; a new
run in the same folder first removes the files the manifest lists (an earlier run's
``metrics.json`` never stands beside a new run's chunks) and never anything else. A file
being written is ``.<stem>.tmp<suffix>`` until it is complete, so a full disk or a kill
leaves the earlier file or none, never a truncated one. Any :class:`OSError` becomes an
:class:`~navsim.foundations.errors.OutputError` (exit code 4) naming the path.
"""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path
from typing import Callable

from navsim.foundations.config import plain_name
from navsim.foundations.errors import OutputError

MANIFEST = ".navsim-files.json"


def temporary_name(path: Path) -> Path:
    """Where ``path`` is written before it is renamed: hidden, with the same suffix."""
    return path.with_name(f".{path.stem}.tmp{path.suffix}")


def write_atomic(path: Path, write: Callable[[Path], object], *, fsync: bool = False) -> Path:
    """Call ``write(tmp)`` on :func:`temporary_name` of ``path`` and rename it to ``path``;
    with ``fsync`` the file and its folder are flushed to the disk first. On an error the
    temporary file is removed and an :class:`OutputError` raised; ``path`` keeps its old
    content, if any."""
    path = Path(path)
    tmp = temporary_name(path)
    try:
        write(tmp)
        if fsync:
            with open(tmp, "rb+") as f:
                os.fsync(f.fileno())
        os.replace(tmp, path)
        if fsync:
            _fsync_folder(path.parent)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise OutputError(path, exc) from None
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise
    return path


def _fsync_folder(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:                      # a folder that cannot be opened (not POSIX): no fsync
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class OutputFolder:
    """The output folder of one command.

    Parameters
    ----------
    path : Path
        The folder; created with its parents. A path naming a file, or a folder that cannot be
        created or written, raises :class:`OutputError`.
    """

    def __init__(self, path: Path):
        self.path = Path(path)
        if self.path.exists() and not self.path.is_dir():
            raise OutputError(self.path, reason="exists and is not a folder")
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(exc.filename or self.path, exc) from None
        self._names = self._read_manifest()
        self._save_manifest()            # also proves the folder writable before any work

    def _read_manifest(self) -> list[str]:
        try:
            names = json.loads((self.path / MANIFEST).read_text())
        except (OSError, ValueError):
            return []
        return [n for n in names if isinstance(n, str) and plain_name(n)] if isinstance(names, list) else []

    def _save_manifest(self) -> None:
        names = sorted(set(self._names))
        write_atomic(self.path / MANIFEST, lambda p: p.write_text(json.dumps(names)))

    def clear_earlier(self) -> list[str]:
        """Remove the files an earlier run wrote here (those the manifest lists); returns them."""
        removed = []
        for name in self._names:
            target = self.path / name
            try:
                temporary_name(target).unlink(missing_ok=True)     # left by a killed writer
                if target.is_file():
                    target.unlink()
                    removed.append(name)
            except OSError as exc:
                raise OutputError(target, exc) from None
        self._names = []
        self._save_manifest()
        return removed

    def record(self, paths) -> None:
        """Add files written in the folder (by their own writers) to the manifest."""
        self._names += [Path(p).name for p in paths if Path(p).parent.resolve() == self.path.resolve()]
        self._save_manifest()

    def write(self, name: str, write: Callable[[Path], object]) -> Path:
        """Write the file ``name`` with ``write(tmp_path)`` (see :func:`write_atomic`)."""
        self.record([self.path / name])
        return write_atomic(self.path / name, write)

    def text(self, name: str, text: str) -> Path:
        """Write ``text`` to the file ``name``."""
        return self.write(name, lambda p: p.write_text(text))
