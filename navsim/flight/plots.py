"""Pictures of a flight: 3-D track, ground track, altitude / airspeed / bank versus time."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from navsim.flight.truth import Truth
from navsim.foundations.earth import local_ne
from navsim.foundations.outputs import write_atomic


#: the most samples of a flight's 100 Hz record a line draws: a page's axes are about 800 pixels
#: wide, and drawing 50 000 points a line took most of a flight page's time
PLOT_POINTS = 2000

#: a flight page's margins around its axes, inches (fixed, not measured): left (tick labels and
#: y label), right, below (tick labels and x label), between two rows, above the first row
#: (the segments' numbers)
MARGIN_IN = {"left": 0.95, "right": 0.3, "bottom": 0.55, "row": 0.2, "numbers": 0.2}
#: the most a heading drawn unwrapped may turn in all, deg (more: drawn wrapped to [0, 360))
MAX_UNWRAPPED_DEG = 720.0


def drawn(y: np.ndarray, points: int = PLOT_POINTS) -> np.ndarray:
    """The indices of a series' samples to draw, in order: all of them up to ``points``; else
    the first and the last sample and, in each of about ``points / 2`` equal runs of samples
    (the last one shorter), the smallest and the largest of ``y`` and its first NaN (min/max
    decimation: a line through them covers the pixels the whole series would at a page's
    width, a spike stays drawn and a gap stays a gap)."""
    n = len(y)
    if n <= points:
        return np.arange(n)
    k = -(-n // (points // 2))
    rows = np.minimum(np.arange(-(-n // k) * k), n - 1).reshape(-1, k)      # the last run padded
    body = np.asarray(y, float)[rows]
    nan = np.isnan(body)
    low, high = np.argmin(np.where(nan, np.inf, body), axis=1), np.argmax(np.where(nan, -np.inf, body), axis=1)
    cols = [low, high, np.where(nan.any(axis=1), np.argmax(nan, axis=1), low)]
    picked = np.take_along_axis(rows, np.stack(cols, axis=1), axis=1)
    return np.unique(np.concatenate([[0], picked.ravel(), [n - 1]]))


def plot_drawn(ax, t: np.ndarray, y: np.ndarray, *args, **kw):
    """``ax.plot(t, y, ...)`` of the samples :func:`drawn` picks."""
    k = drawn(y)
    return ax.plot(np.asarray(t)[k], np.asarray(y)[k], *args, **kw)


def fill_drawn(ax, t: np.ndarray, lo: np.ndarray, hi: np.ndarray, **kw):
    """``ax.fill_between(t, lo, hi, ...)`` of the samples :func:`drawn` picks of either edge."""
    k = np.unique(np.r_[drawn(lo), drawn(hi)])
    return ax.fill_between(np.asarray(t)[k], np.asarray(lo)[k], np.asarray(hi)[k], **kw)


def _fixed_layout(fig, top_in: float, footer_in: float) -> None:
    """The figure's column of axes between fixed margins (:data:`MARGIN_IN`), ``top_in`` free
    above it and ``footer_in`` below (``tight_layout`` measured every label)."""
    w, h = fig.get_size_inches()
    m = MARGIN_IN
    rows = len(fig.axes)
    top, bottom = 1 - (top_in + m["numbers"]) / h, (footer_in + m["bottom"]) / h
    cell = ((top - bottom) * h - (rows - 1) * m["row"]) / rows
    fig.subplots_adjust(left=m["left"] / w, right=1 - m["right"] / w, top=top, bottom=bottom,
                        hspace=m["row"] / cell)


def _segments(truth: Truth, ax, label: bool = True) -> None:
    """Shade alternate segments and number them along the top of ``ax`` (the numbers of
    :func:`segment_names`)."""
    for j, (_, name, a, b) in enumerate(truth.segment_spans()):
        if j % 2:
            ax.axvspan(a, b, color="0.92", zorder=0)
        if label:
            ax.text(0.5 * (a + b), 1.01, str(j + 1), transform=ax.get_xaxis_transform(), fontsize=7,
                    ha="center", va="bottom", clip_on=False)


def segment_names(truth: Truth) -> list[str]:
    """``"3 turn"``: each segment numbered in flight order (a track repeats its names)."""
    return [f"{j + 1} {name}" for j, (_, name, _, _) in enumerate(truth.segment_spans())]


def label_points(east: np.ndarray, north: np.ndarray, t_s: np.ndarray, spans) -> list[tuple[float, float]]:
    """Where each segment's number goes on the ground track: the point of its middle 80 % farthest
    from the numbers placed before it and from the start (segments that start where another
    ends, or a circle flown over its own entry, keep their numbers apart)."""
    placed = [(float(east[0]), float(north[0]))]
    out = []
    for _, _, a, b in spans:
        k = np.flatnonzero((t_s >= a + 0.1 * (b - a)) & (t_s <= b - 0.1 * (b - a)))
        if not k.size:
            k = np.array([min(int(np.searchsorted(t_s, a)), len(east) - 1)])
        k = k[:: max(1, k.size // 60)]
        cand = np.column_stack([east[k], north[k]])
        gap = np.min(np.linalg.norm(cand[:, None, :] - np.asarray(placed)[None], axis=-1), axis=1)
        best = cand[int(np.argmax(gap))]
        out.append((float(best[0]), float(best[1])))
        placed.append(out[-1])
    return out


def _number_segments(ax, east, north, truth: Truth) -> None:
    """Each segment's number on its own stretch of the ground track (colour is not the only
    cue), boxed so the track under it stays readable."""
    for j, (x, y) in enumerate(label_points(east, north, truth.t_s, truth.segment_spans())):
        ax.text(x, y, str(j + 1), fontsize=7, ha="center", va="center", color="0.1",
                bbox={"boxstyle": "round,pad=0.15", "facecolor": "white", "alpha": 0.8, "lw": 0})


def plot_flight(truth: Truth, out_dir: str | Path, prefix: str = "flight") -> list[Path]:
    """Write ``<prefix>_3d.png``, ``<prefix>_ground.png`` and ``<prefix>_time.png``."""
    import matplotlib.pyplot as plt
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for name, fig in flight_figures(truth):
        files.append(write_atomic(out / f"{prefix}_{name}.png",
                                  lambda p: fig.savefig(p, dpi=120, bbox_inches="tight")))
        plt.close(fig)
    return files


def flight_figures(truth: Truth, figsize=None, footer_in: float = 0.0) -> list:
    """``(name, figure)`` of the 3-D track, the ground track and the time histories; ``figsize``
    (inches) gives every figure one size (a report's page), ``footer_in`` a strip kept free at
    the foot."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    north, east = local_ne(truth.lat_rad, truth.lon_rad, truth.lat_rad[0], truth.lon_rad[0])
    h = truth.h_m
    spans = truth.segment_spans()
    colors = plt.cm.tab20(np.linspace(0, 1, max(len(spans), 2)))
    figs = []

    names = segment_names(truth)
    every = np.unique(np.r_[np.arange(0, len(h), -(-len(h) // PLOT_POINTS)), len(h) - 1])   # a track is smooth
    t_k, east_k, north_k, h_k = truth.t_s[every], east[every], north[every], h[every]
    fig = plt.figure(figsize=figsize or (8, 6.5))
    ax = fig.add_subplot(projection="3d")
    for j, (_, _, a, b) in enumerate(spans):
        m = (t_k >= a) & (t_k <= b)
        ax.plot(east_k[m], north_k[m], h_k[m], color=colors[j], lw=1.5, label=names[j])
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(5))
    # same scale on both horizontal axes, so turns look like turns
    half = 0.5 * max(np.ptp(east), np.ptp(north), 1.0)
    ce, cn = 0.5 * (east.max() + east.min()), 0.5 * (north.max() + north.min())
    ax.set_xlim(ce - half, ce + half)
    ax.set_ylim(cn - half, cn + half)
    ax.set_xlabel("east, m")
    ax.set_ylabel("north, m")
    ax.set_zlabel("height, m")
    ax.set_title(f"{truth.meta.get('track', '')}: 3-D track")
    ax.legend(fontsize=6, loc="upper left", ncol=2)
    figs.append(("3d", fig))

    fig, ax = plt.subplots(figsize=figsize or (7.5, 7))
    for j, (_, _, a, b) in enumerate(spans):
        m = (t_k >= a) & (t_k <= b)
        ax.plot(east_k[m], north_k[m], color=colors[j], lw=1.5, label=names[j])
    _number_segments(ax, east, north, truth)
    ax.plot(east[0], north[0], "k^", ms=8, label="start")
    ax.plot(east[-1], north[-1], "ks", ms=7, label="end")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east, m")
    ax.set_ylabel("north, m")
    ax.grid(alpha=0.3)
    ax.set_title(f"{truth.meta.get('track', '')}: ground track "
                 f"(origin {np.degrees(truth.lat_rad[0]):.4f}°N, {np.degrees(truth.lon_rad[0]):.4f}°E)")
    ax.legend(fontsize=7, loc="best", ncol=2)
    _fixed_layout(fig, 0.3, footer_in)
    figs.append(("ground", fig))

    figs.append(("time", _time_figure(truth, names, figsize, footer_in)))
    return figs


def _wind_axis(ax, truth: Truth) -> None:
    """The air mass's velocity north and east with its gusts (thin) and its steady part (the
    scenario's wind, dashed)."""
    t = truth.t_s
    for j, (name, colour) in enumerate((("north", "tab:blue"), ("east", "tab:orange"))):
        plot_drawn(ax, t, truth.wind_n_mps[:, j], color=colour, lw=0.4, alpha=0.6, label=f"wind {name} (with gusts)")
        plot_drawn(ax, t, truth.wind_steady_n_mps[:, j], color=colour, lw=1.3, ls="--", label=f"steady wind {name}")
    ax.set_ylabel("wind, m/s")
    ax.legend(fontsize=7, loc="best", ncol=2)


def _heading_axis(ax, truth: Truth) -> None:
    """The heading, continuous where it turns less than :data:`MAX_UNWRAPPED_DEG` in all; else
    (a vehicle circling for long) wrapped to [0, 360) deg and drawn as dots, evenly thinned."""
    t, yaw = truth.t_s, np.degrees(np.unwrap(truth.euler_rad[:, 2]))
    if np.ptp(yaw) <= MAX_UNWRAPPED_DEG:
        plot_drawn(ax, t, yaw, label="heading")
    else:
        k = np.arange(0, len(t), -(-len(t) // PLOT_POINTS))
        ax.plot(t[k], yaw[k] % 360.0, ".", ms=1.5, label="heading")
        ax.set_ylim(0.0, 360.0)
        ax.set_yticks([0, 90, 180, 270, 360])
    ax.set_ylabel("heading, deg")


def _rotor_axis(ax, truth: Truth) -> None:
    """A multirotor's rotor speeds: their mean and the band from the slowest to the fastest."""
    t, rpm = truth.t_s, truth.rotor_rpm
    lo, hi = rpm.min(axis=1), rpm.max(axis=1)
    fill_drawn(ax, t, lo, hi, color="tab:purple", alpha=0.3, lw=0, label=f"slowest to fastest of {rpm.shape[1]} rotors")
    plot_drawn(ax, t, rpm.mean(axis=1), color="tab:purple", lw=1.0, label="mean")
    ax.set_ylabel("rotor speed, r/min")
    ax.legend(fontsize=7, loc="best")


def _time_figure(truth: Truth, names: list[str], figsize, footer_in: float):
    """Height, speeds, bank and pitch, heading, a multirotor's rotor speeds and (in wind) the
    wind against time, the segments shaded and numbered."""
    import matplotlib.pyplot as plt
    windy = bool(np.nan_to_num(truth.wind_n_mps).any())      # a log's reference holds no wind (NaN)
    rotors = truth.rotor_rpm.shape[1] > 1
    fig, axs = plt.subplots(4 + windy + rotors, 1, figsize=figsize or (10, 10), sharex=True)
    t = truth.t_s
    plot_drawn(axs[0], t, truth.h_m, label="height (ellipsoid)")
    if not np.isnan(truth.h_agl_m).all():
        plot_drawn(axs[0], t, truth.h_agl_m, "--", lw=0.8, label="above surface")
    axs[0].set_ylabel("height, m")
    axs[0].legend(fontsize=7, loc="best")
    if not np.isnan(truth.tas_mps).all():
        plot_drawn(axs[1], t, truth.tas_mps, label="true airspeed")
    plot_drawn(axs[1], t, np.hypot(truth.vel_n_mps[:, 0], truth.vel_n_mps[:, 1]), lw=0.8, label="ground speed")
    axs[1].set_ylabel("speed, m/s")
    axs[1].legend(fontsize=7, loc="best")
    plot_drawn(axs[2], t, np.degrees(truth.euler_rad[:, 0]), label="roll (bank)")
    plot_drawn(axs[2], t, np.degrees(truth.euler_rad[:, 1]), label="pitch")
    axs[2].set_ylabel("angle, deg")
    axs[2].legend(fontsize=7, loc="best")
    _heading_axis(axs[3], truth)
    if rotors:
        _rotor_axis(axs[4], truth)
    if windy:
        _wind_axis(axs[-1], truth)
    axs[-1].set_xlabel("time, s")
    for j, ax in enumerate(axs):
        _segments(truth, ax, label=(j == 0))
        ax.grid(alpha=0.3)
    fig.suptitle(f"{truth.meta.get('track', '')}: flight against time", fontsize=11, y=1 - 0.1 / fig.get_figheight())
    listed = "segments (numbered on top): " + ", ".join(names[:16]) + (", ..." if len(names) > 16 else "")
    height_in = fig.get_figheight()
    wrap = int(130 * fig.get_figwidth() / 10)
    lines = textwrap.wrap(listed, wrap)
    fig.text(0.5, 1 - 0.35 / height_in, "\n".join(lines), ha="center", va="top", fontsize=7.5)
    _fixed_layout(fig, 0.45 + 0.14 * len(lines), footer_in)
    return fig
