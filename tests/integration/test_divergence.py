"""Divergence: a run whose solution, covariance or NEES has blown up is flagged, with when and
why, and left out of the statistics; an estimator that raises is flagged and stopped while the
other estimators go on, bit for bit as without it (issue 17)."""

import copy
import dataclasses

import numpy as np
import pytest
import yaml

import navsim.navigation.estimators.factory
from navsim.experiment.chunkstore import ChunkStore, part_arrays, part_from_arrays
from navsim.experiment.driver import NEES_BOUND, PSD_TOL, SYMMETRY_TOL, covariance_faults
from navsim.experiment.options import RunOptions
from navsim.experiment.runner import run_monte_carlo
from navsim.experiment.scenario import load_scenario
from navsim.foundations import earth
from navsim.navigation.kernels.records import covariance_record
from navsim.navigation.estimators import kalman
from navsim.records.chunk import ChunkPart, merge_parts
from navsim.records.history import EstimatorHistory
from navsim.scoring.scorer import DIVERGENCE_LISTED, score, score_parts, score_run

P0 = "p0_bd_sins_ads"
SANE = "BD/SINS/ADS ES-KF 16"
BLOWN = "ES-KF, GNSS sigma 1e-12 m"
TWIN = "the same ES-KF, spoiled"


def with_twin(sc):
    """``sc`` flying the sane ES-KF and a second one like it labelled :data:`TWIN`, and ``sc``
    flying the sane one alone."""
    sane = next(e for e in sc.estimators if e.label == SANE)
    return (dataclasses.replace(sc, estimators=[sane, dataclasses.replace(sane, label=TWIN)]),
            dataclasses.replace(sc, estimators=[sane]))


@pytest.fixture(scope="module")
def p0(repo_root, tmp_path_factory):
    """P0's scenario data, its flight's first 60 s and the flight's cached path; the ES-KF's GNSS
    sigma 1e-12 m as a second ES-KF beside the sane one."""
    import os

    from navsim.experiment.runner import cached_flight
    os.environ.setdefault("NAVSIM_CACHE", str(tmp_path_factory.mktemp("cache")))
    raw = yaml.safe_load((repo_root / "scenarios" / f"{P0}.yaml").read_text())
    sane = next(e for e in raw["estimators"] if e["label"] == SANE)
    blown = copy.deepcopy(sane)
    blown["label"] = BLOWN
    next(m for m in blown["measurements"] if m["type"] == "gnss_position")["sigma_m"] = 1.0e-12
    raw["estimators"] = [sane, blown]
    raw.pop("reference")                  # P0's claims name the free SINS, left out here
    path = tmp_path_factory.mktemp("scenario") / f"{P0}_blown.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    sc = load_scenario(path)
    truth, truth_path, _ = cached_flight(sc.flight)
    return sc, truth.slice(0, 6001), truth_path


def test_a_blown_up_filter_is_flagged_and_the_sane_one_scored_on_every_run(p0, tmp_path, close_metrics):
    # Measured (3 runs, seed 1; the whole 500 s flight gives the same): the GNSS sigma 1e-12 m
    # filter has NEES 2e26 from its first fix at 1 s on (the sane one averages 8.8), and is
    # flagged "NEES above bound" there in every run. Its covariance stays positive definite
    # once scaled to a unit diagonal (the "indefinite" is rounding in the raw
    # eigenvalues, 1e-24 of the largest): the NEES bound is what catches it.
    sc, truth, truth_path = p0
    store = ChunkStore(tmp_path / "chunks", {"seed": 1}, mode="new")
    res = run_monte_carlo(sc, truth, truth_path, RunOptions(runs=3, seed=1, workers=1, chunk_runs=2), store=store)
    assert res.failed == {} and list(res.runs) == [0, 1, 2]
    blown, sane = res.histories[BLOWN], res.histories[SANE]
    assert blown.diverged.all() and blown.divergence == [(1.0, "NEES above bound")] * 3
    assert np.nanmin(blown.nees[:, 1:]) > NEES_BOUND and np.nanmax(blown.nees) > 1e20
    assert not sane.diverged.any() and sane.divergence == [None] * 3 and np.nanmax(sane.nees) < 1e3
    m = score(blown, 10.0).to_dict()
    assert m["diverged_runs"] == 3 and m["runs_counted"] == 0 and "rms" not in m
    assert m["divergence"] == {"count": 3, "causes": {"NEES above bound": 3},
                               "runs": [{"run": r, "t_s": 1.0, "cause": "NEES above bound"} for r in range(3)]}
    s = score(sane, 10.0).to_dict()
    assert s["diverged_runs"] == 0 and s["runs_counted"] == 3 and "divergence" not in s
    assert max(s["rms"]["pos_m"]) < 5.0 and max(s["rms"]["att_deg"]) < 0.1
    # the streamed scorer (chunks of 2 and 1 runs) lists the same
    streamed = score_run(store.parts, 10.0).estimators
    close_metrics(m, streamed[BLOWN].to_dict())
    close_metrics(s, streamed[SANE].to_dict())


