"""Experiments: a scenario (:mod:`~navsim.experiment.scenario`, checked against
:mod:`~navsim.experiment.schema`) flown, emulated and estimated over Monte Carlo runs.

:mod:`~navsim.experiment.driver` is the one time loop over the filter epochs,
what it records is in :mod:`navsim.records` (below), :mod:`~navsim.experiment.runner` cuts the runs
into chunks for a process pool or Dask (:mod:`~navsim.experiment.executors`) and streams them to a
:mod:`~navsim.experiment.chunkstore`; :mod:`~navsim.experiment.closed_loop` flies navigation in the
loop, :mod:`~navsim.experiment.sweep` reads a parameter sweep.
"""
