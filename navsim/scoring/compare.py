"""Two estimators' metrics compared, the runs as the samples: ``B - A`` with its 95 % interval
and a verdict, run by run (paired) where both flew the same runs, else side against side.

Every metric compared is a ratio of per-run sums (:mod:`navsim.records.samples`),
``R = sum(s) / sum(n)``, or its square root. Its run-by-run influence values (the linearised
ratio, as :func:`navsim.scoring.intervals.ratio_se`),

    g_b = f'(R) (s_b - R n_b) / mean(n),

have the metric's sampling variance ``var(g) / B``. Paired, the runs both sides have are
matched by run number and the difference's variance is that of ``g_B - g_A``: the errors the
two share (the same flight, sensor noise, biases and initial errors) cancel. Unpaired, the
variances add (Welch's degrees of freedom). The interval is Student's t on that standard error.

A verdict: for an error (an RMS) ``better`` when B - A is significantly below 0, ``worse`` above,
``no significant difference`` otherwise, with the runs at which the difference seen would be
significant over the family (:func:`runs_to_resolve`). A consistency
statistic (NEES) has no better side: ``higher`` or ``lower``. The verdicts hold for the family
of components compared together (Holm's step-down at 5 %: the chance that any of them is
called different when none is stays at 5 %, where 30 components each tested at 5 % would call
one in four out of nothing); the intervals are each one's own 95 %. A component whose own
interval excludes 0 but that does not pass Holm's step is ``no significant difference`` with
its ``p_value`` shown.

A practical-equivalence margin (``margin``, per cent of the larger of A's and B's value,
:data:`DEFAULT_MARGIN_PCT` unless given, per metric path if asked) says what difference
matters: a component whose whole 95 % interval lies within ``+- margin`` is ``negligible``
(the two are equivalent to within it, significant or not: two filters 66 nm apart), and a
``no significant difference`` whose difference seen is within the margin is offered no run
count (resolving it would not matter). A margin of 0 turns this off: the intervals' verdicts alone.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from navsim.foundations.config import close_match
from navsim.foundations.distributions import t_ppf, t_sf
from navsim.foundations.errors import UsageError
from navsim.records.samples import EstimatorSamples, MetricSamples
from navsim.records.states import POS, SIGMA_STATES
from navsim.scoring.intervals import CONFIDENCE, MIN_RUNS, student_runs

#: the verdicts (an error metric; a consistency statistic)
BETTER, WORSE, SAME = "better", "worse", "no significant difference"
HIGHER, LOWER = "higher", "lower"
#: the verdict of a difference whose 95 % interval lies within the practical-equivalence margin
NEGLIGIBLE = "negligible"
#: the practical-equivalence margin, per cent of the larger of A's and B's value: a difference
#: below it does not matter (an RMS 1 % apart is within what a Monte Carlo is usually asked for)
DEFAULT_MARGIN_PCT = 1.0
#: the names of a metric's components, by its shape (the metric path's start decides first)
COMPONENTS = {"attitude.rms_deg": ("roll", "pitch", "yaw"), "nees.per_state": SIGMA_STATES}
AXES = tuple(s.split("_")[1] for s in SIGMA_STATES[POS])
#: the paths with a horizontal component (the root of the N and E mean squares' sum)
HORIZONTAL = ("rms.pos_m", "final.pos_m")


@dataclass(frozen=True)
class Difference:
    """One component of one metric: A's and B's values, ``B - A`` and its 95 % interval."""

    metric: str                 #: the metrics path (``rms.pos_m``)
    component: str              #: ``N``, ``horizontal``, ``roll``, ``pos_E``, or "" for a scalar
    a: float
    b: float
    diff: float
    ci95: list[float]
    verdict: str
    #: the runs (per side) at which the difference would be significant over the family if it
    #: held (Bonferroni's bound of Holm's step); only for ``no significant difference``
    runs_needed: int | None = None
    #: the two-sided p-value of B - A = 0 (Student's t on the same standard error)
    p_value: float = math.nan
    #: the runs it is over (paired: both sides'; unpaired: the smaller side)
    runs: int = 0
    #: the standard error of B - A
    se: float = math.nan
    #: the standard error B - A would have at one run per side (``se * sqrt(runs)`` paired;
    #: ``sqrt(var(g_A) + var(g_B))`` unpaired): what the runs needed scale
    spread: float = math.nan
    #: the practical-equivalence margin in the metric's unit (its per cent of max(|A|, |B|))
    margin: float = math.nan

    @property
    def relative(self) -> float:
        """``(B - A) / A`` (NaN where A is 0)."""
        return self.diff / self.a if self.a else math.nan

    @property
    def name(self) -> str:
        return f"{self.metric} {self.component}".strip()


def _components(path: str, k: int) -> tuple[str, ...]:
    if len(COMPONENTS.get(path, ())) == k:
        return COMPONENTS[path]
    return AXES if k == 3 else tuple(str(j) for j in range(k)) if k > 1 else ("",)


def columns(path: str, m: MetricSamples) -> list[tuple[str, MetricSamples]]:
    """The metric's columns as ``(component, one-column samples)``, with the horizontal one."""
    names = _components(path, m.s.shape[1])
    out = [(c, MetricSamples(m.s[:, j:j + 1], m.n[:, j:j + 1], m.root)) for j, c in enumerate(names)]
    if path in HORIZONTAL:
        out.append(("horizontal", MetricSamples(m.s[:, :2].sum(1, keepdims=True), m.n[:, :1], m.root)))
    return out


