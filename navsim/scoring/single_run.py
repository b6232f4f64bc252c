"""A published number from one flight judged against the spread of our single runs (issue 55):
:func:`prediction_range`, :func:`judge_single_run`, :func:`share_meeting`.

A paper's single flight is one draw from the distribution our runs sample; judged against the
confidence interval of our mean (which shrinks as ``1/sqrt(N)``) it fails for almost any value
once N is large. It is judged instead against the range a new single run falls in: the
distribution-free 95 % prediction interval of N runs, between the order statistics of ranks
``floor(0.025 (N + 1))`` and ``ceil(0.975 (N + 1))`` (a new independent draw falls between them
with probability ``(m - k) / (N + 1) >= 0.95`` whatever the distribution). The paper's
percentile among our runs is reported with it; a bound the paper states for its flight ("within
1 m") gets the share of our runs that meet it, with its Clopper-Pearson 95 % interval.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

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


def prediction_range(per_run: np.ndarray, coverage: float = COVERAGE) -> tuple[float, float]:
    """The distribution-free prediction interval of a new run from ``per_run`` (finite values):
    the order statistics of ranks ``floor(a (N + 1))`` and ``ceil((1 - a) (N + 1))``,
    ``a = (1 - coverage) / 2``; an end beyond the sample is infinite (too few runs to bound it:
    39 runs bound both ends at 95 %)."""
    x = np.sort(np.asarray(per_run, float)[np.isfinite(per_run)])
    n = x.size
    a = (1.0 - coverage) / 2.0
    k, m = math.floor(a * (n + 1)), math.ceil((1.0 - a) * (n + 1))
    low = x[k - 1] if k >= 1 else -math.inf
    high = x[m - 1] if m <= n else math.inf
    return float(low), float(high)


def judge_single_run(paper: float, per_run: np.ndarray, coverage: float = COVERAGE) -> SingleRunVerdict:
    """The paper's single-flight ``paper`` against our runs' values ``per_run``: passed when it
    lies inside the prediction range of one run, with its percentile among ours (ties counted
    half)."""
    x = np.asarray(per_run, float)
    x = x[np.isfinite(x)]
    low, high = prediction_range(x, coverage)
    pct = 100.0 * (np.sum(x < paper) + 0.5 * np.sum(x == paper)) / x.size if x.size else math.nan
    return SingleRunVerdict(low, high, float(pct), bool(low <= paper <= high), int(x.size))


def clopper_pearson(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """The exact (Clopper-Pearson) interval of a binomial share ``k / n``."""
    from scipy.stats import beta
    a = (1.0 - confidence) / 2.0
    lo = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1.0 - a, k + 1, n - k))
    return lo, hi


def share_meeting(per_run: np.ndarray, bound: float, rule: str) -> tuple[float, tuple[float, float], int]:
    """The share of runs whose value meets ``bound`` (``at_most`` or ``at_least``), its
    Clopper-Pearson 95 % interval and the runs counted."""
    x = np.asarray(per_run, float)
    x = x[np.isfinite(x)]
    if rule not in ("at_most", "at_least"):
        raise ValueError(f"rule {rule!r}: a share is of a bound, at_most or at_least")
    k = int(np.sum(x <= bound) if rule == "at_most" else np.sum(x >= bound))
    return (k / x.size if x.size else math.nan), clopper_pearson(k, x.size), int(x.size)
