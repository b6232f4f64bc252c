"""Reports: a run's ``report.pdf`` and PNGs (:mod:`~navsim.report.pages`) and a replay's
(:mod:`~navsim.report.replay`)."""
