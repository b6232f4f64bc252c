"""Streaming chunks to the output folder, ``--resume`` and the Dask executor: the numbers must
equal the local executor's, bit for bit."""

import json

import numpy as np
import pytest
from test_run import SHORT, run, short, short_pdf  # noqa: F401 (fixtures)

import navsim
from navsim.cli import main
from navsim.experiment.chunkstore import ChunkStore, part_arrays, part_from_arrays
from navsim.records.chunk import ChunkPart, merge_parts
from navsim.records.history import EstimatorHistory
from navsim.records.truth import CalibrationHistory, TruthBias


@pytest.fixture(autouse=True)
def need_distributed(request):
    """A test marked ``dask`` (it needs Dask distributed: the README's ``.[test]`` install lacks
    it) is skipped without it, except in CI (``NAVSIM_REQUIRE_DASK=1``), where it fails;
    ``.ci/run`` runs the marked tests again with the ``dask`` extra (``-m dask``)."""
    import os
    if request.node.get_closest_marker("dask") is None:
        return
    try:
        import distributed  # noqa: F401
    except ImportError:
        if os.environ.get("NAVSIM_REQUIRE_DASK") == "1":
            pytest.fail("NAVSIM_REQUIRE_DASK=1 but Dask distributed is not installed")
        pytest.skip("the Dask tests need pip install -e '.[test,dask]'")


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    """An uninterrupted run of the PDF-only short scenario, the reference a resumed run must
    equal (the numbers do not depend on the chunking); the tests only read it."""
    folder = tmp_path_factory.mktemp("whole")
    path = folder / "short.yaml"
    path.write_text(SHORT + "report: {formats: [pdf]}\n")
    assert run(path, folder / "out", "--chunk-runs", "2") == 0
    return folder / "out"


def numbers(out):
    """metrics.json without the wall times."""
    m = json.loads((out / "metrics.json").read_text())
    return {k: {q: v for q, v in e.items() if q != "cost"} for k, e in m["estimators"].items()}, m


def kf_errors(out):
    """The KF's position errors of every run the folder holds (its chunks)."""
    store = navsim.open_result(out).store
    return np.concatenate([p.histories["KF"].pos_err_m for p in store.parts()])


def synthetic_part(runs, seed):
    """A chunk part with every optional field: NaN NIS, resets, no covariance, a calibration."""
    rng = np.random.default_rng(seed)
    h = EstimatorHistory(
        label="CPF-EKF", t_s=np.arange(4.0), att_err_rad=rng.normal(size=(2, 4, 3)),
        vel_err_mps=rng.normal(size=(2, 4, 3)), pos_err_m=rng.normal(size=(2, 4, 3)), sigma=None, nees=None,
        nis={"mag_heading:mag": np.array([[np.nan, 1.0, 2.0, np.nan]] * 2), "baro:b": rng.random((2, 4))},
        nis_dim={"mag_heading:mag": 1, "baro:b": 1}, diverged=np.array([False, True]),
        cost={"propagate_s": 0.1, "epoch_s": 0.2, "runs": 2, "epochs": 3, "batches": 1},
        euler_err_rad=rng.normal(size=(2, 4, 3)), resets=[[], [(1.5 + seed, "divergence"), (2.0, "innovation")]])
    bias = TruthBias(gyro_bias=rng.normal(size=(2, 4, 3)), accel_bias=rng.normal(size=(2, 4, 3)))
    return ChunkPart(list(runs), {"CPF-EKF": h}, bias,
                     {"mag": CalibrationHistory(np.arange(3.0), np.arange(3.0), rng.random((2, 3)),
                                                rng.random((2, 3)))})


