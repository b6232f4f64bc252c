"""The summary of a run as sections of tables, declared once for the terminal and the report.

Each builder returns a :class:`Section` (a title, the sentences that say how to read it, a
table) or None where there is nothing to show: the results per estimator, the paper checks, the
consistency findings, the diverged runs, the attitude estimators, the landmark sightings, the
closed loop and the metrics windows. :func:`text_table` prints a section in the terminal;
:func:`summary_figures` and :func:`window_figures` typeset them (:mod:`navsim.report.tables`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from navsim.records.run import RunRecord
from navsim.records.states import SIGMA_STATES
from navsim.report.tables import FAIL, PASS, WARN, Heading, Paragraph, Table, layout
from navsim.records.metrics import RunMetrics
from navsim.scoring.intervals import runs_for_precision
from navsim.scoring.scorer import NORM_QUANTITIES
from navsim.scoring.verdicts import (
    VERDICT_COLUMN,
    VERDICT_HEADERS,
    num,
    verdict_rows,
    verdict_summary,
    with_interval,
)

#: below this share of epochs inside its 95 % band a NEES or NIS is called out
CONSISTENT_FRACTION = 0.5
#: the mean (error/sigma)^2 of a navigation error that the consistency section leaves unmentioned
PER_STATE_RANGE = (0.8, 1.25)
_COLOURS = {"pass": PASS, "FAIL": FAIL}


@dataclass
class Section:
    title: str
    text: str = ""
    headers: list[str] = field(default_factory=list)
    rows: list[list[str]] = field(default_factory=list)
    colours: list[list[str | None]] | None = None
    #: a line shown on its own after the table (in the report and on the terminal)
    note: str | None = None

    @classmethod
    def of_rows(cls, title: str, text: str, headers: list[str], rows: list, colours=None) -> "Section | None":
        """The section of ``rows``, None without them (nothing to show)."""
        return cls(title, text, headers, rows, colours) if rows else None


def pct(fraction) -> str:
    return "-" if fraction is None else f"{100 * fraction:.0f} %"


def pct_ci(fraction, interval) -> str:
    """A share in per cent with its 95 % interval (:func:`pct` alone where there is none)."""
    if fraction is None or interval is None:
        return pct(fraction)
    return with_interval(100 * fraction, [[100 * v for v in interval]]) + " %"


def _nis_worst(m):
    """The NIS of the estimator's measurement least often inside its band, or None."""
    if not m.nis:
        return None
    return min(m.nis.items(), key=lambda kv: kv[1].fraction_inside)


def results(metrics: RunMetrics, settle_s: float) -> Section:
    rows, colours = [], []
    for label, m in metrics.estimators.items():
        rms, nees, worst = m.rms, m.nees, _nis_worst(m)
        nis_cell = "-" if worst is None else pct(worst[1].fraction_inside)
        rows.append([label, *(num(None if rms is None else getattr(rms, k)) for k in ("pos_m", "vel_mps", "att_deg")),
                     num(nees and nees.average), pct(nees and nees.fraction_inside), nis_cell,
                     num(m.convergence_s), str(m.diverged_runs), num(m.cost and m.cost.ms_per_run)])
        low = lambda f: WARN if f is not None and f < CONSISTENT_FRACTION else None
        colours.append([None] * 5 + [low(nees and nees.fraction_inside), low(worst and worst[1].fraction_inside)]
                       + [None, FAIL if m.diverged_runs else None, None])
    return Section(
        f"Results over {metrics.runs_done} runs",
        f"RMS of the errors after {settle_s:g} s, over every counted run and epoch (N, E, D; attitude as a "
        "rotation vector). NEES: average of the navigation errors' NEES and the share of epochs inside its "
        f"95 % band, also from {settle_s:g} s on; NIS: the same share for the measurement least often inside "
        "(which: under Consistency); "
        "converged: when "
        "the RMS position error settles; cost: wall time per run of the batched filter, without compiling "
        "its kernels.",
        ["estimator", "position\nN E D, m", "velocity\nN E D, m/s", "attitude\nN E D, deg", "NEES\navg", "NEES\nin band",
         "NIS\nin band", "converged\ns", "diverged\nruns", "cost\nms/run"], rows, colours, compile_note(metrics))


