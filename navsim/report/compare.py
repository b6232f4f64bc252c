"""A comparison (:mod:`navsim.scoring.compare`) for people: its table (terminal and
``compare.csv``), and one page per estimator pair with the per-run differences drawn.

The page: one line per metric component, the runs' differences as dots (paired: each run's
``B - A`` of its own value; unpaired: each side's runs about A's value), ``B - A`` over the runs
with its 95 % interval as a bar, coloured by the verdict; all in per cent of A's value, so that
metrics of different units share one axis.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.report.figures import TITLE_LINE_IN, Page, page_figure, titled
from navsim.report.tables import FAIL, PASS, wrap_text
from navsim.scoring.compare import (BETTER, HIGHER, LOWER, NEGLIGIBLE, SAME, WORSE, Comparison, Difference, columns,
                                    margin_pct, paired_rows)
from navsim.scoring.intervals import CONFIDENCE
from navsim.scoring.verdicts import num

#: the table's columns (terminal, CSV: the same order)
HEADERS = ("metric", "A", "B", "B - A [95 %]", "B - A, %", "verdict")
CSV_HEADERS = ("estimator_a", "estimator_b", "paired", "runs", "metric", "component", "a", "b", "diff",
               "ci95_lo", "ci95_hi", "relative", "p_value", "verdict", "runs_needed", "margin")
#: the headline over the panels: its size (points), and its place (inches): from the page's top
#: and sides, and the room it keeps above the panels
HEAD_PT = 6.5
HEAD_IN = {"top": 0.55, "left": 0.5, "right": 0.3, "below": 0.35}
COLOURS = {BETTER: PASS, WORSE: FAIL, SAME: "#555555", HIGHER: "#1f5fa8", LOWER: "#1f5fa8", NEGLIGIBLE: "#8a8a8a"}


def _signed(v: float) -> str:
    return "-" if not math.isfinite(v) else ("+" if v > 0 else "") + num(v)


def verdict_text(d: Difference, runs: int) -> str:
    """The verdict as printed: ``no significant difference at 50 runs (~210 would resolve it)``."""
    if d.verdict == NEGLIGIBLE:
        return f"{NEGLIGIBLE}: within +-{num(d.margin)}"
    if d.verdict != SAME:
        return f"B {d.verdict}"
    if d.runs_needed:
        more = f"~{d.runs_needed} runs would resolve {_signed(d.diff)}"
    elif math.isfinite(d.margin) and abs(d.diff) <= d.margin:
        more = f"{_signed(d.diff)} is within the margin +-{num(d.margin)}"
    else:
        more = ""
    if math.isfinite(d.p_value) and d.p_value < 1 - CONFIDENCE:     # its own interval excludes 0
        return f"not significant over the components (Holm; its own p {d.p_value:.2g}" + (f"; {more})" if more else ")")
    return f"{SAME} at {runs} runs" + (f" ({more})" if more else "")


def text_rows(c: Comparison) -> list[list[str]]:
    """The table's rows, one per metric component."""
    rows = []
    for d in c.differences:
        rel = "-" if not math.isfinite(d.relative) else f"{100 * d.relative:+.2f}"
        rows.append([d.name, num(d.a), num(d.b), f"{_signed(d.diff)} [{_signed(d.ci95[0])}, {_signed(d.ci95[1])}]",
                     rel, verdict_text(d, c.runs_compared)])
    return rows


def csv_rows(c: Comparison) -> list[list]:
    """The rows of ``compare.csv`` (numbers unformatted; empty for none)."""
    v = lambda x: "" if x is None or (isinstance(x, float) and not math.isfinite(x)) else x
    return [[c.a.estimator, c.b.estimator, c.paired, c.runs_compared, d.metric, d.component, v(d.a), v(d.b),
             v(d.diff), v(d.ci95[0]), v(d.ci95[1]), v(d.relative), v(d.p_value), d.verdict, v(d.runs_needed),
             v(d.margin)]
            for d in c.differences]


def headline(c: Comparison) -> str:
    """Who is compared with whom, how, and the count of each verdict."""
    side = lambda s, k: f"{k}: {s.estimator} in {s.result} ({s.runs} runs{', interrupted' if s.interrupted else ''})"
    counts = ", ".join(f"{n} {v}" for v, n in c.summary().items())
    left = [f"{len(runs)} counted only in {k} ({', '.join(map(str, runs[:5]))}{', ...' if len(runs) > 5 else ''})"
            for k, runs in (("A", c.only_a), ("B", c.only_b)) if runs]
    left = f" (left out: {'; '.join(left)}: diverged on the other side)" if left else ""
    return (f"{side(c.a, 'A')}\n{side(c.b, 'B')}\n{c.pairing}; {c.runs_compared} runs compared{left}; {counts}; "
            f"the verdicts over the {len(c.differences)} components together (Holm, 5 %); {_margin_text(c)}")