class RaisesOnce:
    """A real estimator whose ``method`` raises LinAlgError at its ``call``-th call."""

    def __init__(self, inner, method: str, call: int):
        self.inner, self.method, self.call, self.calls = inner, method, call, 0
        self.period_s = inner.period_s

    def __getattr__(self, name):
        attr = getattr(self.inner, name)
        if name != self.method:
            return attr

        def wrapped(*args, **kw):
            self.calls += 1
            if self.calls == self.call:
                raise np.linalg.LinAlgError("Singular matrix")
            return attr(*args, **kw)
        return wrapped


@pytest.mark.parametrize("method, call, t_s", [("epoch", 5, 5.0), ("propagate", 6, 6.0),
                                               ("solution", 6, 5.0), ("initialize", 1, 0.0)])
def test_an_estimator_that_raises_is_flagged_and_the_others_go_on(same_history, p0, monkeypatch, method, call, t_s):
    sc, truth, truth_path = p0
    truth = truth.slice(0, 1201)
    sc, alone = with_twin(sc)
    want = run_monte_carlo(alone, truth, truth_path, RunOptions(runs=3, seed=1, workers=1)).histories[SANE]
    real = navsim.navigation.estimators.factory.build
    monkeypatch.setattr(navsim.navigation.estimators.factory, "build",
                        lambda e: RaisesOnce(real(e), method, call) if e.label == TWIN else real(e))
    res = run_monte_carlo(sc, truth, truth_path, RunOptions(runs=3, seed=1, workers=1))
    assert res.failed == {}                              # the chunk is not lost
    bad, sane = res.histories[TWIN], res.histories[SANE]
    same_history(want, sane, timed=False)
    assert bad.diverged.all() and bad.divergence == [(t_s, "LinAlgError: Singular matrix")] * 3
    assert bad.pos_err_m.shape == sane.pos_err_m.shape == (3, 13, 3)
    stop = np.searchsorted(bad.t_s, t_s)                  # NaN from the failing epoch on
    assert np.isnan(bad.pos_err_m[:, stop:]).all() and np.isfinite(bad.pos_err_m[:, :stop]).all()
    m = score(bad, 0.0)
    assert m.runs_counted == 0 and m.divergence.causes == {"LinAlgError: Singular matrix": 3}


def test_an_indefinite_covariance_in_one_run_flags_that_run_alone(same_history, p0, monkeypatch):
    sc, truth, truth_path = p0
    truth = truth.slice(0, 1201)
    sc, alone = with_twin(sc)
    want = run_monte_carlo(alone, truth, truth_path, RunOptions(runs=3, seed=1, workers=1)).histories[SANE]
    real = navsim.navigation.estimators.factory.build

    class Spoiled:
        """The sane ES-KF, whose covariance in run 1 gets a correlation of 2 at 4 s."""

        def __init__(self, inner):
            self.inner, self.period_s = inner, inner.period_s

        def __getattr__(self, name):
            return getattr(self.inner, name)

        def epoch(self, t, sensors):
            out = self.inner.epoch(t, sensors)
            if t == 4.0:
                P = self.inner.P
                P[1, 0, 1] = P[1, 1, 0] = 2.0 * np.sqrt(P[1, 0, 0] * P[1, 1, 1])
            return out
    monkeypatch.setattr(navsim.navigation.estimators.factory, "build",
                        lambda e: Spoiled(real(e)) if e.label == TWIN else real(e))
    res = run_monte_carlo(sc, truth, truth_path, RunOptions(runs=3, seed=1, workers=1))
    spoiled = res.histories[TWIN]
    assert list(spoiled.diverged) == [False, True, False]
    assert spoiled.divergence == [None, (4.0, "covariance not positive definite"), None]
    for name in ("pos_err_m", "att_err_rad", "sigma", "nees"):   # runs 0 and 2 as without the spoiling
        assert np.array_equal(getattr(spoiled, name)[[0, 2]], getattr(want, name)[[0, 2]]), name
    same_history(want, res.histories[SANE], timed=False)
    assert score(spoiled, 0.0).runs_counted == 2


