"""Edges of the command line and the registries (issue 50): a plug-in that cannot be loaded is
named once and left out; ``budget`` and ``sweep`` check every argument before any work; the
hints and the help say what each command can do; a sweep's points numbered one way."""

import json
import warnings

import pytest

from navsim import api
from navsim.cli import build_parser, main
from navsim.experiment import sweep as sweep_module
from navsim.experiment.sweep import SweepResult, parse_sweep
from navsim.foundations import plugins
from navsim.navigation.estimators import base
from navsim.sensors import registry

#: a plug-in whose package is installed (its dist-info) but whose module is gone
BROKEN_ENTRY_POINTS = "[navsim.estimators]\nghost = ghost_plugin.filters:Ghost\n\n" \
                      "[navsim.sensors]\nghost_kind = ghost_plugin.kinds:KIND\n"


@pytest.fixture
def broken_plugin(tmp_path, monkeypatch):
    """An installed distribution ``ghost-plugin`` whose entry points name a module that does
    not exist (an editable install whose folder was removed); the registries read afresh."""
    dist = tmp_path / "ghost_plugin-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: ghost-plugin\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(BROKEN_ENTRY_POINTS)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_ENTRY_POINTS_READ", [])
    monkeypatch.setattr(plugins, "_FAILED", set())


def test_a_plugin_that_cannot_be_loaded_is_named_once_and_left_out(broken_plugin):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(KeyError, match="no estimator 'eskff'.*did you mean 'eskf'"):
            base.get("eskff")
        with pytest.raises(KeyError, match="no sensor kind 'imuu'.*did you mean 'imu'"):
            registry.get("imuu")
        assert base.get("eskf").__name__ and registry.get("imu").name == "imu"
        assert "ghost" not in base.available() and "ghost_kind" not in registry.available()
        base.known("another_unknown")
    texts = [str(w.message) for w in caught if issubclass(w.category, plugins.PluginWarning)]
    assert len(texts) == 2, texts                     # one per entry point, however often looked up
    est = next(t for t in texts if "ghost =" in t)
    assert "ghost-plugin" in est and "ghost_plugin.filters:Ghost" in est and "navsim.estimators" in est
    assert "ModuleNotFoundError" in est and "ghost_plugin" in est
    assert any("ghost_kind = 'ghost_plugin.kinds:KIND'" in t and "navsim.sensors" in t for t in texts)


def test_validate_works_beside_a_broken_plugin(broken_plugin, repo_root, capsys):
    """The whole scenario check (estimators, sensors, measurements) beside the broken plug-in."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plugins.PluginWarning)
        assert main(["validate", str(repo_root / "scenarios" / "p3_sins_gps.yaml")]) == 0


@pytest.fixture
def no_work(monkeypatch):
    """Every Monte Carlo, budget and sweep fails the test: what is checked must be refused first."""
    def ran(*args, **kwargs):
        raise AssertionError("work started before the arguments were checked")
    for name in ("run", "budget", "sweep"):
        monkeypatch.setattr(api, name, ran)


P0 = "p0_matched_ads.yaml"


@pytest.mark.parametrize("factor", ["1e308", "1e200", "1001"])
def test_a_scale_above_its_bound_is_refused_before_any_run(factor, no_work, repo_root, tmp_path, capsys):
    out = tmp_path / "b"
    assert main(["budget", str(repo_root / "scenarios" / P0), "--scale", f"bd.position_sigma={factor}",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--scale 'bd.position_sigma={factor}'" in err and "at most 1000" in err and not out.exists()


def test_the_scale_bound_is_in_the_help(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["budget", "--help"])
    assert "K >= 0, at most 1000" in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("metric, words", [
    ("nonsense.path:Q", "'nonsense.path'"),
    ("final.pos_m:Q", "component 'Q'"),
    ("final.pos_m", "has components"),
    ("rms.att_deg:horizontal", "component 'horizontal'"),
    ("nees.average:", "not budgeted"),
    ("windows.nowhere.height_m.rms:", "window 'nowhere'"),
])
def test_a_budget_metric_is_checked_before_any_run(metric, words, no_work, repo_root, tmp_path, capsys):
    out = tmp_path / "b"
    assert main(["budget", str(repo_root / "scenarios" / P0), "--metric", "final.pos_m:horizontal",
                 "--metric", metric, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--metric {metric!r}" in err and words in err and "hint:" in err, err
    assert not out.exists()


def test_a_budget_of_more_runs_than_memory_holds_hints_fewer_runs(monkeypatch, repo_root, tmp_path, capsys):
    """10^6 runs per Monte Carlo: refused before any flight with a hint ``budget`` can follow
    (its Monte Carlos are held in memory: ``out=`` is navsim.run's, not the command's)."""
    from navsim.experiment import resources
    path = repo_root / "scenarios" / P0
    monkeypatch.setattr(resources, "available_memory", lambda: 4 * resources.flight_bytes(api.load_scenario(path)))
    monkeypatch.setattr(api, "budget", lambda *a, **k: pytest.fail("the budget started"))
    out = tmp_path / "b"
    assert main(["budget", str(path), "--runs", "1000000", "--workers", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "1000000 runs held in memory" in err and "fewer --runs" in err and "out=" not in err
    assert not out.exists()


SCENARIO = """
name: edge
track:
  start: {lat_deg: 37.0, lon_deg: 118.0, alt_m: 300, speed_mps: 14, heading_deg: 30}
  segments: [{type: straight, time_s: 20}]
