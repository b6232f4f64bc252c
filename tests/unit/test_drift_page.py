"""The drift page (issues 35, 50): each window's error (RMS over the runs) and the filter's own
1-sigma against the time since the window's start, what it draws checked: horizontal for an
outage's drift, the height for a height study (a scenario whose reference judges its windows'
``height_m``); a log scale only where the curves span decades, plain tick labels; estimators
drawn on one line said to coincide."""

from types import SimpleNamespace

import numpy as np

from navsim.records.history import EstimatorHistory
from navsim.records.reference import PaperCheck
from navsim.report import drift
from navsim.report.consistency import LOG_DECADES


def _history(rng, label, sigma: bool, growth=(1, 30), pos=None):
    t = np.arange(100.0)
    runs = 4
    if pos is None:
        pos = rng.normal(size=(runs, 100, 3)) * np.geomspace(*growth, 100)[None, :, None]
        pos[0, 80:] = np.nan                              # a run whose records end early
    return EstimatorHistory(label=label, t_s=t, att_err_rad=np.zeros((runs, 100, 3)), vel_err_mps=np.zeros((runs, 100, 3)),
                            pos_err_m=pos, sigma=np.abs(rng.normal(size=(runs, 100, 9))) + 1 if sigma else None,
                            nees=None, nis={}, nis_dim={}, diverged=np.zeros(runs, bool))


def _page(hs, windows=(("outage", 40.0, 89.0),), reference=None):
    scenario = SimpleNamespace(windows=list(windows), reference=reference)
    return drift.pages(SimpleNamespace(histories=hs, scenario=scenario))


def _height_study(window="outage"):
    return SimpleNamespace(source="P2", checks=(
        PaperCheck("KF", f"windows.{window}.height_m.std", "close", 1.6),))


def test_the_drift_page_draws_each_windows_error_and_sigma():
    rng = np.random.default_rng(5)
    hs = {"KF": _history(rng, "KF", True, (1, 3000)), "free": _history(rng, "free", False, (1, 3000))}
    pages = _page(hs)
    assert [p.name for p in pages] == ["drift"]
    ax = pages[0].figure.axes[0]
    lines = ax.get_lines()
    assert len(lines) == 3                                # KF error and sigma, free error
    m = (hs["KF"].t_s >= 40) & (hs["KF"].t_s <= 89)
    hor = np.hypot(hs["KF"].pos_err_m[:, m, 0], hs["KF"].pos_err_m[:, m, 1])
    want = np.sqrt(np.nanmean(hor ** 2, axis=0))          # RMS over the runs that have a record
    np.testing.assert_allclose(lines[0].get_xdata(), hs["KF"].t_s[m] - 40.0)
    np.testing.assert_allclose(lines[0].get_ydata(), want)
    sig = hs["KF"].sigma[:, m, 6:8]
    np.testing.assert_allclose(lines[1].get_ydata(), np.sqrt(np.mean(sig[..., 0] ** 2 + sig[..., 1] ** 2, axis=0)))
    assert "horizontal" in ax.get_ylabel() and "Horizontal" in pages[0].title
    assert _page(hs, windows=[]) == []


def test_a_height_studys_drift_page_plots_the_height_error():
    """P2 judges its windows' height error: the page draws the height error (up) and the
    filter's vertical 1-sigma, not the horizontal error."""
    rng = np.random.default_rng(6)
    hs = {"KF": _history(rng, "KF", True)}
    page = _page(hs, reference=_height_study())[0]
    ax = page.figure.axes[0]
    m = (hs["KF"].t_s >= 40) & (hs["KF"].t_s <= 89)
    up = -hs["KF"].pos_err_m[:, m, 2]
    err, sig = ax.get_lines()[:2]
    np.testing.assert_allclose(err.get_ydata(), np.sqrt(np.nanmean(up ** 2, axis=0)))
    np.testing.assert_allclose(sig.get_ydata(), np.sqrt(np.mean(hs["KF"].sigma[:, m, 8] ** 2, axis=0)))
    assert "height" in ax.get_ylabel() and "Height" in page.title
    # a reference judging the windows' horizontal drift keeps the horizontal error
    drift_study = SimpleNamespace(source="x", checks=(
        PaperCheck("KF", "windows.outage.horizontal_m.final", "close", 9.0),))
    assert "horizontal" in _page(hs, reference=drift_study)[0].figure.axes[0].get_ylabel()


def _tick_texts(ax):
    ax.figure.canvas.draw()
    return [t.get_text() for t in ax.get_yticklabels() + ax.get_yticklabels(minor=True) if t.get_text()]


def test_a_log_scale_only_where_the_curves_span_decades_with_plain_tick_labels():
    rng = np.random.default_rng(7)
    whole = [("whole flight", 0.0, 99.0)]
    narrow = _page({"KF": _history(rng, "KF", False, (2, 5))}, whole)[0].figure.axes[0]
    assert narrow.get_yscale() == "linear"
    wide = _page({"KF": _history(rng, "KF", False, (1, 10 ** (LOG_DECADES + 1)))}, whole)[0].figure.axes[0]
    assert wide.get_yscale() == "log"
    for ax in (narrow, wide):
        texts = _tick_texts(ax)
        assert len(texts) >= 3 and not [t for t in texts if "times" in t or "^" in t or "×" in t], texts
    # a log axis of a decade and a half: 2 and 5 times the decades labelled too, plain
    pos = np.zeros((4, 100, 3))
    pos[..., 0] = np.geomspace(0.2, 15.0, 100)            # 1.9 decades, the same in every run
    short = _page({"KF": _history(rng, "KF", False, pos=pos)}, whole)[0].figure.axes[0]
    assert short.get_yscale() == "log"
    texts = _tick_texts(short)
    assert len(texts) >= 3 and all(t.replace(".", "").replace(",", "").isdigit() for t in texts), texts


def test_estimators_drawn_on_one_line_are_said_to_coincide():
    """Three estimators whose horizontal errors agree to 0.35 % (P2's) were drawn as one line
    with nothing said; the panel now names those that coincide (checked numerically), not the
    others, and its note covers no curve."""
    rng = np.random.default_rng(8)
    a = _history(rng, "A", False)
    same = _history(rng, "B", False, pos=a.pos_err_m * (1 + 1e-3))
    other = _history(rng, "C", False, (1, 3))
    ax = _page({"A": a, "B": same, "C": other})[0].figure.axes[0]
    notes = [t.get_text().replace("\n", " ") for t in ax.texts]
    assert len(notes) == 1 and notes[0].startswith("A and B coincide"), notes
    assert "C" not in notes[0].split("coincide")[0]
    ax.figure.canvas.draw()
    box = ax.texts[0].get_bbox_patch().get_window_extent()
    for line in ax.get_lines():
        xy = line.get_transform().transform(np.column_stack([line.get_xdata(), line.get_ydata()]))
        under = (xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1)
        assert not (xy[under, 1] > box.y0).any()
    apart = _page({"A": a, "C": other})[0].figure.axes[0]
    assert not apart.texts
