"""Wall time of ``navsim run`` end to end (report included, flight and kernels cached) of the
issue 56 cases, best of ``--repeat``: P0 at 1000 runs (target <= 8 s), ``p4_circle`` at 20 runs
(<= 6 s), ``p4_divergence`` at 20 runs (<= 10 s), each with its scenario's workers. With
``--baseline DIR`` (another checkout of navsim, e.g. ``git worktree add /tmp/old <commit>``) the
same runs of that checkout, alternated with this one's, side by side (its kernels compiled and
flights flown by a first, untimed run).

    python benchmarks/end_to_end.py [--repeat 2] [--baseline DIR] [--cases p0 p4_circle p4_divergence]
"""

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: name -> (scenario file, runs, target s)
CASES = {"p0": ("p0_bd_sins_ads.yaml", 1000, 8.0), "p4_circle": ("p4_circle.yaml", 20, 6.0),
         "p4_divergence": ("p4_divergence.yaml", 20, 10.0)}
#: runs ``navsim`` from the checkout ``sys.argv[1]``, not the installed (editable) one
FROM_CHECKOUT = ("import runpy, sys; root = sys.argv.pop(1); "
                 "sys.meta_path = [f for f in sys.meta_path if 'editable' not in str(f).lower()]; "
                 "sys.path.insert(0, root); sys.argv[0] = 'navsim'; runpy.run_module('navsim', run_name='__main__')")


def run(checkout: Path, scenario: str, runs: int, out: Path) -> float:
    cmd = [sys.executable, "-c", FROM_CHECKOUT, str(checkout), "run", str(checkout / "scenarios" / scenario),
           "--runs", str(runs), "--out", str(out)]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode:
        print(proc.stdout[-1500:], proc.stderr[-2000:])
        raise SystemExit(f"navsim run ({checkout}) exited {proc.returncode}")
    return wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--baseline", type=Path, help="another checkout of navsim, run side by side")
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES))
    args = parser.parse_args()
    checkouts = {"this checkout": ROOT} | ({f"baseline {args.baseline}": args.baseline.resolve()}
                                           if args.baseline else {})
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            scenario, runs, target = CASES[case]
            walls = {name: [] for name in checkouts}
            for name, where in checkouts.items():             # flights flown, kernels compiled
                run(where, scenario, runs, Path(tmp) / "out")
            for _ in range(args.repeat):
                for name, where in checkouts.items():
                    walls[name].append(run(where, scenario, runs, Path(tmp) / "out"))
            print(f"navsim run {scenario} --runs {runs} (target <= {target:g} s):")
            for name, w in walls.items():
                print(f"  {name:<40} best {min(w):6.2f} s of {len(w)} ({', '.join(f'{x:.2f}' for x in w)})")


if __name__ == "__main__":
    main()
