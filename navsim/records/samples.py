"""Each run's part of an estimator's metrics, kept beside ``metrics.json`` in ``samples.npz``:
what :func:`navsim.compare` pairs run by run.

A metric that is a ratio of sums over the runs (a mean square over runs and epochs, a mean)
is kept as each run's sum ``s`` and count ``n``, ``(B, k)`` for its ``k`` components (N, E, D;
the nine states); its value over any set of runs is ``sum(s) / sum(n)``, under a square root
for an RMS (``root``). Kept: ``rms.*``, ``final.*``, ``attitude.rms_deg``, ``nees.average``
(the pooled mean over runs and scored epochs: ``metrics.json``'s average of the per-epoch
means where every run has every epoch), ``nees.per_state``, the windows' ``rms`` and the
landmarks' ``rms_after_m``.

Percentiles, maxima, window extremes and standard deviations, convergence times and reset
counts are not ratios of per-run sums: each run's own value of the same statistic (its p99, its
largest error, its std about its own mean, ...) is kept apart, ``(B, k)`` per metric path
(:attr:`EstimatorSamples.per_run`): what a paper's single flight is judged against
(:mod:`navsim.scoring.single_run`). :meth:`EstimatorSamples.run_values` reads either kind.

The file holds plain arrays only (read with ``allow_pickle=False``): ``format``, ``labels``,
and per estimator ``i`` ``e{i}.runs``, ``e{i}.paths``, ``e{i}.roots`` and ``e{i}.{path}.s`` /
``.n``; the per-run values, where kept, ``e{i}.values`` (their paths) and ``e{i}.v.{path}``
(a file written before them has none: read as none). :func:`load_samples` checks each array's
type and shape against the others: a damaged, truncated or foreign file is a
:class:`~navsim.foundations.errors.UsageError` naming the file and the array.
"""

from __future__ import annotations

import zipfile
import zlib
from dataclasses import dataclass, field
from fnmatch import fnmatchcase
from pathlib import Path

import numpy as np

from navsim.foundations.errors import UsageError

#: the file's name in a result folder and the version of its layout
SAMPLES_FILE, SAMPLES_FORMAT = "samples.npz", "samples-1"

#: the metric paths (``fnmatch`` patterns) that each run has a value of: the ratio metrics
#: (:class:`MetricSamples`) and those kept apart (:attr:`EstimatorSamples.per_run`; what a
#: ``single_run`` paper check can be judged on, :mod:`navsim.scoring.single_run`)
RUN_VALUE_PATTERNS = (
    "rms.*", "final.*", "p99.*", "max_abs.*", "convergence_s", "resets.mean_per_run",
    "attitude.rms_deg", "attitude.p95_deg", "attitude.p95_about_run_mean_deg", "attitude.max_abs_deg",
    "nees.average", "nees.per_state", "wind.rms_mps", "wind.final_mps", "landmarks.rms_after_m",
    "windows.*.horizontal_m.*", "windows.*.max_pos", "windows.*.max_neg", "windows.*.std",
    "windows.*.p95_abs", "windows.*.rms",
)


def has_run_values(path: str) -> bool:
    """Whether each run has its own value of the metric ``path`` (:data:`RUN_VALUE_PATTERNS`)."""
    return any(fnmatchcase(path, p) for p in RUN_VALUE_PATTERNS)


@dataclass(frozen=True)
class MetricSamples:
    """One metric's per-run sums and counts, ``(B, k)``, in the order of the runs."""

    s: np.ndarray
    n: np.ndarray
    root: bool              #: the metric is the square root of ``sum(s) / sum(n)``

    def value(self, rows=slice(None)) -> np.ndarray:
        """The metric over the runs ``rows`` (default all), ``(k,)``; NaN without a count."""
        with np.errstate(invalid="ignore", divide="ignore"):
            v = np.sum(self.s[rows], axis=0) / np.sum(self.n[rows], axis=0)
        return np.sqrt(v) if self.root else v

    def per_run(self) -> np.ndarray:
        """Each run's own value, ``(B, k)`` (what the compare page draws)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            v = self.s / self.n
        return np.sqrt(v) if self.root else v


@dataclass(frozen=True)
class EstimatorSamples:
    """An estimator's kept metrics over its counted runs (the diverged ones left out)."""

    runs: np.ndarray                       #: (B,) run numbers
    metrics: dict[str, MetricSamples] = field(default_factory=dict)
    #: metric path -> each run's own value of the statistic, ``(B, k)`` (not ratios of sums)
    per_run: dict[str, np.ndarray] = field(default_factory=dict)

    def run_values(self, path: str) -> np.ndarray | None:
        """Each run's own value of the metric ``path``, ``(B, k)``: kept apart, or a ratio
        metric's per-run value; None where the runs' values are not kept."""
        if path in self.per_run:
            return self.per_run[path]
        m = self.metrics.get(path)
        return None if m is None else m.per_run()


