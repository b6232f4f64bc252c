"""Per-run data that can be trusted: chunks checked against their index and their name, no
deletion through a link, a checked flight cache, estimator labels that never share a key in
``runs.npz``, and compile time kept out of the per-run cost (issue 31)."""

import json
import os
import shutil
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import navsim
from navsim import api
from navsim.cli import main
from navsim.experiment import runner
from navsim.experiment.chunkstore import ChunkStore, ResumeError
from navsim.flight.truth import Pose, Truth
from navsim.foundations.errors import UsageError
from navsim.foundations.outputs import OutputFolder
from navsim.records import cost as run_cost
from navsim.records.chunk import ChunkPart
from navsim.records.history import EstimatorHistory

TINY = """
name: tiny
track:
  start: {lat_deg: 37.0, lon_deg: 118.0, alt_m: 300, speed_mps: 14, heading_deg: 30}
  segments:
    - {type: straight, time_s: 6}
sensors:
  imu: {model: p3_imu}
  gps: {model: p3_gps}
estimators:
  - {label: free SINS, type: sins}
  - label: KF
    type: eskf
    states: p3_15
    noise: {imu: p3_imu}
    measurements:
      - {type: gnss_position, sensor: gps, sigma_m: [2, 2, 1]}
initial_errors: {pos_m: [5, 5, 3], vel_mps: [0.2, 0.2, 0.1], att_arcsec: 60}
montecarlo: {runs: 4, seed: 4, workers: 1}
metrics: {settle_s: 1}
report: {formats: [pdf]}
"""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """``(scenario path, a finished run's folder)``: 4 runs of 6 s in chunks of 2 (seed 4),
    flown into a cache of this module's."""
    root = tmp_path_factory.mktemp("integrity")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NAVSIM_CACHE", str(root / "cache"))
        path = root / "tiny.yaml"
        path.write_text(TINY)
        navsim.run(path, out=root / "base", chunk_runs=2)
        yield path, root / "base"


@pytest.fixture
def copy_of(tiny, tmp_path, monkeypatch):
    """``copy_of(name)``: a copy of the finished run in ``tmp_path/name``."""
    monkeypatch.setenv("NAVSIM_CACHE", str(tiny[1].parent / "cache"))

    def make(name):
        shutil.copytree(tiny[1], tmp_path / name, symlinks=True)
        return tmp_path / name
    return make


def resume(path, out, **kw):
    return navsim.run(path, out=out, resume=True, **kw)


# --- 1. chunks checked against their index and their name -------------------------------------

def test_a_chunk_of_another_seed_is_refused_on_resume_and_open(tiny, copy_of, tmp_path):
    path, _ = tiny
    out, other = copy_of("out"), tmp_path / "seed5"
    navsim.run(path, out=other, seed=5, chunk_runs=2)
    shutil.copy(other / "chunks" / "chunk_2-3.npz", out / "chunks" / "chunk_2-3.npz")
    with pytest.raises(ResumeError, match=r"chunk_2-3\.npz: belongs to another run \(seed 5 in the chunk, 4"):
        resume(path, out)
    with pytest.raises(UsageError, match=r"chunk_2-3\.npz: belongs to another run"):
        navsim.open_result(out)


def test_a_chunk_whose_runs_are_not_its_name_is_refused(tiny, copy_of):
    path, _ = tiny
    out = copy_of("out")
    shutil.copy(out / "chunks" / "chunk_0-1.npz", out / "chunks" / "chunk_2-3.npz")
    with pytest.raises(ResumeError, match=r"chunk_2-3\.npz: holds runs 0-1 but its name says 2-3"):
        resume(path, out)
    with pytest.raises(ResumeError, match="holds runs 0-1"):
        list(ChunkStore.open(out / "chunks").parts())


def test_an_index_listing_more_runs_than_the_job_is_refused(tiny, copy_of):
    path, _ = tiny
    out = copy_of("out")
    index = json.loads((out / "chunks" / "index.json").read_text())
    index["chunks"]["4-5"] = "chunk_4-5.npz"
    (out / "chunks" / "index.json").write_text(json.dumps(index))
    shutil.copy(out / "chunks" / "chunk_2-3.npz", out / "chunks" / "chunk_4-5.npz")
    with pytest.raises(ResumeError, match=r"lists chunk 4-5, which is not a chunk of this run \(4 runs in chunks of 2"):
        resume(path, out)
    with pytest.raises(UsageError, match="lists chunk 4-5"):
        navsim.open_result(out)


