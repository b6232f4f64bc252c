"""Output folders: one writer at a time, files written under a temporary name and renamed, and
a manifest of what navsim wrote, so that a rerun removes its own earlier files and nothing else.
(Over 600 lines, kept whole: the lock, the manifest and the atomic writes share one held state
per folder, :class:`OutputFolder`'s, and each guards the others' guarantees.)

An :class:`OutputFolder` is the folder of one command's results (``reports/<name>`` by
default). Opening one takes its lock (``.navsim.lock``: ``fcntl.flock`` on a file holding the
holder's pid, host, start time and command): a second writer, in this process or another, is
refused at once with the holder named (:class:`~navsim.foundations.errors.UsageError`, exit 2)
and nothing touched; a lock left by a killed process is taken over with a warning; the lock
goes with the last :class:`OutputFolder` of this process on the folder (re-entrant), at exit,
on an error, or with the process itself. A folder that is not empty and not navsim's (no
manifest, no navsim ``run.json``) is refused unless ``force``.

A folder holds one command's result: the manifest names the command that wrote it
(:data:`COMMANDS`), and another command writing there is refused (a :class:`UsageError` naming
what is there, even with ``force``), so that no command removes the files of another: ``navsim
compare --out`` into a run's folder leaves the run as it was. The same command writing again
replaces its own earlier files.

The manifest ``.navsim-files.json`` lists each file navsim wrote with its identity (size,
``mtime_ns``, inode, device); a new run in the same folder first removes the listed files that
are still regular files with that identity (never through a link) and nothing else; an old
manifest (a plain list of names) is read, but nothing it lists is removed. A file being written
is ``.<stem>.tmp<suffix>`` until it is complete, so a full disk or a kill leaves the earlier
file or none, never a truncated one. An :class:`OSError`, or any error caused by one (zlib's
after a full disk inside matplotlib's PDF writer), becomes an
:class:`~navsim.foundations.errors.OutputError` (exit code 4) naming the path.

Every JSON file navsim writes is strict JSON: :func:`strict_json` (NaN and infinities as null).

One module, over 600 lines, for one concept: the lock, the manifest and the atomic writes are the
three halves of "nothing another command wrote is lost", and each reads the others' state.
"""

from __future__ import annotations

import contextlib
import errno
import fnmatch
import json
import logging
import math
import numbers
import os
import socket
import stat
import sys
import threading
import time
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from navsim.foundations.config import plain_name
from navsim.foundations.errors import OutputError, UsageError

try:
    import fcntl
except ImportError:                      # not POSIX: an exclusive create and a pid check instead
    fcntl = None

log = logging.getLogger(__name__)
MANIFEST = ".navsim-files.json"
LOCK = ".navsim.lock"
#: the manifest's format: 3 names the command that wrote the folder; 2 lists each file's identity
#: without it; 1, a plain list of names (2 and 1 are only read)
MANIFEST_FORMAT = 3
#: the commands whose results an output folder holds, each its own (``navsim.write_report`` and
#: ``navsim.run`` write a run's result, ``"run"``; a run's failed flight goes to ``flight/``, ``"fly"``)
COMMANDS = ("run", "fly", "sensors", "sweep", "compare", "budget", "replay", "tune")
#: how the result of a folder written before format 3 is told: the first of these files its
#: manifest lists (navsim 0.3.0 and older wrote no command into it)
LEGACY_SIGNATURES = (("compare.json", "compare"), ("budget.json", "budget"), ("budget_part_*.npz", "budget"),
                     ("sweep.json", "sweep"),
                     ("truth.npz", "fly"), ("replay.pdf", "replay"), ("sensor_*.png", "sensors"),
                     ("run.json", "run"),
                     ("metrics.json", "run"))
#: the identity of a file navsim wrote, as the manifest records it
IDENTITY = ("size", "mtime_ns", "ino", "dev")
#: how many of a foreign folder's files a refusal names
SHOWN_FILES = 5
#: how many times a lock found taken is tried again (10 ms apart) before the writer is refused: a
#: reader testing it (:func:`writer`) holds it for microseconds
PROBE_RETRIES = 3
#: the most of a lock file or a run.json read to tell whose they are
READ_LIMIT = 1 << 20


