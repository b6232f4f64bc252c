"""A scenario's ``reference``: published numbers and claims read with their rules, and judged
against metrics (:mod:`navsim.experiment.reference`, :mod:`navsim.records.reference`,
:mod:`navsim.scoring.verdicts`)."""

import numpy as np
import pytest

from navsim.experiment.reference import parse_reference, stored_kind
from navsim.foundations.config import Node
from navsim.foundations.errors import ScenarioError
from navsim.records.vocabulary import check_metric_path
from navsim.records.metrics import EstimatorMetrics, RunMetrics
from navsim.records.samples import EstimatorSamples
from navsim.scoring.verdicts import judge, verdict_rows, verdict_summary

LABELS = ["SINS", "KF"]


def stats(pos, vel=(0.1, 0.1, 0.1), att=(0.01, 0.01, 0.1)):
    return {"pos_m": list(pos), "vel_mps": list(vel), "att_deg": list(att)}


ESTIMATORS = {
    "SINS": EstimatorMetrics.from_dict({"runs_counted": 4, "diverged_runs": 0, "settle_s": 60,
                                        "final": stats([90.0, 95.0, 70.0]), "convergence_s": None}),
    "KF": EstimatorMetrics.from_dict({"runs_counted": 4, "diverged_runs": 0, "settle_s": 60, "convergence_s": 4.0,
                                      "rms": stats([1.6, 1.7, 1.0]), "final": stats([2.0, 2.0, 1.0])}),
}


def reference(data, kind="population"):
    """``data`` read as a reference section, of ``kind`` where it does not say (None: as it is)."""
    data = data if kind is None or "kind" in data else {"kind": kind, **data}
    return parse_reference(Node(data, "reference", "s.yaml"), LABELS,
                           lambda path, key: check_metric_path(path, [("w", 0, 1)], file="s.yaml", key=key))


def test_values_take_the_reference_rule_or_their_own_and_claims_their_threshold():
    ref = reference({
        "source": "paper", "check": "at_most",
        "values": {"KF": {"rms.pos_m": [2, 2, 2], "convergence_s": {"paper": 5.0, "check": "close", "tolerance": 0.1}}},
        "claims": [{"claim": "SINS diverges", "estimator": "SINS", "metric": "final.pos_m",
                    "at_least": {"times": 10, "of": "KF"}},
                   {"claim": "KF does not diverge", "estimator": "KF", "metric": "diverged_runs", "at_most": 0}]})
    rules = [(c.estimator, c.metric, c.rule, c.bound, c.of) for c in ref.checks]
    assert rules == [("KF", "rms.pos_m", "at_most", [2, 2, 2], None), ("KF", "convergence_s", "close", 5.0, None),
                     ("SINS", "final.pos_m", "at_least", 10.0, "KF"), ("KF", "diverged_runs", "at_most", 0, None)]
    v = judge(ref, ESTIMATORS)
    # 1.6/1.7/1.0 <= 2; |4 - 5| = 1 > 0.1 * 5; 90/95/70 >= 10 x 2/2/1 = 20/20/10; 0 <= 0
    assert [x.passed for x in v] == [True, False, True, True]
    assert v[2].bound == [20.0, 20.0, 10.0] and v[2].times == 10.0 and v[2].of == "KF"
    assert verdict_summary(v) == "3 of 4 paper checks pass, 1 fail"
    rows = verdict_rows(v)
    assert rows[1][1:] == ["as published", "convergence_s", "population", "5 ±10%", "4", "FAIL"]
    assert rows[2][1:5] == ["SINS diverges", "final.pos_m", "population", ">= 10 x KF (20 20 10)"]