sensors: {imu: {model: p3_imu}, gps: {model: p3_gps}}
estimators:
  - label: KF
    type: eskf
    states: p3_15
    noise: {imu: p3_imu}
    measurements: [{type: gnss_position, sensor: gps, sigma_m: [2, 2, 1]}]
montecarlo: {runs: 2, seed: 4}
metrics: {settle_s: 5, windows: [{name: late, start_s: 10, end_s: 20}]}
"""


@pytest.fixture
def sweep_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "cache"))
    (tmp_path / "edge.yaml").write_text(SCENARIO)
    return tmp_path


def _sweep(folder, text: str):
    path = folder / "w.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("metric, words", [
    ("rms.pos_m.ci95", "'rms.pos_m' is a number or a list of numbers"),
    ("windows.late.height_m", "a group of metrics (max_pos, max_neg"),
    ("resets.times_s", "not a number"),
    ("nis.gnss_position:gps", "a group of metrics (average, band"),
])
def test_a_sweep_metric_that_is_not_a_number_is_refused_before_running(metric, words, sweep_dir, no_work,
                                                                       capsys):
    path = _sweep(sweep_dir, f"scenario: edge.yaml\ngrid: {{montecarlo.seed: [1, 2]}}\nmetric: {metric}\n")
    assert main(["sweep", str(path), "--out", str(sweep_dir / "out")]) == 2
    err = capsys.readouterr().err
    assert f"{path}: metric: '{metric}'" in err and words in err and "expected the path of a number" in err, err
    assert not (sweep_dir / "out").exists()


def test_sweep_metrics_that_are_numbers_are_taken(sweep_dir):
    for metric in ("rms.pos_m", "windows.late.height_m.rms", "windows.late.horizontal_m.final", "nees.average",
                   "diverged_runs", "nis.gnss_position:gps.fraction_inside", "attitude.rms_deg"):
        path = _sweep(sweep_dir, f"scenario: edge.yaml\ngrid: {{montecarlo.seed: [1, 2]}}\nmetric: {metric}\n")
        assert parse_sweep(path)[2] == metric


def test_an_absolute_scenario_path_is_refused_saying_why(sweep_dir, capsys):
    path = _sweep(sweep_dir, f"scenario: {sweep_dir / 'edge.yaml'}\ngrid: {{montecarlo.seed: [1, 2]}}\n")
    assert main(["sweep", str(path), "--out", str(sweep_dir / "out")]) == 2
    err = capsys.readouterr().err
    assert "is an absolute path" in err and "not found" not in err and "relative to the sweep file" in err


def test_a_sweep_of_more_runs_than_memory_holds_hints_the_sweep_file(sweep_dir, monkeypatch, capsys):
    from navsim.experiment import resources
    monkeypatch.setattr(resources, "available_memory",
                        lambda: 4 * resources.flight_bytes(api.load_scenario(sweep_dir / "edge.yaml")))
    monkeypatch.setattr(api.sweeps, "run", lambda *a, **k: pytest.fail("a point started"))
    monkeypatch.setattr(sweep_module, "cached_flight", lambda *a, **k: pytest.fail("a point was flown"))
    path = _sweep(sweep_dir, "scenario: edge.yaml\nruns: 1000000\ngrid: {montecarlo.seed: [1, 2]}\n")
    assert main(["sweep", str(path), "--out", str(sweep_dir / "out")]) == 2
    err = capsys.readouterr().err
    assert f"{path}: point 1/2" in err and "fewer 'runs'" in err and "out=" not in err


class FakeResult:
    """What a sweep's progress line reads of a point's result."""

    def __init__(self, runs):
        self.runs, self.record = runs, type("Record", (), {"wall_s": 0.1})


def test_a_sweep_numbers_its_points_one_way_and_exits_1_when_one_failed(sweep_dir, monkeypatch, capsys):
    """Point 2 of 3 without a successful run: the progress line, the error and sweep.csv say
    point 2 (of 3); exit 1, as the docs say."""
    def fake_sweep(path, workers=None, *, progress=None, on_point=None, **how):
        result = SweepResult([], "rms.pos_m")
        for i in range(3):
            result.rows.append(({"montecarlo.seed": i + 1}, {"KF": None if i == 1 else 1.0 + i}))
            result.metrics.append(None)
            result.intervals.append({})
            if i == 1:
                result.failed_points[i] = "RuntimeError: filter exploded"
            on_point(i, *result.rows[-1], FakeResult([] if i == 1 else [0, 1]))
        return result
    monkeypatch.setattr(api, "sweep", fake_sweep)
    path = _sweep(sweep_dir, "scenario: edge.yaml\ngrid: {montecarlo.seed: [1, 2, 3]}\n")
    out = sweep_dir / "out"
    assert main(["sweep", str(path), "--out", str(out)]) == 1
    text = capsys.readouterr()
    assert "point 2/3 (montecarlo.seed=2)" in text.out
    assert "error: no run of point 2/3 (montecarlo.seed=2) succeeded: RuntimeError: filter exploded" in text.err
    assert "1 of 3 points failed" in text.err
    assert [row.split(",")[0] for row in (out / "sweep.csv").read_text().splitlines()[1:]] == ["1", "2", "3"]


@pytest.mark.parametrize("command", ["fly", "sensors", "compare", "replay", "sweep", "run", "budget"])
def test_the_help_promises_resume_only_where_there_is_one(command, capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args([command, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert ("--resume" in text) == (command in ("run", "budget")), text
