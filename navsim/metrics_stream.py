"""The scores of :func:`navsim.metrics.score` computed chunk by chunk, so that the memory does
not grow with the number of runs (``navsim run`` on a chunk store: 10 000 runs score in the
memory of one chunk).

Sums, counts, extremes and per-epoch sums over the runs are accumulated as the chunks go by;
the standard deviations combine the chunks' means and squared deviations (Chan et al.); the
percentiles of absolute errors are exact, in two passes over the chunks: the first counts the
values in fixed logarithmic bins (:data:`BINS_PER_DECADE`), the second keeps only the values
in the bins that hold the wanted ranks and picks them (numpy's linear interpolation). The
results equal :func:`~navsim.metrics.score` of the merged runs up to the rounding of the sums
(tested to 1e-12 relative), and do not depend on the chunk size beyond that.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from scipy.stats import chi2

from navsim.metrics import (
    DivergenceLog,
    calibration_score,
    chi2_band,
    convergence_time,
    reset_metrics,
    sighting_metrics,
    window_quantities,
)
from navsim.montecarlo import sum_cost

BINS_PER_DECADE = 400
_LOG_MIN, _LOG_MAX = -15.0, 15.0
_NBINS = int((_LOG_MAX - _LOG_MIN) * BINS_PER_DECADE) + 2


def _bins(v):
    """Bin of each absolute value (0: below 1e-15 or zero; last: above 1e15 or inf)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (np.log10(v) - _LOG_MIN) * BINS_PER_DECADE + 1
    return np.clip(np.nan_to_num(x, nan=0.0, neginf=0.0, posinf=_NBINS - 1), 0, _NBINS - 1).astype(np.int64)


def _lerp(a, b, t):
    """numpy's linear interpolation between neighbouring order statistics."""
    diff = b - a
    return b - diff * (1 - t) if t >= 0.5 else a + diff * t


class AbsPercentiles:
    """Exact ``np.nanpercentile(np.abs(x), q)`` of values fed in pieces, in two passes.

    Feed every piece with :meth:`add` (pass 1), call :meth:`second_pass`, feed the same pieces
    again, then read :meth:`value`. Each key has its own percentile ``q``.
    """

    def __init__(self):
        self.q: dict = {}
        self.hist: dict = {}
        self.window: dict | None = None      # key -> (first bin, last bin, values below, ranks, t)
        self.kept: dict = {}

    def add(self, key, x, q: float) -> None:
        v = np.abs(np.asarray(x, float)).ravel()
        v = v[~np.isnan(v)]
        b = _bins(v)
        if self.window is None:
            self.q[key] = q
            counts = np.bincount(b, minlength=_NBINS)
            self.hist[key] = self.hist[key] + counts if key in self.hist else counts
        elif key in self.window and self.window[key] is not None:
            lo, hi = self.window[key][:2]
            self.kept.setdefault(key, []).append(v[(b >= lo) & (b <= hi)])

    def second_pass(self) -> None:
        self.window = {}
        for key, hist in self.hist.items():
            n = int(hist.sum())
            if n == 0:
                self.window[key] = None
                continue
            pos = self.q[key] / 100.0 * (n - 1)
            r_lo = int(np.floor(pos))
            r_hi = min(r_lo + 1, n - 1)              # numpy interpolates with the next value even at t = 0
            cum = np.cumsum(hist)
            b_lo, b_hi = (int(np.searchsorted(cum, r, side="right")) for r in (r_lo, r_hi))
            below = int(cum[b_lo - 1]) if b_lo > 0 else 0
            self.window[key] = (b_lo, b_hi, below, (r_lo, r_hi), pos - r_lo)

    def value(self, key) -> float:
        w = self.window.get(key)
        if w is None:
            return float("nan")
        _, _, below, (r_lo, r_hi), t = w
        vals = np.sort(np.concatenate(self.kept.get(key, [np.empty(0)])))
        return float(_lerp(vals[r_lo - below], vals[r_hi - below], t))


class _Moments:
    """Count, mean and squared deviations of the non-NaN values, combined across pieces."""

    def __init__(self):
        self.n, self.mean, self.m2 = 0, 0.0, 0.0

    def add(self, x) -> None:
        v = x[~np.isnan(x)]
        n = v.size
        if n == 0:
            return
        mean = float(np.mean(v))
        m2 = float(np.sum((v - mean) ** 2))
        delta = mean - self.mean
        tot = self.n + n
        self.mean += delta * n / tot
        self.m2 += m2 + delta ** 2 * self.n * n / tot
        self.n = tot

    def std(self) -> float:
        return float(np.sqrt(self.m2 / self.n)) if self.n else float("nan")


