"""A scenario's published results judged against ours: :func:`judge`, and their table.

Where our metric has a 95 % interval (:attr:`~navsim.records.metrics.EstimatorMetrics.ci95`,
the runs as the samples) the check is judged on the interval, not on the point value: it passes
when the whole interval satisfies the rule, fails when none of it does, and is otherwise
*undecided at N runs*, with the runs that would decide it (the interval's half-width towards
the bound shrinks as ``1 / sqrt(runs)``; :func:`navsim.scoring.intervals.runs_needed`). A vector
passes when every component does and fails when one does. A metric without an interval (a
maximum, a single run) is judged on its value, as is the bound of a claim relative to another
estimator (``of``: its metric times the factor, taken as exact).

A ``single_run`` check (the paper's number is one flight: :data:`~navsim.records.reference.KINDS`)
is judged instead against each run's own value of the statistic
(:meth:`~navsim.records.samples.EstimatorSamples.run_values`; of a claim relative to another
estimator, each run's ratio of the two): a number (``close``) passes when it lies inside the
95 % range of one run and fails outside it, with its percentile among our runs (``none``: the
range and the percentile shown, no verdict); a
bound (``at_most``, ``at_least``) passes when the range reaches it (a flight meeting it can be
one of ours: at least as many runs meet it, every component at once, as the range's end rank),
with the share of our runs meeting it and its Clopper-Pearson interval
(:mod:`navsim.scoring.single_run`). Below :func:`~navsim.scoring.single_run.min_runs` runs the
range is open and the check undecided.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.records.metrics import EstimatorMetrics, Verdict
from navsim.records.reference import PaperCheck, Reference
from navsim.records.samples import EstimatorSamples
from navsim.scoring.intervals import runs_needed
from navsim.scoring.single_run import bound_reached, coverage_interval, judge_single_run, min_runs, share_meeting

#: the mark of each verdict, in the terminal and on the report's first page: a check with a rule
#: whose metric we do not have (or is not a number of the bound's shape) is "no value", never
#: a silent "-" (which is a value shown without a verdict, rule ``none``)
MARKS = {True: "pass", False: "FAIL", None: "-"}
NO_VALUE = "no value"
#: metrics whose absence is a result: a filter that never converged has no convergence time
ABSENT_IS_INFINITE = ("convergence_s",)
#: how each rule reads in a table (the bound after it)
RULE_SIGNS = {"at_most": "<=", "at_least": ">=", "close": "~", "none": ""}
#: the columns of :func:`verdict_rows`
VERDICT_HEADERS = ["estimator", "paper's result", "our metric", "kind", "paper", "ours", "verdict"]
#: the verdict's column in :data:`VERDICT_HEADERS`
VERDICT_COLUMN = VERDICT_HEADERS.index("verdict")
#: how each kind reads in the tables: ours is the mean's 95 % interval, or one run's 95 % range
KIND_TEXT = {"population": "population", "single_run": "single run"}


def _passes(rule: str, ours: np.ndarray, bound: np.ndarray, tolerance: float) -> bool | None:
    if rule == "at_most":
        return bool(np.all(ours <= bound))
    if rule == "at_least":
        return bool(np.all(ours >= bound))
    if rule == "close":
        return bool(np.all(np.abs(ours - bound) <= tolerance * np.abs(bound)))
    return None


def _region(rule: str, bound: float, tolerance: float) -> tuple[float, float]:
    """The values that satisfy ``rule`` against ``bound``."""
    if rule == "at_most":
        return -math.inf, bound
    if rule == "at_least":
        return bound, math.inf
    return bound - tolerance * abs(bound), bound + tolerance * abs(bound)


def _decide(rule: str, ours: np.ndarray, bound: np.ndarray, tolerance: float, interval, runs: int):
    """``(passed, runs needed)`` of a rule judged on the per-component ``interval`` ``(k, 2)``:
    passed None (undecided) where an interval straddles an edge of the rule's region."""
    outcomes, needed = [], []
    for v, (lo, hi), b in zip(ours, interval, bound):
        a, z = _region(rule, b, tolerance)
        if a <= lo and hi <= z:
            outcomes.append(True)
        elif hi < a or lo > z:
            outcomes.append(False)
        else:
            outcomes.append(None)
            edges = [e for e in (a, z) if math.isfinite(e) and lo <= e <= hi]
            n = [runs_needed(runs, v, (lo, hi), e) for e in edges]
            needed.append(max((x for x in n if x is not None and math.isfinite(x)), default=None))
    if False in outcomes:
        return False, None
    if None in outcomes:
        known = [n for n in needed if n is not None]
        return None, (max(known) if known and len(known) == len(needed) else None)
    return True, None


