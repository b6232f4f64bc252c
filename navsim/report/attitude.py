"""Attitude estimators (P4): the roll, pitch and yaw errors with the paper's bounds and the
divergence monitor's resets."""

from __future__ import annotations

import numpy as np

from navsim.flight.plots import plot_drawn
from navsim.report.figures import Page, ReportInput, page_figure, shade, slug, titled
from navsim.records.metrics import EULER_AXES
from navsim.scoring.stats import row_percentiles


def paper_attitude_bounds(reference) -> dict:
    """Estimator label -> ``{axis index: (bound_deg, what)}``: the roll/pitch/yaw accuracy a
    scenario's ``reference`` claims (``attitude.p95*`` values, ``windows.*.<axis>_deg.p95_abs``)
    with the rule ``at_most``, to draw on the attitude pages."""
    out = {}
    for c in (reference.checks if reference else ()):
        if c.rule != "at_most" or c.of is not None:
            continue
        parts = c.metric.split(".")
        if parts[0] == "attitude" and parts[1].startswith("p95") and isinstance(c.bound, list):
            for j, b in enumerate(c.bound):
                out.setdefault(c.estimator, {}).setdefault(j, (float(b), f"{reference.source.split(',')[0]}: ±{b:g}°"))
        elif (parts[0] == "windows" and len(parts) == 4 and parts[2] in ("roll_deg", "pitch_deg", "yaw_deg")
              and isinstance(c.bound, (int, float))):
            j = ("roll_deg", "pitch_deg", "yaw_deg").index(parts[2])
            out.setdefault(c.estimator, {}).setdefault(
                j, (float(c.bound), f"{reference.source.split(',')[0]}: ±{c.bound:g}° ({parts[1]})"))
    return out


def pages(inp: ReportInput) -> list[Page]:
    """Roll, pitch, yaw error of each attitude estimator: a few runs, the 95th percentile of
    |error| over the runs drawn, the paper's bounds, and a tick per reset of the divergence
    monitor (red; the count is the scorer's, the times listed those of the first run)."""
    histories, settle_s, runs_plotted = inp.histories, inp.scenario.settle_s, inp.runs_plotted
    spans, bounds = inp.spans, paper_attitude_bounds(inp.scenario.reference)
    labels = [k for k, h in histories.items() if h.euler_err_rad is not None and h.resets is not None]
    out = []
    for label in labels:
        h = histories[label]
        e = np.degrees(h.euler_err_rad)
        fig, axes = page_figure(3, 1, sharex=True)
        for j, ax in enumerate(axes):
            for r in range(min(runs_plotted, e.shape[0])):
                plot_drawn(ax, h.t_s, e[r, :, j], lw=0.5, alpha=0.7)
            p95 = row_percentiles(e[:, :, j].T, 95)          # over the runs, at each epoch
            plot_drawn(ax, h.t_s, p95, "k", lw=1.0, label="95th pct of |error| over the runs")
            plot_drawn(ax, h.t_s, -p95, "k", lw=1.0)
            after = h.t_s >= settle_s
            lim = max(3 * float(np.nanpercentile(np.abs(e[:, after, j]), 99)), 0.05) if after.any() else None
            if lim and np.isfinite(lim):
                ax.set_ylim(-lim, lim)
            shade(ax, spans)
            b = (bounds or {}).get(label, {}).get(j)
            if b is not None:
                for y in (b[0], -b[0]):
                    ax.axhline(y, color="tab:red", lw=1.0, ls="-.", label=b[1] if y > 0 else None)
                if lim is not None and np.isfinite(lim) and lim < 1.3 * b[0]:
                    ax.set_ylim(-1.3 * b[0], 1.3 * b[0])
            ax.set_ylabel(f"{EULER_AXES[j]} error, deg")
            ax.grid(alpha=0.3)
            if b is not None:
                ax.legend(fontsize=7, loc="upper right")
        times = [t for r in h.resets for t, _ in r]
        for t in sorted(set(round(t, 1) for t in times)):
            for ax in axes:
                ax.axvline(t, color="r", lw=0.6, alpha=0.5)
        first = ", ".join(f"{t:.0f}" for t, _ in h.resets[0]) if h.resets and h.resets[0] else "none"
        resets = inp.metrics.estimators[label].resets
        said = f"resets (red) {resets.count} in {resets.runs_with_reset} runs" if resets else "no resets scored"
        axes[0].set_title(said + (f"; run 0 at {first} s" if times else ""), fontsize=9, loc="left")
        axes[0].legend(fontsize=7, loc="upper right")
        axes[-1].set_xlabel("time, s")
        out.append(titled(fig, f"attitude_{slug(label)}", f"{label}: roll, pitch and yaw errors"))
    return out

