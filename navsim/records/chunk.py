"""A block of runs' records (a chunk), as the driver returns them and the chunk store keeps
them (:class:`ChunkPart`), and blocks merged in run order (:func:`merge_parts`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from navsim.records.history import merge_histories

#: the arrays of a magnetometer calibration history (navsim.navigation.magcal) shared by all
#: runs, ``(E,)``; the others are per run, ``(B, E)``
CALIBRATION_SHARED = ("t_s", "turns")


@dataclass
class ChunkPart:
    """The records of a block of runs (a chunk), as the driver returns them and the chunk store
    keeps them."""

    #: the run indices, in order
    runs: list
    #: estimator label -> its history over these runs
    histories: dict
    #: the IMU's true biases at the first estimator's epochs, ``(B, E, 3)``: ``"gyro_bias"``
    #: (rad/s) and ``"accel_bias"`` (m/s^2), and, for an IMU with scale factors or
    #: misalignments, ``"gyro_bias_seen"`` and ``"accel_bias_seen"``: the bias plus what those
    #: add at the true rate or specific force (what a bias state sees,
    #: :func:`navsim.sensors.imu.seen_bias`)
    truth_bias: dict = field(default_factory=dict)
    #: magnetometer name -> its online calibration history (navsim.navigation.magcal)
    calibration: dict = field(default_factory=dict)


def merge_parts(parts) -> ChunkPart:
    """Chunk parts (in any order) as one part over all their runs, in run order."""
    parts = sorted(parts, key=lambda p: p.runs[0])
    runs = [r for p in parts for r in p.runs]
    hist = {label: merge_histories([p.histories[label] for p in parts]) for label in parts[0].histories}
    bias = {k: np.concatenate([p.truth_bias[k] for p in parts]) for k in parts[0].truth_bias}
    calib = {name: {k: v if k in CALIBRATION_SHARED else np.concatenate([p.calibration[name][k] for p in parts])
                    for k, v in c.items()} for name, c in parts[0].calibration.items()}
    return ChunkPart(runs, hist, bias, calib)
