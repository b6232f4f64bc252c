"""What is recorded of the truth beside the histories (:mod:`navsim.records.truth`): the IMU's
true biases (:class:`TruthBias`) and a magnetometer's calibration history
(:class:`CalibrationHistory`), typed where they were string-keyed dicts: chunks concatenate to
the one batch, they round-trip through the chunk store bit for bit, and a chunk folder in the
layout written before them (``bias.<name>``, ``c<i>.<name>``, their names in ``meta``) still
reads."""

import json
from dataclasses import FrozenInstanceError, fields

import numpy as np
import pytest

import navsim.records
from navsim.experiment.chunkstore import ChunkStore, part_arrays, part_from_arrays
from navsim.records.chunk import CALIBRATION_SHARED, ChunkPart, merge_parts
from navsim.records.history import EstimatorHistory
from navsim.records.truth import CalibrationHistory, TruthBias

R, E, EC = 5, 4, 6          # runs, history epochs, calibration epochs
KEY = {"scenario_hash": "abc", "seed": 3, "runs": R, "chunk_runs": 2}


def _batch(seed=0):
    """One batch of ``R`` runs: biases with their seen variants, a calibration with NaNs."""
    rng = np.random.default_rng(seed)
    bias = TruthBias(gyro_bias=rng.normal(size=(R, E, 3)), gyro_bias_seen=rng.normal(size=(R, E, 3)),
                     accel_bias=rng.normal(size=(R, E, 3)), accel_bias_seen=rng.normal(size=(R, E, 3)))
    hard = rng.random((R, EC))
    hard[:, 0] = np.nan                                  # no ellipsoid yet
    cal = CalibrationHistory(t_s=np.arange(EC, dtype=float), turns=np.linspace(0, 3, EC), hard_iron_err=hard,
                             soft_iron_err=rng.random((R, EC)))
    return bias, cal


def _history(runs, rng):
    n = len(runs)
    return EstimatorHistory(label="KF", t_s=np.arange(E, dtype=float), att_err_rad=rng.normal(size=(n, E, 3)),
                            vel_err_mps=rng.normal(size=(n, E, 3)), pos_err_m=rng.normal(size=(n, E, 3)),
                            sigma=None, nees=None, nis={}, nis_dim={}, diverged=np.zeros(n, bool))


def _rows(record, rows):
    """``record``'s runs ``rows`` (its per-run arrays sliced, the shared kept)."""
    return type(record)(**{f.name: None if getattr(record, f.name) is None else
                           getattr(record, f.name)[rows] if "run" in f.metadata["dims"] else getattr(record, f.name)
                           for f in fields(record)})


def _parts(seed=0):
    """The batch cut into chunks of runs 0-1, 2-3, 4 (as ChunkParts)."""
    bias, cal = _batch(seed)
    rng = np.random.default_rng(seed + 1)
    return [ChunkPart(list(r), {"KF": _history(r, rng)}, _rows(bias, slice(r[0], r[-1] + 1)),
                      {"mag": _rows(cal, slice(r[0], r[-1] + 1))}) for r in (range(0, 2), range(2, 4), range(4, 5))]


def _same_bits(a: dict, b: dict):
    assert list(a) == list(b)
    for k in a:
        assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape and a[k].tobytes() == b[k].tobytes(), k


def test_the_fields_declare_their_dims_and_units_and_the_shared_ones_are_derived():
    for cls in (TruthBias, CalibrationHistory):
        assert all({"dims", "units"} <= f.metadata.keys() for f in fields(cls)), cls
    assert CALIBRATION_SHARED == ("t_s", "turns") == navsim.records.CALIBRATION_SHARED
    assert [f.name for f in fields(TruthBias)] == ["gyro_bias", "gyro_bias_seen", "accel_bias", "accel_bias_seen"]
    assert {f.metadata["units"] for f in fields(TruthBias) if f.name.startswith("gyro")} == {"rad/s"}
    bias, cal = _batch()
    with pytest.raises(FrozenInstanceError):
        bias.gyro_bias = None
    with pytest.raises(TypeError):              # keyword-only: a positional mix-up of gyro and accel is refused
        TruthBias(bias.gyro_bias, bias.accel_bias)
    with pytest.raises(ValueError, match="gyro_rad_s"):
        TruthBias.from_arrays({"gyro_rad_s": bias.gyro_bias})
    assert TruthBias.from_arrays({}) is None
    assert bias.seen("gyro_bias") is bias.gyro_bias_seen
    plain = TruthBias(gyro_bias=bias.gyro_bias, accel_bias=bias.accel_bias)
    assert plain.seen("accel_bias") is bias.accel_bias and list(plain.arrays()) == ["gyro_bias", "accel_bias"]