def test_covariance_faults():
    rng = np.random.default_rng(2)
    A = rng.normal(size=(9, 9))
    # a healthy covariance with P0's scales: rad^2 attitude and position, m^2 height, and tiny
    scale = np.array([1e-8, 1e-8, 1e-7, 1e-2, 1e-2, 1e-2, 6e-13, 1e-38, 1e2])
    healthy = (A @ A.T + 9 * np.eye(9)) * np.sqrt(np.outer(scale, scale))
    negative = np.diag(np.r_[np.ones(8), -1e-3])
    indefinite = np.eye(9)
    indefinite[0, 1] = indefinite[1, 0] = 1.5
    asymmetric = healthy.copy()
    asymmetric[2, 5] *= 1.01
    nan, inf = healthy.copy(), healthy.copy()
    nan[3, 3] = np.nan
    inf[0, 8] = inf[8, 0] = np.inf
    zero = np.zeros((9, 9))                         # no uncertainty at all: not a divergence
    P = np.stack([healthy, negative, indefinite, asymmetric, nan, inf, zero, healthy.T])
    assert covariance_faults(P) == [None, "covariance not positive definite", "covariance not positive definite",
                                    "covariance not symmetric", "covariance not finite", "covariance not finite",
                                    None, None]
    assert covariance_faults(np.stack([healthy, zero])) == [None, None]          # the batch at once


def test_the_record_of_a_covariance_against_numpy_with_its_divergence_codes():
    """``covariance_record``: the NEES against numpy's solve (NaN for a singular P),
    the 1-sigma with the position in metres, and the code's order of precedence."""
    rng = np.random.default_rng(5)
    A = rng.normal(size=(6, 9, 9))
    P = A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(9)
    P[2] = 0.0
    P[4, 0, 1] += 1.0                                   # not symmetric
    errors = np.concatenate([rng.normal(size=(6, 9)), np.zeros((6, 6))], -1)
    errors[3, 10] = np.nan                              # a non-finite error (NED position)
    errors[5, :9] *= 1e8                                # NEES above the bound
    truth = np.array([[0.5, 2.0, 300.0, 0, 0, 0, 0, 0, 0]])
    sigma, nees, code = np.empty((6, 9)), np.empty(6), np.zeros(6, np.int64)
    covariance_record(P, errors, truth, np.array([SYMMETRY_TOL, PSD_TOL, NEES_BOUND]), sigma, nees, code)
    ok = [0, 1, 3, 5]
    want = np.einsum("bi,bi->b", errors[ok, :9], np.linalg.solve(P[ok], errors[ok, :9, None])[..., 0])
    np.testing.assert_allclose(nees[ok], want, rtol=1e-10, atol=0)
    assert np.isnan(nees[2]) and nees[5] > NEES_BOUND
    r_m, r_n = earth.radii(0.5)
    want = np.sqrt(np.einsum("bii->bi", P))
    want[:, 6] *= r_m + 300.0
    want[:, 7] *= (r_n + 300.0) * np.cos(0.5)
    np.testing.assert_allclose(sigma, want, rtol=1e-14)
    assert code.tolist() == [0, 0, 0, 4, 2, 5]          # a zero P is positive semi-definite


