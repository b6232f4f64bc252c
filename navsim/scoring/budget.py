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

The contributions and shares have 95 % intervals over the runs too (the runs the Monte Carlos
all have; the same seeds make them paired, run by run). A line's ``D = d_k^2 = c_k^2 - c_0^2`` is
a difference of two ratios of per-run sums: its influence values ``g_k - g_0`` (each mean
square's, :func:`navsim.scoring.compare.influence`, so that ``c_0``'s noise, shared by every line,
counts once per run) give its standard error, and the interval is Student's t on ``log D``
(the delta method; a mean square of a random constant per run is right-skewed, and the log
interval covers it at a few runs where a symmetric one does not), its root the contribution's.
A share ``D_k / sum_j D_j`` has the influence values ``(g_k - share * sum_j g_j) / sum_j D_j``
and Student's t on its logit. Lines whose contributions' intervals overlap are not ranked
(:meth:`MetricBudget.unranked`): the runs are too few to order them.

"What if": a source scaled by ``K`` changes the mean square by ``(K^2 - 1) d_k^2``, so
``A' = sqrt(A^2 + (K^2 - 1) d_k^2)``; :class:`WhatIf` holds that prediction beside a run.

By covariance analysis (:mod:`navsim.navigation.covariance`) each source's variance of the
errors comes without runs, and the contributions add up exactly (``c_0 = 0``, the ratio 1):
:func:`covariance_budgets`; beside a Monte Carlo budget it is the cross-check, each line's
:attr:`BudgetLine.covariance` (:func:`with_covariance`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from navsim.foundations.config import close_match
from navsim.foundations.distributions import t_ppf
from navsim.foundations.errors import UsageError
from navsim.navigation.covariance import Contributions
from navsim.records.metrics import HorizontalStats
from navsim.records.samples import EstimatorSamples, MetricSamples
from navsim.records.states import ATT, POS, VEL
from navsim.scoring.compare import AXES, COMPONENTS, HORIZONTAL, columns, influence
from navsim.scoring.intervals import CONFIDENCE, MIN_RUNS
from navsim.scoring.samples import ERRORS
from navsim.scoring.scorer import EULER_QUANTITIES, WINDOW_QUANTITIES

#: the metrics the terminal shows by default: (path, component)
DEFAULT_METRICS = (("final.pos_m", "horizontal"), ("final.att_deg", "D"), ("rms.pos_m", "horizontal"),
                   ("rms.att_deg", "D"))
#: a budget whose root-sum-square is further than this from the all-on value is flagged
LINEARITY_TOLERANCE = 0.05
#: the share of a metric's variance from which a line is ranked against the others: lines below
#: it are the rest, not ordered among themselves (:meth:`MetricBudget.unranked`)
RANK_SHARE = 0.01
#: how the contributions are had: Monte Carlo, covariance analysis, or both (the second the
#: cross-check of the first)
METHODS = ("montecarlo", "covariance", "both")
#: the errors a covariance analysis gives, their columns of :class:`Contributions`' variances
#: and the factor of their unit
_COVARIANCE_ERRORS = (("att_deg", ATT, (180.0 / math.pi) ** 2), ("vel_mps", VEL, 1.0), ("pos_m", POS, 1.0))


@dataclass(frozen=True)
class BudgetLine:
    """One source (or group) of one metric: its metric alone, its contribution, its share."""

    source: str
    alone: float                 #: the metric with this source alone on (``c_k``)
    contribution: float          #: ``d_k``
    share: float                 #: of the summed variance
    #: the covariance analysis's contribution of the same line (NaN: not analysed, or the
    #: source has no linear form)
    covariance: float = math.nan
    #: the 95 % intervals of :attr:`contribution` and :attr:`share` over the runs (NaN: fewer
    #: than 2 runs, or a covariance analysis's line, which has no sampling error)
    contribution_ci95: list[float] = field(default_factory=lambda: [math.nan, math.nan])
    share_ci95: list[float] = field(default_factory=lambda: [math.nan, math.nan])


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

    def unranked(self) -> list[list[str]]:
        """The lines the runs are too few to order: each set (in the table's order) of lines
        linked by overlapping 95 % intervals of their contributions, the larger of each pair
        holding at least :data:`RANK_SHARE` of the variance; where there are no intervals (one
        run), every line holding that much."""
        big = [x for x in self.lines if x.share >= RANK_SHARE]
        if not any(all(math.isfinite(v) for v in x.contribution_ci95) for x in self.lines):
            return [[x.source for x in big]] if len(big) > 1 else []
        tied = {x.source: {x.source} for x in self.lines}
        for i, x in enumerate(self.lines):
            for y in self.lines[i + 1:]:
                if max(x.share, y.share) >= RANK_SHARE and _overlap(x, y):
                    merged = tied[x.source] | tied[y.source]
                    for s in merged:
                        tied[s] = merged
        order = [x.source for x in self.lines]
        sets = {frozenset(v) for v in tied.values() if len(v) > 1}
        return sorted((sorted(s, key=order.index) for s in sets), key=lambda s: order.index(s[0]))


def _overlap(x: BudgetLine, y: BudgetLine) -> bool:
    """Whether two lines' contribution intervals overlap (an end that is NaN: they may)."""
    (a, b), (c, d) = x.contribution_ci95, y.contribution_ci95
    if not all(math.isfinite(v) for v in (a, b, c, d)):
        return True
    return a <= d and c <= b


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
    method: str = "montecarlo"                   #: one of :data:`METHODS`
    #: the sources a covariance analysis leaves to Monte Carlo (no linear form)
    monte_carlo_only: list[str] = field(default_factory=list)
    #: each of those -> why it has no linear form
    left_out: dict = field(default_factory=dict)
    #: estimators the covariance analysis does not take -> why
    not_analysed: dict = field(default_factory=dict)
    covariance_s: float = math.nan               #: the covariance analysis's wall time
    #: estimator -> its sources' errors against time (:class:`Contributions`) by Monte Carlo:
    #: what each adds to the mean square over the runs (:func:`monte_carlo_curves`)
    curves: dict = field(default_factory=dict)
    #: the same by covariance analysis
    covariance_curves: dict = field(default_factory=dict)
    #: the ``--set`` changes made to the scenario file (``PATH=VALUE``)
    overrides: list = field(default_factory=list)

    def get(self, estimator: str, metric: str, component: str = "") -> MetricBudget | None:
        return next((m for m in self.metrics if (m.estimator, m.metric, m.component) == (estimator, metric, component)),
                    None)

    def to_dict(self) -> dict:
        clean = lambda v: ([clean(x) for x in v] if isinstance(v, list) else
                           None if isinstance(v, float) and not math.isfinite(v) else v)
        return {"scenario": self.scenario, "overrides": self.overrides, "runs": self.runs, "seed": self.seed,
                "sources": self.sources,
                "group": self.group, "method": self.method, "wall_s": clean(self.wall_s),
                "covariance_s": clean(self.covariance_s), "monte_carlo_only": self.monte_carlo_only,
                "left_out": self.left_out,
                "not_analysed": self.not_analysed, "linearity_tolerance": LINEARITY_TOLERANCE,
                "metrics": [{"estimator": m.estimator, "metric": m.metric, "component": m.component,
                             "all_on": clean(m.all_on), "baseline": clean(m.baseline), "rss": clean(m.rss),
                             "ratio": clean(m.ratio), "ratio_ci95": [clean(v) for v in m.ratio_ci95],
                             "additive": m.additive, "unranked": m.unranked() if self.method != "covariance" else [],
                             "lines": [{k: clean(v) for k, v in vars(x).items()} for x in m.lines]}
                            for m in self.metrics],
                "what_if": [{**{k: clean(v) for k, v in vars(w).items()}, "error": clean(w.error)}
                            for w in self.what_if]}

    def to_xarray(self):
        """``xarray.Dataset``: ``contribution``, ``share`` and ``alone`` (and the contribution's
        and share's 95 % intervals, ``contribution_lo``, ``contribution_hi``, ``share_lo``,
        ``share_hi``) on (estimator, metric, source), ``all_on``, ``baseline``, ``rss`` on
        (estimator, metric); metric names ``"final.pos_m horizontal"``."""
        import xarray as xr  # heavy to import (pandas): only when asked, as Result.to_xarray
        ests = list(dict.fromkeys(m.estimator for m in self.metrics))
        names = list(dict.fromkeys(m.name for m in self.metrics))
        srcs = list(dict.fromkeys(x.source for m in self.metrics for x in m.lines))
        cube = {k: np.full((len(ests), len(names), len(srcs)), np.nan)
                for k in ("contribution", "share", "alone", "covariance", "contribution_lo", "contribution_hi",
                          "share_lo", "share_hi")}
        flat = {k: np.full((len(ests), len(names)), np.nan) for k in ("all_on", "baseline", "rss")}
        for m in self.metrics:
            i, j = ests.index(m.estimator), names.index(m.name)
            for k in flat:
                flat[k][i, j] = getattr(m, k)
            for x in m.lines:
                values = {**vars(x), "contribution_lo": x.contribution_ci95[0], "contribution_hi": x.contribution_ci95[1],
                          "share_lo": x.share_ci95[0], "share_hi": x.share_ci95[1]}
                for k in cube:
                    cube[k][i, j, srcs.index(x.source)] = values[k]
        return xr.Dataset({**{k: (("estimator", "metric", "source"), v) for k, v in cube.items()},
                           **{k: (("estimator", "metric"), v) for k, v in flat.items()}},
                          coords={"estimator": ests, "metric": names, "source": srcs},
                          attrs={"scenario": self.scenario, "runs": self.runs, "seed": self.seed, "group": self.group})


def budget_paths(windows) -> dict[str, tuple[str, ...]]:
    """Metric path -> its components (``""`` for a number), of every metric a budget can have
    for a scenario whose metric windows are named ``windows``: the RMS metrics of the runs'
    samples (:meth:`navsim.scoring.samples.RunSamples.table`), those of the Euler errors, a wind
    estimate and landmarks where an estimator records them."""
    out = {}
    for head in ("rms", "final"):
        for name in ERRORS:
            path = f"{head}.{name}"
            out[path] = AXES + (("horizontal",) if path in HORIZONTAL else ())
    out["attitude.rms_deg"] = COMPONENTS["attitude.rms_deg"]
    out.update(dict.fromkeys(("wind.rms_mps", "wind.final_mps", "landmarks.rms_after_m"), ("",)))
    for w in windows:
        out.update(dict.fromkeys([f"windows.{w}.{q}.rms" for q in WINDOW_QUANTITIES + EULER_QUANTITIES]
                                 + [f"windows.{w}.horizontal_m.{f.name}" for f in dataclasses.fields(HorizontalStats)],
                                 ("",)))
    return out


def check_metric(item: str, windows) -> tuple[str, str]:
    """The ``(path, component)`` of a ``--metric PATH[:COMPONENT]`` argument ``item``, checked
    against what a budget of a scenario with the metric windows ``windows`` can score
    (:func:`budget_paths`) before anything runs; else a :class:`UsageError` naming it."""
    path, _, comp = item.partition(":")
    paths = budget_paths(windows)
    head, _, rest = path.partition(".")
    name = rest.split(".")[0]
    if head == "windows" and path not in paths and name not in windows:
        raise UsageError(f"--metric {item!r}: window '{name}' is not under the scenario's metrics.windows; hint: "
                         + (close_match(name, windows) if windows else "the scenario has no metric windows"))
    if path not in paths:
        raise UsageError(f"--metric {item!r}: '{path}' is not budgeted (a budget splits the RMS errors: "
                         "rms.* and final.* of pos_m, vel_mps, att_deg, attitude.rms_deg, wind.*, "
                         "windows.<name>.<quantity>.rms); hint: " + (close_match(path, paths) or ""))
    if comp not in paths[path]:
        what = f"has no component '{comp}'" if comp else f"has components ({', '.join(paths[path])}): name one"
        raise UsageError(f"--metric {item!r}: '{path}' {what}; hint: "
                         + ", ".join(f"{path}:{c}" if c else path for c in paths[path]))
    return path, comp


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
    its kind). Each line's contribution and share have their 95 % intervals over the runs
    every Monte Carlo counted (:func:`_line_intervals`)."""
    a, zero = _values(all_on), _values(none)
    each = {s: _values(x) for s, x in alone.items()}
    cross = _cross_terms(all_on, none, alone)
    runs = _common_runs(all_on, none, alone)
    g0 = _influences(none, runs)
    g_each = {s: _influences(x, runs) for s, x in alone.items()}
    out = []
    for key, value in a.items():
        c0 = zero.get(key, math.nan)
        members: dict[str, dict[str, float]] = {}
        for s, v in each.items():
            ck = v.get(key, math.nan)
            members.setdefault(groups[s], {})[s] = ck * ck - c0 * c0
        infl = {s: g[key] - g0[key] for s, g in g_each.items() if key in g and key in g0}
        lines = []
        for g, ds in members.items():
            d2 = sum(max(d, 0.0) for d in ds.values())
            lines.append(BudgetLine(g, math.sqrt(c0 * c0 + d2), math.sqrt(d2), d2))
        total = sum(x.share for x in lines)
        intervals = _line_intervals(members, infl)
        lines = sorted((BudgetLine(x.source, x.alone, x.contribution, x.share / total if total > 0 else math.nan,
                                   contribution_ci95=intervals[x.source][0], share_ci95=intervals[x.source][1])
                        for x in lines), key=lambda x: -x.contribution)
        rss = math.sqrt(c0 * c0 + total)
        out.append(MetricBudget(label, key[0], key[1], value, c0, lines, rss, cross.get(key, [math.nan, math.nan])))
    return out


def _common_runs(all_on: EstimatorSamples, none: EstimatorSamples, alone: dict) -> np.ndarray:
    """The run numbers every Monte Carlo of a budget counted, in order: its paired samples."""
    runs = all_on.runs
    for x in (none, *alone.values()):
        runs = np.intersect1d(runs, x.runs)
    return runs


def _influences(samples: EstimatorSamples, runs) -> dict[tuple[str, str], np.ndarray]:
    """(path, component) -> each run's influence value ``(B,)`` on the RMS metric's mean square
    (:func:`~navsim.scoring.compare.influence`), rows of ``runs``."""
    rows = np.searchsorted(samples.runs, runs)
    out = {}
    for path, m in samples.metrics.items():
        if m.root:
            for comp, col in columns(path, m):
                out[path, comp] = influence(MetricSamples(col.s[rows], col.n[rows], False))[1]
    return out


def _line_intervals(members: dict[str, dict[str, float]], infl: dict[str, np.ndarray]) -> dict[str, tuple]:
    """Line -> the 95 % intervals of its contribution and share. ``members``: line -> its
    sources' ``D_k = c_k^2 - c_0^2``; ``infl``: source -> the runs' influence values of its
    ``D_k`` (``g_k - g_0``). A line's ``D`` sums its members' that are above 0 (all of them,
    for its interval, where none is: its contribution then 0 to what the runs allow)."""
    nan = [math.nan, math.nan]
    if not members:
        return {}
    point, g_line = {}, {}
    for line, ds in members.items():
        kept = [s for s, d in ds.items() if d > 0] or list(ds)
        if not all(s in infl for s in kept):
            return {line: (nan, nan) for line in members}
        point[line] = sum(max(ds[s], 0.0) for s in kept)
        g_line[line] = sum(infl[s] for s in kept)
    raw = {line: sum(members[line].values()) if point[line] == 0 else point[line] for line in members}
    total = sum(point.values())
    g_total = sum((g_line[x] for x in members if point[x] > 0), np.zeros_like(next(iter(g_line.values()))))
    out = {}
    for line in members:
        d_ci = _log_interval(point[line], raw[line], g_line[line])
        share = point[line] / total if total > 0 else math.nan
        g_share = (g_line[line] - share * g_total) / total if total > 0 else g_line[line] * math.nan
        out[line] = ([math.sqrt(v) if math.isfinite(v) else math.nan for v in d_ci], _logit_interval(share, g_share))
    return out


def _half_width(g: np.ndarray) -> float:
    """Student's 95 % half-width of the mean of the influence values ``g`` (NaN: too few runs)."""
    g = np.asarray(g, float)
    if g.size < MIN_RUNS or not np.all(np.isfinite(g)):
        return math.nan
    return float(t_ppf(0.5 + CONFIDENCE / 2, g.size - 1)) * float(np.std(g, ddof=1)) / math.sqrt(g.size)


