"""Consistency: the average NEES and NIS over the runs against their chi-square bands, each
panel quoting the scorer's share of epochs inside (from the settling time on, every run
counted), not a share of its own."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.report.figures import Page, ReportInput, head, legend_columns, page_figure, pyplot, shade
from navsim.report.summary import pct
from navsim.scoring.stats import chi2_band

#: the most panels on one consistency page (more go to the next)
PANELS_PER_PAGE = 5


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


def _panels(inp: ReportInput, filters: dict, colours) -> list:
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


def pages(inp: ReportInput) -> list[Page]:
    """The average NEES and NIS over the runs against their two-sided 95 % chi-square bands
    (dashed), each panel quoting the scorer's share of epochs inside; :data:`PANELS_PER_PAGE` a
    page."""
    from matplotlib.lines import Line2D
    filters = {k: h for k, h in inp.histories.items() if h.nees is not None}
    colours = pyplot().cm.tab10(np.arange(10))
    panels = _panels(inp, filters, colours)
    settle_s = inp.scenario.settle_s
    out = []
    for start in range(0, len(panels), PANELS_PER_PAGE):
        page = panels[start:start + PANELS_PER_PAGE]
        fig, axs = page_figure(len(page), 1, sharex=True, squeeze=False)
        for ax, (ylabel, series) in zip(axs[:, 0], page):
            notes = []
            for s in series:
                ax.plot(s.t, s.y, s.marker, ms=2, lw=1.2, color=s.colour)
                _band(ax, s.lo, s.hi, s.colour)
                notes.append(f"{s.label}: {quote(s.score)}" if len(series) > 1 else quote(s.score))
            ax.text(0.01, 0.96, "\n".join(notes), transform=ax.transAxes, fontsize=7, va="top",
                    bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})
            ax.axvline(settle_s, color="0.4", lw=0.8, ls=":")
            shade(ax, inp.spans, label=ax is axs[0, 0])
            ax.set_ylabel(ylabel, fontsize=7.5)
            ax.grid(alpha=0.3)
        axs[-1, 0].set_xlabel("time, s")
        axs[0, 0].set_title(f"the shares of epochs inside, as scored (metrics.json): from {settle_s:g} s on, over "
                            "every run that did not diverge", fontsize=7.5, loc="left", color="0.3")
        handles = [Line2D([], [], color=colours[c % 10], lw=1.2, label=k) for c, k in enumerate(filters)]
        handles += [Line2D([], [], color="0.4", lw=0.9, ls="--", label="95 % chi-square band of the average"),
                    Line2D([], [], color="0.4", lw=0.8, ls=":", label=f"settling time {settle_s:g} s")]
        title = "Consistency: the average NEES and NIS over the runs" + (" (continued)" if start else "")
        head(fig, title, handles, min(len(handles), legend_columns(filters)))
        out.append(Page("consistency" if not start else f"consistency_{start // PANELS_PER_PAGE + 1}", title, fig))
    return out