def save_samples(path: Path, samples: dict[str, EstimatorSamples], extra: dict | None = None) -> None:
    """Write label -> :class:`EstimatorSamples` to ``path`` (an ``.npz``), with the arrays
    ``extra`` beside (names without a dot: :func:`load_samples` reads past them)."""
    arrays = {"format": np.array(SAMPLES_FORMAT), "labels": np.array(list(samples), dtype=str)}
    for i, es in enumerate(samples.values()):
        paths = list(es.metrics)
        arrays.update({f"e{i}.runs": np.asarray(es.runs, np.int64), f"e{i}.paths": np.array(paths, dtype=str),
                       f"e{i}.roots": np.array([es.metrics[p].root for p in paths], bool)})
        for p in paths:
            arrays[f"e{i}.{p}.s"], arrays[f"e{i}.{p}.n"] = es.metrics[p].s, es.metrics[p].n
        if es.per_run:
            arrays[f"e{i}.values"] = np.array(list(es.per_run), dtype=str)
            arrays.update({f"e{i}.v.{p}": np.asarray(v, float) for p, v in es.per_run.items()})
    with open(path, "wb") as f:
        np.savez(f, **arrays, **(extra or {}))


class _Damaged(Exception):
    """What is wrong with a samples file (its array named)."""


#: what reading a damaged ``.npz`` raises (a truncated or corrupt archive or member; a file that
#: is no archive is taken for a pickle and refused, which is no advice to pass on)
_READ_ERRORS = (ValueError, EOFError, zipfile.BadZipFile, zlib.error, KeyError, IndexError)


def _array(z, name: str, kinds: str, ndim: int) -> np.ndarray:
    """The array ``name`` of the open archive ``z``, of a dtype kind in ``kinds`` and ``ndim``
    dimensions; :class:`_Damaged` naming it otherwise."""
    if name not in z.files:
        raise _Damaged(f"it has no array {name}")
    try:
        a = z[name]
    except _READ_ERRORS:
        raise _Damaged(f"its array {name} cannot be read (truncated or corrupt)") from None
    if a.dtype.kind not in kinds or a.ndim != ndim:
        raise _Damaged(f"its array {name} is {a.dtype} of shape {a.shape}, not the {ndim}-d "
                       f"{'numbers' if 'f' in kinds else 'text' if kinds == 'U' else a.dtype.kind} its layout has")
    return a


def _estimator(z, i: int) -> EstimatorSamples:
    """The ``i``-th estimator's samples of the open archive ``z``, checked."""
    runs = _array(z, f"e{i}.runs", "iu", 1)
    paths, roots = _array(z, f"e{i}.paths", "U", 1).tolist(), _array(z, f"e{i}.roots", "b", 1).tolist()
    if len(paths) != len(roots) or len(set(runs.tolist())) != len(runs):
        raise _Damaged(f"its arrays e{i}.paths and e{i}.roots differ in length, or e{i}.runs repeats a run")
    metrics = {}
    for p, r in zip(paths, roots):
        s, n = _array(z, f"e{i}.{p}.s", "fiu", 2), _array(z, f"e{i}.{p}.n", "fiu", 2)
        if s.shape != n.shape or s.shape[0] != len(runs) or s.shape[1] < 1:
            raise _Damaged(f"its arrays e{i}.{p}.s {s.shape} and .n {n.shape} are not (runs, components) "
                           f"for the {len(runs)} runs of e{i}.runs")
        metrics[p] = MetricSamples(s, n, bool(r))
    per_run = {}
    for p in (_array(z, f"e{i}.values", "U", 1).tolist() if f"e{i}.values" in z.files else []):
        v = _array(z, f"e{i}.v.{p}", "f", 2)
        if v.shape[0] != len(runs):
            raise _Damaged(f"its array e{i}.v.{p} {v.shape} is not (runs, components) for the {len(runs)} runs")
        per_run[p] = v
    return EstimatorSamples(runs, metrics, per_run)


def load_samples(path: Path) -> dict[str, EstimatorSamples]:
    """Read what :func:`save_samples` wrote, every array checked against the layout;
    :class:`~navsim.foundations.errors.UsageError` naming the file (and the array) for another
    layout, a damaged or truncated file; ``OSError`` where it cannot be opened."""
    hint = "hint: run its scenario again to write it anew"
    try:
        with np.load(path, allow_pickle=False) as z:
            fmt = _array(z, "format", "U", 0) if "format" in z.files else None
            if fmt is None or str(fmt) != SAMPLES_FORMAT:
                raise _Damaged(f"it is not a {SAMPLES_FORMAT} samples file (no format {SAMPLES_FORMAT!r})")
            return {label: _estimator(z, i) for i, label in enumerate(_array(z, "labels", "U", 1).tolist())}
    except _Damaged as exc:
        raise UsageError(f"{path}: damaged: {exc}; {hint}") from None
    except OSError as exc:
        if exc.errno is not None:              # cannot be opened: the caller's to say
            raise
        raise UsageError(f"{path}: damaged: not a readable .npz archive; {hint}") from None
    except _READ_ERRORS:
        raise UsageError(f"{path}: damaged: not a readable .npz archive (truncated, corrupt or another "
                         f"kind of file); {hint}") from None