def strict_json(obj, *, indent: int | None = 2, default=str) -> str:
    """``obj`` as strict JSON (``allow_nan=False``): NaN and ±inf as null, NumPy numbers and
    arrays as plain numbers and lists; ``default`` for anything else JSON lacks."""
    return json.dumps(_finite(obj), indent=indent, default=default, allow_nan=False)


def _finite(v):
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(x) for x in v]
    if isinstance(v, (bool, str)) or v is None:
        return v
    if isinstance(v, numbers.Integral):
        return int(v)
    if isinstance(v, numbers.Real):
        return float(v) if math.isfinite(v) else None
    if hasattr(v, "tolist") and hasattr(v, "dtype"):        # a NumPy array or scalar
        return _finite(v.tolist())
    return v


def temporary_name(path: Path) -> Path:
    """Where ``path`` is written before it is renamed: hidden, with the same suffix."""
    return path.with_name(f".{path.stem}.tmp{path.suffix}")


def _os_cause(exc: BaseException) -> OSError | None:
    """The :class:`OSError` behind ``exc`` (itself, or its cause or context, a few deep)."""
    for _ in range(8):
        if exc is None or isinstance(exc, OSError):
            return exc
        exc = exc.__cause__ or exc.__context__
    return None


def write_atomic(path: Path, write: Callable[[Path], object], *, fsync: bool = False) -> Path:
    """Call ``write(tmp)`` on :func:`temporary_name` of ``path`` and rename it to ``path``;
    with ``fsync`` the file and its folder are flushed to the disk first. On an error the
    temporary file is removed; an :class:`OSError`, or an error raised because of one (the
    ``zlib.error`` matplotlib's PDF writer raises after a full disk), becomes an
    :class:`OutputError`; ``path`` keeps its old content, if any."""
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
    except Exception as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        cause = _os_cause(exc)
        if cause is None:
            raise
        raise OutputError(path, cause) from None
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


def identity(path: Path) -> dict | None:
    """What the manifest records of a file (:data:`IDENTITY`), or None when ``path`` is not a
    regular file (missing, a link, a folder); links are not followed."""
    try:
        st = os.lstat(path)
    except OSError:
        return None
    if not stat.S_ISREG(st.st_mode):
        return None
    return {"size": st.st_size, "mtime_ns": st.st_mtime_ns, "ino": st.st_ino, "dev": st.st_dev}


# --- the folder's lock --------------------------------------------------------------------------


def _holder_text(raw: bytes) -> tuple[dict, str]:
    """The holder a lock file names, and it in words."""
    try:
        h = json.loads(raw.decode(errors="replace") or "{}")
    except ValueError:
        h = {}
    h = h if isinstance(h, dict) else {}
    return h, (f"pid {h.get('pid', '?')} on {h.get('host', '?')}, started {h.get('started', '?')}"
               f" ({h.get('command', '?')})")


def _pid_alive(pid) -> bool:
    if not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:                          # alive, another user's
        return True
    return True


def _refuse(folder: Path, holder: str):
    return UsageError(f"{folder}: in use by another navsim writer ({holder}); nothing was touched: "
                      "wait for it to finish, or write elsewhere with --out")


#: what flock raises on a file system without it (Lustre mounted without -o flock, some CIFS)
NO_FLOCK = {errno.ENOSYS, errno.ENOLCK, errno.EOPNOTSUPP, getattr(errno, "ENOTSUP", errno.EOPNOTSUPP)}


