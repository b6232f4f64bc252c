"""A result folder's files as :func:`navsim.compare` reads them, and what two results share:
whether they flew the same flights and sensor data (then they pair run by run) and whether their
metrics can be compared at all.

Read: ``metrics.json``, ``run.json``, ``scenario.resolved.yaml`` and ``samples.npz`` (each run's
part of the metrics, :mod:`navsim.records.samples`); nothing is written. A folder that lacks one
of them, one of them damaged (named with its key path), a ``samples.npz`` an older navsim wrote
or a result a newer navsim wrote is refused with a
:class:`~navsim.foundations.errors.UsageError` naming it.
"""

from __future__ import annotations

import dataclasses
import json
import re
import typing
from dataclasses import dataclass
from pathlib import Path

import yaml

from navsim.foundations.errors import UsageError
from navsim.foundations.outputs import writer
from navsim.records.metrics import MetricsError, RunMetrics, check_typed, read_metrics
from navsim.records.run import RunRecord
from navsim.records.samples import SAMPLES_FILE, EstimatorSamples, load_samples
from navsim.version import __version__

#: the first navsim that writes ``samples.npz``
SAMPLES_SINCE = (0, 2, 0)
#: the keys of a resolved scenario that do not change the flights or the sensor data: what is
#: estimated, how many runs and workers, the paper's numbers, the names
NOT_THE_DATA = ("name", "description", "estimators", "reference", "report")
NOT_THE_DATA_MONTECARLO = ("runs", "workers")
#: the keys that make the metrics: results that differ here cannot be compared
METRIC_SET = ("metrics",)


@dataclass(frozen=True)
class ResultFiles:
    """A finished (or interrupted) run's files."""

    folder: Path | str                            #: a result held in memory: its scenario's name
    metrics: RunMetrics
    record: RunRecord
    resolved: dict                                #: scenario.resolved.yaml
    samples: dict[str, EstimatorSamples]

    @property
    def version(self) -> str:
        return str(self.record.versions.get("navsim", "unknown"))


def _version(text: str) -> tuple:
    """``"0.2.0rc1"`` -> ``(0, 2, 0)``: the leading digits of the first three parts (``()``
    for none)."""
    out = []
    for part in text.split("+")[0].split(".")[:3]:
        digits = re.match(r"\d+", part)
        if digits is None:
            break
        out.append(int(digits.group()))
    return tuple(out)


def check_not_being_written(folder: Path) -> None:
    """A :class:`UsageError` when a navsim process is writing ``folder`` now (its lock held):
    its files are not a result yet."""
    busy = writer(Path(folder))
    if busy is not None:
        raise UsageError(f"{folder}: being written by another navsim ({busy}); its result is not complete: "
                         "wait for that command to finish, then read it")


def read_record(path: Path) -> RunRecord:
    """``run.json`` at ``path``, each field of the type :class:`RunRecord` declares; a file that
    is not JSON or not a record is a :class:`UsageError` naming the file and the key."""
    hint = "hint: navsim run writes it; run the scenario again (or undo the edit)"
    try:
        raw = json.loads(Path(path).read_bytes())
    except (UnicodeDecodeError, ValueError) as exc:
        raise UsageError(f"{path}: not JSON ({exc}); {hint}") from None
    if not isinstance(raw, dict):
        raise UsageError(f"{path}: holds {type(raw).__name__}, not a mapping; {hint}")
    try:
        record = RunRecord.from_dict(raw)
    except (ValueError, TypeError, AttributeError) as exc:
        raise UsageError(f"{path}: failed_runs: {exc} (expected run number -> why); {hint}") from None
    hints = typing.get_type_hints(RunRecord)
    for f in dataclasses.fields(record):
        try:
            check_typed(hints[f.name], getattr(record, f.name), f.name)
        except MetricsError as exc:
            raise UsageError(f"{path}: {exc}; {hint}") from None
    return record


def read_files(folder: Path) -> tuple[RunMetrics, RunRecord, dict]:
    """``metrics.json``, ``run.json`` and ``scenario.resolved.yaml`` of a result folder, checked;
    :class:`UsageError` naming the file (and the key) missing or damaged; ``OSError`` where one
    cannot be read."""
    missing = [n for n in ("metrics.json", "run.json", "scenario.resolved.yaml") if not (folder / n).is_file()]
    if missing:
        raise UsageError(f"{folder}: not a navsim result (no {', '.join(missing)}); "
                         "hint: pass the folder navsim run wrote (its --out)")
    metrics, record = read_metrics(folder / "metrics.json"), read_record(folder / "run.json")
    try:
        resolved = yaml.safe_load((folder / "scenario.resolved.yaml").read_bytes())
    except yaml.YAMLError as exc:
        raise UsageError(f"{folder}/scenario.resolved.yaml: not YAML ({exc}); hint: run the scenario again") from None
    if not isinstance(resolved, dict):
        raise UsageError(f"{folder}/scenario.resolved.yaml: expected a mapping; hint: run the scenario again")
    return metrics, record, resolved