def test_a_part_round_trips_every_field(same_history, tmp_path):
    part = synthetic_part([4, 5], 1)
    h = part.histories["CPF-EKF"]
    np.savez(tmp_path / "p.npz", **part_arrays(part))
    with np.load(tmp_path / "p.npz", allow_pickle=False) as data:
        back = part_from_arrays(data)
    assert back.runs == [4, 5]
    same_history(h, back.histories["CPF-EKF"])
    assert back.truth_bias.arrays().keys() == part.truth_bias.arrays().keys() == {"gyro_bias", "accel_bias"}
    assert all(np.array_equal(back.truth_bias.arrays()[k], v) for k, v in part.truth_bias.arrays().items())
    assert back.calibration.keys() == {"mag"}
    cal = back.calibration["mag"].arrays()
    assert all(np.array_equal(cal[k], v) for k, v in part.calibration["mag"].arrays().items())


def test_the_merged_store_equals_the_in_memory_merge(same_history, tmp_path):
    parts = [synthetic_part(range(2, 4), 2), synthetic_part(range(0, 2), 1)]
    store = ChunkStore(tmp_path, {"seed": 1}, mode="new")
    for part in parts:
        store.add(part)
    a, b = merge_parts(parts), store.merged()
    assert list(a.runs) == list(b.runs) == [0, 1, 2, 3]
    same_history(a.histories["CPF-EKF"], b.histories["CPF-EKF"])
    assert np.array_equal(a.truth_bias.gyro_bias, b.truth_bias.gyro_bias)
    assert np.array_equal(a.truth_bias.accel_bias, b.truth_bias.accel_bias) and b.truth_bias.gyro_bias_seen is None
    assert a.calibration.keys() == b.calibration.keys() == {"mag"}
    assert all(np.array_equal(a.calibration["mag"].arrays()[k], v) for k, v in b.calibration["mag"].arrays().items())


def test_stored_chunks_equal_the_in_memory_histories(same_history, short_pdf, tmp_path):
    from navsim.experiment.options import RunOptions
    from navsim.experiment.runner import cached_flight, run_monte_carlo
    from navsim.experiment.scenario import load_scenario
    sc = load_scenario(short_pdf)
    truth, path, _ = cached_flight(sc.flight)
    key = {"scenario_hash": "x", "seed": 4, "runs": 5, "chunk_runs": 2}
    store = ChunkStore(tmp_path / "chunks", key, mode="new")
    memory = run_monte_carlo(sc, truth, path, RunOptions(runs=5, seed=4, workers=1, chunk_runs=2))
    stored = run_monte_carlo(sc, truth, path, RunOptions(runs=5, seed=4, workers=1, chunk_runs=2), store=store)
    assert sorted(p.name for p in (tmp_path / "chunks").iterdir()) == [
        "chunk_0-1.npz", "chunk_2-3.npz", "chunk_4-4.npz", "index.json"]
    assert list(stored.runs) == list(memory.runs) == [0, 1, 2, 3, 4]
    assert memory.histories and memory.histories.keys() == stored.histories.keys()
    for label in memory.histories:
        same_history(memory.histories[label], stored.histories[label], timed=False)
    held, back = memory.truth_bias.arrays(), stored.truth_bias.arrays()
    assert held and held.keys() == back.keys()
    assert all(np.array_equal(held[k], back[k]) for k in held)
    index = json.loads((tmp_path / "chunks" / "index.json").read_text())
    assert index["chunks"]["2-3"] == "chunk_2-3.npz" and index["failed"] == {} and index["seed"] == 4


