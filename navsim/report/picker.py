"""The run picker of ``report.html``: any run, the worst by a metric, or the diverged ones,
its errors on each axis against its own ±3σ and its events, redrawn in the browser.

The errors held are the position's, then the attitude's and the velocity's while the page stays
within :data:`MAX_VALUES` values (:func:`quantities`). Each estimator's errors and 1-sigmas of
every run are held in the page as 16-bit integers scaled per run and trace (:func:`quantised`:
the trace's largest value over 32767, a step under 1/30 000 of the plot's height), thinned as
the PDF's curves are beyond :data:`~navsim.flight.plots.PLOT_POINTS` epochs (:func:`run_traces`);
a JavaScript callback (:data:`PICK_JS`) decodes the chosen run as :func:`decoded` does in Python
(the browser tests compare the two to the bit).
"""

from __future__ import annotations

import warnings

import numpy as np
from bokeh.layouts import column, row
from bokeh.models import (ColumnDataSource, CustomJS, DataTable, Div, HTMLTemplateFormatter, LegendItem, MultiLine,
                          Select, TableColumn, VSpan)
from matplotlib.colors import to_hex

from navsim.flight.plots import PLOT_POINTS, drawn
from navsim.records.states import BLOCKS
from navsim.report.errors import AXES, ERROR_FIELDS, envelopes, split_free
from navsim.report.figures import ReportInput, estimator_colours
from navsim.report.html_parts import WIDTH, esc, hide, legend_row, shade, time_figure
from navsim.scoring.stats import last_finite

#: the worst runs the picker lists by each metric
WORST_RUNS = 20
#: a 16-bit trace's full scale
FULL_SCALE = 32767
#: the most values the picker holds (errors and sigmas over runs and epochs drawn): about 2 MB
#: of the page and 0.1 s of its writing per million (P0's 1000 runs: its position, 4.5 million;
#: with the attitude, 19.7 MB written in 0.3 s more; P4's 40 runs: position and attitude)
MAX_VALUES = 6_000_000


