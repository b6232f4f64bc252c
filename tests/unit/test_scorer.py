"""The one scorer (navsim.scoring.scorer): chunk by chunk equal to numpy's statistics of the
merged runs, and independent of the chunking."""

import dataclasses

import numpy as np
import pytest
from scipy.stats import chi2

from navsim.records.chunk import ChunkPart, merge_parts
from navsim.records.history import EstimatorHistory
from navsim.records.truth import CalibrationHistory
from navsim.scoring.calibration import calibration_score
from navsim.scoring.landmarks import sighting_metrics
from navsim.scoring.scorer import score, score_parts, score_run
from navsim.records.samples import has_run_values
from navsim.scoring.stats import AbsPercentiles, convergence_time


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
    wind = err(0.4)
    wind[..., 2] = np.nan                             # no vertical wind state
    wind[0, 90:] = np.nan
    return EstimatorHistory(
        label="KF", t_s=t, att_err_rad=att, vel_err_mps=vel, pos_err_m=pos,
        sigma=np.abs(rng.normal(size=(runs, E, 9))) if nees else None,
        nees=rng.chisquare(9, size=(runs, E)) if nees else None,
        nis=nis if nees else {}, nis_dim={"gnss:bd": 3, "height:ads": 1} if nees else {},
        diverged=diverged, gyro_bias=None, accel_bias=None,
        cost={"propagate_s": 0.5, "epoch_s": 0.25, "runs": runs, "epochs": E, "batches": 1},
        euler_err_rad=att[..., ::-1].copy() if euler else None,
        resets=[[(12.0, "cpf")] if r % 3 == 0 else [] for r in range(runs)] if euler else None,
        wind_err_mps=wind if nees else None)


def _rms(x, axis):
    return np.sqrt(np.nanmean(x ** 2, axis=axis))


def numpy_scores(h, settle_s, windows) -> dict:
    """The scores written out with numpy over the merged runs (the reference)."""
    good = ~h.diverged
    after = h.t_s >= settle_s
    err = {"pos_m": h.pos_err_m[good][:, after], "vel_mps": h.vel_err_mps[good][:, after],
           "att_deg": np.degrees(h.att_err_rad[good][:, after])}
    out = {"rms": {k: _rms(v, (0, 1)).tolist() for k, v in err.items()},
           "max_abs": {k: np.nanmax(np.abs(v), axis=(0, 1)).tolist() for k, v in err.items()},
           "p99": {k: np.nanpercentile(np.abs(v), 99, axis=(0, 1)).tolist() for k, v in err.items()}}
    finite = np.isfinite(h.pos_err_m[good][..., 0])
    last = finite.shape[1] - 1 - np.argmax(finite[:, ::-1], axis=1)      # each run's last record
    rows = np.arange(len(last))
    out["final"] = {"pos_m": _rms(h.pos_err_m[good][rows, last], 0).tolist(),
                    "vel_mps": _rms(h.vel_err_mps[good][rows, last], 0).tolist(),
                    "att_deg": _rms(np.degrees(h.att_err_rad[good][rows, last]), 0).tolist()}
    q = {"north_m": h.pos_err_m[good][..., 0], "east_m": h.pos_err_m[good][..., 1],
         "height_m": -h.pos_err_m[good][..., 2], "speed_mps": np.linalg.norm(h.vel_err_mps[good][..., :2], axis=-1),
         "heading_deg": -np.degrees(h.att_err_rad[good][..., 2])}
    if h.euler_err_rad is not None:
        e = np.degrees(h.euler_err_rad[good])
        q.update(roll_deg=e[..., 0], pitch_deg=e[..., 1], yaw_deg=e[..., 2])
        e = e[:, after]
        out["attitude"] = {"p95_deg": np.nanpercentile(np.abs(e), 95, axis=(0, 1)).tolist(),
                           "rms_deg": _rms(e, (0, 1)).tolist(), "max_abs_deg": np.nanmax(np.abs(e), axis=(0, 1)).tolist(),
                           "p95_about_run_mean_deg": np.nanpercentile(
                               np.abs(e - np.nanmean(e, axis=1, keepdims=True)), 95, axis=(0, 1)).tolist()}
    out["windows"] = {}
    for name, a, b in windows:
        m = (h.t_s >= a) & (h.t_s <= b)
        out["windows"][name] = w = {k: {"max_pos": np.nanmax(v[:, m]), "max_neg": np.nanmin(v[:, m]),
                                        "std": np.nanstd(v[:, m]), "rms": _rms(v[:, m], (0, 1)),
                                        "p95_abs": np.nanpercentile(np.abs(v[:, m]), 95)}
                                    for k, v in q.items()} if m.any() else {}
        if m.any():
            hor = np.hypot(*np.moveaxis(h.pos_err_m[good][:, m, :2], -1, 0))
            w["horizontal_m"] = {"rms": _rms(hor, (0, 1)), "final": _rms(hor[:, -1], 0),
                                 "max": _rms(np.nanmax(hor, axis=1), 0)}
        if m.any() and h.nees is not None:
            lo, hi = chi2.ppf([0.025, 0.975], 9 * good.sum()) / good.sum()
            mean = np.nanmean(h.nees[good][:, m], axis=0)
            w["nees"] = {"average": np.nanmean(mean), "fraction_inside": np.mean((mean > lo) & (mean < hi))}
    if h.wind_err_mps is not None:
        w = h.wind_err_mps[good][:, after]
        hor2 = np.sum(w[..., :2] ** 2, axis=-1)
        fin = np.isfinite(hor2)
        end = hor2[np.arange(len(hor2)), fin.shape[1] - 1 - np.argmax(fin[:, ::-1], axis=1)]
        out["wind"] = {"rms_mps": np.sqrt(np.nanmean(hor2)), "final_mps": np.sqrt(np.mean(end)),
                       "rms_axes_mps": _rms(w[..., :2], (0, 1)).tolist() + [None]}
    if h.nees is not None:
        sel = after & (h.t_s > 0)
        mean = np.nanmean(h.nees[good], axis=0)
        n = np.sum(np.isfinite(h.nees[good][:, sel]), axis=0)        # runs recorded at each epoch
        lo, hi = chi2.ppf(0.025, 9 * n) / n, chi2.ppf(0.975, 9 * n) / n
        e = np.concatenate([h.att_err_rad, h.vel_err_mps, h.pos_err_m], -1)[good][:, after]
        out["nees"] = {"average": np.nanmean(mean[sel]), "fraction_inside": np.mean((mean[sel] > lo) & (mean[sel] < hi)),
                       "average_from_start": np.nanmean(mean[1:]),
                       "per_state": np.nanmean((e / h.sigma[good][:, after]) ** 2, axis=(0, 1)).tolist()}
        out["nis"] = {k: {"average": np.nanmean(np.nanmean(v[good][:, after], axis=0))} for k, v in h.nis.items()}
    return out


