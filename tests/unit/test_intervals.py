"""The 95 % intervals of :mod:`navsim.scoring.intervals`: their coverage on synthetic Monte
Carlos whose truth is known (a share of 1000 seeded trials, inside the binomial spread of 95 %:
sigma 0.7 %, bounds at 3.5 sigma), the exact ones against their definition, and the run-keyed
bootstrap's independence of the chunking."""

import math

import numpy as np
import pytest
from scipy.stats import binomtest, norm

from navsim.records.history import EstimatorHistory
from navsim.scoring import intervals as iv
from navsim.scoring.landmarks import SightingEpochs, sighting_intervals
from navsim.scoring.scorer import EstimatorScore, score
from navsim.scoring.stats import AbsPercentiles

TRIALS = 1000
#: a calibrated 95 % interval covers 950 of 1000 trials give or take 3.5 binomial sigmas
COVERED = (0.925, 0.975)


def _coverage(draw, interval, truth, seed) -> float:
    rng = np.random.default_rng(seed)
    hits = 0
    for _ in range(TRIALS):
        lo, hi = interval(*draw(rng))
        hits += lo <= truth <= hi
    return hits / TRIALS


@pytest.mark.parametrize("case", ["one value per run", "random constant plus noise"])
def test_the_rms_interval_covers_its_truth_at_20_runs(case):
    """One zero-mean Gaussian value per run (the mean square is chi2(20)/20: right-skewed), and a
    random constant per run under white noise (each run's mean square ~ 1 + chi2(1)): both
    covered at 95 % from 20 runs."""
    if case == "one value per run":
        draw = lambda rng: (rng.normal(0, 2.0, 20) ** 2, np.ones(20))
        truth = 2.0
    else:
        draw = lambda rng: (np.sum((rng.normal(0, 1, (20, 1)) + rng.normal(0, 1, (20, 100))) ** 2, 1), np.full(20, 100))
        truth = math.sqrt(2.0)
    share = _coverage(draw, iv.rms_interval, truth, 11)
    assert COVERED[0] <= share <= COVERED[1], share


def test_the_order_statistic_interval_of_a_median_and_a_p95_covers_at_least_95_pct():
    """Distribution-free: at least 95 % whatever the distribution (an exponential here)."""
    for q in (50, 95):
        truth = -math.log(1 - q / 100)
        share = _coverage(lambda rng: (rng.exponential(1.0, 200), q), iv.order_statistic_interval, truth, 3)
        assert share >= COVERED[0], (q, share)


def test_the_order_statistic_interval_is_the_classical_one_and_open_where_runs_are_too_few():
    x = np.arange(1.0, 21.0)
    assert iv.order_statistic_interval(x, 50) == [6.0, 15.0]       # the 6th and 15th of 20
    lo, hi = iv.order_statistic_interval(x, 95)
    assert lo == 17.0 and math.isnan(hi)                              # 20 runs cannot bound a p95 from above


def test_clopper_pearson_is_scipys_exact_interval():
    for k, n in ((0, 20), (7, 20), (20, 20), (193, 200)):
        ci = binomtest(k, n).proportion_ci(0.95, method="exact")
        assert np.allclose(iv.binomial_interval(k, n), [ci.low, ci.high], rtol=1e-9, atol=1e-12)


def test_woodruff_covers_a_pooled_percentile_of_independent_runs():
    """The 95th percentile of |x| pooled over 20 runs of 50 values each."""
    truth = norm.ppf(0.975)

    def interval(x, q):
        p = AbsPercentiles()
        p.add("x", x, q)
        p.second_pass()
        p.add("x", x, q)
        return p.interval("x")

    share = _coverage(lambda rng: (rng.normal(size=(20, 50)), 95), interval, truth, 5)
    assert COVERED[0] <= share <= COVERED[1], share


def test_a_share_and_a_std_cover_their_truth():
    share = _coverage(lambda rng: (rng.binomial(30, 0.8, 20), np.full(20, 30)), iv.share_interval, 0.8, 2)
    assert COVERED[0] <= share <= COVERED[1], share

    def std_draw(rng):
        y = rng.normal(0, 3.0, (20, 50))
        return y.sum(1), (y ** 2).sum(1), np.full(20, 50)

    share = _coverage(std_draw, iv.std_interval, 3.0, 4)
    assert COVERED[0] <= share <= COVERED[1], share


def test_fewer_than_two_runs_have_no_interval():
    assert all(math.isnan(v) for v in iv.rms_interval([4.0], [1]))
    assert all(math.isnan(v) for v in iv.order_statistic_interval([1.0], 50))


def test_runs_needed_scales_the_half_width_as_one_over_sqrt_runs():
    # value 1.0, interval 0.8-1.2 at 20 runs, bound 1.1: the half-width must shrink from 0.2 to 0.1
    assert iv.runs_needed(20, 1.0, [0.8, 1.2], 1.1) == 80
    assert iv.runs_needed(20, 1.0, [0.8, 1.2], 1.3) is None        # decided already


def test_a_runs_bootstrap_weights_do_not_depend_on_its_chunk():
    together = iv.bootstrap_weights(np.arange(10, 20))
    alone = iv.bootstrap_weights([13])
    assert np.array_equal(together[:, 3], alone[:, 0])
    assert together.shape == (iv.BOOTSTRAP_REPLICATES, 10) and abs(together.mean() - 1) < 0.05


