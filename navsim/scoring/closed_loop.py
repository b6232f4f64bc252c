"""Navigation in the loop scored: how the runs ended, the miss distances at the recovery area
against the truth-guided flight, and whether the filter's sigmas at the parachute match its
true error."""

from __future__ import annotations

import numpy as np

from navsim.records.states import POS_NE
from navsim.scoring.intervals import binomial_interval, mean_interval, order_statistic_interval, rounded
from navsim.scoring.stats import chi2_band


def cep(miss_m: np.ndarray) -> dict:
    """Circular error probable of horizontal miss distances: the 50 % and 95 % quantiles, with
    their 95 % intervals (``ci95``: between order statistics; the mean's Student's t; NaN where
    the runs cannot bound it, as a CEP95's upper end below 59 runs)."""
    m = np.asarray(miss_m, float)
    m = m[np.isfinite(m)]
    if not m.size:
        return {"cep50_m": None, "cep95_m": None, "mean_m": None, "max_m": None, "n": 0}
    return {"cep50_m": float(np.percentile(m, 50)), "cep95_m": float(np.percentile(m, 95)),
            "mean_m": float(m.mean()), "max_m": float(m.max()), "n": int(m.size),
            "ci95": rounded({"cep50_m": order_statistic_interval(m, 50), "cep95_m": order_statistic_interval(m, 95),
                             "mean_m": mean_interval(m)})}


def landing_consistency(h, land_t_s) -> dict:
    """How the filter's own horizontal uncertainty at the parachute compares with its true
    horizontal error there: the average over the landed runs of ``eN²/σN² + eE²/σE²`` (2 degrees
    of freedom: inside ``band`` when the filter is consistent) and the CEP50 its sigmas
    predict, ``1.1774 sqrt((σN² + σE²)/2)`` (median over runs)."""
    land = np.asarray(land_t_s, float)
    ok = np.isfinite(land)
    if h.sigma is None or not ok.any():
        return {}
    k = np.clip(np.searchsorted(h.t_s, land[ok] + 1e-9) - 1, 0, len(h.t_s) - 1)
    rows = np.flatnonzero(ok)
    e = h.pos_err_m[rows, k, :2]
    sd = h.sigma[rows, k, POS_NE]
    q = np.sum((e / sd) ** 2, axis=-1)
    lo, hi = chi2_band(2, int(ok.sum()))
    return {"normalised_error": float(np.mean(q)), "band": [lo, hi], "dim": 2,
            "predicted_cep50_m": float(np.median(1.1774 * np.sqrt(np.mean(sd ** 2, axis=-1)))),
            "horizontal_error_rms_m": float(np.sqrt(np.mean(np.sum(e ** 2, axis=-1))))}


def closed_loop_metrics(loop, reference, config, histories: dict | None = None) -> dict:
    """Outcome of navigation-in-the-loop runs (``loop``: the
    :class:`~navsim.experiment.runner.LoopRuns` of :func:`navsim.experiment.runner.run_closed_loop`,
    None when no run finished) and the truth-guided ``reference`` flight: how many
    runs landed, reached the recovery area, failed; CEP50/CEP95 of the true miss distance (and
    of the navigation solution's own, which the guidance closed), against the reference."""
    out = {"fly_on": config.fly_on, "time_limit_s": config.time_limit_s}
    if loop is None:
        return out
    outcome = [str(o) for o in loop.outcome]
    out["outcomes"] = {k: outcome.count(k) for k in sorted(set(outcome))}
    #: each outcome's share of the runs, Clopper-Pearson's exact 95 % interval
    out["outcome_shares_ci95"] = {k: rounded(binomial_interval(n, len(outcome))) for k, n in out["outcomes"].items()}
    rtl = config.return_to_land
    if rtl is not None:
        miss = np.asarray(loop.miss_m, float)
        out["return_to_land"] = {
            "area_m": rtl.area_m, "landed": int(np.isfinite(miss).sum()),
            "reached_area": int((miss <= rtl.area_m).sum()),
            "miss": cep(miss), "miss_estimate": cep(loop.miss_est_m),
            "abort_t_s": _finite_stats(loop.abort_t_s), "land_t_s": _finite_stats(loop.land_t_s),
            "truth_guided": {"miss_m": float(reference.miss_m[0]) if np.isfinite(reference.miss_m[0]) else None,
                             "land_t_s": float(reference.land_t_s[0]) if np.isfinite(reference.land_t_s[0]) else None,
                             "outcome": reference.outcome[0]}}
        h = (histories or {}).get(config.fly_on)
        if h is not None:
            out["return_to_land"]["consistency"] = landing_consistency(h, loop.land_t_s)
    return out


def _finite_stats(x) -> dict:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    if not x.size:
        return {"n": 0}
    return {"n": int(x.size), "min": float(x.min()), "mean": float(x.mean()), "max": float(x.max())}
