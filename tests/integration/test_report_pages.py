"""Every page of the P0, P2, P3 and P4 reports (every shipped scenario's in the slow suite)
written: no text lies outside its figure, no two tick labels of an axis overprint (the suite's
checker, tests/pages.py, on every figure a test saves: the PDF's pages and the PNGs drawn in
this process), the summary carries the paper checks with their verdicts, every page is A4, numbered and in
the contents; and no number
on a page differs from ``metrics.json`` (the results table, the metrics windows and the
consistency panels read back from the drawn pages' text and compared with the file the run
wrote). One run of each: the pages, and that their numbers are the scorer's."""

import json
import re
from collections import defaultdict

import matplotlib
import matplotlib.pyplot as plt
import pytest
from matplotlib.text import Text
from pages import text_outside

import navsim
from navsim.foundations.config import load_yaml
from navsim.report.summary import pct
from navsim.report.tables import FAIL, PASS, PNG_DPI
from navsim.scoring.scorer import NORM_QUANTITIES
from navsim.scoring.verdicts import num

matplotlib.use("Agg")

#: the shipped scenarios whose reports the default suite draws: one of each family of pages
#: (P0's, P2's height with its drift page, P3's, P4's attitude; the wind's drift and consistency
#: pages at their sizes in test_pages_written.py, from synthetic histories)
REPORTED = ("p0_bd_sins_ads", "p2_sea_height", "p3_sins_gps", "p4_static")
#: the other shipped scenarios with estimators, in the slow suite (2-45 s each, a closed loop's
#: flight the longest)
REPORTED_SLOW = ("p0_matched_ads", "p0_two_step", "p0_wind", "p0_wind_dead_reckoning", "p0_wind_gust_front",
                 "p0_wind_veering",
                 "p1_emi_powerline", "p1_federated", "p1_gnss_denied_landmarks", "p1_mag_calibration",
                 "p1_return_to_land", "p1_return_to_land_wind", "p4_circle", "p4_divergence", "p4_three_resets",
                 "p4_octo_circle", "p4_octo_divergence", "p4_octo_three_resets", "octo25_return_home")


def test_every_shipped_scenario_with_estimators_has_its_report_drawn(shipped_scenarios):
    """A scenario added to scenarios/ has its report drawn here (the flights-only ones have
    their pages written by ``navsim fly`` and ``navsim sensors``, test_cli.py)."""
    with_estimators = {p.stem for p in shipped_scenarios if load_yaml(p).get("estimators")}
    assert with_estimators == set(REPORTED) | set(REPORTED_SLOW)


#: the flights a report is drawn from cut short, s (the pages, not the statistics): P4's 360 s
#: parked test to 150 s past its 60 s settling (its CPF-EKF's epochs, in numpy, cost 8 s more)
CUT_S = {"p4_static": 150.0}


@pytest.fixture(scope="module", params=[*REPORTED, *(pytest.param(n, marks=pytest.mark.slow) for n in REPORTED_SLOW)])
def report(request, repo_root, shipped_flight, tmp_path_factory):
    scenario, truth, path = shipped_flight(request.param)
    if request.param in CUT_S:
        truth = truth.slice(0, int(round(CUT_S[request.param] / truth.dt_s)) + 1)
    out = tmp_path_factory.mktemp(request.param) / "run"
    result = navsim.run(scenario, runs=1, seed=1, workers=1, out=out,       # the pages, not the statistics
                        flight=(truth, path, True))
    pages = navsim.report_figures(result)
    yield request.param, result, pages
    for page in pages:
        plt.close(page.figure)


def test_every_page_written_as_a_png_and_the_verdicts_on_the_first(report, tmp_path):
    """Every page written (the suite's checker, tests/conftest.py, measures each as the PDF and
    the PNGs draw it: no text outside its page, no tick labels printed over each other)."""
    name, result, pages = report
    files = navsim.write_report(result, tmp_path / name)
    pngs = sorted(p.stem for p in files if p.suffix == ".png")
    assert pages and pngs == sorted(page.name for page in pages) and all(p.stat().st_size > 20_000 for p in files)
    first = next(page.figure for page in pages if page.name == "summary")
    # one verdict a check: "pass", "FAIL" (a single run's with its percentile or share), "undecided ..."
    texts = [t for t in first.findobj(Text) if t.get_text().split(" ")[0] in ("pass", "FAIL", "undecided")]
    headed = any("Paper against ours" in t.get_text() for t in first.findobj(Text))
    if result.scenario.reference is None:                   # no paper numbers: no block
        assert not texts and not headed and result.metrics.paper_checks is None
        return
    assert len(texts) == len(result.metrics.paper_checks) > 0 and headed
    marked = [t for t in texts if not t.get_text().startswith("undecided")]
    assert all(matplotlib.colors.to_hex(t.get_color()) == (PASS if t.get_text().startswith("pass") else FAIL)
               for t in marked)


