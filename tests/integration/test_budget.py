"""navsim budget on P0: every source's realisation alone is the one it has with all on (the
emulated errors add exactly), the budget of the ES-KF closes, and the inputs it refuses."""

import json

import numpy as np
import pytest

import navsim
from navsim.cli import main
from navsim.experiment.budget import alone, error_sources
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
    assert "root-sum-square" in capsys.readouterr().out


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