def _margin_text(c: Comparison) -> str:
    """The practical-equivalence margin in words."""
    if not isinstance(c.margin_pct, dict):
        return f"negligible: the interval within +-{c.margin_pct:g} % of the larger value"
    parts = [f"{k} {v:g} %" for k, v in c.margin_pct.items() if k] + [f"the others {margin_pct(c.margin_pct, ''):g} %"]
    return "negligible: the interval within the margin, per cent of the larger value (" + ", ".join(parts) + ")"


def _dots(c: Comparison) -> dict:
    """Per difference name, the runs' values drawn (paired: each run's B - A; unpaired: each
    side's own)."""
    sa, sb = c.samples_a, c.samples_b
    if sa is None or sb is None:
        return {}
    ia, ib = paired_rows(sa, sb) if c.paired else (slice(None), slice(None))
    out = {}
    for path in [p for p in sa.metrics if p in sb.metrics]:
        ma, mb = sa.metrics[path], sb.metrics[path]
        for (comp, ca), (_, cb) in zip(columns(path, ma), columns(path, mb)):
            va, vb = ca.per_run()[ia, 0], cb.per_run()[ib, 0]
            out[f"{path} {comp}".strip()] = (vb - va,) if c.paired else (va, vb)
    return out


def _short(d: Difference) -> str:
    """The verdict beside a line of the page."""
    if d.verdict == NEGLIGIBLE:
        return NEGLIGIBLE
    if d.verdict != SAME:
        return f"B {d.verdict}"
    p = f", p {d.p_value:.2g}" if math.isfinite(d.p_value) and d.p_value < 1 - CONFIDENCE else ""
    return f"n.s. (~{d.runs_needed} runs{p})" if d.runs_needed else "n.s."


def _panel(ax, c: Comparison, diffs: list[Difference], dots: dict) -> None:
    """One panel of lines (see the module docstring)."""
    rng = np.random.default_rng(0)                 # the dots' vertical jitter only
    ends = []
    for y, d in enumerate(diffs):
        a = d.a if d.a else math.nan
        colour = COLOURS.get(d.verdict, "#555555")
        for k, vals in enumerate(dots.get(d.name, ())):
            rel = 100 * (vals if c.paired else vals - a) / a
            rel = rel[np.isfinite(rel)]
            off = 0.0 if c.paired else (-0.18 if k == 0 else 0.18)
            ax.scatter(rel, y + off + rng.uniform(-0.12, 0.12, rel.size), s=3,
                       color="#9e9e9e" if (c.paired or k == 0) else "#6a9fd4", alpha=0.6, lw=0, zorder=1)
            ends += np.percentile(rel, [5, 95]).tolist() if rel.size else []
        lo, hi = (100 * v / a for v in d.ci95)
        if math.isfinite(lo) and math.isfinite(hi):
            ax.plot([lo, hi], [y, y], color=colour, lw=2.2, zorder=3, solid_capstyle="butt")
            ends += [lo, hi]
        ax.plot([100 * d.diff / a], [y], "o", color=colour, ms=3.5, zorder=4)
        ax.text(1.02, y, _short(d), transform=ax.get_yaxis_transform(), fontsize=6, va="center", color=colour)
    ax.axvline(0, color="black", lw=0.7, zorder=2)
    ax.set_yticks(range(len(diffs)), [d.name for d in diffs], fontsize=6.5)
    ax.set_ylim(len(diffs) - 0.5, -0.5)
    span = max([abs(e) for e in ends if math.isfinite(e)] + [1e-3]) * 1.15
    ax.set_xlim(-span, span)
    ax.tick_params(axis="x", labelsize=7)
    ax.grid(axis="x", lw=0.3, alpha=0.5)


def compare_page(c: Comparison, name: str = "compare") -> Page:
    """The page of one comparison (see the module docstring): the errors above, the
    consistency statistics (NEES) below, each panel on its own scale."""
    groups = [g for g in ([d for d in c.differences if not d.metric.startswith("nees.")],
                          [d for d in c.differences if d.metric.startswith("nees.")]) if g]
    fig, axes = page_figure(len(groups), 1, squeeze=False,
                            gridspec_kw={"height_ratios": [len(g) + 2 for g in groups]})
    dots = _dots(c)
    for ax, diffs in zip(axes[:, 0], groups):
        _panel(ax, c, diffs, dots)
    axes[-1, 0].set_xlabel("B - A, % of A " + ("(grey: each run's own B - A)" if c.paired else
                                               "(grey: A's runs, blue: B's runs, about A's value)"), fontsize=7.5)
    page = titled(fig, name, f"Compare: {c.b.estimator} (B) against {c.a.estimator} (A)")
    w, h = fig.get_size_inches()
    top = HEAD_IN["top"] + TITLE_LINE_IN * fig.get_suptitle().count("\n")      # under a title of more lines
    lines = wrap_text(headline(c).replace("; ", ";\n", 1), w - HEAD_IN["left"] - HEAD_IN["right"], HEAD_PT)
    fig.text(HEAD_IN["left"] / w, 1 - top / h, "\n".join(lines), fontsize=HEAD_PT, va="top")
    below = top + len(lines) * HEAD_PT * 1.2 / 72 + HEAD_IN["below"]
    fig.subplots_adjust(right=0.74, top=1 - below / h)
    return page