#: the relative precision the intervals section gives the runs for
PRECISION = 0.05
#: the metrics the intervals section shows: (what, path, unit, scale)
INTERVAL_ROWS = (("RMS position", "rms.pos_m", "m", 1), ("RMS velocity", "rms.vel_mps", "m/s", 1),
                 ("RMS attitude", "rms.att_deg", "deg", 1), ("final position", "final.pos_m", "m", 1),
                 ("p99 position", "p99.pos_m", "m", 1), ("NEES average", "nees.average", "", 1),
                 ("NEES in band", "nees.fraction_inside", "%", 100), ("converged", "convergence_s", "s", 1))


def intervals(metrics: RunMetrics) -> Section | None:
    """Each estimator's main metrics with their 95 % intervals (none at one run)."""
    rows = []
    for label, m in metrics.estimators.items():
        first = True
        for what, path, unit, scale in INTERVAL_ROWS:
            v, iv = m.get(path), m.interval(path)
            if v is None or iv is None or not np.isfinite(np.asarray(iv, float)).any():
                continue                      # no interval (an open end shows as "-")
            v, iv = np.atleast_1d(np.asarray(v, float)) * scale, np.asarray(iv, float).reshape(-1, 2) * scale
            cells = [with_interval(x, [lim.tolist()]) for x, lim in zip(v, iv)]
            needed = [runs_for_precision(m.runs_counted, x, lim, PRECISION) for x, lim in zip(v, iv)]
            needed = max([n for n in needed if n is not None], default=None)
            rows.append([label if first else "", what + (f", {unit}" if unit else ""), *(cells + ["", "", ""])[:3],
                         "-" if needed is None else str(needed)])
            first = False
    return Section.of_rows(f"95 % intervals over {metrics.runs_done} runs",
                           "Each value with its 95 % confidence interval, the runs as the independent samples (a "
                           "run's random-constant biases are one draw): an interval narrows as 1/sqrt(runs), never "
                           "with the epochs. RMS: studentized bootstrap over runs; p99: Woodruff's; NEES and "
                           "convergence: bootstrap over runs (navsim.scoring.intervals). Runs for ±5 %: the runs at "
                           "which every component's interval would be its value ±5 % (the half-width scaled as "
                           "t(runs - 1)/sqrt(runs)).",
                           ["estimator", "metric", "N / value", "E", "D", "runs for\n±5 %"], rows)


def compile_note(metrics: RunMetrics) -> str | None:
    """The seconds each estimator spent compiling its kernels (once per worker process; kept out
    of the cost column), or None when none was measured."""
    spent = {label: m.cost.compile_s for label, m in metrics.estimators.items()
             if m.cost is not None and m.cost.compile_s is not None}
    if not spent:
        return None
    return ("Compile time (numba kernels compiled or loaded from the cache, once per worker process; not in the "
            "cost column): " + ", ".join(f"{label} {s:.2f} s" for label, s in spent.items()) + ".")


def paper_checks(metrics: RunMetrics, reference) -> Section | None:
    if reference is None or metrics.paper_checks is None:
        return None
    rows = verdict_rows(metrics.paper_checks)
    colours = [[None] * VERDICT_COLUMN + [_COLOURS.get(r[VERDICT_COLUMN].split()[0])] for r in rows]
    text = f"Published in {reference.source}. " + (reference.note.strip() if reference.note else "")
    single = [v for v in metrics.paper_checks if v.kind == "single_run"]
    if single:
        text += " " + single_run_note(single, reference.kind_note)
    return Section(f"Paper against ours: {verdict_summary(metrics.paper_checks)}", text.strip(),
                   VERDICT_HEADERS, rows, colours)