def _log_interval(value: float, raw: float, g: np.ndarray) -> list[float]:
    """The 95 % interval of a mean-square difference ``value >= 0`` with influence values ``g``:
    Student's t on its logarithm where it is above 0; where it is 0 (``raw``, the difference
    before it was held at 0, is not above), from 0 to ``raw`` plus the half-width."""
    half = _half_width(g)
    if not math.isfinite(half):
        return [math.nan, math.nan]
    if value > 0:
        h = min(half / value, 700.0)
        return [value * math.exp(-h), value * math.exp(h)]
    return [0.0, max(raw + half, 0.0)]


def _logit_interval(share: float, g: np.ndarray) -> list[float]:
    """The 95 % interval of a share with influence values ``g``: Student's t on its logit
    (inside 0 to 1); at 0 or 1 from there by the half-width."""
    half = _half_width(g)
    if not (math.isfinite(half) and math.isfinite(share)):
        return [math.nan, math.nan]
    if 0 < share < 1:
        c, h = math.log(share / (1 - share)), half / (share * (1 - share))
        return [1 / (1 + math.exp(min(h - c, 700))), 1 / (1 + math.exp(min(-h - c, 700)))]
    return [0.0, min(half, 1.0)] if share <= 0 else [max(1 - half, 0.0), 1.0]


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
    runs = _common_runs(all_on, none, alone)
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
        half = float(t_ppf(0.5 + CONFIDENCE / 2, len(q) - 1)) * float(np.std(g, ddof=1)) / math.sqrt(len(q))
        out[key] = [math.sqrt(max(1 - f - half, 0.0)), math.sqrt(max(1 - f + half, 0.0))]
    return out


