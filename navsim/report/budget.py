"""An error budget (:mod:`navsim.scoring.budget`) for people: its tables (terminal and
``budget.csv``) and its pages, one per estimator: a sorted horizontal bar per source (or group)
of each metric's contribution, the all-on value and the root-sum-square beside it."""

from __future__ import annotations

import logging
import math
import textwrap

import numpy as np

from navsim.report.figures import Page, page_figure, titled
from navsim.report.tables import FAIL, PASS
from navsim.scoring.budget import DEFAULT_METRICS, Budget, MetricBudget
from navsim.scoring.intervals import MIN_RUNS
from navsim.scoring.verdicts import num

log = logging.getLogger(__name__)

#: the columns of ``budget.csv``
CSV_HEADERS = ("estimator", "metric", "component", "all_on", "baseline", "rss", "ratio", "line", "alone",
               "contribution", "share", "covariance", "contribution_lo", "contribution_hi", "share_lo", "share_hi")
#: the terminal table's columns (with the 95 % intervals where runs were flown, ``covariance``
#: where a covariance analysis ran beside)
HEADERS = ("source", "alone", "contribution", "share")
#: the interval columns, after the contribution's and the share's
CI_HEADERS = ("contribution 95 %", "share 95 %")
#: what a covariance budget's table says in a left-out source's figures
LEFT_OUT = "left out"
#: the bars a page draws per metric (the rest summed as one)
BARS = 12
#: the sources a page of errors against time draws (by their share of the final horizontal
#: position error), the rest summed as one line
CURVES = 5
#: the errors against time: (label, unit, columns of the variances, factor of the unit)
_CURVE_PANELS = (("horizontal position", "m", (6, 7), 1.0), ("horizontal velocity", "m/s", (3, 4), 1.0),
                 ("attitude about D (heading)", "deg", (2,), (180.0 / math.pi) ** 2))


def budget_csv_rows(b: Budget) -> list[list]:
    v = lambda x: "" if x is None or (isinstance(x, float) and not math.isfinite(x)) else x
    return [[m.estimator, m.metric, m.component, v(m.all_on), v(m.baseline), v(m.rss), v(m.ratio), x.source,
             v(x.alone), v(x.contribution), v(x.share), v(x.covariance), *map(v, x.contribution_ci95),
             *map(v, x.share_ci95)] for m in b.metrics for x in m.lines]


def headers(b: Budget) -> tuple[str, ...]:
    """The terminal table's columns for ``b``: each figure's 95 % interval where runs were
    flown; the covariance figure beside the Monte Carlo's where both ran."""
    heads = HEADERS if b.method == "covariance" else (HEADERS[0], HEADERS[1], HEADERS[2], CI_HEADERS[0], HEADERS[3],
                                                       CI_HEADERS[1])
    return heads + (("covariance", "cov / MC") if b.method == "both" else ())


def covariance_notes(b: Budget) -> list[str]:
    """What a covariance analysis left out: the sources it leaves to Monte Carlo, the
    estimators it does not take."""
    out = []
    if b.method != "montecarlo" and b.monte_carlo_only:
        out.append("no linear form (Monte Carlo only): " + ", ".join(b.monte_carlo_only))
        why: dict[str, list[str]] = {}
        for name in b.monte_carlo_only:
            why.setdefault(b.left_out.get(name, "no linear form"), []).append(name)
        out += [f"  {', '.join(names)}: {reason}" for reason, names in why.items()]
    out += [f"not analysed: {label}: {why}" for label, why in b.not_analysed.items()]
    return out


def left_out_rows(b: Budget, m: MetricBudget, heads=HEADERS) -> list[list[str]]:
    """A covariance budget's table rows of the sources it leaves to Monte Carlo, one each
    (their figures :data:`LEFT_OUT`, the reason in :func:`covariance_notes`); none beside a
    Monte Carlo budget (its lines have every source) or where ``m``'s lines name the source."""
    if b.method != "covariance":
        return []
    named = {x.source for x in m.lines}
    return [[name, "-", LEFT_OUT, "no linear form (below)"] + ["-"] * (len(heads) - 4)
            for name in b.monte_carlo_only if name not in named]


