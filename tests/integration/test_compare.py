"""navsim compare on real results: a filter change found run by run, the same sensor data paired
exactly, two seeds unpaired, two estimators of one result, and the inputs it refuses (exit 2,
one message, nothing written)."""

import csv
import json
import shutil

import pytest

import navsim
from navsim.cli import main, parse_margins
from navsim.records.samples import EstimatorSamples, MetricSamples, load_samples, save_samples

ESKF = "BD/SINS/ADS ES-KF 16"
RUNS = 12


@pytest.fixture(scope="module")
def results(repo_root, tmp_path_factory):
    """P0's ES-KF (seed 1 and 2), the same filter with its BD sigma x1.1, and the same filter
    alone in a scenario of its own (the same sensor data), 12 runs each."""
    root = tmp_path_factory.mktemp("compare")
    base = repo_root / "scenarios" / "p0_bd_sins_ads.yaml"
    wider = repo_root / "examples" / "compare" / "p0_gnss_sigma_x1.1.yaml"
    alone = root / "alone.yaml"
    alone.write_text(wider.read_text().replace("sigma_m: [8.8, 8.8, 8.8]", "sigma_m: [8, 8, 8]"))
    out = {}
    for key, scenario, seed in (("a", base, 1), ("b", wider, 1), ("same", alone, 1), ("seed2", base, 2)):
        out[key] = root / key
        navsim.run(scenario, RUNS, seed, 1, out=out[key])     # the run's files, no report
    return out


def test_a_wider_gnss_sigma_is_found_run_by_run(results, tmp_path, capsys):
    capsys.readouterr()
    assert main(["compare", str(results["a"]), str(results["b"]), "--out", str(tmp_path / "c")]) == 0
    text = capsys.readouterr().out
    assert "paired run by run" in text
    [c] = json.loads((tmp_path / "c" / "compare.json").read_text())["comparisons"]
    rows = {(r["metric"], r["component"]): r for r in c["differences"]}
    nees = rows[("nees.average", "")]
    # a sigma the filter thinks 10 % larger: its NEES falls (by about 10 % at 50 runs)
    assert nees["verdict"] == "lower" and nees["ci95"][1] < 0
    metrics_a = json.loads((results["a"] / "metrics.json").read_text())["estimators"][ESKF]
    assert rows[("rms.pos_m", "N")]["a"] == pytest.approx(metrics_a["rms"]["pos_m"][0], rel=1e-9)
    with open(tmp_path / "c" / "compare.csv") as f:
        assert len(list(csv.DictReader(f))) == len(c["differences"])
    assert (tmp_path / "c" / "compare.pdf").stat().st_size > 0 and (tmp_path / "c" / "compare.png").stat().st_size > 0
    # the unpaired comparison of the same data cannot see it at these runs
    [u] = navsim.compare(results["a"], results["b"], unpaired=True)
    un = next(d for d in u.differences if d.metric == "nees.average")
    assert un.verdict == "no significant difference" and un.runs_needed > RUNS
    assert un.ci95[1] - un.ci95[0] > 3 * (nees["ci95"][1] - nees["ci95"][0])


def test_the_same_sensor_data_pairs_exactly_and_two_seeds_do_not(results):
    [c] = navsim.compare(results["a"], results["same"])
    assert c.paired and c.runs_compared == RUNS
    assert all(d.diff == 0 and d.verdict == "negligible" for d in c.differences)     # within any margin
    by_label = {c.a.estimator: c for c in navsim.compare(results["a"], results["seed2"])}
    c = by_label[ESKF]
    assert not c.paired and "montecarlo" in c.pairing
    assert all(d.verdict in ("no significant difference", "negligible") for d in c.differences), c.summary()


def test_results_at_hand_compare_as_their_folders(results):
    """A :class:`navsim.Result` (read back, or run in memory) against a folder: the same pairing."""
    [c] = navsim.compare(navsim.open_result(results["a"]), results["same"])
    assert c.paired and all(d.diff == 0 for d in c.differences)
    held = navsim.run(results["same"] / "scenario.resolved.yaml", RUNS, 1, 1)   # in memory
    [c] = navsim.compare(results["b"], held)
    assert c.paired and c.runs_compared == RUNS and any(d.verdict == "higher" for d in c.differences)


