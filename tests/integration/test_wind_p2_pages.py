"""The wind report's pages and P2's (issue 50), drawn from synthetic runs into the page
functions: the consistency page puts a curve that spans decades on a log scale with plain tick
labels and keeps its notes off the windows' labels and the curves; the wind page's legend shows
the runs in the colours they are drawn in; the windows table has one heading row."""

import re
from types import SimpleNamespace

import numpy as np
from matplotlib.colors import to_rgba

from navsim.flight.environment import parse_environment
from navsim.records.history import EstimatorHistory
from navsim.report import consistency, summary, wind
from navsim.report.figures import pyplot
from navsim.scoring.scorer import score

T_S = np.arange(0.0, 600.0, 1.0)
RUNS = 3
WINDOWS = (("outage over the turn", 100.0, 219.0), ("outage over the straight legs", 360.0, 539.0))


def _nees_history(rng, label, grow: float):
    """A filter's NEES: chi-square(9) times ``1 + grow * (t / t_end)^2`` (``grow`` 0: consistent),
    and a 3-dim NIS."""
    e = T_S.size
    nees = rng.chisquare(9, (RUNS, e)) * (1 + grow * (T_S / T_S[-1]) ** 2)
    z = np.zeros((RUNS, e, 3))
    return EstimatorHistory(label=label, t_s=T_S, att_err_rad=z, vel_err_mps=z, pos_err_m=z, sigma=None, nees=nees,
                            nis={"gnss_position:bd": rng.chisquare(3, (RUNS, e))}, nis_dim={"gnss_position:bd": 3},
                            diverged=np.zeros(RUNS, bool))


def _consistency_input(grows: dict):
    rng = np.random.default_rng(3)
    hs = {k: _nees_history(rng, k, g) for k, g in grows.items()}
    inside = lambda f: SimpleNamespace(fraction_inside=f)
    metrics = SimpleNamespace(estimators={k: SimpleNamespace(nees=SimpleNamespace(dim=9, fraction_inside=0.5),
                                                             nis={"gnss_position:bd": inside(0.9)}) for k in hs})
    return SimpleNamespace(histories=hs, metrics=metrics, scenario=SimpleNamespace(settle_s=60.0), spans=WINDOWS)


def _nees_axes(grows: dict):
    page = consistency.pages(_consistency_input(grows))[0]
    return page.figure.axes[0]


def _ticks(ax):
    ax.figure.canvas.draw()
    return [t.get_text() for t in ax.get_yticklabels() + ax.get_yticklabels(minor=True) if t.get_text()]


def test_a_nees_that_spans_decades_is_drawn_on_a_log_scale_with_plain_tick_labels():
    """A filter whose NEES grows to ~6e5 beside a consistent one (~9): a linear axis flattens the
    consistent one and its band to 0; the page draws the NEES on a log scale, and a panel whose
    curves stay within :data:`~navsim.report.consistency.LOG_DECADES` decades linearly."""
    both = _nees_axes({"good": 0.0, "wind neglected": 6e4})
    assert both.get_yscale() == "log"
    decades = re.compile(r"^(\$10\^\{-?\d+\}\$|[\d,]+|0\.0*1)$")          # 10^6, 1,000, 0.01; no 3.2x10^0
    assert all(decades.match(t) for t in _ticks(both)), _ticks(both)
    lo, hi = both.get_ylim()
    assert lo < 5 and hi > 5e5                           # the good filter's band (~7-11 for 3 runs) is seen
    assert _nees_axes({"good": 0.0}).get_yscale() == "linear"


def _box(text, renderer):
    patch = text.get_bbox_patch()
    return (patch or text).get_window_extent(renderer)