def _interval(estimators: dict, label: str, path: str, shape) -> np.ndarray | None:
    """Our metric's interval as ``(k, 2)`` of the value's ``k`` components (an open end
    infinite), or None where it has none (or not for every component)."""
    m = estimators.get(label)
    iv = None if m is None else m.interval(path)
    if iv is None:
        return None
    try:
        a = np.asarray(iv, float).reshape(-1, 2)
    except (TypeError, ValueError):
        return None
    if a.shape[0] != shape[0] or np.isnan(a).all(axis=1).any():
        return None
    # an open end (null: the runs cannot bound it there) reaches as far as it can
    return np.where(np.isnan(a), np.array([-np.inf, np.inf]), a)


def judge(reference: Reference | None, estimators: dict[str, EstimatorMetrics],
          samples: dict[str, EstimatorSamples] | None = None) -> list[Verdict] | None:
    """Each of ``reference``'s checks against the estimators' metrics (None without a
    reference); a ``single_run`` check against the runs' ``samples``. A metric of ours that is
    missing or not a number, or has another length than the bound, gets no verdict."""
    if reference is None:
        return None
    out = []
    for c in reference.checks:
        if c.kind == "single_run":
            out.append(_judge_single(c, estimators, samples or {}))
            continue
        ours, bound = _metric(estimators, c.estimator, c.metric), c.bound
        if ours is None and c.metric in ABSENT_IS_INFINITE and c.estimator in estimators:
            ours = math.inf
        if c.of is not None:
            base = _numbers(_metric(estimators, c.of, c.metric))
            bound = None if base is None else (base * c.bound).tolist()
        passed, interval, runs, needed = None, None, None, None
        a, b = _numbers(ours), _numbers(bound)
        if a is not None and b is not None and a.shape == b.shape and not np.isnan(a).any() and np.isfinite(b).all():
            passed = _passes(c.rule, a, b, c.tolerance)
            interval = _interval(estimators, c.estimator, c.metric, a.shape) if c.rule != "none" else None
            if interval is not None:
                runs = estimators[c.estimator].runs_counted
                passed, needed = _decide(c.rule, a, b, c.tolerance, interval, runs)
        out.append(Verdict(c.estimator, c.metric, c.rule, bound, ours, passed,
                           c.tolerance if c.rule == "close" else None, c.claim, c.of,
                           c.bound if c.of is not None else None,
                           None if interval is None else _open_ends(interval), runs,
                           True if interval is not None and passed is None else None, needed))
    return out


