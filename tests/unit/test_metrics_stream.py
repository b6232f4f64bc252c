"""Chunk-by-chunk scoring (navsim.metrics_stream) against navsim.metrics.score of the merged runs."""

import numpy as np
import pytest

from navsim.metrics import score
from navsim.metrics_stream import AbsPercentiles, score_parts
from navsim.montecarlo import EstimatorHistory
from navsim.runner import _merge


@pytest.mark.filterwarnings("ignore:invalid value encountered")   # q=100 with an inf: inf - inf, as numpy
@pytest.mark.parametrize("q", [0, 50, 95, 99, 100])
def test_streamed_percentiles_are_exact(q):
    rng = np.random.default_rng(3)
    pieces = [rng.standard_t(3, size=(n, 7)) * 10.0 ** rng.integers(-3, 4) for n in (1, 40, 0, 333)]
    pieces[1][:5] = 0.0                             # zeros (the underflow bin) and ties
    pieces[1][5:9] = 2.5
    pieces[3][::7, 2] = np.nan                      # NaN skipped as nanpercentile does
    pieces[3][3, 3] = np.inf
    p = AbsPercentiles()
    for x in pieces:
        p.add("k", x, q)
    p.second_pass()
    for x in pieces:
        p.add("k", x, q)
    want = np.nanpercentile(np.abs(np.concatenate([x.ravel() for x in pieces])), q)
    np.testing.assert_equal(p.value("k"), want)        # (q=100 with an inf: NaN, as numpy)
    # only the values of the bins holding the two ranks are kept, not the 2 600 values
    assert sum(v.size for v in p.kept["k"]) < 200


def history(rng, runs, E=120, nees=True, euler=True):
    t = np.arange(E) * 1.0
    err = lambda s: rng.normal(scale=s, size=(runs, E, 3)) + rng.normal(scale=s, size=(runs, 1, 3))
    pos, vel, att = err(3.0), err(0.2), err(1e-3)
    # a closed-loop-like run whose records end early, and a diverged run
    pos[0, 90:] = vel[0, 90:] = att[0, 90:] = np.nan
    diverged = np.zeros(runs, bool)
    diverged[-1] = runs > 2
    nis = {"gnss:bd": np.where(np.arange(E) % 5 == 0, rng.chisquare(3, size=(runs, E)), np.nan),
           "height:ads": rng.chisquare(1, size=(runs, E))}
    nis["gnss:bd"][:, 100:] = np.nan                  # an outage: epochs with no NIS at all
    return EstimatorHistory(
        label="KF", t_s=t, att_err_rad=att, vel_err_mps=vel, pos_err_m=pos,
        sigma=np.abs(rng.normal(size=(runs, E, 15))) if nees else None,
        nees=rng.chisquare(9, size=(runs, E)) if nees else None,
        nis=nis if nees else {}, nis_dim={"gnss:bd": 3, "height:ads": 1} if nees else {},
        diverged=diverged, gyro_bias=None, accel_bias=None,
        cost={"propagate_s": 0.5, "epoch_s": 0.25, "runs": runs, "epochs": E, "batches": 1},
        euler_err_rad=att[..., ::-1].copy() if euler else None,
        resets=[[(12.0, "cpf")] if r % 3 == 0 else [] for r in range(runs)] if euler else None)


@pytest.mark.parametrize("nees, euler", [(True, True), (False, False)])
def test_chunk_by_chunk_score_equals_the_score_of_the_merged_runs(nees, euler, close_metrics):
    close = close_metrics
    rng = np.random.default_rng(11)
    sizes = [7, 1, 12, 5]
    starts = np.cumsum([0] + sizes[:-1])
    parts = [([int(a) + i for i in range(n)], {"KF": history(rng, n, nees=nees, euler=euler)}, {}, {})
             for a, n in zip(starts, sizes)]
    windows = [("turn", 20.0, 60.0), ("late", 80.0, 119.0), ("never", 500.0, 600.0)]
    merged = _merge(parts)[1]["KF"]
    want = score(merged, 30.0, windows)
    got = score_parts(lambda: iter(parts), 30.0, windows)["KF"]
    close(want, got)
    assert got["diverged_runs"] == 3 and got["runs_counted"] == sum(sizes) - 3
    if nees:
        assert set(got["nis"]) == {"gnss:bd", "height:ads"}
    # the chunking does not matter: one chunk gives the same numbers
    close(want, score_parts(lambda: iter([_merge(parts)[:2] + ({}, {})]), 30.0, windows)["KF"])


def test_landmark_and_calibration_scores_from_chunks_equal_the_merged_ones(close_metrics):
    close = close_metrics
    from navsim.metrics import calibration_score, sighting_metrics
    from navsim.metrics_stream import score_run
    rng = np.random.default_rng(5)
    T = 50
    turns = np.linspace(0, 3, T)

    def cal(n):
        return {"t_s": np.arange(T) * 2.0, "turns": turns, "hard_iron_err": rng.random((n, T)),
                "soft_iron_err": rng.random((n, T))}
    parts = [(list(range(a, a + n)), {"KF": history(rng, n)}, {}, {"mag": cal(n)}) for a, n in ((0, 4), (4, 6))]
    # sightings: one at the start, one across the records' end, two in between
    spans = [("cam landmark 1", 0.0, 3.0, 2.0), ("cam landmark 2", 40.5, 44.2, 1.5),
             ("cam landmark 3", 70.0, 70.0, 3.0), ("cam landmark 4", 110.0, 400.0, 2.0)]
    metrics, calib = score_run(lambda: iter(parts), 30.0, (), spans)
    runs, hist, _, cals = _merge(parts)
    close(sighting_metrics(hist["KF"], spans), metrics["KF"]["landmarks"])
    whole = calibration_score(cals["mag"])
    close(whole, calib["mag"])
    assert "after_2_turns" in whole and whole["runs"] == 10
