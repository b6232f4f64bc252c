"""An error budget from Monte Carlos: each error source's share of an estimator's errors.

The runs are flown once with every source on (``A``, the metric as ``navsim run`` gives it),
once with none (``c_0``: what is left with ideal sensors and exact initial conditions, the
filter's own approximations) and once per source alone (``c_k``), with the same seeds: each
source's realisation is the one it has with all on (:mod:`navsim.experiment.budget`). For an
RMS metric, a source's contribution is what it adds to the mean square,

    d_k = sqrt(max(c_k^2 - c_0^2, 0)),

its share of the variance ``d_k^2 / sum_j d_j^2``, and where the errors add linearly (a linear
filter, independent sources) ``sqrt(c_0^2 + sum_k d_k^2)`` is ``A``: their ratio is printed as
the linearity check. Over a finite number of runs the sources' cross terms do not quite average
out (a final error, one epoch per run, least): the ratio's 95 % interval comes from each run's
cross term ``s_all - s_0 - sum_k (s_k - s_0)`` (its sums of squares in each Monte Carlo), and
a budget is called non-additive only when that interval is clear of ``1 +- 5 %``: a fault or a
gain that switches with the data.

"What if": a source scaled by ``K`` changes the mean square by ``(K^2 - 1) d_k^2``, so
``A' = sqrt(A^2 + (K^2 - 1) d_k^2)``; :class:`WhatIf` holds that prediction beside a run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from scipy.stats import t as student_t

from navsim.records.samples import EstimatorSamples
from navsim.scoring.compare import columns
from navsim.scoring.intervals import CONFIDENCE, MIN_RUNS

#: the metrics the terminal shows by default: (path, component)
DEFAULT_METRICS = (("final.pos_m", "horizontal"), ("final.att_deg", "D"), ("rms.pos_m", "horizontal"),
                   ("rms.att_deg", "D"))
#: a budget whose root-sum-square is further than this from the all-on value is flagged
LINEARITY_TOLERANCE = 0.05


@dataclass(frozen=True)
class BudgetLine:
    """One source (or group) of one metric: its metric alone, its contribution, its share."""

    source: str
    alone: float                 #: the metric with this source alone on (``c_k``)
    contribution: float          #: ``d_k``
    share: float                 #: of the summed variance


@dataclass(frozen=True)
class MetricBudget:
    """One estimator's budget of one metric component, its lines sorted by share."""

    estimator: str
    metric: str
    component: str
    all_on: float                #: ``A``
    baseline: float              #: ``c_0``, every source off
    lines: list[BudgetLine]
    rss: float                   #: ``sqrt(c_0^2 + sum d_k^2)``
    #: the 95 % interval of :attr:`ratio` from the runs' cross terms (NaN: fewer than 2 runs)
    ratio_ci95: list[float] = field(default_factory=lambda: [math.nan, math.nan])

    @property
    def ratio(self) -> float:
        """``rss / all_on``: 1 where the sources add up."""
        return self.rss / self.all_on if self.all_on else math.nan

    @property
    def additive(self) -> bool:
        """Whether the sources add up: the ratio within ``1 +- 5 %``, or its interval reaching
        there (the runs too few to tell the cross terms from noise)."""
        lo, hi = self.ratio_ci95
        tol = LINEARITY_TOLERANCE
        if math.isfinite(lo) and math.isfinite(hi):
            return lo <= 1 + tol and hi >= 1 - tol
        return math.isfinite(self.ratio) and abs(self.ratio - 1) <= tol

    @property
    def name(self) -> str:
        return f"{self.metric} {self.component}".strip()

    def line(self, source: str) -> BudgetLine | None:
        return next((x for x in self.lines if x.source == source), None)


@dataclass(frozen=True)
class WhatIf:
    """A source scaled by ``factor``: the metric the budget predicts and the one a run gives."""

    source: str
    factor: float
    estimator: str
    metric: str
    component: str
    all_on: float
    predicted: float
    measured: float

    @property
    def error(self) -> float:
        """``predicted / measured - 1``."""
        return self.predicted / self.measured - 1 if self.measured else math.nan


@dataclass(frozen=True)
class Budget:
    """The budget of every estimator and RMS metric of a scenario (:func:`metric_budgets`)."""

    scenario: str
    runs: int
    seed: int
    sources: list[str]
    group: str                                   #: how the lines are grouped (``source``, ...)
    metrics: list[MetricBudget]
    what_if: list[WhatIf] = field(default_factory=list)
    wall_s: float = math.nan

    def get(self, estimator: str, metric: str, component: str = "") -> MetricBudget | None:
        return next((m for m in self.metrics if (m.estimator, m.metric, m.component) == (estimator, metric, component)),
                    None)

    def to_dict(self) -> dict:
        clean = lambda v: None if isinstance(v, float) and not math.isfinite(v) else v
        return {"scenario": self.scenario, "runs": self.runs, "seed": self.seed, "sources": self.sources,
                "group": self.group, "wall_s": clean(self.wall_s), "linearity_tolerance": LINEARITY_TOLERANCE,
                "metrics": [{"estimator": m.estimator, "metric": m.metric, "component": m.component,
                             "all_on": clean(m.all_on), "baseline": clean(m.baseline), "rss": clean(m.rss),
                             "ratio": clean(m.ratio), "ratio_ci95": [clean(v) for v in m.ratio_ci95],
                             "additive": m.additive,
                             "lines": [{k: clean(v) for k, v in vars(x).items()} for x in m.lines]}
                            for m in self.metrics],
                "what_if": [{**{k: clean(v) for k, v in vars(w).items()}, "error": clean(w.error)}
                            for w in self.what_if]}

    def to_xarray(self):
        """``xarray.Dataset``: ``contribution``, ``share`` and ``alone`` on (estimator, metric,
        source), ``all_on``, ``baseline``, ``rss`` on (estimator, metric); metric names
        ``"final.pos_m horizontal"``."""
        import xarray as xr  # heavy to import (pandas): only when asked, as Result.to_xarray
        ests = list(dict.fromkeys(m.estimator for m in self.metrics))
        names = list(dict.fromkeys(m.name for m in self.metrics))
        srcs = list(dict.fromkeys(x.source for m in self.metrics for x in m.lines))
        cube = {k: np.full((len(ests), len(names), len(srcs)), np.nan) for k in ("contribution", "share", "alone")}
        flat = {k: np.full((len(ests), len(names)), np.nan) for k in ("all_on", "baseline", "rss")}
        for m in self.metrics:
            i, j = ests.index(m.estimator), names.index(m.name)
            for k in flat:
                flat[k][i, j] = getattr(m, k)
            for x in m.lines:
                for k in cube:
                    cube[k][i, j, srcs.index(x.source)] = getattr(x, k)
        return xr.Dataset({**{k: (("estimator", "metric", "source"), v) for k, v in cube.items()},
                           **{k: (("estimator", "metric"), v) for k, v in flat.items()}},
                          coords={"estimator": ests, "metric": names, "source": srcs},
                          attrs={"scenario": self.scenario, "runs": self.runs, "seed": self.seed, "group": self.group})