def test_a_chunk_of_another_scenario_with_other_epochs_is_refused_cleanly(tiny, copy_of, tmp_path, capsys):
    """The hostile pass's case: today a traceback from ChunkStore.merged."""
    path, _ = tiny
    out = copy_of("out")
    other = tmp_path / "other.yaml"
    other.write_text(TINY.replace("type: eskf", "type: eskf\n    period_s: 0.5"))
    navsim.run(other, out=tmp_path / "other", chunk_runs=2)
    shutil.copy(tmp_path / "other" / "chunks" / "chunk_2-3.npz", out / "chunks" / "chunk_2-3.npz")
    assert main(["run", str(path), "--out", str(out), "--resume"]) == 2
    err = capsys.readouterr().err
    assert "chunk_2-3.npz: belongs to another run (scenario_hash" in err and "Traceback" not in err


def synthetic(runs, epochs, seed=1):
    """A chunk part of one estimator over ``runs`` with ``epochs`` epochs."""
    rng = np.random.default_rng(seed)
    B = len(runs)
    h = EstimatorHistory(
        label="KF", t_s=np.arange(float(epochs)), att_err_rad=rng.normal(size=(B, epochs, 3)),
        vel_err_mps=rng.normal(size=(B, epochs, 3)), pos_err_m=rng.normal(size=(B, epochs, 3)), sigma=None,
        nees=None, nis={}, nis_dim={}, diverged=np.zeros(B, bool),
        cost={"propagate_s": 0.1, "epoch_s": 0.2, "runs": B, "epochs": epochs - 1, "batches": 1})
    return ChunkPart(list(runs), {"KF": h})


def test_a_chunk_with_another_epoch_count_is_refused_by_merged(tmp_path):
    store = ChunkStore(tmp_path, {"scenario_hash": "x", "seed": 1, "runs": 4, "chunk_runs": 2}, mode="new")
    store.add(synthetic([0, 1], 4))
    store.add(synthetic([2, 3], 5))
    with pytest.raises(ResumeError, match=r"chunk_2-3\.npz: .*differs from chunk_0-1\.npz"):
        store.merged()


@pytest.mark.parametrize("change, words", [
    (lambda i: i.update(chunk_runs="2"), "chunk_runs is '2' (expected a whole number 1-1000000)"),
    (lambda i: i.update(runs=10**12), "runs is 1000000000000"),
    (lambda i: i.update(chunk_runs=None), "chunk_runs is None"),
    (lambda i: i.update(chunk_runs=0), "chunk_runs is 0"),
    (lambda i: i.update(chunks=["chunk_0-1.npz"]), "chunks is ['chunk_0-1.npz'] (expected a mapping"),
    (lambda i: i.update(failed={"0-1": 3}), "failed is {'0-1': 3}"),
    (lambda i: i.update(seed=True), "seed is True"),
])
def test_an_index_of_wrong_types_is_refused_cleanly(tiny, copy_of, change, words):
    path, _ = tiny
    out = copy_of("out")
    index = json.loads((out / "chunks" / "index.json").read_text())
    change(index)
    (out / "chunks" / "index.json").write_text(json.dumps(index))
    with pytest.raises(UsageError) as exc:
        resume(path, out)
    assert "index.json" in str(exc.value) and words in str(exc.value), str(exc.value)


