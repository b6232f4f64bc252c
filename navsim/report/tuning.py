"""The pages of ``navsim tune``'s report (``tune.pdf`` and its PNGs): the summary (the best
values against the original, the checks' verdicts), the objective against the trial, each
parameter against the objective, and the tuned minus the original with its 95 % interval on the
tuning seed and on the held-out seed side by side (over-fitting shows as a gap)."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.ticker import FormatStrFormatter, MaxNLocator, NullFormatter

from navsim.records.metrics import Verdict
from navsim.records.tuning import TuneRecord
from navsim.report.figures import Page, fit, page_figure
from navsim.report.render import render
from navsim.report.tables import Heading, Paragraph, Table, layout
from navsim.scoring.verdicts import VERDICT_HEADERS, num, verdict_rows, verdict_summary

#: how the checks are named on the pages
CHECK_NAMES = {"tuning": "tuning seed", "held_out": "held-out seed", "log": "log"}


def value_text(v) -> str:
    """A parameter's value as set: a number, a list of numbers, a datasheet value with its unit."""
    if isinstance(v, str):
        return v
    return num(v) if not isinstance(v, list) else "[" + ", ".join(num(x) for x in v) + "]"


def summary_pages(r: TuneRecord, params: list) -> list[Page]:
    """The tuning in words and tables: the best trial's values, the checks."""
    best = r.best_trial
    rows = [[p.what, f"{num(p.lo)} - {num(p.hi)}{' ' + p.unit if p.unit else ''}{' (log)' if p.log else ''}",
             value_text(p.base) if p.base is not None else "-", num(best.values[p.name]),
             value_text(p.value(best.values[p.name]))] for p in params]
    blocks = [Paragraph(f"Estimator '{r.estimator}' of {r.scenario}; objective {r.objective}"
                        + (f" ({r.metric})" if r.objective in ("rms", "rms+consistent") else "")
                        + f"; {len(r.trials)} trials of {r.runs} runs each on seed {r.seed} (every trial the same runs); "
                        f"{r.sampler}; best trial {r.best}, objective {num(best.objective)}; {r.wall_s:.0f} s."),
              Heading("Parameters"),
              Table(["parameter", "range", "original", "best trial", "value set"], rows, max_column=0.5),
              Heading("Fitted truth against the original: the paper checks" if r.tuned_sensors is not None
                      else "Tuned against original, paired")]
    for name, c in r.checks.items():
        rows = [[d["metric"] + (f" {d['component']}" if d["component"] else ""), num(d["a"]), num(d["b"]),
                 f"{num(d['diff'])} [{num(d['ci95'][0])}, {num(d['ci95'][1])}]", d["verdict"]] for d in c.differences]
        where = "On the log" if name == "log" else f"On the {CHECK_NAMES.get(name, name)} ({c.seed}, {c.runs} runs)"
        blocks.append(Paragraph(f"{where}: objective {num(c.objective_original)} original, {num(c.objective_tuned)} "
                                + ("fitted truth." if c.paper_checks else "tuned.")))
        if rows:
            blocks.append(Table(["metric", "original", "tuned", "tuned - original [95 %]", "verdict"], rows))
        blocks.append(Table(["consistency", "original: average [band], inside", "tuned: average [band], inside"],
                            consistency_rows(c.consistency)))
        for title, rows in paper_check_tables(c):
            blocks += [Paragraph(title + "."), Table(VERDICT_HEADERS, rows, max_column=0.3)]
    figs = layout(f"navsim tune: {r.estimator}", blocks)
    return [Page("tune_summary" if i == 0 else f"tune_summary_{i + 1}", "Summary", f) for i, f in enumerate(figs)]


def paper_check_tables(c) -> list[tuple[str, list]]:
    """A truth fit's check (:class:`~navsim.records.tuning.TuneCheck`): per truth, original and
    fitted, its title with the verdicts' summary and the paper checks' rows
    (:data:`~navsim.scoring.verdicts.VERDICT_HEADERS`)."""
    out = []
    for side, checks in (c.paper_checks or {}).items():
        verdicts = [Verdict.from_dict(v) for v in checks]
        out.append((f"Paper checks, {'fitted' if side == 'tuned' else 'original'} truth: {verdict_summary(verdicts)}",
                    verdict_rows(verdicts)))
    return out