def test_resume_runs_only_the_missing_chunks_and_gives_the_same_metrics(short_pdf, whole, tmp_path, monkeypatch):
    import navsim.experiment.runner
    real, calls, stop = navsim.experiment.runner._chunk, [], [True]

    def interrupt(args):
        calls.append(list(args[3])[0])
        if calls[-1] == 4 and stop[0]:
            raise KeyboardInterrupt
        return real(args)

    monkeypatch.setattr(navsim.experiment.runner, "_chunk", interrupt)
    assert run(short_pdf, tmp_path / "cut", "--chunk-runs", "2") == 130
    assert numbers(tmp_path / "cut")[1]["runs_done"] == 4
    calls.clear()
    stop[0] = False
    assert run(short_pdf, tmp_path / "cut", "--resume") == 0          # the chunk size comes from the index
    assert calls == [4]
    (a, ma), (b, mb) = numbers(whole), numbers(tmp_path / "cut")
    assert a == b and mb["runs_done"] == 6 and mb["interrupted"] is False
    assert json.loads((tmp_path / "cut" / "run.json").read_text())["resumed"] is True
    assert np.array_equal(kf_errors(whole), kf_errors(tmp_path / "cut"))


def test_resume_refuses_another_run(short_pdf, tmp_path, capsys):
    assert run(short_pdf, tmp_path / "none", "--resume") == 2
    assert "nothing to resume" in capsys.readouterr().err
    assert run(short_pdf, tmp_path / "out", "--chunk-runs", "3") == 0
    assert run(short_pdf, tmp_path / "out", "--resume", "--seed", "5") == 2
    assert "seed 4 there, 5 now" in capsys.readouterr().err


@pytest.mark.dask
def test_dask_local_cluster_gives_the_local_numbers(short_pdf, tmp_path, monkeypatch):
    assert run(short_pdf, tmp_path / "local", "--chunk-runs", "2", "--workers", "1") == 0
    assert run(short_pdf, tmp_path / "dask", "--chunk-runs", "2", "--workers", "2", "--executor", "dask") == 0
    (a, _), (b, mb) = numbers(tmp_path / "local"), numbers(tmp_path / "dask")
    assert a == b and mb["runs_done"] == 6
    assert np.array_equal(kf_errors(tmp_path / "local"), kf_errors(tmp_path / "dask"))
    assert json.loads((tmp_path / "dask" / "run.json").read_text())["executor"] == "dask"


@pytest.mark.dask
def test_dask_retries_a_chunk_once_and_flags_one_that_fails_twice(short_pdf, tmp_path, monkeypatch):
    import navsim.experiment.runner
    real, marker = navsim.experiment.runner._chunk, tmp_path / "failed_once"

    def flaky(args):
        first = list(args[3])[0]
        if first == 0 and not marker.exists():
            marker.touch()
            raise MemoryError("worker killed once")
        if first == 2:
            raise MemoryError("worker killed")
        return real(args)

    monkeypatch.setattr(navsim.experiment.runner, "_chunk", flaky)
    assert run(short_pdf, tmp_path / "out", "--chunk-runs", "2", "--workers", "2", "--executor", "dask") == 0
    _, m = numbers(tmp_path / "out")
    assert m["runs_done"] == 4 and set(m["failed_runs"]) == {"2", "3"} and marker.exists()
    record = json.loads((tmp_path / "out" / "run.json").read_text())
    assert list(record["failed_chunks"]) == ["2-3"] and "worker killed" in record["failed_chunks"]["2-3"]


def test_closed_loop_refuses_dask(repo_root, tmp_path, capsys):
    assert main(["run", str(repo_root / "scenarios" / "p1_return_to_land.yaml"), "--executor", "dask",
                 "--out", str(tmp_path)]) == 2
    assert "local executor only" in capsys.readouterr().err


@pytest.mark.dask
@pytest.mark.filterwarnings("ignore:No artists with labels")   # the stub returns no runs
def test_sweep_passes_the_executor_to_every_point(short_pdf, tmp_path, monkeypatch):
    import navsim.api
    import navsim.experiment.runner
    seen = []

    def record(*args, **kwargs):
        seen.append((args[3].executor, args[3].scheduler))     # run_monte_carlo(scenario, truth, path, options)
        return navsim.experiment.runner.RunResult({}, np.array([0, 1]))

    monkeypatch.setattr(navsim.api.runs, "run_monte_carlo", record)
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"scenario: {short_pdf.name}\nruns: 2\npoints: [{{montecarlo.seed: 1}}, {{montecarlo.seed: 2}}]\n")
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--executor", "dask",
                 "--scheduler", "tcp://nowhere:8786"]) == 0
    assert seen == [("dask", "tcp://nowhere:8786")] * 2


