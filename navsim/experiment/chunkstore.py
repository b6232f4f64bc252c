"""Streaming Monte Carlo results: each finished chunk of runs on disk as it completes.

A :class:`ChunkStore` is a folder (``<out>/chunks`` for ``navsim run``) holding one
``chunk_<first>-<last>.npz`` per finished chunk and an ``index.json`` that names the run it
belongs to (scenario content hash, seed, runs, chunk size), the chunks done and the chunks that
failed with their error. Chunk files and the index are written to a temporary name and renamed,
so a run killed at any moment leaves a consistent folder that ``navsim run --resume`` completes.

A chunk is the worker's :class:`~navsim.records.chunk.ChunkPart`; every field of
:class:`~navsim.records.history.EstimatorHistory`, :class:`~navsim.records.truth.TruthBias` and
:class:`~navsim.records.truth.CalibrationHistory` round-trips exactly: arrays are stored as they are
(no pickle; ``h<i>.<field>``, ``bias.<field>``, ``c<i>.<field>``), the per-run reset events, the NIS
names and dimensions, the cost and the names of the bias and calibration arrays held go to a JSON
string inside the same file.

Each chunk file also carries its identity (``ident``: the store's key, i.e. the scenario hash,
seed, runs and chunk size, and the chunk's first and last run), checked whenever a chunk is
read (resume, :meth:`ChunkStore.open`, :meth:`ChunkStore.parts`, :meth:`ChunkStore.merged`): a
chunk of another run, a chunk whose runs are not the ones its name says, or an index listing
chunks outside the run is refused with a :class:`ResumeError`, never merged. The store never
deletes through a symbolic link: a ``chunks`` folder that is a link, or listed files that are
links, are refused.
"""

from __future__ import annotations

import json
import logging
import os
import re
import stat
import zipfile
from pathlib import Path

import numpy as np

from navsim.foundations.config import MAX_RUNS
from navsim.foundations.errors import OutputError, UsageError
from navsim.foundations.outputs import temporary_name, write_atomic
from navsim.records.chunk import ChunkPart
from navsim.records.cost import sum_cost
from navsim.records.history import ARRAY_FIELDS, ARRAYS, EstimatorHistory
from navsim.records.truth import CALIBRATION_SHARED, CalibrationHistory, TruthBias

log = logging.getLogger(__name__)
INDEX = "index.json"
_ARRAYS = ARRAY_FIELDS
#: the entry of a chunk file holding its identity (JSON: the store's key and ``chunk``)
IDENT = "ident"
#: the entries of a chunk file that are not arrays over its runs
_META_ENTRIES = ("meta", IDENT)
#: the history arrays (``h<i>.<name>``) without a run axis, the same in every chunk
_HISTORY_SHARED = tuple(name for name in _ARRAYS if "run" not in ARRAYS[name][0])
#: the index's entries -> the JSON type they must have (the key's and the chunk lists)
INDEX_TYPES = {"scenario_hash": str, "seed": int, "runs": int, "chunk_runs": int, "chunks": dict, "failed": dict}


class ResumeError(UsageError):
    """A chunk folder that cannot be used: missing, written for another run, holding chunks of
    another run, damaged in a way that cannot be repaired by running again."""


def chunk_name(runs) -> str:
    """``"<first>-<last>"`` of a chunk of run indices."""
    runs = list(runs)
    return f"{runs[0]}-{runs[-1]}"


def _savez(path: Path, arrays: dict) -> None:
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def job_chunks(runs: int, size: int) -> list[range]:
    """Runs ``0 .. runs-1`` cut into chunks of ``size`` (``size`` at least 1)."""
    return [range(a, min(a + size, runs)) for a in range(0, runs, size)]


