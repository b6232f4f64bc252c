"""report.html in a real browser (headless Chromium driven by Playwright): it opens from the disk
with no console error, the run picker draws the chosen run's position error and ±3σ (read back
from the page's Bokeh document), no text runs out of its box, and hostile input (quotes and
``</script>`` in labels, NaN records, a diverged run, a result folder of an older navsim) still
gives a page that opens, its text shown as written.

Marked ``browser``: skipped where Playwright or Chromium is missing, unless
``NAVSIM_REQUIRE_BROWSER=1`` (``.ci/run``, which installs both), where that fails instead.
``NAVSIM_SCREENSHOTS=DIR`` keeps a screenshot of every tab there, to be looked at."""

import dataclasses
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

import navsim
from navsim.api.results import _report_input
from navsim.cli import main
from navsim.scoring.budget import DEFAULT_METRICS
from navsim.report import html, picker

pytestmark = pytest.mark.browser

#: JavaScript: every element, inside Bokeh's shadow roots too, whose text runs out of its box:
#: content wider or taller than the element where its overflow is drawn, or cut by it (a table's
#: cell or header narrower than its text)
OVERFLOWING_JS = """() => {
  const out = [], todo = [document.documentElement];
  while (todo.length) {
    const el = todo.pop();
    if (el.shadowRoot) todo.push(...el.shadowRoot.children);
    todo.push(...el.children);
    if (!el.offsetParent || !el.textContent.trim() || el.children.length) continue;
    const visible = getComputedStyle(el).overflow === 'visible';
    const cell = /slick-cell|slick-column-name/.test(el.className);
    if (!visible && !cell) continue;
    if (el.scrollWidth > el.clientWidth + 2 || (visible && el.scrollHeight > el.clientHeight + 2))
      out.push(el.tagName + ' ' + el.className + ': ' + el.textContent.trim().slice(0, 60));
  }
  return out;
}"""


def _missing(what: str):
    if os.environ.get("NAVSIM_REQUIRE_BROWSER") == "1":
        pytest.fail(f"{what} is missing (NAVSIM_REQUIRE_BROWSER=1)")
    pytest.skip(f"{what} is missing: pip install -e '.[browser]' and Debian's chromium")


@pytest.fixture(scope="module")
def browser():
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _missing("playwright")
    chromium = os.environ.get("NAVSIM_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        _missing("chromium")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        yield b
        b.close()


class Page:
    """A report page open in the browser, its console errors and page errors kept."""

    def __init__(self, browser, path: Path):
        self.page = browser.new_page(viewport={"width": 1400, "height": 1000})
        self.errors = []
        self.page.on("console", lambda m: self.errors.append(f"console {m.type}: {m.text}")
                     if m.type in ("error", "warning") else None)
        self.page.on("pageerror", lambda e: self.errors.append(f"page error: {e}"))
        self.page.on("dialog", lambda d: (self.errors.append(f"dialog: {d.message}"), d.dismiss()))
        self.page.goto(path.resolve().as_uri())
        self.page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0 && "
                                    "Bokeh.documents[0].get_model_by_name('run_select') !== null")
        self.page.wait_for_timeout(300)

    def tab(self, name: str) -> None:
        self.page.get_by_text(name, exact=True).first.click()
        self.page.wait_for_timeout(300)
        shots = os.environ.get("NAVSIM_SCREENSHOTS")
        if shots:
            Path(shots).mkdir(parents=True, exist_ok=True)
            self.page.screenshot(path=str(Path(shots) / f"{self.page.title()[:40]}_{name}.png".replace(" ", "_")))

    def data(self, name: str) -> dict:
        """A named ColumnDataSource's data, typed arrays as lists (NaN as None)."""
        return self.page.evaluate("""(name) => {
          const d = Bokeh.documents[0].get_model_by_name(name).data, out = {};
          for (const [k, v] of Object.entries(d))
            out[k] = Array.from(v, x => (x && x.length !== undefined && typeof x !== 'string')
                                         ? Array.from(x, y => Number.isNaN(y) ? null : y) : x);
          return out;
        }""", name)

    def pick(self, text: str) -> None:
        """Choose the run picker's option ``text`` in its <select>, as a user does."""
        self.page.locator("select").first.select_option(label=text)
        self.page.wait_for_timeout(200)

    def close(self) -> None:
        self.page.close()


@pytest.fixture(scope="module")
def p0_folder(repo_root, shipped_flight, tmp_path_factory):
    """P0, 8 runs, written with its report (report.html among them)."""
    shipped_flight("p0_bd_sins_ads")
    out = tmp_path_factory.mktemp("p0html") / "p0"
    navsim.write_report(navsim.run(repo_root / "scenarios" / "p0_bd_sins_ads.yaml", runs=8, workers=2, out=out))
    return out


def _as_array(values: list) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], float)