def rank_notes(m: MetricBudget, runs: int) -> list[str]:
    """The table's notes on its order: each set of lines the ``runs`` runs are too few to rank
    (their contributions' 95 % intervals overlap, :meth:`~MetricBudget.unranked`); with fewer
    than 2 runs, that there are no intervals. None for a budget without runs (a covariance
    analysis: exact for its linear model)."""
    if runs <= 0:
        return []
    tied = m.unranked()
    if runs < MIN_RUNS:
        return [f"{runs} run: no intervals, so no order of the lines is shown to hold: "
                + ", ".join(tied[0])] if tied else []
    return [f"too few runs to rank ({runs} runs): {', '.join(s)}: their contributions' 95 % intervals overlap, "
            "so the table's order among them is not a ranking" for s in tied]


def warn_unranked(b: Budget, shown: list[MetricBudget]) -> None:
    """One warning in the log where the runs are too few to rank the lines of a metric shown."""
    runs = b.runs if b.method != "covariance" else 0
    bad = [m for m in shown if rank_notes(m, runs)]
    if bad:
        log.warning("budget of %s: %d run(s) are too few to rank the sources of %d of the %d metrics shown "
                    "(%s): their 95 %% intervals overlap; more runs (--runs) separate them",
                    b.scenario, runs, len(bad), len(shown), ", ".join(f"{m.estimator} {m.name}" for m in bad[:3])
                    + (" ..." if len(bad) > 3 else ""))


def chosen(b: Budget, metrics=None) -> list[MetricBudget]:
    """The budgets of ``metrics`` ((path, component) pairs; default
    :data:`~navsim.scoring.budget.DEFAULT_METRICS`) that were scored, estimator by estimator."""
    want = list(metrics or DEFAULT_METRICS)
    return [m for m in b.metrics if (m.metric, m.component) in want]


def check_text(m: MetricBudget) -> str:
    """The linearity check's line."""
    verdict = ("the sources add up" if m.additive else
               "NOT additive: the contributions do not sum to the all-on value beyond the runs' noise")
    lo, hi = m.ratio_ci95
    ci = f" [{lo:.3f}, {hi:.3f}]" if math.isfinite(lo) and math.isfinite(hi) else ""
    return (f"all on {num(m.all_on)}, root-sum-square of the contributions {num(m.rss)} (ratio {m.ratio:.3f}{ci}: "
            f"{verdict}); with no source {num(m.baseline)}")


def text_rows(m: MetricBudget, heads=HEADERS) -> list[list[str]]:
    """The terminal table's rows of ``m`` under the columns ``heads`` (:func:`headers`)."""
    rows = []
    for x in m.lines:
        row = [x.source, num(x.alone), num(x.contribution), f"{100 * x.share:.1f} %"]
        if CI_HEADERS[0] in heads:
            row[3:3] = [_ci(x.contribution_ci95, num)]
            row.append(_ci(x.share_ci95, lambda v: f"{100 * v:.1f}") + (" %" if math.isfinite(x.share_ci95[0]) else ""))
        if "covariance" in heads:
            ratio = x.covariance / x.contribution if x.contribution > 0 and math.isfinite(x.covariance) else math.nan
            row += [num(x.covariance), f"{ratio:.2f}" if math.isfinite(ratio) else "-"]
        rows.append(row)
    return rows


def _ci(ci, fmt) -> str:
    """``[lo, hi]`` of an interval, ``-`` where it has none."""
    lo, hi = ci
    return f"[{fmt(lo)}, {fmt(hi)}]" if math.isfinite(lo) and math.isfinite(hi) else "-"


