"""A published number from one flight judged against the spread of our single runs (issue 55):
:func:`prediction_range`, :func:`judge_single_run`, :func:`share_meeting`.

A paper's single flight is one draw from the distribution our runs sample; judged against the
confidence interval of our mean (which shrinks as ``1/sqrt(N)``) it fails for almost any value
once N is large. It is judged instead against the range a new single run falls in: the
distribution-free 95 % prediction interval of N runs, between the order statistics of ranks
``floor(0.025 (N + 1))`` and ``ceil(0.975 (N + 1))`` (a new independent draw falls between them
with probability ``(m - k) / (N + 1) >= 0.95`` whatever the distribution). The paper's
percentile among our runs is reported with it; a bound the paper states for its flight ("within
1 m") passes when a flight meeting it can be one of ours: when at least as many of our runs
meet it as the range's end rank (:func:`bound_reached`), and gets the share of our runs that
meet it, with its Clopper-Pearson 95 % interval.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navsim.foundations.distributions import beta_ppf
from navsim.scoring.intervals import CONFIDENCE, binomial_interval

#: the prediction range's coverage of a new single run
COVERAGE = 0.95


@dataclass(frozen=True)
class SingleRunVerdict:
    """The paper's value against our single runs: the 95 % prediction range of one run, the
    paper's percentile among ours (0-100), inside or not, and the runs it rests on."""

    low: float
    high: float
    percentile: float
    passed: bool
    runs: int


def _ranks(n: int, coverage: float) -> tuple[int, int]:
    """The 1-based ranks ``k``, ``m`` of the prediction range's ends among ``n`` runs."""
    a = (1.0 - coverage) / 2.0
    return math.floor(a * (n + 1)), math.ceil((1.0 - a) * (n + 1))


def min_runs(coverage: float = COVERAGE) -> int:
    """The fewest runs whose prediction range has both ends (39 at 95 %)."""
    return math.ceil(2.0 / (1.0 - coverage)) - 1


def coverage_interval(n: int, coverage: float = COVERAGE, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The ``confidence`` interval of the share of single runs that the range of ``n`` runs
    holds: that share is ``Beta(m - k, n + 1 - (m - k))`` distributed (its mean ``(m - k) /
    (n + 1)``): the range's own uncertainty at ``n`` runs."""
    k, m = _ranks(n, coverage)
    if k < 1 or m > n:
        return math.nan, math.nan
    a = (1.0 - confidence) / 2.0
    lo, hi = beta_ppf(np.array([a, 1.0 - a]), m - k, n + 1 - (m - k))
    return float(lo), float(hi)


def _values(per_run) -> np.ndarray:
    """The runs' values, NaN (no value in that run) left out; an infinite one ("never") kept."""
    x = np.asarray(per_run, float).ravel()
    return x[~np.isnan(x)]


def prediction_range(per_run: np.ndarray, coverage: float = COVERAGE) -> tuple[float, float]:
    """The distribution-free prediction interval of a new run from ``per_run`` (NaN left out):
    the order statistics of ranks ``floor(a (N + 1))`` and ``ceil((1 - a) (N + 1))``,
    ``a = (1 - coverage) / 2``; an end beyond the sample is infinite (too few runs to bound it:
    39 runs bound both ends at 95 %, :func:`min_runs`)."""
    x = np.sort(_values(per_run))
    n = x.size
    k, m = _ranks(n, coverage)
    low = x[k - 1] if k >= 1 else -math.inf
    high = x[m - 1] if m <= n else math.inf
    return float(low), float(high)


def judge_single_run(paper: float, per_run: np.ndarray, coverage: float = COVERAGE) -> SingleRunVerdict:
    """The paper's single-flight ``paper`` against our runs' values ``per_run``: passed when it
    lies inside the prediction range of one run, with its percentile among ours (ties counted
    half)."""
    x = _values(per_run)
    low, high = prediction_range(x, coverage)
    pct = 100.0 * (np.sum(x < paper) + 0.5 * np.sum(x == paper)) / x.size if x.size else math.nan
    return SingleRunVerdict(low, high, float(pct), bool(low <= paper <= high), int(x.size))


def _meets(per_run, bound, rule: str) -> np.ndarray:
    """Which runs meet ``bound`` (``at_most``/``at_least``), every component at once: a bool per
    run of ``per_run`` ``(B, k)`` (a run with a NaN component left out)."""
    if rule not in ("at_most", "at_least"):
        raise ValueError(f"rule {rule!r}: a share is of a bound, at_most or at_least")
    x = np.asarray(per_run, float)
    x = x.reshape(len(x), int(np.prod(x.shape[1:]))) if x.ndim else x.reshape(1, 1)
    x = x[~np.isnan(x).any(axis=1)]
    return np.all(x <= bound, axis=1) if rule == "at_most" else np.all(x >= bound, axis=1)


def bound_reached(per_run: np.ndarray, bound, rule: str, coverage: float = COVERAGE) -> bool:
    """Whether a flight meeting ``bound`` (``at_most``/``at_least``; every component of a run
    of ``k``, ``(B, k)``) lies within the prediction range of one run: at least
    ``floor(a (N + 1))`` of the N runs meet it (for one component: the range's end reaches the
    bound), ``a = (1 - coverage) / 2``."""
    meets = _meets(per_run, bound, rule)
    k, _ = _ranks(meets.size, coverage)
    return bool(k >= 1 and meets.sum() >= k)


def share_meeting(per_run: np.ndarray, bound, rule: str) -> tuple[float, tuple[float, float], int]:
    """The share of runs whose value meets ``bound`` (``at_most`` or ``at_least``; a run of
    ``k`` components, ``(B, k)``, meets it when every component does), its Clopper-Pearson 95 %
    interval and the runs counted (a run with a NaN component left out)."""
    meets = _meets(per_run, bound, rule)
    k, n = int(meets.sum()), int(meets.size)
    return (k / n if n else math.nan), tuple(binomial_interval(k, n)), n
