"""Each metric window's error against the time since its start, one panel per window, every
estimator, the RMS over the runs with the filters' own 1-sigma: the horizontal error (an
outage's drift), or the height error in a height study (:func:`quantity`); a log scale where the
curves span decades (:func:`~navsim.report.consistency.log_scale_if_wide`); estimators whose
curves coincide (drawn as one line) said to in the panel."""

from __future__ import annotations

import numpy as np
from matplotlib.lines import Line2D

from navsim.flight.plots import plot_drawn
from navsim.records.states import POS
from navsim.report.consistency import NOTE_PT, log_scale_if_wide, make_room, panel_note
from navsim.report.figures import Page, ReportInput, estimator_colours, head, legend_columns, page_figure
from navsim.report.tables import wrap_text

#: the windows drawn on one page (more: more pages)
WINDOWS_PER_PAGE = 3
#: what a drift page can draw: its y label and the page's title
QUANTITIES = {"horizontal": ("horizontal error, m", "Horizontal error through each metrics window (an outage's drift)"),
              "height": ("height error, m", "Height error through each metrics window")}
#: two estimators' error curves in a window coincide where they differ by less than this share
#: of the larger's largest value at every epoch (they are drawn as one line)
COINCIDE = 0.01
#: the error lines' width, points (the 1-sigma's: :data:`SIGMA_LW`, dotted)
ERROR_LW, SIGMA_LW = 1.3, 0.9


def quantity(scenario) -> str:
    """``"height"`` for a height study (the scenario's reference judges its windows'
    ``height_m`` and none's ``horizontal_m``, as P2 does), else ``"horizontal"``."""
    ref = getattr(scenario, "reference", None)
    judged = {c.metric.split(".")[-2] for c in (ref.checks if ref else ()) if c.metric.startswith("windows.")}
    return "height" if "height_m" in judged and "horizontal_m" not in judged else "horizontal"


def _rms(x):
    """RMS over the runs of what they have (NaN where none has a record)."""
    with np.errstate(invalid="ignore"):
        n = np.sum(np.isfinite(x), axis=0)
        return np.sqrt(np.nansum(x ** 2, axis=0) / np.where(n > 0, n, np.nan))


def _curves(h, m, what: str) -> tuple:
    """A history's error (RMS over the runs) and its 1-sigma (RMS of the runs' sigmas; None
    without a covariance) at the epochs ``m``: horizontal, or the height (up)."""
    pos = h.pos_err_m[:, m]
    sig = None if h.sigma is None else h.sigma[:, m][..., POS]
    if what == "height":
        return _rms(-pos[..., 2]), None if sig is None else _rms(sig[..., 2])
    return _rms(np.hypot(pos[..., 0], pos[..., 1])), None if sig is None else _rms(np.hypot(sig[..., 0], sig[..., 1]))


def coinciding(curves: dict) -> list[list[str]]:
    """The groups (two or more) of ``curves`` (label -> values on the same epochs) that coincide
    (:data:`COINCIDE`), in the order drawn; curves on epochs of other lengths (estimators at
    other periods) coincide with none."""
    groups: list[list[str]] = []
    for k, y in curves.items():
        for g in groups:
            ref = curves[g[0]]
            if np.shape(ref) != np.shape(y):
                continue
            scale = np.nanmax(np.abs(np.r_[ref, y])) if np.isfinite(np.r_[ref, y]).any() else 0.0
            same = np.isfinite(y) == np.isfinite(ref)
            if same.all() and np.nanmax(np.abs(y - ref), initial=0.0) <= COINCIDE * scale:
                g.append(k)
                break
        else:
            groups.append([k])
    return [g for g in groups if len(g) > 1]


def _said(group: list[str]) -> str:
    return (", ".join(group[:-1]) + " and " + group[-1]) + " coincide"


def _panel(ax, inp: ReportInput, window: tuple, what: str, colours):
    """One window: each estimator's error (RMS over the runs, solid) and its predicted 1-sigma
    (dotted); a log scale where they span decades; returns the note naming the estimators drawn
    as one line (None where none coincide), placed by :func:`make_room` once laid out."""
    name, a, b = window
    errors, drawn = {}, []
    for label, h in inp.histories.items():
        m = (h.t_s >= a) & (h.t_s <= b)
        if not m.any():
            continue
        t = h.t_s[m] - a
        err, sig = _curves(h, m, what)
        errors[label] = err
        plot_drawn(ax, t, err, color=colours[label], lw=ERROR_LW)
        drawn.append(err)
        if sig is not None:
            plot_drawn(ax, t, sig, color=colours[label], lw=SIGMA_LW, ls=":")
            drawn.append(sig)
    if not log_scale_if_wide(ax, drawn):
        ax.set_ylim(bottom=0.0)
    ax.set_title(f"{name} ({a:g}-{b:g} s)", fontsize=9)
    ax.set_ylabel(QUANTITIES[what][0], fontsize=8)
    ax.grid(alpha=0.3, which="both")
    said = [_said(g) for g in coinciding(errors)]
    if not said:
        return None
    text = f"{'; '.join(said)}: drawn as one line (within {COINCIDE:.0%} of each other at every epoch)"
    width_in = 0.9 * ax.get_position().width * ax.figure.get_figwidth()
    return panel_note(ax, "\n".join(wrap_text(text, width_in, NOTE_PT)))


def pages(inp: ReportInput) -> list[Page]:
    """The drift pages: one panel per metric window (the scenario's ``metrics.windows``), none
    without a window; the horizontal error, or the height error in a height study
    (:func:`quantity`)."""
    windows = list(inp.scenario.windows)
    if not windows:
        return []
    what = quantity(inp.scenario)
    colours = estimator_colours(inp.histories)
    handles = [Line2D([], [], color=c, lw=ERROR_LW, label=k) for k, c in colours.items()]
    handles += [Line2D([], [], color="0.3", lw=ERROR_LW, label="error, RMS over the runs"),
                Line2D([], [], color="0.3", lw=SIGMA_LW, ls=":", label="the filter's 1σ (RMS over the runs)")]
    out = []
    for first in range(0, len(windows), WINDOWS_PER_PAGE):
        part = windows[first:first + WINDOWS_PER_PAGE]
        fig, axs = page_figure(len(part), 1, squeeze=False)
        notes = [_panel(ax, inp, window, what, colours) for ax, window in zip(axs[:, 0], part)]
        axs[-1, 0].set_xlabel("time since the window's start, s")
        title = QUANTITIES[what][1] + (" (continued)" if out else "")
        head(fig, title, handles, legend_columns(colours))
        for ax, note in zip(axs[:, 0], notes):
            if note is not None:
                make_room(ax, note)
        out.append(Page("drift" if not out else f"drift_{len(out) + 1}", title, fig))
    return out
