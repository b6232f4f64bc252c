"""The objectives of ``navsim tune`` (navsim.scoring.tuning): the NEES distance symmetric in over-
and under-confidence, the band penalty, and the chi-square shape distance (Kolmogorov-Smirnov)
near 0 for chi-square samples and far from it for samples of the right mean but the wrong shape."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from navsim.records.metrics import Nees
from navsim.records.reference import PaperCheck
from navsim.records.samples import EstimatorSamples
from navsim.scoring.tuning import band_distance, objective, paper_checks_of, paper_distance, shape_distance


def _metrics(average, band=(7.9, 10.2), inside=0.5):
    nees = Nees(average=average, band=list(band), fraction_inside=inside, dim=9, average_from_start=average)
    rms = SimpleNamespace(pos_m=[3.0, 4.0, 0.0])
    m = SimpleNamespace(diverged_runs=0, runs_counted=10, nees=nees, nis={}, rms=rms)
    m.get = lambda path: {"rms.pos_m": rms.pos_m}.get(path)
    return m


def test_the_nees_objective_weighs_over_and_under_confidence_alike():
    assert objective("nees", _metrics(18.0)) == pytest.approx(objective("nees", _metrics(4.5)))
    assert objective("nees", _metrics(9.0)) == 0.0
    assert objective("nees-band", _metrics(9.0, inside=0.8)) == pytest.approx(0.2)


def test_rms_plus_consistent_is_the_rms_inside_the_band_and_penalised_outside():
    assert objective("rms", _metrics(9.0)) == pytest.approx(5.0)           # sqrt(3^2 + 4^2)
    assert objective("rms+consistent", _metrics(9.0)) == pytest.approx(5.0)
    assert objective("rms+consistent", _metrics(20.4)) == pytest.approx(10.0)   # 20.4 = 2 x 10.2
    assert band_distance(math.nan, (1, 2)) == math.inf and objective("rms+consistent", _metrics(math.nan)) is None


def test_the_shape_distance_is_small_for_chi_square_samples_only():
    """20 runs x 500 epochs: chi-square(9) samples lie within the KS distance's 99.9 % bound
    (1.95 / sqrt(n)); samples of the same mean, half of them at 0.5 and half at 1.5 times a
    chi-square (a covariance right on average, wrong by phase), lie far outside it."""
    rng = np.random.default_rng(5)
    good = rng.chisquare(9, (20, 500))
    bad = good * np.where(np.arange(500) < 250, 0.5, 1.5)
    t = np.arange(500.0)
    bound = 1.95 / math.sqrt(good.size)
    assert shape_distance(SimpleNamespace(t_s=t, nees=good), 0.0, False) < bound
    assert shape_distance(SimpleNamespace(t_s=t, nees=bad), 0.0, False) > 5 * bound
    nis = SimpleNamespace(t_s=t, nis={"gnss": rng.chisquare(3, (20, 500))}, nis_dim={"gnss": 3})
    assert shape_distance(nis, 0.0, True) < bound


def test_the_paper_objective_is_the_log_distance_of_the_runs_median_from_the_papers_numbers():
    """Runs whose per-run values have the medians 2 m (a std) and -3 m (a largest negative
    error): 0 against the paper's 2 and -3; ln 2 / sqrt(2) when one is twice the paper's; the
    claims, the bounds and the population numbers are not fitted; a median of the other sign is
    no fit."""
    runs = np.arange(5)
    samples = EstimatorSamples(runs, {}, {"windows.w.height_m.std": np.c_[[1.0, 2.0, 2.0, 3.0, 9.0]],
                                          "windows.w.height_m.max_neg": np.c_[[-1.0, -3.0, -3.0, -4.0, -9.0]]})
    check = lambda path, paper, **kw: PaperCheck("KF", path, "close", paper, kind=kw.pop("kind", "single_run"), **kw)
    ref = SimpleNamespace(checks=[check("windows.w.height_m.std", 2.0), check("windows.w.height_m.max_neg", -3.0),
                                  check("windows.w.height_m.std", 1.0, kind="population"),
                                  check("windows.w.height_m.std", 0.1, claim="c", of="other"),
                                  PaperCheck("other", "windows.w.height_m.std", "close", 5.0, kind="single_run"),
                                  PaperCheck("KF", "windows.w.height_m.std", "at_most", 5.0, kind="single_run")])
    fitted = paper_checks_of(ref, "KF")
    assert [c.bound for c in fitted] == [2.0, -3.0]
    assert paper_distance(fitted, samples) == 0.0
    twice = [check("windows.w.height_m.std", 1.0), fitted[1]]
    assert paper_distance(twice, samples) == pytest.approx(math.log(2) / math.sqrt(2))
    assert paper_distance([check("windows.w.height_m.max_neg", 3.0)], samples) is None
    assert paper_distance([check("p99.pos_m", [1.0, 1.0, 1.0])], samples) is None        # not kept: no fit