def _take_lock(folder: Path, flock: bool = fcntl is not None) -> int:
    """Take the lock of ``folder``; returns the lock file's descriptor (kept open while held).
    With ``flock``: ``fcntl.flock`` on the lock file (falling back, with a warning, where the file
    system has none); without: an exclusive create and the holder's pid checked."""
    path = folder / LOCK
    me = json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                     "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "command": " ".join(sys.argv)})
    for attempt in range(20):                # another process removing the file between our steps
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0)
                         | (0 if flock else os.O_EXCL), 0o644)
        except FileExistsError:              # no flock: held, or left by a dead process
            h, text = _holder_text(_read(path))
            if h.get("host") == socket.gethostname() and not _pid_alive(h.get("pid")):
                log.warning("%s: taking over the lock of %s, which is no longer running", folder, text)
                path.unlink(missing_ok=True)
                continue
            raise _refuse(folder, text) from None
        if flock:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                text = _holder_text(os.pread(fd, READ_LIMIT, 0))[1]
                os.close(fd)
                if attempt < PROBE_RETRIES:      # perhaps a reader's probe (:func:`writer`), held for microseconds
                    time.sleep(0.01)
                    continue
                raise _refuse(folder, text) from None
            except OSError as exc:
                empty = not os.pread(fd, 1, 0)
                os.close(fd)
                if exc.errno not in NO_FLOCK:
                    raise
                log.warning("%s: the file system has no flock (%s); locking by an exclusive create instead",
                            folder, exc.strerror)
                if empty:                    # the file this call created, no holder's
                    path.unlink(missing_ok=True)
                return _take_lock(folder, flock=False)
            if not _same_file(fd, path):     # removed by its holder as we opened it: again
                os.close(fd)
                continue
            earlier = os.pread(fd, READ_LIMIT, 0)
            if earlier.strip():
                log.warning("%s: taking over the lock of %s, which is no longer running", folder,
                            _holder_text(earlier)[1])
            os.ftruncate(fd, 0)
        os.pwrite(fd, me.encode(), 0)
        return fd
    raise OutputError(path, reason="the lock file keeps changing: another process is taking it")


def _read(path: Path) -> bytes:
    try:
        with open(path, "rb") as f:
            return f.read(READ_LIMIT)
    except OSError:
        return b""


def _same_file(fd: int, path: Path) -> bool:
    try:
        a, b = os.fstat(fd), os.stat(path)
    except OSError:
        return False
    return (a.st_ino, a.st_dev) == (b.st_ino, b.st_dev)


@dataclass
class _Held:
    """A folder this process holds: its lock, the users, the manifest's entries (name -> identity;
    None: not verifiable), the names written by this process, the folders it created."""

    fd: int
    count: int = 1
    entries: dict = field(default_factory=dict)
    mine: set = field(default_factory=set)
    legacy: list = field(default_factory=list)
    created: list = field(default_factory=list)
    command: str = "run"
    saved: bool = False
    #: the thread that holds it: another thread of this process is refused as another process is
    thread: int = field(default_factory=threading.get_ident)
    thread_name: str = field(default_factory=lambda: threading.current_thread().name)


#: the folders this process holds, by their real path
_HELD: dict[str, _Held] = {}


def _forget_locks() -> None:
    """In a forked child: the parent's locks are not the child's (the parent keeps them)."""
    for held in _HELD.values():
        with contextlib.suppress(OSError):
            os.close(held.fd)
    _HELD.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_locks)


def _release(key: str, folder: Path) -> None:
    """One user of ``folder`` less; the last one saves the manifest and gives the lock back."""
    held = _HELD.get(key)
    if held is None:
        return
    held.count -= 1
    if held.count > 0:
        return
    try:
        if held.mine or held.saved:
            _save(folder, held)
    finally:
        del _HELD[key]
        _give_back(folder, held.fd)
        for made in reversed(held.created):  # folders made for a command that wrote nothing
            with contextlib.suppress(OSError):
                made.rmdir()


# --- the manifest --------------------------------------------------------------------------------


@dataclass
class Manifest:
    """What a folder's manifest says: the files navsim wrote (name -> identity; None: not
    verifiable), the names of a format-1 list (never removed), and the command whose result the
    folder holds (None: no manifest, or one that does not tell)."""

    entries: dict = field(default_factory=dict)
    legacy: list = field(default_factory=list)
    command: str | None = None


def _legacy_command(names) -> str | None:
    """The command whose files ``names`` are, by :data:`LEGACY_SIGNATURES`."""
    names = set(names)
    return next((cmd for pattern, cmd in LEGACY_SIGNATURES if fnmatch.filter(names, pattern)), None)


