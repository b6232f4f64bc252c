"""The report of a ``navsim run``: PNG figures and ``report.pdf`` (matplotlib ``PdfPages``)."""

from __future__ import annotations

import os
import signal
import sys
import threading
import warnings
from pathlib import Path

import numpy as np
import yaml

from navsim.flight.plots import flight_figures
from navsim.foundations.errors import OutputError
from navsim.foundations.outputs import OutputFolder, write_atomic
from navsim.records.states import BLOCKS
from navsim.report.summary import summary_pages
from navsim.report.tables import PNG_DPI, layout, monospace_block
from navsim.scoring.metrics import EULER_AXES, RunMetrics
from navsim.scoring.stats import chi2_band

AXES = {"pos": ("position error", "m", ["north", "east", "down"]),
        "vel": ("velocity error", "m/s", ["north", "east", "down"]),
        "att": ("attitude error", "deg", ["about north (roll-like)", "about east", "about down (heading)"])}


def pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _nanmean(x):
    """Mean over the runs (axis 0) of what they have: a closed-loop run's records end at its
    landing (NaN after it)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(x, axis=0)


def landmark_figure(histories: dict, metrics: RunMetrics, sightings, runs_plotted: int = 3):
    """Horizontal position error of the landmark-aided estimators on a linear scale, the
    sightings shaded, the camera's 3-sigma fix noise marked at the end of each sighting."""
    labels = [k for k, m in metrics.estimators.items() if m.landmarks and m.landmarks.fraction_within_3sigma > 0.5]
    if not labels or not sightings:
        return []
    plt = pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(10, 8.5), sharex=True)
    for label in labels:
        h = histories[label]
        good = ~np.asarray(h.diverged, bool)
        for j, (ax, name) in enumerate(zip(axes, ("north", "east"))):
            e = h.pos_err_m[good][..., j]
            for r in range(min(runs_plotted, e.shape[0])):
                ax.plot(h.t_s, e[r], lw=0.5, alpha=0.6)
            ax.plot(h.t_s, np.sqrt(_nanmean(e ** 2)), "k", lw=1.2, label=f"{label}: MC RMS")
        ratio = [s.max_ratio for s in metrics.estimators[label].landmarks.sightings]
        axes[2].plot([s[2] for s in sightings], ratio, "o", ms=3, label=f"{label}: worst run")
    for ax in axes:
        _shade(ax, sightings)
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
    axes[0].set_title("landmark sightings (green): the error drifts between anchors and returns after each")
    fig.tight_layout()
    return [("landmarks", fig)]


def closed_loop_figures(loop, reference, scenario):
    """Plan view of every run's true path with the landings and CEP circles, and the miss
    distances' distribution against the truth-guided flight."""
    plt = pyplot()
    rtl = scenario.closed_loop.return_to_land
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11.5, 5.2), gridspec_kw={"width_ratios": [1.3, 1]})
    paths = loop.path_n_m
    for p in paths:
        ax.plot(p[:, 1], p[:, 0], lw=0.5, color="tab:blue", alpha=0.35)
    ref = reference.path_n_m[0]
    ax.plot(ref[:, 1], ref[:, 0], lw=1.5, color="k", label="guided on the truth")
    if rtl is not None and reference.point_n_m is not None:
        pn, pe = reference.point_n_m
        land = loop.landing_n_m
        ax.plot(land[:, 1], land[:, 0], "x", color="tab:red", ms=4, label="parachute (truth)")
        ax.plot([pe], [pn], "*", color="tab:green", ms=12, label="recovery point")
        miss = np.asarray(loop.miss_m, float)
        th = np.linspace(0, 2 * np.pi, 200)
        for q, ls in ((50, "--"), (95, ":")):
            if np.isfinite(miss).any():
                r = np.nanpercentile(miss, q)
                ax.plot(pe + r * np.sin(th), pn + r * np.cos(th), ls, color="tab:red", lw=1,
                        label=f"CEP{q} {r:.1f} m")
        ax.plot(pe + rtl.area_m * np.sin(th), pn + rtl.area_m * np.cos(th), "-", color="tab:green",
                lw=0.8, label=f"recovery area {rtl.area_m:g} m")
        zoom = ax.inset_axes([0.03, 0.03, 0.36, 0.36])          # the recovery area, magnified
        zoom.plot(land[:, 1], land[:, 0], "x", color="tab:red", ms=3)
        zoom.plot([pe], [pn], "*", color="tab:green", ms=9)
        for q, ls in ((50, "--"), (95, ":")):
            if np.isfinite(miss).any():
                r = np.nanpercentile(miss, q)
                zoom.plot(pe + r * np.sin(th), pn + r * np.cos(th), ls, color="tab:red", lw=0.8)
        zoom.plot(pe + rtl.area_m * np.sin(th), pn + rtl.area_m * np.cos(th), "-", color="tab:green", lw=0.8)
        half = 1.15 * max(rtl.area_m, float(np.nanmax(miss)) if np.isfinite(miss).any() else 0.0)
        zoom.set(xlim=(pe - half, pe + half), ylim=(pn - half, pn + half), aspect="equal")
        zoom.tick_params(labelsize=6)
        srt = np.sort(miss[np.isfinite(miss)])
        if srt.size:
            bx.step(srt, np.arange(1, srt.size + 1) / srt.size, where="post", color="tab:blue",
                    label=f"guided on the solution ({srt.size} runs)")
            for q, ls in ((50, "--"), (95, ":")):
                bx.axvline(np.percentile(srt, q), ls=ls, color="tab:red", lw=1,
                           label=f"CEP{q} {np.percentile(srt, q):.1f} m")
        if np.isfinite(reference.miss_m[0]):
            bx.axvline(reference.miss_m[0], color="k", lw=1.5,
                       label=f"guided on the truth {reference.miss_m[0]:.2f} m")
        bx.set(xlabel="true miss distance at the parachute, m", ylabel="fraction of runs",
               title="miss distance")
        bx.legend(fontsize=7, loc="lower right")
        bx.grid(alpha=0.3)
    ax.set(xlabel="east, m", ylabel="north, m", title=f"true paths, flown on '{scenario.closed_loop.fly_on}'")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7, loc="best")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return [("closed_loop", fig)]


