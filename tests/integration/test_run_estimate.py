"""Before a Monte Carlo starts, what it will take: ``navsim run`` prints one line with the disk
its chunks need and the time its runs take (the API logs it), and refuses a run whose chunks
the disk cannot hold (issue 50: ``--runs 1000000`` started a 20 GB, one-hour run unannounced)."""

import logging
import re

import pytest

import navsim
from navsim.cli import main
from navsim.experiment import resources
from navsim.experiment.scenario import load_scenario
from navsim.foundations.errors import UsageError

from test_determinism import SCENARIO


@pytest.fixture
def scenario(tmp_path, monkeypatch):
    monkeypatch.setenv("NAVSIM_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "estimate.yaml"
    path.write_text(SCENARIO)
    return path


def test_the_estimated_disk_is_what_the_chunk_store_writes(scenario, tmp_path, caplog):
    """The chunks' bytes per run, estimated before the run, against the chunks it wrote (within
    15 %), and the estimate logged by the API before the first run."""
    sc = load_scenario(scenario)
    caplog.set_level(logging.INFO, logger="navsim.experiment.resources")
    navsim.run(sc, runs=4, workers=1, out=tmp_path / "out", chunk_runs=2)
    written = sum(f.stat().st_size for f in (tmp_path / "out" / "chunks").glob("chunk_*.npz"))
    assert resources.store_bytes(sc, 4, 2) == pytest.approx(written, rel=0.15)
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("estimate:")]
    assert len(lines) == 1 and "4 runs" in lines[0], lines


def test_a_million_runs_are_announced_and_refused_where_the_disk_cannot_hold_them(scenario, tmp_path, monkeypatch,
                                                                                     capsys):
    sc = load_scenario(scenario)
    need = resources.store_bytes(sc, 10**6)
    monkeypatch.setattr(resources, "_free_disk", lambda out: need // 2)
    code = main(["run", str(scenario), "--runs", "1000000", "--out", str(tmp_path / "big")])
    out, err = capsys.readouterr()
    assert code == 2 and "Traceback" not in err
    assert "on disk" in err and "--runs" in err and str(tmp_path / "big") in err, err
    assert not (tmp_path / "big").exists()                       # nothing started
    with pytest.raises(UsageError, match="on disk"):
        navsim.run(sc, runs=10**6, out=tmp_path / "big")


def test_the_cli_prints_one_estimate_line_before_the_runs(scenario, tmp_path, capsys):
    """One line, before the summary: the runs, the disk of their chunks and the free space
    there, and the time on the workers; the time is the declared per-run cost's."""
    assert main(["run", str(scenario), "--runs", "3", "--workers", "1", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if line.startswith("estimate:")]
    assert len(lines) == 1 and out.index(lines[0]) < out.index("runs in"), out
    assert re.search(r"3 runs, about [\d.]+ [KMG]iB of chunks .* free\), the runs about (under 1 s|[\d.]+ (s|min|h)) on 1 worker",
                     lines[0]), lines[0]
    sc = load_scenario(scenario)
    one, many = (resources.run_seconds(sc, runs, 2) for runs in (1000, 4000))
    assert many == pytest.approx(4 * one) and resources.run_seconds(sc, 1000, 1) > one


def test_a_closed_loop_estimate_counts_each_runs_flight(repo_root):
    """Each closed-loop run flies its own flight: P1's return to land (100 runs in 154 s on
    2 workers, docs/performance.md) is estimated within a factor of 2 of that."""
    sc = load_scenario(repo_root / "scenarios" / "p1_return_to_land.yaml")
    assert 77 < resources.run_seconds(sc, 100, 2) < 310
