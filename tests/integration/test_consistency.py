"""The shipped scenarios whose filter models are the sensors' own: their sigmas describe their
errors (NEES and NIS inside their 95 % chi-square bands, each navigation error's mean
(error/sigma)^2 near 1). Slow: 200 runs each, as shipped (``docs/consistency.md``)."""

from pathlib import Path

import pytest

import navsim

ROOT = Path(__file__).resolve().parents[2]

#: scenario -> the estimator whose every model matches the sensors
MATCHED = {"p0_matched_ads": "ES-KF 17, matched ADS", "p3_sins_gps": "SINS/GPS 15-state"}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(MATCHED))
def test_a_matched_filter_is_consistent(name):
    result = navsim.run(ROOT / "scenarios" / f"{name}.yaml")
    m = result.metrics.estimators[MATCHED[name]]
    assert result.record.runs == 200
    # the epochs share each run's random-constant biases, so the fraction of them inside the
    # band spreads far wider than for independent epochs: p0_matched_ads at 200 runs, seeds 1-11,
    # 0.875-1.000 (mean 0.94); the average over the epochs sits inside the band at every seed
    assert m.nees.band[0] <= m.nees.average <= m.nees.band[1], m.nees
    assert m.nees.fraction_inside >= 0.8, m.nees
    # each navigation error: 200 runs put a consistent filter's mean within about +-0.2 of 1
    assert len(m.nees.per_state) == 9, m.nees.per_state      # att, vel, pos; N, E, D
    assert all(0.8 <= v <= 1.25 for v in m.nees.per_state), m.nees.per_state
    assert m.nis, "no NIS scored"
    for key, nis in m.nis.items():
        assert nis.fraction_inside >= 0.9, (key, nis)