@pytest.mark.parametrize("rule, bound, passed", [
    ("at_most", [1.6, 1.7, 1.0], True),        # equal passes
    ("at_most", [1.6, 1.69, 1.0], False),      # one component over fails the vector
    ("at_least", [1.6, 1.7, 1.0], True),
    ("at_least", [1.61, 1.0, 0.5], False),
    ("close", [2.0, 2.0, 1.25], True),         # within 25 % of each
    ("close", [2.0, 2.0, 0.7], False),
    ("none", [1.6, 1.7, 1.0], None),
])
def test_each_rule_on_a_vector(rule, bound, passed):
    ref = reference({"source": "p", "check": rule, "values": {"KF": {"rms.pos_m": bound}}})
    assert judge(ref, ESTIMATORS)[0].passed is passed


def test_no_verdict_without_a_number_of_ours():
    ref = reference({"source": "p", "check": "at_most",
                     "values": {"SINS": {"rms.pos_m": 1.0, "convergence_s": 10.0}, "KF": {"rms.pos_m": 1.0}},
                     "claims": [{"claim": "c", "estimator": "KF", "metric": "rms.pos_m",
                                 "at_most": {"times": 0.5, "of": "SINS"}}]})
    v = judge(ref, ESTIMATORS)
    # SINS has no rms; it never converged (no convergence time: it fails "within 10 s"); a
    # scalar bound against a vector of ours; the SINS it is relative to has no rms
    assert [x.passed for x in v] == [None, False, None, None]
    assert verdict_summary(v) == "0 of 4 paper checks pass, 1 fail, 3 without a value"
    assert [r[-1] for r in verdict_rows(v)] == ["no value", "FAIL", "no value", "no value"]
    assert verdict_rows(v)[1][5] == "never"
    assert judge(None, ESTIMATORS) is None


def test_a_group_of_metrics_gets_no_value_and_the_tolerance_is_inherited():
    ref = reference({"source": "p", "check": "close", "tolerance": 0.5,
                     "values": {"KF": {"rms.pos_m": {"paper": [2, 2, 2]}, "windows.w.height_m": 1.0}}})
    assert [c.tolerance for c in ref.checks] == [0.5, 0.5]
    kf = EstimatorMetrics.from_dict({**ESTIMATORS["KF"].to_dict(), "windows": {"w": {"height_m": {
        "max_pos": 1.0, "max_neg": -1.0, "std": 0.5, "rms": 0.6, "p95_abs": 0.9}}}})
    v = judge(ref, {"KF": kf})
    # 1.6/1.7/1.0 within 50 % of 2; "windows.w.height_m" is a group of five numbers, not one
    assert [x.passed for x in v] == [True, None] and verdict_rows(v)[1][-1] == "no value"


def test_verdicts_round_trip_through_metrics_json():
    ref = reference({"source": "p", "claims": [{"claim": "c", "estimator": "SINS", "metric": "final.pos_m",
                                                "at_least": {"times": 10, "of": "KF"}},
                                               {"claim": "d", "estimator": "SINS", "metric": "rms.pos_m",
                                                "at_most": {"times": 2, "of": "KF"}}]})   # no verdict
    m = RunMetrics("s", 4, 4, 1, {}, False, dict(ESTIMATORS), paper_checks=judge(ref, ESTIMATORS))
    back = RunMetrics.from_dict(m.to_dict())
    assert back.paper_checks == m.paper_checks and back.to_dict() == m.to_dict()


