"""navsim budget on P0: every source's realisation alone is the one it has with all on (the
emulated errors add exactly), the budget of the ES-KF closes, and the inputs it refuses."""

import json

import numpy as np
import pytest
import yaml
from scipy.stats import norm

import navsim
from navsim.cli import main
from navsim.experiment.budget import alone, error_sources
from navsim.scoring.budget import DEFAULT_METRICS
from navsim.scoring.compare import columns, influence
from navsim.sensors import emulate

#: the outputs whose errors are sums of the sources' (the IMU's and the BD's; the ADS's raw
#: pressures and vanes): each source alone on adds to the others exactly
ADDITIVE = {"imu": ("dtheta_b_rad", "dv_b_mps"), "bd": ("lat_rad", "lon_rad", "h_m"),
            "ads": ("p_static_pa", "p_total_pa", "temp_k", "alpha_rad", "beta_rad")}


@pytest.fixture(scope="module")
def p0(repo_root):
    return navsim.load_scenario(repo_root / "scenarios" / "p0_matched_ads.yaml")


def test_each_source_alone_has_its_all_on_realisation(p0, shipped_flight):
    truth = shipped_flight("p0_matched_ads")[1]
    sources = error_sources(p0)
    none = alone(p0, None, sources)
    for j, c in enumerate(p0.sensors):
        full, base = emulate(truth, c, 5, [0, 3]), emulate(truth, none.sensors[j], 5, [0, 3])
        parts = [emulate(truth, alone(p0, s, sources).sensors[j], 5, [0, 3]) for s in sources if s.sensor == c.name]
        for key in ADDITIVE[c.name]:
            f, b = full.values[key], base.values[key]
            summed = b + sum(p.values[key] - b for p in parts)
            assert np.max(np.abs(f - summed)) <= 1e-9 * np.max(np.abs(f - b)), (c.name, key)


def test_a_budget_writes_its_tables_and_pages(p0, repo_root, tmp_path, capsys):
    out = tmp_path / "b"
    assert main(["budget", str(repo_root / "scenarios" / "p0_matched_ads.yaml"), "--runs", "2",
                 "--workers", "1", "--scale", "bd.position_sigma=0.5", "--group", "kind",
                 "--metric", "final.pos_m:horizontal",
                 "--out", str(out)]) == 0
    data = json.loads((out / "budget.json").read_text())
    assert data["sources"] == [s.name for s in error_sources(p0)] and data["group"] == "kind"
    m = next(x for x in data["metrics"] if x["estimator"] == "ES-KF 17, matched ADS"
             and (x["metric"], x["component"]) == ("final.pos_m", "horizontal"))
    assert {x["source"] for x in m["lines"]} == {"imu gyro", "imu accel", "bd", "ads", "initial errors"}
    assert abs(sum(x["share"] for x in m["lines"]) - 1) < 1e-9
    assert any(w["source"] == "bd.position_sigma" and w["factor"] == 0.5 for w in data["what_if"])
    assert (out / "budget.csv").read_text().count("\n") == 1 + sum(len(x["lines"]) for x in data["metrics"])
    assert (out / "budget.png").stat().st_size > 0 and (out / "budget.pdf").stat().st_size > 0
    captured = capsys.readouterr()
    assert "root-sum-square" in captured.out