def consistency_rows(consistency: dict) -> list:
    """A row for the NEES and each NIS: each side's average, band and share of epochs inside."""
    cell = lambda x: "-" if not x else (f"{num(x['average'])} [{num(x['band'][0])}, {num(x['band'][1])}], "
                                        f"{100 * x['fraction_inside']:.0f} %")
    o, t = consistency.get("original") or {}, consistency.get("tuned") or {}
    rows = [["NEES", cell(o.get("nees")), cell(t.get("nees"))]]
    for k in (o.get("nis") or {}):
        rows.append([f"NIS {k}", cell(o["nis"][k]), cell((t.get("nis") or {}).get(k))])
    return rows


def objective_page(r: TuneRecord) -> Page:
    """The objective of every trial and the best so far."""
    fig, ax = page_figure()
    n = np.array([t.number for t in r.trials])
    y = np.array([np.nan if t.objective is None else t.objective for t in r.trials])
    ax.plot(n, y, "o", ms=4, color="tab:blue", label="trial")
    failed = np.isnan(y)
    if failed.any():
        ax.plot(n[failed], np.full(failed.sum(), np.nanmax(y) if (~failed).any() else 1.0), "x", color="tab:red",
                label="no objective (diverged)")
    best = np.fmin.accumulate(np.where(failed, np.inf, y))
    ax.step(n, np.where(np.isinf(best), np.nan, best), where="post", color="black", lw=1.2, label="best so far")
    if np.nanmin(y) > 0 and np.nanmax(y) / np.nanmin(y) > 20:
        ax.set_yscale("log")
    ax.set_xlabel("trial")
    ax.set_ylabel(f"objective: {r.objective}")
    ax.set_title(f"{r.estimator}: the objective, trial by trial ({r.runs} runs each)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fit(fig)
    return Page("tune_objective", "The objective against the trial", fig)


def parameter_page(r: TuneRecord, params: list) -> Page:
    """Each parameter's trial values against the objective, the best marked."""
    cols = 1 if len(params) == 1 else 2
    rows_n = math.ceil(len(params) / cols)
    fig, axes = page_figure(rows_n, cols, squeeze=False)
    best = r.best_trial
    for ax, p in zip(axes.flat, params):
        x = np.array([t.values[p.name] for t in r.trials])
        y = np.array([np.nan if t.objective is None else t.objective for t in r.trials])
        ax.plot(x, y, "o", ms=3.5, color="tab:blue")
        ax.plot([best.values[p.name]], [best.objective], "*", ms=12, color="tab:orange", label="best")
        if p.log:
            _log_x(ax, np.r_[x, p.lo, p.hi])
        ax.yaxis.set_major_locator(MaxNLocator(6))
        ax.yaxis.set_major_formatter(FormatStrFormatter("%.3g"))
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel(p.what, fontsize=8)
        ax.set_ylabel(r.objective)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(params):]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=8)
    fit(fig)
    return Page("tune_parameters", "Each parameter against the objective", fig)


def _log_x(ax, x: np.ndarray) -> None:
    """A log x axis over the range searched, five ticks labelled plainly (no minor labels: a
    range narrower than a decade would print them over each other)."""
    ax.set_xscale("log")
    lo, hi = float(np.min(x)), float(np.max(x))
    ax.set_xlim(lo / 1.1, hi * 1.1)
    ax.set_xticks(np.geomspace(lo, hi, 5))
    ax.xaxis.set_major_formatter(FormatStrFormatter("%.3g"))
    ax.xaxis.set_minor_formatter(NullFormatter())