def test_chunks_concatenate_to_the_one_batch():
    bias, cal = _batch()
    cuts = [slice(0, 2), slice(2, 4), slice(4, 5)]
    _same_bits(TruthBias.concatenate([_rows(bias, c) for c in cuts]).arrays(), bias.arrays())
    _same_bits(CalibrationHistory.concatenate([_rows(cal, c) for c in cuts]).arrays(), cal.arrays())
    merged = merge_parts(reversed(_parts()))           # in any order
    assert merged.runs == list(range(R))
    _same_bits(merged.truth_bias.arrays(), bias.arrays())
    _same_bits(merged.calibration["mag"].arrays(), cal.arrays())
    thin = cal.at_epochs([1, 5])
    assert np.array_equal(thin.t_s, [1.0, 5.0]) and thin.hard_iron_err.tobytes() == cal.hard_iron_err[:, [1, 5]].tobytes()


def test_nothing_recorded_stays_nothing():
    parts = [ChunkPart([0], {}), ChunkPart([1], {})]
    merged = merge_parts(parts)
    assert merged.truth_bias is None and merged.calibration == {}
    bias, _ = _batch()
    with pytest.raises(ValueError, match="some chunks"):
        TruthBias.concatenate([None, bias])
    with pytest.raises(ValueError, match="gyro_bias_seen"):
        TruthBias.concatenate([bias, TruthBias(gyro_bias=bias.gyro_bias, accel_bias=bias.accel_bias)])
    back = part_from_arrays(part_arrays(ChunkPart([0, 1], {"KF": _history([0, 1], np.random.default_rng(0))})))
    assert back.truth_bias is None and back.calibration == {}


def test_the_chunk_store_keeps_every_array_bit_for_bit(tmp_path):
    parts = _parts()
    store = ChunkStore(tmp_path, KEY, mode="new")
    for p in parts:
        store.add(p)
    back = list(ChunkStore.open(tmp_path).parts())
    for p, b in zip(parts, back):
        assert b.runs == p.runs
        _same_bits(b.truth_bias.arrays(), p.truth_bias.arrays())
        _same_bits(b.calibration["mag"].arrays(), p.calibration["mag"].arrays())
    merged, whole = ChunkStore.open(tmp_path).merged(), merge_parts(parts)
    _same_bits(merged.truth_bias.arrays(), whole.truth_bias.arrays())
    _same_bits(merged.calibration["mag"].arrays(), whole.calibration["mag"].arrays())


def _old_layout(part: ChunkPart) -> dict:
    """The chunk file of ``part`` as navsim wrote it when the biases and calibration were
    dicts (written out by hand: the key names and the ``meta`` JSON, in their order)."""
    h = part.histories["KF"]
    names = ["t_s", "att_err_rad", "vel_err_mps", "pos_err_m", "diverged"]
    bias = {k: getattr(part.truth_bias, k) for k in ("gyro_bias", "gyro_bias_seen", "accel_bias", "accel_bias_seen")}
    cal = part.calibration["mag"]
    cal = {"t_s": cal.t_s, "turns": cal.turns, "hard_iron_err": cal.hard_iron_err, "soft_iron_err": cal.soft_iron_err}
    arrays = {"runs": np.asarray(part.runs, np.int64), **{f"h0.{n}": getattr(h, n) for n in names},
              **{f"bias.{k}": v for k, v in bias.items()}, **{f"c0.{k}": v for k, v in cal.items()}}
    meta = {"labels": ["KF"], "bias": list(bias), "calibration": {"mag": list(cal)},
            "histories": [{"arrays": names, "nis": [], "nis_dim": {}, "cost": None, "resets": None,
                           "divergence": None}]}
    arrays["meta"] = np.array(json.dumps(meta))
    arrays["ident"] = np.array(json.dumps({**KEY, "chunk": [part.runs[0], part.runs[-1]]}))
    return arrays


def test_a_chunk_folder_of_the_dict_layout_still_reads(tmp_path):
    parts = _parts()
    chunks = {}
    for p in parts:
        name = f"{p.runs[0]}-{p.runs[-1]}"
        chunks[name] = f"chunk_{name}.npz"
        np.savez(tmp_path / chunks[name], **_old_layout(p))
    (tmp_path / "index.json").write_text(json.dumps({**KEY, "chunks": chunks, "failed": {}}))
    store = ChunkStore.open(tmp_path)
    merged, whole = store.merged(), merge_parts(parts)
    assert merged.runs == list(range(R))
    _same_bits(merged.truth_bias.arrays(), whole.truth_bias.arrays())
    _same_bits(merged.calibration["mag"].arrays(), whole.calibration["mag"].arrays())
    for p, b in zip(parts, store.parts()):
        _same_bits(b.calibration["mag"].arrays(), p.calibration["mag"].arrays())
        # and written again, the same entries under the same names, the same meta
        old, new = _old_layout(p), part_arrays(b, KEY)
        assert list(new) == list(old) and str(new["meta"]) == str(old["meta"])
        assert all(new[k].tobytes() == old[k].tobytes() for k in old if k not in ("meta", "ident"))