def test_the_page_opens_and_the_picker_draws_the_chosen_run(browser, p0_folder):
    assert (p0_folder / "report.html").is_file()
    page = Page(browser, p0_folder / "report.html")
    try:
        for tab in ("Summary", "Flight", "Errors", "Consistency", "Run picker"):
            page.tab(tab)
            assert page.page.evaluate(OVERFLOWING_JS) == [], tab
        result = navsim.open_result(p0_folder)
        inp = _report_input(result)
        groups = picker.rankings(inp)
        name = next(g for g in groups if g.startswith("BD/SINS/ADS ES-KF 16: worst") and "final" in g)
        row, text = groups[name][1]                                # the second worst
        page.pick(text)
        h = result.histories["BD/SINS/ADS ES-KF 16"]
        keys = picker.quantities(result.histories)
        assert keys == ("pos", "att", "vel")                       # 8 runs: every error held
        traces = picker.run_traces(h, keys)
        expected = picker.decoded(traces, row)
        for j in range(3):
            drawn = page.data(f"run_pos_1_{j}")
            t, err, plus, minus = (_as_array(v) for v in (drawn["xs"][0], *drawn["ys"]))
            np.testing.assert_array_equal(t, expected["t"])
            np.testing.assert_array_equal(err, expected[f"e{j}"])           # as Python decodes it, to the bit
            np.testing.assert_array_equal(plus, expected[f"p{j}"])
            np.testing.assert_array_equal(minus, -plus)
            recorded = h.pos_err_m[row, :, j].astype(float)
            assert np.max(np.abs(err - recorded)) <= 1e-4 * np.max(np.abs(recorded))
            sigma = h.sigma[row][:, 6 + j].astype(float)
            assert np.max(np.abs(plus - 3 * sigma)) <= 1e-4 * np.max(3 * sigma)
            att = _as_array(page.data(f"run_att_1_{j}")["ys"][0])                # the attitude held too
            np.testing.assert_array_equal(att, picker.decoded(traces, row, 1)[f"e{j}"])
            recorded = np.degrees(h.att_err_rad[row, :, j].astype(float))
            assert np.max(np.abs(att - recorded)) <= 1e-4 * np.max(np.abs(recorded))
        info = page.page.evaluate("() => Bokeh.documents[0].get_model_by_name('run_info').text")
        assert info.startswith(f"Run {text.split(':')[0].split()[1]}: "), info
        assert page.errors == []
    finally:
        page.close()


def _hostile(result):
    """``result`` with a label of quotes and ``</script>``, a description and window name with
    tags, a run's records partly NaN and another run diverged."""
    nasty = 'ES-KF "q" </script><img src=x onerror="window.pwned=1">'
    rename = lambda k: nasty if k.startswith("BD") else k
    hist = {}
    for k, h in result.histories.items():
        h = dataclasses.replace(h, label=rename(k), pos_err_m=h.pos_err_m.copy(), diverged=h.diverged.copy(),
                                divergence=[None] * len(h.diverged))
        h.pos_err_m[0, 100:140] = np.nan
        h.diverged[1] = True
        h.divergence[1] = (250.0, 'NEES > 1e6 "<b>"')
        hist[rename(k)] = h
    metrics = dataclasses.replace(result.metrics,
                                  estimators={rename(k): v for k, v in result.metrics.estimators.items()})
    scenario = dataclasses.replace(result.scenario, description='<img src=x onerror="window.pwned=2"> & <b>bold</b>',
                                   windows=tuple(("<i>w</i>" if i == 0 else w[0], *w[1:])
                                                 for i, w in enumerate(result.scenario.windows)))
    return dataclasses.replace(result, histories=hist, metrics=metrics, scenario=scenario), nasty


def test_hostile_input_gives_a_page_that_opens_with_its_text_as_written(browser, p0_folder, tmp_path):
    result, nasty = _hostile(navsim.open_result(p0_folder))
    path = tmp_path / "report.html"
    html.write_html(path, _report_input(result))
    page = Page(browser, path)
    try:
        page.tab("Summary")
        shown = page.page.get_by_text('<img src=x onerror="window.pwned=2"> & <b>bold</b>', exact=False)
        assert shown.count() == 1 and shown.is_visible()                 # shown as written, not run
        page.tab("Run picker")
        groups = picker.rankings(_report_input(result))
        diverged = next(g for g in groups if g.startswith(nasty) and "diverged" in g)
        page.pick(groups[diverged][0][1])
        events = page.data("run_event_table")
        assert events["event"] == ['diverged: NEES > 1e6 "<b>"'] * 2 and events["t"] == ["250.00"] * 2
        assert sorted(events["estimator"]) == sorted(result.histories)          # each estimator's flag
        page.pick(next(text for r, text in groups["every run"] if r == 0))
        err = _as_array(page.data("run_pos_0_0")["ys"][0])
        assert np.isnan(err).any() and np.isfinite(err).sum() > 100     # a gap, the rest drawn
        for tab in ("Summary", "Flight", "Errors", "Consistency", "Run picker"):     # every text shown
            page.tab(tab)
        assert page.page.evaluate("() => window.pwned === undefined")   # no handler of ours ran
        assert page.errors == []                      # no <img> of theirs made (its src would fail to load)
    finally:
        page.close()