def single_run_note(single: list, why: str = "") -> str:
    """How a single run's checks read: what the range is, its own uncertainty at these runs."""
    ranged = next((v for v in single if v.coverage_ci95), None)
    held = "" if ranged is None else (f" (at {ranged.runs} runs the range holds {100 * ranged.coverage_ci95[0]:.0f}-"
                                      f"{100 * ranged.coverage_ci95[1]:.0f} % of single runs, 95 % confidence)")
    return ((why.strip().rstrip(".") + ": " if why else "") + "a single-run number is one flight, judged against "
            "the range holding 95 % of our single runs' values of the same statistic" + held + "; the verdict "
            "gives the paper's percentile among our runs, or the share of them meeting its bound.")


def consistency(metrics: RunMetrics) -> Section | None:
    """NEES and NIS averages inside their 95 % band on fewer than half the epochs: the filter's
    sigmas do not describe its errors (above the band: overconfident; below: too pessimistic)."""
    rows = []
    for label, m in metrics.estimators.items():
        found = ([("NEES", m.nees)] if m.nees else []) + [(f"NIS {k}", v) for k, v in (m.nis or {}).items()]
        for what, s in found:
            if s.fraction_inside < CONSISTENT_FRACTION:
                side = "above: overconfident" if s.average > s.band[1] else (
                    "below: too pessimistic" if s.average < s.band[0] else "inside on average")
                off = [f"{n} {num(v)}" for n, v in zip(SIGMA_STATES, getattr(s, "per_state", None) or [])
                       if not PER_STATE_RANGE[0] <= v <= PER_STATE_RANGE[1]]
                side += f"; (e/σ)² {', '.join(off)}" if off else ""
                rows.append([label, what, num(s.average), f"{num(s.band[0])}-{num(s.band[1])}",
                             pct(s.fraction_inside), side])
    return Section.of_rows("Consistency: sigmas that do not describe the errors",
                           f"Each NEES or NIS whose average is inside its 95 % chi-square band on fewer than "
                           f"{100 * CONSISTENT_FRACTION:.0f} % of the epochs, with the navigation errors whose mean "
                           f"(error/sigma)² is outside {PER_STATE_RANGE[0]:g}-{PER_STATE_RANGE[1]:g}.",
                           ["estimator", "statistic", "average", "95 % band", "epochs inside", "where"], rows,
                           [[None] * 4 + [WARN, None] for _ in rows])


def divergence(metrics: RunMetrics) -> Section | None:
    rows = []
    for label, m in metrics.estimators.items():
        div = m.divergence
        if not div:
            continue
        listed = [f"run {r.run}" + ("" if r.t_s is None else f" at {r.t_s:.1f} s") for r in div.runs[:6]]
        more = f" (+{div.count - len(listed)} more)" if div.count > len(listed) else ""
        rows.append([label, f"{div.count} of {m.runs_counted + m.diverged_runs}",
                     ", ".join(f"{cause}: {n}" for cause, n in div.causes.items()), ", ".join(listed) + more])
    return Section.of_rows("Runs flagged diverged", "Left out of every statistic above; the others completed.",
                           ["estimator", "runs", "causes", "first runs"], rows,
                           [[None, FAIL, None, None] for _ in rows])


def attitude(metrics: RunMetrics) -> Section | None:
    rows = []
    for label, m in metrics.estimators.items():
        a, r = m.attitude, m.resets
        if not a or r is None:          # the attitude estimators (every one has Euler errors)
            continue
        rows.append([label, num(a.p95_deg), num(a.p95_about_run_mean_deg), num(a.rms_deg), num(a.max_abs_deg),
                     f"{r.count} in {r.runs_with_reset} runs"])
    headers = ["estimator", "p95\nroll pitch yaw", "p95 about\nrun mean", "RMS", "max", "resets"]
    return Section.of_rows("Attitude estimators: roll, pitch, yaw",
                           "Errors in degrees after the settling time, as Euler angles (the results table's attitude "
                           "is the rotation vector N, E, D): the 95th percentile of |error|, the same about each "
                           "run's own mean, RMS and maximum; and the divergence monitor's resets.", headers, rows)


