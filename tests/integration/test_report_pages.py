"""Every page of the P0, P2 and P4 reports drawn as its PNG is (at the PNGs' resolution): no text
lies outside its figure, no two tick labels of an axis overprint, and the first page carries the
paper checks with their verdicts (the pages, not the numbers, are checked here: one run of
each)."""

import matplotlib
import matplotlib.pyplot as plt
import pytest
from matplotlib.text import Text

import navsim
from navsim.report.tables import FAIL, PASS, PNG_DPI

matplotlib.use("Agg")

#: pixels a text may stand over the figure's edge (antialiasing)
EDGE_PX = 1.0


def _axes(ax):
    return [a for a in (ax.xaxis, ax.yaxis, getattr(ax, "zaxis", None)) if a is not None]


def drawn_tick_labels(axis) -> list:
    """The tick labels ``axis`` draws: those of ticks inside its view interval (matplotlib keeps
    labels for ticks beyond it, which are not drawn)."""
    lo, hi = sorted(axis.get_view_interval())
    pad = 1e-9 * max(abs(hi - lo), 1e-300)
    return [lab for tick in axis.get_major_ticks() + axis.get_minor_ticks() if lo - pad <= tick.get_loc() <= hi + pad
            for lab in (tick.label1, tick.label2) if lab.get_visible() and lab.get_text().strip()]


def text_outside(fig, renderer) -> list[str]:
    """The visible texts of ``fig`` that are drawn and whose extent leaves the figure."""
    W, H = fig.bbox.width, fig.bbox.height
    ticks = {id(t) for ax in fig.axes for a in _axes(ax) for tick in a.get_major_ticks() + a.get_minor_ticks()
             for t in (tick.label1, tick.label2)}
    drawn = {id(t) for ax in fig.axes for a in _axes(ax) for t in drawn_tick_labels(a)}
    out = []
    hidden = {id(t) for ax in fig.axes if not ax.get_visible() for t in ax.findobj(Text)}
    for t in fig.findobj(Text):
        if (not t.get_visible() or not t.get_text().strip() or id(t) in hidden
                or (id(t) in ticks and id(t) not in drawn)):
            continue
        e = t.get_window_extent(renderer)
        if e.x0 < -EDGE_PX or e.y0 < -EDGE_PX or e.x1 > W + EDGE_PX or e.y1 > H + EDGE_PX:
            out.append(f"{t.get_text()!r} at x {e.x0:.0f}-{e.x1:.0f}, y {e.y0:.0f}-{e.y1:.0f} of {W:.0f}x{H:.0f}")
    return out


def overprinted_ticks(fig, renderer) -> list[str]:
    """Pairs of drawn tick labels of one axis whose extents overlap."""
    out = []
    for ax in fig.axes:
        for axis in _axes(ax):
            boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in drawn_tick_labels(axis)]
            for i in range(len(boxes)):
                for j in range(i + 1, len(boxes)):
                    (a, ba), (b, bb) = boxes[i], boxes[j]
                    if ba.overlaps(bb) and min(ba.width, bb.width) > 0:
                        out.append(f"{ax.get_title() or ax.get_ylabel()!r}: {a!r} and {b!r}")
    return out


#: P1's landmark, calibration and closed-loop pages too, in the slow suite
SLOW = pytest.mark.slow


@pytest.fixture(scope="module", params=["p0_bd_sins_ads", "p2_sea_height", "p4_static",
                                        pytest.param("p1_gnss_denied_landmarks", marks=SLOW),
                                        pytest.param("p1_mag_calibration", marks=SLOW),
                                        pytest.param("p1_return_to_land", marks=SLOW)])
def report(request, repo_root, shipped_flight):
    scenario, _, _ = shipped_flight(request.param)
    result = navsim.run(scenario, runs=1, seed=1, workers=1)      # the pages, not the statistics
    pages = navsim.report_figures(result)
    yield request.param, result, pages
    for page in pages:
        plt.close(page.figure)


def test_no_text_outside_its_page_and_no_tick_labels_overprinted(report):
    name, _, pages = report
    assert pages, f"{name}: no pages"
    problems = []
    for page in pages:
        fig = page.figure
        fig.set_dpi(PNG_DPI)
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        problems += [f"{name}/{page.name}: outside: {p}" for p in text_outside(fig, renderer)]
        problems += [f"{name}/{page.name}: overprinted: {p}" for p in overprinted_ticks(fig, renderer)]
    assert not problems, "\n".join(problems)


def test_every_page_written_as_a_png_and_the_verdicts_on_the_first(report, tmp_path):
    name, result, pages = report
    files = navsim.write_report(result, tmp_path / name)
    pngs = sorted(p.stem for p in files if p.suffix == ".png")
    assert pages and pngs == sorted(page.name for page in pages) and all(p.stat().st_size > 20_000 for p in files)
    first = next(page.figure for page in pages if page.name == "summary")
    texts = [t for t in first.findobj(Text) if t.get_text() in ("pass", "FAIL")]
    headed = any("Paper against ours" in t.get_text() for t in first.findobj(Text))
    if result.scenario.reference is None:                   # no paper numbers: no block
        assert not texts and not headed and result.metrics.paper_checks is None
        return
    assert len(texts) == len(result.metrics.paper_checks) > 0 and headed
    assert all(matplotlib.colors.to_hex(t.get_color()) == (PASS if t.get_text() == "pass" else FAIL) for t in texts)


def test_the_replay_summary_page_fits(repo_root, tmp_path):
    """``navsim replay``'s summary page, typeset from its metrics.json, keeps its text inside."""
    import json

    from navsim.cli import main
    from navsim.report.replay import summary_blocks
    from navsim.report.tables import layout
    assert main(["replay", str(repo_root / "tests" / "data" / "px4_quad_real_69s.ulg.gz"), "--out",
                 str(tmp_path / "r")]) == 0
    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    for fig in layout("navsim replay", summary_blocks(m, m["provenance"])):
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