def _values(samples: EstimatorSamples) -> dict[tuple[str, str], float]:
    """(path, component) -> the RMS metrics' values over the runs (errors only, not NEES)."""
    out = {}
    for path, m in samples.metrics.items():
        if m.root:
            for comp, col in columns(path, m):
                out[path, comp] = float(col.value()[0])
    return out


def metric_budgets(label: str, all_on: EstimatorSamples, none: EstimatorSamples,
                   alone: dict[str, EstimatorSamples], groups: dict[str, str]) -> list[MetricBudget]:
    """The budgets of one estimator's RMS metrics. ``alone``: source -> its samples with that
    source alone on; ``groups``: source -> the line it is summed under (itself, its sensor,
    its kind)."""
    a, zero = _values(all_on), _values(none)
    each = {s: _values(x) for s, x in alone.items()}
    cross = _cross_terms(all_on, none, alone)
    out = []
    for key, value in a.items():
        c0 = zero.get(key, math.nan)
        sums: dict[str, list[float]] = {}
        for s, v in each.items():
            ck = v.get(key, math.nan)
            sums.setdefault(groups[s], []).append(ck)
        lines = []
        for g, cks in sums.items():
            d2 = sum(max(ck * ck - c0 * c0, 0.0) for ck in cks)
            alone_value = math.sqrt(c0 * c0 + d2)
            lines.append(BudgetLine(g, alone_value, math.sqrt(d2), d2))
        total = sum(x.share for x in lines)
        lines = sorted((BudgetLine(x.source, x.alone, x.contribution, x.share / total if total > 0 else math.nan)
                        for x in lines), key=lambda x: -x.contribution)
        rss = math.sqrt(c0 * c0 + total)
        out.append(MetricBudget(label, key[0], key[1], value, c0, lines, rss, cross.get(key, [math.nan, math.nan])))
    return out


def _per_run(samples: EstimatorSamples, runs) -> dict[tuple[str, str], tuple]:
    """(path, component) -> the runs' sums and counts ``(B,)`` of the RMS metrics, rows of ``runs``."""
    rows = np.searchsorted(samples.runs, runs)
    out = {}
    for path, m in samples.metrics.items():
        if m.root:
            for comp, col in columns(path, m):
                out[path, comp] = (col.s[rows, 0], col.n[rows, 0])
    return out


def _cross_terms(all_on: EstimatorSamples, none: EstimatorSamples, alone: dict) -> dict:
    """(path, component) -> the 95 % interval of ``rss / all_on`` from the runs every Monte
    Carlo counted: each run's cross term ``s_all - s_0 - sum_k (s_k - s_0)`` over ``s_all`` is a
    ratio of per-run sums, ``1 - ratio^2`` (its interval: Student's t on the influence values)."""
    runs = all_on.runs
    for x in (none, *alone.values()):
        runs = np.intersect1d(runs, x.runs)
    if len(runs) < MIN_RUNS or not alone:
        return {}
    a, z = _per_run(all_on, runs), _per_run(none, runs)
    each = [_per_run(x, runs) for x in alone.values()]
    out = {}
    for key, (s_all, n) in a.items():
        if key not in z or any(key not in e for e in each):
            continue
        q = s_all - z[key][0] - sum(e[key][0] - z[key][0] for e in each)
        f = float(np.sum(q) / np.sum(s_all)) if np.sum(s_all) > 0 else math.nan
        g = (q - f * s_all) / np.mean(s_all) if np.mean(s_all) > 0 else np.full(len(q), math.nan)
        half = float(student_t.ppf(0.5 + CONFIDENCE / 2, len(q) - 1)) * float(np.std(g, ddof=1)) / math.sqrt(len(q))
        out[key] = [math.sqrt(max(1 - f - half, 0.0)), math.sqrt(max(1 - f + half, 0.0))]
    return out


def predict(budget: MetricBudget, source: str, factor: float) -> float:
    """The metric with ``source``'s line scaled by ``factor`` (see the module docstring)."""
    line = budget.line(source)
    if line is None:
        return math.nan
    return math.sqrt(max(budget.all_on ** 2 + (factor * factor - 1) * line.contribution ** 2, 0.0))