def subset(got: dict, want: dict) -> dict:
    """``got`` restricted to the keys of ``want``, recursively."""
    return {k: subset(got[k], v) if isinstance(v, dict) else got[k] for k, v in want.items()}


@pytest.mark.filterwarnings("ignore:Mean of empty slice", "ignore:All-NaN slice")
@pytest.mark.parametrize("nees, euler", [(True, True), (False, False)])
def test_chunk_by_chunk_scores_equal_numpy_over_the_merged_runs(nees, euler, close_metrics):
    rng = np.random.default_rng(11)
    sizes = [7, 1, 12, 5]
    starts = np.cumsum([0] + sizes[:-1])
    parts = [ChunkPart([int(a) + i for i in range(n)], {"KF": history(rng, n, nees=nees, euler=euler)})
             for a, n in zip(starts, sizes)]
    windows = [("turn", 20.0, 60.0), ("late", 80.0, 119.0), ("never", 500.0, 600.0)]
    merged = merge_parts(parts)
    got = score_parts(lambda: iter(parts), 30.0, windows)["KF"]
    want = numpy_scores(merged.histories["KF"], 30.0, windows)
    close_metrics(want, subset(got.to_dict(), want))
    assert got.diverged_runs == 3 and got.runs_counted == sum(sizes) - 3
    assert set(got.nis or {}) == ({"gnss:bd", "height:ads"} if nees else set())
    assert (got.attitude is not None) == euler and got.windows["never"].quantities == {}
    assert (got.wind is not None) == nees and (not nees or len(got.interval("wind.rms_mps")) == 2)
    # the chunking does not matter: the merged runs as one chunk give the same numbers
    close_metrics(got.to_dict(), score(merged.histories["KF"], 30.0, windows, runs=merged.runs).to_dict())