def test_two_estimators_of_one_result(results):
    [c] = navsim.compare(results["a"], estimators=["free SINS", ESKF])
    assert c.paired and c.a.estimator == "free SINS"
    pos = [d for d in c.differences if d.metric == "rms.pos_m"]
    assert pos and all(d.verdict == "better" for d in pos)


def _refused(capsys, argv, out) -> str:
    capsys.readouterr()
    assert main(argv + ["--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "\n" not in err and "Traceback" not in err
    assert not out.exists()
    return err


def test_hostile_inputs_are_refused_with_nothing_written(results, repo_root, shipped_flight, tmp_path, capsys):
    out = tmp_path / "never"
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "notes.txt").write_text("not a result")
    assert "not a navsim result" in _refused(capsys, ["compare", str(junk), str(results["a"])], out)
    # an interrupted result: refused, compared with --partial
    cut = tmp_path / "cut"
    shutil.copytree(results["b"], cut)
    record = json.loads((cut / "run.json").read_text())
    (cut / "run.json").write_text(json.dumps({**record, "interrupted": True, "runs": 50}))
    err = _refused(capsys, ["compare", str(results["a"]), str(cut)], out)
    assert "interrupted after 12 of 50 runs" in err and "--partial" in err
    assert main(["compare", str(results["a"]), str(cut), "--partial", "--out", str(tmp_path / "p")]) == 0
    assert "(12 runs, interrupted)" in capsys.readouterr().out
    # a result of an older navsim (no per-run samples)
    old = tmp_path / "old"
    shutil.copytree(results["a"], old)
    (old / "samples.npz").unlink()
    (old / "run.json").write_text(json.dumps({**record, "versions": {**record["versions"], "navsim": "0.1.0"}}))
    assert "written by navsim 0.1.0" in _refused(capsys, ["compare", str(old), str(results["a"])], out)
    # another track
    other = tmp_path / "p3"
    shipped_flight("p3_sins_gps")                    # its flight from the session's cache
    navsim.run(repo_root / "scenarios" / "p3_sins_gps.yaml", 2, workers=1, out=other)
    assert "track" in _refused(capsys, ["compare", str(results["a"]), str(other)], out)
    # the output folder on (or inside) a result compared: refused, the result untouched
    before = sorted(p.name for p in results["a"].iterdir())
    capsys.readouterr()
    assert main(["compare", str(results["a"]), str(results["b"]), "--out", str(results["a"])]) == 2
    assert "--out" in capsys.readouterr().err and sorted(p.name for p in results["a"].iterdir()) == before
    # a side with fewer than two counted runs
    one = tmp_path / "one"
    shutil.copytree(results["b"], one)
    samples = load_samples(one / "samples.npz")
    save_samples(one / "samples.npz", {k: EstimatorSamples(v.runs[:1], {p: MetricSamples(m.s[:1], m.n[:1], m.root)
                                                                        for p, m in v.metrics.items()})
                                       for k, v in samples.items()})
    assert "at least 2 needed" in _refused(capsys, ["compare", str(results["a"]), str(one)], out)
    # one result without two estimators named, an unknown estimator
    assert "--estimators" in _refused(capsys, ["compare", str(results["a"])], out)
    assert "no estimator 'UKF'" in _refused(capsys, ["compare", str(results["a"]), "--estimators", "UKF", ESKF], out)


def test_the_margin_on_the_command_line(results, tmp_path, capsys):
    assert parse_margins(None) == 1.0 and parse_margins(["2"]) == 2.0
    assert parse_margins(["rms.pos_m=5", "0.5"]) == {"rms.pos_m": 5.0, "": 0.5}
    for bad, said in ((["x"], "--margin 'x'"), (["rms.pos_m=-1"], "--margin['rms.pos_m']"), (["500"], "--margin: is 500"),
                      (["rms.pos=5"], "did you mean 'rms.pos_m'")):
        assert main(["compare", str(results["a"]), str(results["same"]), "--margin", *bad,
                     "--out", str(tmp_path / "no")]) == 2
        assert said in capsys.readouterr().err and not (tmp_path / "no").exists()
    assert main(["compare", str(results["a"]), str(results["same"]), "--margin", "rms=0",
                 "--out", str(tmp_path / "c")]) == 0
    rows = json.loads((tmp_path / "c" / "compare.json").read_text())["comparisons"][0]["differences"]
    assert {r["verdict"] for r in rows if r["metric"].startswith("rms.")} == {"no significant difference"}
    assert {r["verdict"] for r in rows if not r["metric"].startswith("rms.")} == {"negligible"}
