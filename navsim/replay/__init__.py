"""``navsim replay``: a real PX4 flight log (ULog) through navsim's estimators, against PX4's own
attitude.

:mod:`~navsim.replay.ulog` reads and checks the log (:func:`load_ulog`), :mod:`~navsim.replay.run`
aligns and drives an estimator over it (:func:`replay`, as :class:`ReplayOptions` say), :mod:`~navsim.replay.metrics` scores the
differences after ``settle_s`` (:func:`replay_metrics`, a :class:`ReplayMetrics`).
"""

from navsim.replay.metrics import ReplayMetrics, replay_metrics
from navsim.replay.run import ReplayOptions, ReplayResult, coarse_alignment, replay
from navsim.replay.ulog import ReplayLog, load_ulog

__all__ = ["ReplayLog", "ReplayMetrics", "ReplayOptions", "ReplayResult", "coarse_alignment", "load_ulog", "replay", "replay_metrics"]
