"""The navigation errors against time: per quantity (position, velocity, attitude) and axis,
the Monte Carlo RMS, the filter's 3 sigma and a few runs of every estimator."""

from __future__ import annotations

import numpy as np

from navsim.flight.plots import plot_drawn
from navsim.records.states import BLOCKS
from navsim.report.figures import (Page, ReportInput, estimator_colours, head, legend_columns, nanmean, page_figure,
                                   shade)

AXES = {"pos": ("position error", "m", ["north", "east", "down"]),
        "vel": ("velocity error", "m/s", ["north", "east", "down"]),
        "att": ("attitude error", "deg", ["about north (roll-like)", "about east", "about down (heading)"])}

#: the history field of each quantity (the attitude's drawn in degrees)
ERROR_FIELDS = {"pos": "pos_err_m", "vel": "vel_err_mps", "att": "att_err_rad"}

#: a free-inertial envelope this many times the aided ones' gets an axis of its own
OWN_AXIS_RATIO = 5.0


def envelopes(h, key: str):
    """``(rms, sigma, errors, t_s)``: RMS and sigma ``(T, 3)`` over the runs that did not diverge
    (``sigma`` None without a covariance), their errors ``(R, T, 3)`` and the estimator's own
    epoch times ``(T,)`` (estimators record at their own periods); None if every run diverged."""
    good = ~np.asarray(h.diverged, bool)
    if not good.any():
        return None
    err = np.asarray(getattr(h, ERROR_FIELDS[key]))[good]
    err = np.degrees(err) if key == "att" else err
    sig = None
    if h.sigma is not None:
        s = h.sigma[..., BLOCKS[key]]
        s = np.degrees(s) if key == "att" else s
        sig = np.sqrt(nanmean(s[good] ** 2))
    return np.sqrt(nanmean(err ** 2)), sig, err, h.t_s


def inside(t_s: np.ndarray, window) -> np.ndarray:
    """The epochs of ``t_s`` inside ``window = (start_s, end_s)``."""
    return (t_s >= window[0]) & (t_s <= window[1])


def split_free(env: dict, span) -> tuple[list, list]:
    """The estimators drawn on the main axes and those (free inertial, no covariance) whose
    errors in ``span`` (after the settling time) exceed :data:`OWN_AXIS_RATIO` times the others'."""
    scale = {}
    for k, e in env.items():
        m = inside(e[3], span)
        if m.any():
            scale[k] = float(np.nanmax(np.abs(e[0][m])))
    aided = [k for k in env if env[k][1] is not None]
    top = max((scale.get(k, 0.0) for k in aided), default=0.0)
    free = [k for k in env if env[k][1] is None and aided and scale.get(k, 0.0) > OWN_AXIS_RATIO * top > 0]
    return [k for k in env if k not in free], free


def _draw_envelope(ax, t, e, j: int, colour, runs_plotted: int) -> None:
    """One estimator on axis ``j``: a few runs (thin), the RMS (solid), the filter's 3 sigma
    (dashed)."""
    rms, sig, err, _ = e
    for r in range(min(runs_plotted, err.shape[0])):
        plot_drawn(ax, t, err[r, :, j], color=colour, lw=0.4, alpha=0.35)
    plot_drawn(ax, t, rms[:, j], color=colour, lw=1.6)
    plot_drawn(ax, t, -rms[:, j], color=colour, lw=1.6)
    if sig is not None:
        plot_drawn(ax, t, 3 * sig[:, j], "--", color=colour, lw=1.0)
        plot_drawn(ax, t, -3 * sig[:, j], "--", color=colour, lw=1.0)


def _ylim(ax, envs, j: int, span) -> None:
    """The y range the estimators on ``ax`` need in ``span`` (after the settling time: RMS and
    3 sigma)."""
    peaks = []
    for e in envs:
        m = inside(e[3], span)
        if m.any():
            peaks += [float(np.nanmax(np.abs(e[0][m, j])))] + ([3 * float(np.nanmax(e[1][m, j]))]
                                                              if e[1] is not None else [])
    peak = max(peaks, default=0.0)
    if np.isfinite(peak) and peak > 0:
        ax.set_ylim(-1.15 * peak, 1.15 * peak)


def pages(inp: ReportInput) -> list[Page]:
    """Per quantity, each axis against time: the Monte Carlo RMS (solid), the filter's 3 sigma
    (dashed) and a few runs (thin) of every estimator, the y range set by them after the
    settling time; a free-inertial estimator that would flatten the others on axes of its own
    (right); the metric windows shaded."""
    from matplotlib.lines import Line2D
    histories, settle_s, runs_plotted = inp.histories, inp.scenario.settle_s, inp.runs_plotted
    colours = estimator_colours(histories)
    out = []
    for key, (title, unit, names) in AXES.items():
        env = {k: e for k, h in histories.items() if (e := envelopes(h, key)) is not None}
        if not env:
            continue
        fig = _error_axes(histories, env, key, colours, inp)
        handles = [Line2D([], [], color=colours[k], lw=1.6, label=k) for k in env]
        handles += [Line2D([], [], color="0.3", lw=1.6, label="Monte Carlo RMS"),
                    Line2D([], [], color="0.3", lw=1.0, ls="--", label="filter ±3σ"),
                    Line2D([], [], color="0.3", lw=0.4, label=f"first {runs_plotted} runs"),
                    Line2D([], [], color="0.4", lw=0.8, ls=":", label=f"settling time {settle_s:g} s")]
        head(fig, title[0].upper() + title[1:] + " against time", handles,
             min(len(handles), legend_columns(histories)), size=12)
        out.append(Page(f"errors_{key}", f"{title[0].upper() + title[1:]} against time", fig))
    return out


def _error_axes(histories: dict, env: dict, key: str, colours: dict, inp: ReportInput):
    """The figure of one quantity: three axes (N, E, D) of the estimators on a common scale and,
    where one would flatten them, a narrow column of the free-inertial ones."""
    from matplotlib.ticker import MaxNLocator
    _, unit, names = AXES[key]
    settle_s = inp.scenario.settle_s
    after = (settle_s, np.inf)
    main, free = split_free(env, after)
    fig, axs = page_figure(3, 2 if free else 1, sharex=True, squeeze=False,
                           gridspec_kw={"width_ratios": [2.2, 1]} if free else None)
    for j in range(3):
        for c, group in enumerate([main] + ([free] if free else [])):
            ax = axs[j, c]
            for k in group:
                _draw_envelope(ax, histories[k].t_s, env[k], j, colours[k], inp.runs_plotted)
            _ylim(ax, [env[k] for k in group], j, after)
            ax.axvline(settle_s, color="0.4", lw=0.8, ls=":")
            shade(ax, inp.spans, label=j == 0)
            ax.grid(alpha=0.3)
            ax.set_ylabel(f"{names[j]}, {unit}" if c == 0 else f"{unit} (own scale)", fontsize=8)
        if free and j == 0:
            axs[0, 1].set_title("free inertial, on its own scale", fontsize=9)
    for ax in axs.flat:                       # the narrow column too: a few time ticks
        ax.xaxis.set_major_locator(MaxNLocator(6 if ax in axs[:, 0] else 4))
    for ax in axs[-1]:
        ax.set_xlabel("time, s")
    return fig
