"""The wind a filter estimates against the true wind: one page per estimator with a wind state."""

from __future__ import annotations

import numpy as np
from matplotlib.lines import Line2D

from navsim.flight.environment import steady_wind_n_mps
from navsim.flight.plots import fill_drawn, plot_drawn
from navsim.report.figures import Page, ReportInput, head, nanmean, page_figure, pyplot, shade, slug

#: the runs drawn beside the mean on a wind page, each in a colour of its own
WIND_RUNS = 3
#: the width of the runs' lines
RUN_LW = 0.6
#: the largest number of wind pages (one per estimator with a wind state)
MAX_WIND_PAGES = 4
_AXES = ("north", "east", "down")


def _axis(ax, h, j: int, steady, gusty, spans, colours) -> None:
    """One axis of the wind: the mean estimate over the runs with its mean ±1σ band, the first
    runs thin (each in its colour of ``colours``, as the legend shows them), the true steady
    wind at the epochs (dashed) and the air mass's velocity with its gusts (grey; ``gusty``:
    the truth's times and velocities, or None)."""
    est, sig = h.wind_n_mps[..., j], h.wind_sigma_mps[..., j]
    shade(ax, spans, label=j == 0)
    if gusty is not None:
        plot_drawn(ax, gusty[0], gusty[1][:, j], color="0.6", lw=0.5)
    mean, s = nanmean(est), nanmean(sig)
    fill_drawn(ax, h.t_s, mean - s, mean + s, color="tab:blue", alpha=0.2, lw=0)
    for r in range(min(WIND_RUNS, est.shape[0])):
        plot_drawn(ax, h.t_s, est[r], color=colours[r], lw=RUN_LW)
    plot_drawn(ax, h.t_s, mean, color="tab:blue", lw=1.4)
    plot_drawn(ax, h.t_s, steady, color="k", lw=1.0, ls="--")
    ax.set_ylabel(f"wind {_AXES[j]}, m/s", fontsize=8)
    ax.grid(alpha=0.3)
    lo, hi = np.nanpercentile(np.r_[mean - s, mean + s, steady], [1, 99])
    pad = max(hi - lo, 1.0) * 0.6
    ax.set_ylim(lo - pad, hi + pad)


def _handles(runs: int, colours) -> list:
    """The legend (two rows of three): the mean and the truths, then each run drawn, in the
    colour it is drawn in."""
    return [Line2D([], [], color="tab:blue", lw=1.4, label="estimate, mean over the runs (band: mean ±1σ)"),
            Line2D([], [], color="k", lw=1.0, ls="--", label="true steady wind"),
            Line2D([], [], color="0.6", lw=0.5, label="true air-mass velocity (with the gusts)")] + [
            Line2D([], [], color=colours[r], lw=RUN_LW, label=f"run {r + 1}") for r in range(runs)]


def pages(inp: ReportInput) -> list[Page]:
    """Per estimator with a wind state: each estimated axis of the wind against the true steady
    wind and the truth's gusty air-mass velocity, the first :data:`WIND_RUNS` runs each in its
    colour, the metric windows (outages) shaded."""
    filters = [(k, h) for k, h in inp.histories.items() if h.wind_n_mps is not None][:MAX_WIND_PAGES]
    if not filters:
        return []
    env = inp.scenario.flight.environment
    colours = pyplot().cm.tab10(np.arange(10) + 1)
    out = []
    for label, h in filters:
        axes = [j for j in range(3) if np.isfinite(h.wind_n_mps[..., j]).any()]
        gusty = None
        if inp.truth is not None and inp.truth.wind_n_mps is not None:
            idx = np.clip(np.searchsorted(inp.truth.t_s, h.t_s - 1e-9), 0, inp.truth.n - 1)
            gusty = inp.truth.t_s[idx], inp.truth.wind_n_mps[idx]
        steady = np.array([steady_wind_n_mps(env, t) for t in h.t_s])
        fig, axs = page_figure(len(axes), 1, sharex=True, squeeze=False)
        for ax, j in zip(axs[:, 0], axes):
            _axis(ax, h, j, steady[:, j], gusty, inp.spans, colours)
        axs[-1, 0].set_xlabel("time, s")
        title = f"{label}: the estimated wind against the true wind"
        handles = _handles(min(WIND_RUNS, h.wind_n_mps.shape[0]), colours)
        head(fig, title, handles if gusty is not None else handles[:2] + handles[3:], 3)
        out.append(Page("wind" if not out else f"wind_{slug(label)}", title, fig))
    return out
