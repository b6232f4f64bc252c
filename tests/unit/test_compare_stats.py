"""The comparison's statistics (navsim.scoring.compare): the paired and unpaired intervals of a
difference of two RMS cover it, pairing narrows them, Holm's step keeps the family's false
alarms at 5 %, the per-run samples round-trip through samples.npz."""

import math

import numpy as np
import pytest

from navsim.records.samples import EstimatorSamples, MetricSamples, load_samples, save_samples
from scipy.stats import t as student_t

from navsim.foundations.errors import UsageError
from navsim.report.compare import verdict_text
from navsim.scoring.compare import (BETTER, NEGLIGIBLE, SAME, Difference, Side, check_margin, compare_samples,
                                    differences, holm, runs_to_resolve)

EPOCHS = 100
TRIALS = 600


def _side(errors, scale: float = 1.0) -> EstimatorSamples:
    """An estimator's ``rms.pos_m`` samples from errors ``(B, epochs, 3)``."""
    e = scale * errors
    return EstimatorSamples(np.arange(e.shape[0]), {"rms.pos_m": MetricSamples(
        np.sum(e ** 2, 1), np.full((e.shape[0], 3), float(EPOCHS)), True)})


def _runs(rng, runs: int):
    """A run's errors: a random constant (its bias) plus white noise, and a small part of its own
    (what two filters on the same data do not share)."""
    shared = rng.normal(0, 1, (runs, 1, 3)) + rng.normal(0, 1, (runs, EPOCHS, 3))
    own = lambda: 0.1 * rng.normal(0, 1, (runs, EPOCHS, 3)) + 0.1 * rng.normal(0, 1, (runs, 1, 3))
    return shared + own(), shared + own()


def test_the_paired_and_unpaired_intervals_cover_the_difference_at_50_runs():
    """B's errors are 1.05 times A's kind: B - A of the RMS is 0.05 sqrt(2.02) per axis; both
    intervals hold it in 95 % of 600 Monte Carlos (give or take 3.5 binomial sigmas, 3.1 %)."""
    rng = np.random.default_rng(21)
    truth = 0.05 * math.sqrt(2.02)
    hits = {True: 0, False: 0}
    for _ in range(TRIALS):
        ea, eb = _runs(rng, 50)
        hits[True] += (lambda d: d.ci95[0] <= truth <= d.ci95[1])(differences(_side(ea), _side(eb, 1.05), True)[0])
        ea, _ = _runs(rng, 50)
        _, eb = _runs(rng, 50)
        hits[False] += (lambda d: d.ci95[0] <= truth <= d.ci95[1])(differences(_side(ea), _side(eb, 1.05), False)[0])
    for paired, n in hits.items():
        assert 0.919 <= n / TRIALS <= 0.981, (paired, n / TRIALS)


def test_pairing_cancels_the_shared_errors():
    """The same data: the paired interval is several times narrower, and finds the 5 % that the
    unpaired one cannot at 50 runs."""
    ea, eb = _runs(np.random.default_rng(4), 50)
    a, b = _side(ea), _side(eb, 1.05)
    p = {d.name: d for d in differences(a, b, True)}
    u = {d.name: d for d in differences(a, b, False)}
    key = "rms.pos_m horizontal"
    assert p[key].diff == u[key].diff
    width = lambda d: d.ci95[1] - d.ci95[0]
    assert width(u[key]) > 4 * width(p[key])
    assert p[key].verdict == "worse" and u[key].verdict == SAME and u[key].runs_needed > 50


def test_holm_keeps_the_familys_false_alarms_at_5_pct():
    """30 components with no difference (two seeds of one filter): one or more is called
    different in at most 5 % of 200 Monte Carlos (give or take 3.5 binomial sigmas), where
    testing each at 5 % calls one in about 79 %."""
    rng = np.random.default_rng(8)
    alarms = raw = 0
    for _ in range(200):
        sides = []
        for _ in range(2):
            e = rng.normal(0, 1, (40, 1, 30)) + rng.normal(0, 1, (40, 20, 30))
            sides.append(EstimatorSamples(np.arange(40), {"nees.per_state": MetricSamples(
                np.sum(e ** 2, 1), np.full((40, 30), 20.0), False)}))
        d = differences(*sides, False, margin=0)          # the intervals' verdicts alone
        alarms += any(x.verdict != SAME for x in d)
        raw += any(x.p_value < 0.05 for x in d)
    assert alarms / 200 <= 0.05 + 3.5 * math.sqrt(0.05 * 0.95 / 200), alarms / 200
    assert raw / 200 > 0.6


