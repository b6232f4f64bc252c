"""The API's arguments and the result files it reads: every argument the command line refuses is
refused by the API with navsim's error (naming the argument, what was expected), from one
declaration each; a damaged ``metrics.json``, ``samples.npz`` or ``run.json`` is named with its
key; a seeded property-based pass over ``run``, ``budget``, ``compare`` and ``open_result`` ends
in a result or a :class:`~navsim.foundations.errors.NavsimError`, never another exception."""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, event, given, settings, strategies as st
from hypothesis.configuration import set_hypothesis_home_dir
from test_api import without_cost

import navsim
from navsim.cli import main
from navsim.experiment.scenario import MAX_SEED, MAX_WORKERS
from navsim.foundations.config import MAX_RUNS
from navsim.foundations.errors import NavsimError, UsageError
from navsim.records.samples import SAMPLES_FILE
from navsim.version import __version__

set_hypothesis_home_dir(Path(tempfile.gettempdir()) / "navsim-hypothesis")   # never .hypothesis/ in the checkout

#: a scenario of 4 s of flight, two estimators (so that one result compares with itself)
TINY = {
    "name": "tiny",
    "track": {"start": {"lat_deg": 37.0, "lon_deg": 118.0, "alt_m": 300, "speed_mps": 14, "heading_deg": 30},
              "segments": [{"type": "straight", "time_s": 4}]},
    "sensors": {"imu": {"model": "p3_imu"}, "gps": {"model": "p3_gps"}},
    "estimators": [{"label": "free SINS", "type": "sins"},
                   {"label": "KF", "type": "eskf", "states": "p3_15", "noise": {"imu": "p3_imu"},
                    "measurements": [{"type": "gnss_position", "sensor": "gps", "sigma_m": [2, 2, 1]}]}],
    "initial_errors": {"pos_m": [5, 5, 3], "vel_mps": [0.2, 0.2, 0.1], "att_arcsec": 60},
    "montecarlo": {"runs": 3, "seed": 4},
    "metrics": {"settle_s": 1},
}
PAIR = ("free SINS", "KF")
#: seeded, no example database (nothing written into the checkout)
SETTINGS = dict(derandomize=True, deadline=None, database=None, phases=(Phase.explicit, Phase.generate),
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny scenario (its flight cached in a folder of this module's) and a result of it
    written to a folder (3 runs)."""
    root = tmp_path_factory.mktemp("api_arguments")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NAVSIM_CACHE", str(root / "cache"))
        scenario = navsim.load_scenario(TINY)
        navsim.run(scenario, out=root / "result", workers=1)
        yield scenario, root / "result"


def _copy(result: Path, tmp_path: Path) -> Path:
    out = tmp_path / "copy"
    shutil.copytree(result, out)
    return out


# --- the API refuses what the command line refuses -------------------------------------------------

#: (keyword, value, the command line's option or None, its text, words of the message)
REFUSED = [
    ("seed", -1, "--seed", "-1", ["seed", "below 0"]),
    ("seed", 1.5, "--seed", "1.5", ["seed", "not an integer"]),
    ("seed", "1", None, None, ["seed", "not an integer"]),
    ("seed", 2**70, "--seed", str(2**70), ["seed", f"above {MAX_SEED}"]),
    ("runs", True, None, None, ["runs", "not an integer"]),
    ("runs", 2.5, "--runs", "2.5", ["runs", "not an integer"]),
    ("runs", 0, "--runs", "0", ["runs", "below 1"]),
    ("runs", MAX_RUNS + 1, "--runs", str(MAX_RUNS + 1), ["runs", f"above {MAX_RUNS}"]),
    ("workers", 0, "--workers", "0", ["workers", "below 1"]),
    ("workers", MAX_WORKERS + 1, "--workers", str(MAX_WORKERS + 1), ["workers", f"above {MAX_WORKERS}"]),
    ("workers", math.nan, "--workers", "nan", ["workers", "not an integer"]),
    ("chunk_runs", 0, "--chunk-runs", "0", ["chunk_runs", "below 1"]),
    ("executor", "slurm", None, None, ["executor", "local, dask"]),
    ("scheduler", "not a url", "--scheduler", "not a url", ["scheduler", "scheme://host:port"]),
    ("resume", "yes", None, None, ["resume", "true or false"]),
    ("progress", 5, None, None, ["progress", "callable"]),
    ("out", 5, None, None, ["out", "folder"]),
    ("out", "", None, None, ["out", "folder"]),
]


@pytest.mark.parametrize("key, value, option, text, words", REFUSED, ids=[f"{r[0]}={r[1]!r}"[:40] for r in REFUSED])
def test_run_refuses_what_the_command_line_refuses(tiny, tmp_path, capsys, key, value, option, text, words):
    scenario, _ = tiny
    with pytest.raises(UsageError) as exc:
        navsim.run(scenario, **{"runs": 2, "workers": 1, key: value})
    message = str(exc.value)
    assert all(w in message for w in words), message
    assert "expected" in message, message
    if option is not None:                  # the same check, the same words, on the command line
        path = tmp_path / "tiny.yaml"
        path.write_text(json.dumps(TINY))
        with pytest.raises(SystemExit) as code:
            main(["run", str(path), "--out", str(tmp_path / "out"), option, text])
        err = capsys.readouterr().err
        assert code.value.code == 2 and option in err, err
        assert message[message.index("(expected"):] in err, (message, err)     # one declaration
    assert not (tmp_path / "out").exists()


def test_numpy_integers_and_the_limits_themselves_are_taken(tiny):
    scenario, _ = tiny
    res = navsim.run(scenario, runs=np.int64(2), seed=MAX_SEED, workers=np.int32(1), chunk_runs=1)
    assert len(res.runs) == 2 and not res.failed and res.record.seed == MAX_SEED


def test_options_as_one_object_give_the_keywords_numbers(tiny):
    """``options=RunOptions(...)`` is the keywords' run, bit for bit; a keyword given beside it
    replaces its field, one of None leaves it; a wrong object or an unknown option is refused."""
    scenario, _ = tiny
    by_keywords = navsim.run(scenario, runs=2, seed=5, workers=1, chunk_runs=1)
    by_object = navsim.run(scenario, options=navsim.RunOptions(runs=3, seed=5, workers=1, chunk_runs=1),
                           runs=2, chunk_runs=None)
    assert by_object.record.chunk_runs == 1 and len(by_object.runs) == 2
    a, b = by_object.to_dict(), by_keywords.to_dict()
    top = lambda m: {k: v for k, v in m.items() if k not in ("estimators", "wall_s")}
    assert json.dumps(without_cost(a)) == json.dumps(without_cost(b)) and top(a) == top(b)
    with pytest.raises(UsageError, match="options: 'fast' is not a RunOptions"):
        navsim.run(scenario, options="fast")
    with pytest.raises(UsageError, match="chunk: not an option of a run .*chunk_runs"):
        navsim.run(scenario, chunk=2)
    with pytest.raises(UsageError, match="seed: -1 is below 0"):
        navsim.run(scenario, options=navsim.RunOptions(seed=-1))


@pytest.mark.parametrize("call, words", [
    (lambda sc, res: navsim.budget(sc, runs=-2), ["runs", "below 1"]),
    (lambda sc, res: navsim.budget(sc, seed="7"), ["seed", "not an integer"]),
    (lambda sc, res: navsim.budget(sc, scales=[("imu.gyro.noise_density", 1e308)]), ["scales", "1e+308", "at most"]),
    (lambda sc, res: navsim.budget(sc, scales=[("imu.gyro.noise_density", -1)]), ["scales", "-1", ">= 0"]),
    (lambda sc, res: navsim.budget(sc, scales="imu=2"), ["scales", "(source, factor)"]),
    (lambda sc, res: navsim.budget(sc, resume=1), ["resume", "true or false"]),
    (lambda sc, res: navsim.budget(sc, executor=None), ["executor", "local, dask"]),
    (lambda sc, res: navsim.sweep("nothing.yaml", workers=0), ["workers", "below 1"]),
    (lambda sc, res: navsim.sweep(None), ["path", "sweep file"]),
    (lambda sc, res: navsim.compare(res, res, estimators=["a", "b", "c"]), ["estimators", "one or two"]),
    (lambda sc, res: navsim.compare(res, res, estimators=[1, 2]), ["estimators", "labels"]),
    (lambda sc, res: navsim.compare(res, 42), ["b", "result folder"]),
    (lambda sc, res: navsim.compare(res, res, partial="no"), ["partial", "true or false"]),
    (lambda sc, res: navsim.open_result(3.5), ["folder", "result folder"]),
    (lambda sc, res: navsim.open_result("a\0b"), ["folder", "NUL"]),
    (lambda sc, res: navsim.write_report("report", "out"), ["result", "Result"]),
    (lambda sc, res: navsim.load_scenario(12), ["scenario", "path"]),
], ids=["budget-runs", "budget-seed", "budget-scale-huge", "budget-scale-negative", "budget-scales-text",
        "budget-resume", "budget-executor", "sweep-workers", "sweep-path", "compare-3-labels",
        "compare-numbers", "compare-b", "compare-partial", "open-number", "open-nul", "report-result",
        "load-number"])
def test_the_other_calls_refuse_their_arguments(tiny, call, words):
    scenario, folder = tiny
    with pytest.raises(UsageError) as exc:
        call(scenario, folder)
    assert all(w in str(exc.value) for w in words), str(exc.value)


def test_a_string_of_estimators_is_one_label(tiny):
    _, folder = tiny
    out = navsim.compare(folder, folder, estimators="KF")
    assert [(c.a.estimator, c.b.estimator) for c in out] == [("KF", "KF")]


# --- the files a result is read from ---------------------------------------------------------------

def test_a_result_without_its_per_run_data_says_so(tiny, tmp_path):
    _, folder = tiny
    cut = _copy(folder, tmp_path)
    shutil.rmtree(cut / "chunks")
    res = navsim.open_result(cut)                    # the metrics still read
    assert set(res.metrics.estimators) == set(PAIR)
    with pytest.raises(UsageError) as exc:
        res.to_xarray()
    assert str(cut) in str(exc.value) and "chunks/" in str(exc.value)
    with pytest.raises(UsageError) as exc:
        navsim.open_result(folder).to_xarray(label="UKF")
    assert "'UKF'" in str(exc.value) and "KF" in str(exc.value)


@pytest.mark.parametrize("edit, words", [
    (lambda m: m["estimators"]["KF"]["rms"].update(pos_m=["x", "y", "z"]), ["estimators.KF.rms.pos_m[0]", "number"]),
    (lambda m: m["estimators"]["KF"]["rms"].update(pos_m=[1.0, 2.0]), ["estimators.KF.rms.pos_m", "3 numbers"]),
    (lambda m: m["estimators"]["KF"].pop("runs_counted"), ["estimators.KF", "runs_counted", "missing"]),
    (lambda m: m["estimators"].update(KF=[1, 2]), ["estimators.KF", "a mapping"]),
    (lambda m: m.update(runs="many"), ["runs", "an integer"]),
    (lambda m: m.update(interrupted=0), ["interrupted", "true or false"]),
    (lambda m: m["estimators"]["KF"]["nees"].update(average=None), []),    # null: NaN, as JSON writes it
], ids=["strings", "short", "missing", "list", "runs", "bool", "null"])
def test_a_damaged_metrics_json_names_the_file_and_the_key(tiny, tmp_path, edit, words):
    _, folder = tiny
    cut = _copy(folder, tmp_path)
    metrics = json.loads((cut / "metrics.json").read_text())
    edit(metrics)
    (cut / "metrics.json").write_text(json.dumps(metrics))
    if not words:
        navsim.open_result(cut).to_xarray()
        return
    for call in (navsim.open_result, lambda f: navsim.compare(f, estimators=PAIR)):
        with pytest.raises(UsageError) as exc:
            call(cut)
        message = str(exc.value)
        assert str(cut / "metrics.json") in message and all(w in message for w in words), message
        assert "__init__" not in message, message


def _truncate_one_array(path: Path) -> str:
    """``path`` (an npz) with its first ``.s`` array cut to its first row; the array's name."""
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    name = next(k for k in arrays if k.endswith(".s") and len(arrays[k]) > 1)
    arrays[name] = arrays[name][:1]
    np.savez(path, **arrays)
    return name


def test_a_damaged_samples_npz_is_named_without_numpy_advice(tiny, tmp_path, capsys):
    _, folder = tiny
    cut = _copy(folder, tmp_path)
    name = _truncate_one_array(cut / SAMPLES_FILE)
    assert main(["compare", str(cut), "--estimators", *PAIR, "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert f"{cut / SAMPLES_FILE}" in err and name.removesuffix(".s") in err and "Traceback" not in err, err
    rng = np.random.default_rng(5)
    for junk in (rng.bytes(4096), b"PK\x03\x04" + rng.bytes(500), (folder / SAMPLES_FILE).read_bytes()[:700]):
        (cut / SAMPLES_FILE).write_bytes(junk)
        with pytest.raises(UsageError) as exc:
            navsim.compare(cut, estimators=PAIR)
        message = str(exc.value)
        assert f"{cut / SAMPLES_FILE}" in message and "damaged" in message, message
        assert "pickle" not in message.lower(), message
    assert not (tmp_path / "c").exists()


def test_a_result_of_a_newer_navsim_is_refused(tiny, tmp_path):
    _, folder = tiny
    cut = _copy(folder, tmp_path)
    record = json.loads((cut / "run.json").read_text())
    (cut / "run.json").write_text(json.dumps({**record, "versions": {**record["versions"], "navsim": "9.9.9"}}))
    with pytest.raises(UsageError) as exc:
        navsim.compare(folder, cut)
    assert "9.9.9" in str(exc.value) and __version__ in str(exc.value)


# --- the property-based pass -------------------------------------------------------------------------

def _hostile():
    """Values no argument takes, and a few that some do."""
    return st.sampled_from([None, 0, -1, 1, 2, 2.5, math.nan, math.inf, -math.inf, True, False, "1", "", "x",
                            2**64, -(2**64), 2**70, [], [1, 2], {"a": 1}, b"1",
                            np.int64(2), np.float64(2.0), object()])


def _check(call) -> None:
    """``call()`` ends in a result or a NavsimError with a message (the outcome counted in the
    statistics: ``--hypothesis-show-statistics``)."""
    try:
        call()
        event("a result")
    except NavsimError as exc:
        assert str(exc) and "Traceback" not in str(exc)
        event(f"{type(exc).__name__}: {str(exc).split(':')[0][:20]}")


def _with(valid: dict, bad: str | None, value) -> dict:
    """``valid`` with the argument ``bad`` (None: none) set to ``value``."""
    return valid if bad is None else {**valid, bad: value}


@settings(max_examples=40, **SETTINGS)
@given(bad=st.sampled_from([None, "runs", "seed", "workers", "chunk_runs", "executor", "progress"]), value=_hostile(),
       runs=st.integers(1, 3), seed=st.integers(0, MAX_SEED), chunk_runs=st.one_of(st.none(), st.integers(1, 3)))
def test_run_ends_in_a_result_or_a_navsim_error(tiny, bad, value, runs, seed, chunk_runs):
    scenario, _ = tiny
    if bad == "workers" and isinstance(value, (int, np.integer)) and value > 1:
        value = 1                                        # no pool of processes for a test
    args = _with(dict(runs=runs, seed=seed, workers=1, chunk_runs=chunk_runs), bad, value)
    _check(lambda: navsim.run(scenario, **args))


@settings(max_examples=25, **SETTINGS)
@given(bad=st.sampled_from([None, "runs", "seed", "scales", "method", "group", "resume"]), value=_hostile(),
       seed=st.integers(0, MAX_SEED), source=st.sampled_from(["imu.gyro.noise_density", "gps.position_sigma", "x"]),
       factor=st.one_of(st.floats(0, 3), st.floats(allow_nan=True, allow_infinity=True)), scaled=st.booleans())
def test_budget_ends_in_a_result_or_a_navsim_error(tiny, bad, value, seed, source, factor, scaled):
    scenario, _ = tiny
    valid = dict(runs=2, seed=seed, workers=1, scales=[(source, factor)] if scaled else (), method="covariance")
    _check(lambda: navsim.budget(scenario, **_with(valid, bad, value)))


@settings(max_examples=30, **SETTINGS)
@given(bad=st.sampled_from([None, "a", "b", "estimators", "partial", "unpaired"]), value=_hostile(),
       a=st.sampled_from(["folder", "result", "folder", "result", "missing", "file"]), b=st.sampled_from([None, "folder", "result"]),
       estimators=st.sampled_from([None, "KF", PAIR, ["KF"], ["UKF"], ("KF", "KF")]), partial=st.booleans())
def test_compare_ends_in_a_result_or_a_navsim_error(tiny, tmp_path, bad, value, a, b, estimators, partial):
    _, folder = tiny
    (tmp_path / "file").write_text("x")
    held = {"folder": folder, "result": navsim.open_result(folder), "missing": tmp_path / "nothing",
            "file": tmp_path / "file", None: None}
    args = _with(dict(a=held[a], b=held[b], estimators=estimators, partial=partial), bad, value)
    _check(lambda: navsim.compare(**args))


#: the files of a result and the damage done to one
FILES = ["metrics.json", "run.json", "scenario.resolved.yaml", SAMPLES_FILE, "chunks/index.json"]


def _damage(path: Path, how: str, value) -> None:
    """``path`` removed, truncated, replaced by bytes, or (JSON) one of its values replaced."""
    if how == "remove":
        path.unlink()
    elif how == "truncate":
        path.write_bytes(path.read_bytes()[: len(path.read_bytes()) // 3])
    elif how == "bytes":
        path.write_bytes(bytes(range(256)))
    elif path.suffix == ".json":
        data = json.loads(path.read_text())
        node, keys = data, []
        while isinstance(node, dict) and node:         # the first key down to a leaf
            keys.append(next(iter(node)) if how == "first" else list(node)[-1])
            parent, node = node, node[keys[-1]]
        parent[keys[-1]] = value
        path.write_text(json.dumps(data))


@settings(max_examples=40, **SETTINGS)
@given(file=st.sampled_from(FILES), how=st.sampled_from(["remove", "truncate", "bytes", "first", "last"]),
       value=st.sampled_from([None, "x", -1, 1.5, [], {}, [1, "a"], True, 10**30]))
def test_open_result_of_a_damaged_folder_ends_in_a_result_or_a_navsim_error(tiny, file, how, value):
    _, folder = tiny
    with tempfile.TemporaryDirectory() as tmp:
        cut = Path(tmp) / "r"
        shutil.copytree(folder, cut)
        _damage(cut / file, how, value)

        def read():
            res = navsim.open_result(cut)
            res.to_xarray()
            navsim.compare(res, estimators=PAIR)
        _check(read)