@pytest.mark.parametrize("data, key, words", [
    ({"source": "p", "check": "below", "values": {"KF": {"rms.pos_m": 1}}}, "reference.check", "at_most"),
    ({"source": "p", "values": {"KF": {"rms.pos_m": {"paper": 1, "check": "near"}}}},
     "reference.values.KF.rms.pos_m.check", "close"),
    ({"source": "p", "values": {"KF": {"rms.pos_m": {"check": "close"}}}}, "reference.values.KF.rms.pos_m.paper",
     "a finite number"),
    ({"source": "p", "claims": [{"claim": "c", "estimator": "KF", "metric": "rms.pos_m", "at_most": 1,
                                 "at_least": 0}]}, "reference.claims[0].at_most", "exactly one"),
    ({"source": "p", "claims": [{"claim": "c", "estimator": "KF", "metric": "rms.pos_m",
                                 "at_most": {"times": 2, "of": "SIN"}}]}, "reference.claims[0].at_most.of",
     "did you mean 'SINS'"),
    ({"source": "p", "claims": [{"claim": "c", "estimator": "KF", "metric": "rmse.pos_m", "at_most": 1}]},
     "reference.claims[0].metric", "not a metric"),
    ({"source": "p", "claims": [{"claim": "c", "estimator": "KF", "metric": "rms.pos_m", "at_most": 1,
                                 "because": "x"}]}, "reference.claims[0].because", "not a known key"),
    ({"source": "p"}, "reference.values", "no values and no claims"),
    ({"source": "p", "kind": "one flight", "values": {"KF": {"rms.pos_m": 1}}}, "reference.kind", "single_run"),
    ({"source": "p", "kind": "single_run", "claims": [{"claim": "c", "estimator": "KF", "metric": "diverged_runs",
                                                       "at_most": 0}]}, "reference.claims[0]", "kind: population"),
    ({"source": "p", "kind": "single_run", "values": {"KF": {"nees.fraction_inside": 1}}},
     "reference.values.KF.nees.fraction_inside",
     "no value per run"),
    ({"source": "p", "kind": "single_run", "values": {"KF": {"rms.pos_m": {"paper": 1, "check": "close",
                                                                            "tolerance": 0.5}}}},
     "reference.values.KF.rms.pos_m.tolerance", "spread of our runs"),
    ({"source": "p", "kind": "single_run", "check": "close", "tolerance": 0.5, "values": {"KF": {"rms.pos_m": 1}}},
     "reference.tolerance", "spread of our runs"),
])
def test_bad_references_name_their_key(data, key, words):
    with pytest.raises(ScenarioError) as exc:
        reference(data)
    text = str(exc.value)
    assert key in text and words in text, text


def test_the_metric_vocabulary_is_the_metrics_dataclasses():
    """Every section and field of EstimatorMetrics is a path a reference may name (a new field
    needs no second list), and a misspelt field is refused with the field it meant."""
    import dataclasses

    from navsim.records.vocabulary import METRIC_HEADS, SCALAR_METRICS, SECTION_FIELDS
    names = {f.name for f in dataclasses.fields(EstimatorMetrics)}
    assert set(METRIC_HEADS) | set(SCALAR_METRICS) == names - {"ci95"}       # the intervals: not a metric
    for head, parts in SECTION_FIELDS.items():
        for part in parts:
            check_metric_path(f"{head}.{part}", [], file="s.yaml", key="k")
    check_metric_path("windows.w.height_m.rms", [("w", 0, 1)], file="s.yaml", key="k")
    check_metric_path("nis.gnss_position:bd.fraction_inside", [], file="s.yaml", key="k")
    with pytest.raises(ScenarioError, match="fraction_inside"):
        check_metric_path("nees.fraction_insde", [], file="s.yaml", key="k")
    with pytest.raises(ScenarioError, match="p95_deg"):
        check_metric_path("attitude.p95deg", [], file="s.yaml", key="k")


def _with_interval(rms, ci, runs=20):
    return {"KF": EstimatorMetrics.from_dict({"runs_counted": runs, "diverged_runs": 0, "settle_s": 60,
                                              "convergence_s": 4.0, "rms": stats(rms),
                                              "ci95": {"rms": {"pos_m": ci}}})}


