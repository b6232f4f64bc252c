"""The test of eskf15, written by ``navsim new estimator eskf15``: on P3's flight (4 runs of its
3000 s), beside navsim's own 15-state ES-KF on the same runs, it does not diverge and its RMS
position error on each axis lies inside the shipped filter's 95 % interval.

    python -m pytest test_eskf15.py
"""

import json
from pathlib import Path

from navsim.cli import main

HERE = Path(__file__).resolve().parent


def test_eskf15_follows_the_shipped_eskf_on_p3(tmp_path, monkeypatch):
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "out"
    assert main(["run", str(HERE / "eskf15_p3.yaml"), "--plugin", str(HERE / "eskf15.py"),
                 "--runs", "4", "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())["estimators"]
    mine, shipped = metrics["eskf15"], metrics["SINS/GPS 15-state"]
    assert mine["diverged_runs"] == 0
    for value, (lo, hi) in zip(mine["rms"]["pos_m"], shipped["ci95"]["rms"]["pos_m"]):
        assert lo <= value <= hi, (mine["rms"]["pos_m"], shipped["ci95"]["rms"]["pos_m"])
