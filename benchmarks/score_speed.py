"""Cost of scoring (navsim.scoring.scorer), the one scorer: the histories of R runs held in memory
(one chunk, :func:`score`) and the same runs as chunks of 250 (:func:`score_run`, what a
streamed ``navsim run`` does), on histories shaped as P0's ES-KF (501 epochs, a covariance, two
NIS streams, two windows), one core.

    python benchmarks/score_speed.py [--runs 1000] [--repeat 3]

Prints the best wall time of ``--repeat`` for each.
"""

import argparse
import time

import numpy as np

from navsim.records.chunk import ChunkPart
from navsim.records.history import EstimatorHistory
from navsim.scoring.scorer import score, score_run

EPOCHS = 501
WINDOWS = (("outage", 200.0, 260.0), ("late", 400.0, 500.0))


def history(rng, runs: int) -> EstimatorHistory:
    """A P0-shaped history of ``runs`` runs with random errors (the scorer's cost does not depend
    on the values)."""
    err = lambda s: rng.normal(scale=s, size=(runs, EPOCHS, 3))
    nis = {"gnss:bd": rng.chisquare(3, size=(runs, EPOCHS)), "airdata:ads": rng.chisquare(1, size=(runs, EPOCHS))}
    return EstimatorHistory("ES-KF", np.arange(EPOCHS, dtype=float), err(1e-3), err(0.1), err(2.0),
                            np.abs(rng.normal(size=(runs, EPOCHS, 9))), rng.chisquare(9, size=(runs, EPOCHS)),
                            nis, {"gnss:bd": 3, "airdata:ads": 1}, np.zeros(runs, bool),
                            cost={"propagate_s": 1.0, "epoch_s": 1.0, "runs": runs, "epochs": EPOCHS, "batches": 1})


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    whole = history(rng, args.runs)
    parts = [ChunkPart(list(range(a, min(a + 250, args.runs))), {"ES-KF": history(rng, min(250, args.runs - a))})
             for a in range(0, args.runs, 250)]
    one = best(lambda: score(whole, 10.0, WINDOWS), args.repeat)
    chunked = best(lambda: score_run(lambda: iter(parts), 10.0, WINDOWS), args.repeat)
    print(f"{args.runs} runs x {EPOCHS} epochs, one estimator, best of {args.repeat}:")
    print(f"  in memory (one chunk)  {one:6.2f} s  ({one / args.runs * 1e3:.2f} ms per run)")
    print(f"  chunks of 250          {chunked:6.2f} s  ({chunked / args.runs * 1e3:.2f} ms per run)")


if __name__ == "__main__":
    main()