def _run_values(c: PaperCheck, samples: dict) -> np.ndarray | None:
    """Each run's value of the check's metric ``(B, k)``; of a claim relative to another
    estimator, each run's ratio to that estimator's on the same run; None where not kept."""
    mine = samples.get(c.estimator)
    x = None if mine is None else mine.run_values(c.metric)
    if x is None or c.of is None:
        return x
    other = samples.get(c.of)
    y = None if other is None else other.run_values(c.metric)
    if y is None or y.shape[1] != x.shape[1]:
        return None
    _, ia, ib = np.intersect1d(mine.runs, other.runs, return_indices=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return x[ia] / y[ib]


def _judge_single(c: PaperCheck, estimators: dict, samples: dict) -> Verdict:
    """A check on one flight against our single runs (the module's text): the runs counted are
    those with every component of the statistic."""
    ours = _metric(estimators, c.estimator, c.metric)
    if c.of is not None:
        base = _numbers(_metric(estimators, c.of, c.metric))
        bound = None if base is None else (base * c.bound).tolist()
    else:
        bound = c.bound
    x, paper = _run_values(c, samples), np.atleast_1d(np.asarray(c.bound, float))
    if x is not None:
        x = x[~np.isnan(x).any(axis=1)]
        if c.of is not None:                          # the factor, for every component of the ratio
            paper = np.full(x.shape[1], float(c.bound))
    plain = dict(estimator=c.estimator, metric=c.metric, rule=c.rule, bound=bound, ours=ours, passed=None,
                 claim=c.claim, of=c.of, times=c.bound if c.of is not None else None, kind=c.kind)
    if x is None or x.shape[1] != paper.size or not len(x):
        return Verdict(**plain)
    judged = [judge_single_run(p, x[:, j]) for j, p in enumerate(paper)]
    runs = len(x)
    plain.update(percentile=[round(j.percentile, 1) for j in judged], runs=runs)
    if runs >= min_runs():
        plain.update(run_range=_open_ends([[j.low, j.high] for j in judged]),
                     coverage_ci95=[round(v, 4) for v in coverage_interval(runs)])
    if c.rule in ("at_most", "at_least"):
        share, ci, _ = share_meeting(x, paper, c.rule)
        plain.update(share=share, share_ci95=list(ci) if all(map(math.isfinite, ci)) else None)
    if c.rule == "none":
        return Verdict(**plain)
    if runs < min_runs():
        return Verdict(**plain, undecided=True, runs_needed=min_runs())
    if c.rule in ("at_most", "at_least"):             # every component at once, as the paper's flight met it
        return Verdict(**{**plain, "passed": bound_reached(x, paper, c.rule)})
    return Verdict(**{**plain, "passed": all(j.passed for j in judged)})


def _metric(estimators: dict, label: str, path: str):
    m = estimators.get(label)
    return m.get(path) if m is not None else None


def _numbers(v) -> np.ndarray | None:
    """``v`` as a 1-d float array, or None if it is not a number or a list of numbers (a group
    of metrics, a string, a ragged list)."""
    if v is None or isinstance(v, (dict, str, bool)):
        return None
    try:
        return np.atleast_1d(np.asarray(v, float))
    except (TypeError, ValueError):
        return None


def num(v) -> str:
    """A number as the tables show it (terminal and report): 3 significant digits, no exponent
    below 100 000, a vector's components separated by spaces, "-" for none or NaN."""
    if v is None or isinstance(v, (dict, str)):
        return "-"
    if isinstance(v, (list, tuple, np.ndarray)):
        return " ".join(num(x) for x in v)
    v = float(v)
    if not math.isfinite(v):
        return "-"
    if abs(v) >= 1000:
        return f"{v:.0f}" if abs(v) < 1e5 else f"{v:.2e}"
    return f"{v:.3g}"


def _fmt(v) -> str:
    """A verdict's value: :func:`num`, and "never" for a metric whose absence is infinite."""
    if isinstance(v, float) and math.isinf(v) and v > 0:
        return "never"
    return num(v)


def verdict_rows(verdicts: list[Verdict]) -> list[list[str]]:
    """``[estimator, result, metric, kind, paper, ours, verdict]`` per verdict: ``result`` the
    claim (``as published`` for a number); ``paper`` the published number (with ``±`` its
    tolerance) or the claim's threshold (``<= 0.4 x other (1.14)`` for one relative to another
    estimator); ``ours`` the metric with its 95 % interval, or for a single run the 95 % range of
    one run (of the ratio, for a claim relative to another estimator), the verdict then with the
    paper's percentile among our runs or the share of them meeting the bound."""
    rows = []
    for v in verdicts:
        single = v.kind == "single_run"
        paper = f"{RULE_SIGNS[v.rule]} {_fmt(v.bound)}".strip()
        if v.of is not None:
            paper = f"{RULE_SIGNS[v.rule]} {v.times:g} x {v.of}" + ("" if single else f" ({_fmt(v.bound)})")
        elif v.rule == "close" and not single:
            paper = f"{_fmt(v.bound)} ±{100 * v.tolerance:.0f}%"
        mark = NO_VALUE if v.passed is None and v.rule != "none" else MARKS[v.passed]
        if v.undecided:
            mark = undecided_text(v)
        elif single and v.run_range is not None:
            mark = f"{mark} ({single_run_text(v)})" if mark != "-" else single_run_text(v)
        elif single and v.percentile is not None and mark == "-":       # shown: too few runs for a range
            mark = single_run_text(v)
        ours = with_interval(v.ours, v.ours_ci95)
        if single:
            ours = "-" if v.run_range is None else "  ".join(f"[{_end(v, lo)}, {_end(v, hi)}]" for lo, hi in v.run_range)
            ours = (f"ratio {ours}" if v.of is not None and v.run_range is not None else ours)
        rows.append([v.estimator, v.claim or "as published", v.metric, KIND_TEXT.get(v.kind, v.kind), paper, ours, mark])
    return rows


def _end(v: Verdict, x) -> str:
    """An end of the range of one run: a number, or beyond every finite value (None: a run that
    never converged, an infinite ratio)."""
    if x is not None:
        return num(x)
    return "never" if v.metric in ABSENT_IS_INFINITE else "inf"


def single_run_text(v: Verdict) -> str:
    """A single-run verdict's detail: ``"p34"`` (the paper's percentile among our runs, per
    component) for a number; ``"96 % [87, 99] of runs meet it"`` for a bound."""
    if v.share is not None:
        ci = f" [{_percent(v.share_ci95[0])}, {_percent(v.share_ci95[1])}]" if v.share_ci95 else ""
        return f"{_percent(v.share)} %{ci} of runs meet it"
    return " ".join("p-" if p is None else f"p{_percent(p / 100)}" for p in v.percentile or [])


def _percent(share: float) -> str:
    """A share as a percent: whole, but with a decimal within 1 % of 0 or 100 (99.6, not 100)."""
    p = 100 * share
    if 0 < p < 1 or 99 < p < 100:                     # never printed as 0.0 or 100.0
        return f"{min(max(p, 0.1), 99.9):.1f}"
    return f"{p:.0f}"


#: beyond this many runs a check is called too close to its bound to decide
DECIDABLE_RUNS = 100_000


def undecided_text(v: Verdict) -> str:
    """``"undecided at 20 runs (~80 decide)"``; ``"... (at the bound)"`` when the value sits so
    close to the bound that more than :data:`DECIDABLE_RUNS` runs would be needed."""
    if v.kind == "single_run":
        return f"undecided at {v.runs} runs ({v.runs_needed} bound one run's 95 % range)"
    if v.runs_needed and v.runs_needed > DECIDABLE_RUNS:
        return f"undecided at {v.runs} runs (at the bound: >{DECIDABLE_RUNS} runs to decide)"
    return f"undecided at {v.runs} runs" + (f" (~{v.runs_needed} decide)" if v.runs_needed else "")


def _open_ends(interval: np.ndarray) -> list:
    """``interval`` ``(k, 2)`` as a list with an open (non-finite) end as None: what
    ``metrics.json`` holds (strict JSON has no infinity), so a result read back equals the one
    in memory."""
    return [[float(x) if math.isfinite(x) else None for x in row] for row in np.asarray(interval, float).tolist()]


def with_interval(value, interval) -> str:
    """A value with its 95 % interval, ``"1.29 [1.21, 1.38]"`` (a vector's components
    separated by two spaces); :func:`num` alone where there is no interval."""
    if interval is None or isinstance(value, (dict, str)) or value is None:
        return _fmt(value)
    values = np.atleast_1d(np.asarray(value, float)).tolist()
    ivs = np.asarray(interval, float).reshape(-1, 2).tolist()
    if len(ivs) != len(values):
        return _fmt(value)
    # an open end (the runs cannot bound it there) shows as "-"
    return "  ".join(_fmt(x) if not any(map(math.isfinite, iv)) else f"{_fmt(x)} [{num(iv[0])}, {num(iv[1])}]"
                     for x, iv in zip(values, ivs))


def verdict_summary(verdicts: list[Verdict]) -> str:
    """``"5 of 6 checks pass, 1 fails"``: the checks without a value of ours counted with the
    judged ones (they did not pass), those shown without a verdict apart."""
    passed = sum(v.passed is True for v in verdicts)
    failed = sum(v.passed is False for v in verdicts)
    undecided = [v for v in verdicts if v.undecided]
    missing = sum(v.passed is None and v.rule != "none" and not v.undecided for v in verdicts)
    judged = passed + failed + missing + len(undecided)
    text = f"{passed} of {judged} paper checks pass" + (f", {failed} fail" if failed else "") \
        + (f", {len(undecided)} undecided at {undecided[0].runs} runs" if undecided else "") \
        + (f", {missing} without a value" if missing else "")
    rest = len(verdicts) - judged
    return text + (f" ({rest} shown without a verdict)" if rest else "")