def test_a_budgets_lines_have_intervals_and_two_runs_do_not_rank_them(repo_root, tmp_path, capsys, caplog):
    """Each line's contribution and share have a 95 % interval over the runs (in budget.json,
    budget.csv and the table); at 2 runs they overlap and the table's notes and the log say the
    runs are too few to rank the sources."""
    data = yaml.safe_load((repo_root / ".ci" / "wheel_check.yaml").read_text())     # 8 s of P0's flight
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(data))
    out = tmp_path / "b"
    assert main(["budget", str(path), "--runs", "2", "--workers", "1", "--metric", "final.pos_m:horizontal",
                 "--out", str(out)]) == 0
    captured = capsys.readouterr()
    data = json.loads((out / "budget.json").read_text())
    for m in data["metrics"]:
        for x in m["lines"]:
            lo, hi = x["contribution_ci95"]
            assert lo is None or lo <= x["contribution"] <= hi, x
            lo, hi = x["share_ci95"]
            assert lo is None or lo <= x["share"] <= hi, x
    shown = [m for m in data["metrics"] if (m["metric"], m["component"]) == ("final.pos_m", "horizontal")]
    assert shown and all(m["unranked"] for m in shown)
    assert any(x["contribution_ci95"][0] is not None for m in shown for x in m["lines"])
    rows = (out / "budget.csv").read_text().splitlines()
    assert rows[0].endswith("contribution_lo,contribution_hi,share_lo,share_hi")
    assert "contribution 95 %" in captured.out and "too few runs to rank (2 runs)" in captured.out
    assert any(r.levelname == "WARNING" and "too few to rank the sources" in r.getMessage() for r in caplog.records)


@pytest.mark.slow               # 11 Monte Carlos of 50 P3 runs: ~1 min on two cores
def test_the_budget_of_p3s_filter_closes_and_predicts(repo_root):
    """P3's SINS/GPS at 50 runs: the root-sum-square of the contributions is the all-on final
    horizontal error within 5 % (the cross terms of independent sources average out), and
    halving its largest source (the GPS position noise) is predicted within 10 % of a run."""
    b = navsim.budget(repo_root / "scenarios" / "p3_sins_gps.yaml", 50, 3, scales=[("gps.position_sigma", 0.5)])
    m = b.get("SINS/GPS 15-state", "final.pos_m", "horizontal")
    assert m.lines[0].source == "gps.position_sigma"
    assert m.additive and abs(m.ratio - 1) < 0.05, m.ratio
    w = next(x for x in b.what_if if (x.estimator, x.metric, x.component) == (m.estimator, m.metric, m.component))
    assert abs(w.error) < 0.1, w