def test_a_better_filter_is_called_better_and_identical_sides_are_no_difference():
    ea, eb = _runs(np.random.default_rng(2), 30)
    d = differences(_side(ea), _side(ea, 0.9), True)
    assert all(x.verdict == BETTER for x in d), [x.verdict for x in d]
    same = differences(_side(ea), _side(ea), True, margin=0)
    assert all(x.verdict == SAME and x.diff == 0 and x.ci95 == [0.0, 0.0] for x in same)
    assert all(x.verdict == "negligible" for x in differences(_side(ea), _side(ea), True))


def test_the_samples_file_round_trips(tmp_path):
    ea, _ = _runs(np.random.default_rng(3), 5)
    per_run = {"p99.pos_m": np.array([[1.0, 2.0, np.inf], [4.0, np.nan, 6.0]]), "convergence_s": np.array([[3.0], [4.0]])}
    s = {"ES-KF, 16": _side(ea), "free SINS": EstimatorSamples(np.array([0, 2]), {}, per_run)}
    save_samples(tmp_path / "samples.npz", s)
    back = load_samples(tmp_path / "samples.npz")
    assert list(back) == list(s)
    m, n = back["ES-KF, 16"].metrics["rms.pos_m"], s["ES-KF, 16"].metrics["rms.pos_m"]
    assert np.array_equal(m.s, n.s) and np.array_equal(m.n, n.n) and m.root
    assert np.array_equal(back["free SINS"].runs, [0, 2]) and back["ES-KF, 16"].per_run == {}
    assert all(np.array_equal(back["free SINS"].run_values(p), v, equal_nan=True) for p, v in per_run.items())
    assert np.array_equal(back["ES-KF, 16"].run_values("rms.pos_m"), n.per_run())   # a ratio metric's own
    # a per-run array of another number of runs than the estimator's is damage, named
    bad = {"free SINS": EstimatorSamples(np.array([0, 2]), {}, {"p99.pos_m": np.zeros((3, 3))})}
    save_samples(tmp_path / "bad.npz", bad)
    with pytest.raises(UsageError, match=r"bad.npz: damaged: its array e0.v.p99.pos_m"):
        load_samples(tmp_path / "bad.npz")


def _fixed(p_values):
    """Differences with the given p-values, each with an interval that excludes 0."""
    return [Difference("rms.pos_m", str(k), 1.0, 1.1, 0.1, [0.01, 0.19], "worse", None, p, 20, 0.04, 0.18)
            for k, p in enumerate(p_values)]


def test_holms_step_down_on_fixed_p_values():
    """m = 4 at 5 %, sorted 0.001, 0.01, 0.03, 0.06: 0.001 <= 0.05/4 and 0.01 <= 0.05/3 pass,
    0.03 > 0.05/2 stops the steps (0.06 after it too); the order given does not matter."""
    out = holm(_fixed([0.03, 0.01, 0.001, 0.06]))
    assert [d.verdict for d in out] == [SAME, "worse", "worse", SAME]
    out = holm(_fixed([0.03, 0.02, 0.04, 0.013]))            # 0.013 > 0.0125: none passes
    assert all(d.verdict == SAME for d in out)
    # a demoted component's runs to resolve it are more than it has, at the family's level
    assert all(d.runs_needed > 20 for d in out)


def test_runs_to_resolve_uses_students_quantile_at_few_runs():
    """A difference 1.5 spreads from 0 at one run (z 1.5): over a family of 10, t(N-1) at
    0.0025 per side needs N with sqrt(N) / t(N - 1) = 1 / 1.5: about 10, where the normal
    quantile alone says 4."""
    d = Difference("rms.pos_m", "N", 1.0, 2.5, 1.5, [0.0, 3.0], SAME, None, 0.06, 3, 0.87, 1.0)
    n = runs_to_resolve(d, 0.05 / 10)
    t = student_t.ppf(1 - 0.0025, n - 1)
    assert 8 <= n <= 14 and t * 1.0 / math.sqrt(n) <= 1.5 * 1.05


