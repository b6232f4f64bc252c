"""A magnetometer's online calibration (:func:`navsim.navigation.magcal.calibration_history`, recorded
as a :class:`~navsim.records.truth.CalibrationHistory`) scored against the truth's hard and soft iron."""

from __future__ import annotations

import numpy as np

from navsim.records.truth import CalibrationHistory
from navsim.records.metrics import CalibrationAt, CalibrationScore, IronErrors
from navsim.scoring.intervals import mean_interval, order_statistic_interval, rounded

#: the calibration is scored when the true heading has made this many full turns (and at the end)
TURNS = 2.0


def _stats(x) -> IronErrors:
    x = 100.0 * x[np.isfinite(x)]
    if not x.size:
        return IronErrors(None, None, None)
    return IronErrors(float(np.mean(x)), float(np.percentile(x, 95)), float(np.max(x)),
                      rounded({"mean": mean_interval(x), "p95": order_statistic_interval(x, 95)}))


def _at(cal: CalibrationHistory, k: int) -> CalibrationAt:
    return CalibrationAt(float(cal.t_s[k]), _stats(cal.hard_iron_err[:, k]), _stats(cal.soft_iron_err[:, k]))


def calibration_score(cal: CalibrationHistory, turns: float = TURNS) -> CalibrationScore:
    """A calibration history scored when the true heading has made ``turns`` full turns and at
    the end: hard-iron error in % of the field magnitude and soft-iron error in % (relative
    Frobenius), mean, 95th percentile and maximum over the runs."""
    reached = np.flatnonzero(cal.turns >= turns)
    return CalibrationScore(int(cal.hard_iron_err.shape[0]), float(cal.turns[-1]), _at(cal, -1), turns,
                            _at(cal, int(reached[0])) if reached.size else None)


def thin_calibration(c: CalibrationHistory, turns: float = TURNS) -> CalibrationHistory:
    """The epochs :func:`calibration_score` reads: the first after ``turns`` full turns and the
    last."""
    reached = np.flatnonzero(c.turns >= turns)
    return c.at_epochs(np.array(sorted({len(c.t_s) - 1, *reached[:1].tolist()})))
