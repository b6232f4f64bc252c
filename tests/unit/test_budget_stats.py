"""The error budget's arithmetic (navsim.scoring.budget): independent sources that add give
contributions equal to each alone, shares summing to 1 and a root-sum-square equal to the
all-on value; a "what if" prediction matches the scaled errors; a non-additive budget says so."""

import math

import numpy as np

from navsim.records.samples import EstimatorSamples, MetricSamples
from navsim.scoring.budget import metric_budgets, predict

EPOCHS = 200


def _samples(e) -> EstimatorSamples:
    """``final.pos_m``-like samples of errors ``(B, 3)`` and ``rms.pos_m`` of ``(B, epochs, 3)``."""
    return EstimatorSamples(np.arange(e.shape[0]), {"rms.pos_m": MetricSamples(
        np.sum(e ** 2, 1), np.full((e.shape[0], 3), float(EPOCHS)), True)})


def _sources(rng, runs=400):
    """Three independent sources of error (a random constant, white noise, a random walk) and a
    tiny residual with none on."""
    base = 1e-4 * rng.normal(0, 1, (runs, EPOCHS, 3))
    parts = {"bias": np.broadcast_to(2.0 * rng.normal(0, 1, (runs, 1, 3)), (runs, EPOCHS, 3)),
             "noise": 1.0 * rng.normal(0, 1, (runs, EPOCHS, 3)),
             "walk": 0.05 * np.cumsum(rng.normal(0, 1, (runs, EPOCHS, 3)), axis=1)}
    return base, parts


def test_independent_additive_sources_make_a_closed_budget():
    rng = np.random.default_rng(3)
    base, parts = _sources(rng)
    all_on = base + sum(parts.values())
    alone = {k: _samples(base + v) for k, v in parts.items()}
    [m] = [x for x in metric_budgets("KF", _samples(all_on), _samples(base), alone, {k: k for k in parts})
           if x.component == "horizontal"]
    assert [x.source for x in m.lines] == ["bias", "noise", "walk"]     # sorted: 2 sqrt 2, sqrt 2, ~0.7
    for x in m.lines:
        own = np.sqrt(np.mean(np.sum(parts[x.source][..., :2] ** 2, -1)))
        assert abs(x.contribution / own - 1) < 1e-3
    assert abs(sum(x.share for x in m.lines) - 1) < 1e-12
    # independent sources: the cross terms average out over 400 runs (a few per cent)
    assert m.additive and abs(m.ratio - 1) < 0.03
    # what if the bias were halved
    halved = base + 0.5 * parts["bias"] + parts["noise"] + parts["walk"]
    [real] = [x for x in metric_budgets("KF", _samples(halved), _samples(base), {}, {}) if x.component == "horizontal"]
    assert abs(predict(m, "bias", 0.5) / real.all_on - 1) < 0.03


def test_groups_add_their_members_variances_and_a_coupled_pair_is_not_additive():
    rng = np.random.default_rng(4)
    base, parts = _sources(rng)
    alone = {k: _samples(base + v) for k, v in parts.items()}
    groups = {"bias": "imu", "walk": "imu", "noise": "gnss"}
    all_on = base + sum(parts.values())
    [m] = [x for x in metric_budgets("KF", _samples(all_on), _samples(base), alone, groups) if x.component == "N"]
    [per] = [x for x in metric_budgets("KF", _samples(all_on), _samples(base), alone, {k: k for k in parts})
             if x.component == "N"]
    imu = m.line("imu").contribution
    assert math.isclose(imu, math.hypot(per.line("bias").contribution, per.line("walk").contribution))
    # a source that doubles another when both are on (a gain that switches with the data)
    coupled = base + 2 * parts["bias"] + parts["noise"]
    alone2 = {k: alone[k] for k in ("bias", "noise")}
    [m2] = [x for x in metric_budgets("KF", _samples(coupled), _samples(base), alone2, {"bias": "bias", "noise": "noise"})
            if x.component == "N"]
    assert not m2.additive and m2.ratio < 0.7