def landmarks(metrics: RunMetrics) -> Section | None:
    ci = lambda m, k: m.interval(f"landmarks.{k}")
    rows = [[label, str(m.landmarks.count), num(m.landmarks.rms_before_m.median),
             with_interval(m.landmarks.rms_after_m, ci(m, "rms_after_m")), num(m.landmarks.max_ratio),
             pct_ci(m.landmarks.fraction_within_3sigma, ci(m, "fraction_within_3sigma"))]
            for label, m in metrics.estimators.items() if m.landmarks]
    return Section.of_rows("Landmark sightings",
                           "Horizontal error just before a sighting (RMS, median over sightings), after its last "
                           "fix (RMS per axis), the largest |error| / fix sigma, and the share inside 3 sigma; "
                           "after and inside with their 95 % intervals over the runs.",
                           ["estimator", "sightings", "before\nm", "after\nm", "max\n|e|/sigma", "inside\n3 sigma"],
                           rows)


def wind(metrics: RunMetrics) -> Section | None:
    """The wind estimate's error against the true steady wind, for each estimator with a wind state."""
    ci = lambda m, k: m.interval(f"wind.{k}")
    rows = [[label, with_interval(m.wind.rms_mps, ci(m, "rms_mps")), with_interval(m.wind.final_mps, ci(m, "final_mps")),
             " ".join("-" if v is None else num(v) for v in m.wind.rms_axes_mps)]
            for label, m in metrics.estimators.items() if m.wind]
    return Section.of_rows("Wind estimate",
                           "The estimated wind minus the true steady wind (the gusts left out), m/s, from the "
                           "settling time on: horizontal RMS over runs and epochs and at the last epoch, with their "
                           "95 % intervals over the runs, and the RMS per axis (-: not estimated).",
                           ["estimator", "horizontal\nRMS", "at the end", "RMS\nN E D"], rows)


def closed_loop(m: dict | None) -> Section | None:
    r = m and m.get("return_to_land")
    if not r:
        return None
    ref, text = r["truth_guided"], (
        f"Flown on '{m['fly_on']}'; outcomes " + ", ".join(f"{k} {v}" for k, v in m.get("outcomes", {}).items())
        + f". {r['landed']} landed, {r['reached_area']} inside the {r['area_m']:g} m recovery area; mission "
        f"abandoned at {num(r['abort_t_s'].get('mean'))} s (mean), landed (parachute or touchdown) at {num(r['land_t_s'].get('mean'))} s.")
    c = r.get("consistency")
    if c:
        text += (f" At the landing the horizontal error RMS is {num(c['horizontal_error_rms_m'])} m, the "
                 f"sigmas predict CEP50 {num(c['predicted_cep50_m'])} m; normalised error (e/sigma)^2 "
                 f"{num(c['normalised_error'])} (95 % band {c['band'][0]:.2f}-{c['band'][1]:.2f}).")
    ci = lambda d, k: [d.get("ci95", {}).get(k)] if d.get("ci95") else None
    row = lambda name, d: [name, *(with_interval(d[k], ci(d, k)) for k in ("cep50_m", "cep95_m", "mean_m")),
                           num(d["max_m"]), str(d["n"])]
    return Section("Navigation in the loop: return to land", text,
                   ["miss distance", "CEP50 m", "CEP95 m", "mean m", "max m", "runs"],
                   [row("true (guided on the solution)", r["miss"]), row("the solution's own", r["miss_estimate"]),
                    ["same flight guided on the truth", num(ref["miss_m"]), "-", "-", "-", "1"]])


#: a window's table shows ``heading_deg`` and leaves ``yaw_deg`` (in metrics.json) out: this
#: says why, with the largest difference of their statistics (deg)
YAW_LEFT_OUT = (" The Euler yaw error (yaw_deg, in metrics.json) is left out: it is the heading error (the "
                "rotation error about the vertical) plus tan(pitch) times the tilt error about the heading "
                "axis, equal in level flight; its statistics are within {} deg of heading_deg's here.")


def _yaw_apart(quantities: dict):
    """The largest difference between the statistics of ``yaw_deg`` and ``heading_deg`` (None
    without both)."""
    if "yaw_deg" not in quantities or "heading_deg" not in quantities:
        return None
    a, b = quantities["yaw_deg"], quantities["heading_deg"]
    stats = ("max_pos", "max_neg", "std", "rms", "p95_abs")
    return float(np.nanmax([abs(getattr(a, k) - getattr(b, k)) for k in stats]))