def test_streamed_metrics_cover_every_run_and_the_plots_the_first(short_pdf, tmp_path, monkeypatch, close_metrics):
    """Metrics chunk by chunk (flat memory) equal the in-memory scores of all runs; the report's
    plots load only the first REPORT_RUNS runs and say so; no runs.npz (the runs are in chunks/)."""
    import navsim.experiment.runner
    from navsim.experiment.scenario import load_scenario
    from navsim.scoring.scorer import score
    monkeypatch.setattr(navsim.experiment.runner, "REPORT_RUNS", 2)
    out = tmp_path / "out"
    assert run(short_pdf, out, "--chunk-runs", "2") == 0
    record = json.loads((out / "run.json").read_text())
    assert record["runs_plotted"] == 2 and record["runs_done"] == 6 and record["per_run_data"] == "chunks/"
    assert not (out / "runs.npz").exists() and (out / "report.pdf").stat().st_size > 0
    sc = load_scenario(short_pdf)
    hist = ChunkStore.open(out / "chunks").merged().histories
    got = json.loads((out / "metrics.json").read_text())["estimators"]
    for label, h in hist.items():
        want = score(h, sc.settle_s, sc.windows).to_dict()
        close_metrics({k: v for k, v in want.items() if k != "cost"}, {k: v for k, v in got[label].items() if k != "cost"})
    assert got["KF"]["runs_counted"] == 6


@pytest.mark.dask
def test_dask_retries_a_chunk_whose_worker_dies_and_flags_one_that_kills_it_twice(short_pdf, tmp_path, monkeypatch):
    """A worker process killed under a chunk (os._exit, as the OOM killer would): the chunk runs
    again on a restarted worker; a chunk that kills its worker twice is flagged, the others complete."""
    import os

    import navsim.experiment.runner
    real, log = navsim.experiment.runner._chunk, tmp_path / "attempts"
    log.mkdir()

    def deadly(args):
        first = list(args[3])[0]
        (log / f"{first}-{len(list(log.iterdir()))}").touch()
        if first == 2 or (first == 0 and len([p for p in log.iterdir() if p.name.startswith("0-")]) == 1):
            os._exit(1)
        return real(args)

    monkeypatch.setattr(navsim.experiment.runner, "_chunk", deadly)
    assert run(short_pdf, tmp_path / "out", "--chunk-runs", "2", "--workers", "2", "--executor", "dask") == 0
    _, m = numbers(tmp_path / "out")
    attempts = [p.name.split("-")[0] for p in log.iterdir()]
    # chunk 0 ran twice (killed once), or three times when its finished result was still on the
    # worker that chunk 2 then killed (Dask recomputes lost results); chunk 2 exactly twice
    assert attempts.count("0") in (2, 3) and attempts.count("2") == 2 and attempts.count("4") in (1, 2)
    assert m["runs_done"] == 4 and set(m["failed_runs"]) == {"2", "3"}
    assert "KilledWorker" in json.loads((tmp_path / "out" / "run.json").read_text())["failed_chunks"]["2-3"]


