"""The causes of the warnings the suite and the runs printed (issue 50), fixed where they
arise rather than filtered: a bootstrap replicate that draws no run (NaN at every epoch) gave
"All-NaN slice encountered", and a report's pages, drawn through pyplot, "More than 20 figures
have been opened"."""

import warnings

import numpy as np
from test_scorer import history

from navsim.report.figures import page_figure, pyplot
from navsim.scoring.scorer import score
from navsim.scoring.stats import convergence_time


def test_convergence_of_an_error_without_a_finite_value_is_none_without_a_warning():
    t_s = np.arange(10.0)
    err = np.full(10, np.nan)                       # a bootstrap replicate that drew no run
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert convergence_time(t_s, err) is None
        assert convergence_time(t_s, np.r_[5.0, 1.0, np.full(8, np.nan)]) is None


def test_scoring_two_runs_warns_nothing():
    """Two counted runs: about one bootstrap replicate in seven draws neither."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = score(history(np.random.default_rng(5), 3), settle_s=10.0, windows=[("w", 20.0, 60.0)])
    assert m.runs_counted == 2 and m.ci95 is not None


def test_report_pages_are_not_held_by_pyplot():
    """A page is a figure of its own, closed when dropped: none is registered with pyplot, so
    a report (or a suite) of more than 20 pages opens none there."""
    plt = pyplot()
    before = set(plt.get_fignums())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        figures = [page_figure(2, 1, sharex=True)[0] for _ in range(25)]
    assert set(plt.get_fignums()) == before
    assert all(f.get_size_inches().tolist() == figures[0].get_size_inches().tolist() for f in figures)