def test_the_replay_summary_page_fits(repo_root, tmp_path, capsys):
    """``navsim replay``'s summary page, typeset from its metrics.json, keeps its text inside;
    the file reads back (:class:`~navsim.replay.metrics.ReplayMetrics`) to the same mapping,
    its keys those of the replay, and the command prints the differences and the cost."""
    import json

    from navsim.cli import main
    from navsim.foundations.outputs import strict_json
    from navsim.replay.metrics import ReplayMetrics
    from navsim.report.replay import summary_blocks
    from navsim.report.tables import layout
    assert main(["replay", str(repo_root / "tests" / "data" / "px4_quad_real_69s.ulg.gz"), "--out",
                 str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out
    assert "cpf_ekf against PX4's vehicle_attitude, after 10 s:" in out and "axis   RMS deg  95% deg  max deg" in out
    assert "68.9 s of log replayed" in out and "us per IMU cycle); wrote" in out
    text = (tmp_path / "r" / "metrics.json").read_text()
    m = ReplayMetrics.from_dict(json.loads(text))
    assert strict_json(m.to_dict()) == text
    assert list(json.loads(text)) == ["log", "estimator", "params", "imu_grid_hz", "period_s", "sensors", "alignment",
                                      "settle_s", "samples_scored", "record_s", "attitude_diff_deg", "resets", "cost",
                                      "wall_s", "provenance", "nis"]
    for fig in layout("navsim replay", summary_blocks(m, m.provenance)):
        fig.canvas.draw()
        assert not text_outside(fig, fig.canvas.get_renderer())
    assert (tmp_path / "r" / "replay.pdf").stat().st_size > 10_000


def test_estimators_at_different_periods_share_the_pages(repo_root, shipped_flight):
    """Each estimator records at its own period: P0 with the free SINS every 0.5 s beside the
    ES-KF's 1 s draws every page (the ranges and the split are taken on each one's epochs)."""
    from navsim.experiment.scenario import parse_scenario
    from navsim.foundations.config import load_yaml
    shipped_flight("p0_bd_sins_ads")                        # the flight cached
    raw = load_yaml(repo_root / "scenarios" / "p0_bd_sins_ads.yaml")
    raw["estimators"][0]["period_s"] = 0.5
    result = navsim.run(parse_scenario(raw, "p0.yaml"), runs=2, seed=1, workers=1)
    h = result.histories
    assert len(h["free SINS"].t_s) != len(h["BD/SINS/ADS ES-KF 16"].t_s)
    pages = navsim.report_figures(result)
    try:
        for page in pages:
            page.figure.set_dpi(PNG_DPI)
            page.figure.canvas.draw()
            assert not text_outside(page.figure, page.figure.canvas.get_renderer()), page.name
    finally:
        for page in pages:
            plt.close(page.figure)


# --- the numbers on the pages are metrics.json's ------------------------------------------------


def drawn(report):
    """``(scenario name, metrics.json as written, page name -> figure)`` of a report."""
    name, result, pages = report
    return name, json.loads((result.folder / "metrics.json").read_text()), {p.name: p.figure for p in pages}


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
        # a first cell wrapped onto lines of its own starts with its first line
        key = line[0] if line[0] in first else next(
            (k for k in first if k.startswith(line[0] + " ")), None)
        if key is not None:
            out[key] += line[1:]
    return dict(out)


def test_the_results_table_is_metrics_json(report):
    name, metrics, pages = drawn(report)
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


def test_the_consistency_panels_quote_metrics_json(report):
    name, metrics, pages = drawn(report)
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


def test_the_window_tables_are_metrics_json(report):
    name, metrics, pages = drawn(report)
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
            if q not in ("nees", "horizontal_m") and not (q == "yaw_deg" and "heading_deg" in qs)}   # summary.YAW_LEFT_OUT
    assert seen == want, name


def test_every_page_is_a4_numbered_and_in_the_contents(report):
    name, _, pages = drawn(report)
    sizes = {tuple(round(v, 2) for v in fig.get_size_inches()) for fig in pages.values()}
    assert sizes == {(8.27, 11.69)}, (name, sizes)
    feet = [[t.get_text() for t in fig.texts if re.search(r"page \d+ of \d+$", t.get_text())] for fig in pages.values()]
    assert [f[0].rsplit(" · ", 1)[1] if f else None for f in feet] == [
        f"page {i + 1} of {len(pages)}" for i in range(len(pages))], name
    contents = table_rows(lines(pages["contents"]), {str(i) for i in range(2, len(pages) + 1)})
    assert sorted(contents, key=int) == [str(i) for i in range(2, len(pages) + 1)], name
    hidden = [page for page, fig in pages.items() for ax in fig.axes if not ax.get_visible()]
    assert not hidden, f"{name}: an empty panel on {hidden}"