def test_a_run_diverged_on_one_side_is_left_out_of_both_and_listed():
    ea, eb = _runs(np.random.default_rng(6), 12)
    a, b = _side(ea), _side(eb, 1.05)
    b = EstimatorSamples(np.delete(b.runs, [3, 7]), {k: MetricSamples(np.delete(m.s, [3, 7], 0),
                                                                        np.delete(m.n, [3, 7], 0), m.root)
                                                     for k, m in b.metrics.items()})
    side = Side("a", "x", 12, 12, 12, False, 1)
    c = compare_samples(side, a, side, b, True, "paired")
    assert c.runs_compared == 10 and c.only_a == [3, 7] and c.only_b == []
    keep = np.delete(np.arange(12), [3, 7])
    assert c.differences[0].a == math.sqrt(np.sum(a.metrics["rms.pos_m"].s[keep, 0]) / (10 * EPOCHS))


def test_two_filters_a_hair_apart_are_negligible_and_offered_no_run_count():
    """Issue 50: two filters 66 nm apart were offered '~28 runs would resolve +6.59e-08 m'."""
    ea, _ = _runs(np.random.default_rng(5), 20)
    a, b = _side(ea), _side(ea + 1e-8 * np.random.default_rng(6).normal(0, 1, ea.shape))
    for d in differences(a, b, True):
        assert d.verdict == NEGLIGIBLE and d.runs_needed is None, d
        assert "would resolve" not in verdict_text(d, 20) and "within" in verdict_text(d, 20)
    strict = differences(a, b, True, margin=0.0)            # no margin: the old verdicts, run counts offered
    assert all(d.verdict != NEGLIGIBLE for d in strict) and any(d.runs_needed for d in strict)


def test_a_difference_within_the_margin_but_unresolved_is_offered_no_run_count():
    """A 0.5 % difference at 3 runs, unpaired: its interval spans far beyond the 1 % margin (not
    negligible, not significant), and resolving it would not matter: no run count; with the
    margin at 0.1 % for rms.pos_m it is offered one."""
    rng = np.random.default_rng(8)
    ea, _ = _runs(rng, 3)
    _, eb = _runs(rng, 3)
    d = {x.name: x for x in differences(_side(ea), _side(ea * 1.005), False)}["rms.pos_m N"]
    assert d.verdict == SAME and d.runs_needed is None and abs(d.diff) <= d.margin < d.ci95[1]
    assert "within the margin" in verdict_text(d, 3)
    d = {x.name: x for x in differences(_side(ea), _side(ea * 1.005), False, margin={"rms.pos_m": 0.1, "": 5})}
    assert d["rms.pos_m N"].runs_needed and math.isclose(d["rms.pos_m N"].margin, 0.001 * d["rms.pos_m N"].b)


def test_a_difference_just_beyond_the_margin_is_called_negligible_at_most_2_5_percent_of_the_time():
    """The verdict is an equivalence test (the 95 % interval inside +-margin): where B - A is
    just over the margin, 'negligible' comes at most as often as the interval misses on one side,
    2.5 % (3 binomial sigmas over 400 Monte Carlos: 0.025 + 3 * 0.0078)."""
    rng = np.random.default_rng(31)
    called = 0
    for _ in range(400):
        ea, eb = _runs(rng, 50)
        d = differences(_side(ea), _side(eb, 1.0102), True)[0]
        called += d.verdict == NEGLIGIBLE
    assert called / 400 <= 0.025 + 3 * math.sqrt(0.025 * 0.975 / 400), called


def test_the_margin_is_checked():
    for bad in (-1, 101, "2", True, math.nan, {"rms.pos_m": -3}, {3: 1.0}):
        with pytest.raises(UsageError, match="margin"):
            check_margin(bad)
    assert check_margin(2) == 2.0 and check_margin({"": 0, "rms.pos_m": 5}) == {"": 0.0, "rms.pos_m": 5.0}
