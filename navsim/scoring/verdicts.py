"""A scenario's published results judged against ours: :func:`judge`, and their table."""

from __future__ import annotations

import math

import numpy as np

from navsim.experiment.reference import Reference
from navsim.scoring.metrics import EstimatorMetrics, Verdict

#: the mark of each verdict, in the terminal and on the report's first page
MARKS = {True: "pass", False: "FAIL", None: "-"}
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
        if c.of is not None:
            base = _metric(estimators, c.of, c.metric)
            bound = None if base is None else (np.asarray(base, float) * c.bound).tolist()
        passed = None
        if ours is not None and bound is not None:
            a, b = np.atleast_1d(np.asarray(ours, float)), np.atleast_1d(np.asarray(bound, float))
            if a.shape == b.shape and np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
                passed = _passes(c.rule, a, b, c.tolerance)
        out.append(Verdict(c.estimator, c.metric, c.rule, bound, ours, passed,
                           c.tolerance if c.rule == "close" else None, c.claim, c.of,
                           c.bound if c.of is not None else None))
    return out


def _metric(estimators: dict, label: str, path: str):
    m = estimators.get(label)
    return m.get(path) if m is not None else None


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, (list, tuple)):
        return " ".join(_fmt(x) for x in v)
    return "-" if not math.isfinite(v) else f"{v:.3g}"


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
        rows.append([v.estimator, v.claim or "as published", v.metric, paper, _fmt(v.ours), MARKS[v.passed]])
    return rows


def verdict_summary(verdicts: list[Verdict]) -> str:
    """``"5 of 6 checks pass, 1 fails"`` (those without a verdict counted apart)."""
    passed = sum(v.passed is True for v in verdicts)
    failed = sum(v.passed is False for v in verdicts)
    judged = passed + failed
    text = f"{passed} of {judged} paper checks pass" + (f", {failed} fail" if failed else "")
    rest = len(verdicts) - judged
    return text + (f" ({rest} shown without a verdict)" if rest else "")