def part_arrays(part: ChunkPart, ident: dict | None = None) -> dict:
    """The arrays of a chunk part for :func:`numpy.savez`, with a JSON ``meta`` entry and, with
    ``ident`` (the store's key), the JSON identity entry :data:`IDENT`."""
    runs, hist, calib = part.runs, part.histories, part.calibration
    bias = part.truth_bias.arrays() if part.truth_bias is not None else {}
    arrays = {"runs": np.asarray(list(runs), dtype=np.int64)}
    meta = {"labels": list(hist), "bias": list(bias), "calibration": {}, "histories": []}
    for i, (label, h) in enumerate(hist.items()):
        present = [name for name in _ARRAYS if getattr(h, name) is not None]
        arrays.update({f"h{i}.{name}": getattr(h, name) for name in present})
        arrays.update({f"h{i}.nis{j}": v for j, v in enumerate(h.nis.values())})
        meta["histories"].append({
            "arrays": present, "nis": list(h.nis), "nis_dim": h.nis_dim, "cost": h.cost,
            "resets": h.resets, "divergence": getattr(h, "divergence", None)})
    arrays.update({f"bias.{k}": np.asarray(v) for k, v in bias.items()})
    for i, (name, c) in enumerate(calib.items()):
        meta["calibration"][name] = list(c.arrays())
        arrays.update({f"c{i}.{k}": np.asarray(v) for k, v in c.arrays().items()})
    arrays["meta"] = np.array(json.dumps(meta, default=float))
    if ident is not None:
        runs = list(part.runs)
        arrays[IDENT] = np.array(json.dumps({**ident, "chunk": [int(runs[0]), int(runs[-1])]},
                                            default=lambda v: v.item() if hasattr(v, "item") else str(v)))
    return arrays


def part_from_arrays(data) -> ChunkPart:
    """The chunk part stored by :func:`part_arrays`."""
    meta = json.loads(str(data["meta"]))
    hist = {}
    for i, (label, m) in enumerate(zip(meta["labels"], meta["histories"])):
        fields = {name: data[f"h{i}.{name}"] for name in m["arrays"]}
        resets, divergence = m["resets"], m.get("divergence")
        hist[label] = EstimatorHistory(
            label=label, **{name: fields.get(name) for name in _ARRAYS},
            nis={k: data[f"h{i}.nis{j}"] for j, k in enumerate(m["nis"])}, nis_dim=m["nis_dim"],
            cost=m["cost"],
            resets=None if resets is None else [[tuple(e) for e in run] for run in resets],
            divergence=None if divergence is None else [None if r is None else (float(r[0]), str(r[1]))
                                                        for r in divergence])
    bias = TruthBias.from_arrays({k: data[f"bias.{k}"] for k in meta["bias"]})
    calib = {name: CalibrationHistory.from_arrays({k: data[f"c{i}.{k}"] for k in keys})
             for i, (name, keys) in enumerate(meta["calibration"].items())}
    return ChunkPart(list(data["runs"].tolist()), hist, bias, calib)


_CHUNK_FILE = re.compile(r"^chunk_\d+-\d+\.npz$")
_CHUNK_NAME = re.compile(r"^\d{1,12}-\d{1,12}$")


def chunk_runs(name: str) -> range:
    """The runs of a chunk named ``"<first>-<last>"``."""
    first, last = name.split("-")
    return range(int(first), int(last) + 1)


def listed_runs(folder: Path) -> list:
    """The runs the index of ``folder`` lists, in order, read from the index alone (the chunk
    files are not opened; :meth:`ChunkStore.open` checks them); none without a readable index."""
    try:
        index = ChunkStore.read_index(folder) or {}
    except ResumeError:
        return []
    names = sorted(_chunk_files(index), key=lambda n: chunk_runs(n)[0])
    if sum(len(chunk_runs(n)) for n in names) > MAX_RUNS:     # counted before any list is built
        raise ResumeError(f"{folder / INDEX}: lists more than {MAX_RUNS} runs; the folder was altered: "
                          "run again without --resume")
    return [r for n in names for r in chunk_runs(n)]


def _chunk_files(index: dict) -> dict:
    """Chunk name -> file name of the chunks an index lists (plain chunk file names only, of
    runs ``first <= last`` below :data:`~navsim.foundations.config.MAX_RUNS`)."""
    chunks = index.get("chunks") if isinstance(index, dict) else None
    if not isinstance(chunks, dict):
        return {}
    return {n: f for n, f in chunks.items()
            if isinstance(f, str) and _CHUNK_FILE.fullmatch(f) and f == f"chunk_{n}.npz" and _plain_span(n)}