def test_a_result_of_an_older_navsim_gets_a_page_that_opens(browser, p0_folder, tmp_path):
    """No per-run samples, no plotted-runs count in its record, an older version: rewritten
    with :func:`navsim.write_report`, its page opens."""
    old = tmp_path / "old"
    shutil.copytree(p0_folder, old)
    (old / "samples.npz").unlink()
    (old / "report.html").unlink()
    record = json.loads((old / "run.json").read_text())
    record.pop("runs_plotted", None)
    (old / "run.json").write_text(json.dumps({**record, "versions": {**record["versions"], "navsim": "0.1.0"}}))
    files = navsim.write_report(navsim.open_result(old))
    assert old / "report.html" in files
    page = Page(browser, old / "report.html")
    try:
        page.tab("Run picker")
        assert page.errors == []
    finally:
        page.close()


def test_the_overflow_check_finds_text_out_of_its_box(browser, tmp_path):
    """The check the pages pass finds a text wider than its box, in a shadow root too."""
    path = tmp_path / "over.html"
    path.write_text("<html><body><div style='width:40px'>a_text_far_wider_than_forty_pixels</div>"
                    "<div id='host'></div><script>const r = document.getElementById('host').attachShadow({mode:"
                    "'open'}); r.innerHTML = \"<p style='width:30px;white-space:nowrap'>inside a shadow root</p>\";"
                    "</script><div class='slick-cell' style='width:30px;overflow:hidden;white-space:nowrap'>"
                    "a table cell cut short</div></body></html>")
    page = browser.new_page()
    try:
        page.goto(path.as_uri())
        found = page.evaluate(OVERFLOWING_JS)
        assert any("far_wider" in f for f in found) and any("shadow root" in f for f in found), found
        assert any("cut short" in f for f in found), found
    finally:
        page.close()


def _open_page(browser, path: Path):
    """A results page (compare, budget, sweep, tune) open in the browser, its errors kept."""
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    errors = []
    page.on("console", lambda m: errors.append(f"console {m.type}: {m.text}") if m.type in ("error", "warning") else None)
    page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
    page.goto(path.resolve().as_uri())
    page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0")
    page.wait_for_timeout(300)
    return page, errors


def test_compare_budget_sweep_and_tune_pages_open_with_their_tables_and_plots(browser, p0_folder, repo_root,
                                                                             tmp_path):
    """Each command's page: no console error, its tables hold the rows its CSV holds, its plots
    drawn (a renderer with data), no text out of its box on either tab."""
    shutil.copy(repo_root / "scenarios" / "p0_bd_sins_ads.yaml", tmp_path / "p0.yaml")
    (tmp_path / "sweep.yaml").write_text("scenario: p0.yaml\nruns: 2\ngrid:\n  montecarlo.seed: [1, 2]\n"
                                         "metric: rms.pos_m\n")
    p0 = str(repo_root / "scenarios" / "p0_bd_sins_ads.yaml")
    runs = {"compare": ["compare", str(p0_folder), "--estimators", "free SINS", "BD/SINS/ADS ES-KF 16"],
            "budget": ["budget", p0, "--method", "covariance"],
            "sweep": ["sweep", str(tmp_path / "sweep.yaml")],
            "tune": ["tune", p0, "--estimator", "BD/SINS/ADS ES-KF 16", "--trials", "3", "--runs", "2",
                     "--check-runs", "2"]}
    for name, args in runs.items():
        out = tmp_path / name
        assert main(args + ["--out", str(out)]) == 0, name
        csv = [line.split(",") for line in (out / f"{name}.csv").read_text().splitlines()[1:]]
        if name == "budget":               # the page's metrics are the PDF's: DEFAULT_METRICS
            csv = [r for r in csv if (r[1], r[2]) in DEFAULT_METRICS]
        csv_rows = len(csv)
        page, errors = _open_page(browser, out / f"{name}.html")
        try:
            shown = page.evaluate("""() => {
              let rows = 0, drawn = 0;
              for (const m of Bokeh.documents[0].all_models) {
                if (m.type === 'DataTable') rows += m.source.get_length();
                if (m.type === 'GlyphRenderer' && m.data_source.get_length() > 0) drawn += 1;
              }
              return [rows, drawn];
            }""")
            left_out = 0                       # a covariance budget lists the Monte-Carlo-only sources too
            if name == "budget":
                tables = {(r[0], r[1], r[2]) for r in csv}
                left_out = len(json.loads((out / "budget.json").read_text())["monte_carlo_only"]) * len(tables)
            assert shown[1] >= 1 and shown[0] == csv_rows + left_out, (name, shown, csv_rows)
            for tab in ("Tables", "Plots"):
                page.get_by_text(tab, exact=True).first.click()
                page.wait_for_timeout(200)
                assert page.evaluate(OVERFLOWING_JS) == [], (name, tab)
            assert errors == [], name
        finally:
            page.close()