def _history(seed: int, runs: int = 12, epochs: int = 40) -> EstimatorHistory:
    rng = np.random.default_rng(seed)
    t = np.arange(epochs, dtype=float)
    err = lambda s: rng.normal(0, s, (runs, 1, 3)) + rng.normal(0, s, (runs, epochs, 3))
    sigma = np.full((runs, epochs, 9), 1.0)
    return EstimatorHistory("x", t, err(1e-3), err(0.1), err(2.0), sigma, rng.chisquare(9, (runs, epochs)), {}, {},
                            np.zeros(runs, bool))


def _rows(h: EstimatorHistory, rows: slice) -> EstimatorHistory:
    return EstimatorHistory("x", h.t_s, h.att_err_rad[rows], h.vel_err_mps[rows], h.pos_err_m[rows], h.sigma[rows],
                            h.nees[rows], {}, {}, h.diverged[rows])


def test_the_intervals_do_not_depend_on_the_chunking_and_hold_the_point_values():
    """Scored in one chunk or in two, the intervals agree (to the interval's 4 digits); each RMS
    interval holds its RMS."""
    h = _history(1)
    one = score(h, settle_s=5.0)
    s = EstimatorScore(5.0)
    halves = [_rows(h, slice(0, 5)), _rows(h, slice(5, None))]
    for p in range(2):
        for b, part in zip((0, 5), halves):
            s.add(part, runs=np.arange(b, b + part.diverged.size))
        if p == 0:
            s.second_pass()
    two = s.result()
    assert one.ci95 == two.ci95
    for name in ("pos_m", "vel_mps", "att_deg"):
        for v, (lo, hi) in zip(getattr(one.rms, name), one.ci95["rms"][name]):
            assert lo <= v <= hi


def test_a_biased_bootstrap_statistic_keeps_its_point_inside_its_interval():
    """The share of epochs whose run-averaged NEES is inside its band falls under resampling
    (the resampled runs add spread): 12 consistent runs, the shifted interval holds the share
    and stays within [0, 1]."""
    m = score(_history(3), settle_s=5.0)
    lo, hi = m.ci95["nees"]["fraction_inside"]
    assert 0.0 <= lo <= m.nees.fraction_inside <= hi <= 1.0
    lo, hi = m.ci95["nees"]["average"]
    assert lo <= m.nees.average <= hi


def test_the_landmark_intervals_cover_their_truth():
    """Gaussian fix errors of a known sigma per run (a random constant per run and sighting):
    the RMS after the sightings and the share inside 3 sigma covered at 95 % from 20 runs."""
    spans = [(f"cam {k}", 10.0 * k, 10.0 * k + 5, 1.5) for k in range(1, 6)]
    t = np.arange(60.0)
    truth_rms, truth_share = 2.0, 2 * norm.cdf(3 * 1.5 / 2.0) - 1
    hits = np.zeros(2)
    rng = np.random.default_rng(5)
    trials = 400
    for _ in range(trials):
        e = rng.normal(0, truth_rms, (20, len(t), 3))
        ci = sighting_intervals(SightingEpochs(t, e, np.zeros(20, bool)), spans)
        hits += [ci["rms_after_m"][0] <= truth_rms <= ci["rms_after_m"][1],
                 ci["fraction_within_3sigma"][0] <= truth_share <= ci["fraction_within_3sigma"][1]]
    # 400 trials: 95 % give or take 3.5 binomial sigmas (3.8 points)
    assert np.all((hits / trials > 0.91) & (hits / trials < 0.99)), hits / trials


def test_the_runs_for_a_precision_give_that_precision():
    """From 20 runs of a random constant under noise, the runs predicted for a +-5 % interval of
    the RMS (the median over 50 such Monte Carlos: one alone is as uncertain as its interval's
    width); at that many runs the interval's half-width is 5 % of the value (mean over 100
    Monte Carlos, within 4.5-5.5 %)."""
    rng = np.random.default_rng(17)
    draw = lambda runs: (np.sum((rng.normal(0, 1, (runs, 1)) + rng.normal(0, 1, (runs, 100))) ** 2, 1),
                         np.full(runs, 100.0))
    predicted = []
    for _ in range(50):
        s, n = draw(20)
        rms = math.sqrt(s.sum() / n.sum())
        predicted.append(iv.runs_for_precision(20, rms, iv.rms_interval(s, n), 0.05))
    runs = int(np.median(predicted))
    assert 100 < runs < 2000
    halves = []
    for _ in range(100):
        s, n = draw(runs)
        rms = math.sqrt(s.sum() / n.sum())
        lo, hi = iv.rms_interval(s, n)
        halves.append((hi - lo) / 2 / rms)
    assert 0.045 < np.mean(halves) < 0.055, (runs, np.mean(halves))


def test_nanmean_of_rows_is_numpys_row_by_row():
    from navsim.scoring.samples import _nanmean
    rng = np.random.default_rng(4)
    a = rng.normal(0, 1, (50, 300)) ** 2
    a[rng.random(a.shape) < 0.2] = np.nan
    a[3] = np.nan
    a[7, ::4] = np.inf
    a[9] = np.inf
    with np.errstate(invalid="ignore"):
        want = [np.nanmean(r) if np.isfinite(r).any() else np.nan for r in a]
    assert np.array_equal(_nanmean(a), np.array(want), equal_nan=True)
