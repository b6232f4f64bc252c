"""IMU bias estimates against the truth, one page per estimator that estimates them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.flight.plots import fill_drawn, plot_drawn
from navsim.records.truth import TruthBias
from navsim.report.figures import Page, ReportInput, head, page_figure, pyplot, slug

#: a bias whose 1-sigma ends above this share of its initial value was not observed
UNOBSERVED_SIGMA_SHARE = 0.8
#: the runs drawn on a bias page
BIAS_RUNS = 3
#: the largest number of bias pages (one per estimator with bias estimates)
MAX_BIAS_PAGES = 4
_BIAS_UNITS = {"gyro_bias": ("gyro", 180 / np.pi * 3600, "deg/h"), "accel_bias": ("accelerometer", 1e6 / 9.80665, "µg")}
#: the larger unit a bias is drawn in when its truth exceeds 1000 of the small one
_BIAS_LARGE = {"gyro_bias": (180 / np.pi, "deg/s"), "accel_bias": (1e3 / 9.80665, "mg")}


def _bias_unit(key: str, truth_bias: TruthBias) -> tuple[float, str]:
    """The scale and unit of ``key``'s plots: deg/h or deg/s, µg or mg, by the truth's size."""
    _, scale, unit = _BIAS_UNITS[key]
    if np.nanmax(np.abs(truth_bias.seen(key))) * scale > 1000:
        return _BIAS_LARGE[key]
    return scale, unit


def _seen_differs(truth_bias: TruthBias) -> bool:
    """Whether the bias a state sees differs from the additive bias (scale factors or
    misalignments in the truth model)."""
    return any(getattr(truth_bias, f"{k}_seen") is not None
               and np.nanmax(np.abs(truth_bias.seen(k) - getattr(truth_bias, k))) * _BIAS_UNITS[k][1] > 1e-3
               for k in _BIAS_UNITS)


@dataclass(frozen=True)
class BiasTruth:
    """The runs' true IMU biases (``bias``) and their times (``t_s``: the first estimator's
    epochs, where the truth is recorded)."""

    bias: TruthBias
    t_s: np.ndarray


def _bias_axis(ax, h, key: str, j: int, truth: BiasTruth, runs: int, colours) -> None:
    """One bias axis of one estimator: per run (its own colour) the estimate (solid) with its
    ±1 sigma band, the bias its state can see (dashed) and the additive bias alone (dotted)
    where they differ (drawn at ``truth.t_s``); the title says when the sigma never left its
    initial value."""
    truth_bias, truth_t = truth.bias, truth.t_s
    name = _BIAS_UNITS[key][0]
    scale, unit = _bias_unit(key, truth_bias)
    est, sig = getattr(h, key), getattr(h, f"{key}_sigma")
    truth, additive = truth_bias.seen(key), getattr(truth_bias, key)
    differs = _seen_differs(truth_bias)
    for r in range(min(runs, est.shape[0])):
        c = colours[r]
        plot_drawn(ax, h.t_s, est[r, :, j] * scale, color=c, lw=1.0)
        if sig is not None and np.isfinite(sig[r, :, j]).any():
            fill_drawn(ax, h.t_s, (est[r, :, j] - sig[r, :, j]) * scale, (est[r, :, j] + sig[r, :, j]) * scale,
                       color=c, alpha=0.15, lw=0)
        plot_drawn(ax, truth_t, truth[r, :, j] * scale, color=c, lw=1.0, ls="--")
        if differs:
            plot_drawn(ax, truth_t, additive[r, :, j] * scale, color=c, lw=0.8, ls=":")
    ax.set_ylabel(f"{name} {'xyz'[j]}, {unit}", fontsize=8)
    ax.grid(alpha=0.3)
    if sig is not None and np.isnan(sig[:, :, j]).all():
        ax.set_title("not a state of this filter", fontsize=7.5, color="0.4", loc="left")
    elif sig is not None:
        share = _sigma_share(sig[:, :, j])
        if np.isfinite(share) and share > UNOBSERVED_SIGMA_SHARE:
            ax.set_title(f"not observable on this flight:\nσ ends at {100 * share:.0f} % of its start "
                         "(median of the runs drawn)",
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


def pages(inp: ReportInput) -> list[Page]:
    """Per estimator with bias estimates: the gyro (left) and accelerometer (right) biases of
    its first :data:`BIAS_RUNS` runs against the truth, each run in its own colour
    (:func:`_bias_axis`)."""
    from matplotlib.lines import Line2D
    histories, truth_bias = inp.histories, inp.result.truth_bias
    filters = [(k, h) for k, h in histories.items() if h.gyro_bias is not None][:MAX_BIAS_PAGES]
    if not filters or truth_bias is None:
        return []
    colours = pyplot().cm.tab10(np.arange(10))
    truth_t = next(iter(histories.values())).t_s          # the truth is recorded at the first estimator's epochs
    seen = _seen_differs(truth_bias)
    handles = [Line2D([], [], color="0.3", lw=1.0, label="estimate (band: ±1σ)"),
               Line2D([], [], color="0.3", lw=1.0, ls="--",
                      label="truth the state sees: bias + (scale factor + misalignment) × rate or force"
                      if seen else "true bias")]
    handles += [Line2D([], [], color="0.3", lw=0.8, ls=":", label="additive bias alone")] if seen else []
    truth = BiasTruth(truth_bias, truth_t)
    out = []
    for label, h in filters:
        fig, axs = page_figure(3, 2, sharex=True)
        for col, key in enumerate(("gyro_bias", "accel_bias")):
            for j in range(3):
                _bias_axis(axs[j, col], h, key, j, truth, BIAS_RUNS, colours)
        for ax in axs[-1]:
            ax.set_xlabel("time, s")
        runs = [Line2D([], [], color=colours[r], lw=1.0, label=f"run {r}")
                for r in range(min(BIAS_RUNS, h.gyro_bias.shape[0]))]
        title = f"{label}: IMU bias estimates against the truth"
        head(fig, f"{title}, first {len(runs)} runs", handles + runs, 2 if seen else len(handles) + len(runs))
        out.append(Page("biases" if not out else f"biases_{slug(label)}", title, fig))
    return out