class _Sum:
    """``np.nansum`` and the non-NaN count over the run axis (and more leading axes)."""

    def __init__(self):
        self.s = self.n = None

    def add(self, x, axis) -> None:
        s, n = np.nansum(x, axis=axis), np.sum(~np.isnan(x), axis=axis)
        self.s, self.n = (s, n) if self.s is None else (self.s + s, self.n + n)

    def mean(self):
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.s / self.n


class _Extreme:
    def __init__(self, fn):
        self.fn, self.v = fn, None

    def value(self, shape=()):
        """The extreme; NaN (of ``shape``) where every value was NaN, as ``np.nanmax``."""
        return np.full(shape, np.nan) if self.v is None else self.v

    def add(self, x, axis=None) -> None:
        if np.all(np.isnan(x)):
            return
        v = self.fn(x, axis=axis)
        self.v = v if self.v is None else self.fn(np.stack([self.v, v]), axis=0)


class EstimatorScore:
    """:func:`navsim.metrics.score` of one estimator, fed one chunk history at a time (twice)."""

    def __init__(self, settle_s: float = 0.0, windows=()):
        self.settle_s, self.windows = settle_s, list(windows)
        self.pct = AbsPercentiles()
        self.acc: dict = {}
        self.good = self.bad = 0
        self.divergence = DivergenceLog()
        self.final: list = []
        self.resets: list | None = None
        self.costs: list = []
        self.t_s = None
        self.has_nees = self.has_euler = False
        self.nis_dim: dict = {}
        self.nis_keys: list = []
        self.quantities: list = []          # window quantities, in window_quantities' order
        self.passes = 1

    def _a(self, key, make):
        if key not in self.acc:
            self.acc[key] = make()
        return self.acc[key]

    def add(self, h, good=None, runs=None) -> None:
        """Feed one chunk's :class:`~navsim.montecarlo.EstimatorHistory` (``good``: runs counted;
        ``runs``: their run numbers, default the runs fed so far counted from 0)."""
        if good is None:
            good = ~np.asarray(h.diverged, bool)
        good = np.asarray(good, bool)
        after = h.t_s >= self.settle_s
        first = self.passes == 1
        if first:
            self.t_s = h.t_s
            self.good += int(good.sum())
            self.bad += int((~good).sum())
            self.divergence.add(h, good, runs)
            self.has_nees = h.nees is not None
            self.nis_dim.update(h.nis_dim)
            self.nis_keys += [k for k in h.nis if k not in self.nis_keys]
            self.has_euler = getattr(h, "euler_err_rad", None) is not None
        pos = h.pos_err_m[good][:, after]
        vel = h.vel_err_mps[good][:, after]
        att = np.degrees(h.att_err_rad[good][:, after])
        for name, x in (("pos_m", pos), ("vel_mps", vel), ("att_deg", att)):
            for j in range(3):
                self.pct.add(("p99", name, j), x[..., j], 99)
        if self.has_euler:
            e = np.degrees(h.euler_err_rad[good][:, after])
            with np.errstate(invalid="ignore"):
                about = np.abs(e - np.nanmean(e, axis=1, keepdims=True)) if e.shape[1] else e
            for j in range(3):
                self.pct.add(("att_p95", j), e[..., j], 95)
                self.pct.add(("att_about", j), about[..., j], 95)
        q = window_quantities(h, good)
        if first:
            self.quantities += [k for k in q if k not in self.quantities]
        for name, a, b in self.windows:
            m = (h.t_s >= a) & (h.t_s <= b)
            if m.any():
                for key, v in q.items():
                    self.pct.add(("win", name, key), v[:, m], 95)
        if not first:
            return
        for name, x in (("pos_m", pos), ("vel_mps", vel), ("att_deg", att)):
            self._a(("sq", name), _Sum).add(x ** 2, (0, 1))
            self._a(("max", name), lambda: _Extreme(np.nanmax)).add(np.abs(x), (0, 1))
        self._a("conv", _Sum).add(np.sum(h.pos_err_m[good] ** 2, axis=-1), 0)
        finite = np.isfinite(h.pos_err_m[good][..., 0])
        last = finite.shape[1] - 1 - np.argmax(finite[:, ::-1], axis=1)
        rows = np.arange(len(last))
        self.final.append((h.pos_err_m[good][rows, last], h.vel_err_mps[good][rows, last],
                           np.degrees(h.att_err_rad[good][rows, last])))
        if self.has_euler:
            self._a("e_sq", _Sum).add(e ** 2, (0, 1))
            self._a("e_max", lambda: _Extreme(np.nanmax)).add(np.abs(e), (0, 1))
        if getattr(h, "resets", None) is not None:
            self.resets = (self.resets or []) + [r for r, g in zip(h.resets, good) if g]
        self.costs.append(h.cost)
        for name, a, b in self.windows:
            m = (h.t_s >= a) & (h.t_s <= b)
            if not m.any():
                continue
            for key, v in q.items():
                x = v[:, m]
                self._a(("wmax", name, key), lambda: _Extreme(np.nanmax)).add(x)
                self._a(("wmin", name, key), lambda: _Extreme(np.nanmin)).add(x)
                self._a(("wmom", name, key), _Moments).add(x)
                self._a(("wsq", name, key), _Sum).add(x ** 2, (0, 1))
            self._a(("whor", name), _Sum).add(np.sum(h.pos_err_m[good][:, m, :2] ** 2, axis=-1), (0, 1))
            if h.nees is not None:
                self._a(("wnees", name), _Sum).add(h.nees[good][:, m], 0)
        if h.nees is not None:
            self._a("nees", _Sum).add(h.nees[good], 0)
            self._a("nees_finite", _Sum).add(np.where(np.isfinite(h.nees[good]), 1.0, np.nan), 0)
            for key, nis in h.nis.items():
                self._a(("nis", key), _Sum).add(nis[good][:, after], 0)

    def second_pass(self) -> None:
        """Start feeding the same chunks again (for the percentiles)."""
        self.pct.second_pass()
        self.passes = 2

    def result(self) -> dict:
        """The metrics, as :func:`navsim.metrics.score` returns them."""
        t_s = self.t_s
        after = t_s >= self.settle_s
        out = {"runs_counted": self.good, "diverged_runs": self.bad, "settle_s": self.settle_s}
        if self.bad:
            out["divergence"] = self.divergence.result()
        if self.good == 0 or not after.any():
            return out
        acc, p = self.acc, self.pct.value
        names = ("pos_m", "vel_mps", "att_deg")
        out["rms"] = {n: np.sqrt(acc[("sq", n)].mean()).tolist() for n in names}
        out["max_abs"] = {n: acc[("max", n)].value(3).tolist() for n in names}
        out["p99"] = {n: [p(("p99", n, j)) for j in range(3)] for n in names}
        out["convergence_s"] = convergence_time(t_s, np.sqrt(acc["conv"].mean()))
        fin = [np.concatenate([f[i] for f in self.final]) for i in range(3)]
        out["final"] = {n: np.sqrt(np.nanmean(f ** 2, axis=0)).tolist() for n, f in zip(names, fin)}
        if self.has_euler:
            out["attitude"] = {"p95_deg": [p(("att_p95", j)) for j in range(3)],
                               "rms_deg": np.sqrt(acc["e_sq"].mean()).tolist(),
                               "max_abs_deg": acc["e_max"].value(3).tolist(),
                               "p95_about_run_mean_deg": [p(("att_about", j)) for j in range(3)]}
        if self.resets is not None:
            out["resets"] = reset_metrics(self.resets)
        cost = sum_cost(self.costs)
        if cost is not None and cost["runs"]:
            out["cost"] = {"ms_per_run": (cost["propagate_s"] + cost["epoch_s"]) / cost["runs"] * 1e3,
                           "propagate_ms_per_run": cost["propagate_s"] / cost["runs"] * 1e3,
                           "epoch_us_per_run": cost["epoch_s"] / max(cost["epochs"], 1) / cost["runs"] * 1e6,
                           "batch_runs": cost["runs"] / cost["batches"]}
        out["windows"] = {}
        for name, a, b in self.windows:
            m = (t_s >= a) & (t_s <= b)
            keys = [k for k in self.quantities if ("wmom", name, k) in acc]
            w = {}
            for key in keys:
                w[key] = {"max_pos": float(acc[("wmax", name, key)].value()),
                          "max_neg": float(acc[("wmin", name, key)].value()),
                          "std": acc[("wmom", name, key)].std(),
                          "rms": float(np.sqrt(acc[("wsq", name, key)].mean())),
                          "p95_abs": p(("win", name, key))}
            out["windows"][name] = w
            if m.any():
                w["horizontal_m"] = {"rms": float(np.sqrt(acc[("whor", name)].mean()))}
            if m.any() and self.has_nees:
                lo, hi = chi2_band(9, self.good)
                mean = acc[("wnees", name)].mean()
                w["nees"] = {"average": float(np.nanmean(mean)),
                             "fraction_inside": float(np.mean((mean > lo) & (mean < hi)))}
        if self.has_nees:
            n = self.good
            lo, hi = chi2_band(9, n)
            mean_all = acc["nees"].mean()
            sel = after & (t_s > 0)
            mean = mean_all[sel]
            count = np.maximum(acc["nees_finite"].n[sel], 1)
            lo_e, hi_e = chi2.ppf(0.025, 9 * count) / count, chi2.ppf(0.975, 9 * count) / count
            out["nees"] = {"average": float(np.nanmean(mean)), "band": [lo, hi],
                           "fraction_inside": float(np.mean((mean > lo_e) & (mean < hi_e))), "dim": 9,
                           "average_from_start": float(np.nanmean(mean_all[1:]))}
            out["nis"] = {}
            for key in self.nis_keys:
                d, s = self.nis_dim[key], acc.get(("nis", key))
                if s is None:
                    continue
                cols = s.n > 0
                if not cols.any():
                    continue
                per_epoch = s.s[cols] / s.n[cols]
                lo, hi = chi2_band(d, int(np.median(s.n[cols])))
                out["nis"][key] = {"average": float(np.nanmean(per_epoch)), "band": [lo, hi], "dim": d,
                                   "fraction_inside": float(np.mean((per_epoch > lo) & (per_epoch < hi)))}
        return out


