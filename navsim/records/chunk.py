"""A block of runs' records (a chunk), as the driver returns them and the chunk store keeps
them (:class:`ChunkPart`), and blocks merged in run order (:func:`merge_parts`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from navsim.records.history import merge_histories
from navsim.records.truth import CALIBRATION_SHARED, CalibrationHistory, TruthBias

__all__ = ["CALIBRATION_SHARED", "ChunkPart", "merge_parts"]


@dataclass
class ChunkPart:
    """The records of a block of runs (a chunk), as the driver returns them and the chunk store
    keeps them."""

    #: the run indices, in order
    runs: list
    #: estimator label -> its history over these runs
    histories: dict
    #: the IMU's true biases at the first estimator's epochs, ``(B, E, 3)`` (:class:`TruthBias`:
    #: ``gyro_bias``, ``accel_bias`` and, for an IMU with scale factors or misalignments,
    #: ``gyro_bias_seen``, ``accel_bias_seen``); None: none recorded
    truth_bias: TruthBias | None = None
    #: magnetometer name -> its online calibration history (:class:`CalibrationHistory`); empty:
    #: no magnetometer calibrated online
    calibration: dict[str, CalibrationHistory] = field(default_factory=dict)


def merge_parts(parts) -> ChunkPart:
    """Chunk parts (in any order) as one part over all their runs, in run order."""
    parts = sorted(parts, key=lambda p: p.runs[0])
    runs = [r for p in parts for r in p.runs]
    hist = {label: merge_histories([p.histories[label] for p in parts]) for label in parts[0].histories}
    bias = TruthBias.concatenate(p.truth_bias for p in parts)
    calib = {name: CalibrationHistory.concatenate(p.calibration[name] for p in parts) for name in parts[0].calibration}
    return ChunkPart(runs, hist, bias, calib)