def read_manifest(folder: Path) -> Manifest:
    """The folder's manifest (an empty one where there is none or it cannot be read); a
    manifest before format 3 names its command by the files it lists (:data:`LEGACY_SIGNATURES`)."""
    path = folder / MANIFEST
    if identity(path) is None:
        return Manifest()
    try:
        data = json.loads(_read(path).decode(errors="replace"))
    except ValueError:
        return Manifest()
    if isinstance(data, list):
        names = [n for n in data if isinstance(n, str) and plain_name(n)]
        return Manifest(legacy=names, command=_legacy_command(names))
    files = data.get("files") if isinstance(data, dict) else None
    if not isinstance(files, dict):
        return Manifest()
    ok = lambda i: isinstance(i, dict) and set(i) == set(IDENTITY) and all(type(i[k]) is int for k in IDENTITY)
    entries = {n: (i if ok(i) else None) for n, i in files.items() if isinstance(n, str) and plain_name(n)}
    command = data.get("command")
    if isinstance(command, str) and plain_name(command):      # a newer navsim's command too: named, never free
        return Manifest(entries, command=command)
    return Manifest(entries, command=_legacy_command(entries))


def folder_command(folder: Path) -> str | None:
    """The command whose result ``folder`` holds: its manifest's, else that of a navsim
    ``run.json`` there (``"run"``); None: neither."""
    command = read_manifest(folder).command
    if command is None and _is_navsim_run(folder / "run.json"):
        command = _legacy_command(os.listdir(folder)) or "run"
    return command


def writer(folder: Path) -> str | None:
    """The navsim process writing ``folder`` now, in words (pid, host, start, command); None when
    none holds its lock (or this thread does). Read-only: the lock is tested (a shared lock taken
    and given back at once; a writer starting meanwhile tries again, :func:`_take_lock`)."""
    held = _HELD.get(os.path.realpath(folder))
    if held is not None:
        return None if held.thread == threading.get_ident() else \
            f"pid {os.getpid()} (this process), its thread {held.thread_name}"
    path = folder / LOCK
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_CLOEXEC", 0))
    except OSError:
        return None
    try:
        raw = os.pread(fd, READ_LIMIT, 0)
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except BlockingIOError:
                return _holder_text(raw)[1]
            except OSError:                  # no flock here: the holder's pid tells
                pass
            else:
                return None
        h, text = _holder_text(raw)
        return text if h.get("host") == socket.gethostname() and _pid_alive(h.get("pid")) else None
    finally:
        os.close(fd)


def _save(folder: Path, held: _Held) -> None:
    """Write the manifest, with the identity of each file this process wrote as it is now."""
    for name in held.mine:
        held.entries[name] = identity(folder / name)
    data = {"format": MANIFEST_FORMAT, "command": held.command, "files": dict(sorted(held.entries.items()))}
    write_atomic(folder / MANIFEST, lambda p: p.write_text(json.dumps(data, indent=1)))
    held.saved = True


def _is_navsim_run(path: Path) -> bool:
    """Whether ``path`` is a ``run.json`` navsim wrote (its ``versions`` name navsim)."""
    if identity(path) is None:
        return False
    try:
        data = json.loads(_read(path).decode(errors="replace"))
    except ValueError:
        return False
    return isinstance(data, dict) and isinstance(data.get("versions"), dict) and "navsim" in data["versions"]


def foreign_files(folder: Path) -> list[str]:
    """The entries of an existing folder that make it not navsim's: none when it is missing,
    empty, or holds a manifest or a navsim ``run.json``; subfolders that are navsim output
    folders themselves (``flight/``, ``sensors/``) do not count. Folders end in ``/``."""
    try:
        names = sorted(os.listdir(folder))
    except (FileNotFoundError, NotADirectoryError):
        return []
    except OSError as exc:
        raise OutputError(folder, exc) from None
    if identity(folder / MANIFEST) is not None or _is_navsim_run(folder / "run.json"):
        return []
    out = []
    for name in names:
        if name == LOCK:
            continue
        path = folder / name
        if path.is_dir() and not path.is_symlink():
            if identity(path / MANIFEST) is None:
                out.append(name + "/")
        else:
            out.append(name)
    return out


