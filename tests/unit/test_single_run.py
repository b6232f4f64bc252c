"""A paper's single flight against the spread of our single runs (navsim.scoring.single_run):
the prediction range covers a new run as often as it claims, whatever the distribution; a value
in the far tail fails; the share of runs meeting a bound carries its exact interval."""

import numpy as np
import pytest

from navsim.scoring.intervals import binomial_interval
from navsim.scoring.single_run import (
    bound_reached,
    coverage_interval,
    judge_single_run,
    min_runs,
    prediction_range,
    share_meeting,
)

TRIALS = 1000


@pytest.mark.parametrize("runs", [40, 100])
def test_one_draw_of_the_per_run_distribution_passes_in_95_percent_of_trials(runs):
    """1000 seeded trials: our N runs and the "paper's" flight all drawn from one skewed per-run
    distribution (an RMS over a run: the root of a scaled chi-square of 5 degrees); the paper's
    value passes in 95 % +- 2 % of the trials (binomial spread at 1000 trials: +-1.4 %, plus the
    range's coverage (m - k)/(N + 1), 95.1 % at 40 runs, 95.0 % at 100)."""
    rng = np.random.default_rng(55)
    passed = 0
    for _ in range(TRIALS):
        ours = np.sqrt(rng.chisquare(5, runs) / 5)
        paper = np.sqrt(rng.chisquare(5) / 5)
        passed += judge_single_run(paper, ours).passed
    assert 0.93 <= passed / TRIALS <= 0.97


def test_a_value_at_the_0_1_percent_quantile_fails_in_at_least_95_percent_of_trials():
    """At 100 runs the range's low end is the 2nd smallest run: a value at the distribution's
    0.1 % quantile lies below it unless two of the 100 runs do (probability 0.5 %)."""
    from scipy.stats import chi2
    rng = np.random.default_rng(56)
    q = np.sqrt(chi2.ppf(0.001, 5) / 5)
    failed = sum(not judge_single_run(q, np.sqrt(rng.chisquare(5, 100) / 5)).passed for _ in range(TRIALS))
    assert failed / TRIALS >= 0.95


def test_the_range_and_the_percentile_of_a_known_sample():
    x = np.arange(1.0, 101.0)                        # 1..100: ranks 2 and 99 bound 95 %
    assert prediction_range(x) == (2.0, 99.0)
    v = judge_single_run(50.0, x)
    assert v.passed and v.percentile == pytest.approx(49.5) and v.runs == 100
    assert prediction_range(np.arange(10.0)) == (-np.inf, np.inf)      # 10 runs bound neither end


def test_the_share_of_runs_meeting_a_bound_has_its_exact_interval():
    share, (lo, hi), n = share_meeting(np.r_[np.zeros(18), np.ones(2)], 0.5, "at_most")
    assert share == 0.9 and n == 20
    assert (lo, hi) == pytest.approx((0.683, 0.988), abs=1e-3)        # Clopper-Pearson, 18 of 20
    assert binomial_interval(0, 10)[0] == 0.0 and binomial_interval(10, 10)[1] == 1.0


def test_39_runs_bound_the_range_and_its_coverage_interval_holds_the_coverage_of_new_runs():
    """At 38 runs the 95 % range is open; at 39 it is the sample's extremes. The share of new
    runs a 100-run range holds is Beta(97, 4): over 2000 seeded trials (uniform values, where
    that share is the distance between the order statistics), 95 % +- 1.5 % fall in its
    95 % interval."""
    assert min_runs() == 39
    assert np.isinf(prediction_range(np.arange(38.0))).all() and prediction_range(np.arange(39.0)) == (0.0, 38.0)
    lo, hi = coverage_interval(100)
    assert lo < 0.95 < hi and np.isnan(coverage_interval(20)).all()
    rng = np.random.default_rng(57)
    held = [lo <= np.diff(prediction_range(rng.uniform(size=100)))[0] <= hi for _ in range(2000)]
    assert 0.935 <= np.mean(held) <= 0.965


def test_a_never_is_a_value_of_a_run_and_a_missing_one_is_left_out():
    """A run that never converges has an infinite time (a value, at the top of the range); a run
    without the statistic (NaN) is left out of the runs counted."""
    x = np.r_[np.arange(1.0, 41.0), np.inf, np.nan]
    v = judge_single_run(500.0, x)
    assert v.runs == 41 and v.high == np.inf and v.passed
    share, _, n = share_meeting(np.c_[x, x], [100.0, 100.0], "at_most")
    assert n == 41 and share == 40 / 41


def test_a_bound_on_a_vector_is_met_by_every_component_of_one_run_at_once():
    """100 runs, one component 1..100 and the other 100..1: the bound [2, 2] is met on each
    component by two runs (the range's low end, rank 2, reaches it), but by no run on both at
    once, so the paper's flight, which met it on both, is outside our range; [3, 99] is met by
    two runs at once (runs 2 and 3), which is enough."""
    x = np.c_[np.arange(1.0, 101.0), np.arange(100.0, 0.0, -1.0)]
    assert prediction_range(x[:, 0])[0] <= 2 and prediction_range(x[:, 1])[0] <= 2
    assert not bound_reached(x, [2.0, 2.0], "at_most")
    assert bound_reached(x, [3.0, 99.0], "at_most") and not bound_reached(x, [2.0, 99.0], "at_most")
    assert bound_reached(x, [99.0, 2.0], "at_least") is False and bound_reached(x, [99.0, 1.0], "at_least")