def predict(budget: MetricBudget, source: str, factor: float) -> float:
    """The metric with ``source``'s line scaled by ``factor`` (see the module docstring)."""
    line = budget.line(source)
    if line is None:
        return math.nan
    return math.sqrt(max(budget.all_on ** 2 + (factor * factor - 1) * line.contribution ** 2, 0.0))


def covariance_values(c: Contributions, settle_s: float) -> dict[tuple[str, str], np.ndarray]:
    """(path, component) -> each source's mean square ``(K,)`` of the RMS errors a covariance
    analysis gives: ``rms.*`` (the epochs from ``settle_s`` on, as the scorer counts them) and
    ``final.*``, per axis and horizontal for position, attitude in degrees."""
    after = c.t_s >= settle_s
    out = {}
    for name, cols, unit in _COVARIANCE_ERRORS:
        var = c.var[:, :, cols] * unit
        for head, x in (("rms", var[:, after].mean(axis=1)), ("final", var[:, -1])):
            path = f"{head}.{name}"
            for j, comp in enumerate(AXES):
                out[path, comp] = x[:, j]
            if path in HORIZONTAL:
                out[path, "horizontal"] = x[:, 0] + x[:, 1]
    return out


def covariance_budgets(label: str, c: Contributions, settle_s: float, groups: dict[str, str]) -> list[MetricBudget]:
    """One estimator's budgets by covariance analysis: each line's contribution the root of its
    sources' variances, the all-on value their root-sum-square (no baseline, a ratio of 1)."""
    out = []
    for (path, comp), ms in covariance_values(c, settle_s).items():
        sums: dict[str, float] = {}
        for s, v in zip(c.sources, ms):
            sums[groups[s]] = sums.get(groups[s], 0.0) + max(float(v), 0.0)
        total = sum(sums.values())
        lines = sorted((BudgetLine(g, math.sqrt(d2), math.sqrt(d2), d2 / total if total > 0 else math.nan,
                                   math.sqrt(d2)) for g, d2 in sums.items()), key=lambda x: -x.contribution)
        out.append(MetricBudget(label, path, comp, math.sqrt(total), 0.0, lines, math.sqrt(total)))
    return out


