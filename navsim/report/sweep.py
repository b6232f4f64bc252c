"""The figure of a ``navsim sweep``, shaped by its grid (:func:`write_sweep_figure`).

- one swept parameter: the metric of each estimator against the parameter's values, a line
  each, with its 95 % interval over the runs as error bars;
- two: small multiples, one heat map per estimator (rows the first parameter, columns the
  second), each cell holding its number and its 95 % interval;
- more, or a list of points: the metric of each estimator at each point, the points numbered
  on the axis (``sweep.csv`` says which point is which).
"""

from __future__ import annotations

import numpy as np

from navsim.experiment.sweep import SweepResult
from navsim.foundations.outputs import OutputFolder
from navsim.report.figures import pyplot
from navsim.report.tables import wrap_text
from navsim.scoring.verdicts import num

#: the title's size, points, and the room it keeps from the figure's sides, inches
TITLE_PT = 10
TITLE_SIDES_IN = 0.3


def short_key(path: str) -> str:
    """A swept key path as a column or axis names it: its last two parts (``gyro.bias_sigma``)."""
    parts = [p for p in path.replace("[", ".").replace("]", "").split(".") if p and not p.isdigit()]
    return ".".join(parts[-2:])


def _values(sweep: SweepResult, label: str) -> list:
    return [np.nan if v.get(label) is None else float(v[label]) for _, v in sweep.rows]


def _errors(sweep: SweepResult, label: str) -> np.ndarray:
    """The error bars' lengths below and above each point's value, ``(2, points)`` (0: none)."""
    out = np.zeros((2, len(sweep.rows)))
    for n, v in enumerate(_values(sweep, label)):
        iv = sweep.interval(n, label)
        if iv is not None and np.all(np.isfinite(iv)) and np.isfinite(v):
            out[:, n] = [max(v - iv[0], 0.0), max(iv[1] - v, 0.0)]
    return out


def _log_if_positive(ax, values) -> None:
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size and np.all(v > 0) and v.max() > 10 * v.min():
        ax.set_yscale("log")


def _lines(fig, sweep: SweepResult, labels: list, key: str | None) -> None:
    """One axis: the metric per estimator over the parameter's values (or the points)."""
    ax = fig.add_subplot()
    ticks = [str(p.get(key, "-")) for p, _ in sweep.rows] if key else [str(i + 1) for i in range(len(sweep.rows))]
    for lb in labels:
        ax.errorbar(range(len(sweep.rows)), _values(sweep, lb), yerr=_errors(sweep, lb), fmt="o-", capsize=3,
                    label=lb)
    ax.set_xticks(range(len(sweep.rows)), ticks, rotation=30 if max(map(len, ticks)) > 8 else 0,
                  ha="right" if max(map(len, ticks)) > 8 else "center", fontsize=8)
    ax.set_xlabel(short_key(key) if key else "point (see sweep.csv)")
    ax.set_ylabel(sweep.metric)
    _log_if_positive(ax, [x for lb in labels for x in _values(sweep, lb)])
    for n in sweep.failed_points:             # a point not flown, or none of whose runs succeeded
        ax.text(n, 0.03, "not flown" if n in sweep.unflown else "no run",
                transform=ax.get_xaxis_transform(), ha="center", fontsize=8, color="tab:red")
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:        # no point with a value: no line to name
        ax.legend(fontsize=8)


def _heatmaps(fig, sweep: SweepResult, labels: list, rows_key: str, cols_key: str, axes: dict) -> None:
    """A heat map per estimator over a two-parameter grid, each cell annotated."""
    R, C = axes[rows_key], axes[cols_key]
    grid_axes = fig.subplots(1, len(labels), squeeze=False)[0]
    for ax, lb in zip(grid_axes, labels):
        M = np.full((len(R), len(C)), np.nan)
        text = {}
        for n, ((p, _), v) in enumerate(zip(sweep.rows, _values(sweep, lb))):
            i, j = R.index(p[rows_key]), C.index(p[cols_key])
            M[i, j] = v
            iv = sweep.interval(n, lb)
            ends = f"[{num(iv[0])}, {num(iv[1])}]" if iv is not None else ""
            text[i, j] = num(v) + ("\n" + (ends.replace(", ", ",\n") if len(ends) > 16 else ends) if ends else "")
        im = ax.imshow(M, cmap="viridis", aspect="auto")
        for i in range(len(R)):
            for j in range(len(C)):
                dark = np.isfinite(M[i, j]) and M[i, j] < np.nanmean(M)
                ax.text(j, i, text.get((i, j), "-"), ha="center", va="center", fontsize=7, color="w" if dark else "k")
        ax.set_xticks(range(len(C)), [str(c) for c in C], fontsize=7, rotation=20, ha="right")
        ax.set_yticks(range(len(R)), [str(r) for r in R], fontsize=7)
        ax.set_xlabel(short_key(cols_key), fontsize=8)
        ax.set_ylabel(short_key(rows_key), fontsize=8)
        ax.set_title(lb, fontsize=9)
        fig.colorbar(im, ax=ax, shrink=0.8)


def write_sweep_figure(folder: OutputFolder, sweep: SweepResult, title: str) -> None:
    """``sweep.png`` in ``folder``: the metric of every estimator over the grid (see the module
    docstring for the shape)."""
    plt = pyplot()
    labels = list(sweep.rows[0][1]) if sweep.rows else []
    axes = sweep.axes()
    combos = {tuple(repr(p.get(k)) for k in axes) for p, _ in sweep.rows}
    grid = (len(axes) == 2 and all(set(p) == set(axes) for p, _ in sweep.rows)
            and len(combos) == len(sweep.rows) == np.prod([len(v) for v in axes.values()]))
    width = max(6.5, 4.0 * len(labels)) if grid else max(6.5, 0.9 * len(sweep.rows) + 3)
    fig = plt.figure(figsize=(min(width, 16), 4.8), layout="constrained")
    if not sweep.rows:                        # interrupted before its first point finished
        fig.text(0.5, 0.5, "no point finished", ha="center", va="center")
    elif grid:
        _heatmaps(fig, sweep, labels, *axes, axes)
    else:
        _lines(fig, sweep, labels, next(iter(axes)) if len(axes) == 1 else None)
    lines = wrap_text(title, fig.get_figwidth() - 2 * TITLE_SIDES_IN, TITLE_PT)
    fig.suptitle("\n".join(lines), fontsize=TITLE_PT)
    folder.write("sweep.png", lambda p: fig.savefig(p, dpi=110))
    plt.close(fig)
