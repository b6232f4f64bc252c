"""Scoring: the estimators' errors over the Monte Carlo runs turned into typed metrics.

:mod:`navsim.records` holds what the driver records (``EstimatorHistory``, ``ChunkPart``; scoring
imports nothing of :mod:`navsim.experiment`),
:mod:`~navsim.scoring.scorer` the one scorer (chunk by chunk; in memory is one chunk),
:mod:`navsim.records.metrics` the typed results and their ``metrics.json`` mapping,
:mod:`~navsim.scoring.stats` the streaming statistics and chi-square bands, and
:mod:`~navsim.scoring.landmarks`, :mod:`~navsim.scoring.calibration`,
:mod:`~navsim.scoring.closed_loop` the scores of landmark fixes, magnetometer calibration and
navigation in the loop.
"""

from navsim.records.chunk import ChunkPart
from navsim.records.history import EstimatorHistory
from navsim.records.metrics import CalibrationScore, EstimatorMetrics, RunMetrics
from navsim.scoring.scorer import EstimatorScore, score, score_run

__all__ = ["ChunkPart", "EstimatorHistory", "CalibrationScore", "EstimatorMetrics", "RunMetrics",
           "EstimatorScore", "score", "score_run"]
