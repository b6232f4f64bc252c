"""What the Monte Carlo driver records of the truth beside the estimators' histories: the IMU's
true biases at the epochs (:class:`TruthBias`) and a magnetometer's online calibration scored
against its true iron (:class:`CalibrationHistory`).

Both declare each array field's dimensions and units (``dataclasses.fields(...)[i].metadata``:
``dims``, ``units``); a field whose ``dims`` hold no ``run`` is the same for every run (shared by
all chunks of a Monte Carlo run, not concatenated). Their array names (:meth:`_RunArrays.arrays`)
are the field names, the names the chunk store keeps them under
(:mod:`navsim.experiment.chunkstore`: ``bias.<name>``, ``c<i>.<name>``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np


def _array(dims: tuple, units: str, **default):
    """An array field with named ``dims`` and ``units``."""
    return field(metadata={"dims": dims, "units": units}, **default)


def _per_run(f) -> bool:
    """Whether the array field ``f`` carries the run axis (first)."""
    return "run" in f.metadata["dims"]


class _RunArrays:
    """Array records over runs: their arrays by name, and chunks of runs joined in run order."""

    def arrays(self) -> dict:
        """Field name -> array of every field that holds one (None fields left out), in field
        order."""
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}

    @classmethod
    def _from_named(cls, arrays) -> dict:
        """``arrays`` (name -> array) checked to name only fields of ``cls``."""
        names = {f.name for f in fields(cls)}
        unknown = [k for k in arrays if k not in names]
        if unknown:
            raise ValueError(f"{cls.__name__} has no array {', '.join(map(repr, unknown))} "
                             f"(its arrays: {', '.join(sorted(names))})")
        return dict(arrays)

    @classmethod
    def _joined(cls, parts: list):
        """``parts`` (chunks of consecutive runs, in run order) as one: the per-run arrays
        concatenated along the run axis, the shared ones the first chunk's; a field absent
        (None) in the first chunk stays absent."""
        out = {}
        for f in fields(cls):
            values = [getattr(p, f.name) for p in parts]
            if values[0] is None:
                out[f.name] = None
            elif any(v is None for v in values):
                raise ValueError(f"{cls.__name__}.{f.name}: held by some chunks and not by others")
            else:
                out[f.name] = np.concatenate(values) if _per_run(f) else values[0]
        return cls(**out)


_RUN_EPOCH_AXIS = ("run", "epoch", "axis")


@dataclass(frozen=True, eq=False, kw_only=True)
class TruthBias(_RunArrays):
    """The IMU's true biases at the first estimator's epochs, ``(R, E, 3)`` over ``R`` runs,
    ``E`` epochs and the body x, y, z axes.

    ``gyro_bias_seen`` and ``accel_bias_seen`` (an IMU with scale factors or misalignments) are the
    bias plus what those add at the true rate or specific force: what a bias state sees
    (:func:`navsim.sensors.imu.seen_bias`); None where the IMU model has neither. The fields are
    keyword-only, in the order the chunk store lists them."""

    gyro_bias: np.ndarray = _array(_RUN_EPOCH_AXIS, "rad/s")
    gyro_bias_seen: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "rad/s", default=None)
    accel_bias: np.ndarray = _array(_RUN_EPOCH_AXIS, "m/s^2")
    accel_bias_seen: np.ndarray | None = _array(_RUN_EPOCH_AXIS, "m/s^2", default=None)

    @classmethod
    def from_arrays(cls, arrays) -> "TruthBias | None":
        """The biases of ``arrays`` (field name -> array, as :meth:`arrays` gives them); None
        when it is empty (no biases recorded)."""
        return cls(**cls._from_named(arrays)) if arrays else None

    @classmethod
    def concatenate(cls, parts) -> "TruthBias | None":
        """The biases of chunks of consecutive runs (in run order) as one; None when no chunk
        recorded any (a chunk with biases among chunks without is a ``ValueError``)."""
        parts = list(parts)
        if all(p is None for p in parts):
            return None
        if any(p is None for p in parts):
            raise ValueError("TruthBias.concatenate: some chunks recorded the true biases and others not")
        return cls._joined(parts)

    def seen(self, name: str) -> np.ndarray:
        """The truth a bias state estimates of ``name`` (``"gyro_bias"`` or ``"accel_bias"``):
        ``<name>_seen`` where recorded, else the additive bias ``<name>``."""
        seen = getattr(self, f"{name}_seen")
        return seen if seen is not None else getattr(self, name)


_RUN_EPOCH = ("run", "epoch")


@dataclass(frozen=True, eq=False)
class CalibrationHistory(_RunArrays):
    """A magnetometer's online calibration (:func:`navsim.navigation.magcal.calibration_history`)
    scored against its true hard and soft iron at ``E`` epochs, over ``R`` runs: ``t_s`` and
    ``turns`` are the same for every run, the errors ``(R, E)`` (NaN before the fit has an
    ellipsoid)."""

    t_s: np.ndarray = _array(("epoch",), "s")
    #: full turns of the true heading since the start
    turns: np.ndarray = _array(("epoch",), "turns")
    #: hard-iron error, a fraction of the field magnitude
    hard_iron_err: np.ndarray = _array(_RUN_EPOCH, "1")
    #: soft-iron error, relative Frobenius norm (a fraction)
    soft_iron_err: np.ndarray = _array(_RUN_EPOCH, "1")

    @classmethod
    def from_arrays(cls, arrays) -> "CalibrationHistory":
        """The history of ``arrays`` (field name -> array, as :meth:`arrays` gives them)."""
        return cls(**cls._from_named(arrays))

    @classmethod
    def concatenate(cls, parts) -> "CalibrationHistory":
        """Chunks of consecutive runs (in run order) as one history: the errors concatenated,
        ``t_s`` and ``turns`` the first chunk's."""
        return cls._joined(list(parts))

    def at_epochs(self, idx) -> "CalibrationHistory":
        """The history at the epochs ``idx`` only."""
        idx = np.asarray(idx)
        return type(self)(**{f.name: getattr(self, f.name)[:, idx] if _per_run(f) else getattr(self, f.name)[idx]
                             for f in fields(self)})


#: the arrays of a :class:`CalibrationHistory` shared by all runs, ``(E,)`` (the others are per
#: run, ``(R, E)``): its fields without a run axis
CALIBRATION_SHARED = tuple(f.name for f in fields(CalibrationHistory) if not _per_run(f))