def _plain_span(name: str) -> bool:
    """Whether a chunk name ``"<first>-<last>"`` is a span of runs a job can have."""
    first, last = (int(x) for x in name.split("-"))
    return first <= last < MAX_RUNS


def _readable(path: Path) -> bool:
    """Whether a stored chunk file is whole (its zip CRCs check); a truncated or damaged one is
    run again on resume."""
    try:
        with zipfile.ZipFile(path) as z:
            return z.testzip() is None
    except (OSError, zipfile.BadZipFile, EOFError, ValueError):
        return False


def _shared(key: str) -> bool:
    """Whether an array of a stored part is the same for every chunk (no leading run axis): the
    JSON entries, a history's arrays declared without a run axis (``h<i>.t_s``) and a calibration
    history's (``c<i>.t_s``, ``c<i>.turns``)."""
    group, _, name = key.partition(".")
    if key in _META_ENTRIES:
        return True
    if re.fullmatch(r"h\d+", group):
        return name in _HISTORY_SHARED
    return bool(re.fullmatch(r"c\d+", group)) and name in CALIBRATION_SHARED


def check_index(index, path: Path) -> dict:
    """``index`` (read from ``path``) if it is a chunk index: a mapping whose entries of
    :data:`INDEX_TYPES` have their types (``runs`` at least 0, ``chunk_runs`` at least 1, the
    chunk lists mapping names to text); a :class:`ResumeError` naming the entry otherwise."""
    if not isinstance(index, dict):
        raise ResumeError(f"{path}: not a chunk index (expected a JSON object, found {type(index).__name__})")
    for key, tp in INDEX_TYPES.items():
        if key not in index:
            continue
        value = index[key]
        bad = not isinstance(value, tp) or isinstance(value, bool)
        if not bad and tp is int:
            bad = not (1 if key == "chunk_runs" else 0) <= value <= MAX_RUNS
        if not bad and tp is dict:
            bad = not all(isinstance(k, str) and isinstance(v, str) for k, v in value.items())
        if bad:
            what = {str: "text", int: f"a whole number {1 if key == 'chunk_runs' else 0}-{MAX_RUNS}",
                    dict: "a mapping of chunk names to text"}[tp]
            raise ResumeError(f"{path}: {key} is {value!r} (expected {what}); the folder was not written by "
                              "this navsim: run without --resume into a fresh folder")
    for name in index.get("chunks") or {}:
        if not (_CHUNK_NAME.fullmatch(name) and _plain_span(name)):
            raise ResumeError(f"{path}: lists chunk {name!r}, which is no span of runs (expected "
                              f"'<first>-<last>', first <= last < {MAX_RUNS}); the folder was altered: run "
                              "again without --resume")
    return index


def _span(runs: list) -> str:
    """``"a-b"`` of a list of runs (``"none"`` when empty)."""
    return f"{runs[0]}-{runs[-1]}" if runs else "none"


def _read_entry(data, name: str):
    """A JSON entry of a chunk file, or None when the file has none."""
    return json.loads(str(data[name])) if name in data.files else None


