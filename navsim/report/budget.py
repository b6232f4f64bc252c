"""An error budget (:mod:`navsim.scoring.budget`) for people: its tables (terminal and
``budget.csv``) and its pages, one per estimator: a sorted horizontal bar per source (or group)
of each metric's contribution, the all-on value and the root-sum-square beside it."""

from __future__ import annotations

import math

import numpy as np

from navsim.report.figures import Page, page_figure, titled
from navsim.report.tables import FAIL, PASS
from navsim.scoring.budget import DEFAULT_METRICS, Budget, MetricBudget
from navsim.scoring.verdicts import num

#: the columns of ``budget.csv``
CSV_HEADERS = ("estimator", "metric", "component", "all_on", "baseline", "rss", "ratio", "line", "alone",
               "contribution", "share")
#: the terminal table's columns
HEADERS = ("source", "alone", "contribution", "share")
#: the bars a page draws per metric (the rest summed as one)
BARS = 12


def budget_csv_rows(b: Budget) -> list[list]:
    v = lambda x: "" if x is None or (isinstance(x, float) and not math.isfinite(x)) else x
    return [[m.estimator, m.metric, m.component, v(m.all_on), v(m.baseline), v(m.rss), v(m.ratio), x.source,
             v(x.alone), v(x.contribution), v(x.share)] for m in b.metrics for x in m.lines]


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


def text_rows(m: MetricBudget) -> list[list[str]]:
    return [[x.source, num(x.alone), num(x.contribution), f"{100 * x.share:.1f} %"] for x in m.lines]


def _bars(ax, m: MetricBudget) -> None:
    lines = m.lines[:BARS]
    rest = m.lines[BARS:]
    labels = [x.source for x in lines] + ([f"{len(rest)} more"] if rest else [])
    values = [x.contribution for x in lines] + ([math.sqrt(sum(x.contribution ** 2 for x in rest))] if rest else [])
    shares = [x.share for x in lines] + ([sum(x.share for x in rest)] if rest else [])
    y = np.arange(len(values))
    ax.barh(y, values, color="#4c72b0")
    for yi, v, s in zip(y, values, shares):
        ax.text(v, yi, f" {num(v)} ({100 * s:.0f} %)", va="center", fontsize=6.5)
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


def budget_pages(b: Budget, metrics=None) -> list[Page]:
    """One page per estimator: the chosen metrics' bars."""
    out = []
    by_est: dict[str, list[MetricBudget]] = {}
    for m in chosen(b, metrics):
        by_est.setdefault(m.estimator, []).append(m)
    for j, (label, ms) in enumerate(by_est.items()):
        fig, axes = page_figure(len(ms), 1, squeeze=False)
        for ax, m in zip(axes[:, 0], ms):
            _bars(ax, m)
        axes[-1, 0].set_xlabel("contribution (the metric's unit): what the source adds to the mean square, "
                               "its root; share of the variance in brackets", fontsize=7)
        title = (f"Error budget of {label}: {b.scenario}, {b.runs} runs per source, seed {b.seed} "
                 f"(lines: {b.group})")
        out.append(titled(fig, "budget" if j == 0 else f"budget_{j + 1}", title))
    return out
