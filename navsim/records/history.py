"""What the Monte Carlo driver records of one estimator over a batch of runs
(:class:`EstimatorHistory`), its arrays declared once (:data:`ARRAYS`) with their dimensions and
units, and histories of consecutive blocks of runs merged (:func:`merge_histories`).

Arrays carry the run axis first: ``(B, E, ...)`` over the ``B`` runs and the ``E`` filter epochs.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import numpy as np

from navsim.records.cost import sum_cost
from navsim.records.states import DIM_SIZES


def _array(dims: tuple, units: str, dtype=np.float64, **default):
    """A field of :class:`EstimatorHistory` holding an array with named ``dims`` and ``units``,
    recorded by the driver as ``dtype``."""
    return field(metadata={"dims": dims, "units": units, "dtype": dtype}, **default)


#: the recorded errors and 1-sigmas are single precision: 7 significant digits, where the
#: metrics print 3 to 4 (a chunk of 250 P0 runs holds half the memory)
_F32 = np.float32


_RUN_EPOCH_AXIS = ("run", "epoch", "axis")


@dataclass
class EstimatorHistory:
    """What one estimator did over the batch, sampled at its epochs ``t_s`` ``(E,)``.

    Each array field declares its dimensions and units (``dataclasses.fields(...)[i].metadata``:
    ``dims``, ``units``); ``axis`` is N, E, D (position, velocity, attitude error about them) or
    the body x, y, z (biases); ``state`` is :data:`~navsim.records.states.SIGMA_STATES`."""

    label: str
    t_s: np.ndarray = _array(("epoch",), "s")
    att_err_rad: np.ndarray = _array(_RUN_EPOCH_AXIS, "rad", _F32)     #: rotation-vector error, NED
    vel_err_mps: np.ndarray = _array(_RUN_EPOCH_AXIS, "m/s", _F32)
    pos_err_m: np.ndarray = _array(_RUN_EPOCH_AXIS, "m", _F32)         #: NED
    #: 1-sigma: att (rad), vel (m/s), pos NED (m); the blocks are named slices of
    #: :mod:`navsim.records.states` (``sigma[..., POS]``)
    sigma: np.ndarray | None = _array(("run", "epoch", "state"), "rad, m/s, m", _F32)
    nees: np.ndarray | None = _array(("run", "epoch"), "1")      #: NEES of the 9 navigation errors
    nis: dict = field()            #: measurement name -> (B, E_m) NIS, NaN without a sample
    nis_dim: dict = field()        #: measurement name -> its dimension
    diverged: np.ndarray = _array(("run",), "bool")
    gyro_bias: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "rad/s", default=None)      #: estimated
    accel_bias: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "m/s^2", default=None)     #: estimated
    #: 1-sigma of the estimates (NaN on an axis that is not a state)
    gyro_bias_sigma: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "rad/s", _F32, default=None)
    accel_bias_sigma: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "m/s^2", _F32, default=None)
    #: the estimated wind (air-mass velocity NED, NaN on an axis that is not a state) and its
    #: 1-sigma, where the estimator has a wind state
    wind_n_mps: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "m/s", default=None)
    wind_sigma_mps: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "m/s", _F32, default=None)
    #: the estimate minus the truth's steady wind (``Truth.wind_steady_n_mps``: the gusts left out)
    wind_err_mps: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "m/s", _F32, default=None)
    #: CPU seconds spent in ``propagate`` and in the epochs (predict + corrections), summed over
    #: the batches, and the number of runs and filter epochs they covered
    #: (:func:`~navsim.records.cost.sum_cost`); the seconds compiling kernels inside those calls
    #: are apart, in ``compile_s`` (:func:`~navsim.records.cost.compute_clock`)
    cost: dict | None = None
    #: roll, pitch, yaw of the solution minus the truth's, wrapped to [-pi, pi)
    euler_err_rad: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "rad", _F32, default=None)
    #: per run, the estimator's reset events ``(t_s, cause)`` (P4's divergence monitor), or None
    resets: list | None = None
    #: per run, None or ``(t_s, cause)``: when and why it was first flagged diverged (None: not
    #: recorded, as in histories built by hand)
    divergence: list | None = None


#: the array fields of :class:`EstimatorHistory` -> their ``(dims, units)``
ARRAYS = {f.name: (f.metadata["dims"], f.metadata["units"]) for f in fields(EstimatorHistory) if "dims" in f.metadata}
#: the dtype the driver records each array in (the errors and 1-sigmas single precision)
RECORD_DTYPES = {f.name: f.metadata["dtype"] for f in fields(EstimatorHistory) if "dims" in f.metadata}
#: the arrays with a run and an epoch axis, ``(B, E, ...)``: what the driver records epoch by
#: epoch, chunks concatenate, closed-loop records pad and blank, the chunk store saves
EPOCH_ARRAYS = tuple(k for k, (dims, _) in ARRAYS.items() if dims[:2] == ("run", "epoch"))
#: every array: the epoch times ``(E,)``, the epoch arrays and the per-run flag ``diverged``
#: ``(B,)`` (the NIS are a dict of ``(B, E_m)`` arrays beside)
ARRAY_FIELDS = ("t_s", *EPOCH_ARRAYS, "diverged")
#: the per-run lists (one entry per run) of an :class:`EstimatorHistory`, or None
RUN_LISTS = ("resets", "divergence")
#: the error array of each block of :data:`~navsim.records.states.BLOCKS`, in its order: the
#: errors ``sigma`` describes, state by state (``np.concatenate([... for b in BLOCKS], -1)``)
BLOCK_ERRORS = {"att": "att_err_rad", "vel": "vel_err_mps", "pos": "pos_err_m"}


def epoch_shape(name: str, runs: int) -> tuple:
    """The shape of one epoch of the epoch array ``name`` (:data:`EPOCH_ARRAYS`) over ``runs``
    runs: ``(runs,)`` and the sizes of its dimensions after the epoch
    (:data:`~navsim.records.states.DIM_SIZES`)."""
    return (runs, *(DIM_SIZES[d] for d in ARRAYS[name][0][2:]))


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


def in_double(h: EstimatorHistory) -> EstimatorHistory:
    """``h`` with its single-precision records (:data:`RECORD_DTYPES`) as double: what the
    scorer sums, so that its figures do not depend on how the runs were cut into chunks (a sum
    of singles rounds to 1e-7 by the order of its terms)."""
    single = {name: getattr(h, name).astype(np.float64) for name in EPOCH_ARRAYS
              if getattr(h, name) is not None and getattr(h, name).dtype == np.float32}
    return replace(h, **single) if single else h
