"""Each metric window's horizontal error against the time since its start: an outage's drift,
one panel per window, every estimator, the RMS over the runs with the filters' own 1-sigma."""

from __future__ import annotations

import numpy as np

from navsim.records.states import POS
from navsim.report.figures import Page, ReportInput, estimator_colours, head, legend_columns, page_figure

#: the windows drawn on one page (more: more pages)
WINDOWS_PER_PAGE = 3


def _rms(x):
    """RMS over the runs of what they have (NaN where none has a record)."""
    with np.errstate(invalid="ignore"):
        n = np.sum(np.isfinite(x), axis=0)
        return np.sqrt(np.nansum(x ** 2, axis=0) / np.where(n > 0, n, np.nan))


def _panel(ax, inp: ReportInput, name: str, a: float, b: float, colours) -> None:
    """One window: each estimator's horizontal error (RMS over the runs, solid) and its
    predicted 1-sigma (RMS of ``sqrt(sigma_N^2 + sigma_E^2)``, dotted), log scale."""
    for label, h in inp.histories.items():
        m = (h.t_s >= a) & (h.t_s <= b)
        if not m.any():
            continue
        t = h.t_s[m] - a
        ax.plot(t, _rms(np.hypot(h.pos_err_m[:, m, 0], h.pos_err_m[:, m, 1])), color=colours[label], lw=1.3)
        if h.sigma is not None:
            sig = h.sigma[:, m][..., POS]
            ax.plot(t, _rms(np.hypot(sig[..., 0], sig[..., 1])), color=colours[label], lw=0.9, ls=":")
    ax.set_yscale("log")
    ax.set_title(f"{name} ({a:g}-{b:g} s)", fontsize=9)
    ax.set_ylabel("horizontal error, m", fontsize=8)
    ax.grid(alpha=0.3, which="both")


def pages(inp: ReportInput) -> list[Page]:
    """The drift pages: one panel per metric window (the scenario's ``metrics.windows``), none
    without a window."""
    from matplotlib.lines import Line2D
    windows = list(inp.scenario.windows)
    if not windows:
        return []
    colours = estimator_colours(inp.histories)
    handles = [Line2D([], [], color=c, lw=1.3, label=k) for k, c in colours.items()]
    handles += [Line2D([], [], color="0.3", lw=1.3, label="error, RMS over the runs"),
                Line2D([], [], color="0.3", lw=0.9, ls=":", label="the filter's 1σ (RMS over the runs)")]
    out = []
    for first in range(0, len(windows), WINDOWS_PER_PAGE):
        part = windows[first:first + WINDOWS_PER_PAGE]
        fig, axs = page_figure(len(part), 1, squeeze=False)
        for ax, (name, a, b) in zip(axs[:, 0], part):
            _panel(ax, inp, name, a, b, colours)
        axs[-1, 0].set_xlabel("time since the window's start, s")
        title = "Horizontal error through each metrics window (an outage's drift)"
        head(fig, title + (" (continued)" if out else ""), handles, legend_columns(colours))
        out.append(Page("drift" if not out else f"drift_{len(out) + 1}", title + (" (continued)" if out else ""), fig))
    return out
