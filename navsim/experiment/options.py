"""How a Monte Carlo runs, declared once: :class:`RunOptions`, built by the command line or the
caller and passed down through the API to the runner, instead of the same keyword chain at each
layer.

Each number is an :class:`~navsim.foundations.config.Argument`: the API checks a value and the
command line reads its option's text with the same words (``seed: -1 is below 0 (expected an
integer 0-9223372036854775807)``). None for ``runs``, ``seed`` and ``workers`` means the
scenario's ``montecarlo`` setting (:meth:`RunOptions.for_scenario`).
"""

from __future__ import annotations

import dataclasses
import urllib.parse
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from navsim.experiment.scenario import MAX_SEED, MAX_WORKERS
from navsim.foundations.config import MAX_RUNS, Argument, close_match
from navsim.foundations.errors import UsageError

RUNS = Argument("runs", int, minimum=1, maximum=MAX_RUNS)
SEED = Argument("seed", int, minimum=0, maximum=MAX_SEED)
WORKERS = Argument("workers", int, minimum=1, maximum=MAX_WORKERS)
CHUNK_RUNS = Argument("chunk_runs", int, minimum=1, maximum=MAX_RUNS)
#: where the chunks of runs go (``executor=``, ``--executor``)
EXECUTORS = ("local", "dask")
#: the Dask schemes a scheduler address may use
SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss", "inproc", "ucx")


def shown(value) -> str:
    """``value`` for a message, at most 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def check_scheduler(address, name: str = "scheduler") -> str:
    """``address`` if it is a Dask scheduler address, ``scheme://host:port`` or ``host:port``
    for TCP as Dask reads it; else a :class:`UsageError` (naming ``name``, when given)."""
    url = None
    if isinstance(address, str) and address:
        try:
            url = urllib.parse.urlsplit(address if "://" in address else f"tcp://{address}")
            port = url.port
        except ValueError:
            url = None
    if url is None or url.scheme not in SCHEDULER_SCHEMES or not url.hostname or (
            url.scheme != "inproc" and port is None):
        raise UsageError(f"{name + ': ' if name else ''}{shown(address)} is not a scheduler address (expected "
                         f"scheme://host:port, scheme one of {', '.join(SCHEDULER_SCHEMES)}, e.g. tcp://10.0.0.5:8786)")
    return address


def check_flags(flags: dict, functions: dict | None = None) -> None:
    """:class:`UsageError` for a flag (name -> value) that is not a bool, or a function
    (``progress=``) that is neither None nor callable."""
    for name, value in flags.items():
        if not isinstance(value, (bool, np.bool_)):
            raise UsageError(f"{name}: {shown(value)} is not true or false (expected a bool)")
    for name, value in (functions or {}).items():
        if value is not None and not callable(value):
            raise UsageError(f"{name}: {shown(value)} is not callable (expected a function or None)")


@dataclass(frozen=True)
class RunOptions:
    """How the runs of a Monte Carlo are made; none of it changes the numbers but ``runs`` and
    ``seed`` (the chunking, the workers and the executor do not, bit for bit).

    Build it with :meth:`checked` (or :meth:`of`), which refuses what the command line refuses.
    """

    runs: int | None = None                   #: Monte Carlo runs (None: the scenario's)
    seed: int | None = None                   #: the seed (None: the scenario's)
    workers: int | None = None                #: worker processes (None: the scenario's)
    executor: str = "local"                   #: one of :data:`EXECUTORS`
    scheduler: str | None = None              #: a Dask scheduler's address (``executor="dask"``)
    chunk_runs: int | None = None             #: runs per chunk (None: the runner's default)
    resume: bool = False                      #: complete an interrupted run in the output folder
    progress: Callable[[int], None] | None = None    #: ``progress(runs_finished)`` as chunks end

    def checked(self) -> RunOptions:
        """These options if every field is valid (the numbers as ``int``: a numpy integer as an
        ``int``), else a :class:`UsageError` naming the field, the value and what was expected."""
        numbers = {}
        for argument in (RUNS, SEED, WORKERS, CHUNK_RUNS):
            value = getattr(self, argument.name)
            if value is not None:
                numbers[argument.name] = argument.check(value)
        if not isinstance(self.executor, str) or self.executor not in EXECUTORS:
            raise UsageError(f"executor: {shown(self.executor)} is not an executor (expected one of "
                             f"{', '.join(EXECUTORS)})")
        if self.scheduler is not None:
            check_scheduler(self.scheduler)
        check_flags({"resume": self.resume}, {"progress": self.progress})
        return dataclasses.replace(self, **numbers)

    @classmethod
    def of(cls, runs=None, seed=None, workers=None, **options) -> RunOptions:
        """The options of an API call, checked: ``runs``, ``seed``, ``workers`` and the other
        fields as keywords, or ``options=RunOptions(...)``, whose fields the keywords given
        replace (None for a field whose default is None is not given: the field keeps the
        ``options=`` value). An unknown keyword is a :class:`UsageError` naming the closest field."""
        base = options.pop("options", None)
        if base is not None and not isinstance(base, RunOptions):
            raise UsageError(f"options: {shown(base)} is not a RunOptions")
        names = [f.name for f in dataclasses.fields(cls)]
        for key in options:
            if key not in names:
                raise UsageError(f"{key}: not an option of a run ({close_match(key, names)})")
        unset = {f.name for f in dataclasses.fields(cls) if f.default is None}
        given = {k: v for k, v in dict(options, runs=runs, seed=seed, workers=workers).items()
                 if not (v is None and k in unset)}
        return dataclasses.replace(base or cls(), **given).checked()

    def for_scenario(self, scenario) -> RunOptions:
        """``runs``, ``seed`` and ``workers`` filled from ``scenario``'s ``montecarlo`` where None."""
        return dataclasses.replace(self, runs=scenario.runs if self.runs is None else self.runs,
                                   seed=scenario.seed if self.seed is None else self.seed,
                                   workers=scenario.workers if self.workers is None else self.workers)
