"""What the Monte Carlo driver records and the scorer reads: one estimator's errors over a batch
of runs (:class:`EstimatorHistory`) and a block of runs' records (:class:`ChunkPart`).

Arrays carry the run axis first: ``(B, E, ...)`` over the ``B`` runs and the ``E`` filter epochs.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field, fields

import numpy as np
from numba.core import event as numba_event

#: the states of :attr:`EstimatorHistory.sigma`'s last axis
SIGMA_STATES = ("att_N", "att_E", "att_D", "vel_N", "vel_E", "vel_D", "pos_N", "pos_E", "pos_D")


def _array(dims: tuple, units: str, **default):
    """A field of :class:`EstimatorHistory` holding an array with named ``dims`` and ``units``."""
    return field(metadata={"dims": dims, "units": units}, **default)


_RUN_EPOCH_AXIS = ("run", "epoch", "axis")


@dataclass
class EstimatorHistory:
    """What one estimator did over the batch, sampled at its epochs ``t_s`` ``(E,)``.

    Each array field declares its dimensions and units (``dataclasses.fields(...)[i].metadata``:
    ``dims``, ``units``); ``axis`` is N, E, D (position, velocity, attitude error about them) or
    the body x, y, z (biases); ``state`` is :data:`SIGMA_STATES`."""

    label: str
    t_s: np.ndarray = _array(("epoch",), "s")
    att_err_rad: np.ndarray = _array(_RUN_EPOCH_AXIS, "rad")     #: rotation-vector error, NED
    vel_err_mps: np.ndarray = _array(_RUN_EPOCH_AXIS, "m/s")
    pos_err_m: np.ndarray = _array(_RUN_EPOCH_AXIS, "m")         #: NED
    #: 1-sigma: att (rad), vel (m/s), pos NED (m)
    sigma: np.ndarray | None = _array(("run", "epoch", "state"), "rad, m/s, m")
    nees: np.ndarray | None = _array(("run", "epoch"), "1")      #: NEES of the 9 navigation errors
    nis: dict = field()            #: measurement name -> (B, E_m) NIS, NaN without a sample
    nis_dim: dict = field()        #: measurement name -> its dimension
    diverged: np.ndarray = _array(("run",), "bool")
    gyro_bias: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "rad/s", default=None)      #: estimated
    accel_bias: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "m/s^2", default=None)     #: estimated
    #: 1-sigma of the estimates (NaN on an axis that is not a state)
    gyro_bias_sigma: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "rad/s", default=None)
    accel_bias_sigma: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "m/s^2", default=None)
    #: CPU seconds spent in ``propagate`` and in the epochs (predict + corrections), summed over
    #: the batches, and the number of runs and filter epochs they covered (:func:`sum_cost`);
    #: the seconds compiling kernels inside those calls are apart, in ``compile_s``
    #: (:func:`compute_clock`)
    cost: dict | None = None
    #: roll, pitch, yaw of the solution minus the truth's, wrapped to [-pi, pi)
    euler_err_rad: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "rad", default=None)
    #: per run, the estimator's reset events ``(t_s, cause)`` (P4's divergence monitor), or None
    resets: list | None = None
    #: per run, None or ``(t_s, cause)``: when and why it was first flagged diverged (None: not
    #: recorded, as in histories built by hand)
    divergence: list | None = None


#: the array fields of :class:`EstimatorHistory` -> their ``(dims, units)``
ARRAYS = {f.name: (f.metadata["dims"], f.metadata["units"]) for f in fields(EstimatorHistory) if "dims" in f.metadata}
#: the arrays with a run and an epoch axis, ``(B, E, ...)``: what chunks concatenate, closed-loop
#: records pad and blank, the chunk store saves
EPOCH_ARRAYS = tuple(k for k, (dims, _) in ARRAYS.items() if dims[:2] == ("run", "epoch"))
#: every array: the epoch times ``(E,)``, the epoch arrays and the per-run flag ``diverged``
#: ``(B,)`` (the NIS are a dict of ``(B, E_m)`` arrays beside)
ARRAY_FIELDS = ("t_s", *EPOCH_ARRAYS, "diverged")
#: the per-run lists (one entry per run) of an :class:`EstimatorHistory`, or None
RUN_LISTS = ("resets", "divergence")
#: the arrays of a magnetometer calibration history (navsim.navigation.magcal) shared by all
#: runs, ``(E,)``; the others are per run, ``(B, E)``
CALIBRATION_SHARED = ("t_s", "turns")


def sum_cost(costs):
    """The :attr:`EstimatorHistory.cost` of several batches added up (None if one is None)."""
    if any(c is None for c in costs):
        return None
    return {"propagate_s": sum(c["propagate_s"] for c in costs), "epoch_s": sum(c["epoch_s"] for c in costs),
            "runs": sum(c["runs"] for c in costs), "epochs": costs[0]["epochs"],
            "batches": sum(c["batches"] for c in costs),
            "compile_s": None if any(c.get("compile_s") is None for c in costs) else sum(c["compile_s"] for c in costs)}


class _CompileTimer(numba_event.Listener):
    """Seconds this process spent in numba's compiler (compiling kernels, or loading them from
    its cache): the outermost holds of its compiler lock, summed, per thread."""

    def __init__(self):
        self._local = threading.local()
        self.total_s = 0.0

    def on_start(self, event):
        local = self._local
        local.depth = getattr(local, "depth", 0) + 1
        if local.depth == 1:
            local.t0 = time.perf_counter()

    def on_end(self, event):
        local = self._local
        local.depth -= 1
        if local.depth == 0:
            self.total_s += time.perf_counter() - local.t0


_COMPILE_TIMER = _CompileTimer()
numba_event.register("numba:compiler_lock", _COMPILE_TIMER)


def compile_seconds() -> float:
    """Seconds this process has spent compiling (or loading compiled) numba kernels so far."""
    return _COMPILE_TIMER.total_s


def compute_clock() -> float:
    """:func:`time.perf_counter` less :func:`compile_seconds`: the differences of two readings
    are the time spent computing, without the kernels' one-off compilation (the cost of a run,
    :attr:`EstimatorHistory.cost`, never counts it; its ``compile_s`` does, apart)."""
    return time.perf_counter() - _COMPILE_TIMER.total_s


@dataclass
class ChunkPart:
    """The records of a block of runs (a chunk), as the driver returns them and the chunk store
    keeps them."""

    #: the run indices, in order
    runs: list
    #: estimator label -> its history over these runs
    histories: dict
    #: ``"gyro_rad_s"``/``"accel_mps2"`` -> the IMU's true bias at the epochs, ``(B, E, 3)``
    truth_bias: dict = field(default_factory=dict)
    #: magnetometer name -> its online calibration history (navsim.navigation.magcal)
    calibration: dict = field(default_factory=dict)


def merge_histories(hs: list) -> EstimatorHistory:
    """Histories of one estimator over consecutive blocks of runs, as one."""
    cat = lambda name: None if getattr(hs[0], name) is None else np.concatenate([getattr(h, name) for h in hs])
    # per-run lists; a history without one (built by hand) has None per run
    lists = {name: None if all(getattr(h, name) is None for h in hs) else [
        r for h in hs for r in (getattr(h, name) or [None] * len(h.diverged))] for name in RUN_LISTS}
    return EstimatorHistory(
        label=hs[0].label, t_s=hs[0].t_s, **{name: cat(name) for name in (*EPOCH_ARRAYS, "diverged")},
        nis={k: np.concatenate([h.nis[k] for h in hs]) for k in hs[0].nis},
        nis_dim=hs[0].nis_dim, cost=sum_cost([h.cost for h in hs]), **lists)


def merge_parts(parts) -> ChunkPart:
    """Chunk parts (in any order) as one part over all their runs, in run order."""
    parts = sorted(parts, key=lambda p: p.runs[0])
    runs = [r for p in parts for r in p.runs]
    hist = {label: merge_histories([p.histories[label] for p in parts]) for label in parts[0].histories}
    bias = {k: np.concatenate([p.truth_bias[k] for p in parts]) for k in parts[0].truth_bias}
    calib = {name: {k: v if k in CALIBRATION_SHARED else np.concatenate([p.calibration[name][k] for p in parts])
                    for k, v in c.items()} for name, c in parts[0].calibration.items()}
    return ChunkPart(runs, hist, bias, calib)