def windows(metrics: RunMetrics, spans=()) -> list[Section]:
    """One section per metrics window: each estimator's quantities (``spans``: the scenario's
    ``(name, start_s, end_s)``); ``yaw_deg`` left out beside ``heading_deg`` (:data:`YAW_LEFT_OUT`)."""
    names = list(dict.fromkeys(w for m in metrics.estimators.values() for w in (m.windows or {})))
    times = {name: (a, b) for name, a, b in spans}
    out = []
    for name in names:
        rows, nees, drift, apart = [], [], [], []
        for label, m in metrics.estimators.items():
            w = (m.windows or {}).get(name)
            if w is None:
                continue
            ci = lambda key: m.interval(f"windows.{name}.{key}")
            h = w.horizontal_m
            if h is not None and h.final is not None:
                drift.append(f"{label} {with_interval(h.final, ci('horizontal_m.final'))} at its end, largest "
                             f"{with_interval(h.max, ci('horizontal_m.max'))}")
            if w.nees is not None:
                nees.append(f"{label} {with_interval(w.nees.average, ci('nees.average'))}, "
                            f"{pct_ci(w.nees.fraction_inside, ci('nees.fraction_inside'))} in band")
            shown = {q: v for q, v in w.quantities.items()
                     if not (q == "yaw_deg" and "heading_deg" in w.quantities)}
            apart += [d for d in [_yaw_apart(w.quantities)] if d is not None]
            for j, (q, v) in enumerate(shown.items()):
                norm = q in NORM_QUANTITIES
                rows.append([label if j == 0 else "", q + (" (norm)" if norm else ""), num(v.max_pos),
                             "-" if norm else num(v.max_neg), with_interval(v.std, ci(f"{q}.std")),
                             with_interval(v.rms, ci(f"{q}.rms"))])
        span = f" ({times[name][0]:g}-{times[name][1]:g} s)" if name in times else ""
        text = ("Errors over the window, every run: largest positive and negative (a norm has no negative side), "
                "standard deviation and RMS with their 95 % intervals over the runs.")
        text += (" Horizontal position error, m (RMS over the runs; an outage's drift): " + "; ".join(drift) + "."
                 if drift else "")
        text += f" NEES over the window: {'; '.join(nees)}." if nees else ""
        text += YAW_LEFT_OUT.format(num(max(apart))) if apart else ""
        out.append(Section(f"Window '{name}'{span}", text,
                           ["estimator", "quantity", "max +", "max -", "std", "RMS"], rows))
    return out


#: the window quantities the summary's one line per window and estimator shows (their RMS;
#: the rest are on the windows' own pages)
WINDOW_LINE = ("height_m", "heading_deg")


def window_lines(metrics: RunMetrics, spans=()) -> Section | None:
    """What a scenario with metrics windows exists for, one line per window and estimator: the
    horizontal drift at the window's end and its largest (an outage's drift), with their 95 %
    intervals, the RMS of the height and heading errors and the NEES over the window; the windows'
    whole tables are on pages of their own (:func:`windows`). None without windows."""
    names = list(dict.fromkeys(w for m in metrics.estimators.values() for w in (m.windows or {})))
    times = {name: (a, b) for name, a, b in spans}
    rows = []
    for name in names:
        shown = name + (f" ({times[name][0]:g}-{times[name][1]:g} s)" if name in times else "")
        for label, m in metrics.estimators.items():
            w = (m.windows or {}).get(name)
            if w is None:
                continue
            first, shown = shown, ""           # the window named on its first line only
            ci = lambda key: m.interval(f"windows.{name}.{key}")
            h, q = w.horizontal_m, w.quantities
            rows.append([first, label,
                         "-" if h is None else with_interval(h.final, ci("horizontal_m.final")),
                         "-" if h is None else with_interval(h.max, ci("horizontal_m.max")),
                         *[num(q[k].rms) if k in q else "-" for k in WINDOW_LINE],
                         "-" if w.nees is None else f"{num(w.nees.average)}, {pct(w.nees.fraction_inside)}"])
    return Section.of_rows(
        "Metrics windows", "What the scenario measures over its windows, every run: the horizontal position "
        "error at each window's end and its largest (RMS over the runs, an outage's drift, 95 % intervals), "
        "the RMS of the height and heading errors and the NEES (average, share in its band); each window's "
        "whole table is on its own page.",
        ["window", "estimator", "horizontal\nat end, m", "horizontal\nmax, m", "height\nRMS, m",
         "heading\nRMS, deg", "NEES,\nin band"], rows)


