"""A scenario's ``reference:`` read: the published results it reproduces, each a check with a rule
(:class:`~navsim.records.reference.PaperCheck`, :data:`~navsim.records.reference.RULES`).

A paper gives numbers (P2's Table 1, P4's accuracy bounds) or only claims (P0: "free SINS
diverges; the integrated filter converges fast and does not diverge"). Both become a
:class:`PaperCheck` on one metric of one estimator (a dotted path of its ``metrics.json``
entry, :mod:`navsim.records.vocabulary`), judged by a rule (``at_most``, ``at_least``, ``close``,
``none``: :mod:`navsim.records.reference`).

The scenario's form::

    reference:
      source: P3, simulation results
      kind: single_run               # what the numbers are: population (an average over the
                                     # paper's many trials) or single_run (one flight)
      kind_note: P3's figures show one simulation run     # why (optional, a sentence)
      note: ...                      # optional, how ours is read against the paper's
      check: at_most                 # the rule of the plain values (default none)
      tolerance: 0.25                # for close (default 0.25)
      values:                        # published numbers, per estimator label and metric
        SINS/GPS 15-state: {p99.pos_m: [1, 1, 1]}          # the reference's rule
        other: {rms.pos_m: {paper: 2.0, check: close, tolerance: 0.5, kind: population}}
      claims:                        # a paper's qualitative results, each with its threshold
        - {claim: free SINS diverges, estimator: free SINS, metric: final.pos_m, at_least: 50}
        - {claim: "the weights cut the error", estimator: weights, metric: rms.pos_m,
           at_most: {times: 0.5, of: standard KF}}       # relative to another estimator's

A claim's threshold relative to another estimator (``{times, of}``) is that estimator's same
metric times the factor. ``kind`` is required: it decides how the check is judged
(:mod:`navsim.records.reference`); a value or claim may give its own. A ``single_run`` check
needs a metric each run has a value of (:func:`~navsim.records.samples.has_run_values`) and no
``tolerance`` of its own (the spread of our runs is its tolerance).
"""

from __future__ import annotations

from navsim.foundations.config import Node, check_number, check_numbers, close_match
from navsim.records.reference import DEFAULT_TOLERANCE, KINDS, RULES, PaperCheck, Reference
from navsim.records.samples import RUN_VALUE_PATTERNS, has_run_values

#: what ``kind`` expects, as the error says it
_KIND_HELP = "population (an average over the paper's many trials) or single_run (one flight or simulation)"


def _value(node: Node, key: str):
    """A number or a list of three at ``key`` (each within the global bounds of
    :func:`~navsim.foundations.config.check_number`)."""
    value = node.data.get(key)
    node._seen.add(key)
    if value is None:
        raise node.missing(key, "a finite number or a list of three")
    err = lambda m, e: node.error(m, key, expected=f"a finite number or a list of three ({e})")
    if isinstance(value, list):
        return check_numbers(value, 3, error=err)
    return check_number(value, float, error=err)


def _rule(node: Node, default: str = "none", tolerance: float = DEFAULT_TOLERANCE) -> tuple[str, float]:
    """The node's ``check`` and ``tolerance``, the given defaults (the reference's) otherwise."""
    return (node.get("check", str, default, choices=list(RULES)),
            node.get("tolerance", float, tolerance, exclusive_minimum=0.0))


def _kind(node: Node, default: str, path: str) -> str:
    """The check's ``kind`` (the reference's ``default`` otherwise), checked against its metric
    ``path``: a single run needs the metric's per-run values and no tolerance."""
    kind = node.get("kind", str, default, choices=list(KINDS))
    if kind == "single_run" and not has_run_values(path):
        raise node.error(f"'{path}' has no value per run, so a single flight cannot be judged on it", None,
                         expected="a statistic each run has: " + ", ".join(RUN_VALUE_PATTERNS),
                         hint="kind: population, if the paper's number is an average over many trials")
    if kind == "single_run" and "tolerance" in node.data:
        raise node.error("a single_run check has no tolerance: the spread of our runs is its tolerance",
                         "tolerance", expected="no tolerance, or kind: population")
    return kind