def _shade(ax, spans, label: bool = False):
    """Shade the metric windows ``(name, start_s, end_s)`` (fault, interference) in orange and
    landmark sightings ``(name, start_s, end_s, sigma_m)`` in green; ``label``: each window's
    name at the top of its span."""
    for span in spans:
        name, a, b = span[:3]
        if len(span) > 3:
            ax.axvspan(a, b, color="tab:green", alpha=0.25, lw=0)
            continue
        ax.axvspan(a, b, color="tab:orange", alpha=0.12, lw=0)
        if label:
            ax.text((a + b) / 2, 0.97, name, transform=ax.get_xaxis_transform(), fontsize=6.5, ha="center",
                    va="top", color="0.3", clip_on=True)


def estimator_colours(labels) -> dict:
    """A colour per estimator, distinct up to 20 (tab10, or tab20 beyond ten)."""
    labels = list(labels)
    cmap = pyplot().cm.tab10 if len(labels) <= 10 else pyplot().cm.tab20
    return {k: cmap(i % cmap.N) for i, k in enumerate(labels)}


def _legend_columns(labels) -> int:
    """Legend columns that keep a row of long labels inside the figure."""
    longest = max((len(str(lb)) for lb in labels), default=0)
    return 4 if longest <= 28 else 2 if longest <= 60 else 1


#: a free-inertial envelope this many times the aided ones' gets an axis of its own
OWN_AXIS_RATIO = 5.0


def _envelopes(h, key: str):
    """``(rms, sigma, errors, t_s)``: RMS and sigma ``(T, 3)`` over the runs that did not diverge
    (``sigma`` None without a covariance), their errors ``(R, T, 3)`` and the estimator's own
    epoch times ``(T,)`` (estimators record at their own periods); None if every run diverged."""
    good = ~np.asarray(h.diverged, bool)
    if not good.any():
        return None
    err = {"pos": h.pos_err_m, "vel": h.vel_err_mps, "att": np.degrees(h.att_err_rad)}[key][good]
    sig = None
    if h.sigma is not None:
        s = h.sigma[..., BLOCKS[key]]
        s = np.degrees(s) if key == "att" else s
        sig = np.sqrt(_nanmean(s[good] ** 2))
    return np.sqrt(_nanmean(err ** 2)), sig, err, h.t_s


def _span(t_s: np.ndarray, span) -> np.ndarray:
    """The epochs of ``t_s`` inside ``span = (start_s, end_s)``."""
    return (t_s >= span[0]) & (t_s <= span[1])


def _split_free(env: dict, span) -> tuple[list, list]:
    """The estimators drawn on the main axes and those (free inertial, no covariance) whose
    errors in ``span`` (after the settling time) exceed :data:`OWN_AXIS_RATIO` times the others'."""
    scale = {}
    for k, e in env.items():
        m = _span(e[3], span)
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
        ax.plot(t, err[r, :, j], color=colour, lw=0.4, alpha=0.35)
    ax.plot(t, rms[:, j], color=colour, lw=1.6)
    ax.plot(t, -rms[:, j], color=colour, lw=1.6)
    if sig is not None:
        ax.plot(t, 3 * sig[:, j], "--", color=colour, lw=1.0)
        ax.plot(t, -3 * sig[:, j], "--", color=colour, lw=1.0)


def _ylim(ax, envs, j: int, span) -> None:
    """The y range the estimators on ``ax`` need in ``span`` (after the settling time: RMS and
    3 sigma)."""
    peaks = []
    for e in envs:
        m = _span(e[3], span)
        if m.any():
            peaks += [float(np.nanmax(np.abs(e[0][m, j])))] + ([3 * float(np.nanmax(e[1][m, j]))]
                                                              if e[1] is not None else [])
    peak = max(peaks, default=0.0)
    if np.isfinite(peak) and peak > 0:
        ax.set_ylim(-1.15 * peak, 1.15 * peak)


