"""Records: what the Monte Carlo driver records and the scorer reads, and the metric vocabulary,
below both the experiment and the scoring (each imports them; they import neither).

:mod:`~navsim.records.states` names the nine navigation error states and their blocks
(``sigma[..., POS]``), :mod:`~navsim.records.history` one estimator's records over a batch
(``EstimatorHistory``, its arrays declared once in ``ARRAYS``), :mod:`~navsim.records.chunk` a
block of runs' records (``ChunkPart``, ``merge_parts``), :mod:`~navsim.records.truth` what is
recorded of the truth beside them (``TruthBias``, ``CalibrationHistory``),
:mod:`~navsim.records.cost` what a run cost and the clock it is read on,
:mod:`~navsim.records.vocabulary` the metric paths a scenario may name,
:mod:`~navsim.records.reference` the published results it reproduces.
"""

from navsim.records.chunk import CALIBRATION_SHARED, ChunkPart, merge_parts
from navsim.records.cost import compile_seconds, compute_clock, sum_cost
from navsim.records.history import (ARRAY_FIELDS, ARRAYS, EPOCH_ARRAYS, RECORD_DTYPES, RUN_LISTS, EstimatorHistory,
                                    merge_histories)
from navsim.records.states import SIGMA_STATES
from navsim.records.truth import CalibrationHistory, TruthBias

__all__ = ["CALIBRATION_SHARED", "ChunkPart", "merge_parts", "compile_seconds", "compute_clock", "sum_cost",
           "ARRAY_FIELDS", "ARRAYS", "EPOCH_ARRAYS", "RECORD_DTYPES", "RUN_LISTS", "EstimatorHistory",
           "merge_histories",
           "SIGMA_STATES", "CalibrationHistory", "TruthBias"]
