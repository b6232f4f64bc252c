"""Wall time of the report of P0's 1000-run ``navsim run`` (issue 36's target: <= 2 s): the
result run once into a temporary folder (or ``--result`` an existing one), then
:func:`navsim.write_report` timed, best of ``--repeat``, with ``report.html`` and without it
(``report.formats: [pdf, png]``), alternated (issue 57: the page at most 1 s more, at most
25 MB), and the building of its pages apart (:func:`navsim.report_figures`: laid out, not drawn).

    python benchmarks/report_speed.py [--runs 1000] [--repeat 3] [--result FOLDER]
"""

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import navsim
from navsim.report.figures import pyplot

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
        size_mb = (Path(tmp) / "report03" / "report.html").stat().st_size / 1e6
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


if __name__ == "__main__":
    main()
