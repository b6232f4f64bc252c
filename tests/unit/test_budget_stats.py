"""The error budget's arithmetic (navsim.scoring.budget): independent sources that add give
contributions equal to each alone, shares summing to 1 and a root-sum-square equal to the
all-on value; a "what if" prediction matches the scaled errors; a non-additive budget says so."""

import math

import numpy as np
from scipy.stats import binom

from navsim.records.samples import EstimatorSamples, MetricSamples
from navsim.report.budget import rank_notes
from navsim.scoring.budget import MetricBudget, metric_budgets, predict
from navsim.scoring.intervals import CONFIDENCE

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


# --- the contributions' and shares' intervals, and when the runs are too few to rank ----------

#: the epochs per run of the synthetic coverage check (each run's sum of squares over them)
COVERAGE_EPOCHS = 50


def _known(rng, runs, sigmas):
    """Sources of known horizontal mean square: a random constant per run (``bias``), white noise
    (``noise``), a random walk (``walk``), each times its sigma; and their truth ``d_k^2``."""
    e = COVERAGE_EPOCHS
    base = 1e-4 * rng.normal(0, 1, (runs, e, 3))
    unit = {"bias": np.broadcast_to(rng.normal(0, 1, (runs, 1, 3)), (runs, e, 3)),
            "noise": rng.normal(0, 1, (runs, e, 3)),
            "walk": np.cumsum(rng.normal(0, 1, (runs, e, 3)), axis=1)}
    per_axis = {"bias": 1.0, "noise": 1.0, "walk": (e + 1) / 2}          # the unit processes' mean squares
    parts = {k: sigmas[k] * unit[k] for k in sigmas}
    truth = {k: 2 * sigmas[k] ** 2 * per_axis[k] for k in sigmas}         # N and E
    return base, parts, truth


def _samples_e(e) -> EstimatorSamples:
    """``rms.pos_m`` samples of errors ``(B, epochs, 3)``."""
    return EstimatorSamples(np.arange(e.shape[0]), {"rms.pos_m": MetricSamples(
        np.sum(e ** 2, 1), np.full((e.shape[0], 3), float(e.shape[1])), True)})


def _horizontal(base, parts) -> MetricBudget:
    alone = {k: _samples_e(base + v) for k, v in parts.items()}
    out = metric_budgets("KF", _samples_e(base + sum(parts.values())), _samples_e(base), alone,
                         {k: k for k in parts})
    return next(m for m in out if m.component == "horizontal")


def test_the_contributions_and_shares_intervals_cover_the_truth():
    """300 seeded budgets of 30 runs with known contributions (a random constant per run, white
    noise, a random walk): each 95 % interval of a contribution and of a share covers the truth
    in 95 % of them, within the binomial spread of 300 draws (99.9 % band)."""
    sigmas = {"bias": 2.0, "noise": 1.0, "walk": 0.05}
    reps, runs = 300, 30
    rng = np.random.default_rng(11)
    covered = {(k, what): 0 for k in sigmas for what in ("contribution", "share")}
    for _ in range(reps):
        base, parts, truth = _known(rng, runs, sigmas)
        m = _horizontal(base, parts)
        total = sum(truth.values())
        for x in m.lines:
            lo, hi = x.contribution_ci95
            covered[x.source, "contribution"] += lo <= math.sqrt(truth[x.source]) <= hi
            lo, hi = x.share_ci95
            covered[x.source, "share"] += lo <= truth[x.source] / total <= hi
    lo, hi = binom.ppf([0.0005, 0.9995], reps, CONFIDENCE) / reps
    for key, n in covered.items():
        assert lo <= n / reps <= hi, (key, n / reps, (lo, hi))


def test_too_few_runs_to_rank_is_said_and_a_clear_order_is_not():
    """Two sources of nearly the same size at 3 runs: their intervals overlap, the budget says
    they are not ranked (and the table's notes say so); three well-separated sources at 200
    runs: ranked, no note."""
    rng = np.random.default_rng(5)
    base, parts, _ = _known(rng, 3, {"bias": 1.0, "noise": 1.1, "walk": 0.01})
    few = _horizontal(base, parts)
    assert any({"bias", "noise"} <= set(tied) for tied in few.unranked()), few.unranked()
    notes = rank_notes(few, runs=3)
    assert notes and "too few runs to rank" in notes[0] and "bias" in notes[0] and "noise" in notes[0]
    base, parts, _ = _known(rng, 200, {"bias": 2.0, "noise": 1.0, "walk": 0.05})
    many = _horizontal(base, parts)
    assert [x.source for x in many.lines] == ["bias", "noise", "walk"]
    assert many.unranked() == [] and rank_notes(many, runs=200) == []
    for a, b in zip(many.lines, many.lines[1:]):
        assert a.contribution_ci95[0] > b.contribution_ci95[1]


def test_one_run_has_no_interval_and_no_order():
    rng = np.random.default_rng(6)
    base, parts, _ = _known(rng, 1, {"bias": 2.0, "noise": 1.0, "walk": 0.05})
    m = _horizontal(base, parts)
    assert all(not math.isfinite(v) for x in m.lines for v in x.contribution_ci95 + x.share_ci95)
    assert "no intervals" in " ".join(rank_notes(m, runs=1))