def test_a_singular_innovation_covariance_spoils_its_own_run_only():
    rng = np.random.default_rng(7)
    B, n, m = 3, 4, 2
    A = rng.normal(size=(B, n, n))
    x, P = rng.normal(size=(B, n)), A @ np.swapaxes(A, -1, -2) + np.eye(n)
    z, H = rng.normal(size=(B, m)), rng.normal(size=(B, m, n))
    R = np.broadcast_to(np.eye(m), (B, m, m)).copy()
    P[1], R[1] = 0.0, 0.0                            # S = 0 in run 1
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.solve(H @ P @ np.swapaxes(H, -1, -2) + R, z[..., None])
    xb, Pb, _, _, nis = kalman.update(x, P, z, H, R)
    assert np.isnan(xb[1]).all() and np.isnan(Pb[1]).all() and np.isnan(nis[1])
    for i in (0, 2):
        one = kalman.update(x[i:i + 1], P[i:i + 1], z[i:i + 1], H[i:i + 1], R[i:i + 1])
        assert np.array_equal(one[0], xb[i:i + 1]) and np.array_equal(one[1], Pb[i:i + 1])
        assert np.array_equal(one[4], nis[i:i + 1])
    # where run 1 has no sample, it keeps its state
    xv, Pv, _, _, nisv = kalman.update(x, P, z, H, R, valid=np.array([True, False, True]))
    assert np.array_equal(xv[1], x[1]) and np.array_equal(Pv[1], P[1]) and np.isnan(nisv[1])
    assert np.array_equal(xv[[0, 2]], xb[[0, 2]])


def synthetic(runs, seed, divergence=True):
    """A chunk part whose runs 1 and 3 (of each 4) are diverged, with their records."""
    rng = np.random.default_rng(seed)
    B, E = len(runs), 5
    diverged = np.array([i % 4 in (1, 3) for i in range(B)])
    div = [(float(i), f"cause {i % 3}") if d else None for i, d in enumerate(diverged)]
    h = EstimatorHistory(
        label="KF", t_s=np.arange(E, dtype=float), att_err_rad=rng.normal(size=(B, E, 3)),
        vel_err_mps=rng.normal(size=(B, E, 3)), pos_err_m=rng.normal(size=(B, E, 3)),
        sigma=None, nees=None, nis={}, nis_dim={}, diverged=diverged,
        cost={"propagate_s": 0.1, "epoch_s": 0.2, "runs": B, "epochs": E - 1, "batches": 1},
        divergence=div if divergence else None)
    return ChunkPart(list(runs), {"KF": h})


def test_divergence_records_round_trip_and_are_listed_with_their_runs(tmp_path, close_metrics):
    part = synthetic(range(10, 14), 1)
    np.savez(tmp_path / "p.npz", **part_arrays(part))
    with np.load(tmp_path / "p.npz", allow_pickle=False) as data:
        back = part_from_arrays(data).histories["KF"]
    assert back.divergence == part.histories["KF"].divergence == [None, (1.0, "cause 1"), None, (3.0, "cause 0")]
    # merged in memory and from a store, with a chunk built without records
    parts = [synthetic(range(14, 17), 2, divergence=False), synthetic(range(10, 14), 1),
             synthetic(range(17, 57), 3)]
    store = ChunkStore(tmp_path / "chunks", {"seed": 1}, mode="new")
    for p in parts:
        store.add(p)
    runs, merged = (lambda m: (m.runs, m.histories))(merge_parts(parts))
    stored = store.merged().histories["KF"]
    assert stored.divergence == merged["KF"].divergence and len(merged["KF"].divergence) == 47
    assert merged["KF"].divergence[4:7] == [None] * 3
    # in memory and chunk by chunk, the same runs are listed, by their run numbers
    want = score(merged["KF"], runs=runs).to_dict()
    got = score_parts(lambda: iter(sorted(parts, key=lambda p: p.runs[0])))["KF"].to_dict()
    close_metrics(want, got)
    d = got["divergence"]
    assert d["count"] == got["diverged_runs"] == int(merged["KF"].diverged.sum()) == 23
    assert d["causes"] == {"cause 1": 8, "cause 0": 8, "not recorded": 1, "cause 2": 6}
    assert len(d["runs"]) == DIVERGENCE_LISTED
    assert d["runs"][:3] == [{"run": 11, "t_s": 1.0, "cause": "cause 1"}, {"run": 13, "t_s": 3.0, "cause": "cause 0"},
                             {"run": 15, "t_s": None, "cause": "not recorded"}]