def influence(m: MetricSamples) -> tuple[float, np.ndarray]:
    """The metric's value over the runs and each run's influence value ``g_b`` (``(B,)``)."""
    s, n = m.s[:, 0], m.n[:, 0]
    mean_n = float(np.mean(n))
    ratio = float(np.sum(s) / np.sum(n)) if np.sum(n) > 0 else math.nan
    g = (s - ratio * n) / mean_n if mean_n > 0 else np.full(len(s), math.nan)
    if m.root:
        value = math.sqrt(ratio) if ratio >= 0 else math.nan
        return value, g / (2 * value) if value > 0 else np.zeros(len(s))
    return ratio, g


def _interval(diff: float, se: float, dof: float) -> list[float]:
    """The t interval of ``diff`` (NaN where it cannot be had)."""
    if not (math.isfinite(se) and dof >= 1):
        return [math.nan, math.nan]
    half = float(t_ppf(0.5 + CONFIDENCE / 2, dof)) * se
    return [diff - half, diff + half]


def _verdict(metric: str, ci: list[float]) -> str:
    """The verdict of one component's own interval (before Holm's step over the family)."""
    lo, hi = ci
    error = not metric.startswith("nees.")
    if lo > 0:
        return WORSE if error else HIGHER
    if hi < 0:
        return BETTER if error else LOWER
    return SAME


def paired_rows(a: EstimatorSamples, b: EstimatorSamples) -> tuple[np.ndarray, np.ndarray]:
    """The rows of ``a`` and of ``b`` of the runs both have, in run order."""
    _, ia, ib = np.intersect1d(a.runs, b.runs, return_indices=True)
    return ia, ib


def _rows(m: MetricSamples, rows) -> MetricSamples:
    return MetricSamples(m.s[rows], m.n[rows], m.root)


def check_margin(margin):
    """``margin`` as :func:`compare_samples` takes it (a per cent, or a mapping of metric path ->
    per cent, ``""`` the default), checked: each a number 0-100; else a :class:`UsageError`."""
    items = margin.items() if isinstance(margin, Mapping) else [("", margin)]
    for key, pct in items:
        where = f"margin[{key!r}]" if isinstance(margin, Mapping) else "margin"
        if not isinstance(key, str):
            raise UsageError(f"{where}: the key is not a metric path (expected a string such as 'rms.pos_m')")
        if isinstance(pct, bool) or not isinstance(pct, numbers.Real) or not 0 <= float(pct) <= 100:
            raise UsageError(f"{where}: is {pct!r} (expected a number of per cent, 0-100; default "
                             f"{DEFAULT_MARGIN_PCT:g})")
    return {"": DEFAULT_MARGIN_PCT, **{k: float(v) for k, v in margin.items()}} if isinstance(margin, Mapping) \
        else float(margin)


def check_margin_paths(margin, paths) -> None:
    """A :class:`UsageError` for a key of a per-path ``margin`` that starts none of the metric
    ``paths`` compared (``rms.pos`` for ``rms.pos_m``), with the closest path."""
    if not isinstance(margin, Mapping):
        return
    paths = set(paths)
    starts = paths | {p.rsplit(".", j)[0] for p in paths for j in range(1, p.count(".") + 1)}
    for key in margin:
        if key and key not in starts:
            raise UsageError(f"margin[{key!r}]: no metric compared is {key!r} or starts with it; "
                             f"hint: {close_match(key, sorted(starts))}")


