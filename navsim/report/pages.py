"""The pages of a ``navsim run`` report, a registry of page sources in reading order.

Each source (:data:`PAGE_SOURCES`) is a function of a :class:`~navsim.report.figures.ReportInput`
returning its :class:`~navsim.report.figures.Page` objects, none where it has nothing to show:
the summary and the metrics windows (text pages), the scenario as run, the flight, the closed
loop, then the figures by topic (errors, the windows' drift, height, landmarks, attitude, consistency, biases,
wind, calibration), each in a module of its own. Every statistic a page prints is read from the
scorer's :class:`~navsim.records.metrics.RunMetrics` (the numbers of ``metrics.json``); the
curves are drawn from the runs' histories. :func:`report_pages` puts a contents page first and
numbers every page; :func:`write_report` writes them (:mod:`navsim.report.render`). A new page is
a function here and a line in :data:`PAGE_SOURCES`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from navsim import report
from navsim.experiment.scenario import REPORT_FORMATS
from navsim.flight.plots import flight_figures
from navsim.foundations.outputs import OutputFolder
from navsim.report import attitude, biases, calibration, closed_loop, consistency, errors, height, landmarks
from navsim.report import drift, scenario_page, wind
from navsim.report.figures import FIGURE_IN, FOOTER_IN, Page, ReportInput, pyplot
from navsim.report.render import ForkedWrite, render
from navsim.report.summary import summary_figures, window_figures
from navsim.report.tables import Table, layout


def summary(inp: ReportInput) -> list[Page]:
    figs = summary_figures(inp.scenario, inp.record, inp.metrics)
    return [Page("summary" if i == 0 else f"summary_{i + 1}", "Summary" + (" (continued)" if i else ""), f)
            for i, f in enumerate(figs)]


def windows(inp: ReportInput) -> list[Page]:
    figs = window_figures(inp.scenario, inp.metrics)
    return [Page("windows" if i == 0 else f"windows_{i + 1}", "Metrics windows" + (" (continued)" if i else ""), f)
            for i, f in enumerate(figs)]


#: the flight's figures: their titles in the contents
FLIGHT_TITLES = {"3d": "The flight: 3-D track", "ground": "The flight: ground track", "time": "The flight against time"}


def flight(inp: ReportInput) -> list[Page]:
    if inp.truth is None:
        return []
    return [Page(f"flight_{n}", FLIGHT_TITLES.get(n, f"The flight: {n}"), f)
            for n, f in flight_figures(inp.truth, figsize=FIGURE_IN, footer_in=FOOTER_IN)]


def _with_histories(source: Callable) -> Callable:
    """``source`` where the run has histories to draw (none: no page)."""
    def pages(inp: ReportInput) -> list[Page]:
        return source(inp) if inp.histories else []
    pages.__doc__, pages.__name__ = source.__doc__, source.__module__.rsplit(".", 1)[-1]
    return pages


@dataclass(frozen=True)
class PageSource:
    """A page source: its name (``navsim report`` says what it drew) and its function."""

    name: str
    pages: Callable[[ReportInput], list[Page]]


#: the report's page sources, in reading order
PAGE_SOURCES: tuple[PageSource, ...] = (
    PageSource("summary", summary),
    PageSource("windows", windows),
    PageSource("scenario", scenario_page.pages),
    PageSource("flight", flight),
    PageSource("closed_loop", closed_loop.pages),
    PageSource("errors", _with_histories(errors.pages)),
    PageSource("drift", _with_histories(drift.pages)),
    PageSource("height", _with_histories(height.pages)),
    PageSource("landmarks", _with_histories(landmarks.pages)),
    PageSource("attitude", _with_histories(attitude.pages)),
    PageSource("consistency", _with_histories(consistency.pages)),
    PageSource("biases", _with_histories(biases.pages)),
    PageSource("wind", _with_histories(wind.pages)),
    PageSource("calibration", _with_histories(calibration.pages)),
)


def contents(title: str, pages: list[Page]) -> list[Page]:
    """The contents page(s): each page's number and title (the contents counted first)."""
    def table(first: int) -> list:
        return [Table(["page", "contents"], [[str(first + i), p.title] for i, p in enumerate(pages)],
                      align=["r", "l"], max_column=0.85)]
    figs = layout(f"{title}: contents", table(2))
    if len(figs) > 1:                      # a contents longer than a page moves the others on
        for f in figs:
            pyplot().close(f)
        figs = layout(f"{title}: contents", table(1 + len(figs)))
    return [Page("contents" if i == 0 else f"contents_{i + 1}", "Contents" + (" (continued)" if i else ""), f)
            for i, f in enumerate(figs)]


def number(pages: list[Page], title: str) -> None:
    """Write ``title · page i of n`` at the foot of every page."""
    for i, page in enumerate(pages):
        page.figure.text(0.5, 0.18 / page.figure.get_figheight(), f"{title} · page {i + 1} of {len(pages)}",
                         ha="center", va="bottom", fontsize=7, color="0.45")


def report_pages(inp: ReportInput) -> list[Page]:
    """The report's pages in order: the contents, then every source's pages
    (:data:`PAGE_SOURCES`) read from ``inp``, each numbered at its foot."""
    pages = []
    try:
        for source in PAGE_SOURCES:
            pages += source.pages(inp)
        title = f"navsim report: {inp.scenario.name}"
        pages = contents(title, pages) + pages
        number(pages, title)
    except BaseException:
        for page in pages:                   # those drawn before the failure
            pyplot().close(page.figure)
        raise
    return pages


#: the interactive page written beside report.pdf (:mod:`navsim.report.html`; named here, so that
#: naming it does not import Bokeh into this process)
HTML_FILE = "report.html"


def write_report(folder: OutputFolder, inp: ReportInput) -> list[Path]:
    """Write the PNGs, ``report.pdf`` and ``report.html`` (those of the scenario's
    ``report.formats``) of the run ``inp`` (its scenario, flight, histories, metrics, record; for
    a closed loop its per-run outcome and truth-guided flight; its landmark sightings, shaded in
    green) into the output folder ``folder`` (each name recorded in its manifest before it is
    written); returns the files written."""
    fmts = inp.scenario.report.get("formats", REPORT_FORMATS)
    pages, written, page = [], [], None
    if "html" in fmts:                        # a forked child writes it meanwhile (Bokeh imported there only)
        path = folder.path / HTML_FILE
        folder.record([path])
        page = ForkedWrite(lambda: report.html.write_html(path, inp), [path])
    try:
        if {"pdf", "png"} & set(fmts):
            pages = report_pages(inp)
            written = render(folder, pages, fmts, f"navsim report: {inp.scenario.name}")
        if page is not None:
            page.finish()
            written.append(path)
    finally:
        for p in pages:
            pyplot().close(p.figure)
        if page is not None:
            page.end(abandon=True)           # after a failure here: the child ended, its file removed
    return written