@pytest.mark.parametrize("name", ["5-3", "0-9999999999"])
def test_an_index_listing_an_impossible_chunk_is_refused_through_the_cli(tiny, copy_of, capsys, name):
    """A chunk name whose runs run backwards (an IndexError traceback in the resume count) or
    span ten billion runs (a list of every run: MemoryError) is no chunk of the run: exit 2."""
    path, _ = tiny
    out = copy_of("out")
    index = json.loads((out / "chunks" / "index.json").read_text())
    index["chunks"][name] = f"chunk_{name}.npz"
    (out / "chunks" / "index.json").write_text(json.dumps(index))
    code = main(["run", str(path), "--out", str(out), "--resume"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err


def test_an_index_that_is_not_a_mapping_is_refused(tiny, copy_of):
    path, _ = tiny
    out = copy_of("out")
    (out / "chunks" / "index.json").write_text("[1, 2]")
    with pytest.raises(ResumeError, match="not a chunk index"):
        resume(path, out)


# --- 2. never delete through a link --------------------------------------------------------------

def snapshot(folder):
    return {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(folder.iterdir())}


def test_a_chunks_folder_linked_to_another_run_is_refused_and_that_run_kept(tiny, copy_of):
    path, _ = tiny
    victim, attacker = copy_of("victim"), copy_of("attacker")
    before = snapshot(victim / "chunks")
    shutil.rmtree(attacker / "chunks")
    (attacker / "chunks").symlink_to(victim / "chunks")
    with pytest.raises(UsageError, match=r"chunks: is a symbolic link"):
        navsim.run(path, out=attacker, chunk_runs=2)
    with pytest.raises(UsageError, match="is a symbolic link"):
        ChunkStore(attacker / "chunks", {"seed": 4}, mode="new")
    assert snapshot(victim / "chunks") == before


def test_chunk_files_that_are_links_are_refused_and_their_targets_kept(tiny, copy_of):
    path, _ = tiny
    victim, attacker = copy_of("victim"), copy_of("attacker")
    before = snapshot(victim / "chunks")
    (attacker / "chunks" / "chunk_0-1.npz").unlink()
    (attacker / "chunks" / "chunk_0-1.npz").symlink_to(victim / "chunks" / "chunk_0-1.npz")
    with pytest.raises(UsageError, match=r"chunk_0-1\.npz: is a symbolic link"):
        navsim.run(path, out=attacker, chunk_runs=2)
    assert snapshot(victim / "chunks") == before
    assert (attacker / "chunks" / "chunk_0-1.npz").is_symlink()          # nothing removed either


# --- 3. the flight cache -----------------------------------------------------------------------

@pytest.fixture
def flight_config(tiny, tmp_path, monkeypatch):
    """The tiny scenario's flight config, a fresh cache, and ``fly`` replaced by a counted
    static flight (``flown`` lists the calls)."""
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "cache"))
    flown = []

    def fly(config, progress=None):
        flown.append(config)
        time.sleep(0.2)                               # two threads overlap
        return Truth.static(2.0, rate_hz=50.0)
    monkeypatch.setattr(runner, "fly", fly)
    return navsim.load_scenario(tiny[0]).flight, flown


def test_a_truncated_cached_flight_is_flown_again_and_replaced(flight_config, caplog):
    config, flown = flight_config
    truth, path, cached = runner.cached_flight(config)
    assert not cached and len(flown) == 1
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2])
    again, path2, cached = runner.cached_flight(config)          # today: BadZipFile
    assert not cached and len(flown) == 2 and again == truth and path2 == path
    assert "unusable" in caplog.text
    assert runner.cached_flight(config)[2] is True and len(flown) == 2   # the bad file was replaced


def test_another_flight_under_the_key_is_not_used(flight_config):
    config, flown = flight_config
    truth, path, _ = runner.cached_flight(config)
    Truth.static(3.0, rate_hz=50.0, pose=Pose(yaw_deg=90)).save(path)        # a foreign flight, no key
    again, _, cached = runner.cached_flight(config)
    assert not cached and again == truth and len(flown) == 2
    other = Truth.static(3.0, rate_hz=50.0, pose=Pose(yaw_deg=90))
    other.save(path, key="0" * 20)                                # another flight's key
    assert runner.cached_flight(config)[2] is False and len(flown) == 3
    truth.save(path, key=runner.flight_key(config))               # the right key
    with np.load(path) as data:                                   # but contents altered
        entries = {k: data[k] for k in data.files}
    entries["h_m"] = entries["h_m"] + 1.0
    np.savez_compressed(path, **entries)
    assert runner.cached_flight(config)[2] is False and len(flown) == 4


def test_two_runs_flying_at_once_write_under_names_of_their_own(flight_config, monkeypatch):
    config, flown = flight_config
    names, real = [], Truth.save

    def save(self, path, *args, **kw):
        names.append(str(path))
        return real(self, path, *args, **kw)
    monkeypatch.setattr(Truth, "save", save)
    results = []
    threads = [threading.Thread(target=lambda: results.append(runner.cached_flight(config))) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(flown) == 2 and len(names) == 2 and len(set(names)) == 2, names
    assert all(r[0] == results[0][0] for r in results)
    assert runner.cached_flight(config)[2] is True
    assert [p.name for p in results[0][1].parent.iterdir()] == [results[0][1].name]   # no temporary left


def test_an_unusable_flight_cache_flies_without_caching(tiny, tmp_path, monkeypatch, caplog):
    """NAVSIM_CACHE through a file: the flight is flown (not cached, a warning) and the runs go
    to the workers with the flight itself, not a cache path (today: TypeError at None / ...)."""
    (tmp_path / "afile").write_text("")
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "afile" / "cache"))
    config = navsim.load_scenario(tiny[0]).flight
    truth, path, cached = runner.cached_flight(config)
    assert path is None and not cached and truth.n > 0 and "cache" in caplog.text
    res = navsim.run(tiny[0], runs=2, workers=2)
    assert len(res.runs) == 2 and not res.failed


# --- 4. estimator labels never share a key in runs.npz --------------------------------------------