def test_landmark_and_calibration_scores_from_chunks_equal_the_merged_ones(close_metrics):
    close = close_metrics
    rng = np.random.default_rng(5)
    T = 50
    turns = np.linspace(0, 3, T)

    def cal(n):
        return CalibrationHistory(t_s=np.arange(T) * 2.0, turns=turns, hard_iron_err=rng.random((n, T)),
                                  soft_iron_err=rng.random((n, T)))
    parts = [ChunkPart(list(range(a, a + n)), {"KF": history(rng, n)}, None, {"mag": cal(n)})
             for a, n in ((0, 4), (4, 6))]
    # sightings: one at the start, one across the records' end, two in between
    spans = [("cam landmark 1", 0.0, 3.0, 2.0), ("cam landmark 2", 40.5, 44.2, 1.5),
             ("cam landmark 3", 70.0, 70.0, 3.0), ("cam landmark 4", 110.0, 400.0, 2.0)]
    scores = score_run(lambda: iter(parts), 30.0, (), spans)
    metrics, calib = scores.estimators, scores.calibration
    merged = merge_parts(parts)
    close(sighting_metrics(merged.histories["KF"], spans).to_dict(), metrics["KF"].landmarks.to_dict())
    whole = calibration_score(merged.calibration["mag"])
    close(whole.to_dict(), calib["mag"].to_dict())
    assert whole.after_turns is not None and whole.runs == 10
    # against the calibration history itself: the first epoch after two turns, over all runs
    k = int(np.flatnonzero(turns >= 2.0)[0])
    hard = 100 * merged.calibration["mag"].hard_iron_err[:, k]
    assert whole.after_turns.hard_iron_pct.p95 == pytest.approx(np.percentile(hard, 95), rel=1e-12)


def _one_run(h: EstimatorHistory, r: int) -> EstimatorHistory:
    """Run ``r`` of ``h`` alone (every field with a run axis cut to it), counted."""
    B, out = len(h.diverged), {}
    for f in dataclasses.fields(h):
        v = getattr(h, f.name)
        if isinstance(v, np.ndarray) and v.ndim and v.shape[0] == B:
            out[f.name] = v[r:r + 1]
        elif isinstance(v, list) and len(v) == B:
            out[f.name] = v[r:r + 1]
        elif isinstance(v, dict) and v and all(isinstance(x, np.ndarray) for x in v.values()):
            out[f.name] = {k: x[r:r + 1] for k, x in v.items()}
    return dataclasses.replace(h, **{**out, "diverged": np.zeros(1, bool)})


@pytest.mark.filterwarnings("ignore:Mean of empty slice", "ignore:All-NaN slice", "ignore:Degrees of freedom")
def test_each_runs_own_statistics_equal_numpy_over_that_run_alone(close_metrics):
    """The per-run values kept for single-flight checks (p99, maxima, the windows' extremes,
    std about the run's own mean and p95, the attitude percentiles, the convergence time, the
    resets), streamed in chunks, equal the pooled formulas applied to each run alone; every kept
    path is one a ``single_run`` check accepts (has_run_values)."""
    rng = np.random.default_rng(12)
    sizes = [4, 1, 6]
    starts = np.cumsum([0] + sizes[:-1])
    parts = [ChunkPart([int(a) + i for i in range(n)], {"KF": history(rng, n)}) for a, n in zip(starts, sizes)]
    windows = [("turn", 20.0, 60.0), ("late", 80.0, 119.0)]
    es = score_run(lambda: iter(parts), 30.0, windows).samples["KF"]
    h = merge_parts(parts).histories["KF"]
    counted = np.flatnonzero(~h.diverged)
    assert es.runs.tolist() == counted.tolist()
    assert {"p99.pos_m", "attitude.p95_about_run_mean_deg", "windows.turn.height_m.std", "windows.late.yaw_deg.max_neg",
            "convergence_s", "resets.mean_per_run"} <= set(es.per_run)
    assert all(has_run_values(p) for p in [*es.per_run, *es.metrics])
    for i, r in enumerate(counted):
        one = _one_run(h, r)
        want = numpy_scores(one, 30.0, windows)
        for path, v in es.per_run.items():
            if path == "convergence_s":                    # the run alone, to its last record
                err = np.linalg.norm(h.pos_err_m[r], axis=-1)
                end = np.flatnonzero(np.isfinite(err))[-1] + 1
                t = convergence_time(h.t_s[:end], err[:end])
                assert v[i, 0] == (np.inf if t is None else t)
            elif path == "resets.mean_per_run":
                assert v[i, 0] == len(h.resets[r])
            else:
                node = want
                for key in path.split("."):
                    node = node[key]
                close_metrics({"v": np.atleast_1d(node).tolist()}, {"v": v[i].tolist()})