def error_figures(histories: dict, settle_s: float, runs_plotted: int = 5, spans=()):
    """Per quantity, each axis against time: the Monte Carlo RMS (solid), the filter's 3 sigma
    (dashed) and a few runs (thin) of every estimator, the y range set by them after the
    settling time; a free-inertial estimator that would flatten the others on axes of its own
    (right); the metric windows shaded."""
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MaxNLocator
    plt = pyplot()
    colours = estimator_colours(histories)
    figs = []
    for key, (title, unit, names) in AXES.items():
        env = {k: e for k, h in histories.items() if (e := _envelopes(h, key)) is not None}
        if not env:
            continue
        after = (settle_s, np.inf)
        main, free = _split_free(env, after)
        cols = 2 if free else 1
        fig, axs = plt.subplots(3, cols, figsize=(11, 9), sharex=True, squeeze=False,
                                gridspec_kw={"width_ratios": [2.2, 1]} if free else None)
        for j in range(3):
            for c, group in enumerate([main] + ([free] if free else [])):
                ax = axs[j, c]
                for k in group:
                    _draw_envelope(ax, histories[k].t_s, env[k], j, colours[k], runs_plotted)
                _ylim(ax, [env[k] for k in group], j, after)
                ax.axvline(settle_s, color="0.4", lw=0.8, ls=":")
                _shade(ax, spans, label=j == 0)
                ax.grid(alpha=0.3)
                ax.set_ylabel(f"{names[j]}, {unit}" if c == 0 else f"{unit} (own scale)", fontsize=8)
            if free and j == 0:
                axs[0, 1].set_title("free inertial, on its own scale", fontsize=9)
        for ax in axs.flat:                       # the narrow column too: a few time ticks
            ax.xaxis.set_major_locator(MaxNLocator(6 if ax in axs[:, 0] else 4))
        for ax in axs[-1]:
            ax.set_xlabel("time, s")
        handles = [Line2D([], [], color=colours[k], lw=1.6, label=k) for k in env]
        handles += [Line2D([], [], color="0.3", lw=1.6, label="Monte Carlo RMS"),
                    Line2D([], [], color="0.3", lw=1.0, ls="--", label="filter ±3σ"),
                    Line2D([], [], color="0.3", lw=0.4, label=f"first {runs_plotted} runs"),
                    Line2D([], [], color="0.4", lw=0.8, ls=":", label=f"settling time {settle_s:g} s")]
        fig.suptitle(title, fontsize=12)
        fig.legend(handles=handles, loc="upper center", ncol=min(len(handles), _legend_columns(histories)),
                   fontsize=7.5, frameon=False, bbox_to_anchor=(0.5, 0.962))
        fig.tight_layout(rect=(0, 0, 1, 0.935))
        figs.append((f"errors_{key}", fig))
    return figs


#: the most panels on one consistency page (more go to the next)
PANELS_PER_PAGE = 5


def _inside(series: np.ndarray, lo: float, hi: float) -> str:
    ok = np.isfinite(series)
    return f"{100 * np.mean((series[ok] >= lo) & (series[ok] <= hi)):.0f} % of epochs inside" if ok.any() else ""


def _band(ax, lo: float, hi: float, colour) -> None:
    """A 95 % band as two dashed lines (no fill: the windows' shading stays readable)."""
    for y in (lo, hi):
        ax.axhline(y, color=colour, lw=0.9, ls="--", alpha=0.8)


def _consistency_panels(filters: dict, colours) -> list:
    """``(ylabel, [(label, t, series, lo, hi, colour, marker)])`` per panel: the NEES of every
    filter together, then each filter's NIS per measurement."""
    nees, nis = [], []
    for c, (label, h) in enumerate(filters.items()):
        good = ~np.asarray(h.diverged, bool)
        n = int(good.sum())
        if n == 0:
            continue
        lo, hi = chi2_band(9, n)
        nees.append((label, h.t_s[1:], np.nanmean(h.nees[good], axis=0)[1:], lo, hi, colours[c % 10], "-"))
        for key, v in h.nis.items():
            d, v = h.nis_dim[key], v[good]
            cols = ~np.isnan(v).all(axis=0)
            lo, hi = chi2_band(d, n)
            nis.append((f"NIS {key}, dim {d}\n{label}",
                        [(label, h.t_s[cols], np.nanmean(v[:, cols], axis=0), lo, hi, colours[c % 10], ".")]))
    return ([("average NEES, dim 9\n(att, vel, pos)", nees)] if nees else []) + nis


