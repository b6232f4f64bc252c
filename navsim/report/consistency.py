"""Consistency: the average NEES and NIS over the runs against their chi-square bands, each
panel quoting the scorer's share of epochs inside (from the settling time on, every run
counted), not a share of its own.

The rule every report page follows for its y scale is declared here (:func:`log_scale_if_wide`):
a plot whose largest value is more than :data:`LOG_DECADES` decades above one of its curves is
drawn on a log scale (on a linear one a consistent filter's NEES of ~9 beside a diverging one's
6e5 flattens to 0, band and all), its ticks labelled as plain numbers at the decades, and at 2 and 5 times them on an axis
of few decades ("0.2", "1", "5"; "10⁶" on an axis reaching 10⁵; never "3.2×10⁰")."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter

from navsim.report.figures import Page, ReportInput, head, legend_columns, page_figure, pyplot, shade
from navsim.report.summary import pct
from navsim.report.tables import text_width_in
from navsim.scoring.stats import chi2_band

#: the most panels on one consistency page (more go to the next)
PANELS_PER_PAGE = 5
#: a plot is drawn on a log scale where its largest value is more than this many decades above
#: the low level of one of its curves (:func:`spans_decades`): on a linear axis that curve
#: would lie within 3 % of its height, flat at 0
LOG_DECADES = 1.5
#: a curve's low level: this percentile of its positive values (one epoch's near-zero average
#: NIS does not make a log scale)
LOW_PERCENTILE = 10
#: a log axis whose top reaches this value labels its decades as powers of ten, else as plain numbers
PLAIN_BELOW = 1e5
#: a log axis with fewer decades than this inside it labels 2 and 5 times each decade too
MINOR_LABELS_BELOW = 3
#: a panel's notes (the shares of epochs inside): font size, points; left edge and top, a share
#: of the axes; the gap kept under them and under the windows' labels, inches
NOTE_PT = 7.0
NOTE_AT = (0.01, 0.97)
NOTE_GAP_IN = 0.04
#: a text's line height, in font sizes, and its box's pad (matplotlib's default), points
LINE_HEIGHT, BOX_PAD_PT = 1.25, 4.0


def spans_decades(curves, decades: float = LOG_DECADES) -> bool:
    """Whether the largest positive finite value of ``curves`` (arrays of any shape: a curve, a
    band's edges) is more than ``decades`` decades above the lowest curve's low level (its
    :data:`LOW_PERCENTILE` th percentile)."""
    kept = [v[np.isfinite(v) & (v > 0)] for v in (np.ravel(np.asarray(c, float)) for c in curves)]
    kept = [v for v in kept if v.size]
    if not kept:
        return False
    top, low = max(v.max() for v in kept), min(np.percentile(v, LOW_PERCENTILE) for v in kept)
    return bool(np.log10(top / low) > decades)


def _plain(v: float) -> str:
    """``v`` as a plain number: ``0.02``, ``5``, ``1,000``."""
    return f"{v:,.0f}" if v >= 1 else f"{v:g}"


def minor_label(v: float, lo: float, hi: float) -> str:
    """A log axis' tick label between decades: ``2`` and ``5`` times a decade, as plain numbers,
    on an axis from ``lo`` to ``hi`` with fewer than :data:`MINOR_LABELS_BELOW` decades inside
    and under :data:`PLAIN_BELOW` (one or two labelled ticks cannot be read); else none."""
    inside = np.floor(np.log10(hi) + 1e-9) - np.ceil(np.log10(lo) - 1e-9) + 1
    if v <= 0 or hi >= PLAIN_BELOW or inside >= MINOR_LABELS_BELOW:
        return ""
    m = v / 10 ** np.floor(np.log10(v) + 1e-9)
    return _plain(v) if min(abs(m - 2), abs(m - 5)) < 1e-6 else ""


def decade_label(v: float, top: float) -> str:
    """A log axis' tick label at the decade ``v``: a plain number (``0.01``, ``1``, ``100``,
    ``10,000``) on an axis whose top is under :data:`PLAIN_BELOW`, else the power of ten
    (``10⁶``: ``10,000,000,000`` would push the axis' label off the page)."""
    if top >= PLAIN_BELOW or v < 1e-3:
        return f"$10^{{{round(np.log10(v))}}}$"
    return _plain(v)


def log_scale_if_wide(ax, values) -> bool:
    """Draw ``ax``'s y axis on a log scale where ``values`` (the curves it plots, a band's edges
    as one) span decades (:func:`spans_decades`), its ticks labelled by :func:`decade_label` and
    :func:`minor_label`; else keep it linear, without an offset or a power of ten. Returns
    whether the scale is log."""
    if not spans_decades(values):
        ax.ticklabel_format(axis="y", style="plain", useOffset=False)
        return False
    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: decade_label(v, ax.get_ylim()[1])))
    ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _pos: minor_label(v, *ax.get_ylim())))
    return True