def with_covariance(monte_carlo: list[MetricBudget], covariance: list[MetricBudget]) -> list[MetricBudget]:
    """The Monte Carlo budgets with each line's :attr:`BudgetLine.covariance` from the
    covariance analysis's budget of the same estimator, metric and line."""
    cov = {(m.estimator, m.metric, m.component): m for m in covariance}
    out = []
    for m in monte_carlo:
        other = cov.get((m.estimator, m.metric, m.component))
        if other is None:
            out.append(m)
            continue
        lines = [dataclasses.replace(x, covariance=other.line(x.source).contribution)
                 if other.line(x.source) is not None else x for x in m.lines]
        out.append(dataclasses.replace(m, lines=lines))
    return out


def epoch_mean_squares(histories: dict) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Estimator label -> ``(t_s (E,), mean square (E, 9))``: each epoch's navigation errors
    squared and averaged over the runs not diverged (attitude in rad^2, velocity, position NED),
    what a Monte Carlo budget's errors against time are made of."""
    out = {}
    for label, h in histories.items():
        good = ~np.asarray(h.diverged, bool)
        e = np.concatenate([h.att_err_rad, h.vel_err_mps, h.pos_err_m], axis=-1)[good].astype(np.float64)
        ms = np.full((len(h.t_s), 9), np.nan)
        if len(e):
            with np.errstate(invalid="ignore"):
                ms = np.nanmean(e * e, axis=0)
        out[label] = (np.asarray(h.t_s, float), ms)
    return out


def monte_carlo_curves(mean_squares: dict, sources: list[str]) -> dict[str, Contributions]:
    """Estimator label -> each source's errors against time from the Monte Carlos' epoch mean
    squares (``what -> label -> (t_s, ms)``, :func:`epoch_mean_squares`): what the source alone
    adds to the mean square of the run with none, ``max(ms_k - ms_0, 0)``, as a variance."""
    out = {}
    for label, (t, ms0) in mean_squares["none"].items():
        var = np.stack([np.maximum(mean_squares[s][label][1] - ms0, 0.0) for s in sources])
        out[label] = Contributions(list(sources), t, var)
    return out
