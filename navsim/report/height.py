"""Height error against time (P2's Figures 4-5), the sensor faults and metric windows shaded."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.flight.plots import plot_drawn
from navsim.report.errors import envelopes, inside, split_free
from navsim.report.figures import Page, ReportInput, estimator_colours, head, nanmean, page_figure, shade

#: the metric windows drawn magnified under the whole flight (the first ones)
ZOOMED_WINDOWS = 2


@dataclass(frozen=True)
class HeightPage:
    """What every panel of the height page shares: the run (``inp``), the estimators' colours
    and the sensor faults ``(sensor name, fault)`` shaded on each panel."""

    inp: ReportInput
    colours: dict
    faults: list


def _height_panel(ax, page: HeightPage, labels: list, spans, after, shown=(-np.inf, np.inf)) -> None:
    """The height errors (up) of ``labels``: a few runs (thin), the RMS over runs (solid) and the
    filter's ±3 sigma (dashed), the y range set by them in the time span ``after``; the page's
    sensor faults shaded red (named where they start inside the span ``shown``), ``spans``
    (windows) orange."""
    inp, colours, faults = page.inp, page.colours, page.faults
    peak = 0.0
    for k in labels:
        h = inp.histories[k]
        good = ~np.asarray(h.diverged, bool)
        dh = -h.pos_err_m[good][..., 2]
        for r in range(min(inp.runs_plotted, dh.shape[0])):
            plot_drawn(ax, h.t_s, dh[r], color=colours[k], lw=0.5, alpha=0.5)
        plot_drawn(ax, h.t_s, np.sqrt(nanmean(dh ** 2)), color=colours[k], lw=1.6)
        m = inside(h.t_s, after)
        if h.sigma is not None:
            sig = envelopes(h, "pos")[1][:, 2]
            plot_drawn(ax, h.t_s, 3 * sig, "--", color=colours[k], lw=1.0)
            plot_drawn(ax, h.t_s, -3 * sig, "--", color=colours[k], lw=1.0)
            if m.any():
                peak = max(peak, 3 * float(np.nanmax(sig[m])))
        if m.any():
            peak = max(peak, float(np.nanpercentile(np.abs(dh[:, m]), 99.5)))
    end = next(iter(inp.histories.values())).t_s[-1]
    named = 0
    for name, f in sorted(faults, key=lambda nf: nf[1].start_s):
        ax.axvspan(f.start_s, min(f.end_s, end), color="tab:red", alpha=0.15, lw=0)
        if shown[0] <= f.start_s <= min(shown[1], end):       # on three rows: faults close in time
            ax.text(f.start_s, 0.97 - 0.06 * (named % 3), f" {name} {f.type}", transform=ax.get_xaxis_transform(),
                    fontsize=6.5, va="top", color="tab:red", clip_on=True)
            named += 1
    shade(ax, spans)
    if peak > 0 and np.isfinite(peak):
        ax.set_ylim(-1.15 * peak, 1.15 * peak)
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set(xlabel="time, s", ylabel="height error (up), m")
    ax.grid(alpha=0.3)


def pages(inp: ReportInput) -> list[Page]:
    """Height error against time over the whole flight: the RMS over runs, the filter's ±3 sigma
    and a few runs of each estimator; a free-inertial one that would flatten the others on axes
    of its own under them; then the first :data:`ZOOMED_WINDOWS` metric windows magnified."""
    from matplotlib.lines import Line2D
    scenario = inp.scenario
    faults = [(c.name, f) for c in scenario.sensors for f in c.faults if f.type != "interference"]
    env = {k: e for k, h in inp.histories.items() if (e := envelopes(h, "pos")) is not None}
    if not env or (not faults and not scenario.windows):
        return []
    colours = estimator_colours(inp.histories)
    after = (scenario.settle_s, np.inf)
    main, free = split_free({k: (e[0][:, 2:], e[1], e[2], e[3]) for k, e in env.items()}, after)
    zoomed = list(scenario.windows[:ZOOMED_WINDOWS])
    fig, axs = page_figure(1 + bool(free) + len(zoomed), 1, squeeze=False)
    axs = list(axs[:, 0])
    page = HeightPage(inp, colours, faults)
    _height_panel(axs[0], page, main, scenario.windows, after)
    axs[0].set_title("the whole flight", fontsize=9, loc="left")
    if free:
        _height_panel(axs[1], page, free, scenario.windows, after)
        axs[1].set_title("free inertial, on its own scale", fontsize=9, loc="left")
    for ax, (name, a, b) in zip(axs[1 + bool(free):], zoomed):
        _height_panel(ax, page, main, (), (a, b), (a, b))
        ax.set_xlim(a, b)
        ax.set_title(f"window '{name}' ({a:g}-{b:g} s)", fontsize=9, loc="left")
    handles = [Line2D([], [], color=colours[k], lw=1.6, label=f"{k}: RMS over runs") for k in env]
    handles += [Line2D([], [], color="0.3", lw=1.0, ls="--", label="filter ±3σ"),
                Line2D([], [], color="0.3", lw=0.5, label=f"first {inp.runs_plotted} runs")]
    shaded = (["sensor faults red"] if faults else []) + (["metric windows orange"] if scenario.windows else [])
    head(fig, "Height error against time" + (f" ({', '.join(shaded)})" if shaded else ""), handles,
         min(len(handles), 3))
    return [Page("height", "Height error against time", fig)]