@dataclass(frozen=True)
class _Series:
    """One average NEES or NIS curve: the drawn runs' average ``y`` at ``t``, its band ``lo``,
    ``hi`` for those runs, and the scorer's statistic (``score``: its ``fraction_inside``)."""

    label: str
    t: np.ndarray
    y: np.ndarray
    lo: float
    hi: float
    colour: object
    marker: str
    score: object


def _band(ax, lo: float, hi: float, colour) -> None:
    """A 95 % band as two dashed lines (no fill: the windows' shading stays readable)."""
    for y in (lo, hi):
        ax.axhline(y, color=colour, lw=0.9, ls="--", alpha=0.8)


def series_panels(inp: ReportInput, filters: dict, colours) -> list:
    """``(ylabel, [_Series])`` per panel: the NEES of every filter together, then each filter's
    NIS per measurement (only the statistics the scorer has)."""
    nees, nis = [], []
    for c, (label, h) in enumerate(filters.items()):
        m = inp.metrics.estimators.get(label)
        good = ~np.asarray(h.diverged, bool)
        n = int(good.sum())
        if n == 0 or m is None or m.nees is None:
            continue
        lo, hi = chi2_band(m.nees.dim, n)
        nees.append(_Series(label, h.t_s[1:], np.nanmean(h.nees[good], axis=0)[1:], lo, hi, colours[c % 10], "-",
                            m.nees))
        for key, v in h.nis.items():
            if key not in (m.nis or {}):
                continue
            d, v = h.nis_dim[key], v[good]
            cols = ~np.isnan(v).all(axis=0)
            lo, hi = chi2_band(d, n)
            nis.append((f"NIS {key}, dim {d}\n{label}",
                        [_Series(label, h.t_s[cols], np.nanmean(v[:, cols], axis=0), lo, hi, colours[c % 10], ".",
                                 m.nis[key])]))
    return ([("average NEES, dim 9\n(att, vel, pos)", nees)] if nees else []) + nis


def quote(score) -> str:
    """The scorer's share of epochs inside the band, as a consistency panel prints it."""
    return f"{pct(score.fraction_inside)} of epochs inside"


def _axes_in(ax) -> tuple[float, float]:
    """The axes' width and height, inches."""
    box, (w, h) = ax.get_position(), ax.figure.get_size_inches()
    return box.width * w, box.height * h


def _text_height_in(text) -> float:
    """What a text of ``text``'s lines and font size takes in height, its box's pad included."""
    pad = 2 * BOX_PAD_PT if text.get_bbox_patch() is not None else 0.0
    return ((text.get_text().count("\n") + 1) * LINE_HEIGHT * text.get_fontsize() + pad) / 72


def _x_extent(ax, text, w_in: float) -> tuple[float, float]:
    """A text's horizontal extent with its box, a share of the axes' width (a window's label is
    centred on its span's middle, in data units; the notes start at their left edge)."""
    pad = (BOX_PAD_PT / 72 if text.get_bbox_patch() is not None else 0.0) / w_in
    width = text_width_in(text.get_text(), text.get_fontsize()) / w_in
    x = text.get_position()[0]
    if text.get_transform() is not ax.transAxes:
        lo, hi = ax.get_xlim()
        x = (x - lo) / (hi - lo)
    x0 = x - width / 2 if text.get_ha() == "center" else x
    return x0 - pad, x0 + width + pad


