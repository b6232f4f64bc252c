"""The published results a scenario reproduces (:class:`Reference`), each a check with a rule on
one metric of one estimator (:class:`PaperCheck`; the metric a dotted path of its
``metrics.json`` entry, :mod:`navsim.records.vocabulary`, as
:meth:`navsim.records.metrics.EstimatorMetrics.get` reads it). The rules (:data:`RULES`):

- ``at_most``: ours ``<=`` the bound (an accuracy the paper claims: "within 1 m");
- ``at_least``: ours ``>=`` the bound (free SINS "diverges": its error grows past a bound);
- ``close``: ``|ours - paper| <= tolerance * |paper|`` (a number to reproduce);
- ``none``: shown beside ours without a verdict.

A vector (``[N, E, D]``, roll/pitch/yaw) passes when every component does; a claim's threshold
relative to another estimator (``of``) is that estimator's same metric times the factor. The
scenario's ``reference:`` section is read by :mod:`navsim.experiment.reference`, the checks are
judged by :mod:`navsim.scoring.verdicts`.
"""

from __future__ import annotations

from dataclasses import dataclass

RULES = ("at_most", "at_least", "close", "none")
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


@dataclass(frozen=True)
class Reference:
    """The published results a scenario reproduces."""

    source: str
    note: str
    checks: tuple[PaperCheck, ...]
