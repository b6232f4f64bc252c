"""The published results a scenario reproduces (:class:`Reference`), each a check with a rule on
one metric of one estimator (:class:`PaperCheck`; the metric a dotted path of its
``metrics.json`` entry, :mod:`navsim.records.vocabulary`, as
:meth:`navsim.records.metrics.EstimatorMetrics.get` reads it). The rules (:data:`RULES`):

- ``at_most``: ours ``<=`` the bound (an accuracy the paper claims: "within 1 m");
- ``at_least``: ours ``>=`` the bound (free SINS "diverges": its error grows past a bound);
- ``close``: ``|ours - paper| <= tolerance * |paper|`` (a number to reproduce);
- ``none``: shown beside ours without a verdict.

A vector (``[N, E, D]``, roll/pitch/yaw) passes when every component does; a claim's threshold
relative to another estimator (``of``) is that estimator's same metric times the factor.

Each check says what kind of number the paper published (:data:`KINDS`): ``population``, an
average over the many trials the paper ran, is judged on the 95 % confidence interval of our
metric over the runs; ``single_run``, one flight or one simulation, is judged against the
spread of the same statistic computed on each of our runs (the 95 % range of one run,
:mod:`navsim.scoring.single_run`): a maximum over 100 runs is not what one flight shows. The
scenario's ``reference:`` section is read by :mod:`navsim.experiment.reference`, the checks are
judged by :mod:`navsim.scoring.verdicts`.
"""

from __future__ import annotations

from dataclasses import dataclass

RULES = ("at_most", "at_least", "close", "none")
#: what a published number is: an average over many trials, or one flight or simulation
KINDS = ("population", "single_run")
DEFAULT_TOLERANCE = 0.25


@dataclass(frozen=True)
class PaperCheck:
    """One published number or claim on one estimator's metric."""

    estimator: str                 #: the estimator's label
    metric: str                    #: dotted path of its metrics, e.g. ``p99.pos_m``
    rule: str                      #: one of :data:`RULES`
    bound: float | list            #: the paper's number, or the claim's threshold
    tolerance: float = DEFAULT_TOLERANCE   #: ``close``: relative to the paper's number
    claim: str | None = None       #: the claim's words; None for a published number
    of: str | None = None          #: a claim relative to this estimator: ``bound`` is the factor
    kind: str = "population"       #: one of :data:`KINDS`


@dataclass(frozen=True)
class Reference:
    """The published results a scenario reproduces."""

    source: str
    note: str
    checks: tuple[PaperCheck, ...]
    kind: str = "population"       #: its checks' kind unless one says otherwise (:data:`KINDS`)
    kind_note: str = ""            #: why: what the paper's numbers are (one flight, many trials)