def _label(node: Node, key: str, labels: list) -> str:
    """The estimator label at ``key`` (``estimator``, ``of``) or, for another key, the key."""
    named = key in ("estimator", "of")
    label = node.get(key, str) if named else key
    if label not in labels:
        raise node.error(f"'{label}' is not an estimator label", key if named else str(label),
                         expected="one of " + ", ".join(labels), hint=close_match(str(label), labels))
    return label


def stored_kind(raw: dict) -> dict:
    """A stored resolved scenario (``scenario.resolved.yaml``) written before references said
    their kind: its reference read as ``population``, what its verdicts were judged as (a copy;
    ``raw`` as it is otherwise)."""
    ref = raw.get("reference") if isinstance(raw, dict) else None
    if not isinstance(ref, dict) or "kind" in ref:
        return raw
    return {**raw, "reference": {**ref, "kind": "population"}}


def parse_reference(node: Node | None, labels: list, check_path) -> Reference | None:
    """The ``reference`` section (``None`` when absent); ``check_path(path, key)`` raises for a
    path that is not a metric."""
    if node is None:
        return None
    source, note = node.get("source", str), node.get("note", str, "")
    if "kind" not in node.data:
        raise node.missing("kind", _KIND_HELP)
    kind, kind_note = node.get("kind", str, choices=list(KINDS)), node.get("kind_note", str, "")
    rule, tol = _rule(node)
    checks = []
    vals = node.child("values", None)
    for label, metrics in (vals.data.items() if vals else ()):
        _label(vals, str(label), labels)
        vals._seen.add(label)
        m = Node(metrics, vals.key(str(label)), node.file)
        for path in m.data:
            check_path(str(path), m.key(str(path)))
            if isinstance(m.data[path], dict):
                one = m.child(str(path))
                r, t = _rule(one, rule, tol)
                k = _kind(one, kind, str(path))
                checks.append(PaperCheck(str(label), str(path), r, _value(one, "paper"), t, kind=k))
                one.done()
            else:
                k = _kind(Node({}, m.key(str(path)), node.file), kind, str(path))
                checks.append(PaperCheck(str(label), str(path), rule, _value(m, str(path)), tol, kind=k))
    if vals:
        vals.done()
    for j, raw in enumerate(node.items("claims", 0, "a list of {claim, estimator, metric, at_most or at_least}")
                            if "claims" in node.data else []):
        checks.append(_claim(Node(raw, node.key(f"claims[{j}]"), node.file), labels, check_path, kind))
    if not checks:
        raise node.error("has no values and no claims", "values", expected="at least one published number or claim")
    if kind == "single_run" and "tolerance" in node.data and not any(
            c.kind == "population" and c.rule == "close" for c in checks):
        raise node.error("a single_run reference has no tolerance: the spread of our runs is its tolerance",
                         "tolerance", expected="no tolerance, or a value of kind: population to use it")
    node.done()
    return Reference(source, note, tuple(checks), kind, kind_note)


def _claim(c: Node, labels: list, check_path, kind: str) -> PaperCheck:
    text, label, path = c.get("claim", str), _label(c, "estimator", labels), c.get("metric", str)
    check_path(path, c.key("metric"))
    kind = _kind(c, kind, path)
    given = [k for k in ("at_most", "at_least") if k in c.data]
    if len(given) != 1:
        raise c.error("needs one threshold", "at_most", expected="exactly one of at_most, at_least")
    rule = given[0]
    if isinstance(c.data[rule], dict):              # {times, of}: relative to another estimator
        rel = c.child(rule)
        times, of = rel.get("times", float, exclusive_minimum=0.0), _label(rel, "of", labels)
        rel.done()
        out = PaperCheck(label, path, rule, times, claim=text, of=of, kind=kind)
    else:
        out = PaperCheck(label, path, rule, _value(c, rule), claim=text, kind=kind)
    c.done()
    return out
