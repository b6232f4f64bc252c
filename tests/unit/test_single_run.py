"""A paper's single flight against the spread of our single runs (navsim.scoring.single_run):
the prediction range covers a new run as often as it claims, whatever the distribution; a value
in the far tail fails; the share of runs meeting a bound carries its exact interval."""

import numpy as np
import pytest

from navsim.scoring.single_run import clopper_pearson, judge_single_run, prediction_range, share_meeting

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
    assert clopper_pearson(0, 10)[0] == 0.0 and clopper_pearson(10, 10)[1] == 1.0
