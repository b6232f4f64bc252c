"""``navsim new``: a scenario copied from a shipped one with its comments, a filter in one file with
its scenario and test; nothing that is there is replaced."""

import subprocess
import sys
from pathlib import Path

import pytest

from navsim.cli import main

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "one_file_filter"


def test_the_example_filter_is_what_navsim_new_writes(tmp_path):
    """examples/one_file_filter is ``navsim new estimator eskf15``'s output, file for file."""
    assert main(["new", "estimator", "eskf15", "--out", str(tmp_path)]) == 0
    written = sorted(p.name for p in tmp_path.iterdir())
    assert written == ["eskf15.py", "eskf15_p3.yaml", "test_eskf15.py"]
    assert sorted(p.name for p in EXAMPLE.iterdir() if p.suffix in (".py", ".yaml")) == written
    for name in written:
        assert (tmp_path / name).read_text() == (EXAMPLE / name).read_text(), name


def test_a_new_filter_validates_with_its_plugin_and_its_test_compiles(tmp_path, capsys):
    assert main(["new", "estimator", "my_filter", "--out", str(tmp_path / "mine")]) == 0
    folder = tmp_path / "mine"
    text = (folder / "my_filter.py").read_text()
    assert '@register("my_filter")' in text and "class MyFilter(VehicleFilter):" in text
    compile((folder / "test_my_filter.py").read_text(), "test_my_filter.py", "exec")
    assert main(["validate", str(folder / "my_filter_p3.yaml"), "--plugin", str(folder / "my_filter.py")]) == 0
    assert "my_filter_p3.yaml: ok" in capsys.readouterr().out


def test_a_new_scenario_keeps_the_shipped_comments_and_validates(tmp_path):
    assert main(["new", "scenario", "my_flight", "--from", "p3_sins_gps", "--out", str(tmp_path)]) == 0
    shipped = (ROOT / "scenarios" / "p3_sins_gps.yaml").read_text()
    mine = (tmp_path / "my_flight.yaml").read_text()
    assert mine == shipped.replace("name: p3_sins_gps", "name: my_flight", 1)
    assert "# 200 runs: the attitude's consistency" in mine
    assert main(["validate", str(tmp_path / "my_flight.yaml")]) == 0


@pytest.mark.parametrize("argv, words", [
    (["scenario", "mine", "--from", "p3_sins_gs"], ["no shipped scenario", "p3_sins_gps"]),
    (["scenario", "../mine"], ["not a plain file name"]),
    (["estimator", "My-Filter"], ["not a lower-case Python identifier"]),
    (["estimator", "none"], ["class name 'None'"]),
    (["estimator", "_"], ["class name ''"]),
    (["estimator", "vehicle_strapdown"], ["class name 'VehicleStrapdown'"]),
    (["estimator", "yes"], ["YAML word"]),
    (["estimator", "eskf"], ["registered estimator type"]),
    (["estimator", "numpy"], ["module Python finds"]),
    (["estimator", "mine", "--from", "p3_sins_gps"], ["only for navsim new scenario"]),
])
def test_a_bad_name_or_source_is_refused_with_nothing_written(tmp_path, capsys, argv, words):
    assert main(["new", *argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert all(w in err for w in words) and not (tmp_path / "out").exists(), err


def test_a_file_that_is_there_is_not_replaced(tmp_path, capsys):
    (tmp_path / "their_filter_p3.yaml").write_text("mine\n")
    assert main(["new", "estimator", "their_filter", "--out", str(tmp_path)]) == 2
    assert "their_filter_p3.yaml exists already" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["their_filter_p3.yaml"]
    assert (tmp_path / "their_filter_p3.yaml").read_text() == "mine\n"


@pytest.mark.slow              # P3's 3000 s flight flown, 4 runs of both filters: ~40 s
def test_the_written_test_passes(tmp_path):
    assert main(["new", "estimator", "my_filter", "--out", str(tmp_path)]) == 0
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "0",
                           str(tmp_path / "test_my_filter.py")], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
