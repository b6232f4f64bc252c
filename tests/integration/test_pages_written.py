"""Pages a person reads keep their text inside: figures written by the commands that have no
report of their own to test them (``sweep.png``), and pages drawn at the magnitudes a run of
hundreds of runs gave them. The check itself is the suite's
(``tests/pages.py``, applied by ``tests/conftest.py`` to every figure a test saves): these
tests write the figures and fail through it."""

from types import SimpleNamespace

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.backends.backend_pdf import PdfPages

from navsim.experiment.sweep import SweepResult
from navsim.foundations.outputs import OutputFolder
from navsim.records.history import EstimatorHistory
from navsim.report import consistency, drift
from navsim.report.sweep import write_sweep_figure

#: a metric of the shipped wind sweep (``scenarios/sweeps/p0_wind_force.yaml``): a long name
METRIC = "windows.outage over the turn.horizontal_m.final"
LABELS = ("free SINS", "P0's ES-KF 16 (airspeed along the body axis)", "ES-KF 22 (wind and gust states)")


def _sweep(points: list) -> SweepResult:
    rows = [(p, {lb: 10.0 * (n + 1) + k for k, lb in enumerate(LABELS)}) for n, p in enumerate(points)]
    intervals = [{lb: [v - 1.0, v + 1.0] for lb, v in values.items()} for _, values in rows]
    return SweepResult(rows=rows, metric=METRIC, intervals=intervals)


@pytest.mark.parametrize("points", [
    [{"environment.wind.force": f} for f in (0, 3)],                                    # lines, 6.5 in wide
    [{"environment.wind.force": f} for f in range(7)],                                  # the shipped sweep's
    [{"a.gyro.bias_sigma": g, "b.gps.position_sigma": s} for g in ("1 deg/h", "10 deg/h") for s in (2, 8)],
    [{"a.x": 1}, {"a.x": 2, "b.y": 3}, {"b.y": 4}]])                                    # a list of points
def test_a_sweep_figure_keeps_its_title_on_the_page(points, tmp_path):
    """The title the CLI gives (the sweep file, the metric, what the bars are) wraps to the
    figure's width, whatever the grid's shape."""
    sweep = _sweep(points)
    with OutputFolder(tmp_path / "out", command="sweep") as folder:
        write_sweep_figure(folder, sweep, f"sweep p0_wind_force.yaml: {METRIC} (vectors by their norm), "
                                          "95 % intervals over the runs")
    assert (tmp_path / "out" / "sweep.png").stat().st_size > 10_000


# --- the wind report's consistency page and P2's drift page, at the magnitudes they had -------


def _history(label: str, pos_m: np.ndarray, nees: np.ndarray | None, sigma_m: float) -> EstimatorHistory:
    runs, epochs = pos_m.shape[:2]
    return EstimatorHistory(label=label, t_s=np.arange(float(epochs)), att_err_rad=np.zeros((runs, epochs, 3)),
                            vel_err_mps=np.zeros((runs, epochs, 3)), pos_err_m=pos_m,
                            sigma=np.full((runs, epochs, 9), sigma_m), nees=nees, nis={}, nis_dim={},
                            diverged=np.zeros(runs, bool))


def _input(histories: dict, windows: list) -> SimpleNamespace:
    """What the drift and consistency pages read: the histories, the scenario's windows and
    settling time, and the scorer's NEES shares."""
    nees = SimpleNamespace(dim=9, fraction_inside=0.5)
    metrics = SimpleNamespace(estimators={k: SimpleNamespace(nees=nees, nis={}) for k in histories})
    scenario = SimpleNamespace(windows=windows, settle_s=60.0, reference=None)
    return SimpleNamespace(histories=histories, scenario=scenario, metrics=metrics, spans=tuple(windows))


def _write(pages: list, path) -> None:
    try:
        with PdfPages(path) as pdf:
            for page in pages:
                pdf.savefig(page.figure)
    finally:
        for page in pages:
            plt.close(page.figure)


def test_the_drift_and_consistency_pages_keep_their_text_inside(tmp_path):
    """P2's drift page with a window whose error stays within 2.8-3.1 m (a log axis labelled
    between its decades, '2.95×10⁰': its y label pushed off the page), and the wind report's
    consistency page with a diverging filter's NEES of 6e5 beside a consistent one's 9."""
    rng = np.random.default_rng(3)
    runs, epochs = 4, 900
    flat = 2.9 + 0.05 * rng.standard_normal((runs, epochs, 3))            # ~2.9 m on each axis
    growing = np.linspace(0, 6e5, epochs) * (1 + 0.05 * rng.standard_normal((runs, epochs)))
    hs = {"dynamic weights (P2)": _history("dynamic weights (P2)", flat / np.sqrt(2), 9 + rng.standard_normal(
              (runs, epochs)), 2.0),
          "ES-KF 17 (wind neglected)": _history("ES-KF 17 (wind neglected)", 100 * flat, growing, 3.0)}
    windows = [("outage over the turn", 240.0, 360.0), ("gps_fault", 540.0, 550.0)]
    _write(drift.pages(_input({k: hs[k] for k in list(hs)[:1]}, windows)), tmp_path / "drift.pdf")
    _write(consistency.pages(_input(hs, windows)), tmp_path / "consistency.pdf")