def margin_pct(margin, path: str) -> float:
    """The margin (per cent) of the metric ``path``: ``margin`` itself, or the entry of the
    mapping whose key is the longest start of ``path`` (``"rms.pos_m"``; ``""`` the default,
    else :data:`DEFAULT_MARGIN_PCT`)."""
    if not isinstance(margin, Mapping):
        return float(margin)
    keys = [k for k in margin if path == k or path.startswith(k + ".") or k == ""]
    return float(margin[max(keys, key=len)]) if keys else DEFAULT_MARGIN_PCT


def with_margin(d: Difference, pct: float) -> Difference:
    """``d`` judged against its practical-equivalence margin of ``pct`` per cent: ``negligible``
    when its interval lies within it; no run count for a difference seen within it."""
    scale = max(abs(d.a), abs(d.b)) if math.isfinite(d.a) and math.isfinite(d.b) else math.nan
    margin = pct / 100 * scale
    if not (math.isfinite(margin) and margin > 0):        # 0: no margin, the verdicts of the intervals alone
        return d
    lo, hi = d.ci95
    if -margin <= lo and hi <= margin:
        return replace(d, verdict=NEGLIGIBLE, runs_needed=None, margin=margin)
    if d.verdict == SAME and abs(d.diff) <= margin:
        return replace(d, runs_needed=None, margin=margin)
    return replace(d, margin=margin)


def differences(a: EstimatorSamples, b: EstimatorSamples, paired: bool,
                margin=DEFAULT_MARGIN_PCT) -> list[Difference]:
    """Every metric both sides kept, component by component: ``B - A`` with its interval and
    verdict (Holm's over the components, :func:`holm`; then the margin, :func:`with_margin`:
    ``margin`` per cent, or per metric path as :func:`margin_pct` reads it). Paired: over the
    runs both have (matched by number); unpaired: each side's own."""
    ia, ib = paired_rows(a, b) if paired else (slice(None), slice(None))
    out = []
    for path in [p for p in a.metrics if p in b.metrics]:
        if a.metrics[path].s.shape[1] != b.metrics[path].s.shape[1]:
            continue
        for (comp, ma), (_, mb) in zip(columns(path, _rows(a.metrics[path], ia)),
                                       columns(path, _rows(b.metrics[path], ib))):
            out.append(_difference(path, comp, ma, mb, paired))
    return [with_margin(d, margin_pct(margin, d.metric)) for d in holm(out)]


def holm(diffs: list[Difference], alpha: float = 1 - CONFIDENCE) -> list[Difference]:
    """The verdicts of Holm's step-down over ``diffs``: the k-th smallest p-value (from 0) is
    significant while it and every smaller one is below ``alpha / (m - k)``; the rest are
    ``no significant difference``."""
    order = sorted(range(len(diffs)), key=lambda i: diffs[i].p_value if math.isfinite(diffs[i].p_value) else 2.0)
    keep = set()
    for k, i in enumerate(order):
        if not diffs[i].p_value <= alpha / (len(diffs) - k):
            break
        keep.add(i)
    out = []
    for i, d in enumerate(diffs):
        if i not in keep:
            d = replace(d, verdict=SAME, runs_needed=runs_to_resolve(d, alpha / max(len(diffs), 1)))
        out.append(d)
    return out


def runs_to_resolve(d: Difference, alpha: float) -> int | None:
    """The runs (per side) at which the difference seen would pass a two-sided test at
    ``alpha`` (the family's strictest step, Bonferroni's ``alpha / m``: an upper bound of
    Holm's): the fewest ``N`` with ``t(N - 1) * spread / sqrt(N) <= |diff|``
    (:func:`~navsim.scoring.intervals.student_runs`), and more than the runs it is over. None
    without a difference or a spread."""
    if not d.diff:
        return None
    n = student_runs(d.spread, abs(d.diff), alpha)
    return None if n is None else max(n, d.runs + 1)


