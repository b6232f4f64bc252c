"""What ``navsim tune`` records: every trial (:class:`TuneTrial`), the held-out check of the best
parameters (:class:`TuneCheck`), and the whole tuning (:class:`TuneRecord`, ``tune.json``).
Units are in the names; a parameter's values are those set in the scenario (a scaled term's: its
factor)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field


@dataclass
class TuneTrial:
    """One trial: its parameters' values, its objective (None: a run diverged or it failed) and
    the estimator's position RMS (N, E, D) and NEES average over its runs."""

    number: int
    values: dict                 #: parameter name -> the trial value (a scaled term's factor)
    objective: float | None
    rms_pos_m: list | None = None
    nees_average: float | None = None
    wall_s: float = math.nan


@dataclass
class TuneCheck:
    """The original against the tuned parameters on one set of runs (the tuning seed or one it
    never saw), paired: the objective of each and, per metric component, the tuned minus the
    original with its 95 % interval and verdict (:mod:`navsim.scoring.compare`)."""

    seed: int
    runs: int
    objective_original: float | None
    objective_tuned: float | None
    #: ``{metric, component, a, b, diff, ci95, verdict}`` of ``rms.pos_m``, ``rms.vel_mps``,
    #: ``rms.att_deg`` and ``nees.average``
    differences: list = field(default_factory=list)
    #: ``original`` / ``tuned`` -> ``{"nees": {...}, "nis": {measurement: {...}}}``, each
    #: ``{average, band, fraction_inside}``: the consistency of each against its chi-square band
    consistency: dict = field(default_factory=dict)
    #: a truth model's fit: ``original`` / ``tuned`` -> the scenario's paper checks judged with
    #: each truth (:class:`~navsim.records.metrics.Verdict` mappings): the fit's prediction
    paper_checks: dict | None = None


@dataclass
class TuneRecord:
    """A tuning: the scenario, the estimator, the objective, the parameters' ranges, every trial,
    the best one, the estimator's entry with the best values (``tuned.yaml``) and the checks of
    the best against the original on the tuning seed and on unused seeds."""

    scenario: str
    estimator: str
    objective: str
    metric: str
    params: list                 #: ``{name, path, lo, hi, log, base}``
    seed: int
    runs: int
    trials: list = field(default_factory=list)          #: TuneTrial
    best: int | None = None                             #: the best trial's number
    tuned_entry: dict | None = None
    tuned_sensors: dict | None = None                   #: a truth model's fit: the scenario's sensors
    checks: dict = field(default_factory=dict)          #: ``tuning`` / ``held_out`` -> TuneCheck
    sampler: str = ""
    wall_s: float = math.nan
    shape: float = 0.0                                  #: the weight of the chi-square shape term
    #: whether the best trial is not the original (trial 0); None: the original was not a trial
    #: (a value outside its range, a list of unequal values, a log's estimator)
    improved: bool | None = None

    def to_dict(self) -> dict:
        return asdict(self)

    @property
    def best_trial(self) -> TuneTrial | None:
        return next((t for t in self.trials if t.number == self.best), None)