def consistency_figure(histories: dict, spans=()):
    """The average NEES and NIS over the runs against their two-sided 95 % chi-square bands
    (dashed), each panel saying the share of epochs inside; :data:`PANELS_PER_PAGE` a page."""
    from matplotlib.lines import Line2D
    plt = pyplot()
    filters = {k: h for k, h in histories.items() if h.nees is not None}
    colours = plt.cm.tab10(np.arange(10))
    panels = _consistency_panels(filters, colours)
    figs = []
    for start in range(0, len(panels), PANELS_PER_PAGE):
        page = panels[start:start + PANELS_PER_PAGE]
        fig, axs = plt.subplots(len(page), 1, figsize=(10, 1.2 + 2.3 * len(page)), sharex=True, squeeze=False)
        for ax, (ylabel, series) in zip(axs[:, 0], page):
            notes = []
            for label, t, y, lo, hi, colour, marker in series:
                ax.plot(t, y, marker, ms=2, lw=1.2, color=colour)
                _band(ax, lo, hi, colour)
                notes.append(f"{label}: {_inside(y, lo, hi)}" if len(series) > 1 else _inside(y, lo, hi))
            ax.text(0.01, 0.96, "\n".join(notes), transform=ax.transAxes, fontsize=7, va="top",
                    bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})
            _shade(ax, spans, label=ax is axs[0, 0])
            ax.set_ylabel(ylabel, fontsize=7.5)
            ax.grid(alpha=0.3)
        axs[-1, 0].set_xlabel("time, s")
        handles = [Line2D([], [], color=colours[c % 10], lw=1.2, label=k) for c, k in enumerate(filters)]
        handles.append(Line2D([], [], color="0.4", lw=0.9, ls="--", label="95 % chi-square band of the average"))
        fig.suptitle("Consistency: the average NEES and NIS over the runs" + (" (continued)" if start else ""),
                     fontsize=11)
        fig.legend(handles=handles, loc="upper center", ncol=min(len(handles), _legend_columns(filters)),
                   fontsize=7.5, frameon=False, bbox_to_anchor=(0.5, 1 - 0.35 / fig.get_figheight()))
        fig.tight_layout(rect=(0, 0, 1, 1 - 0.75 / fig.get_figheight()))
        figs.append(("consistency" if not start else f"consistency_{start // PANELS_PER_PAGE + 1}", fig))
    return figs


def _height_panel(ax, histories: dict, labels: list, colours, runs_plotted: int, faults, spans, after) -> None:
    """The height errors (up) of ``labels``: a few runs (thin) and the RMS over runs, the y
    range set by them in the time span ``after``; sensor faults shaded red, windows orange."""
    peak = 0.0
    for k in labels:
        h = histories[k]
        good = ~np.asarray(h.diverged, bool)
        dh = -h.pos_err_m[good][..., 2]
        for r in range(min(runs_plotted, dh.shape[0])):
            ax.plot(h.t_s, dh[r], color=colours[k], lw=0.5, alpha=0.5)
        ax.plot(h.t_s, np.sqrt(_nanmean(dh ** 2)), color=colours[k], lw=1.6)
        m = _span(h.t_s, after)
        if m.any():
            peak = max(peak, float(np.nanpercentile(np.abs(dh[:, m]), 99.5)))
    end = next(iter(histories.values())).t_s[-1]
    for name, f in faults:
        ax.axvspan(f.start_s, min(f.end_s, end), color="tab:red", alpha=0.15, lw=0)
        ax.text(f.start_s, 0.97, f" {name} {f.type}", transform=ax.get_xaxis_transform(), fontsize=6.5, va="top",
                color="tab:red", clip_on=True)
    _shade(ax, spans)
    if peak > 0 and np.isfinite(peak):
        ax.set_ylim(-1.15 * peak, 1.15 * peak)
    ax.axhline(0.0, color="k", lw=0.5)
    ax.grid(alpha=0.3)


def height_figure(histories: dict, scenario, runs_plotted: int = 3):
    """Height error against time (P2's Figures 4-5): the RMS over runs and a few runs of each
    estimator, a free-inertial one that would flatten the others on axes of its own; a second
    row zooms on the first metric window."""
    from matplotlib.lines import Line2D
    plt = pyplot()
    faults = [(c.name, f) for c in scenario.sensors for f in c.faults if f.type != "interference"]
    env = {k: e for k, h in histories.items() if (e := _envelopes(h, "pos")) is not None}
    if not env or (not faults and not scenario.windows):
        return []
    colours = estimator_colours(histories)
    after = (scenario.settle_s, np.inf)
    main, free = _split_free({k: (e[0][:, 2:], e[1], e[2], e[3]) for k, e in env.items()}, after)
    rows = 2 if scenario.windows else 1
    fig, axs = plt.subplots(rows, 2 if free else 1, figsize=(11, 4 + 3.5 * rows), squeeze=False,
                            gridspec_kw={"width_ratios": [2.2, 1]} if free else None)
    _height_panel(axs[0, 0], histories, main, colours, runs_plotted, faults, scenario.windows, after)
    axs[0, 0].set_ylabel("height error (up), m")
    if free:
        _height_panel(axs[0, 1], histories, free, colours, runs_plotted, faults, scenario.windows, after)
        axs[0, 1].set_title("free inertial, on its own scale", fontsize=9)
    if scenario.windows:
        name, a, b = scenario.windows[0]
        _height_panel(axs[1, 0], histories, main, colours, runs_plotted, faults, (), (a, b))
        axs[1, 0].set_xlim(a, b)
        axs[1, 0].set_title(f"window '{name}' ({a:g}-{b:g} s)", fontsize=9)
        axs[1, 0].set_ylabel("height error (up), m")
        if free:
            axs[1, 1].set_visible(False)
    for ax in axs.flat:
        if ax.get_visible():
            ax.set_xlabel("time, s")
    handles = [Line2D([], [], color=colours[k], lw=1.6, label=f"{k}: RMS over runs") for k in env]
    handles.append(Line2D([], [], color="0.3", lw=0.5, label=f"first {runs_plotted} runs"))
    shaded = (["sensor faults red"] if faults else []) + (["metric windows orange"] if scenario.windows else [])
    fig.suptitle("Height error against time" + (f" ({', '.join(shaded)})" if shaded else ""), fontsize=11)
    fig.legend(handles=handles, loc="upper center", ncol=min(len(handles), 3), fontsize=7.5, frameon=False,
               bbox_to_anchor=(0.5, 1 - 0.35 / fig.get_figheight()))
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.8 / fig.get_figheight()))
    return [("height", fig)]