def score_parts(parts, settle_s: float = 0.0, windows=()) -> dict:
    """Label -> :func:`navsim.metrics.score` over chunk parts (``parts()`` yields them in run
    order; it is called twice, for the exact percentiles)."""
    return score_run(parts, settle_s, windows)[0]


def _sighting_epochs(t_s, spans) -> np.ndarray:
    """The epochs :func:`navsim.metrics.sighting_metrics` reads (a sighting's last fix, the
    epochs either side of its start) and the first and last: on these alone it finds the same."""
    E = len(t_s)
    idx = {0, E - 1}
    for _, a, b, _ in spans:
        j = int(np.searchsorted(t_s, a - 1e-6))
        idx.update(int(np.clip(i, 0, E - 1)) for i in (np.searchsorted(t_s, b - 1e-6), j, j - 1))
    return np.array(sorted(idx))


def _thin_calibration(c: dict, turns: float = 2.0) -> dict:
    """The epochs :func:`navsim.metrics.calibration_score` reads: the first after ``turns`` full
    turns and the last."""
    reached = np.flatnonzero(c["turns"] >= turns)
    idx = np.array(sorted({len(c["t_s"]) - 1, *reached[:1].tolist()}))
    return {"t_s": c["t_s"][idx], "turns": c["turns"][idx], "hard_iron_err": c["hard_iron_err"][:, idx],
            "soft_iron_err": c["soft_iron_err"][:, idx]}


