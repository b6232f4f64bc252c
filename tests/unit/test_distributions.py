"""navsim's quantiles against scipy.stats: to the bit (the binomial CDF within 1e-14, and the
order statistics it picks equal), NaN where scipy.stats gives NaN; and a command's imports
without scipy.stats."""

import subprocess
import sys

import numpy as np
import pytest
from scipy import stats

from navsim.foundations import distributions as d
from navsim.scoring.intervals import CONFIDENCE, _order_ranks

RNG = np.random.default_rng(56)
Q = np.concatenate([RNG.uniform(0.0, 1.0, 3000), [0.025, 0.975, 0.5, 0.05, 0.95, 0.999, 1e-9, 1 - 1e-9]])


def same(a, b) -> bool:
    return np.array_equal(np.asarray(a, float), np.asarray(b, float), equal_nan=True)


def test_chi_square_quantile_is_scipys_to_the_bit():
    nu = np.concatenate([RNG.uniform(0.05, 3e5, Q.size - 2000), np.arange(1.0, 2001.0)])
    assert same(d.chi2_ppf(Q, nu), stats.chi2.ppf(Q, nu))
    for q in (0.025, 0.975, 0.999):                                   # scalars, integer degrees
        for k in (1, 2, 3, 9, 16, 4000, 9 * 1000):
            assert float(d.chi2_ppf(q, k)) == float(stats.chi2.ppf(q, k))
    assert np.isnan(d.chi2_ppf(0.5, 0)) and np.isnan(stats.chi2.ppf(0.5, 0))


def test_student_quantile_and_tail_are_scipys_to_the_bit():
    df = np.concatenate([np.arange(1.0, Q.size - 499.0), RNG.uniform(0.2, 60.0, 500)])
    assert same(d.t_ppf(Q, df), stats.t.ppf(Q, df))
    x = RNG.normal(0.0, 4.0, df.size)
    assert same(d.t_sf(x, df), stats.t.sf(x, df))
    assert float(d.t_ppf(0.5 + CONFIDENCE / 2, 39)) == float(stats.t.ppf(0.5 + CONFIDENCE / 2, 39))
    assert np.isnan(d.t_ppf(0.975, 0)) and np.isnan(stats.t.ppf(0.975, 0))


def test_normal_and_beta_quantiles_are_scipys_to_the_bit():
    assert same(d.norm_ppf(Q), stats.norm.ppf(Q))
    a, b = RNG.uniform(0.1, 800.0, Q.size), RNG.uniform(0.1, 800.0, Q.size)
    assert same(d.beta_ppf(Q, a, b), stats.beta.ppf(Q, a, b))
    ka, kb = np.floor(a) + 1, np.floor(b) + 1                        # Clopper-Pearson's whole shapes
    assert same(d.beta_ppf(Q, ka, kb), stats.beta.ppf(Q, ka, kb))
    assert np.isnan(d.beta_ppf(0.5, 0.0, 3.0)) and np.isnan(stats.beta.ppf(0.5, 0.0, 3.0))


@pytest.mark.parametrize("n", [2, 3, 5, 20, 39, 40, 100, 250, 1000, 5000])
def test_binomial_cdf_is_scipys_within_rounding_and_picks_the_same_order_statistics(n):
    k = np.arange(n + 1)
    for p in (0.01, 0.025, 0.05, 0.1, 0.25, 0.3, 0.5, 0.75, 0.9, 0.95, 0.975, 0.99):
        ours, theirs = d.binom_cdf(k, n, p), stats.binom.cdf(k, n, p)
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-14)
        assert ours[-1] == 1.0 and np.all(np.diff(ours) >= -1e-15)
        a = (1 - CONFIDENCE) / 2
        lo, hi = (int(np.searchsorted(theirs, a, side="right")) - 1, int(np.searchsorted(theirs, 1 - a, side="left")))
        expect = None if lo < 0 and hi >= n else (lo, min(hi, n))
        assert _order_ranks(n, p) == expect, (n, p)


def test_a_command_does_not_import_scipy_stats():
    """The command line's imports (every command's module) leave scipy.stats out: 0.35 s of
    every command's start."""
    code = "import sys, navsim.cli.entry, navsim.cli.commands\nprint('scipy.stats' in sys.modules)\n"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False", out