#: a bias whose 1-sigma ends above this share of its initial value was not observed
UNOBSERVED_SIGMA_SHARE = 0.8
#: the largest number of bias pages (one per estimator with bias estimates)
MAX_BIAS_PAGES = 4
_BIAS_UNITS = {"gyro_bias": ("gyro", 180 / np.pi * 3600, "deg/h"), "accel_bias": ("accelerometer", 1e6 / 9.80665, "µg")}
#: the larger unit a bias is drawn in when its truth exceeds 1000 of the small one
_BIAS_LARGE = {"gyro_bias": (180 / np.pi, "deg/s"), "accel_bias": (1e3 / 9.80665, "mg")}


def _bias_unit(key: str, truth_bias: dict) -> tuple[float, str]:
    """The scale and unit of ``key``'s plots: deg/h or deg/s, µg or mg, by the truth's size."""
    _, scale, unit = _BIAS_UNITS[key]
    truth = truth_bias.get(f"{key}_seen", truth_bias.get(key))
    if truth is not None and np.nanmax(np.abs(truth)) * scale > 1000:
        return _BIAS_LARGE[key]
    return scale, unit


def _seen_differs(truth_bias: dict) -> bool:
    """Whether the bias a state sees differs from the additive bias (scale factors or
    misalignments in the truth model)."""
    return any(f"{k}_seen" in truth_bias and k in truth_bias and np.nanmax(np.abs(truth_bias[f"{k}_seen"]
               - truth_bias[k])) * _BIAS_UNITS[k][1] > 1e-3 for k in _BIAS_UNITS)


def _bias_axis(ax, h, key: str, j: int, truth_bias: dict, runs: int, colours, truth_t) -> None:
    """One bias axis of one estimator: per run (its own colour) the estimate (solid) with its
    ±1 sigma band, the bias its state can see (dashed) and the additive bias alone (dotted)
    where they differ (``truth_t``: their times, the first estimator's epochs); the title says
    when the sigma never left its initial value."""
    name = _BIAS_UNITS[key][0]
    scale, unit = _bias_unit(key, truth_bias)
    est, sig = getattr(h, key), getattr(h, f"{key}_sigma")
    seen, additive = truth_bias.get(f"{key}_seen"), truth_bias.get(key)
    differs = _seen_differs(truth_bias)
    for r in range(min(runs, est.shape[0])):
        c = colours[r]
        ax.plot(h.t_s, est[r, :, j] * scale, color=c, lw=1.0)
        if sig is not None and np.isfinite(sig[r, :, j]).any():
            ax.fill_between(h.t_s, (est[r, :, j] - sig[r, :, j]) * scale, (est[r, :, j] + sig[r, :, j]) * scale,
                            color=c, alpha=0.15, lw=0)
        truth = seen if seen is not None else additive
        if truth is not None:
            ax.plot(truth_t, truth[r, :, j] * scale, color=c, lw=1.0, ls="--")
        if differs:
            ax.plot(truth_t, additive[r, :, j] * scale, color=c, lw=0.8, ls=":")
    ax.set_ylabel(f"{name} {'xyz'[j]}, {unit}", fontsize=8)
    ax.grid(alpha=0.3)
    if sig is not None and np.isnan(sig[:, :, j]).all():
        ax.set_title("not a state of this filter", fontsize=7.5, color="0.4", loc="left")
    elif sig is not None:
        share = _sigma_share(sig[:, :, j])
        if np.isfinite(share) and share > UNOBSERVED_SIGMA_SHARE:
            ax.set_title(f"not observable on this flight: sigma ends at {100 * share:.0f} % of its start",
                         fontsize=7.5, color="#b45309", loc="left")


