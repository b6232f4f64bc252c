"""The parts of navsim's interactive pages (Bokeh): escaped text, sortable tables, time plots
on a shared axis with their legend, shaded windows and thinned curves, and a page of tables and
plots; :mod:`navsim.report.html` and :mod:`navsim.report.picker` build the pages from them.

Text a user wrote (the scenario's name and description, labels, window and sensor names) is
escaped wherever it goes: ``html.escape`` into the HTML of a text block, a table's cells through
an escaping template (``<%- %>``), titles and legends as plain text; Bokeh writes the
document's JSON so that no ``</script>`` ends it early.
"""

from __future__ import annotations

import html
import re
from typing import NamedTuple

import numpy as np
from bokeh.embed import file_html
from bokeh.layouts import column
from bokeh.models import (ColumnDataSource, DataRange1d, DataTable, Div, HTMLTemplateFormatter, Legend, MultiLine,
                          Span, TabPanel, Tabs, TableColumn, VStrip)
from bokeh.plotting import figure
from bokeh.resources import INLINE

from navsim.flight.plots import drawn
from navsim.report.figures import ReportInput

#: a figure's size on the page, pixels
WIDTH, HEIGHT = 1100, 260
#: the first number of a table cell (its sort key)
_NUMBER = re.compile(r"[-+]?(?:\d[\d,]*\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
#: a table's width per character of its longest cell, pixels
CHAR_PX = 7
#: the colours of a plot's curves (matplotlib's tab10, as the PDF's)
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")


def esc(text) -> str:
    """``text`` escaped for HTML (quotes too)."""
    return html.escape(str(text), quote=True)


# --- tables -------------------------------------------------------------------------------------
def sort_key(cell: str) -> float:
    """A cell's sort key: its first number (``"2.35 [2.28, 2.42]"`` -> 2.35), NaN without one."""
    m = _NUMBER.search(str(cell).replace("−", "-"))
    if m is None:
        return float("nan")
    try:
        return float(m.group(0).replace(",", ""))
    except ValueError:
        return float("nan")


def table(headers: list[str], rows: list[list[str]]) -> DataTable:
    """A sortable table: column ``i`` sorts by its cells' first numbers where every cell has
    one (else by text) and shows each cell's text, escaped; a first column left blank under
    its value (the PDF's grouping) repeats it, so that a row sorted elsewhere keeps its name."""
    data, columns, total = {}, [], 0
    rows = [list(r) for r in rows]
    for above, r in zip(rows, rows[1:]):
        if r and not str(r[0]).strip() and above:
            r[0] = above[0]
    for i, head in enumerate(headers):
        cells = [str(r[i]) if i < len(r) else "" for r in rows]
        keys = [sort_key(c) for c in cells]
        numeric = all(np.isfinite(k) or c.strip() in ("", "-") for k, c in zip(keys, cells)) and any(
            np.isfinite(keys))
        data[f"c{i}"] = cells
        data[f"k{i}"] = [k if np.isfinite(k) else -np.inf for k in keys] if numeric else cells
        width = CHAR_PX * max([len(head.replace("\n", " "))] + [len(c) for c in cells]) + 20
        total += width
        columns.append(TableColumn(field=f"k{i}", title=esc(head.replace("\n", " ")), width=width,   # shown as HTML
                                   formatter=HTMLTemplateFormatter(template=f"<%- c{i} %>")))
    height = min(36 + 25 * max(len(rows), 1), 640)
    return DataTable(source=ColumnDataSource(data), columns=columns, width=max(total, 300), height=height,
                     index_position=None, sortable=True, reorderable=False, autosize_mode="none")


def section_blocks(s) -> list:
    """A :class:`~navsim.report.summary.Section` as blocks: its title and text, its table, its
    note."""
    out = [Div(text=f"<h3>{esc(s.title)}</h3>" + (f"<p style='max-width:{WIDTH}px'>{esc(s.text)}</p>"
                                                    if s.text else ""))]
    if s.rows:
        out.append(table(s.headers, s.rows))
    if s.note:
        out.append(Div(text=f"<p style='max-width:{WIDTH}px'>{esc(s.note)}</p>"))
    return out


# --- figures ------------------------------------------------------------------------------------
def time_figure(title: str, y_label: str, time_range, **kw):
    """A time plot on the report's shared time axis, its y range fitted to the lines shown (a
    line hidden from its legend entry leaves it)."""
    fig = figure(title=title, width=WIDTH, height=HEIGHT, x_range=time_range, x_axis_label="time, s",
                 y_axis_label=y_label, y_range=DataRange1d(only_visible=True),
                 tools="xpan,xwheel_zoom,box_zoom,reset,save", **kw)
    fig.toolbar.logo = None
    return fig


def legend_row(fig, items: list) -> None:
    """The legend in a row above the plot, a click on an entry hides its lines."""
    fig.add_layout(Legend(items=items, click_policy="hide", label_text_font_size="9pt", orientation="horizontal",
                          padding=2, margin=2), "above")


def shade(fig, inp: ReportInput, faults: bool = False) -> None:
    """The metric windows (orange), the landmark sightings (green) and, with ``faults``, the
    sensors' fault windows (red) on ``fig``, as one renderer."""
    spans = [(span[1], span[2], "green" if len(span) > 3 else "orange") for span in inp.spans]
    spans += [(f.start_s, f.end_s, "red") for _, f in faults_of(inp)] if faults else []
    if spans:
        x0, x1, colour = zip(*spans)
        fig.add_glyph(ColumnDataSource({"x0": list(x0), "x1": list(x1), "c": list(colour)}),
                      VStrip(x0="x0", x1="x1", fill_color="c", fill_alpha=0.12, line_alpha=0))


def faults_of(inp: ReportInput) -> list:
    """``(sensor name, fault)`` of every sensor fault with a time window."""
    return [(c.name, f) for c in inp.scenario.sensors for f in getattr(c, "faults", ())
            if getattr(f, "start_s", None) is not None and getattr(f, "end_s", None) is not None]


class Curve(NamedTuple):
    """One curve of a plot: ``y`` against ``t``, its line's width, opacity and dash."""

    t: np.ndarray
    y: np.ndarray
    width: float = 1.0
    alpha: float = 1.0
    dash: str = "solid"


def curves(fig, colour: str, lines: list):
    """The :class:`Curve` ``lines`` in one colour as one renderer (one ``MultiLine``, each curve
    thinned by :func:`~navsim.flight.plots.drawn`, its style a column): Bokeh's time to write a
    page grows with its objects, about 10 a renderer."""
    picked = [drawn(c.y) for c in lines]
    data = {"xs": [np.asarray(c.t, float)[k] for c, k in zip(lines, picked)],
            "ys": [np.asarray(c.y, float)[k] for c, k in zip(lines, picked)],
            "w": [c.width for c in lines], "a": [c.alpha for c in lines], "d": [c.dash for c in lines]}
    return fig.add_glyph(ColumnDataSource(data), MultiLine(xs="xs", ys="ys", line_color=colour, line_width="w",
                                                           line_alpha="a", line_dash="d"))


def hide(renderers: list, hidden: bool) -> None:
    """Show the ``renderers``, or hide them (a legend entry shows them again)."""
    for r in renderers:
        r.visible = not hidden


# --- the pages of compare, budget, sweep and tune -----------------------------------------------
def results_page(title: str, intro: str, sections: list, figures: list = ()) -> str:
    """A self-contained page of tables (:class:`~navsim.report.summary.Section`, sortable) and,
    in a second tab, interactive figures: what ``compare``, ``budget``, ``sweep`` and ``tune``
    write beside their PDF."""
    tables = [Div(text=f"<p style='max-width:{WIDTH}px'>{esc(intro)}</p>")]
    tables += [b for s in sections for b in section_blocks(s)]
    tabs = [TabPanel(title="Tables", child=column(*tables))]
    if figures:
        tabs.append(TabPanel(title="Plots", child=column(*figures)))
    return file_html(column(Div(text=f"<h1>{esc(title)}</h1>"), Tabs(tabs=tabs)), INLINE, title=title)


def interval_figure(title: str, x_label: str, names: list[str], values, lows, highs, colours=None):
    """One row per name: its value (a dot) and 95 % interval (a bar), a dashed line at 0; a data
    tip names the row."""
    y = [str(n) for n in names]
    fig = figure(title=title, y_range=list(reversed(y)), width=WIDTH, height=60 + 24 * len(y), x_axis_label=x_label,
                 tools="xpan,xwheel_zoom,box_zoom,reset,save,hover", tooltips=[("", "@y"), ("value", "@v"),
                                                                            ("95 %", "[@lo, @hi]")])
    fig.toolbar.logo = None
    src = ColumnDataSource({"y": y, "v": list(values), "lo": list(lows), "hi": list(highs),
                            "c": list(colours or [PALETTE[0]] * len(y))})
    fig.hbar(y="y", left="lo", right="hi", height=0.35, source=src, fill_color="c", fill_alpha=0.35, line_alpha=0)
    fig.scatter(x="v", y="y", source=src, size=8, color="c")
    fig.add_layout(Span(location=0, dimension="height", line_color="#666666", line_dash="dashed"))
    return fig
