"""The same seed gives the same numbers, bit for bit, however the runs are chunked and on
however many workers (issue 50): every sum over runs is taken in run order, each run's part of
it computed alone, so that neither the chunk a run lands in nor the memory layout numpy's
reductions follow changes a bit of ``metrics.json``."""

import json

import numpy as np
import pytest

import navsim
from navsim.scoring.intervals import WeightedSums, bootstrap_weights
from navsim.scoring.stats import Moments, RunSums, Sum

SCENARIO = """
name: determinism
track:
  start: {lat_deg: 37.0, lon_deg: 118.0, alt_m: 300, speed_mps: 14, heading_deg: 30}
  segments:
    - {type: straight, time_s: 8}
sensors:
  imu: {model: p3_imu}
  gps: {model: p3_gps}
estimators:
  - {label: free SINS, type: sins}
  - label: KF
    type: eskf
    states: p3_15
    noise: {imu: p3_imu}
    measurements:
      - {type: gnss_position, sensor: gps, sigma_m: [2, 2, 1]}
initial_errors: {pos_m: [5, 5, 3], vel_mps: [0.2, 0.2, 0.1], att_arcsec: 60}
montecarlo: {runs: 5, seed: 4, workers: 1}
metrics:
  settle_s: 1
  windows:
    - {name: middle, start_s: 2, end_s: 6}
"""

#: the metrics that are timings: they differ from one run to the next
TIMED = ("wall_s", "cost")


def untimed(tree):
    """A metrics tree without its timings."""
    if isinstance(tree, dict):
        return {k: untimed(v) for k, v in tree.items() if k not in TIMED}
    if isinstance(tree, list):
        return [untimed(v) for v in tree]
    return tree


def differences(a, b, path=""):
    """The paths where two metrics trees differ in any bit (NaN equal to NaN)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b)) for d in differences(a.get(k), b.get(k), f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}[{i}]")]
    same = a == b or (isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b))
    return [] if same and type(a) is type(b) else [f"{path}: {a!r} != {b!r}"]


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    root = tmp_path_factory.mktemp("determinism")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NAVSIM_CACHE", str(root / "cache"))
        path = root / "determinism.yaml"
        path.write_text(SCENARIO)
        yield path


def metrics_of(scenario, out, workers, chunk_runs):
    """The metrics of the scenario's 5 runs (seed 4) chunked by ``chunk_runs`` on ``workers``,
    as ``metrics.json`` holds them, without their timings; and the runs' samples."""
    result = navsim.run(scenario, out=out, workers=workers, chunk_runs=chunk_runs)
    with np.load(out / "samples.npz", allow_pickle=False) as data:
        samples = {k: data[k] for k in data.files}
    assert result.metrics.runs_done == 5
    return untimed(json.loads((out / "metrics.json").read_text())), samples


def assert_same(a, b, what):
    (ma, sa), (mb, sb) = a, b
    found = differences(ma, mb)
    assert not found, f"{what}: {len(found)} metrics differ:\n" + "\n".join(found[:30])
    assert list(sa) == list(sb)
    for k in sa:
        assert np.array_equal(sa[k], sb[k], equal_nan=sa[k].dtype.kind == "f"), f"{what}: samples.npz {k}"


def test_metrics_do_not_depend_on_the_chunking(scenario, tmp_path):
    """One worker: chunks of 1, 2 and all 5 runs give the same metrics.json, bit for bit."""
    whole = metrics_of(scenario, tmp_path / "all", 1, 5)
    for chunk_runs in (1, 2):
        assert_same(whole, metrics_of(scenario, tmp_path / f"c{chunk_runs}", 1, chunk_runs), f"chunk_runs {chunk_runs}")


def test_metrics_do_not_depend_on_workers_and_chunking(scenario, tmp_path):
    """Two workers, chunks of 1, 2 and all runs, against one worker and one chunk."""
    whole = metrics_of(scenario, tmp_path / "w1", 1, 5)
    for chunk_runs in (1, 2, 5):
        got = metrics_of(scenario, tmp_path / f"w2c{chunk_runs}", 2, chunk_runs)
        assert_same(whole, got, f"2 workers, chunk_runs {chunk_runs}")


def chunked(x, sizes):
    """``x`` (runs first) in pieces of ``sizes`` runs, each piece laid out as a boolean index of
    its epochs leaves it (not C-contiguous: numpy's reductions follow the layout)."""
    pieces, at = [], 0
    for n in sizes:
        padded = np.concatenate([x[at:at + n], np.zeros((n, 1) + x.shape[2:])], axis=1)
        keep = np.ones(padded.shape[1], bool)
        keep[-1] = False
        pieces.append(padded[:, keep])
        at += n
    return pieces


#: pieces of 150 runs: more than two of the bootstrap's blocks (BOOTSTRAP_BLOCK_RUNS)
CHUNKINGS = ([150], [1] * 150, [2] * 75, [5, 11, 1, 20, 64, 49], [149, 1], [64, 64, 22], [63, 2, 85])


@pytest.mark.parametrize("shape", [(150, 1001), (150, 301, 3)])
def test_sums_over_runs_do_not_depend_on_the_pieces(shape):
    """Sum, Moments, RunSums and the bootstrap's WeightedSums fed the same runs in other pieces
    (with NaN, values over decades) give the same bits."""
    rng = np.random.default_rng(50)
    x = rng.normal(size=shape) * 10.0 ** rng.uniform(-3, 3, size=shape)
    x[rng.random(shape) < 0.02] = np.nan
    found = {}
    for sizes in CHUNKINGS:
        total, per_epoch, moments, per_run, boot = Sum(), Sum(), Moments(), RunSums(len(shape) - 2), WeightedSums()
        at = 0
        for piece, n in zip(chunked(x, sizes), sizes):
            total.add(piece, (0, 1))
            per_epoch.add(piece, 0)
            moments.add(piece if piece.ndim == 2 else piece[..., 0])
            per_run.add(piece)
            flat = piece if piece.ndim == 2 else piece[..., 1]
            boot.add(bootstrap_weights(np.arange(at, at + n)), flat)
            at += n
        got = (total.s, total.n, per_epoch.s, per_epoch.n, moments.std(), *per_run.arrays(), boot.mean(),
               boot.point())
        found[tuple(sizes)] = got
    first = found[tuple(CHUNKINGS[0])]
    assert first[0] == pytest.approx(np.nansum(x, axis=(0, 1)), rel=1e-12)        # and the right numbers
    assert first[4] == pytest.approx(np.nanstd(x if x.ndim == 2 else x[..., 0]), rel=1e-12)
    for sizes, got in found.items():
        for i, (a, b) in enumerate(zip(first, got)):
            assert np.array_equal(a, b, equal_nan=True), (sizes, i)
