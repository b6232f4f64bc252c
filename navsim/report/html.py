"""``report.html``: a run's result to explore in a browser, beside ``report.pdf``.

Made with Bokeh rather than Plotly: time axes are linked by sharing one range object, a table
sorts by any column (``DataTable``), a widget's JavaScript callback (``CustomJS``) redraws a run
from arrays held in the page, and the file stands alone, BokehJS inlined (about 4 MB, no
network), the form of PX4's Flight Review. The page's tabs:

* **Summary**: every section of the PDF's summary (:func:`navsim.report.summary.sections`: the
  results, the 95 % intervals, the paper checks and their verdicts, consistency, ...) as tables
  that sort by a column's numbers (a cell's first number; its text as printed), then the run's
  details.
* **Flight**: the ground track, height, speeds and attitude against time (the truth).
* **Errors**: position, velocity and attitude error per axis against time, every estimator's
  Monte Carlo RMS, mean filter ±3σ and its first runs (:func:`navsim.report.errors.envelopes`),
  the metric windows and faults shaded; all time axes of the page zoom and pan together.
* **Consistency**: the average NEES and NIS over the runs against their 95 % chi-square bands,
  on a log scale where they span decades (:func:`navsim.report.consistency.spans_decades`).
* **Run picker**: any run, or the worst runs by a metric, or the diverged ones: its position error
  on each axis against its own ±3σ, its events (resets, divergence) as lines and in a table,
  the sensor faults shaded, on the same time axis as the other tabs.
  (:mod:`navsim.report.picker`).

Size: a run's traces are thinned as the PDF's are and the picker's values held in 16 bits: P0's
1000 runs make an 11 MB page. ``compare``, ``budget``, ``sweep`` and ``tune`` write a page of
their tables and plots with intervals (:func:`compare_html`, ...). The parts (escaping, sortable
tables, linked time plots) are :mod:`navsim.report.html_parts`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from bokeh.embed import file_html
from bokeh.layouts import column
from bokeh.models import ColumnDataSource, Div, LegendItem, Range1d, Span, TabPanel, Tabs
from bokeh.plotting import figure
from bokeh.resources import INLINE
from matplotlib.colors import to_hex

from navsim.flight.plots import drawn
from navsim.foundations.earth import local_ne
from navsim.foundations.outputs import write_atomic
from navsim.report import budget as budget_report, compare as compare_report
from navsim.report.consistency import quote, series_panels, spans_decades
from navsim.report.errors import AXES, envelopes, split_free
from navsim.report.figures import ReportInput, estimator_colours
from navsim.report.html_parts import (PALETTE, WIDTH, Curve, curves, esc, hide, interval_figure, legend_row,
                                      results_page, section_blocks, shade, time_figure)
from navsim.report.picker import picker_tab
from navsim.report.summary import Section, run_details, sections, windows
from navsim.scoring.verdicts import with_interval

def write_html(path: Path, inp: ReportInput) -> None:
    """Write the page of the run ``inp`` to ``path`` (under a temporary name, then renamed; the
    caller has recorded it in its output folder's manifest)."""
    text = report_html(inp)
    write_atomic(path, lambda p: p.write_text(text, encoding="utf-8"))


def report_html(inp: ReportInput) -> str:
    """The whole page of the run ``inp``, one self-contained HTML string."""
    time_range = Range1d(*_time_span(inp))
    tabs = [TabPanel(title="Summary", child=summary_tab(inp))]
    if inp.truth is not None:
        tabs.append(TabPanel(title="Flight", child=flight_tab(inp, time_range)))
    if inp.histories:
        tabs.append(TabPanel(title="Errors", child=errors_tab(inp, time_range)))
        for title, panel in (("Consistency", consistency_tab(inp, time_range)),
                             ("Run picker", picker_tab(inp, time_range))):
            if panel is not None:
                tabs.append(TabPanel(title=title, child=panel))
    page = column(Div(text=f"<h1>navsim report: {esc(inp.scenario.name)}</h1>"), Tabs(tabs=tabs))
    return file_html(page, INLINE, title=f"navsim report: {inp.scenario.name}")


def _time_span(inp: ReportInput) -> tuple[float, float]:
    ts = [h.t_s for h in inp.histories.values() if len(h.t_s)]
    if inp.truth is not None:
        ts.append(inp.truth.t_s)
    if not ts:
        return 0.0, 1.0
    lo, hi = min(float(np.nanmin(t)) for t in ts), max(float(np.nanmax(t)) for t in ts)
    return (lo, hi) if hi > lo else (lo, lo + 1.0)


def summary_tab(inp: ReportInput):
    """The description, every summary section and the metric windows as sortable tables, the
    run's details."""
    sc = inp.scenario
    parts = [Div(text=f"<p style='max-width:{WIDTH}px'>{esc(sc.description.strip() or '(no description)')}</p>")]
    for s in sections(inp.metrics, sc) + windows(inp.metrics, sc.windows):
        parts += section_blocks(s)
    parts.append(Div(text=f"<h3>Run</h3><p style='max-width:{WIDTH}px'>{esc(run_details(sc, inp.record))}</p>"))
    return column(*parts)


def flight_tab(inp: ReportInput, time_range):
    """The ground track (north against east, equal scales) and the truth against time."""
    tr = inp.truth
    north, east = local_ne(tr.lat_rad, tr.lon_rad, tr.lat_rad[0], tr.lon_rad[0])
    track = figure(title="Ground track (north against east, from the start)", width=560, height=560,
                   match_aspect=True, x_axis_label="east, m", y_axis_label="north, m",
                   tools="pan,wheel_zoom,box_zoom,reset,save")
    track.toolbar.logo = None
    k = drawn(north)
    track.line(east[k], north[k], line_width=1.5)
    speeds = [("true airspeed", tr.tas_mps)] if not np.isnan(tr.tas_mps).all() else []
    plots = (("Height", "m", [("height (ellipsoid)", tr.h_m)]),
             ("Speed", "m/s", speeds + [("ground speed", np.hypot(tr.vel_n_mps[:, 0], tr.vel_n_mps[:, 1]))]),
             ("Attitude", "deg", [(n, np.degrees(tr.euler_rad[:, j])) for j, n in enumerate(("roll", "pitch", "heading"))]))
    figs = []
    for title, unit, lines in plots:
        fig = time_figure(title, unit, time_range)
        legend_row(fig, [LegendItem(label=name, renderers=[curves(fig, PALETTE[i], [Curve(tr.t_s, y, 1.5)])])
                      for i, (name, y) in enumerate(lines)])
        shade(fig, inp)
        figs.append(fig)
    return column(track, *figs)


def errors_tab(inp: ReportInput, time_range):
    """Per quantity and axis: every estimator's RMS (solid), mean ±3σ (dashed) and first runs
    (thin); a free-inertial estimator whose errors would flatten the others' (as the PDF puts
    on axes of its own, :func:`navsim.report.errors.split_free`) starts hidden; a legend entry
    shows or hides an estimator, the y range follows."""
    colours = {k: to_hex(c) for k, c in estimator_colours(inp.histories).items()}
    settle_s = inp.scenario.settle_s
    figs, hidden = [], set()
    for key, (title, unit, names) in AXES.items():
        env = {k: e for k, h in inp.histories.items() if (e := envelopes(h, key)) is not None}
        hidden |= set(split_free(env, (settle_s, np.inf))[1])
        for j, axis in enumerate(names):
            fig = time_figure(f"{title[0].upper() + title[1:]}, {axis}", unit, time_range)
            items = []
            for label, (rms, sig, err, t) in env.items():
                lines = [Curve(t, sgn * rms[:, j], 2.0) for sgn in (1, -1)]           # the first: the legend's
                lines += [Curve(t, sgn * 3 * sig[:, j], 1.0, 1.0, "dashed") for sgn in (1, -1)] if sig is not None else []
                lines += [Curve(t, err[r, :, j], 0.5, 0.35) for r in range(min(inp.runs_plotted, err.shape[0]))]
                line = curves(fig, colours[label], lines)
                hide([line], label in hidden)
                items.append(LegendItem(label=label, renderers=[line]))
            legend_row(fig, items)
            shade(fig, inp)
            fig.add_layout(Span(location=settle_s, dimension="height", line_color="#666666", line_dash="dotted"))
            figs.append(fig)
    note = (f"Thick: the Monte Carlo RMS over the runs that did not diverge; dashed: ±3 × the filter's RMS sigma; "
            f"thin: the first {inp.runs_plotted} runs; dotted: the settling time ({settle_s:g} s); orange: metric "
            "windows. Drag to pan; the wheel zooms time on every plot of the report at once; a legend entry shows or "
            "hides its estimator")
    note += (f" ({', '.join(sorted(hidden))}: hidden at first, its errors would flatten the others')." if hidden
             else ".")
    return column(Div(text=f"<p style='max-width:{WIDTH}px'>{esc(note)}</p>"), *figs)


def consistency_tab(inp: ReportInput, time_range):
    """The average NEES and each NIS over the runs against their 95 % bands (dashed), the
    scorer's share of epochs inside in the legend; None without a filter that has them."""
    filters = {k: h for k, h in inp.histories.items() if h.nees is not None}
    panels = series_panels(inp, filters, PALETTE)
    if not panels:
        return None
    figs = []
    for ylabel, series in panels:
        log = spans_decades([v for s in series for v in (s.y, [s.lo, s.hi])])
        fig = time_figure(ylabel.replace("\n", ", "), "log scale" if log else "", time_range,
                          y_axis_type="log" if log else "linear")
        items = []
        for s in series:
            y = np.where(np.asarray(s.y, float) > 0, s.y, np.nan) if log else s.y
            ends = np.array([float(time_range.start), float(time_range.end)])
            line = curves(fig, s.colour, [Curve(s.t, y, 1.2)] + [Curve(ends, np.array([v, v]), 1.0, 1.0, "dashed")
                                                                 for v in (s.lo, s.hi)])
            items.append(LegendItem(label=f"{s.label}: {quote(s.score)}, band {s.lo:.3g}-{s.hi:.3g}",
                                    renderers=[line]))
        legend_row(fig, items)
        shade(fig, inp)
        figs.append(fig)
    return column(Div(text="<p>Average over the runs that did not diverge, against the 95 % band of an average of "
                           "that many chi-square values (dashed); the share of epochs inside is the scorer's, from "
                           "the settling time on; a log scale where the curves span decades.</p>"), *figs)


def compare_html(comparisons: list) -> str:
    """``compare.html``: each comparison's table (B - A per metric with its interval and
    verdict) and its differences relative to A with their intervals."""
    sections, figures = [], []
    for c in comparisons:
        sections.append(Section(compare_report.headline(c), "", list(compare_report.HEADERS),
                                compare_report.text_rows(c)))
        rel = [d for d in c.differences if np.isfinite(d.relative) and d.a]
        if rel:
            ends = [sorted((100 * d.ci95[0] / d.a, 100 * d.ci95[1] / d.a)) for d in rel]   # (B - A) / A, as its value
            figures.append(interval_figure(
                f"B - A relative to A: {c.b.estimator} against {c.a.estimator}", "B - A, % of A", [d.name for d in rel],
                [100 * d.relative for d in rel], [lo for lo, _ in ends], [hi for _, hi in ends],
                [compare_report.COLOURS.get(d.verdict, PALETTE[0]) for d in rel]))
    return results_page("navsim compare", "B - A of each metric with its 95 % interval (runs paired where both sides "
                        "flew the same runs); the verdicts as printed on the terminal.", sections, figures)


def budget_html(b, metrics=None) -> str:
    """``budget.html``: each metric's budget table (a source alone, its contribution and share
    with their intervals) and its shares with their intervals."""
    heads = list(budget_report.headers(b))
    sections, figures = [], []
    for m in budget_report.chosen(b, metrics):
        rows = budget_report.text_rows(m, heads) + budget_report.left_out_rows(b, m, heads)
        sections.append(Section(f"{m.estimator}: {m.name}", budget_report.check_text(m), heads, rows))
        lines = [x for x in m.lines if np.isfinite(x.share)]
        if lines:
            lo_hi = [x.share_ci95 if np.all(np.isfinite(x.share_ci95)) else (x.share, x.share) for x in lines]
            figures.append(interval_figure(f"{m.estimator}: {m.name}, each source's share", "share, %",
                                           [x.source for x in lines], [100 * x.share for x in lines],
                                           [100 * lo for lo, _ in lo_hi], [100 * hi for _, hi in lo_hi]))
    intro = f"Error budget of {b.scenario} ({b.method}); " + "; ".join(budget_report.covariance_notes(b) or ["-"])
    return results_page(f"navsim budget {b.scenario}", intro, sections, figures)


def sweep_html(sweep) -> str:
    """``sweep.html``: one row per point (its parameters, each estimator's metric and 95 %
    interval) and the metric against the first parameter, per estimator."""
    keys, labels = list(sweep.axes()), list(sweep.rows[0][1]) if sweep.rows else []
    rows = []
    for n, (point, vals) in enumerate(sweep.rows):
        cells = [str(n + 1)] + [str(point.get(k)) for k in keys]
        for lb in labels:
            iv = sweep.interval(n, lb)
            cells.append(with_interval(vals.get(lb), None if iv is None else [iv]))
        rows.append(cells)
    sections = [Section(f"{sweep.metric} at each point", "", ["point", *keys, *labels], rows)]
    figures = []
    if keys and all(isinstance(p.get(keys[0]), (int, float)) for p, _ in sweep.rows):
        fig = figure(title=f"{sweep.metric} against {keys[0]}", width=WIDTH, height=400, x_axis_label=keys[0],
                     y_axis_label=sweep.metric, tools="pan,wheel_zoom,box_zoom,reset,save,hover")
        fig.toolbar.logo = None
        items = []
        for i, lb in enumerate(labels):
            x = [float(p[keys[0]]) for p, _ in sweep.rows]
            v = [_finite(vals.get(lb)) for _, vals in sweep.rows]
            iv = [sweep.interval(n, lb) or [np.nan, np.nan] for n in range(len(sweep.rows))]
            src = ColumnDataSource({"x": x, "v": v, "lo": [_finite(a) for a, _ in iv], "hi": [_finite(b) for _, b in iv]})
            c = PALETTE[i % len(PALETTE)]
            items.append(LegendItem(label=lb, renderers=[
                fig.scatter("x", "v", source=src, size=7, color=c),
                fig.segment(x0="x", y0="lo", x1="x", y1="hi", source=src, line_color=c, line_width=2)]))
        legend_row(fig, items)
        figures.append(fig)
    intro = (f"{len(sweep.rows)} points" + (f", {len(sweep.failed_points)} failed" if sweep.failed_points else "")
             + (", interrupted" if sweep.interrupted else "") + "; each value with its 95 % interval.")
    return results_page(f"navsim sweep: {sweep.metric}", intro, sections, figures)


def tune_html(r, params: list) -> str:
    """``tune.html``: every trial (its objective, parameters and scores) and the objective
    against the trial, the best marked."""
    heads = ["trial", "objective", *[p.what for p in params], "RMS position N E D, m", "NEES average", "wall, s"]
    rows = [[str(t.number), f"{t.objective:.4g}", *[f"{t.values[p.name]:.4g}" for p in params],
             " ".join(f"{v:.3g}" for v in (t.rms_pos_m or [])) or "-",
             "-" if t.nees_average is None else f"{t.nees_average:.3g}", f"{t.wall_s:.2f}"] for t in r.trials]
    fig = figure(title=f"{r.objective} against the trial (lower is better)", width=WIDTH, height=360,
                 x_axis_label="trial", y_axis_label="objective", tools="pan,wheel_zoom,box_zoom,reset,save,hover")
    fig.toolbar.logo = None
    fig.scatter([t.number for t in r.trials], [_finite(t.objective) for t in r.trials], size=7, color=PALETTE[0])
    best = [t for t in r.trials if t.number == r.best]
    if best:
        fig.scatter([best[0].number], [_finite(best[0].objective)], size=14, marker="star", color=PALETTE[3])
    return results_page(f"navsim tune: {r.estimator}", f"{len(r.trials)} trials; the best: trial {r.best}.",
                        [Section("Trials", "", heads, rows)], [fig])


def _finite(v) -> float:
    return float(v) if v is not None and np.isfinite(v) else np.nan
