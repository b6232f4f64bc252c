"""Wall time of the report of P0's 1000-run ``navsim run`` (issue 36's target: <= 2 s): the
result run once into a temporary folder (or ``--result`` an existing one), then
:func:`navsim.write_report` timed, best of ``--repeat``, with ``report.html`` and without it
(``report.formats: [pdf, png]``), alternated (issue 57: the page at most 1 s more, at most
25 MB), and the building of its pages apart (:func:`navsim.report_figures`: laid out, not drawn).
Where Playwright and a Chromium are at hand (``pip install -e '.[browser]'``, Debian's
``chromium``), the page is opened headless: its load time, console errors, and the run picker
asked for the worst run, its drawn position error compared with the recorded one.

    python benchmarks/report_speed.py [--runs 1000] [--repeat 3] [--result FOLDER]
"""

import argparse
import dataclasses
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

import navsim
from navsim.api.results import _report_input
from navsim.report.figures import pyplot
from navsim.report.picker import rankings

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--result", help="an existing result folder of p0_bd_sins_ads (default: run it)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.result
        if folder is None:
            folder = Path(tmp) / "p0"
            navsim.run(ROOT / "scenarios" / "p0_bd_sins_ads.yaml", args.runs, workers=2, out=folder)
        result = navsim.open_result(folder)
        walls = {"with report.html": [], "without": []}
        for i in range(args.repeat):
            for how, formats in (("with report.html", ["pdf", "png", "html"]), ("without", ["pdf", "png"])):
                result.scenario = dataclasses.replace(result.scenario, report={**result.scenario.report,
                                                                               "formats": formats})
                t0 = time.perf_counter()
                navsim.write_report(result, Path(tmp) / f"report{i}{len(formats)}", force=True)
                walls[how].append(time.perf_counter() - t0)
        page = Path(tmp) / "report03" / "report.html"
        size_mb = page.stat().st_size / 1e6
        opened = in_browser(page, result)
        builds = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            pages = navsim.report_figures(result)
            builds.append(time.perf_counter() - t0)
            for p in pages:
                pyplot().close(p.figure)
    for how, w in walls.items():
        print(f"report of p0_bd_sins_ads, {len(result.runs)} runs, {how}: best {min(w):.2f} s of {args.repeat} "
              f"({', '.join(f'{x:.2f}' for x in w)})")
    extra = min(walls["with report.html"]) - min(walls["without"])
    print(f"report.html: {size_mb:.1f} MB (target <= 25 MB), {extra:+.2f} s on the report's best time (target <= 1 s)")
    print(f"of which building its {len(pages)} pages (laid out, not drawn): best {min(builds):.2f} s")
    print(opened)


def in_browser(page: Path, result) -> str:
    """The page opened in headless Chromium: load time, console errors, the worst run picked
    and its drawn north position error against the recorded one."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        return "headless Chromium: not checked (pip install -e '.[browser]')"
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        return "headless Chromium: not checked (no chromium)"
    label = next(k for k, h in result.histories.items() if h.sigma is not None)
    groups = rankings(_report_input(result))
    row, text = groups[next(g for g in groups if g.startswith(f"{label}: worst"))][0]
    index = list(result.histories).index(label)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        tab, errors = browser.new_page(viewport={"width": 1400, "height": 1000}), []
        tab.on("console", lambda m: errors.append(m.text) if m.type in ("error", "warning") else None)
        tab.on("pageerror", lambda e: errors.append(str(e)))
        t0 = time.perf_counter()
        tab.goto(page.as_uri())
        tab.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0 && "
                              "Bokeh.documents[0].get_model_by_name('run_select') !== null")
        load_s = time.perf_counter() - t0
        tab.get_by_text("Run picker", exact=True).first.click()
        tab.locator("select").first.select_option(label=text)
        drawn = tab.evaluate(f"() => Array.from(Bokeh.documents[0].get_model_by_name('run_pos_{index}_0')"
                             ".data.ys[0], y => Number.isNaN(y) ? null : y)")
        browser.close()
    err = np.array([np.nan if v is None else v for v in drawn], float)
    recorded = result.histories[label].pos_err_m[row, :, 0].astype(float)
    return (f"headless Chromium: loaded in {load_s:.2f} s, {len(errors)} console errors; picked '{text}': its north "
            f"error drawn within {np.nanmax(np.abs(err - recorded)):.2g} m of the recorded "
            f"(largest {np.nanmax(np.abs(recorded)):.3g} m)")


if __name__ == "__main__":
    main()