def quantised(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(q, scale)`` of a ``(R, C, N)`` array: ``q`` 16-bit integers, ``x ≈ q * scale`` within
    half a step, ``scale`` ``(R, C)`` (single precision, as the page holds it) each run's trace's
    largest finite magnitude over :data:`FULL_SCALE` (1 where all are 0; kept within single
    precision's normal range), a NaN or an infinite value as ``-32768`` (a gap)."""
    x = np.asarray(x, np.float64)
    finite = np.isfinite(x)
    peak = np.max(np.where(finite, np.abs(x), 0.0), axis=2, initial=0.0)
    f32 = np.finfo(np.float32)
    scale = np.where(peak > 0, np.clip(peak / FULL_SCALE, f32.tiny, f32.max), 1.0).astype(np.float32)
    q = np.clip(np.round(np.where(finite, x, 0.0) / scale[..., None].astype(np.float64)), -FULL_SCALE, FULL_SCALE)
    return np.where(finite, q, -FULL_SCALE - 1).astype(np.int16), scale


def errors_of(h, key: str) -> np.ndarray:
    """An estimator's ``key`` error (``pos``, ``vel``, ``att``: m, m/s, deg) and, where it
    has a covariance, its 1-sigma: ``(R, 3 or 6, E)``, the axes N, E, D then their sigmas."""
    err = np.asarray(getattr(h, ERROR_FIELDS[key]))
    out = [np.moveaxis(np.degrees(err) if key == "att" else err, 2, 1)]
    if h.sigma is not None:
        sig = np.asarray(h.sigma[..., BLOCKS[key]])
        out.append(np.moveaxis(np.degrees(sig) if key == "att" else sig, 2, 1))
    return np.concatenate(out, axis=1)


def quantities(histories: dict) -> tuple[str, ...]:
    """The errors the picker holds: position, then attitude and velocity while the page's
    values stay within :data:`MAX_VALUES` (P0's 1000 runs: position alone; 600 runs or fewer:
    and attitude)."""
    # each error holds as many values: runs x (3 axes, and 3 sigmas) x epochs drawn (about)
    one = sum(len(h.diverged) * (6 if h.sigma is not None else 3) * min(len(h.t_s), 2 * PLOT_POINTS)
              for h in histories.values())
    return ("pos", "att", "vel")[:max(1, min(3, MAX_VALUES // max(one, 1)))]


def run_traces(h, keys=("pos",)) -> dict:
    """One estimator's picker data: its times ``t`` ``(E,)``, per run the epochs drawn (all
    of them, ``idx`` empty, where there are at most PLOT_POINTS; else ``idx`` flat with
    ``offsets``), the errors ``keys`` (:func:`errors_of`, ``per`` channels each) quantised
    (:func:`quantised`) in ``values`` ``(C * total,)`` and ``scales`` ``(R * C,)``."""
    err = np.concatenate([errors_of(h, k) for k in keys], axis=1)
    R, C, E = err.shape
    q, scales = quantised(err)
    if E <= PLOT_POINTS:
        idx, offsets = np.zeros(0, np.int32), np.arange(R + 1, dtype=np.int32) * E
        values = np.moveaxis(q, 1, 0).reshape(C, R * E)
    else:
        keep = [np.unique(np.concatenate([drawn(err[r, c]) for c in range(C)])) for r in range(R)]
        offsets = np.concatenate([[0], np.cumsum([len(k) for k in keep])]).astype(np.int32)
        idx = np.concatenate(keep).astype(np.int32)
        values = np.concatenate([q[r][:, k] for r, k in enumerate(keep)], axis=1)
    return {"t": np.asarray(h.t_s, np.float32), "idx": idx, "offsets": offsets, "values": values.reshape(-1),
            "scales": scales.reshape(-1), "channels": C, "per": C // len(keys)}


def decoded(traces: dict, r: int, q: int = 0) -> dict:
    """Row ``r``'s drawn trace of the ``q``-th error held as the page's JavaScript decodes it:
    ``t`` and, per axis ``j``, the error ``e{j}`` and ``±3σ`` ``p{j}``/``m{j}`` (NaN without a
    sigma)."""
    off, C, per, idx = traces["offsets"], traces["channels"], traces["per"], traces["idx"]
    n0, n1, total = int(off[r]), int(off[r + 1]), int(off[-1])
    t = traces["t"][np.arange(n1 - n0)] if idx.size == 0 else traces["t"][idx[n0:n1]]
    chans = []
    for c in range(q * per, (q + 1) * per):
        v = traces["values"][c * total + n0:c * total + n1].astype(np.float64)
        chans.append(np.where(v == -FULL_SCALE - 1, np.nan, v * np.float64(traces["scales"][r * C + c])))
    out = {"t": t.astype(np.float64)}
    for j in range(3):
        sig = chans[3 + j] if per > 3 else np.full(n1 - n0, np.nan)
        out.update({f"e{j}": chans[j], f"p{j}": 3 * sig, f"m{j}": -3 * sig})
    return out


def axis_data(d: dict, j: int) -> dict:
    """Axis ``j`` of a :func:`decoded` run as the picker's plot holds it: the error, +3σ and
    -3σ as the rows of one ``MultiLine``."""
    return {"xs": [d["t"]] * 3, "ys": [d[f"e{j}"], d[f"p{j}"], d[f"m{j}"]], "w": [1.4, 1.0, 1.0],
            "d": ["solid", "dashed", "dashed"]}


def run_numbers(inp: ReportInput, rows: int) -> np.ndarray:
    """The run number of each history row (the histories hold the first runs of a streamed
    result; an older result without the list: the rows' order)."""
    for name in ("history_runs", "runs"):
        runs = getattr(inp.result, name, None)
        if runs is not None and len(runs) == rows:
            return np.asarray(runs, int)
    return np.arange(rows)


def rankings(inp: ReportInput) -> dict:
    """The picker's option groups: per estimator the worst :data:`WORST_RUNS` runs by RMS
    position error after the settling time and by final position error, its diverged runs;
    then every run: group -> ``[(history row, text)]``, each text naming its run, unique over
    the groups (the option's value is its text)."""
    settle_s = inp.scenario.settle_s
    groups, first = {}, None
    filters_first = sorted(inp.histories.items(), key=lambda kv: kv[1].sigma is None)   # stable
    for label, h in filters_first:
        err = np.asarray(h.pos_err_m, np.float64)
        numbers = run_numbers(inp, err.shape[0]) if first is None else first
        first = numbers
        after = h.t_s >= settle_s
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)         # a run without epochs: NaN
            rms = np.sqrt(np.nanmean(np.sum(err[:, after] ** 2, axis=2), axis=1)) if after.any() else np.full(len(err), np.nan)
            last = last_finite(np.isfinite(err).all(axis=2))
            final = np.linalg.norm(err[np.arange(len(err)), last], axis=1)
        for what, short, v in ((f"RMS position error after {settle_s:g} s", "RMS", rms),
                               ("final position error", "final", final)):
            order = [r for r in np.argsort(-np.nan_to_num(v, nan=-np.inf)) if np.isfinite(v[r])][:WORST_RUNS]
            groups[f"{label}: worst {len(order)} by {what}"] = [(r, f"run {numbers[r]}: {v[r]:.3g} m {short} · {label}")
                                                               for r in order]
        bad = np.flatnonzero(np.asarray(h.diverged, bool))
        if bad.size:
            groups[f"{label}: diverged ({bad.size})"] = [(r, f"run {numbers[r]}: diverged · {label}") for r in bad]
    rows = len(first) if first is not None else 0
    groups["every run"] = [(r, f"run {first[r]}") for r in range(rows)]
    return {g: opts for g, opts in groups.items() if opts}     # a metric no run has: no group



#: the picker's callback: row ``select.value`` of every estimator decoded as :func:`decoded`
#: does, its events listed
PICK_JS = """
const r = option_rows[option_texts.indexOf(select.value)];
const rows = {estimator: [], t: [], event: []};
for (let e = 0; e < src.length; e++) {
  const C = ch[e], off = offsets[e], n0 = off[r], n = off[r + 1] - n0, total = off[off.length - 1];
  const uniform = idx[e].length == 0;
  const t = new Float64Array(n), chans = [];
  for (let i = 0; i < n; i++) t[i] = uniform ? times[e][i] : times[e][idx[e][n0 + i]];
  for (let c = 0; c < C; c++) {
    const v = new Float64Array(n), s = scales[e][r * C + c];
    for (let i = 0; i < n; i++) {
      const q = values[e][c * total + n0 + i];
      v[i] = q == -32768 ? NaN : q * s;
    }
    chans.push(v);
  }
  const per = C / src[e].length;
  for (let q = 0; q < src[e].length; q++) {
    for (let j = 0; j < 3; j++) {
      const b = q * per;
      const p = per > 3 ? chans[b + 3 + j].map(x => 3 * x) : new Float64Array(n).fill(NaN);
      const m = per > 3 ? chans[b + 3 + j].map(x => -3 * x) : new Float64Array(n).fill(NaN);
      src[e][q][j].data = {xs: [t, t, t], ys: [chans[b + j], p, m], w: [1.4, 1, 1], d: ['solid', 'dashed', 'dashed']};
    }
  }
  const ex = [];
  for (let k = 0; k < ev_row[e].length; k++) {
    if (ev_row[e][k] == r) {
      ex.push(ev_t[e][k]);
      rows.estimator.push(labels[e]); rows.t.push(ev_shown[e][k]); rows.event.push(ev_text[e][k]);
    }
  }
  ev_src[e].data = {x: ex};
}
events.source.data = rows;
info.text = 'Run ' + numbers[r] + ': ' + (rows.t.length ? rows.t.length + ' event(s)' : 'no events') + '.';
"""


def events_of(h) -> tuple[list, list, list]:
    """An estimator's events per history row: ``(rows, t_s, texts)`` of its resets and of the
    epoch it was flagged diverged."""
    rows, ts, texts = [], [], []
    for r, events in enumerate(h.resets or []):
        for t, cause in events or []:
            rows.append(r), ts.append(float(t)), texts.append(f"reset: {cause}")
    for r, flag in enumerate(h.divergence or []):
        if flag is not None:
            rows.append(r), ts.append(float(flag[0])), texts.append(f"diverged: {flag[1]}")
    return rows, ts, texts


def picker_tab(inp: ReportInput, time_range):
    """A run chosen from :func:`rankings`: its errors (:func:`quantities`) per axis against
    its own ±3σ, its events as lines and in a table, the sensors' faults shaded (red); None
    without a run."""
    groups = rankings(inp)
    if not groups:
        return None
    keys, labels = quantities(inp.histories), list(inp.histories)
    traces = [run_traces(h, keys) for h in inp.histories.values()]
    row0, start = next(iter(next(iter(groups.values()))))
    srcs = [[[ColumnDataSource(axis_data(decoded(tr, row0, q), j), name=f"run_{k}_{i}_{j}") for j in range(3)]
             for q, k in enumerate(keys)] for i, tr in enumerate(traces)]
    evs = [events_of(h) for h in inp.histories.values()]
    ev_srcs = [ColumnDataSource({"x": [t for r, t in zip(ev[0], ev[1]) if r == row0]}, name=f"run_events_{i}")
               for i, ev in enumerate(evs)]
    figs, hidden = _figures(inp, time_range, keys, srcs, ev_srcs)
    numbers = run_numbers(inp, len(inp.histories[labels[0]].diverged)).tolist()
    events, info = _events(labels, evs, row0, numbers[row0])
    select = Select(title="Run", options={g: [text for _, text in opts] for g, opts in groups.items()}, value=start,
                    width=520, name="run_select")
    every = [(r, text) for opts in groups.values() for r, text in opts]
    args = dict(select=select, src=srcs, ev_src=ev_srcs, events=events, info=info, labels=labels, numbers=numbers,
                ch=[tr["channels"] for tr in traces], offsets=[tr["offsets"] for tr in traces],
                idx=[tr["idx"] for tr in traces], times=[tr["t"] for tr in traces],
                values=[tr["values"] for tr in traces], scales=[tr["scales"] for tr in traces],
                ev_row=[np.asarray(ev[0], np.int32) for ev in evs], ev_t=[np.asarray(ev[1], float) for ev in evs],
                ev_shown=[[f"{t:.2f}" for t in ev[1]] for ev in evs], ev_text=[ev[2] for ev in evs],
                option_texts=[t for _, t in every], option_rows=np.array([r for r, _ in every], np.int32))
    select.js_on_change("value", CustomJS(args=args, code=PICK_JS))
    shown = ", ".join(AXES[k][0] for k in keys)
    text = (f"Choose a run: the worst by a metric of each estimator, its diverged runs, or any run. Solid: its {shown}; "
            "dashed: ± 3 × its own filter sigma; dotted lines: its events (resets, divergence); red: sensor faults; "
            "orange: metric windows. Values drawn to 1/30 000 of each trace's largest (the full data: chunks/)"
            + (f"; {', '.join(sorted(hidden))} hidden at first (its legend entry shows it)." if hidden else "."))
    note = Div(text=f"<p style='max-width:{WIDTH}px'>{esc(text)}</p>")
    return column(note, row(select, info), *figs, events)


def _figures(inp: ReportInput, time_range, keys, srcs, ev_srcs) -> tuple[list, set]:
    """The picker's plots, three axes per error held, each estimator's error, ±3σ and events
    in its colour; a free-inertial estimator that would flatten the others hidden at first."""
    colours = {k: to_hex(c) for k, c in estimator_colours(inp.histories).items()}
    hidden = set()
    for key in keys:
        env = {k: e for k, h in inp.histories.items() if (e := envelopes(h, key)) is not None}
        hidden |= set(split_free(env, (inp.scenario.settle_s, np.inf))[1])
    figs = []
    for q, key in enumerate(keys):
        title, unit, names = AXES[key]
        for j, axis in enumerate(names):
            fig = time_figure(f"{title[0].upper() + title[1:]}, {axis}: the chosen run against its own ±3σ", unit,
                              time_range)
            items = []
            for i, label in enumerate(inp.histories):
                c = colours[label]
                lines = [fig.add_glyph(srcs[i][q][j], MultiLine(xs="xs", ys="ys", line_color=c, line_width="w",
                                                                line_dash="d")),
                         fig.add_glyph(ev_srcs[i], VSpan(x="x", line_color=c, line_width=2, line_dash="dotted"))]
                hide(lines, label in hidden)
                items.append(LegendItem(label=label, renderers=lines))
            legend_row(fig, items)
            shade(fig, inp, faults=True)
            figs.append(fig)
    return figs, hidden


def _events(labels: list, evs: list, row0: int, number: int):
    """The table of the chosen run's events and the line naming the run (row ``row0`` at first)."""
    first = [(labels[i], f"{t:.2f}", x) for i, ev in enumerate(evs) for r, t, x in zip(*ev) if r == row0]
    table = DataTable(source=ColumnDataSource({"estimator": [f[0] for f in first], "t": [f[1] for f in first],
                                               "event": [f[2] for f in first]}, name="run_event_table"),
                      columns=[TableColumn(field=f, title=tt, formatter=HTMLTemplateFormatter(template=f"<%- {f} %>"))
                               for f, tt in (("estimator", "estimator"), ("t", "time, s"), ("event", "event"))],
                      width=WIDTH, height=140, index_position=None, reorderable=False)
    info = Div(text=f"Run {number}: " + (f"{len(first)} event(s)." if first else "no events."), render_as_text=True,
               name="run_info")
    return table, info
