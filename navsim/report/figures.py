"""What every report figure shares: pyplot on the Agg backend, one page size, the estimators'
colours, the shading of metric windows and landmark sightings, the mean over runs that a
landed closed-loop run leaves NaN."""

from __future__ import annotations

import re
import textwrap
import warnings
from dataclasses import dataclass, field

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from navsim.records.run import RunRecord
from navsim.report.tables import PAGE_IN, text_width_in
from navsim.records.metrics import RunMetrics

#: every page of a report: A4 portrait (the text pages' size), inches
FIGURE_IN = PAGE_IN
#: the strip kept free at the foot of every page for its number, inches
FOOTER_IN = 0.4


@dataclass(frozen=True)
class Page:
    """One page of a report: ``name`` the stem of its PNG, ``title`` its line in the contents."""

    name: str
    title: str
    figure: Figure = field(repr=False)


@dataclass(frozen=True)
class ReportInput:
    """What a page source reads: the scenario, the flight (``truth``, None where none is drawn),
    the run's histories and records (``result``: a :class:`navsim.api.Result` or anything with
    ``histories``, ``truth_bias`` and ``calibration``), the scorer's numbers (``metrics``: every
    statistic a page prints comes from there), the run's record, and for a closed loop its
    per-run outcomes and truth-guided flight; ``sightings`` the landmark sightings
    ``(name, start_s, end_s, sigma_m)``."""

    scenario: object
    truth: object
    result: object
    metrics: RunMetrics
    record: RunRecord
    loop: object = None
    reference: object = None
    sightings: tuple = ()

    @property
    def histories(self) -> dict:
        return self.result.histories

    @property
    def runs_plotted(self) -> int:
        return self.scenario.report.get("runs_plotted", 5)

    @property
    def spans(self) -> tuple:
        """The metric windows and the landmark sightings, shaded on the time plots."""
        return tuple(self.scenario.windows) + tuple(self.sightings)


def pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def page_figure(rows: int = 1, cols: int = 1, **kw):
    """``(figure, axes)`` of one report page (:data:`FIGURE_IN`): ``Figure.subplots`` on a page
    of its own, not held by pyplot (a report of more than 20 pages opens none there; a page is
    freed when dropped)."""
    fig = Figure(figsize=FIGURE_IN)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(rows, cols, **kw)


#: a page's fixed margins, inches: left of the axes (tick labels and the y label), right of
#: them, below them (tick labels and the x label), between two rows (tick marks), and what a
#: row's x tick labels and label, and a panel's title, add above the next; between two columns
#: (the next column's tick labels and y label)
MARGIN_IN = {"left": 0.95, "right": 0.3, "bottom": 0.55, "row": 0.3, "xlabels": 0.45, "title": 0.25,
             "column": 0.95}


#: what the first column's y tick labels and y label need beside their texts, inches: room to
#: the page's edge, the tick marks with the labels' pad, the y label's pad
LABEL_ROOM_IN = {"edge": 0.1, "ticks": 0.1, "label": 0.06}
#: a line of text's height, in font sizes
TEXT_LINE = 1.2


def _plain(text: str) -> str:
    """A tick label's mathtext (``$\\mathdefault{2.95\\times10^{0}}$``) as the characters it
    draws, near enough to measure."""
    return re.sub(r"\\mathdefault|[{}$^]", "", text.replace("\\times", "\u00d7").replace("\\minus", "-"))


def y_labels_in(ax) -> float:
    """What ``ax``'s y tick labels (those inside its limits, as its formatters give them at its
    limits now) and its y label take left of it, inches, measured character by character
    (:func:`~navsim.report.tables.text_width_in`), nothing drawn."""
    lo, hi = sorted(ax.get_ylim())
    pad = 1e-9 * abs(hi - lo)
    ticks = [t for t in ax.get_yticklabels() + ax.get_yticklabels(minor=True)
             if t.get_visible() and t.get_text().strip() and lo - pad <= t.get_position()[1] <= hi + pad]
    width = max((text_width_in(_plain(t.get_text()), t.get_fontsize()) for t in ticks), default=0.0)
    label = ax.yaxis.label
    height = (label.get_text().count("\n") + 1) * TEXT_LINE * label.get_fontsize() / 72 if label.get_text() else 0.0
    return (LABEL_ROOM_IN["edge"] + width + LABEL_ROOM_IN["ticks"] * bool(ticks)
            + (LABEL_ROOM_IN["label"] + height) * bool(height))