def _bars(ax, m: MetricBudget) -> None:
    lines = m.lines[:BARS]
    rest = m.lines[BARS:]
    labels = [x.source for x in lines] + ([f"{len(rest)} more"] if rest else [])
    values = [x.contribution for x in lines] + ([math.sqrt(sum(x.contribution ** 2 for x in rest))] if rest else [])
    shares = [x.share for x in lines] + ([sum(x.share for x in rest)] if rest else [])
    y = np.arange(len(values))
    ax.barh(y, values, color="#4c72b0")
    cov = [x.covariance for x in lines] + ([math.nan] if rest else [])
    ends = _error_bars(ax, y, lines, values, m)
    if any(math.isfinite(x.covariance) and x.covariance != x.contribution for x in lines):     # beside a Monte Carlo
        ax.plot(cov, y, "D", color="#dd8452", ms=4, label="covariance analysis")
        ends = [max(e, c) if math.isfinite(c) else e for e, c in zip(ends, cov)]
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=6.5, loc="lower right")
    for yi, v, end, s in zip(y, values, ends, shares):
        ax.text(end, yi, f"  {num(v)} ({100 * s:.0f} %)", va="center", fontsize=6.5)
    values = ends
    ax.set_yticks(y, labels, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlim(0, max(values + [1e-12]) * 1.35)
    ax.tick_params(axis="x", labelsize=7)
    colour = PASS if m.additive else FAIL
    lo, hi = m.ratio_ci95
    ci = f" [{lo:.2f}, {hi:.2f}]" if math.isfinite(lo) and math.isfinite(hi) else ""
    ax.set_title(f"{m.name}: all on {num(m.all_on)}, RSS {num(m.rss)} (ratio {m.ratio:.2f}{ci}"
                 f"{'' if m.additive else ': NOT additive'}), none {num(m.baseline)}", fontsize=8, color=colour,
                 loc="left")
    ax.grid(axis="x", lw=0.3, alpha=0.5)


def _error_bars(ax, y, lines, values, m: MetricBudget) -> list[float]:
    """The lines' 95 % intervals over the runs as error bars (drawn to at most twice the
    largest bar: a few runs' intervals reach far), the lines the runs do not rank
    (:meth:`~navsim.scoring.budget.MetricBudget.unranked`) hatched; returns where each bar's
    figure goes (past its bar and error bar)."""
    ends = list(values)
    have = [i for i, x in enumerate(lines) if all(math.isfinite(v) for v in x.contribution_ci95)]
    if not have:
        return ends
    cap = 2 * max(values)
    for i in have:
        ends[i] = max(values[i], min(lines[i].contribution_ci95[1], cap))
    lo = [values[i] - min(lines[i].contribution_ci95[0], values[i]) for i in have]
    ax.errorbar([values[i] for i in have], y[have], xerr=[lo, [ends[i] - values[i] for i in have]], fmt="none",
                ecolor="k", elinewidth=0.7, capsize=2, label="95 % interval over the runs")
    tied = [i for i, x in enumerate(lines) if any(x.source in s for s in m.unranked())]
    if tied:
        ax.barh(y[tied], [values[i] for i in tied], color="#4c72b0", hatch="////", edgecolor="white", lw=0,
                label="not ranked: intervals overlap")
    return ends


def _left_out_label(b: Budget) -> str:
    """A covariance budget page's line naming the sources it leaves out (none: empty)."""
    if b.method != "covariance" or not b.monte_carlo_only:
        return ""
    return "\n" + "\n".join(textwrap.wrap(f"left out, no linear form (Monte Carlo only; why: budget.json's left_out): "
                                          + ", ".join(b.monte_carlo_only), 150))


def curve_pages(b: Budget) -> list[Page]:
    """Per estimator: the top :data:`CURVES` sources' errors against time (1-sigma, log scale),
    the rest summed, and all of them; by Monte Carlo where it ran (the covariance analysis's
    dashed beside, ``both``), else by covariance analysis."""
    out = []
    primary = b.curves or b.covariance_curves
    for j, (label, c) in enumerate(primary.items()):
        beside = b.covariance_curves.get(label) if b.curves else None
        final = c.var[:, -1, 6] + c.var[:, -1, 7]
        order = np.argsort(-final)
        fig, axes = page_figure(len(_CURVE_PANELS), 1, squeeze=False, sharex=True)
        for ax, panel in zip(axes[:, 0], _CURVE_PANELS):
            _curve_panel(ax, c, beside, order, final, panel)
        axes[0, 0].legend(fontsize=6.5, loc="best", title="source (share of the final horizontal position "
                          "variance)" + ("; dashed: covariance analysis" if beside is not None else ""),
                          title_fontsize=6.5)
        axes[-1, 0].set_xlabel("time (s)", fontsize=8)
        how = (f"by Monte Carlo ({b.runs} runs: what each adds to the mean square, its root)" if b.curves
               else "by covariance analysis")
        title = f"Each source's error against time: {label} ({b.scenario}), {how}"
        out.append(titled(fig, "budget_time" if j == 0 else f"budget_time_{j + 1}", title))
    return out


def _curve_panel(ax, c, beside, order, final, panel) -> None:
    """One quantity's curves: the top sources, the rest, all (``beside``: dashed, same colours)."""
    name, unit, cols, factor = panel
    top, rest = order[:CURVES], order[CURVES:]
    var = c.var[:, :, list(cols)].sum(axis=2) * factor
    other = beside.var[:, :, list(cols)].sum(axis=2) * factor if beside is not None else None
    share = lambda idx: 100 * final[idx].sum() / final.sum() if final.sum() > 0 else math.nan
    for k in top:
        line, = ax.plot(c.t_s, np.sqrt(var[k]), lw=1.0, label=f"{c.sources[k]} ({share([k]):.0f} %)")
        if other is not None and c.sources[k] in beside.sources:
            ax.plot(beside.t_s, np.sqrt(other[beside.sources.index(c.sources[k])]), lw=0.8, ls="--",
                    color=line.get_color())
    if len(rest):
        ax.plot(c.t_s, np.sqrt(var[rest].sum(axis=0)), lw=0.8, color="0.55", ls=":",
                label=f"the other {len(rest)} ({share(rest):.0f} %)")
    total = np.sqrt(var.sum(axis=0))
    ax.plot(c.t_s, total, lw=1.4, color="k", label="all sources")
    ax.set_yscale("log")
    ax.set_ylim(bottom=1e-3 * max(float(np.nanmax(total)), 1e-300))      # three decades under the top
    ax.set_ylabel(f"{name}, 1-sigma ({unit})", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(lw=0.3, alpha=0.5, which="both")


def budget_pages(b: Budget, metrics=None) -> list[Page]:
    """One page per estimator: the chosen metrics' bars; then, where a covariance analysis ran,
    each estimator's top sources against time (:func:`curve_pages`)."""
    out = []
    by_est: dict[str, list[MetricBudget]] = {}
    for m in chosen(b, metrics):
        by_est.setdefault(m.estimator, []).append(m)
    for j, (label, ms) in enumerate(by_est.items()):
        fig, axes = page_figure(len(ms), 1, squeeze=False)
        for ax, m in zip(axes[:, 0], ms):
            _bars(ax, m)
        axes[-1, 0].set_xlabel("contribution (the metric's unit): what the source adds to the mean square, "
                               "its root;\nshare of the variance in brackets"
                               + ("; error bars: 95 % intervals over the runs" if b.method != "covariance" else "")
                               + _left_out_label(b), fontsize=7)
        how = {"montecarlo": f"{b.runs} runs per source, seed {b.seed}", "covariance": "covariance analysis",
               "both": f"{b.runs} runs per source, seed {b.seed}; covariance analysis beside"}[b.method]
        title = f"Error budget of {label}: {b.scenario}, {how} (lines: {b.group})"
        out.append(titled(fig, "budget" if j == 0 else f"budget_{j + 1}", title))
    return out + curve_pages(b)