def sections(metrics: RunMetrics, scenario) -> list[Section]:
    """Every section of the summary, in order (the windows' lines last)."""
    out = [results(metrics, scenario.settle_s), intervals(metrics), paper_checks(metrics, scenario.reference), consistency(metrics),
           divergence(metrics), attitude(metrics), landmarks(metrics), wind(metrics), closed_loop(metrics.closed_loop),
           window_lines(metrics, scenario.windows)]
    return [s for s in out if s is not None]


def text_table(section: Section, table) -> str:
    """A section for the terminal: its title, then ``table(headers, rows)`` (header line breaks
    become spaces)."""
    text = f"{section.title}:\n" + table([h.replace("\n", " ") for h in section.headers], section.rows)
    return text + (f"\n{section.note}" if section.note else "")


def _blocks(section: Section) -> list:
    out = [Heading(section.title)]
    if section.text:
        out.append(Paragraph(section.text, size=7.5, colour="#333333"))
    out.append(Table(section.headers, section.rows, section.colours))
    return out + ([Paragraph(section.note, size=7.5, colour="#333333")] if section.note else [])


def run_details(scenario, record: RunRecord) -> str:
    if record.log is not None:
        return log_details(record)
    plotted = record.plotted
    return (f"Scenario file {record.scenario}, track {scenario.flight.track.name}; {record.runs_done} of "
            f"{record.runs} runs done (seed {record.seed}, {record.workers} workers), "
            f"{len(record.failed_runs)} failed{', interrupted' if record.interrupted else ''}"
            + (f"; plots show the first {plotted} runs" if plotted < record.runs_done else "")
            + f". Flight {'from the cache' if record.flight_cached else 'flown'} ({record.flight_key}); "
            f"wall time {record.wall_s:.1f} s; git {record.git_revision}; "
            + ", ".join(f"{k} {v}" for k, v in record.versions.items()) + ".")


def log_details(record: RunRecord) -> str:
    """A replayed log's run details: its files, what it is scored against, what the replay
    worked around, the software."""
    log = record.log
    against = ("differences from the log's own solution, not errors" if log["scored_against"] == "solution"
               else "errors against the log's reference trajectory")
    files = ", ".join(f"{role} {path}" for role, path in log["files"].items())
    notes = "".join(f" Note: {n}." for n in log.get("notes") or [])
    return (f"A {log['format']} log replayed ({files}) through the estimators of the scenario file "
            f"{record.scenario or '(built in Python)'}, as one run: {against}.{notes} Wall time {record.wall_s:.1f} s; "
            f"git {record.git_revision}; " + ", ".join(f"{k} {v}" for k, v in record.versions.items()) + ".")


def summary_figures(scenario, record: RunRecord, metrics: RunMetrics) -> list:
    """The summary's figures: the description, the sections and the run's details."""
    blocks = [Paragraph(scenario.description.strip() or "(no description)", size=8.5)]
    for s in sections(metrics, scenario):
        blocks += _blocks(s)
    blocks += [Heading("Run"), Paragraph(run_details(scenario, record), size=7, colour="#333333")]
    return layout(f"navsim report: {scenario.name}", blocks)


def window_figures(scenario, metrics: RunMetrics) -> list:
    """The metrics windows' tables, on pages of their own (none without windows)."""
    win = [b for s in windows(metrics, scenario.windows) for b in _blocks(s)]
    return layout(f"{scenario.name}: metrics windows", win) if win else []