def fit(fig, top: float = 1.0) -> None:
    """Lay the page's grid of axes out between fixed margins (:data:`MARGIN_IN`), above the
    page's foot (:data:`FOOTER_IN`) and below ``top`` (a share of the height: room for a title
    and legend drawn on the figure); the left margin wider where the first column's y labels
    need it (:func:`y_labels_in`: their characters' cached widths; ``tight_layout`` measured
    every label, about half the time of drawing a page)."""
    w, h = fig.get_size_inches()
    axes = [ax for ax in fig.axes if ax.get_subplotspec() is not None]
    rows, cols = axes[0].get_subplotspec().get_gridspec().get_geometry() if axes else (1, 1)
    m = MARGIN_IN
    titled = any(ax.get_title() or ax.get_title(loc="left") for ax in axes)
    labelled = any(ax.get_xlabel() and not ax.get_subplotspec().is_last_row() for ax in axes)
    gap = m["row"] + m["xlabels"] * labelled + m["title"] * titled
    bottom, upper = (FOOTER_IN + m["bottom"]) / h, top - (0.1 + m["title"] * titled) / h
    # an axis labelled on the right (a twin's) needs the left margin's room there
    on_right = any(ax.yaxis.get_label_position() == "right" and ax.get_ylabel() for ax in axes)
    # the first column's labels where they need more (a metric's name, a number of many digits)
    first = [ax for ax in axes if ax.get_visible() and ax.get_subplotspec().is_first_col()
             and ax.yaxis.get_label_position() == "left"]
    left = max([m["left"]] + [y_labels_in(ax) for ax in first]) / w
    right = 1 - (m["left"] if on_right else m["right"]) / w
    cell_h = ((upper - bottom) * h - (rows - 1) * gap) / rows
    cell_w = ((right - left) * w - (cols - 1) * m["column"]) / cols
    fig.subplots_adjust(left=left, right=right, bottom=bottom, top=upper,
                        hspace=gap / cell_h, wspace=m["column"] / cell_w)


#: the characters of a page title's line at its font size across the page (a longer title wraps)
TITLE_CHARS = 90
#: the height of a page title's line, inches
TITLE_LINE_IN = 0.2


def titled(fig, name: str, title: str) -> Page:
    """The page ``name`` of ``fig`` under ``title`` (also its line in the contents), fitted; a
    title longer than :data:`TITLE_CHARS` wraps onto more lines, the axes moved down under them."""
    lines = textwrap.wrap(title, TITLE_CHARS) or [""]
    fig.suptitle("\n".join(lines), fontsize=11, y=1 - 0.25 / fig.get_figheight(), va="top")
    fit(fig, 1 - (0.5 + TITLE_LINE_IN * (len(lines) - 1)) / fig.get_figheight())
    return Page(name, title, fig)


def head(fig, title: str, handles: list, ncol: int, size: float = 11.0) -> None:
    """``title`` and a legend of ``handles`` in ``ncol`` columns across the top of the page, the
    axes fitted under them and above the foot."""
    height = fig.get_figheight()
    fig.suptitle(title, fontsize=size, y=1 - 0.25 / height, va="top")
    rows = -(-len(handles) // max(ncol, 1))
    fig.legend(handles=handles, loc="upper center", ncol=ncol, fontsize=7.5, frameon=False,
               bbox_to_anchor=(0.5, 1 - 0.5 / height))
    fit(fig, 1 - (0.45 + 0.15 * rows) / height)


def nanmean(x):
    """Mean over the runs (axis 0) of what they have: a closed-loop run's records end at its
    landing (NaN after it)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(x, axis=0)


def shade(ax, spans, label: bool = False):
    """Shade the metric windows ``(name, start_s, end_s)`` (fault, interference) in orange and
    landmark sightings ``(name, start_s, end_s, sigma_m)`` in green; ``label``: each window's
    name at the top of its span."""
    for span in spans:
        name, a, b = span[:3]
        if len(span) > 3:
            ax.axvspan(a, b, color="tab:green", alpha=0.25, lw=0)
            continue
        ax.axvspan(a, b, color="tab:orange", alpha=0.12, lw=0)
        if label:
            ax.text((a + b) / 2, 0.97, name, transform=ax.get_xaxis_transform(), fontsize=6.5, ha="center",
                    va="top", color="0.3", clip_on=True)


def estimator_colours(labels) -> dict:
    """A colour per estimator, distinct up to 20 (tab10, or tab20 beyond ten)."""
    labels = list(labels)
    cmap = pyplot().cm.tab10 if len(labels) <= 10 else pyplot().cm.tab20
    return {k: cmap(i % cmap.N) for i, k in enumerate(labels)}


def legend_columns(labels) -> int:
    """Legend columns that keep a row of long labels inside the figure."""
    longest = max((len(str(lb)) for lb in labels), default=0)
    return 4 if longest <= 28 else 2 if longest <= 60 else 1


def slug(label: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in label).strip("_").lower()