def check_version(folder, record: RunRecord) -> None:
    """:class:`UsageError` for a result written by a navsim before :data:`SAMPLES_SINCE` or
    after this one (:data:`navsim.version.__version__`: its files may hold what this one does
    not read)."""
    version = str(record.versions.get("navsim", "unknown"))
    since = ".".join(map(str, SAMPLES_SINCE))
    if _version(version) < SAMPLES_SINCE:
        raise UsageError(f"{folder}: written by navsim {version}, before the per-run samples a comparison reads "
                         f"(navsim {since}); hint: run its scenario again with this navsim")
    if _version(version) > _version(__version__):
        raise UsageError(f"{folder}: written by navsim {version}, newer than this navsim {__version__}; hint: "
                         "compare it with that navsim, or run its scenario again with this one")


def read_result(folder) -> ResultFiles:
    """The files of the result in ``folder``; :class:`UsageError` for a folder that is not a
    result, a damaged file, or a result written by a navsim before :data:`SAMPLES_SINCE` or
    after this one."""
    folder = Path(folder)
    if not folder.is_dir():
        raise UsageError(f"{folder}: no such folder (expected a result folder of navsim run)")
    check_not_being_written(folder)
    try:
        metrics, record, resolved = read_files(folder)
    except OSError as exc:
        raise UsageError(f"{folder}: not a readable navsim result ({exc.strerror or exc})") from None
    check_version(folder, record)
    if not (folder / SAMPLES_FILE).is_file():
        raise UsageError(f"{folder}: no {SAMPLES_FILE} (each run's part of the metrics, what a comparison reads); "
                         "hint: run its scenario again")
    try:
        samples = load_samples(folder / SAMPLES_FILE)
    except OSError as exc:
        raise UsageError(f"{folder}/{SAMPLES_FILE}: not readable ({exc.strerror or exc}); hint: run its scenario "
                         "again") from None
    return ResultFiles(folder, metrics, record, resolved, samples)


def the_data(resolved: dict) -> dict:
    """The part of a resolved scenario that makes the flights and sensor data (every key but
    :data:`NOT_THE_DATA` and the Monte Carlo's run and worker counts)."""
    out = {k: v for k, v in resolved.items() if k not in NOT_THE_DATA}
    mc = dict(out.get("montecarlo") or {})
    for k in NOT_THE_DATA_MONTECARLO:
        mc.pop(k, None)
    out["montecarlo"] = mc
    return out


def check_comparable(a: ResultFiles, b: ResultFiles) -> None:
    """:class:`UsageError` when two results cannot be compared: different tracks, or different
    metric settings (settling time, windows)."""
    ta, tb = a.resolved.get("track"), b.resolved.get("track")
    if ta != tb:
        raise UsageError(f"{a.folder} flew track {ta!r}, {b.folder} track {tb!r}: errors on different "
                         "flights are not comparable; hint: compare results of one track")
    for key in METRIC_SET:
        if a.resolved.get(key) != b.resolved.get(key):
            raise UsageError(f"{a.folder} and {b.folder} score differently ({key}: {a.resolved.get(key)!r} "
                             f"against {b.resolved.get(key)!r}): their metrics are not the same quantities")


def pairing(a: ResultFiles, b: ResultFiles) -> tuple[bool, str]:
    """Whether the two results flew the same flights and sensor data (then their runs pair by
    number), and why: from the resolved scenarios' content, the flight's cache key and, where
    both runs recorded one, their data key (:func:`navsim.experiment.runner.data_key`: the
    sensor models as resolved, which a model file's path alone does not tell)."""
    if a is b:
        return True, "one result: the same runs"
    da, db = the_data(a.resolved), the_data(b.resolved)
    differ = sorted(k for k in set(da) | set(db) if da.get(k) != db.get(k))
    if a.record.flight_key != b.record.flight_key:
        differ.append("flight")
    keyed = bool(a.record.data_key and b.record.data_key)
    if keyed and a.record.data_key != b.record.data_key and not differ:
        differ.append("the resolved sensor models or the flown estimator")    # a model file's content
    if differ or (keyed and a.record.data_key != b.record.data_key):
        return False, f"not the same sensor data (they differ in {', '.join(differ)}): unpaired"
    return True, "the same flight, sensors, initial errors and seed: paired run by run"
