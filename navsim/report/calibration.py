"""Magnetometer online calibration: hard- and soft-iron errors and the heading error."""

from __future__ import annotations

import warnings

import numpy as np

from navsim.flight.plots import plot_drawn
from navsim.report.figures import Page, ReportInput, nanmean, page_figure, pyplot, shade, titled

#: the runs drawn thin on a calibration page
CALIBRATION_RUNS = 3


def pages(inp: ReportInput) -> list[Page]:
    """Per calibrated magnetometer: hard- and soft-iron errors against time (mean and 95th
    percentile over the runs, a few runs thin) with the mark of two full turns and the 2 %
    line, and the heading error of each estimator (Monte Carlo RMS) against time; the numbers
    in the title are the scorer's."""
    histories, metrics, runs_plotted = inp.histories, inp.metrics, CALIBRATION_RUNS
    colors = pyplot().cm.tab10(np.arange(10))
    out = []
    for name, cal in inp.result.calibration.items():
        fig, axs = page_figure(3, 1, sharex=True)
        t = cal.t_s
        mark = np.flatnonzero(cal.turns >= 2.0)
        t2 = t[mark[0]] if mark.size else None
        for ax, err, title in ((axs[0], cal.hard_iron_err, "hard-iron error, % of |m|"),
                               (axs[1], cal.soft_iron_err, "soft-iron error, % (Frobenius)")):
            e = 100.0 * err
            for r in range(min(runs_plotted, e.shape[0])):
                plot_drawn(ax, t, e[r], color="0.6", lw=0.5)
            with warnings.catch_warnings():          # epochs where no run has an ellipsoid yet
                warnings.simplefilter("ignore", RuntimeWarning)
                plot_drawn(ax, t, np.nanmean(e, 0), color="tab:blue", lw=1.6, label="mean over runs")
                plot_drawn(ax, t, np.nanpercentile(e, 95, axis=0), color="tab:red", lw=1.2, label="95th percentile")
            ax.axhline(2.0, color="k", ls="--", lw=0.8, label="2 % (acceptance)")
            ax.set_yscale("log")
            ax.set_ylim(0.05, 200)
            ax.set_ylabel(title, fontsize=8)
            ax.grid(alpha=0.3, which="both")
            ax2 = ax.twinx()
            plot_drawn(ax2, t, cal.turns, color="tab:green", lw=0.8)
            ax2.set_ylabel("full turns (true heading)", fontsize=7, color="tab:green")
        score = (metrics.calibration or {}).get(name)
        if score and score.after_turns:
            at, h, s_ = score.after_turns, score.after_turns.hard_iron_pct, score.after_turns.soft_iron_pct
            axs[0].set_title(f"after {score.turns:g} full turns ({at.t_s:.0f} s), mean / 95th percentile / max: "
                             f"hard iron {h.mean:.2f} / {h.p95:.2f} / {h.max:.2f} %,\nsoft iron {s_.mean:.2f} / "
                             f"{s_.p95:.2f} / {s_.max:.2f} %", fontsize=8)
        for c, (label, hist) in enumerate(histories.items()):
            good = ~np.asarray(hist.diverged, bool)
            if good.any():
                rms = np.sqrt(nanmean(np.degrees(hist.att_err_rad[good][..., 2]) ** 2))
                plot_drawn(axs[2], hist.t_s, rms, color=colors[c % 10], lw=1.4, label=f"{label}: MC RMS")
        axs[2].set_ylabel("heading error, deg (RMS over runs)", fontsize=8)
        axs[2].set_yscale("log")
        axs[2].grid(alpha=0.3, which="both")
        axs[2].legend(fontsize=7, loc="upper right")
        for j, ax in enumerate(axs):
            shade(ax, inp.scenario.windows, label=j == 0)
            if t2 is not None:
                ax.axvline(t2, color="tab:green", lw=1.0, ls=":")
        if t2 is not None:
            axs[1].text(t2, 1.0, " two full turns", transform=axs[1].get_xaxis_transform(), fontsize=7,
                        va="top", color="tab:green")
        axs[0].legend(fontsize=7, loc="upper right")
        axs[-1].set_xlabel("time, s")
        out.append(titled(fig, f"calibration_{name}",
                          f"Magnetometer '{name}': online calibration (RLS ellipsoid fit) and heading error"))
    return out

