"""The scores' types, declared in :mod:`navsim.records.metrics` (the layer below experiment and
scoring, so that a scenario's parser checks metric paths against them); re-exported here,
unchanged, for plug-ins and notebooks that import them from this module (navsim itself imports
them from :mod:`navsim.records.metrics`)."""

from navsim.records.metrics import (  # noqa: F401
    AttitudeStats,
    CalibrationAt,
    CalibrationScore,
    Cost,
    DivergedRun,
    Divergence,
    EULER_AXES,
    ErrorStats,
    EstimatorMetrics,
    HorizontalStats,
    IronErrors,
    Landmarks,
    Nees,
    Nis,
    QuantityStats,
    Resets,
    RunMetrics,
    Sighting,
    SpreadStats,
    Verdict,
    Window,
    WindowNees,
    lookup,
)
