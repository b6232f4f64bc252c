"""navsim: a testbed for UAV integrated navigation.

JSBSim flies a fixed-wing through a scripted track under a closed-loop autopilot
(:mod:`navsim.flight`); the recorded truth feeds sensor emulators and estimators.

Notation (after pyins)
----------------------
Frames: ``i`` inertial (ECI), ``e`` Earth-fixed (ECEF), ``n`` local level North-East-Down,
``b`` body (x forward, y right, z down).

* ``vec_a``      a vector resolved in frame ``a``: ``vel_n`` (NED velocity), ``f_b`` (specific force),
  ``omega_ib_b`` (angular rate of ``b`` relative to ``i``, resolved in ``b``).
* ``C_ab``       a direction-cosine matrix taking vectors from ``b`` to ``a``: ``vec_a = C_ab @ vec_b``.
* ``quat_ab``    the same rotation as a unit quaternion, scalar first ``(w, x, y, z)``.
* Euler angles are roll, pitch, yaw (z-y-x sequence) of ``b`` relative to ``n``.

Units are SI everywhere inside the package (m, s, rad, kg, Pa, K). Datasheet or imperial units
appear only at the edges, with the unit in the name (``alt_ft``, ``gyro_bias_dph``), and are
converted in one place: JSBSim's imperial properties in :mod:`navsim.flight.properties`.

Arrays are batch-first: quantities of several Monte Carlo runs carry a leading run axis ``B``.

The Python API (:mod:`navsim.api`): :func:`load_scenario`, :func:`run` (a :class:`Result`),
:func:`open_result` (a finished run's folder, read-only), :func:`write_report`, :func:`report_figures`
(the report's pages as figures), :func:`sweep`, and :func:`compare` (two estimators, ``B - A`` with
95 % intervals, run by run where they flew the same runs) with :func:`write_comparison`, and
:func:`budget` (each error source's share of the errors) with :func:`write_budget`, and
:func:`read_log` with :func:`replay_log` (an INS/GNSS log, KF-GINS text or CSV, through a
scenario's estimators, scored as one run); :func:`tune` (an estimator's noise searched against
the truth over Monte Carlo runs, checked on runs it was not tuned on); how the runs
are made, one :class:`RunOptions` (``options=``, or its fields as keywords).

The subpackages follow the data flow; each imports only from those before it:
:mod:`navsim.foundations` (Earth, rotations, atmosphere, YAML, errors, output folders) ->
:mod:`navsim.flight` (JSBSim, tracks, autopilot, truth) -> :mod:`navsim.sensors` (emulators) ->
:mod:`navsim.navigation` (strapdown, kernels, estimators) -> :mod:`navsim.records` (what the driver
records and the scorer reads, the metric vocabulary) -> :mod:`navsim.experiment` (scenario,
driver, chunks, executors, closed loop, sweep) -> :mod:`navsim.scoring` (typed metrics) and
:mod:`navsim.replay` (PX4 logs, INS/GNSS logs) -> :mod:`navsim.report` -> :mod:`navsim.api` -> :mod:`navsim.cli`.
"""

import lazy_loader

#: the API's names, loaded on first use (``lazy_loader``, scientific Python's SPEC 1): a process
#: that imports only the modules it needs (a Monte Carlo worker: the driver, the sensors, the
#: filters) does not load the report's matplotlib, the scoring's scipy.stats nor optuna
API = ["Result", "RunOptions", "TuneOptions", "TuneResult", "budget", "write_budget", "compare", "write_comparison",
       "load_scenario", "open_result", "read_log", "replay_log", "report_figures", "run", "sweep", "tune", "tune_log",
       "write_report"]

#: the subpackages, also reached as attributes on first use (``navsim.experiment.runner``)
SUBPACKAGES = ["foundations", "flight", "sensors", "navigation", "records", "experiment", "scoring", "replay",
               "report", "cli"]

__getattr__, __dir__, _ = lazy_loader.attach(__name__, submodules=SUBPACKAGES,
                                             submod_attrs={"api": API, "version": ["__version__"]})
__all__ = [*API, "__version__"]