def check_page(r: TuneRecord) -> Page:
    """Tuned minus original, each metric component, with its 95 % interval, on the tuning seed
    and on the held-out seed: a held-out difference outside the tuning one is over-fitting."""
    fig, ax = page_figure()
    labels = [d["metric"] + (f" {d['component']}" if d["component"] else "") for d in r.checks["tuning"].differences]
    y = np.arange(len(labels))
    for k, (name, colour) in enumerate((("tuning", "tab:blue"), ("held_out", "tab:orange"))):
        c = r.checks.get(name)
        if c is None:
            continue
        rel = [(d["diff"] / abs(d["a"]) * 100, d["ci95"][0] / abs(d["a"]) * 100, d["ci95"][1] / abs(d["a"]) * 100)
               if d["a"] else (np.nan,) * 3 for d in c.differences]
        mid, lo, hi = (np.array(v) for v in zip(*rel))
        ax.errorbar(mid, y + (k - 0.5) * 0.3, xerr=[mid - lo, hi - mid], fmt="o", color=colour, capsize=3,
                    label=f"{CHECK_NAMES[name]} ({c.seed}, {c.runs} runs)")
    ax.axvline(0, color="black", lw=0.8)
    ax.set_yticks(y, labels, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("tuned - original, % of the original (95 % interval, paired)")
    ax.set_title("Tuned against original: lower is better for RMS; NEES nearer its dimension")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="x")
    fit(fig)
    return Page("tune_check", "Tuned against original on the tuning and held-out seeds", fig)


def prediction_page(r: TuneRecord) -> Page:
    """Each single-flight paper number against the 95 % range of one of our runs, with the
    original and with the fitted truth (held-out seed), as a multiple of the paper's number: the
    fit's numbers should sit inside; the other estimators' are its prediction."""
    c = r.checks.get("held_out") or r.checks["tuning"]
    sides = {side: [Verdict.from_dict(v) for v in checks] for side, checks in c.paper_checks.items()}
    rows = [(k, v) for k, v in enumerate(sides["tuned"]) if v.kind == "single_run" and v.of is None and v.run_range]
    fig, ax = page_figure()
    labels = []
    for y, (k, v) in enumerate(rows):
        paper = np.atleast_1d(np.asarray(v.bound, float))
        role = "fitted" if v.estimator == r.estimator else "predicted"
        metric = v.metric.split(".", 1)[-1] if v.metric.startswith("windows.") else v.metric
        labels.append(f"{v.estimator} ({role}):\n{metric}")
        for side, colour, dy in (("original", "tab:gray", -0.15), ("tuned", "tab:blue", 0.15)):
            w = sides[side][k]
            if not w.run_range:
                continue
            for j, (lo, hi) in enumerate(w.run_range):
                ends = sorted(e / paper[j] for e in (-np.inf if lo is None else lo, np.inf if hi is None else hi))
                ax.plot(ends, [y + dy] * 2, color=colour, lw=3, solid_capstyle="butt",
                        label=f"{'original' if side == 'original' else 'fitted'} truth" if y == j == 0 else None)
        ax.plot([1.0], [y], "D", color="tab:red", ms=6, label="the paper's flight" if y == 0 else None)
    ax.axvline(1.0, color="tab:red", lw=0.6, alpha=0.5)
    ax.set_yticks(range(len(labels)), labels, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("ours / the paper's number: the 95 % range of one run")
    where = CHECK_NAMES["held_out" if "held_out" in r.checks else "tuning"]
    ax.set_title(f"The paper's single flight against one of our runs ({where}, {c.runs} runs)", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="x")
    fit(fig)
    return Page("tune_prediction", "The paper's numbers against one run, original and fitted truth", fig)


def write_tune_report(folder, r: TuneRecord, params: list, formats=("pdf", "png")) -> list:
    """``tune.pdf`` and a PNG per page in the output folder ``folder`` (``formats``: the
    scenario's ``report.formats``); returns the files."""
    pages = summary_pages(r, params) + [objective_page(r), parameter_page(r, params)]
    if r.tuned_sensors is not None:           # a truth model's fit: the paper's numbers, predicted
        pages.append(prediction_page(r))
    elif "tuning" in r.checks:                # a scenario's: the tuning and held-out seeds
        pages.append(check_page(r))
    return render(folder, pages, list(formats), f"navsim tune: {r.estimator}", pdf="tune.pdf")