@pytest.mark.parametrize("rule, bound, passed, needed", [
    ("at_most", 1.3, True, None),      # the whole interval of every axis below
    ("at_most", 0.85, False, None),    # all of N's interval above: fails whatever the rest
    ("at_most", 1.05, None, 80),       # N straddles 1.05: half-width 0.2 must become 0.1 -> 4 x 20 runs
    ("at_least", 0.5, True, None),
    ("close", 0.78, None, 1280),       # 25 % of 0.78: 0.585-0.975 cuts every axis; N's 0.95 is 0.025
                                       # from 0.975 with a half-width 0.2: 64 x 20 runs
])
def test_a_check_with_an_interval_passes_fails_or_is_undecided_with_the_runs_that_decide_it(rule, bound, passed, needed):
    est = _with_interval([0.95, 0.6, 1.0], [[0.75, 1.15], [0.5, 0.7], [0.9, 1.1]])
    ref = reference({"source": "paper", "check": rule, "values": {"KF": {"rms.pos_m": [bound] * 3}}})
    v = judge(ref, est)[0]
    assert v.passed is passed and v.ours_ci95 == [[0.75, 1.15], [0.5, 0.7], [0.9, 1.1]] and v.runs == 20
    assert v.undecided is (True if passed is None else None)
    if passed is None:
        assert v.runs_needed == needed
        row = verdict_rows([v])[0]
        assert row[-1] == f"undecided at 20 runs (~{v.runs_needed} decide)"
        assert row[5].startswith("0.95 [0.75, 1.15]")
        assert verdict_summary([v]) == "0 of 1 paper checks pass, 1 undecided at 20 runs"


def test_a_check_without_an_interval_is_judged_on_its_value():
    est = _with_interval([0.95, 0.6, 1.0], [[None, None]] * 3, runs=1)
    ref = reference({"source": "paper", "check": "at_most", "values": {"KF": {"rms.pos_m": [1.0] * 3}}})
    v = judge(ref, est)[0]
    assert v.passed is True and v.ours_ci95 is None and v.undecided is None


def test_a_value_on_its_bound_is_undecided_at_the_bound():
    """N's 0.95 with [0.75, 1.15] against a bound of 0.9500001: 0.2 / 1e-7 squared x 20 runs
    would decide it, far beyond any Monte Carlo: the verdict says so instead of the count."""
    est = _with_interval([0.95, 0.6, 1.0], [[0.75, 1.15], [0.5, 0.7], [0.9, 1.1]])
    ref = reference({"source": "paper", "check": "at_most", "values": {"KF": {"rms.pos_m": [0.9500001, 1.3, 1.3]}}})
    v = judge(ref, est)[0]
    assert v.undecided and v.runs_needed > 10 ** 6
    assert verdict_rows([v])[0][-1] == "undecided at 20 runs (at the bound: >100000 runs to decide)"


def test_a_reference_without_its_kind_is_refused_with_the_two_kinds_named():
    with pytest.raises(ScenarioError) as exc:
        reference({"source": "p", "values": {"KF": {"rms.pos_m": 1}}}, kind=None)
    text = str(exc.value)
    assert "reference.kind" in text and "population" in text and "single_run" in text


def _samples(per_run: dict, runs):
    """Estimator label -> EstimatorSamples holding the metric values ``per_run`` ``(B, k)``."""
    return {label: EstimatorSamples(np.asarray(runs), {}, {p: np.asarray(v, float).reshape(len(runs), -1)
                                                          for p, v in values.items()})
            for label, values in per_run.items()}


