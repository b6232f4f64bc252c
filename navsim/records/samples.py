"""Each run's part of an estimator's metrics, kept beside ``metrics.json`` in ``samples.npz``:
what :func:`navsim.compare` pairs run by run.

A metric that is a ratio of sums over the runs (a mean square over runs and epochs, a mean)
is kept as each run's sum ``s`` and count ``n``, ``(B, k)`` for its ``k`` components (N, E, D;
the nine states); its value over any set of runs is ``sum(s) / sum(n)``, under a square root
for an RMS (``root``). Kept: ``rms.*``, ``final.*``, ``attitude.rms_deg``, ``nees.average``
(the pooled mean over runs and scored epochs: ``metrics.json``'s average of the per-epoch
means where every run has every epoch), ``nees.per_state``, the windows' ``rms`` and the
landmarks' ``rms_after_m``. Percentiles, maxima, shares and times are not ratios of per-run
sums and are not kept.

The file holds plain arrays only (read with ``allow_pickle=False``): ``format``, ``labels``,
and per estimator ``i`` ``e{i}.runs``, ``e{i}.paths``, ``e{i}.roots`` and ``e{i}.{path}.s`` /
``.n``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: the file's name in a result folder and the version of its layout
SAMPLES_FILE, SAMPLES_FORMAT = "samples.npz", "samples-1"


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
    with open(path, "wb") as f:
        np.savez(f, **arrays, **(extra or {}))


def load_samples(path: Path) -> dict[str, EstimatorSamples]:
    """Read what :func:`save_samples` wrote; ``ValueError`` for another layout."""
    with np.load(path, allow_pickle=False) as z:
        if "format" not in z.files or str(z["format"]) != SAMPLES_FORMAT:
            raise ValueError(f"not a {SAMPLES_FORMAT} samples file")
        out = {}
        for i, label in enumerate(z["labels"].tolist()):
            paths, roots = z[f"e{i}.paths"].tolist(), z[f"e{i}.roots"].tolist()
            out[label] = EstimatorSamples(z[f"e{i}.runs"], {p: MetricSamples(z[f"e{i}.{p}.s"], z[f"e{i}.{p}.n"], bool(r))
                                                              for p, r in zip(paths, roots)})
        return out
