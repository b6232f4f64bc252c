"""Landmark sightings: the horizontal error of the landmark-aided estimators around each fix."""

from __future__ import annotations

import numpy as np

from navsim.flight.plots import plot_drawn
from navsim.report.figures import Page, ReportInput, nanmean, page_figure, shade, titled

#: the runs drawn thin on the landmark page
LANDMARK_RUNS = 3


def pages(inp: ReportInput) -> list[Page]:
    """Horizontal position error of the landmark-aided estimators on a linear scale, the
    sightings shaded, the camera's 3-sigma fix noise marked at the end of each sighting, and the
    scorer's worst ratio per sighting."""
    histories, metrics, sightings, runs_plotted = inp.histories, inp.metrics, inp.sightings, LANDMARK_RUNS
    labels = [k for k, m in metrics.estimators.items() if m.landmarks and m.landmarks.fraction_within_3sigma > 0.5]
    if not labels or not sightings:
        return []
    fig, axes = page_figure(3, 1, sharex=True)
    for label in labels:
        h = histories[label]
        good = ~np.asarray(h.diverged, bool)
        for j, (ax, name) in enumerate(zip(axes, ("north", "east"))):
            e = h.pos_err_m[good][..., j]
            for r in range(min(runs_plotted, e.shape[0])):
                plot_drawn(ax, h.t_s, e[r], lw=0.5, alpha=0.6)
            plot_drawn(ax, h.t_s, np.sqrt(nanmean(e ** 2)), "k", lw=1.2, label=f"{label}: MC RMS")
        ratio = [s.max_ratio for s in metrics.estimators[label].landmarks.sightings]
        axes[2].plot([s[2] for s in sightings], ratio, "o", ms=3, label=f"{label}: worst run")
    for ax in axes:
        shade(ax, sightings)
        ax.grid(alpha=0.3)
    for ax, name in zip(axes[:2], ("north", "east")):
        ts = [s[2] for s in sightings]
        ax.plot(ts, [3 * s[3] for s in sightings], "g_", ms=8, label="3 sigma of the fix")
        ax.plot(ts, [-3 * s[3] for s in sightings], "g_", ms=8)
        ax.set_ylabel(f"{name} error, m")
        lim = 8 * max(s[3] for s in sightings)
        ax.set_ylim(-lim, lim)
    axes[2].axhline(3.0, color="g", lw=1, label="3")
    axes[2].set(ylabel="|error| / fix sigma\nat the sighting's end", xlabel="time, s")
    axes[0].legend(fontsize=7, loc="upper right")
    axes[2].legend(fontsize=7, loc="upper right")
    axes[0].set_title("the error drifts between anchors and returns after each", fontsize=9, loc="left")
    return [titled(fig, "landmarks", "Landmark sightings (green)")]