@pytest.mark.parametrize("args, words", [
    (["--scale", "imu.gyro.bias_instability=0.5"], "no error source 'imu.gyro.bias_instability'"),
    (["--scale", "bd.position_sigma=-1"], "factor K >= 0"),
    (["--scale", "bd.position_sigma=half"], "factor K >= 0"),
])
def test_bad_scales_are_refused_naming_the_sources(args, words, repo_root, tmp_path, capsys):
    out = tmp_path / "never"
    assert main(["budget", str(repo_root / "scenarios" / "p0_matched_ads.yaml"), *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err and not out.exists()
    if "no error source" in words:
        assert "imu.gyro.bias_sigma" in err and "initial.pos" in err


def test_a_scenario_without_error_sources_is_refused(repo_root, tmp_path, capsys):
    text = (repo_root / "scenarios" / "p0_matched_ads.yaml").read_text()
    text = text.replace("imu: {model: p0_imu}", "imu: {model: p0_imu, off: all}")
    text = text.replace("bd: {model: p0_bd2}", "bd: {model: p0_bd2, off: all}")
    text = text.replace("ads: {model: p0_ads, override: &vanes {velocity_axis: air, vane_noise: 0.5 deg}}",
                        "ads: {model: p0_ads, override: &vanes {velocity_axis: air, vane_noise: 0.5 deg}, off: all}")
    text = text.replace("initial_errors: {pos_m: [5, 5, 10], vel_mps: 0.1, att_arcsec: [20, 20, 50]}",
                        "initial_errors: {pos_m: 0, vel_mps: 0, att_arcsec: 0}")
    path = tmp_path / "ideal.yaml"
    path.write_text(text)
    assert main(["budget", str(path), "--out", str(tmp_path / "never")]) == 2
    assert "no error source is on" in capsys.readouterr().err and not (tmp_path / "never").exists()


# --- covariance analysis ------------------------------------------------------------------------

def test_p3s_covariance_analysis_agrees_with_its_monte_carlo(repo_root, shipped_flight):
    """P3's SINS/GPS and free SINS: the covariance analysis's RMS errors (the sum of its
    sources; position and velocity over the flight and at its end, each axis) within a 20-run
    Monte Carlo's standard error (each run's influence on the mean square) times Bonferroni's
    quantile for all of them at 5 %, plus 3 % for the filter's gains (the analysis takes them
    along the truth, a run along its estimate)."""
    scenario, truth, path = shipped_flight("p3_sins_gps")
    b = navsim.budget(scenario, method="covariance")
    assert b.method == "covariance" and b.monte_carlo_only == [] and b.not_analysed == {}
    res = navsim.run(scenario, 20, 11, 1, flight=(truth, path, True))       # one worker: beside xdist's
    checks = [(label, p, comp, col) for label, samples in res.samples.items()
              for p in ("rms.pos_m", "rms.vel_mps", "final.pos_m", "final.vel_mps")
              for comp, col in columns(p, samples.metrics[p])]
    z = norm.ppf(1 - 0.05 / (2 * len(checks)))
    for label, p, comp, col in checks:
        value, g = influence(col)
        se = np.std(g, ddof=1) / np.sqrt(len(g))
        cov = b.get(label, p, comp).all_on
        assert abs(cov - value) <= z * se + 0.03 * value, (label, p, comp, value, se, cov)


@pytest.mark.slow               # 11 Monte Carlos of 200 P3 runs and the covariance analysis: ~5 min
def test_p3s_covariance_budget_matches_its_monte_carlo_budget(repo_root):
    """Issue 34's cross-check: on P3 (200 runs), every source above 5 % of a metric's variance
    has its covariance contribution within 15 % of its Monte Carlo contribution, for the final
    horizontal position, heading, and RMS horizontal position of both estimators."""
    b = navsim.budget(repo_root / "scenarios" / "p3_sins_gps.yaml", 200, 3, method="both")
    checked = 0
    for m in b.metrics:
        if (m.metric, m.component) in DEFAULT_METRICS:
            for x in m.lines:
                if x.share > 0.05:
                    assert abs(x.covariance / x.contribution - 1) < 0.15, (m.estimator, m.name, x)
                    checked += 1
    assert checked >= 15, checked          # their times: benchmarks/budget_covariance.py


def test_a_covariance_budget_names_what_it_leaves_to_monte_carlo(repo_root, tmp_path, capsys):
    """P0's air data terms have no linear form yet: named, left to Monte Carlo; its ES-KF and
    free SINS analysed, each source's errors against time drawn."""
    out = tmp_path / "cov"
    assert main(["budget", str(repo_root / "scenarios" / "p0_bd_sins_ads.yaml"), "--method", "covariance",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    data = json.loads((out / "budget.json").read_text())
    assert data["method"] == "covariance" and "ads.static_noise" in data["monte_carlo_only"]
    assert "no linear form (Monte Carlo only)" in text and "a covariance analysis in" in text
    assert len({m["estimator"] for m in data["metrics"]}) == 2
    # every source is in each table: a contribution, or left out with the reason why
    ads = [s for s in data["sources"] if s.startswith("ads.")]
    assert len(ads) == 5 and set(data["left_out"]) == set(data["monte_carlo_only"]) >= set(ads)
    assert all("ads kind declares no linear form" in data["left_out"][s] for s in ads)
    for m in data["metrics"]:
        assert {x["source"] for x in m["lines"]} | set(data["left_out"]) == set(data["sources"]), m
    tables = text.split("\n\n")
    for table in (x for x in tables if "source " in x):
        listed = [line.split()[0] for line in table.splitlines()[3:] if line and not line.startswith("all on")]
        assert set(listed) >= set(data["sources"]), table
        assert all(f"{s} " in table and "left out" in table.split(f"{s} ", 1)[1].splitlines()[0] for s in ads)
    assert (out / "budget_time.png").stat().st_size > 0


@pytest.mark.parametrize("edit, words", [
    (None, "a closed loop flies on the filter's solution"),
    ("sins", "it takes eskf and sins"),
    ("quantized", "none of its sources has a linear form (imu.gyro.quantization"),
])
def test_covariance_analysis_refuses_what_it_cannot_take(edit, words, repo_root, tmp_path, capsys):
    """A closed loop, a scenario of adaptive filters only, sources none of which is linear:
    exit 2 before anything is written."""
    path = repo_root / "scenarios" / ("p1_return_to_land.yaml" if edit is None else "p0_two_step.yaml")
    if edit is not None:
        data = yaml.safe_load(path.read_text())
        if edit == "sins":
            data["estimators"] = [e for e in data["estimators"] if e["type"] not in ("sins", "eskf")]
        else:
            data["sensors"] = {"imu": {"model": "p0_imu", "override": {"gyro": {"quantization": "0.001 deg/s"}},
                                       "off": ["gyro.bias_sigma", "gyro.noise_density", "accel.bias_sigma",
                                               "accel.noise_density"]},
                               "bd": {"model": "p0_bd2", "off": "all"}, "ads": {"model": "p0_ads", "off": "all"}}
            data["initial_errors"] = {"pos_m": 0, "vel_mps": 0, "att_arcsec": 0}
        path = tmp_path / "edited.yaml"
        path.write_text(yaml.safe_dump(data))
    out = tmp_path / "never"
    assert main(["budget", str(path), "--method", "covariance", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err and not out.exists()


def test_a_covariance_budget_names_the_filters_it_does_not_take(repo_root, tmp_path, capsys):
    out = tmp_path / "cov"
    assert main(["budget", str(repo_root / "scenarios" / "p0_two_step.yaml"), "--method", "covariance",
                 "--out", str(out)]) == 0
    data = json.loads((out / "budget.json").read_text())
    scenario = navsim.load_scenario(repo_root / "scenarios" / "p0_two_step.yaml")
    adaptive = [e.label for e in scenario.estimators if e.type not in ("sins", "eskf")]
    assert adaptive and list(data["not_analysed"]) == adaptive and "gains follow its data" in capsys.readouterr().out
    assert {m["estimator"] for m in data["metrics"]} == {e.label for e in scenario.estimators} - set(adaptive)


def test_an_interrupted_budget_keeps_what_finished_and_resumes(repo_root, tmp_path, monkeypatch, capsys):
    """Ctrl-C in the third Monte Carlo: exit 130, the two finished kept; --resume runs only the
    rest and gives the budget an uninterrupted one gives."""
    import navsim.api as api
    data = yaml.safe_load((repo_root / ".ci" / "wheel_check.yaml").read_text())     # 8 s of P0's flight
    data["sensors"]["bd"]["off"] = data["sensors"]["ads"]["off"] = "all"              # 7 sources, 9 Monte Carlos
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(data))
    args = ["budget", str(path), "--runs", "2", "--workers", "1", "--metric", "final.pos_m:horizontal"]
    assert main(args + ["--out", str(tmp_path / "whole")]) == 0
    whole = json.loads((tmp_path / "whole" / "budget.json").read_text())["metrics"]
    real, calls = api.run, []

    def interrupted(*a, **k):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*a, **k)
    monkeypatch.setattr(api.budgets, "run", interrupted)      # the run each Monte Carlo of a budget calls
    out = tmp_path / "resumed"
    assert main(args + ["--out", str(out)]) == 130
    assert "2 finished Monte Carlo(s) kept" in capsys.readouterr().err
    assert len(list(out.glob("budget_part_*.npz"))) == 2 and not (out / "budget.json").exists()
    calls.clear()
    monkeypatch.setattr(api.budgets, "run", lambda *a, **k: calls.append(1) or real(*a, **k))
    assert main(args + ["--out", str(out), "--resume"]) == 0
    sources = len(error_sources(navsim.load_scenario(path)))
    assert len(calls) == sources + 2 - 2
    assert json.loads((out / "budget.json").read_text())["metrics"] == whole
