"""The objectives ``navsim tune`` minimises, each a number of one estimator's scores
(:class:`~navsim.records.metrics.EstimatorMetrics`) over a trial's runs: :func:`objective`.

- ``rms``: the RMS of a metric (``metric``, default ``rms.pos_m``), its axes combined as the
  root of the sum of their squares: accuracy against the truth;
- ``nees``: ``|ln(NEES average / its dimension)|``: how far the filter's covariance is from
  describing its errors, over- or under-confident alike (Chen et al. 2018);
- ``nis``: the same for each measurement's NIS, averaged over the measurements: consistency
  without the truth, so also on a log;
- ``nees-band``, ``nis-band``: the share of the epochs whose average over the runs lies outside
  its 95 % band (for the NIS, averaged over the measurements): consistent all along the flight,
  not only on average;
- ``rms+consistent``: the RMS, multiplied by ``exp(d)`` where the NEES average lies outside its
  95 % band by ``d`` in log (the nearest edge): the most accurate filter whose covariance can be
  trusted.

- ``paper``: how far the estimator's runs sit from the single-flight numbers a paper
  published for it (the scenario's ``single_run`` reference values of rule ``close`` or ``none``,
  :mod:`navsim.records.reference`): the RMS over those numbers of ``ln(median / paper)``, the
  median over the runs of each run's own statistic (:func:`paper_distance`). The paper's flight
  is one draw; the truth model whose runs' median equals it is the one that most plausibly flew
  it. What calibrating a paper's unpublished sensor errors minimises (truth parameters).

A trial whose runs diverged, or whose objective is not a finite number, has none (None).

With a shape weight ``w`` (``--shape``; Chen et al. 2023), ``w`` times :func:`shape_distance` is
added: the Kolmogorov-Smirnov distance of the NEES samples (every run and epoch from the settling
time on; for ``nis`` and ``nis-band``, each measurement's NIS, averaged) from the chi-square
distribution of their dimension. A covariance right on average can still be wrong in shape (too
large in some phases, too small in others); the KS distance is 0 only for a chi-square
distribution.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.records.metrics import EstimatorMetrics

#: the objectives, and those that need the truth (a log without a reference offers NIS only)
OBJECTIVES = ("rms", "nees", "nees-band", "nis", "nis-band", "rms+consistent", "paper")
NEEDS_TRUTH = frozenset({"rms", "nees", "nees-band", "rms+consistent", "paper"})
DEFAULT_METRIC = "rms.pos_m"


def _log_ratio(average: float, dim: int) -> float:
    return abs(math.log(average / dim)) if average > 0 and dim > 0 else math.inf


def metric_value(m: EstimatorMetrics, path: str) -> float:
    """The metric at ``path``, its components combined as the root of their sum of squares."""
    v = m.get(path)
    if v is None:
        raise KeyError(path)
    return float(np.sqrt(np.sum(np.square(np.asarray(v, float)))))


def band_distance(average: float, band) -> float:
    """How far ``average`` lies outside ``band`` in log (0 inside)."""
    lo, hi = band
    if not average > 0:                   # zero, negative or NaN: no consistency to speak of
        return math.inf
    return max(0.0, math.log(average / hi), math.log(lo / average))


def objective(name: str, m: EstimatorMetrics, metric: str = DEFAULT_METRIC) -> float | None:
    """The objective ``name`` (:data:`OBJECTIVES`) of the scores ``m``; None for a trial with a
    diverged run, no scores or a value that is not finite."""
    if m is None or m.diverged_runs or m.runs_counted == 0:
        return None
    if name == "rms":
        value = metric_value(m, metric)
    elif name == "nees":
        value = _log_ratio(m.nees.average, m.nees.dim) if m.nees else math.nan
    elif name == "nees-band":
        value = 1.0 - m.nees.fraction_inside if m.nees else math.nan
    elif name in ("nis", "nis-band"):
        return nis_objective(name, m.nis)
    elif name == "paper":
        raise ValueError("the paper objective is of the runs' own values: paper_distance(checks, samples)")
    elif name == "rms+consistent":
        value = metric_value(m, metric) * math.exp(band_distance(m.nees.average, m.nees.band)) if m.nees else math.nan
    else:
        raise ValueError(f"no objective '{name}' (the objectives: {', '.join(OBJECTIVES)})")
    return value if math.isfinite(value) else None


def paper_checks_of(reference, label: str) -> list:
    """The checks of ``reference`` that ``paper`` fits for the estimator ``label``: the numbers
    its single flight gave (``single_run`` values of rule ``close`` or ``none``; a bound, "within
    1 m", is no number to centre the runs on, nor a claim)."""
    return [c for c in (reference.checks if reference else ()) if c.estimator == label and c.kind == "single_run"
            and c.of is None and c.claim is None and c.rule in ("close", "none")]


def paper_distance(checks: list, samples) -> float | None:
    """The ``paper`` objective: the RMS over the checks' components of ``ln(median / paper)``,
    the median over the runs (``samples``: :class:`~navsim.records.samples.EstimatorSamples`) of
    each run's own value; a median of the other sign than the paper's, or zero, is infinitely
    far (None)."""
    terms = []
    for c in checks:
        x = None if samples is None else samples.run_values(c.metric)
        paper = np.atleast_1d(np.asarray(c.bound, float))
        if x is None or x.shape[1] != paper.size or not len(x):
            return None
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.nanmedian(x, axis=0) / paper
            terms += np.log(ratio).tolist()
    value = float(np.sqrt(np.mean(np.square(terms)))) if terms else math.nan
    return value if math.isfinite(value) else None


def nis_objective(name: str, nis: dict | None) -> float | None:
    """``nis`` or ``nis-band`` of the measurements' :class:`~navsim.records.metrics.Nis`
    (an estimator's or a log replay's), averaged over them; None without one or not finite."""
    values = [_log_ratio(n.average, n.dim) if name == "nis" else 1.0 - n.fraction_inside
              for n in (nis or {}).values()]
    value = float(np.mean(values)) if values else math.nan
    return value if math.isfinite(value) else None


def band_record(x) -> dict:
    """A NEES or NIS against its band, as ``tune.json`` keeps it: ``average``, ``band``,
    ``fraction_inside``."""
    return {"average": x.average, "band": list(x.band), "fraction_inside": x.fraction_inside}


def shape_distance(history, settle_s: float, use_nis: bool) -> float:
    """The Kolmogorov-Smirnov distance of ``history``'s NEES samples after ``settle_s`` (or the
    mean over its measurements of their NIS samples', ``use_nis``) from the chi-square of their
    dimension; NaN without samples."""
    from scipy.stats import chi2, kstest
    keep = np.asarray(history.t_s) >= settle_s
    if use_nis:
        out = []
        for key, v in (history.nis or {}).items():
            x = np.asarray(v)[:, keep].ravel()
            x = x[np.isfinite(x)]
            if x.size:
                out.append(kstest(x, chi2(history.nis_dim[key]).cdf).statistic)
        return float(np.mean(out)) if out else math.nan
    if history.nees is None:
        return math.nan
    x = np.asarray(history.nees)[:, keep].ravel()
    x = x[np.isfinite(x)]
    return float(kstest(x, chi2(9).cdf).statistic) if x.size else math.nan