def _listed(names: list[str]) -> str:
    """The first :data:`SHOWN_FILES` names, and how many more."""
    return ", ".join(names[:SHOWN_FILES]) + (f" and {len(names) - SHOWN_FILES} more" if len(names) > SHOWN_FILES else "")


def _refuse_foreign(folder: Path, names: list[str]) -> UsageError:
    shown = _listed(names)
    return UsageError(f"{folder}: not a navsim output folder (it holds {shown}); navsim writes into a new "
                      "or empty folder or one of its own results: choose another with --out, or write "
                      "here anyway with --force (files of the same names are then replaced)")


def _make_folders(path: Path) -> list[Path]:
    """Create ``path`` and its missing parents; returns those created, outermost first."""
    missing = [p for p in [path, *path.parents] if not p.exists()][::-1]
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(exc.filename or path, exc) from None
    return missing


def _refuse_other(folder: Path, command: str, theirs: str) -> UsageError:
    shown = _listed(sorted(n for n in os.listdir(folder) if n not in (LOCK, MANIFEST)))
    whose = theirs if theirs == UNTOLD else f"`navsim {theirs}`"
    return UsageError(f"{folder}: holds the result of {whose} ({shown or 'no file now'}); `navsim "
                      f"{command}` does not write into another command's folder, and nothing there was touched: "
                      "choose a folder of its own with --out (out=... in Python)")


def _open(path: Path, command: str, force: bool) -> _Held:
    """Lock a folder no user of this process holds; refuse another command's result, or a
    folder not navsim's without ``force``."""
    foreign = [] if force else foreign_files(path)
    if foreign:
        raise _refuse_foreign(path, foreign)
    created = _make_folders(path)
    try:
        fd = _take_lock(path)
    except BaseException as exc:             # the folders made for it go again, whatever failed
        _unmake(path, created)
        if isinstance(exc, OSError):
            raise OutputError(exc.filename or path / LOCK, exc) from None
        raise
    manifest = read_manifest(path)
    theirs = _holder_command(path, manifest)
    if theirs is not None and theirs != command:
        _give_back(path, fd)
        raise _refuse_other(path, command, theirs)
    return _Held(fd, entries=manifest.entries, legacy=manifest.legacy, created=created, command=command)


#: what a refusal calls a folder whose manifest lists files but not the command that wrote them
UNTOLD = "an earlier navsim command (its manifest does not say which)"


def _holder_command(path: Path, manifest: Manifest) -> str | None:
    """The command whose result ``path`` holds, for another command opening it: the manifest's
    (:data:`UNTOLD` where it lists files but cannot tell whose), else a navsim ``run.json``'s;
    None where no file the manifest lists is left (a result removed, or a failure's empty folder)."""
    listed = [n for n in [*manifest.entries, *manifest.legacy] if os.path.lexists(path / n)]
    if manifest.command is not None:
        return manifest.command if listed else None
    if listed:
        return folder_command(path) or UNTOLD
    return folder_command(path)


def _unmake(path: Path, created: list) -> None:
    """Remove the folders made for a folder that could not be opened (and its lock file)."""
    if created:
        with contextlib.suppress(OSError):
            (path / LOCK).unlink(missing_ok=True)
    for made in reversed(created):
        with contextlib.suppress(OSError):
            made.rmdir()


def _give_back(folder: Path, fd: int) -> None:
    """Release a lock this process took (its file removed when it is still ours)."""
    if _same_file(fd, folder / LOCK):
        with contextlib.suppress(OSError):
            (folder / LOCK).unlink()
    with contextlib.suppress(OSError):
        os.close(fd)


