"""A scenario's published results judged against ours: :func:`judge`, and their table."""

from __future__ import annotations

import math

import numpy as np

from navsim.records.reference import Reference
from navsim.records.metrics import EstimatorMetrics, Verdict

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
VERDICT_HEADERS = ["estimator", "paper's result", "our metric", "paper", "ours", "verdict"]


def _passes(rule: str, ours: np.ndarray, bound: np.ndarray, tolerance: float) -> bool | None:
    if rule == "at_most":
        return bool(np.all(ours <= bound))
    if rule == "at_least":
        return bool(np.all(ours >= bound))
    if rule == "close":
        return bool(np.all(np.abs(ours - bound) <= tolerance * np.abs(bound)))
    return None


def judge(reference: Reference | None, estimators: dict[str, EstimatorMetrics]) -> list[Verdict] | None:
    """Each of ``reference``'s checks against the estimators' metrics (None without a
    reference). A metric of ours that is missing or not a number, or has another length than
    the bound, gets no verdict."""
    if reference is None:
        return None
    out = []
    for c in reference.checks:
        ours, bound = _metric(estimators, c.estimator, c.metric), c.bound
        if ours is None and c.metric in ABSENT_IS_INFINITE and c.estimator in estimators:
            ours = math.inf
        if c.of is not None:
            base = _numbers(_metric(estimators, c.of, c.metric))
            bound = None if base is None else (base * c.bound).tolist()
        passed = None
        a, b = _numbers(ours), _numbers(bound)
        if a is not None and b is not None and a.shape == b.shape and not np.isnan(a).any() and np.isfinite(b).all():
            passed = _passes(c.rule, a, b, c.tolerance)
        out.append(Verdict(c.estimator, c.metric, c.rule, bound, ours, passed,
                           c.tolerance if c.rule == "close" else None, c.claim, c.of,
                           c.bound if c.of is not None else None))
    return out


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
    """``[estimator, result, metric, paper, ours, verdict]`` per verdict: ``result`` the claim
    (``as published`` for a number); ``paper`` the published number (with ``±`` its tolerance)
    or the claim's threshold (``<= 0.4 x other (1.14)`` for one relative to another estimator)."""
    rows = []
    for v in verdicts:
        paper = f"{RULE_SIGNS[v.rule]} {_fmt(v.bound)}".strip()
        if v.of is not None:
            paper = f"{RULE_SIGNS[v.rule]} {v.times:g} x {v.of} ({_fmt(v.bound)})"
        elif v.rule == "close":
            paper = f"{_fmt(v.bound)} ±{100 * v.tolerance:.0f}%"
        mark = NO_VALUE if v.passed is None and v.rule != "none" else MARKS[v.passed]
        rows.append([v.estimator, v.claim or "as published", v.metric, paper, _fmt(v.ours), mark])
    return rows


def verdict_summary(verdicts: list[Verdict]) -> str:
    """``"5 of 6 checks pass, 1 fails"``: the checks without a value of ours counted with the
    judged ones (they did not pass), those shown without a verdict apart."""
    passed = sum(v.passed is True for v in verdicts)
    failed = sum(v.passed is False for v in verdicts)
    missing = sum(v.passed is None and v.rule != "none" for v in verdicts)
    judged = passed + failed + missing
    text = f"{passed} of {judged} paper checks pass" + (f", {failed} fail" if failed else "") \
        + (f", {missing} without a value" if missing else "")
    rest = len(verdicts) - judged
    return text + (f" ({rest} shown without a verdict)" if rest else "")