def make_room(ax, note) -> None:
    """Put ``note`` (its box) at the top left of ``ax``, under the windows' labels where one
    stands above it, and raise the y limit so that the curves keep below both: nothing overlaps."""
    w_in, h_in = _axes_in(ax)
    labels = [t for t in ax.texts if t is not note and t.get_text().strip()]
    a, b = _x_extent(ax, note, w_in)
    top = NOTE_AT[1]
    row = max((_text_height_in(t) for t in labels), default=0.0)
    if any(x0 < b and a < x1 for x0, x1 in (_x_extent(ax, t, w_in) for t in labels)):
        top -= (row + NOTE_GAP_IN) / h_in
    note.set_y(top - BOX_PAD_PT / 72 / h_in)            # the box's top at ``top``
    clear = min(top - _text_height_in(note) / h_in, NOTE_AT[1] - row / h_in) - NOTE_GAP_IN / h_in
    lo, hi = ax.get_ylim()
    if ax.get_yscale() == "log":
        lo, hi = np.log10(lo), np.log10(hi)
        ax.set_ylim(10 ** lo, 10 ** (lo + (hi - lo) / clear))
    else:
        ax.set_ylim(lo, lo + (hi - lo) / clear)


def _draw_panel(ax, series: list, ylabel: str, spans, label_windows: bool):
    """One panel's curves and bands (a log scale where they span decades), the windows shaded,
    and its notes (returned, placed by :func:`make_room` once the page is laid out)."""
    log_scale_if_wide(ax, [v for s in series for v in (s.y, [s.lo, s.hi])])
    notes = []
    for s in series:
        ax.plot(s.t, s.y, s.marker, ms=2, lw=1.2, color=s.colour)
        _band(ax, s.lo, s.hi, s.colour)
        notes.append(f"{s.label}: {quote(s.score)}" if len(series) > 1 else quote(s.score))
    shade(ax, spans, label=label_windows)
    ax.set_ylabel(ylabel, fontsize=7.5)
    ax.grid(alpha=0.3)
    return panel_note(ax, "\n".join(notes))


def panel_note(ax, text: str):
    """A note at the top left of a panel, in a white box; :func:`make_room` places it once the
    page is laid out."""
    return ax.text(*NOTE_AT, text, transform=ax.transAxes, fontsize=NOTE_PT, va="top",
                   bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})


def pages(inp: ReportInput) -> list[Page]:
    """The average NEES and NIS over the runs against their two-sided 95 % chi-square bands
    (dashed), each panel quoting the scorer's share of epochs inside; :data:`PANELS_PER_PAGE` a
    page; a panel whose curves span decades on a log scale (:func:`log_scale_if_wide`)."""
    filters = {k: h for k, h in inp.histories.items() if h.nees is not None}
    colours = pyplot().cm.tab10(np.arange(10))
    panels = series_panels(inp, filters, colours)
    settle_s = inp.scenario.settle_s
    out = []
    for start in range(0, len(panels), PANELS_PER_PAGE):
        page = panels[start:start + PANELS_PER_PAGE]
        fig, axs = page_figure(len(page), 1, sharex=True, squeeze=False)
        notes = []
        for ax, (ylabel, series) in zip(axs[:, 0], page):
            notes.append(_draw_panel(ax, series, ylabel, inp.spans, ax is axs[0, 0]))
            ax.axvline(settle_s, color="0.4", lw=0.8, ls=":")
        axs[-1, 0].set_xlabel("time, s")
        axs[0, 0].set_title(f"the shares of epochs inside, as scored (metrics.json): from {settle_s:g} s on, over "
                            "every run that did not diverge", fontsize=7.5, loc="left", color="0.3")
        handles = [Line2D([], [], color=colours[c % 10], lw=1.2, label=k) for c, k in enumerate(filters)]
        handles += [Line2D([], [], color="0.4", lw=0.9, ls="--", label="95 % chi-square band of the average"),
                    Line2D([], [], color="0.4", lw=0.8, ls=":", label=f"settling time {settle_s:g} s")]
        title = "Consistency: the average NEES and NIS over the runs" + (" (continued)" if start else "")
        head(fig, title, handles, min(len(handles), legend_columns(filters)))
        for ax, note in zip(axs[:, 0], notes):
            make_room(ax, note)
        out.append(Page("consistency" if not start else f"consistency_{start // PANELS_PER_PAGE + 1}", title, fig))
    return out