def _difference(path: str, comp: str, ma: MetricSamples, mb: MetricSamples, paired: bool) -> Difference:
    va, ga = influence(ma)
    vb, gb = influence(mb)
    na, nb = len(ga), len(gb)
    diff = vb - va
    if min(na, nb) < MIN_RUNS:
        se, dof, spread = math.nan, 0.0, math.nan
    elif paired:
        spread = float(np.std(gb - ga, ddof=1))
        se, dof = spread / math.sqrt(na), na - 1.0
    else:
        va2, vb2 = np.var(ga, ddof=1) / na, np.var(gb, ddof=1) / nb
        se, spread = float(math.sqrt(va2 + vb2)), float(math.sqrt(va2 * na + vb2 * nb))
        denom = va2 ** 2 / (na - 1) + vb2 ** 2 / (nb - 1)
        dof = float((va2 + vb2) ** 2 / denom) if denom > 0 else na + nb - 2.0
    if se == 0:                                # the runs agree exactly: 0, or a certain difference
        return Difference(path, comp, va, vb, diff, [diff, diff], _verdict(path, [diff, diff]), None,
                          1.0 if diff == 0 else 0.0, min(na, nb), 0.0, 0.0)
    ci = _interval(diff, se, dof)
    p = float(2 * t_sf(abs(diff) / se, dof)) if math.isfinite(se) and dof >= 1 else math.nan
    return Difference(path, comp, va, vb, diff, ci, _verdict(path, ci), None, p, min(na, nb), se,
                      spread if min(na, nb) >= MIN_RUNS else math.nan)


@dataclass(frozen=True)
class Side:
    """One side of a comparison: the result and the estimator."""

    result: str                 #: the result folder
    estimator: str
    runs: int                   #: its counted runs (the diverged left out)
    runs_done: int              #: the runs its result finished
    runs_asked: int
    interrupted: bool
    seed: int


@dataclass(frozen=True)
class Comparison:
    """A against B, metric by metric (:func:`differences`)."""

    a: Side
    b: Side
    paired: bool
    pairing: str                #: why paired or not
    runs_compared: int          #: paired: the runs both have; unpaired: the smaller side
    differences: list[Difference]
    #: paired: the counted runs of one side the other left out (diverged there), per side
    only_a: list[int] = field(default_factory=list)
    only_b: list[int] = field(default_factory=list)
    #: the samples compared (what the page draws)
    samples_a: EstimatorSamples | None = field(default=None, repr=False)
    samples_b: EstimatorSamples | None = field(default=None, repr=False)
    #: the practical-equivalence margin, per cent (one for every metric, or by metric path)
    margin_pct: float | dict = DEFAULT_MARGIN_PCT

    def summary(self) -> dict[str, int]:
        """Verdict -> how many components have it."""
        out: dict[str, int] = {}
        for d in self.differences:
            out[d.verdict] = out.get(d.verdict, 0) + 1
        return out

    def to_dict(self) -> dict:
        """The comparison as ``compare.json`` holds it (NaN as None)."""
        clean = lambda v: None if isinstance(v, float) and not math.isfinite(v) else v
        side = lambda s: dict(vars(s))
        rows = [{"metric": d.metric, "component": d.component, "a": clean(d.a), "b": clean(d.b),
                 "diff": clean(d.diff), "relative": clean(d.relative), "ci95": [clean(v) for v in d.ci95],
                 "verdict": d.verdict, "runs_needed": d.runs_needed, "p_value": clean(d.p_value),
                 "margin": clean(d.margin)}
                for d in self.differences]
        return {"a": side(self.a), "b": side(self.b), "paired": self.paired, "pairing": self.pairing,
                "runs_compared": self.runs_compared, "left_out": {"a_only": self.only_a, "b_only": self.only_b},
                "confidence": CONFIDENCE,
                "verdicts": "Holm's step-down over the components at 5 %; negligible: the 95 % interval within "
                            "the practical-equivalence margin", "margin_pct": self.margin_pct, "summary": self.summary(),
                "differences": rows}


def compare_samples(a: Side, sa: EstimatorSamples, b: Side, sb: EstimatorSamples, paired: bool,
                    pairing: str, margin=DEFAULT_MARGIN_PCT) -> Comparison:
    """The :class:`Comparison` of two estimators' samples (paired: over the runs both counted;
    those only one side counted are listed), with the practical-equivalence ``margin``
    (:func:`differences`)."""
    runs = len(paired_rows(sa, sb)[0]) if paired else min(len(sa.runs), len(sb.runs))
    only = lambda x, y: np.setdiff1d(x.runs, y.runs).astype(int).tolist() if paired else []
    pct = dict(margin) if isinstance(margin, Mapping) else float(margin)
    return Comparison(a, b, paired, pairing, runs, differences(sa, sb, paired, margin), only(sa, sb), only(sb, sa),
                      sa, sb, pct)
