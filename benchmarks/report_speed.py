"""Wall time of the report of P0's 1000-run ``navsim run`` (issue 36's target: <= 2 s): the
result run once into a temporary folder (or ``--result`` an existing one), then
:func:`navsim.write_report` timed, best of ``--repeat``, and the building of its pages apart
(:func:`navsim.report_figures`: laid out, not drawn).

    python benchmarks/report_speed.py [--runs 1000] [--repeat 3] [--result FOLDER]
"""

import argparse
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
        walls = []
        for i in range(args.repeat):
            t0 = time.perf_counter()
            navsim.write_report(result, Path(tmp) / f"report{i}", force=True)
            walls.append(time.perf_counter() - t0)
        builds = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            pages = navsim.report_figures(result)
            builds.append(time.perf_counter() - t0)
            for p in pages:
                pyplot().close(p.figure)
    print(f"report of p0_bd_sins_ads, {len(result.runs)} runs: best {min(walls):.2f} s of {args.repeat} "
          f"({', '.join(f'{w:.2f}' for w in walls)}) (target <= 2 s)")
    print(f"of which building its {len(pages)} pages (laid out, not drawn): best {min(builds):.2f} s")


if __name__ == "__main__":
    main()