def score_run(parts, settle_s: float = 0.0, windows=(), sightings=()) -> tuple[dict, dict]:
    """What ``navsim run`` scores, from chunk parts: label -> metrics (with ``landmarks`` for
    an estimator with a covariance when there are ``sightings``) and magnetometer -> calibration
    score (:func:`navsim.metrics.calibration_score`).

    Parameters
    ----------
    parts : callable
        ``parts()`` yields the chunk parts in run order; called twice.
    settle_s, windows, sightings
        As :func:`navsim.metrics.score` and :func:`navsim.metrics.sighting_metrics`.
    """

    scores, thin, calib = {}, {}, {}
    for part in parts():
        for label, h in part[1].items():
            scores.setdefault(label, EstimatorScore(settle_s, windows)).add(h, runs=part[0])
            if sightings and h.sigma is not None:
                idx = _sighting_epochs(h.t_s, sightings)
                thin.setdefault(label, []).append((h.t_s[idx], h.pos_err_m[:, idx], h.diverged))
        for name, c in part[3].items():
            calib.setdefault(name, []).append(_thin_calibration(c))
    for s in scores.values():
        s.second_pass()
    for part in parts():
        for label, h in part[1].items():
            scores[label].add(h, runs=part[0])
    out = {label: s.result() for label, s in scores.items()}
    for label, pieces in thin.items():
        h = SimpleNamespace(t_s=pieces[0][0], pos_err_m=np.concatenate([p[1] for p in pieces]),
                            diverged=np.concatenate([p[2] for p in pieces]))
        out[label]["landmarks"] = sighting_metrics(h, sightings)
    cal = {name: calibration_score({k: v if k in ("t_s", "turns") else np.concatenate([p[k] for p in ps])
                                    for k, v in ps[0].items()}) for name, ps in calib.items()}
    return out, cal