def test_a_run_killed_by_sigkill_resumes_to_the_uninterrupted_metrics(short_pdf, whole, tmp_path):
    """``navsim run`` killed (SIGKILL: no handler runs) once two chunks are stored; ``--resume``
    completes it with the metrics of an uninterrupted run."""
    import subprocess
    import sys
    import time
    cut = tmp_path / "cut"
    proc = subprocess.Popen([sys.executable, "-m", "navsim", "run", str(short_pdf), "--out", str(cut),
                             "--chunk-runs", "1", "--workers", "1"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    index, done, deadline = cut / "chunks" / "index.json", 0, time.monotonic() + 600
    while proc.poll() is None and done < 2 and time.monotonic() < deadline:
        try:
            done = len(json.loads(index.read_text())["chunks"])
        except (OSError, ValueError, KeyError):
            pass
        time.sleep(0.02)
    proc.kill()
    proc.wait()
    assert 2 <= done < 6 and not (cut / "metrics.json").exists()
    assert run(short_pdf, cut, "--resume") == 0
    (a, _), (b, mb) = numbers(whole), numbers(cut)
    assert a == b and mb["runs_done"] == 6


@pytest.mark.dask
def test_dask_on_a_running_scheduler_gives_the_local_numbers(short_pdf, tmp_path):
    """``--scheduler ADDRESS``: the truth is scattered to the cluster's workers (no flight cache
    needed there) and the numbers equal the local executor's."""
    import distributed
    assert run(short_pdf, tmp_path / "local", "--chunk-runs", "3", "--workers", "1") == 0
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=None) as cluster:
        assert run(short_pdf, tmp_path / "remote", "--chunk-runs", "3", "--executor", "dask",
                   "--scheduler", cluster.scheduler_address) == 0
    (a, _), (b, mb) = numbers(tmp_path / "local"), numbers(tmp_path / "remote")
    assert a == b and mb["runs_done"] == 6
    assert json.loads((tmp_path / "remote" / "run.json").read_text())["scheduler"] == cluster.scheduler_address


def _ones(args):
    return np.ones(1000)


def test_the_local_pool_keeps_no_part_once_it_is_handed_on():
    """With ``on_part`` (the chunk store) the driver holds no finished part: memory flat in runs."""
    import gc
    import weakref

    from navsim.experiment.runner import run_chunks
    refs, alive = [], []

    def on_part(part):
        gc.collect()
        alive.append(sum(r() is not None for r in refs))     # earlier parts still held
        refs.append(weakref.ref(part))
    parts, failed, _ = run_chunks(_ones, [range(i, i + 1) for i in range(4)], lambda ch, remote: ch, 2, None,
                                  on_part)
    assert parts == [] and failed == {} and alive == [0, 0, 0, 0]


def test_a_bad_chunk_size_clears_nothing(short_pdf, tmp_path, capsys):
    assert run(short_pdf, tmp_path / "out", "--chunk-runs", "3") == 0
    with pytest.raises(SystemExit) as exc:             # a usage error, from the command line parser
        run(short_pdf, tmp_path / "out", "--chunk-runs", "0")
    assert exc.value.code == 2
    assert "--chunk-runs: 0 is below 1" in capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "out" / "chunks").glob("chunk_*")) == ["chunk_0-2.npz", "chunk_3-5.npz"]


def test_resume_rescores_with_other_metric_settings_without_running_again(short_pdf, tmp_path, monkeypatch):
    """The chunks do not depend on the ``metrics`` block: a resume with another settling time runs
    nothing and scores the stored runs anew."""
    import navsim.experiment.runner
    assert run(short_pdf, tmp_path / "out", "--chunk-runs", "3") == 0
    before = json.loads((tmp_path / "out" / "metrics.json").read_text())["estimators"]["KF"]
    calls = []
    monkeypatch.setattr(navsim.experiment.runner, "_chunk", lambda args: calls.append(args))
    rescored = short_pdf.with_name("rescored.yaml")
    rescored.write_text(short_pdf.read_text().replace("settle_s: 10", "settle_s: 20"))
    assert run(rescored, tmp_path / "out", "--resume") == 0
    after = json.loads((tmp_path / "out" / "metrics.json").read_text())["estimators"]["KF"]
    assert calls == [] and after["settle_s"] == 20 and before["settle_s"] == 10
    assert after["rms"] != before["rms"] and after["final"] == before["final"]
