"""Scores of an estimator over a Monte Carlo batch: RMS after settling, final errors, window
statistics (P2's Table 1 format), NEES and NIS against chi-square bands.

The quantities (per run, per epoch) are the NED position error ``pos_m``, the velocity error
``vel_mps``, the attitude error ``att_deg`` and, for windows, ``north_m``, ``east_m``,
``height_m`` (height error, up positive), ``speed_mps`` (horizontal speed error norm),
``heading_deg`` (yaw error, estimate minus truth, ``-phi_D``).
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from navsim.closedloop import cep
from navsim.sensors import emulate

#: diverged runs listed by run in an estimator's ``divergence`` metrics (all are counted)
DIVERGENCE_LISTED = 20


def _rms(x, axis):
    return np.sqrt(np.nanmean(x ** 2, axis=axis))


class DivergenceLog:
    """The runs of an estimator left out of its statistics, fed one history at a time: their
    count, the count per cause, and the first :data:`DIVERGENCE_LISTED` with when and why
    (:attr:`~navsim.montecarlo.EstimatorHistory.divergence`; ``"not recorded"`` where the
    history has no record)."""

    def __init__(self):
        self.count = 0
        self.causes: dict = {}
        self.listed: list = []
        self.rows = 0                 # runs fed so far: the default run numbers

    def add(self, h, good, runs=None) -> None:
        """Feed a history ``h`` whose runs ``good`` are counted; ``runs``: their run numbers
        (default: the runs fed so far, counted from 0)."""
        good = np.asarray(good, bool)
        runs = np.arange(self.rows, self.rows + good.size) if runs is None else np.asarray(runs)
        self.rows += good.size
        records = getattr(h, "divergence", None)
        for b in np.flatnonzero(~good):
            rec = records[b] if records is not None else None
            t_s, cause = (float(rec[0]), str(rec[1])) if rec is not None else (None, "not recorded")
            self.count += 1
            self.causes[cause] = self.causes.get(cause, 0) + 1
            if len(self.listed) < DIVERGENCE_LISTED:
                self.listed.append({"run": int(runs[b]), "t_s": t_s, "cause": cause})

    def result(self) -> dict:
        """``{"count", "causes": {cause: runs}, "runs": [{"run", "t_s", "cause"}, ...]}``."""
        return {"count": self.count, "causes": dict(self.causes), "runs": list(self.listed)}


def chi2_band(dim: int, runs: int, p: float = 0.95) -> tuple[float, float]:
    """Two-sided band of the average of ``runs`` NEES/NIS of dimension ``dim``."""
    a = (1 - p) / 2
    lo, hi = chi2.ppf([a, 1 - a], dim * runs) / runs
    return float(lo), float(hi)


def window_quantities(h, good):
    pos = h.pos_err_m[good]
    out = {"north_m": pos[..., 0], "east_m": pos[..., 1], "height_m": -pos[..., 2],
           "speed_mps": np.linalg.norm(h.vel_err_mps[good][..., :2], axis=-1),
           "heading_deg": -np.degrees(h.att_err_rad[good][..., 2])}
    if getattr(h, "euler_err_rad", None) is not None:
        e = np.degrees(h.euler_err_rad[good])
        out.update(roll_deg=e[..., 0], pitch_deg=e[..., 1], yaw_deg=e[..., 2])
    return out


def score(h, settle_s: float = 0.0, windows=(), good=None, runs=None) -> dict:
    """The metrics of one estimator's :class:`~navsim.montecarlo.EstimatorHistory`; ``good``
    selects the runs counted (diverged ones are excluded by default), and the runs left out
    are listed with when and why in ``divergence`` (:class:`DivergenceLog`; ``runs``: the run
    numbers of the history's rows, default 0, 1, ...). Errors, NEES and NIS are scored from
    ``settle_s`` on (``nees.average_from_start`` keeps the whole run); the convergence time
    and the windows use the whole run."""
    if good is None:
        good = ~np.asarray(h.diverged, bool)
    after = h.t_s >= settle_s
    pos = h.pos_err_m[good][:, after]
    vel = h.vel_err_mps[good][:, after]
    att = np.degrees(h.att_err_rad[good][:, after])
    out = {"runs_counted": int(good.sum()), "diverged_runs": int((~good).sum()),
           "settle_s": settle_s}
    if not good.all():
        log = DivergenceLog()
        log.add(h, good, runs)
        out["divergence"] = log.result()
    if good.sum() == 0 or not after.any():
        return out
    out["rms"] = {"pos_m": _rms(pos, (0, 1)).tolist(), "vel_mps": _rms(vel, (0, 1)).tolist(),
                  "att_deg": _rms(att, (0, 1)).tolist()}
    out["max_abs"] = {"pos_m": np.nanmax(np.abs(pos), axis=(0, 1)).tolist(),
                      "vel_mps": np.nanmax(np.abs(vel), axis=(0, 1)).tolist(),
                      "att_deg": np.nanmax(np.abs(att), axis=(0, 1)).tolist()}
    out["p99"] = {"pos_m": np.nanpercentile(np.abs(pos), 99, axis=(0, 1)).tolist(),
                  "vel_mps": np.nanpercentile(np.abs(vel), 99, axis=(0, 1)).tolist(),
                  "att_deg": np.nanpercentile(np.abs(att), 99, axis=(0, 1)).tolist()}
    out["convergence_s"] = convergence_time(h.t_s, np.sqrt(np.nanmean(
        np.sum(h.pos_err_m[good] ** 2, axis=-1), axis=0)))
    # each run's last epoch (a closed-loop run's records end at its own landing)
    finite = np.isfinite(h.pos_err_m[good][..., 0])
    last = finite.shape[1] - 1 - np.argmax(finite[:, ::-1], axis=1)
    rows = np.arange(len(last))
    out["final"] = {"pos_m": _rms(h.pos_err_m[good][rows, last], 0).tolist(),
                    "vel_mps": _rms(h.vel_err_mps[good][rows, last], 0).tolist(),
                    "att_deg": _rms(np.degrees(h.att_err_rad[good][rows, last]), 0).tolist()}
    if getattr(h, "euler_err_rad", None) is not None:
        out["attitude"] = attitude_metrics(h.euler_err_rad[good][:, after])
    if getattr(h, "resets", None) is not None:
        out["resets"] = reset_metrics([r for r, g in zip(h.resets, good) if g])
    if h.cost is not None and h.cost["runs"]:
        c = h.cost
        out["cost"] = {"ms_per_run": (c["propagate_s"] + c["epoch_s"]) / c["runs"] * 1e3,
                       "propagate_ms_per_run": c["propagate_s"] / c["runs"] * 1e3,
                       "epoch_us_per_run": c["epoch_s"] / max(c["epochs"], 1) / c["runs"] * 1e6,
                       "batch_runs": c["runs"] / c["batches"]}
    q = window_quantities(h, good)
    out["windows"] = {}
    for name, a, b in windows:
        m = (h.t_s >= a) & (h.t_s <= b)
        out["windows"][name] = {
            key: {"max_pos": float(np.nanmax(v[:, m])), "max_neg": float(np.nanmin(v[:, m])),
                  "std": float(np.nanstd(v[:, m])), "rms": float(_rms(v[:, m], (0, 1))),
                  "p95_abs": float(np.nanpercentile(np.abs(v[:, m]), 95))}
            for key, v in q.items()} if m.any() else {}
        if m.any():
            out["windows"][name]["horizontal_m"] = {"rms": float(_rms(np.hypot(*np.moveaxis(
                h.pos_err_m[good][:, m, :2], -1, 0)), (0, 1)))}
        if m.any() and h.nees is not None and good.any():
            lo, hi = chi2_band(9, int(good.sum()))
            mean = np.nanmean(h.nees[good][:, m], axis=0)
            out["windows"][name]["nees"] = {"average": float(np.nanmean(mean)),
                                            "fraction_inside": float(np.mean((mean > lo) & (mean < hi)))}
    if h.nees is not None:
        n = int(good.sum())
        lo, hi = chi2_band(9, n)
        mean_all = np.nanmean(h.nees[good], axis=0)
        sel = after & (h.t_s > 0)
        mean = mean_all[sel]
        # the band of each epoch's own number of runs (closed-loop runs end at their landing)
        count = np.maximum(np.sum(np.isfinite(h.nees[good][:, sel]), axis=0), 1)
        lo_e, hi_e = chi2.ppf(0.025, 9 * count) / count, chi2.ppf(0.975, 9 * count) / count
        out["nees"] = {"average": float(np.nanmean(mean)), "band": [lo, hi],
                       "fraction_inside": float(np.mean((mean > lo_e) & (mean < hi_e))), "dim": 9,
                       "average_from_start": float(np.nanmean(mean_all[1:]))}
        out["nis"] = {}
        for key, nis in h.nis.items():
            d = h.nis_dim[key]
            v = nis[good][:, after]
            cols = ~np.isnan(v).all(axis=0)
            if not cols.any():
                continue
            per_epoch = np.nanmean(v[:, cols], axis=0)
            counts = np.sum(~np.isnan(v[:, cols]), axis=0)
            lo, hi = chi2_band(d, int(np.median(counts)))
            out["nis"][key] = {"average": float(np.nanmean(per_epoch)), "band": [lo, hi], "dim": d,
                               "fraction_inside": float(np.mean((per_epoch > lo) & (per_epoch < hi)))}
    return out


def convergence_time(t_s, err, factor: float = 2.0, hold_s: float = 60.0):
    """First time from which ``err`` (the Monte Carlo RMS of the position error norm) stays
    below ``factor`` times its steady value (the median over the second half of the run) for
    ``hold_s`` (or to the end of the run), so that a later fault window does not count as
    a failure to converge; None if it never does, or if the steady error is not below the
    initial one (an error that grows, as free inertial navigation's, has not converged)."""
    t_s, err = np.asarray(t_s, float), np.asarray(err, float)
    steady = np.nanmedian(err[len(err) // 2:])
    if not steady < err[0]:
        return None
    ok = err <= factor * steady
    bad_t = t_s[~ok]
    for i in np.flatnonzero(ok):
        later_bad = bad_t[bad_t > t_s[i]]
        if later_bad.size == 0 or later_bad[0] - t_s[i] >= hold_s:
            return float(t_s[i])
    return None


def lookup(metrics: dict, path: str):
    """The value at a dotted metric path (``rms.pos_m``, ``windows.low_leg.height_m.std``)."""
    node = metrics
    for part in path.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


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
    sd = h.sigma[rows, k, 6:8]
    q = np.sum((e / sd) ** 2, axis=-1)
    lo, hi = chi2_band(2, int(ok.sum()))
    return {"normalised_error": float(np.mean(q)), "band": [lo, hi], "dim": 2,
            "predicted_cep50_m": float(np.median(1.1774 * np.sqrt(np.mean(sd ** 2, axis=-1)))),
            "horizontal_error_rms_m": float(np.sqrt(np.mean(np.sum(e ** 2, axis=-1))))}


def closed_loop_metrics(loop: dict, reference, config, histories: dict | None = None) -> dict:
    """Outcome of navigation-in-the-loop runs (``loop``: the per-run arrays of
    :func:`navsim.runner.run_closed_loop`) and the truth-guided ``reference`` flight: how many
    runs landed, reached the recovery area, failed; CEP50/CEP95 of the true miss distance (and
    of the navigation solution's own, which the guidance closed), against the reference."""
    out = {"fly_on": config.fly_on, "time_limit_s": config.time_limit_s}
    if not loop:
        return out
    outcome = [str(o) for o in loop["outcome"]]
    out["outcomes"] = {k: outcome.count(k) for k in sorted(set(outcome))}
    rtl = config.return_to_land
    if rtl is not None:
        miss = np.asarray(loop["miss_m"], float)
        out["return_to_land"] = {
            "area_m": rtl.area_m, "landed": int(np.isfinite(miss).sum()),
            "reached_area": int((miss <= rtl.area_m).sum()),
            "miss": cep(miss), "miss_estimate": cep(loop["miss_est_m"]),
            "abort_t_s": _finite_stats(loop["abort_t_s"]), "land_t_s": _finite_stats(loop["land_t_s"]),
            "truth_guided": {"miss_m": float(reference.miss_m[0]) if np.isfinite(reference.miss_m[0]) else None,
                             "land_t_s": float(reference.land_t_s[0]) if np.isfinite(reference.land_t_s[0]) else None,
                             "outcome": reference.outcome[0]}}
        h = (histories or {}).get(config.fly_on)
        if h is not None:
            out["return_to_land"]["consistency"] = landing_consistency(h, loop["land_t_s"])
    return out


def _finite_stats(x) -> dict:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    if not x.size:
        return {"n": 0}
    return {"n": int(x.size), "min": float(x.min()), "mean": float(x.mean()), "max": float(x.max())}


def sighting_spans(truth, scenario, seed: int = 0) -> list[tuple]:
    """``(name, start_s, end_s, sigma_m)`` of every landmark sighting of the scenario's cameras
    on ``truth`` (the same for every run: the flight is shared), ``sigma_m`` the camera's fix
    noise per axis at the sighting's last fix (``noise + noise_ratio * range``)."""
    out = []
    for c in scenario.sensors:
        if c.kind != "camera":
            continue
        data = emulate(truth, c, seed, [0])
        v = data.valid[0].astype(int)
        edges = np.flatnonzero(np.diff(np.r_[0, v, 0]))
        for a, b in zip(edges[::2], edges[1::2]):
            lm = int(data.values["landmark"][0, a])
            sigma = c.spec.noise + c.spec.noise_ratio * float(data.errors["range_m"][b - 1])
            out.append((f"{c.name} landmark {lm}", float(data.t_s[a]), float(data.t_s[b - 1]), sigma))
    return out


def sighting_metrics(h, spans, good=None) -> dict:
    """Position error of an estimator at the last fix of each landmark sighting against the
    camera's fix noise ``sigma``: per sighting the RMS over runs of the north and east errors
    and their largest ratio to ``sigma``; over all, the share of (run, sighting, axis) inside
    3 sigma, and the RMS horizontal error just before the sightings (the growth between them)."""
    if good is None:
        good = ~np.asarray(h.diverged, bool)
    if not spans or not good.any():
        return {}
    per, inside, before = [], [], []
    for name, a, b, sigma in spans:
        k = int(np.clip(np.searchsorted(h.t_s, b - 1e-6), 0, len(h.t_s) - 1))
        k0 = int(np.clip(np.searchsorted(h.t_s, a - 1e-6) - 1, 0, len(h.t_s) - 1))
        e = h.pos_err_m[good][:, k, :2]
        ratio = np.abs(e) / max(sigma, 1e-9)
        inside.append(ratio <= 3.0)
        before.append(float(np.sqrt(np.mean(np.sum(h.pos_err_m[good][:, k0, :2] ** 2, -1)))))
        per.append({"name": name, "t_s": float(h.t_s[k]), "sigma_m": sigma,
                    "rms_ne_m": np.sqrt(np.mean(e ** 2, axis=0)).tolist(),
                    "max_ratio": float(ratio.max()), "rms_before_m": before[-1]})
    inside = np.concatenate([x.ravel() for x in inside])
    return {"count": len(spans), "fraction_within_3sigma": float(inside.mean()),
            "max_ratio": float(max(p["max_ratio"] for p in per)),
            "rms_after_m": float(np.sqrt(np.mean([np.mean(np.square(p["rms_ne_m"])) for p in per]))),
            "rms_before_m": {"median": float(np.median(before)), "max": float(np.max(before))},
            "sightings": per}


def calibration_score(cal: dict, turns: float = 2.0) -> dict:
    """A magnetometer calibration history (:func:`navsim.magcal.calibration_history`) scored
    when the true heading has made ``turns`` full turns and at the end: hard-iron error in % of
    the field magnitude and soft-iron error in % (relative Frobenius), mean, 95th percentile and
    maximum over the runs."""
    def stats(x):
        x = 100.0 * x[np.isfinite(x)]
        if not x.size:
            return {"mean": None, "p95": None, "max": None}
        return {"mean": float(np.mean(x)), "p95": float(np.percentile(x, 95)), "max": float(np.max(x))}
    out = {"runs": int(cal["hard_iron_err"].shape[0]), "turns_total": float(cal["turns"][-1])}
    reached = np.flatnonzero(cal["turns"] >= turns)
    if reached.size:
        k = int(reached[0])
        out[f"after_{turns:g}_turns"] = {"t_s": float(cal["t_s"][k]), "hard_iron_pct": stats(cal["hard_iron_err"][:, k]),
                                         "soft_iron_pct": stats(cal["soft_iron_err"][:, k])}
    out["final"] = {"t_s": float(cal["t_s"][-1]), "hard_iron_pct": stats(cal["hard_iron_err"][:, -1]),
                    "soft_iron_pct": stats(cal["soft_iron_err"][:, -1])}
    return out


#: the Euler axes of :func:`attitude_metrics`
EULER_AXES = ("roll", "pitch", "yaw")


def attitude_metrics(euler_err_rad: np.ndarray) -> dict:
    """Roll, pitch, yaw error statistics (deg) of ``(B, E, 3)`` errors: 95th percentile, RMS and
    maximum of the absolute error, and the 95th percentile of the error about each run's own
    mean -- what a reference sharing the vehicle's bench, level and field sees (P4's MTi)."""
    e = np.degrees(np.asarray(euler_err_rad, float))
    a = np.abs(e)
    about = np.abs(e - np.nanmean(e, axis=1, keepdims=True))
    return {"p95_deg": np.nanpercentile(a, 95, axis=(0, 1)).tolist(),
            "rms_deg": np.sqrt(np.nanmean(e ** 2, axis=(0, 1))).tolist(),
            "max_abs_deg": np.nanmax(a, axis=(0, 1)).tolist(),
            "p95_about_run_mean_deg": np.nanpercentile(about, 95, axis=(0, 1)).tolist()}


def reset_metrics(resets: list) -> dict:
    """The divergence monitor's resets: count, runs reset, per-run times (s) and causes."""
    return {"count": int(sum(len(r) for r in resets)), "runs_with_reset": int(sum(bool(r) for r in resets)),
            "mean_per_run": float(np.mean([len(r) for r in resets])) if resets else 0.0,
            "times_s": [[round(float(t), 2) for t, _ in r] for r in resets],
            "causes": sorted({c for r in resets for _, c in r})}
