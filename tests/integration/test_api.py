"""The Python API (``navsim.run``, ``open_result``, ``write_report``, ``Result.to_xarray``) and the
notebook example: the same numbers as ``navsim run``, a finished run read back without a byte
of its folder changed."""

import hashlib
import json
import runpy
from pathlib import Path

import numpy as np
import pytest
from test_run import interrupt_at, run, short, short_pdf  # noqa: F401 (fixtures)

import navsim
from navsim.experiment.chunkstore import ChunkStore, ResumeError

ROOT = Path(__file__).resolve().parents[2]


def checksums(folder: Path) -> dict:
    """Every file under ``folder`` with its SHA-256 and modification time."""
    return {p.relative_to(folder).as_posix(): (hashlib.sha256(p.read_bytes()).hexdigest(), p.stat().st_mtime_ns)
            for p in sorted(folder.rglob("*")) if p.is_file()}


def without_cost(metrics: dict) -> dict:
    return {label: {k: v for k, v in m.items() if k != "cost"} for label, m in metrics["estimators"].items()}


def test_the_notebook_example_gives_navsim_runs_numbers(tmp_path, monkeypatch, close_metrics, capsys):
    """examples/p0_quickstart.py (3 runs of P0) against ``navsim run`` of the same runs, which
    judges P0's claims (free SINS diverges; the integrated filter converges fast, does not
    diverge, stays within the BD's sigma) and prints the verdicts, read back equal."""
    monkeypatch.setenv("NAVSIM_EXAMPLE_RUNS", "3")
    monkeypatch.setenv("NAVSIM_EXAMPLE_OUT", str(tmp_path / "example"))
    example = runpy.run_path(str(ROOT / "examples" / "p0_quickstart.py"))
    assert (tmp_path / "example" / "horizontal_error.png").stat().st_size > 10_000
    out = tmp_path / "cli"
    assert run(ROOT / "scenarios" / "p0_bd_sins_ads.yaml", out, "--runs", "3", "--seed", "1", "--workers", "2") == 0
    written = json.loads((out / "metrics.json").read_text())
    checks = written.pop("paper_checks")
    # P0's claims are read off one flight: at 3 runs the range of one run is open (39 runs bound
    # it), so they are undecided; the count of diverged runs is a population check, decided
    assert [(c["estimator"], c["passed"], c["kind"]) for c in checks] == [
        ("free SINS", None, "single_run"), ("BD/SINS/ADS ES-KF 16", None, "single_run"),
        ("BD/SINS/ADS ES-KF 16", True, "population"), ("BD/SINS/ADS ES-KF 16", None, "single_run")]
    assert checks[1]["undecided"] and checks[1]["runs"] == 3 and checks[1]["runs_needed"] == 39
    assert "1 of 4 paper checks pass, 3 undecided at 3 runs" in capsys.readouterr().out
    assert example["result"].metrics.paper_checks == navsim.open_result(out).metrics.paper_checks
    close_metrics(without_cost({k: v for k, v in example["result"].to_dict().items() if k != "paper_checks"}),
                  without_cost(written))
    ds = example["ds"]
    assert dict(ds.sizes) == {"estimator": 2, "run": 3, "epoch": 501, "axis": 3, "state": 9, "bound": 2}
    assert ds.pos_err_m.attrs["units"] == "m" and ds.t_s.attrs["units"] == "s"
    kf = example["result"].histories["BD/SINS/ADS ES-KF 16"]
    assert np.array_equal(ds.pos_err_m.sel(estimator="BD/SINS/ADS ES-KF 16").values, kf.pos_err_m)


def test_a_run_held_in_memory_writes_nothing_until_asked(short_pdf, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = navsim.run(short_pdf, runs=3, seed=4, workers=1)
    assert result.folder is None and sorted(p.name for p in tmp_path.iterdir()) == ["cache", "short.yaml"]
    assert list(result.runs) == [0, 1, 2] and result.record.seed == 4 and result.record.git_revision
    with pytest.raises(navsim.api.UsageError, match="needs a folder"):
        navsim.write_report(result)
    files = navsim.write_report(result, tmp_path / "report")
    assert (tmp_path / "report" / "report.pdf") in files
    assert json.loads((tmp_path / "report" / "metrics.json").read_text()) == result.to_dict()
    ds = result.to_xarray()
    ds.to_netcdf(tmp_path / "runs.nc", engine="scipy")
    import xarray as xr
    back = xr.open_dataset(tmp_path / "runs.nc", engine="scipy")
    assert np.array_equal(back.pos_err_m.values, ds.pos_err_m.values, equal_nan=True)
    # the metrics beside the histories, each with its 95 % interval over the 3 runs
    for label in result.metrics.estimators:
        m = result.metrics.estimators[label]
        assert np.allclose(ds.rms_pos_m.sel(estimator=label).values, m.rms.pos_m)
        lo, hi = ds.rms_pos_m_ci95.sel(estimator=label, bound="lo"), ds.rms_pos_m_ci95.sel(estimator=label, bound="hi")
        assert np.all((lo.values <= m.rms.pos_m) & (np.asarray(m.rms.pos_m) <= hi.values))
    assert back.rms_pos_m_ci95.attrs["units"] == "m"


def test_open_result_reads_a_finished_and_an_interrupted_run_and_changes_no_byte(short_pdf, tmp_path, monkeypatch,
                                                                                  same_history):
    assert run(short_pdf, tmp_path / "whole", "--chunk-runs", "2") == 0
    interrupt_at(monkeypatch, 4)
    assert run(short_pdf, tmp_path / "cut", "--chunk-runs", "2") == 130
    for name, runs in (("whole", list(range(6))), ("cut", [0, 1, 2, 3])):
        folder = tmp_path / name
        before = checksums(folder)
        result = navsim.open_result(folder)
        assert list(result.runs) == runs and result.interrupted == (name == "cut")
        assert result.to_dict() == json.loads((folder / "metrics.json").read_text())
        assert result.metrics.estimators["KF"].runs_counted == len(runs)
        stored = [r for part in result.store.parts() for r in part.runs]
        assert stored == runs
        merged = result.store.merged()
        for label, h in result.histories.items():
            same_history(h, merged.histories[label])
        assert result.to_xarray().sizes["run"] == len(runs)
        with pytest.raises(ResumeError, match="read-only"):        # the store refuses to write
            result.store.add(result.store.merged())
        with pytest.raises(ResumeError, match="read-only"):
            result.store.flag({"0-1": "x"})
        with pytest.raises(TypeError):       # a store opened neither new nor resumed: refused (the
            ChunkStore(folder / "chunks", result.store.key)    # old default deleted the chunks)
        assert checksums(folder) == before
    with pytest.raises(navsim.api.UsageError, match="not a finished navsim run"):
        navsim.open_result(tmp_path / "nowhere")