def test_labels_a_space_b_and_a_underscore_b_keep_their_own_data(tiny, tmp_path, monkeypatch):
    monkeypatch.setenv("NAVSIM_CACHE", str(tiny[1].parent / "cache"))
    text = TINY.replace("label: free SINS", "label: a b").replace("label: KF", "label: a_b")
    (tmp_path / "ab.yaml").write_text(text)
    result = navsim.run(tmp_path / "ab.yaml", out=None)
    api.results.write_run(result, OutputFolder(tmp_path / "ab", command="run"))
    back = navsim.open_result(tmp_path / "ab")
    assert set(back.histories) == {"a b", "a_b"}
    for label in ("a b", "a_b"):
        assert np.array_equal(back.histories[label].pos_err_m, result.histories[label].pos_err_m), label
    assert not np.array_equal(back.histories["a b"].pos_err_m, back.histories["a_b"].pos_err_m)


def test_npz_keys_are_injective_and_older_files_still_read(tmp_path):
    labels = ["a b", "a_b", "a-b", "a/b", "a%20b", "a.b", "é", "BD/SINS/ADS ES-KF 16"]
    keys = [api.npz_key(label) for label in labels]
    assert len(set(keys)) == len(keys) and all("." not in k for k in keys)
    old = {"runs": np.arange(2), "BD-SINS-ADS_ES-KF_16.t_s": np.arange(3.0),        # before the keys
           "BD-SINS-ADS_ES-KF_16.pos_err_m": np.ones((2, 3, 3))}
    np.savez(tmp_path / "runs.npz", **old)
    runs, hist = api.results.npz_histories(tmp_path / "runs.npz", ["BD/SINS/ADS ES-KF 16"])
    assert list(runs) == [0, 1] and np.array_equal(hist["BD/SINS/ADS ES-KF 16"].pos_err_m, np.ones((2, 3, 3)))


# --- 5. compile time kept out of the per-run cost -----------------------------------------------

COSTS = """
import json, sys
import navsim
result = navsim.run(sys.argv[1], out=None)
print(json.dumps({k: m.cost.to_dict() for k, m in result.metrics.estimators.items()}))
"""


@pytest.mark.slow          # compiles every kernel of the two filters: ~40 s on two cores
def test_a_cold_kernel_cache_leaves_the_per_run_cost_alone(tiny, tmp_path):
    """The first report's cost column counted the kernels' compile time (ES-KF 155 ms/run
    against 11.8 warm): with an empty numba cache the per-run cost stays near the warm one and
    the compile time is reported apart."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"), NAVSIM_CACHE=str(tiny[1].parent / "cache"))

    def costs():
        out = subprocess.run([sys.executable, "-c", COSTS, str(tiny[0])], env=env, capture_output=True, text=True,
                             timeout=300, check=True).stdout
        return json.loads(out.strip().splitlines()[-1])
    cold, warm = costs(), costs()
    for label in ("free SINS", "KF"):
        c, w = cold[label], warm[label]
        assert c["ms_per_run"] < max(5 * w["ms_per_run"], w["ms_per_run"] + 100), (label, c, w)
        assert c["compile_s"] > 0.5 and c["compile_s"] > 5 * w["compile_s"], (label, c, w)


def test_compile_time_is_kept_apart_in_the_bookkeeping():
    import numba
    from navsim.report.summary import compile_note
    from navsim.scoring.scorer import cost_metrics

    @numba.njit
    def fresh(x):                       # compiled at its first call, in this test
        return np.sqrt(x * x + 1.0)
    k0, c0, t0 = run_cost.compile_seconds(), run_cost.compute_clock(), time.perf_counter()
    fresh(2.0)
    compiled, computed, wall = run_cost.compile_seconds() - k0, run_cost.compute_clock() - c0, time.perf_counter() - t0
    assert compiled > 0.01 and computed < 0.2 * wall, (compiled, computed, wall)
    one = {"propagate_s": 0.1, "epoch_s": 0.1, "runs": 2, "epochs": 5, "batches": 1, "compile_s": 3.0}
    total = run_cost.sum_cost([one, dict(one, compile_s=0.5)])
    assert total["compile_s"] == 3.5
    cost = cost_metrics(total)
    assert cost.ms_per_run == pytest.approx(100.0) and cost.compile_s == 3.5
    assert cost_metrics({k: v for k, v in one.items() if k != "compile_s"}).compile_s is None   # older chunks
    est = type("M", (), {"cost": cost})()
    metrics = type("R", (), {"estimators": {"KF": est}})()
    assert compile_note(metrics).endswith("KF 3.50 s.") and cost.to_dict()["compile_s"] == 3.5