def _overlaps(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def test_the_consistency_notes_cover_neither_a_windows_label_nor_a_curve():
    page = consistency.pages(_consistency_input({"good": 0.0, "wind neglected": 6e4}))[0]
    fig = page.figure
    renderer = fig.canvas.get_renderer()
    fig.canvas.draw()
    for ax in fig.axes:
        texts = [t for t in ax.texts if t.get_visible() and t.get_text().strip()]
        assert texts
        boxes = [(t.get_text(), _box(t, renderer)) for t in texts]
        clash = [(a, b) for i, (a, ba) in enumerate(boxes) for b, bb in boxes[i + 1:] if _overlaps(ba, bb)]
        assert not clash, clash
        for line in ax.get_lines():
            if len(line.get_xdata()) <= 2:                # the bands and the settling time's mark
                continue
            xy = line.get_transform().transform(np.column_stack([line.get_xdata(), line.get_ydata()]))
            for name, b in boxes:
                under = (xy[:, 0] >= b.x0) & (xy[:, 0] <= b.x1)
                assert not (xy[under, 1] > b.y0).any(), f"{name!r} covers the curve {line.get_label()}"
    pyplot().close(fig)


def _wind_input():
    rng = np.random.default_rng(4)
    env = parse_environment({"wind": {"force": 4, "from_deg": 300}})
    e, runs = T_S.size, 5
    true = np.array([-3.35, 5.8, 0.0])
    est = true + rng.normal(0, 0.3, (runs, e, 3)) * np.exp(-T_S / 100)[None, :, None]
    est[..., 2] = np.nan                                  # no vertical wind state
    z = np.zeros((runs, e, 3))
    h = EstimatorHistory(label="ES-KF 22", t_s=T_S, att_err_rad=z, vel_err_mps=z, pos_err_m=z, sigma=None, nees=None,
                         nis={}, nis_dim={}, diverged=np.zeros(runs, bool), wind_n_mps=est,
                         wind_sigma_mps=np.full((runs, e, 3), 0.3))
    scenario = SimpleNamespace(flight=SimpleNamespace(environment=env))
    return SimpleNamespace(histories={"ES-KF 22": h}, scenario=scenario, truth=None, spans=WINDOWS)


def _style(artist):
    return to_rgba(artist.get_color()), round(artist.get_linewidth(), 3), artist.get_linestyle()


def test_the_wind_pages_legend_draws_each_line_as_it_is_drawn():
    """Every legend entry has a line drawn in its colour, width and style (the runs were drawn in
    colour under a grey "first 3 runs" entry); each run drawn has its entry."""
    page = wind.pages(_wind_input())[0]
    fig = page.figure
    handles = fig.legends[0].legend_handles
    drawn = {_style(line) for ax in fig.axes for line in ax.get_lines()}
    assert all(_style(h) in drawn for h in handles), [h.get_label() for h in handles if _style(h) not in drawn]
    runs = [h for h in handles if "run" in h.get_label() and "runs" not in h.get_label()]
    assert len(runs) == wind.WIND_RUNS and len({_style(h) for h in runs}) == wind.WIND_RUNS
    pyplot().close(fig)


def _euler_history(rng):
    """Errors in level flight: the Euler yaw error equals the heading error (-phi_D)."""
    runs, e = 4, T_S.size
    att = rng.normal(0, 1e-3, (runs, e, 3))
    euler = att * np.array([1.0, 1.0, -1.0])
    pos = rng.normal(0, 3, (runs, e, 3))
    return EstimatorHistory(label="KF", t_s=T_S, att_err_rad=att, vel_err_mps=np.zeros((runs, e, 3)), pos_err_m=pos,
                            sigma=None, nees=None, nis={}, nis_dim={}, diverged=np.zeros(runs, bool),
                            euler_err_rad=euler)


def test_the_windows_table_has_one_heading_row_and_says_where_the_yaw_is():
    rng = np.random.default_rng(9)
    m = score(_euler_history(rng), 0.0, WINDOWS[:1])
    assert {"heading_deg", "yaw_deg"} <= set(m.windows[WINDOWS[0][0]].quantities)    # both scored
    section = summary.windows(SimpleNamespace(estimators={"KF": m}), WINDOWS[:1])[0]
    quantities = [row[1] for row in section.rows]
    assert "heading_deg" in quantities and "yaw_deg" not in quantities
    assert "yaw_deg" in section.text


def test_the_pages_written_keep_their_text_inside(tmp_path):
    """The three pages written as PNGs: the suite's checker (``tests/conftest.py``) fails a
    saved page with text outside it or tick labels printed over each other."""
    grows = {"P0 ES-KF 16 (wind neglected)": 1e3, "ES-KF 17 (wind neglected)": 6e4, "ES-KF 22, wind + gusts": 0.0}
    pages = consistency.pages(_consistency_input(grows)) + wind.pages(_wind_input())
    for page in pages:
        page.figure.savefig(tmp_path / f"{page.name}.png", dpi=80)
        pyplot().close(page.figure)
    assert len(list(tmp_path.glob("*.png"))) == len(pages) >= 2


def test_the_log_scale_rule_measures_the_top_against_the_lowest_curve():
    """P0 in wind: ES-KF 16's NEES up to ~430 beside ES-KF 22's ~9 (1.7 decades: ES-KF 22 and
    its band flat at 0 on a linear axis) is drawn on a log scale; a curve 25 times another is not."""
    level = np.full(50, 9.0)
    assert consistency.spans_decades([level, np.linspace(100, 430, 50), [7.0, 11.0]])
    assert not consistency.spans_decades([level, np.linspace(100, 225, 50)])
    assert not consistency.spans_decades([np.full(5, np.nan), [0.0]])