def _sigma_share(sig: np.ndarray) -> float:
    """The median over runs of each run's last finite sigma over its first ``(R, E)`` (a run
    that stopped or landed ends in NaN)."""
    shares = []
    for s in sig:
        ok = np.flatnonzero(np.isfinite(s))
        if ok.size:
            shares.append(s[ok[-1]] / max(s[ok[0]], 1e-300))
    return float(np.median(shares)) if shares else float("nan")


def bias_figure(histories: dict, truth_bias: dict, runs_plotted: int = 3):
    """Per estimator with bias estimates: the gyro (left) and accelerometer (right) biases of
    its first runs against the truth, each run in its own colour (:func:`_bias_axis`)."""
    from matplotlib.lines import Line2D
    plt = pyplot()
    filters = [(k, h) for k, h in histories.items() if h.gyro_bias is not None][:MAX_BIAS_PAGES]
    if not filters or not truth_bias:
        return []
    colours = plt.cm.tab10(np.arange(10))
    truth_t = next(iter(histories.values())).t_s          # the truth is recorded at the first estimator's epochs
    figs = []
    for label, h in filters:
        fig, axs = plt.subplots(3, 2, figsize=(11, 8.5), sharex=True)
        for col, key in enumerate(("gyro_bias", "accel_bias")):
            for j in range(3):
                _bias_axis(axs[j, col], h, key, j, truth_bias, runs_plotted, colours, truth_t)
        for ax in axs[-1]:
            ax.set_xlabel("time, s")
        seen = _seen_differs(truth_bias)
        handles = [Line2D([], [], color="0.3", lw=1.0, label="estimate (band: ±1σ)"),
                   Line2D([], [], color="0.3", lw=1.0, ls="--",
                          label="truth the state sees: bias + (scale factor + misalignment) × rate or force"
                          if seen else "true bias"),
                   Line2D([], [], color="0.3", lw=0.8, ls=":", label="additive bias alone" if seen else "")]
        styles = [hd for hd in handles if hd.get_label()]
        runs = [Line2D([], [], color=colours[r], lw=1.0, label=f"run {r}")
                for r in range(min(runs_plotted, h.gyro_bias.shape[0]))]
        fig.suptitle(f"{label}: IMU bias estimates against the truth, first {runs_plotted} runs", fontsize=11)
        fig.add_artist(fig.legend(handles=styles, loc="upper center", ncol=len(styles), fontsize=7.5, frameon=False,
                                  bbox_to_anchor=(0.5, 0.965)))
        fig.legend(handles=runs, loc="upper center", ncol=len(runs), fontsize=7.5, frameon=False,
                   bbox_to_anchor=(0.5, 0.94))
        fig.tight_layout(rect=(0, 0, 1, 0.915))
        figs.append(("biases" if not figs else f"biases_{_slug(label)}", fig))
    return figs


def calibration_figures(calibration: dict, histories: dict, metrics: RunMetrics, spans=(), runs_plotted: int = 3):
    """Per calibrated magnetometer: hard- and soft-iron errors against time (mean and 95th
    percentile over the runs, a few runs thin) with the mark of two full turns and the 2 %
    line, and the heading error of each estimator (Monte Carlo RMS) against time."""
    plt = pyplot()
    colors = plt.cm.tab10(np.arange(10))
    figs = []
    for name, cal in calibration.items():
        fig, axs = plt.subplots(3, 1, figsize=(10, 11), sharex=True, gridspec_kw={"height_ratios": [3, 3, 3]})
        t = cal["t_s"]
        mark = np.flatnonzero(cal["turns"] >= 2.0)
        t2 = t[mark[0]] if mark.size else None
        for ax, key, title in ((axs[0], "hard_iron_err", "hard-iron error, % of |m|"),
                               (axs[1], "soft_iron_err", "soft-iron error, % (Frobenius)")):
            e = 100.0 * cal[key]
            for r in range(min(runs_plotted, e.shape[0])):
                ax.plot(t, e[r], color="0.6", lw=0.5)
            with warnings.catch_warnings():          # epochs where no run has an ellipsoid yet
                warnings.simplefilter("ignore", RuntimeWarning)
                ax.plot(t, np.nanmean(e, 0), color="tab:blue", lw=1.6, label="mean over runs")
                ax.plot(t, np.nanpercentile(e, 95, axis=0), color="tab:red", lw=1.2, label="95th percentile")
            ax.axhline(2.0, color="k", ls="--", lw=0.8, label="2 % (acceptance)")
            ax.set_yscale("log")
            ax.set_ylim(0.05, 200)
            ax.set_ylabel(title, fontsize=8)
            ax.grid(alpha=0.3, which="both")
            ax2 = ax.twinx()
            ax2.plot(t, cal["turns"], color="tab:green", lw=0.8)
            ax2.set_ylabel("full turns (true heading)", fontsize=7, color="tab:green")
        score = (metrics.calibration or {}).get(name)
        if score and score.after_turns:
            at, h, s_ = score.after_turns, score.after_turns.hard_iron_pct, score.after_turns.soft_iron_pct
            axs[0].set_title(f"after {score.turns:g} full turns ({at.t_s:.0f} s): hard iron {h.mean:.2f} / "
                             f"{h.p95:.2f} / {h.max:.2f} %, soft iron {s_.mean:.2f} / {s_.p95:.2f} / "
                             f"{s_.max:.2f} % (mean / 95th percentile / max)", fontsize=8)
        for c, (label, hist) in enumerate(histories.items()):
            good = ~np.asarray(hist.diverged, bool)
            if good.any():
                rms = np.sqrt(_nanmean(np.degrees(hist.att_err_rad[good][..., 2]) ** 2))
                axs[2].plot(hist.t_s, rms, color=colors[c % 10], lw=1.4, label=f"{label}: MC RMS")
        axs[2].set_ylabel("heading error, deg (RMS over runs)", fontsize=8)
        axs[2].set_yscale("log")
        axs[2].grid(alpha=0.3, which="both")
        axs[2].legend(fontsize=7, loc="upper right")
        for j, ax in enumerate(axs):
            _shade(ax, spans, label=j == 0)
            if t2 is not None:
                ax.axvline(t2, color="tab:green", lw=1.0, ls=":")
        if t2 is not None:
            axs[1].text(t2, 1.0, " two full turns", transform=axs[1].get_xaxis_transform(), fontsize=7,
                        va="top", color="tab:green")
        axs[0].legend(fontsize=7, loc="upper right")
        axs[-1].set_xlabel("time, s")
        fig.suptitle(f"Magnetometer '{name}': online calibration (RLS ellipsoid fit) and heading error")
        fig.tight_layout()
        figs.append((f"calibration_{name}", fig))
    return figs


