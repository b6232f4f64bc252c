"""A filter in one file (``--plugin``): the single-vehicle contract run for every run and scored
like any estimator, beside the shipped ES-KF on the same runs; files that cannot be a plug-in
are refused (exit 2, the file named), nothing written and nothing shipped shadowed."""

import json
from pathlib import Path

import numpy as np
import pytest
from test_run import SHORT, run, short  # noqa: F401 (fixtures)

from navsim.navigation.estimators.base import ESTIMATORS

ROOT = Path(__file__).resolve().parents[2]
FILTER = ROOT / "examples" / "one_file_filter" / "eskf15.py"
ONE_FILE = """  - label: one-file ES-KF
    type: eskf15
    gnss: gps
    sigma_m: [2, 2, 1]
    sigma_mps: 0.05
"""


@pytest.fixture
def beside(short):
    """The short scenario with the one-file ES-KF beside its ES-KF (the same IMU model and
    measurement noise), a PDF report only."""
    text = SHORT.replace("initial_errors:", ONE_FILE + "initial_errors:")
    short.write_text(text + "report: {formats: [pdf]}\n")
    return short


def test_a_one_file_filter_is_scored_beside_the_shipped_eskf_on_the_same_runs(beside, tmp_path, capsys):
    """Its position RMS on each axis inside the 95 % interval of the shipped 15-state ES-KF's
    over the same 6 runs (the same model, a simpler F: no Earth or transport rate), its NEES in
    its band on most epochs, its cost per run in metrics.json."""
    out = tmp_path / "out"
    assert run(beside, out, "--plugin", str(FILTER)) == 0
    m = json.loads((out / "metrics.json").read_text())["estimators"]
    mine, kf = m["one-file ES-KF"], m["KF"]
    lo, hi = np.array(kf["ci95"]["rms"]["pos_m"]).T
    ours = np.array(mine["rms"]["pos_m"])
    assert np.all((lo <= ours) & (ours <= hi)), (ours, kf["ci95"]["rms"])
    # paired, run by run on the same data: the models differ by the Earth and transport rates'
    # terms (7e-5 rad/s over a 1 s epoch), far below the GNSS noise
    assert np.allclose(ours, kf["rms"]["pos_m"], rtol=0.02), (ours, kf["rms"]["pos_m"])
    assert mine["diverged_runs"] == 0 and mine["nees"]["fraction_inside"] > 0.5, mine["nees"]
    assert mine["nis"]["gnss_position:gps"]["average"] == pytest.approx(kf["nis"]["gnss_position:gps"]["average"],
                                                                          rel=0.02)
    assert mine["cost"]["ms_per_run"] > kf["cost"]["ms_per_run"]      # a Python loop per run
    assert "one-file ES-KF" in capsys.readouterr().out


CASES = [
    ("raises.py", "import numpy\n\nraise RuntimeError('no calibration file')\n", ["raises.py:3", "RuntimeError",
                                                                                    "no calibration file"]),
    ("syntax.py", "def f(:\n", ["syntax.py:1", "SyntaxError"]),
    ("nothing.py", "import numpy as np\n\nX = np.zeros(3)\n", ["registers nothing", "navsim.plugin.register"]),
    ("shadow.py", "from navsim.plugin import register\n\n\n@register('eskf')\nclass Mine:\n"
                  "    period_s = 1.0\n    def initialize(self, nav0, P0): pass\n    def predict(self, imu): pass\n"
                  "    def update(self, t_s, samples): pass\n    def solution(self): pass\n",
     ["registers estimator 'eskf'", "already"]),
    ("notes.txt", "", ["not a Python file"]),
]


@pytest.mark.parametrize("name, text, words", CASES, ids=[c[0] for c in CASES])
def test_a_file_that_cannot_be_a_plugin_is_refused_naming_it(short, tmp_path, capsys, name, text, words):
    shipped = ESTIMATORS.get("eskf")
    (tmp_path / name).write_text(text)
    out = tmp_path / "out"
    assert run(short, out, "--plugin", str(tmp_path / name)) == 2
    err = capsys.readouterr().err
    assert all(w in err for w in words) and "Traceback" not in err, err
    assert not out.exists() and ESTIMATORS.get("eskf") is shipped


def test_a_run_whose_filter_raises_is_flagged_and_the_others_complete(short, tmp_path):
    """The one-vehicle filter raises in the runs whose initial height is above the track's
    start (its error drawn per run): those runs are flagged diverged with the exception, the
    others are scored."""
    (tmp_path / "fragile.py").write_text(FRAGILE)
    short.write_text(SHORT.replace("initial_errors:", "  - {label: fragile, type: fragile_one_file}\ninitial_errors:")
                     + "report: {formats: [pdf]}\n")
    out = tmp_path / "out"
    assert run(short, out, "--plugin", str(tmp_path / "fragile.py")) == 0
    m = json.loads((out / "metrics.json").read_text())["estimators"]["fragile"]
    assert 0 < m["diverged_runs"] < 6, m["diverged_runs"]
    assert json.loads((out / "metrics.json").read_text())["estimators"]["KF"]["diverged_runs"] == 0
    causes = m["divergence"]["causes"]
    assert causes == {"raised FloatingPointError: the covariance lost its positive definiteness": m["diverged_runs"]}
    record = json.loads((out / "run.json").read_text())
    # the run records the file its filter came from, its text's digest in the run's identity
    import hashlib
    assert record["plugins"] == [{"type": "fragile_one_file", "file": str((tmp_path / "fragile.py").resolve()),
                                  "sha256": hashlib.sha256((tmp_path / "fragile.py").read_bytes()).hexdigest()}]


def test_a_key_the_filter_does_not_take_is_refused_when_the_scenario_is_read(beside, tmp_path, capsys):
    beside.write_text(beside.read_text().replace("    sigma_mps: 0.05\n", "    sigma_mp: 0.05\n"))
    assert run(beside, tmp_path / "out", "--plugin", str(FILTER)) == 2
    err = capsys.readouterr().err
    assert "estimators[2]" in err and "sigma_mp" in err and "sigma_mps" in err, err


FRAGILE = """
from navsim.plugin import VehicleFilter, VehicleSolution, VehicleStrapdown, register


@register("fragile_one_file")
class Fragile(VehicleFilter):
    def initialize(self, nav0, P0):
        self.ins, self.high = VehicleStrapdown(nav0), nav0.h_m[0] > 300.0

    def predict(self, imu):
        self.ins.step(imu)

    def update(self, t_s, samples):
        if self.high and t_s > 5:
            raise FloatingPointError("the covariance lost its positive definiteness")

    def solution(self):
        return VehicleSolution(nav=self.ins.nav)
"""
