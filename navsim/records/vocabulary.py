"""The metric vocabulary: the dotted paths of an estimator's ``metrics.json`` entry that a
scenario's ``reference:`` and a sweep's ``metric`` may name (``rms.pos_m``,
``windows.<name>.pos_m.rms``, ``diverged_runs``), checked by :func:`check_metric_path`."""

from __future__ import annotations

from navsim.foundations.config import close_match
from navsim.foundations.errors import ScenarioError

#: the first part of a metric path (``rms.pos_m``, ``windows.<name>.pos_m.rms``) in metrics.json
METRIC_HEADS = ("rms", "final", "max_abs", "p99", "windows", "attitude", "resets", "nees", "nis", "cost")
#: the metrics of an estimator that are one number (no dotted rest)
SCALAR_METRICS = ("runs_counted", "diverged_runs", "convergence_s")
#: the error statistics, each per quantity
ERROR_QUANTITIES = ("pos_m", "vel_mps", "att_deg")
_QUANTITIES = {head: ERROR_QUANTITIES for head in ("rms", "final", "max_abs", "p99")}


def check_metric_path(path: str, windows, *, file: str | None, key: str) -> None:
    """Raise :class:`ScenarioError` unless ``path`` names a metric of an estimator's
    metrics.json (:data:`METRIC_HEADS`; ``windows.<name>`` a window of ``windows``, each
    ``(name, start_s, end_s)``)."""
    head, _, rest = path.partition(".")
    if head in SCALAR_METRICS and not rest:
        return
    if head not in METRIC_HEADS or not rest:
        raise ScenarioError(f"'{path}' is not a metric", file=file, key=key,
                            expected=" or ".join([f"{h}.*" for h in METRIC_HEADS] + list(SCALAR_METRICS)),
                            hint=close_match(head, METRIC_HEADS + SCALAR_METRICS))
    quantity = rest.split(".")[0]
    if head in _QUANTITIES and quantity not in _QUANTITIES[head]:
        raise ScenarioError(f"'{path}' is not a metric", file=file, key=key,
                            expected=" or ".join(f"{head}.{q}" for q in _QUANTITIES[head]),
                            hint=close_match(quantity, _QUANTITIES[head]))
    if head == "windows":
        name = rest.split(".")[0]
        if name not in [w[0] for w in windows]:
            raise ScenarioError(f"window '{name}' is not defined under metrics.windows", file=file, key=key,
                                hint=close_match(name, [w[0] for w in windows]))
