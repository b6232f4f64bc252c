import math

import numpy as np
import pytest
from scipy.stats import chi2

from navsim.records.history import EstimatorHistory
from navsim.records.metrics import EstimatorMetrics, lookup
from navsim.scoring.scorer import score
from navsim.scoring.stats import chi2_band, convergence_time


def test_convergence_time_of_an_exponential_decay():
    t = np.arange(200.0)
    err = 10 * np.exp(-t / 10) + 1
    steady = np.median(err[100:])
    # 10 exp(-t/10) + 1 = 2 steady  ->  t = 10 ln(10 / (2 steady - 1))
    expected = 10 * math.log(10 / (2 * steady - 1))
    assert convergence_time(t, err) == pytest.approx(math.ceil(expected))
    assert convergence_time(t, np.exp(t / 10)) is None
    assert convergence_time(t, 1 + 1e-6 * t ** 3) is None          # free-inertial drift


def test_chi2_band_of_an_average():
    lo, hi = chi2_band(3, 50)
    assert lo == pytest.approx(chi2.ppf(0.025, 150) / 50) and hi == pytest.approx(chi2.ppf(0.975, 150) / 50)
    assert lo < 3 < hi


def test_score_of_a_known_history():
    rng = np.random.default_rng(3)
    B, E = 400, 50
    t = np.arange(E, dtype=float)
    sig = np.array([1.0, 2.0, 0.5])
    pos = rng.normal(size=(B, E, 3)) * sig
    z = np.zeros((B, E, 3))
    sigma = np.concatenate([np.full((B, E, 6), 1.0), np.broadcast_to(sig, (B, E, 3))], -1)
    nees = np.sum((pos / sig) ** 2, -1) + rng.chisquare(6, size=(B, E))
    h = EstimatorHistory("x", t, z, z, pos, sigma, nees, {}, {}, np.zeros(B, bool))
    typed = score(h, settle_s=10.0, windows=(("w", 20.0, 30.0),))
    m = typed.to_dict()
    np.testing.assert_allclose(typed.rms.pos_m, sig, rtol=0.03)
    assert typed.windows["w"].quantities["height_m"].std == m["windows"]["w"]["height_m"]["std"]
    assert EstimatorMetrics.from_dict(m) == typed            # the metrics.json mapping round-trips
    assert m["windows"]["w"]["height_m"]["std"] == pytest.approx(0.5, rel=0.05)
    assert m["windows"]["w"]["height_m"]["max_pos"] > 1.0 > 0 > -1.0 > m["windows"]["w"]["height_m"]["max_neg"]
    assert m["nees"]["average"] == pytest.approx(9.0, rel=0.03) and m["nees"]["fraction_inside"] > 0.8
    assert lookup(m, "windows.w.height_m.std") == m["windows"]["w"]["height_m"]["std"]
    assert lookup(m, "rms.nothing") is None and typed.get("rms.pos_m") == typed.rms.pos_m
    # a diverged run is excluded and counted
    h.diverged[0] = True
    h.pos_err_m[0] = np.nan
    m = score(h, 10.0).to_dict()
    assert m["diverged_runs"] == 1 and m["runs_counted"] == B - 1 and np.isfinite(m["rms"]["pos_m"]).all()


def test_nees_is_scored_after_the_settling_time():
    rng = np.random.default_rng(4)
    B, E = 200, 60
    t = np.arange(E, dtype=float)
    z = np.zeros((B, E, 3))
    nees = rng.chisquare(9, size=(B, E))
    nees[:, :20] *= 50.0                        # an adaptive filter still learning its R
    h = EstimatorHistory("x", t, z, z, z, np.ones((B, E, 9)), nees, {}, {}, np.zeros(B, bool))
    lo, hi = chi2_band(9, B)
    settled = score(h, settle_s=20.0).nees
    assert lo < settled.average < hi and settled.fraction_inside > 0.8
    assert settled.average_from_start > 100.0
    assert score(h, settle_s=0.0).nees.average > 100.0


def test_metrics_of_no_counted_run_and_an_older_file_read_back():
    rng = np.random.default_rng(5)
    B, E = 3, 10
    z = rng.normal(size=(B, E, 3))
    h = EstimatorHistory("x", np.arange(E, dtype=float), z, z, z, None, None, {}, {}, np.ones(B, bool))
    m = score(h, 0.0)
    assert m.to_dict() == {"runs_counted": 0, "diverged_runs": 3, "settle_s": 0.0,
                           "divergence": {"count": 3, "causes": {"not recorded": 3},
                                          "runs": [{"run": r, "t_s": None, "cause": "not recorded"} for r in range(3)]}}
    # an older metrics.json wrote an empty section as {}: read back as not scored
    old = EstimatorMetrics.from_dict({**m.to_dict(), "landmarks": {}})
    assert old.landmarks is None and old.divergence.runs[0].t_s is None