def test_a_single_flight_is_judged_on_the_range_of_one_run_not_on_the_interval_of_the_mean():
    """100 runs whose per-run p99 is 1..100 (KF) and 2..200 (SINS), and whose RMS's mean
    interval is tight: a paper value of 90 (inside [2, 99], the 95 % range of one run) passes as
    a single run and would fail as a population number; 100.5 fails; a bound of 1.5 passes as
    the range reaches it (the 2nd run of 100 is 2: "at_most 1.5" fails) with the share of runs
    meeting it; a claim relative to another estimator is judged on each run's ratio."""
    runs = np.arange(100)
    samples = _samples({"KF": {"p99.pos_m": np.c_[runs + 1.0, runs + 1.0, runs + 1.0]},
                        "SINS": {"p99.pos_m": np.c_[2 * runs + 2.0, 2 * runs + 2.0, 2 * runs + 2.0]}}, runs)
    est = {"KF": EstimatorMetrics.from_dict({"runs_counted": 100, "diverged_runs": 0, "settle_s": 0,
                                             "p99": stats([99.0] * 3)}),
           "SINS": EstimatorMetrics.from_dict({"runs_counted": 100, "diverged_runs": 0, "settle_s": 0,
                                               "p99": stats([198.0] * 3)})}
    ref = reference({"source": "p", "values": {"KF": {
        "p99.pos_m": {"paper": [90, 50, 3], "check": "close"}}}, "claims": [
        {"claim": "in", "estimator": "KF", "metric": "p99.pos_m", "at_most": [3, 3, 3]},
        {"claim": "out", "estimator": "KF", "metric": "p99.pos_m", "at_most": [1.5, 50, 50]},
        {"claim": "half", "estimator": "KF", "metric": "p99.pos_m", "at_most": {"times": 0.5, "of": "SINS"}},
        {"claim": "above", "estimator": "KF", "metric": "p99.pos_m", "at_least": [100.5, 1, 1]}]}, kind="single_run")
    close, inside, outside, ratio, above = judge(ref, est, samples)
    assert close.passed is True and close.kind == "single_run" and close.runs == 100
    assert close.run_range == [[2.0, 99.0]] * 3 and close.percentile == [89.5, 49.5, 2.5]
    assert close.coverage_ci95[0] < 0.97 < close.coverage_ci95[1]          # Beta(97, 4)
    assert inside.passed is True and inside.share == 0.03 and inside.share_ci95[0] < 0.03 < inside.share_ci95[1]
    assert outside.passed is False and outside.share == 0.01
    assert ratio.passed is True and ratio.run_range == [[0.5, 0.5]] * 3 and ratio.share == 1.0
    assert above.passed is False                     # the range's top, 99, is below 100.5
    rows = verdict_rows([close, inside, outside])
    assert rows[0][3] == "single run" and rows[0][5] == "  ".join(["[2, 99]"] * 3)
    assert rows[0][6] == "pass (p90 p50 p2)" or rows[0][6] == "pass (p90 p50 p3)", rows[0][6]
    assert rows[1][6] == "pass (3 % [0.6, 9] of runs meet it)" and rows[2][6].startswith("FAIL (1 %")
    back = RunMetrics.from_dict({"scenario": "s", "runs": 100, "runs_done": 100, "seed": 1, "failed_runs": {},
                                 "interrupted": False, "estimators": {}, "paper_checks": [close.to_dict()]})
    assert back.paper_checks == [close]


def test_a_single_run_check_below_39_runs_is_undecided_and_says_why():
    runs = np.arange(20)
    samples = _samples({"KF": {"rms.pos_m": np.ones((20, 3))}}, runs)
    ref = reference({"source": "p", "check": "close", "values": {"KF": {"rms.pos_m": 1000}}}, kind="single_run")
    est = {"KF": EstimatorMetrics.from_dict({"runs_counted": 20, "diverged_runs": 0, "settle_s": 0,
                                             "rms": stats([1.0] * 3)})}
    ref = reference({"source": "p", "check": "close", "values": {"KF": {"rms.pos_m": [1000, 1, 1]}}},
                    kind="single_run")
    (v,) = judge(ref, est, samples)
    assert v.passed is None and v.undecided and v.runs_needed == 39
    assert verdict_rows([v])[0][6] == "undecided at 20 runs (39 bound one run's 95 % range)"
    assert "1 undecided at 20 runs" in verdict_summary([v])


def test_a_stored_scenario_from_before_the_kinds_reads_its_reference_as_population():
    """A result folder written before references said their kind (its scenario.resolved.yaml)
    still opens: its checks were judged on the interval of the mean, population."""
    raw = {"track": "p0", "reference": {"source": "p", "values": {"KF": {"rms.pos_m": 1}}}}
    assert stored_kind(raw)["reference"]["kind"] == "population" and "kind" not in raw["reference"]
    given = {"track": "p0", "reference": {"source": "p", "kind": "single_run"}}
    assert stored_kind(given) is given and stored_kind({"track": "p0"}) == {"track": "p0"}