class ChunkStore:
    """The chunks of one Monte Carlo run in ``folder``, and its ``index.json``.

    A store is opened for one of three things, said explicitly: to write a new run
    (``mode="new"``: the chunks the folder's index lists are removed first, nothing else), to
    complete an interrupted one (``mode="resume"``), or to read one back (:meth:`open`: nothing
    in the folder is written or removed).

    Parameters
    ----------
    folder : Path
        Where the chunk files and the index live (created).
    key : dict
        What identifies the run: ``scenario_hash`` (:func:`navsim.experiment.runner.scenario_hash`), ``seed``,
        ``runs``, ``chunk_runs``.
    mode : {"new", "resume"}
        ``resume``: keep the chunks of an earlier, matching run (a :class:`ResumeError` if the
        folder holds none or another run's); ``new``: the folder's earlier chunks are removed.
    """

    def __init__(self, folder: Path, key: dict, mode: str):
        if mode not in ("new", "resume"):
            raise ValueError(f"mode {mode!r}: expected 'new' or 'resume' (ChunkStore.open reads a store)")
        self.folder = Path(folder)
        self.key = dict(key)
        self.done: dict = {}         #: chunk name -> file name
        self.failed: dict = {}       #: chunk name -> error message
        self.read_only = False
        self._refuse_links()
        if mode == "resume":
            self._reopen()
        else:
            self._clear()
        self._write_index()

    @classmethod
    def open(cls, folder: Path) -> "ChunkStore":
        """The store in ``folder``, read-only: its key and failed chunks from the index, the
        chunks it lists that are whole; nothing is written or removed (:meth:`add` and
        :meth:`flag` refuse). A :class:`ResumeError` when the folder has no index."""
        index = cls.read_index(folder)
        if index is None:
            raise ResumeError(f"no stored chunks in {folder}: no {INDEX}")
        store = cls.__new__(cls)
        store.folder, store.read_only = Path(folder), True
        store.key = {k: v for k, v in index.items() if k not in ("chunks", "failed")}
        listed = store._check_listed(_chunk_files(index))
        store.done = {name: file for name, file in listed.items() if _readable(store.folder / file)}
        for file in store._files():
            store._check_file(file)
        failed = index.get("failed")
        store.failed = dict(failed) if isinstance(failed, dict) else {}
        return store

    @staticmethod
    def read_index(folder: Path) -> dict | None:
        """The index of ``folder``, or None when there is none."""
        path = Path(folder) / INDEX
        if not path.is_file():
            return None
        try:
            index = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise ResumeError(f"{path}: unreadable index ({exc})") from None
        return check_index(index, path)

    def _refuse_links(self) -> None:
        """A :class:`UsageError` when the folder, its index or a chunk file it lists is a
        symbolic link (or not a plain file): writing or clearing it would reach another folder."""
        if self.folder.is_symlink():
            raise UsageError(f"{self.folder}: is a symbolic link (to {os.readlink(self.folder)}); navsim writes "
                             "and removes chunks only in a folder of its own: remove the link, or write elsewhere "
                             "with --out")
        try:
            index = self.read_index(self.folder) if not (self.folder / INDEX).is_symlink() else None
        except ResumeError:
            index = None
        for file in (INDEX, *_chunk_files(index or {}).values()):
            for path in (self.folder / file, temporary_name(self.folder / file)):
                try:
                    mode = os.lstat(path).st_mode
                except OSError:
                    continue
                if not stat.S_ISREG(mode):
                    kind = "a symbolic link" if stat.S_ISLNK(mode) else "not a plain file"
                    raise UsageError(f"{path}: is {kind}; navsim writes and removes only plain files it wrote: "
                                     "remove it, or write elsewhere with --out")

    def _check_listed(self, listed: dict) -> dict:
        """``listed`` (chunk name -> file) if every chunk is one of the run's
        (:func:`job_chunks` of the key's ``runs`` and ``chunk_runs``); a :class:`ResumeError`
        naming the first that is not."""
        runs, size = self.key.get("runs"), self.key.get("chunk_runs")
        if not (isinstance(runs, int) and isinstance(size, int) and size >= 1):
            return listed
        expected = {chunk_name(ch) for ch in job_chunks(runs, size)}
        for name in sorted(set(listed) - expected, key=lambda n: chunk_runs(n)[0]):
            raise ResumeError(f"{self.folder / INDEX}: lists chunk {name}, which is not a chunk of this run "
                              f"({runs} runs in chunks of {size}); the folder was altered: run again without "
                              "--resume")
        return listed

    def _check_file(self, file: str) -> None:
        """Open a stored chunk and check it (:meth:`_check_data`)."""
        with np.load(self.folder / file, allow_pickle=False) as data:
            self._check_data(file, data)

    def _check_data(self, file: str, data) -> None:
        """A :class:`ResumeError` naming ``file`` unless the chunk's runs are those of its name and
        its identity (:data:`IDENT`) matches the store's key. A chunk without an identity (written
        by an older navsim, whose index the store's key was checked against) is taken with a warning."""
        path = self.folder / file
        named = list(chunk_runs(file[len("chunk_"):-len(".npz")]))
        try:
            held = [int(r) for r in np.asarray(data["runs"]).reshape(-1)]
            ident = _read_entry(data, IDENT)
        except (KeyError, ValueError, TypeError) as exc:
            raise ResumeError(f"{path}: not a navsim chunk ({type(exc).__name__}: {exc})") from None
        if held != named:
            raise ResumeError(f"{path}: holds runs {_span(held)} but its name says {_span(named)}; the folder "
                              "was altered: run again without --resume")
        if ident is None or not isinstance(ident, dict):   # an older navsim's: a campaign goes on after an upgrade
            log.warning("%s: carries no identity (written by an older navsim): its runs checked against its "
                        "name, its run against the index only", path)
            return
        want = {**self.key, "chunk": [named[0], named[-1]]}
        diff = [f"{k} {ident.get(k)!r} in the chunk, {v!r} in the index" for k, v in want.items()
                if ident.get(k) != v]
        if diff:
            raise ResumeError(f"{path}: belongs to another run ({'; '.join(diff)}); it is not merged: remove it, "
                              "or run again without --resume")

    def _reopen(self) -> None:
        index = self.read_index(self.folder)
        if index is None:
            raise ResumeError(f"nothing to resume in {self.folder}: no {INDEX} (run without --resume)")
        diff = [f"{k} {index.get(k)!r} there, {v!r} now" for k, v in self.key.items() if index.get(k) != v]
        if diff:
            raise ResumeError(f"{self.folder} holds another run ({'; '.join(diff)}); resume it with the same "
                              "scenario, seed, runs and chunk size, or run without --resume")
        listed = self._check_listed(_chunk_files(index))
        self.done = {name: file for name, file in listed.items() if _readable(self.folder / file)}
        for name in sorted(set(listed) - set(self.done)):
            log.warning("%s: chunk %s is missing or damaged; its runs are run again", self.folder, name)
        for file in self._files():           # before anything runs: never merged with another run's
            self._check_file(file)

    def _clear(self) -> None:
        """Remove the chunk files the folder's index lists (and their temporary files) that are
        plain files (``lstat``: a link is never followed; :meth:`_refuse_links` refused them),
        nothing else: a folder without an index is left as it is."""
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            index = self.read_index(self.folder)
        except (OSError, ResumeError):
            index = None
        for file in _chunk_files(index or {}).values():
            for path in (self.folder / file, temporary_name(self.folder / file)):
                try:
                    if stat.S_ISREG(os.lstat(path).st_mode):
                        path.unlink()
                except FileNotFoundError:
                    continue
                except OSError as exc:
                    raise OutputError(path, exc) from None

    def _writable(self) -> None:
        if self.read_only:
            raise ResumeError(f"{self.folder}: opened read-only (ChunkStore.open); nothing was written")

    def _write_index(self) -> None:
        self._writable()
        index = {**self.key, "chunks": self.done, "failed": self.failed}
        write_atomic(self.folder / INDEX, lambda p: p.write_text(json.dumps(index, indent=1)), fsync=True)

    def missing(self, chunks: list) -> list:
        """The chunks of ``chunks`` (ranges of run indices) not stored yet."""
        return [ch for ch in chunks if chunk_name(ch) not in self.done]

    def add(self, part) -> None:
        """Store a finished chunk part and record it in the index."""
        self._writable()
        name = chunk_name(part.runs)
        file = f"chunk_{name}.npz"
        write_atomic(self.folder / file, lambda p: _savez(p, part_arrays(part, self.key)), fsync=True)
        self.done[name] = file
        self.failed.pop(name, None)
        self._write_index()

    def flag(self, failed_chunks: dict) -> None:
        """Record chunks that failed (chunk name -> error message) in the index."""
        self._writable()
        self.failed.update(failed_chunks)
        self._write_index()

    def _names(self) -> list:
        return sorted(self.done, key=lambda n: chunk_runs(n)[0])

    def _files(self) -> list:
        return [self.done[n] for n in self._names()]

    def parts(self):
        """The stored :class:`~navsim.records.chunk.ChunkPart` one at a time,
        in run order (one chunk in memory at a time)."""
        for file in self._files():
            with np.load(self.folder / file, allow_pickle=False) as data:
                self._check_data(file, data)
                part = part_from_arrays({k: data[k] for k in data.files})
            yield part

    def runs(self) -> list:
        """The run indices stored, in order."""
        return [r for n in self._names() for r in chunk_runs(n)]

    def _copy_rows(self, file: str, first: str, data, out: dict, offset: int) -> int:
        """Copy a chunk's rows into the merged arrays ``out`` at ``offset``; returns its number of
        runs. A chunk whose fields, shapes, epochs or estimators differ from the first chunk's
        (``first``) is refused with a :class:`ResumeError` (else rows would stay uninitialised or
        mix two runs)."""
        path = self.folder / file
        if set(data.files) != set(out):
            raise ResumeError(f"{path}: holds other fields than {first} "
                              f"({', '.join(sorted(set(data.files) ^ set(out)))})")
        labels = json.loads(str(data["meta"])).get("labels")
        if labels != json.loads(str(out["meta"])).get("labels"):
            raise ResumeError(f"{path}: holds the estimators {labels}, {first} others; it is not merged")
        n = len(data["runs"])
        for k in data.files:
            if k in _META_ENTRIES:
                continue
            a, want = data[k], out[k]
            if _shared(k):
                if a.shape != want.shape or not np.array_equal(a, want, equal_nan=a.dtype.kind == "f"):
                    raise ResumeError(f"{path}: {k} differs from {first}'s ({a.shape[0] if a.ndim else a} "
                                      f"against {want.shape[0] if want.ndim else want} epochs or other times); "
                                      "it is of another run and is not merged")
            elif a.shape[:1] != (n,) or a.shape[1:] != want.shape[1:] or offset + n > len(want):
                raise ResumeError(f"{path}: {k} has the shape {a.shape}, {first}'s rows {want.shape[1:]} "
                                  f"({n} runs); it is of another run and is not merged")
            else:
                want[offset:offset + n] = a
        return n

    def merged(self, limit: int | None = None) -> ChunkPart | None:
        """The stored chunks as one :class:`~navsim.records.chunk.ChunkPart`, or None:
        all of them, or the first chunks (in run order) that hold ``limit`` runs.

        The chunk files are read one at a time into arrays allocated once for all the runs, so
        the peak memory is the merged result plus one chunk (not twice the result).
        """
        files, sizes = [], []
        for file in self._files():
            if limit is not None and sum(sizes) >= limit:
                break
            files.append(file)
            sizes.append(len(chunk_runs(file[len("chunk_"):-len(".npz")])))
        if not files:
            return None
        with np.load(self.folder / files[0], allow_pickle=False) as first:
            meta = json.loads(str(first["meta"]))
            total = sum(sizes)
            out = {k: first[k] if _shared(k) else np.empty((total, *first[k].shape[1:]), first[k].dtype)
                   for k in first.files}
        metas, offset = [], 0
        for file in files:
            with np.load(self.folder / file, allow_pickle=False) as data:
                self._check_data(file, data)
                offset += self._copy_rows(file, files[0], data, out, offset)
                metas.append(json.loads(str(data["meta"])))
        for i, h in enumerate(meta["histories"]):
            parts = [m["histories"][i] for m in metas]
            h["cost"] = sum_cost([m["cost"] for m in parts])
            h["resets"] = None if h["resets"] is None else [r for m in parts for r in m["resets"]]
            if any(m.get("divergence") is not None for m in parts):
                h["divergence"] = [r for m, n in zip(parts, sizes) for r in (m.get("divergence") or [None] * n)]
        out["meta"] = np.array(json.dumps(meta))
        return part_from_arrays(out)