class OutputFolder:
    """The output folder of one command, locked while it is open.

    Parameters
    ----------
    path : Path
        The folder; created with its parents. A path naming a file, or a folder that cannot be
        created or written, raises :class:`OutputError`.
    command : str
        The command whose result the folder holds (one of :data:`COMMANDS`): a folder holding
        another command's result is refused (:class:`UsageError`, nothing touched).
    force : bool
        Write into a non-empty folder that is not navsim's (else a :class:`UsageError` naming
        its files, before anything is touched).

    The lock is taken at once: another writer holding the folder raises a :class:`UsageError`
    naming it. It is given back by :meth:`close` (or leaving a ``with`` block, or when the
    object is collected) of the last :class:`OutputFolder` of this process on the folder;
    those share the manifest.
    """

    def __init__(self, path: Path, *, command: str, force: bool = False):
        if command not in COMMANDS:
            raise ValueError(f"command {command!r}: expected one of {', '.join(COMMANDS)}")
        self.path = Path(path)
        if self.path.exists() and not self.path.is_dir():
            raise OutputError(self.path, reason="exists and is not a folder")
        key = os.path.realpath(self.path)
        held = _HELD.get(key)
        if held is not None and held.thread != threading.get_ident():
            raise _refuse(self.path, f"pid {os.getpid()} (this process), its thread {held.thread_name}")
        if held is not None and held.command != command:
            raise _refuse_other(self.path, command, held.command)
        if held is not None:
            held.count += 1
        else:
            held = _HELD[key] = _open(self.path, command, force)
        self._held = held
        self._close = weakref.finalize(self, _release, key, Path(key))   # absolute: a later chdir does not move it

    @property
    def command(self) -> str:
        """The command whose result the folder holds (:data:`COMMANDS`)."""
        return self._held.command

    def close(self) -> None:
        """Give this user's hold on the folder back (the last one saves the manifest and
        releases the lock); again: nothing."""
        self._close()

    def __enter__(self) -> "OutputFolder":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _save_manifest(self) -> None:
        _save(self.path, self._held)

    def clear_earlier(self) -> list[str]:
        """Remove the files an earlier run wrote here: those the manifest lists that are still
        regular files with the identity recorded (never a link, never a file changed since);
        returns them. An old manifest's files are left (they cannot be verified), with a warning."""
        held, removed, kept = self._held, [], []
        for name, ident in held.entries.items():
            target = self.path / name
            if name in held.mine:                  # this command's own
                continue
            if ident is None:
                kept += [name] if identity(target) is not None else []
                continue
            now = identity(target)
            try:
                if now == ident:
                    target.unlink()
                    removed.append(name)
                elif now is not None or os.path.lexists(target):
                    kept.append(name)
                tmp = temporary_name(target)       # left by a killed writer
                if identity(tmp) is not None:
                    tmp.unlink()
            except OSError as exc:
                raise OutputError(target, exc) from None
        kept += [n for n in held.legacy if os.path.lexists(self.path / n)]
        if kept:
            log.warning("%s: left %s in place: changed since navsim wrote them, or listed by an old "
                        "manifest without their identity", self.path, ", ".join(sorted(kept)))
        held.entries = {n: i for n, i in held.entries.items() if n in held.mine}
        held.legacy = []
        self._save_manifest()
        return removed

    def written(self) -> set[str]:
        """The names of the files this command wrote or kept here (:meth:`record`)."""
        return set(self._held.mine)

    def record(self, paths) -> None:
        """Add files written in the folder (by their own writers) to the manifest; their
        identity is taken when the manifest is saved (now, and when the folder is closed)."""
        here = self.path.resolve()
        names = [Path(p).name for p in paths if Path(p).parent.resolve() == here]
        self._held.mine.update(names)
        self._held.entries.update({n: None for n in names if n not in self._held.entries})
        self._save_manifest()

    def write(self, name: str, write: Callable[[Path], object]) -> Path:
        """Write the file ``name`` with ``write(tmp_path)`` (see :func:`write_atomic`)."""
        self.record([self.path / name])
        path = write_atomic(self.path / name, write)
        self._save_manifest()
        return path

    def text(self, name: str, text: str) -> Path:
        """Write ``text`` to the file ``name``."""
        return self.write(name, lambda p: p.write_text(text))

    def json(self, name: str, obj, **kw) -> Path:
        """Write ``obj`` as strict JSON (:func:`strict_json`) to the file ``name``."""
        return self.text(name, strict_json(obj, **kw))
