"""How a Monte Carlo run was made: :class:`RunRecord`, what ``navsim run`` writes as ``run.json``.

The fields are in the order ``run.json`` holds them. Those marked ``optional`` are written only
when set (``chunk_runs`` for an open-loop run; ``failed_chunks`` and ``per_run_data`` for a run
streamed to a chunk store), so a file keeps the keys it always had; :meth:`RunRecord.from_dict`
reads the files of older navsim versions (a missing field takes its default, an unknown key is
kept in :attr:`RunRecord.extra` and written back).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields


def _optional():
    """A field left out of ``run.json`` while it is None."""
    return field(default=None, metadata={"optional": True})


@dataclass(kw_only=True)
class RunRecord:
    """``run.json``: the run's size and seed, where its flight and per-run data came from, what
    failed, and the software it ran on (:func:`navsim.foundations.provenance.provenance`)."""

    scenario: str | None = None         #: the scenario file; None for a scenario built in Python
    runs: int = 0                       #: runs asked for
    runs_done: int = 0                  #: runs that finished (failed ones included)
    seed: int = 0
    workers: int = 1
    flight_cached: bool = False         #: the flight came from the cache (not flown for this run)
    flight_key: str = ""                #: the flight cache's key of the scenario's flight
    #: the key of the flights and sensor data (:func:`navsim.experiment.runner.data_key`; ""
    #: in older files): equal keys pair run by run
    data_key: str = ""
    executor: str = "local"
    scheduler: str | None = None        #: a Dask scheduler's address
    resumed: bool = False               #: continued an interrupted run (``--resume``)
    chunk_runs: int | None = _optional()        #: runs per chunk (open loop)
    failed_chunks: dict | None = _optional()    #: chunk name -> why it failed (chunk store)
    per_run_data: str | None = _optional()      #: where the per-run histories are (chunk store)
    failed_runs: dict = field(default_factory=dict)     #: run -> why it diverged or failed
    interrupted: bool = False
    wall_s: float = math.nan
    versions: dict = field(default_factory=dict)        #: package -> version, navsim's first
    git_revision: str | None = None     #: the checkout's revision; None outside a git checkout
    utc: str = ""                       #: when the run was recorded (ISO 8601)
    command: str = ""
    platform: str = ""
    runs_plotted: int | None = None     #: runs whose histories the report draws; None: all done
    #: the ``--set PATH=VALUE`` changes made to the scenario file (in scenario.resolved.yaml)
    overrides: list | None = _optional()
    #: the ``--plugin`` files its estimators came from (``type``, ``file``, ``sha256``)
    plugins: list | None = _optional()
    #: a replayed log (``navsim replay``): its format, files (role -> path), what it is scored
    #: against (``reference`` or ``solution``) and what the replay worked around
    log: dict | None = _optional()
    extra: dict = field(default_factory=dict, repr=False)   #: keys of a newer or older navsim

    @property
    def plotted(self) -> int:
        """Runs the report's plots show."""
        return self.runs_done if self.runs_plotted is None else self.runs_plotted

    def montecarlo(self) -> dict:
        """The ``montecarlo`` settings the run used (a resolved scenario's)."""
        return {"runs": self.runs, "seed": self.seed, "workers": self.workers}

    def to_dict(self) -> dict:
        """``run.json``'s mapping: the fields in order, an optional one only when set, then
        :attr:`extra`."""
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name != "extra" and not (f.metadata.get("optional") and value is None):
                out[f.name] = value
        return {**out, **self.extra}

    @classmethod
    def from_dict(cls, raw: dict) -> "RunRecord":
        """A record read from ``run.json`` (any navsim version's: missing keys take defaults)."""
        if not isinstance(raw, dict):
            raise TypeError(f"run.json holds {type(raw).__name__}, not a mapping")
        names = {f.name for f in fields(cls)} - {"extra"}
        known = {k: v for k, v in raw.items() if k in names}
        known["failed_runs"] = {int(k): v for k, v in (known.get("failed_runs") or {}).items()}
        if known.get("wall_s", 0.0) is None:           # NaN is written as null (strict JSON)
            known["wall_s"] = math.nan
        return cls(**known, extra={k: v for k, v in raw.items() if k not in names})
