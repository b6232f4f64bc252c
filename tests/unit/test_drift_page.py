"""The drift page (issue 35): each window's horizontal error (RMS over the runs) and the filter's
own horizontal 1-sigma against the time since the window's start, what it draws checked."""

from types import SimpleNamespace

import numpy as np

from navsim.records.history import EstimatorHistory
from navsim.report import drift


def _history(rng, label, sigma: bool):
    t = np.arange(100.0)
    runs = 4
    pos = rng.normal(size=(runs, 100, 3)) * np.linspace(1, 30, 100)[None, :, None]
    pos[0, 80:] = np.nan                                  # a run whose records end early
    return EstimatorHistory(label=label, t_s=t, att_err_rad=np.zeros((runs, 100, 3)), vel_err_mps=np.zeros((runs, 100, 3)),
                            pos_err_m=pos, sigma=np.abs(rng.normal(size=(runs, 100, 9))) + 1 if sigma else None,
                            nees=None, nis={}, nis_dim={}, diverged=np.zeros(runs, bool))


def test_the_drift_page_draws_each_windows_error_and_sigma():
    rng = np.random.default_rng(5)
    hs = {"KF": _history(rng, "KF", True), "free": _history(rng, "free", False)}
    scenario = SimpleNamespace(windows=[("outage", 40.0, 89.0)])
    pages = drift.pages(SimpleNamespace(histories=hs, scenario=scenario))
    assert [p.name for p in pages] == ["drift"]
    lines = pages[0].figure.axes[0].get_lines()
    assert len(lines) == 3                                # KF error and sigma, free error
    m = (hs["KF"].t_s >= 40) & (hs["KF"].t_s <= 89)
    hor = np.hypot(hs["KF"].pos_err_m[:, m, 0], hs["KF"].pos_err_m[:, m, 1])
    want = np.sqrt(np.nanmean(hor ** 2, axis=0))          # RMS over the runs that have a record
    np.testing.assert_allclose(lines[0].get_xdata(), hs["KF"].t_s[m] - 40.0)
    np.testing.assert_allclose(lines[0].get_ydata(), want)
    sig = hs["KF"].sigma[:, m, 6:8]
    np.testing.assert_allclose(lines[1].get_ydata(), np.sqrt(np.mean(sig[..., 0] ** 2 + sig[..., 1] ** 2, axis=0)))
    assert pages[0].figure.axes[0].get_yscale() == "log"
    assert drift.pages(SimpleNamespace(histories=hs, scenario=SimpleNamespace(windows=[]))) == []