def report_pages(scenario, truth, result, metrics: RunMetrics, record: dict, loop=None,
                 reference=None, sightings=()) -> list:
    """The report's pages ``[(name, figure), ...]`` in order (see :func:`write_report`)."""
    runs_plotted = scenario.report.get("runs_plotted", 5)
    pages = summary_pages(scenario, record, metrics)
    resolved = dict(scenario.raw)
    resolved["montecarlo"] = {**(resolved.get("montecarlo") or {}), "runs": record["runs"],
                              "seed": record["seed"], "workers": record["workers"]}
    text = yaml.safe_dump(resolved, sort_keys=False, width=110, default_flow_style=None).splitlines()
    if len(text) > 120:
        text = text[:118] + ["...", "(the whole file: scenario.resolved.yaml)"]
    pages += [("scenario" if i == 0 else f"scenario_{i + 1}", f)
              for i, f in enumerate(layout(f"{scenario.name}: the scenario as run", [monospace_block(text)]))]
    if truth is not None:
        pages += [(f"flight_{n}", f) for n, f in flight_figures(truth)]
    if loop is not None:
        pages += closed_loop_figures(loop, reference, scenario)
    if result.histories:
        spans = tuple(scenario.windows) + tuple(sightings)
        pages += error_figures(result.histories, scenario.settle_s, runs_plotted, spans)
        pages += height_figure(result.histories, scenario)
        pages += landmark_figure(result.histories, metrics, sightings, runs_plotted)
        pages += attitude_figure(result.histories, scenario.settle_s, runs_plotted, spans,
                                 paper_attitude_bounds(scenario.reference))
        pages += consistency_figure(result.histories, spans)
        pages += bias_figure(result.histories, result.truth_bias)
        pages += calibration_figures(result.calibration, result.histories, metrics, scenario.windows)
    return pages


def write_report(folder: OutputFolder, scenario, truth, result, metrics: RunMetrics, record: dict,
                 loop: dict | None = None, reference=None, sightings=()) -> list[Path]:
    """Write the PNGs and ``report.pdf`` into the output folder ``folder`` (each name recorded
    in its manifest before it is written); returns the files written. ``loop`` and
    ``reference``: the per-run outcome of a closed-loop scenario and its truth-guided flight;
    ``sightings``: landmark sightings ``(name, start_s, end_s, sigma_m)``, shaded in green."""
    plt = pyplot()
    pages = []
    try:
        pages = report_pages(scenario, truth, result, metrics, record, loop, reference, sightings)
        return _render(folder, pages, scenario.report.get("formats", ["pdf", "png"]),
                       f"navsim report: {scenario.name}")
    finally:
        for _, fig in pages:               # also those not reached when writing failed
            plt.close(fig)


def _render(folder: OutputFolder, pages: list, fmts, title: str) -> list[Path]:
    """Each page to ``<name>.png`` and all of them, in order, to ``report.pdf``; returns the
    files written. Where the machine has a second core and ``fork`` (Linux), a forked child
    draws the PNGs while this process draws the PDF (about half the time: a page costs as
    much to draw for either)."""
    out = folder.path
    pngs = [(out / f"{name}.png", fig) for name, fig in pages] if "png" in fmts else []
    pdf_path = out / "report.pdf" if "pdf" in fmts else None
    folder.record([p for p, _ in pngs] + ([pdf_path] if pdf_path else []))
    child = _fork_writer(pngs) if pngs and pdf_path and _can_fork() else None
    if child is None:
        _write_pngs(pngs)
    try:
        if pdf_path is not None:
            write_atomic(pdf_path, lambda p: _write_pdf(p, pages, title))
    except BaseException:
        if child is not None:                 # this error is the one reported
            _join_writer(*child, report=False)
        raise
    if child is not None:
        _join_writer(*child)
    return [p for p, _ in pngs] + ([pdf_path] if pdf_path else [])




