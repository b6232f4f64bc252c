"""No number on a report page differs from ``metrics.json``: the P0 and P3 reports' results table,
metrics windows and consistency panels read back from the drawn pages (their text artists) and
compared with the file the run wrote. The pages are drawn from the runs' histories; every
statistic they print must be the scorer's."""

import json
import re
from collections import defaultdict

import matplotlib.pyplot as plt
import pytest

import navsim
from navsim.report.summary import pct
from navsim.scoring.scorer import NORM_QUANTITIES
from navsim.scoring.verdicts import num


@pytest.fixture(scope="module", params=["p0_bd_sins_ads", "p3_sins_gps"])
def drawn(request, shipped_flight, tmp_path_factory):
    scenario, _, _ = shipped_flight(request.param)
    out = tmp_path_factory.mktemp(request.param) / "run"
    result = navsim.run(scenario, runs=4, seed=5, workers=1, out=out)
    metrics = json.loads((out / "metrics.json").read_text())
    pages = navsim.report_figures(result)
    yield request.param, metrics, {p.name: p.figure for p in pages}
    for p in pages:
        plt.close(p.figure)


def lines(fig, headings: bool = False) -> list:
    """The page's text lines top to bottom, each the texts on one baseline from left to right
    (a typeset page draws every cell line as a text of its own); ``headings``: each line as
    ``(texts, whether it is a heading)`` (bold, 11 pt or more)."""
    rows = defaultdict(list)
    for t in fig.texts:
        if t.get_visible() and t.get_text().strip():
            x, y = t.get_position()
            rows[round(y, 5)].append((x, t.get_text(), t.get_weight() == "bold" and t.get_fontsize() >= 11))
    out = [sorted(rows[y]) for y in sorted(rows, reverse=True)]
    return [([s for _, s, _ in r], r[0][2]) for r in out] if headings else [[s for _, s, _ in r] for r in out]


def section(fig, heading: str) -> list[list[str]]:
    """The lines under the heading starting with ``heading``, to the next heading."""
    out, inside = [], False
    for line, is_heading in lines(fig, headings=True):
        if is_heading:
            inside = line[0].startswith(heading)
        elif inside:
            out.append(line)
    return out


def table_rows(block: list[list[str]], first: set) -> dict:
    """``first cell -> the other cells`` of a table's rows (a table split into column groups
    repeats its first column: the groups are joined)."""
    out = defaultdict(list)
    for line in block:
        if line[0] in first:
            out[line[0]] += line[1:]
    return dict(out)


def test_the_results_table_is_metrics_json(drawn):
    name, metrics, pages = drawn
    est = metrics["estimators"]
    block = section(pages["summary"], "Results over")
    assert any(line[0] == f"Results over {metrics['runs_done']} runs" for line in lines(pages["summary"]))
    rows = table_rows(block, set(est))
    assert set(rows) == set(est), (name, block)
    for label, m in est.items():
        rms, nees, nis = m.get("rms") or {}, m.get("nees"), m.get("nis") or {}
        worst = min(nis.values(), key=lambda s: s["fraction_inside"]) if nis else None
        want = [num(rms.get("pos_m")), num(rms.get("vel_mps")), num(rms.get("att_deg")),
                num(nees and nees["average"]), pct(nees and nees["fraction_inside"]),
                "-" if worst is None else pct(worst["fraction_inside"]), num(m.get("convergence_s")),
                str(m["diverged_runs"]), num((m.get("cost") or {}).get("ms_per_run"))]
        assert rows[label] == want, (name, label)


def test_the_consistency_panels_quote_metrics_json(drawn):
    name, metrics, pages = drawn
    quoted = 0
    for page, fig in pages.items():
        if not page.startswith("consistency"):
            continue
        for ax in fig.axes:
            ylabel = ax.get_ylabel()
            notes = [t.get_text() for t in ax.texts if "of epochs inside" in t.get_text()]
            assert len(notes) == 1, (name, page, ylabel)
            for note in notes[0].split("\n"):
                label, _, said = note.rpartition(": ")
                if ylabel.startswith("average NEES"):
                    labels = [label] if label else [k for k, m in metrics["estimators"].items() if m.get("nees")]
                    score = metrics["estimators"][labels[0]]["nees"]
                else:
                    key, label = re.match(r"NIS (.+), dim \d+\n(.+)", ylabel).groups()
                    score = metrics["estimators"][label]["nis"][key]
                assert said == f"{pct(score['fraction_inside'])} of epochs inside", (name, page, ylabel, note)
                quoted += 1
    with_nis = sum(len(m.get("nis") or {}) + bool(m.get("nees")) for m in metrics["estimators"].values())
    assert quoted == with_nis > 0, name


def test_the_window_tables_are_metrics_json(drawn):
    name, metrics, pages = drawn
    est = metrics["estimators"]
    windows = {w for m in est.values() for w in m.get("windows") or {}}
    figs = [fig for page, fig in pages.items() if page.startswith("windows")]
    assert bool(figs) == bool(windows), name
    seen = set()
    for fig in figs:
        window = label = None
        for line, is_heading in lines(fig, headings=True):
            if is_heading and (m := re.match(r"Window '(.+)'", line[0])):
                window = m.group(1)
                continue
            if line[0] in est:
                label, line = line[0], line[1:]
            quantity = line[0].removesuffix(" (norm)") if line else None
            if window is None or quantity not in (est.get(label, {}).get("windows") or {}).get(window, {}):
                continue
            q = est[label]["windows"][window][quantity]
            max_neg = "-" if quantity in NORM_QUANTITIES else num(q["max_neg"])
            assert line[1:5] == [num(q["max_pos"]), max_neg, num(q["std"]), num(q["rms"])], (window, label, line)
            seen.add((window, label, quantity))
    want = {(w, k, q) for k, m in est.items() for w, qs in (m.get("windows") or {}).items() for q in qs
            if q not in ("nees", "horizontal_m")}
    assert seen == want, name


def test_every_page_is_a4_numbered_and_in_the_contents(drawn):
    name, _, pages = drawn
    sizes = {tuple(round(v, 2) for v in fig.get_size_inches()) for fig in pages.values()}
    assert sizes == {(8.27, 11.69)}, (name, sizes)
    feet = [[t.get_text() for t in fig.texts if re.search(r"page \d+ of \d+$", t.get_text())] for fig in pages.values()]
    assert [f[0].rsplit(" · ", 1)[1] if f else None for f in feet] == [
        f"page {i + 1} of {len(pages)}" for i in range(len(pages))], name
    contents = table_rows(lines(pages["contents"]), {str(i) for i in range(2, len(pages) + 1)})
    assert sorted(contents, key=int) == [str(i) for i in range(2, len(pages) + 1)], name
    hidden = [page for page, fig in pages.items() for ax in fig.axes if not ax.get_visible()]
    assert not hidden, f"{name}: an empty panel on {hidden}"
