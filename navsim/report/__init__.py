"""Reports: a run's ``report.pdf`` and PNGs (:mod:`~navsim.report.pages`), a replay's
(:mod:`~navsim.report.replay`) and a sweep's figure (:mod:`~navsim.report.sweep`)."""