def _write_pngs(pngs: list) -> None:
    for path, fig in pngs:
        write_atomic(path, lambda p, fig=fig: fig.savefig(p, dpi=PNG_DPI))


def _write_pdf(path: Path, pages: list, title: str) -> None:
    from matplotlib.backends.backend_pdf import PdfPages
    with PdfPages(path) as pdf:
        for _, fig in pages:
            pdf.savefig(fig)
        pdf.infodict()["Title"] = title


def _can_fork() -> bool:
    return (sys.platform == "linux" and hasattr(os, "fork") and len(os.sched_getaffinity(0)) > 1
            and threading.current_thread() is threading.main_thread())


def _fork_writer(pngs: list):
    """Fork a child that writes the PNGs ``(path, figure)``; returns its pid and the pipe on
    which it reports a failure (errno, path and reason of an OS error, or an exception's
    name and message; nothing on success), or None when the fork fails. Ctrl-C is held back
    across the fork, so it reaches the child inside its ``try``."""
    r, w = os.pipe()
    held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        pid = os.fork()
    except OSError:                          # no process to spare: drawn one after the other
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
        os.close(r)
        os.close(w)
        return None
    if pid:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
        os.close(w)
        return pid, r
    code = 0
    try:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
        os.close(r)
        _write_pngs(pngs)
    except OutputError as exc:
        os.write(w, f"{exc.errno or 0}\n{exc.path}\n{exc.reason}".encode())
        code = 4
    except KeyboardInterrupt:
        code = 130
    except BaseException as exc:              # the parent reports it; never return into it
        os.write(w, f"\n\n{type(exc).__name__}: {exc}".encode())
        code = 1
    finally:
        os._exit(code)


def _join_writer(pid: int, pipe: int, report: bool = True) -> None:
    """Wait for the PNG writer and, with ``report``, raise its failure here."""
    try:
        with os.fdopen(pipe, "rb") as f:
            message = f.read().decode(errors="replace")
    finally:                                  # never a zombie, even on Ctrl-C
        _, status = os.waitpid(pid, 0)
    code = os.waitstatus_to_exitcode(status)
    if code == 0 or not report:
        return
    if code == 130:
        raise KeyboardInterrupt
    number, path, why = (message.split("\n", 2) + ["", ""])[:3]
    if path:
        number = int(number or 0)
        raise OutputError(path, OSError(number, why)) if number else OutputError(path, reason=why)
    raise RuntimeError(f"the PNG writer failed: {why or f'exit code {code}'}")


# --- attitude estimators (P4): the summary's attitude table and the roll/pitch/yaw pages ---


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


def attitude_figure(histories: dict, settle_s: float, runs_plotted: int = 5, spans=(), bounds=None):
    """Roll, pitch, yaw error of each attitude estimator: a few runs, the 95th percentile of
    |error| over the runs, and a tick per reset of the divergence monitor (red, with its time
    listed for the first run)."""
    labels = [k for k, h in histories.items() if h.euler_err_rad is not None and h.resets is not None]
    if not labels:
        return []
    plt = pyplot()
    figs = []
    for label in labels:
        h = histories[label]
        e = np.degrees(h.euler_err_rad)
        fig, axes = plt.subplots(3, 1, figsize=(10, 8.5), sharex=True)
        for j, ax in enumerate(axes):
            for r in range(min(runs_plotted, e.shape[0])):
                ax.plot(h.t_s, e[r, :, j], lw=0.5, alpha=0.7)
            p95 = np.nanpercentile(np.abs(e[:, :, j]), 95, axis=0)
            ax.plot(h.t_s, p95, "k", lw=1.0, label="95th pct of |error| over the runs")
            ax.plot(h.t_s, -p95, "k", lw=1.0)
            after = h.t_s >= settle_s
            lim = max(3 * float(np.nanpercentile(np.abs(e[:, after, j]), 99)), 0.05) if after.any() else None
            if lim and np.isfinite(lim):
                ax.set_ylim(-lim, lim)
            _shade(ax, spans)
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
        title = f"{label}: attitude error; resets (red) {len(times)} in {sum(bool(r) for r in h.resets)} runs"
        axes[0].set_title(title + f"; run 0 at {first} s" if times else title)
        axes[0].legend(fontsize=7, loc="upper right")
        axes[-1].set_xlabel("time, s")
        fig.tight_layout()
        figs.append((f"attitude_{_slug(label)}", fig))
    return figs


def _slug(label: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in label).strip("_").lower()
