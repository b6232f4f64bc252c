"""The runs as the samples of an estimator's scores: what each run contributes to a metric,
kept run by run as the chunks go by, and the 95 % intervals made of it
(:mod:`navsim.scoring.intervals`), in the shape of the metrics mapping
(:attr:`~navsim.records.metrics.EstimatorMetrics.ci95`: ``ci95.rms.pos_m`` is
``[[lo, hi]] * 3`` beside ``rms.pos_m``).

Kept per run: the sums of squares and counts of the errors (RMS), of the Euler errors, of the
normalised errors (``nees.per_state``), of the NEES from the settling time (``nees.average``
where every run has every epoch: then a ratio of per-run sums), of the windows' quantities
(RMS, standard deviation) and the last epoch's errors (``final``); kept per replicate of a
Poisson bootstrap over runs (``(R, epochs)``): the summed NEES, NIS and squared position error
(the other NEES and NIS averages and shares, the convergence time). Memory: a few numbers per run and metric, and
:data:`~navsim.scoring.intervals.BOOTSTRAP_REPLICATES` rows per epoch array.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from navsim.records.metrics import WindStats
from navsim.records.samples import EstimatorSamples, MetricSamples
from navsim.scoring.intervals import (
    MIN_RUNS,
    WeightedSums,
    bootstrap_interval,
    bootstrap_weights,
    mean_square_interval,
    rms_intervals,
    std_interval,
)
from navsim.scoring.stats import (
    RunSums,
    chi2_band,
    convergence_times,
    last_finite,
    row_percentiles,
)

#: the errors scored per axis (as :data:`navsim.scoring.scorer.ERRORS`)
ERRORS = ("pos_m", "vel_mps", "att_deg")


def _rms(acc: RunSums) -> list:
    return rms_intervals(*acc.arrays())


#: a window's horizontal statistics: the key of their per-run sums -> the field of
#: :class:`~navsim.records.metrics.HorizontalStats`
_HORIZONTAL = {"whor": "rms", "whor_end": "final", "whor_max": "max"}


class RunSamples:
    """Each run's part of an estimator's metrics, fed once per chunk (the first pass)."""

    def __init__(self, windows=()):
        self.windows = list(windows)
        self.sums: dict = {}
        self.boot: dict = {}
        self.final: list = []
        self.runs: list = []
        self.values: dict = {}                 # metric path -> each chunk's per-run values (R, k)

    def _s(self, key, keep: int = 0) -> RunSums:
        if key not in self.sums:
            self.sums[key] = RunSums(keep)
        return self.sums[key]

    def _b(self, key) -> WeightedSums:
        if key not in self.boot:
            self.boot[key] = WeightedSums()
        return self.boot[key]

    def add(self, c, runs, masks: dict) -> None:
        """Feed a chunk ``c`` (:class:`navsim.scoring.scorer._Chunk`) whose counted runs have
        the numbers ``runs``; ``masks``: window name -> its epochs."""
        h, good = c.h, c.good
        self.runs.append(np.asarray(runs, np.int64))
        for name, x in c.errors.items():
            self._s(("sq", name), 1).add(x ** 2)
        if c.euler is not None:
            self._s("e_sq", 1).add(c.euler ** 2)
        for name, m in masks.items():
            for key, v in c.quantities.items():
                self._s(("w1", name, key)).add(v[:, m])
                self._s(("wsq", name, key)).add(v[:, m] ** 2)
            hor2 = np.sum(h.pos_err_m[good][:, m, :2] ** 2, axis=-1)
            self._s(("whor", name)).add(hor2)
            if hor2.shape[1]:
                self._s(("whor_end", name)).add(hor2[:, -1:])
                with warnings.catch_warnings():       # a run without a finite epoch there: NaN, left out
                    warnings.simplefilter("ignore", RuntimeWarning)
                    self._s(("whor_max", name)).add(np.nanmax(hor2, axis=1, keepdims=True))
        self._run_values(c, masks)
        w = bootstrap_weights(runs)
        self._b("conv").add(w, np.sum(h.pos_err_m[good] ** 2, axis=-1))
        if h.nees is not None:
            self._s("nees_run").add(h.nees[good][:, c.after & (h.t_s > 0)])
            self._b("nees").add(w, h.nees[good])
            for key, nis in h.nis.items():
                self._b(("nis", key)).add(w, nis[good][:, c.after])

    def _keep(self, path: str, v) -> None:
        v = np.asarray(v, float)
        self.values.setdefault(path, []).append(v.reshape(len(v), int(np.prod(v.shape[1:]))))

    def _run_values(self, c, masks: dict) -> None:
        """Each run's own value of the statistics that are not ratios of per-run sums (the
        same formulas as the pooled metrics, over one run's epochs: a paper's single flight)."""
        h, good = c.h, c.good
        with warnings.catch_warnings():               # a run without a finite value there: NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            for name, x in c.errors.items():
                self._keep(f"p99.{name}", row_percentiles(x, 99))
                self._keep(f"max_abs.{name}", _row_max(np.abs(x)))
            if c.euler is not None:
                self._keep("attitude.p95_deg", row_percentiles(c.euler, 95))
                self._keep("attitude.p95_about_run_mean_deg", row_percentiles(c.about, 95))
                self._keep("attitude.max_abs_deg", _row_max(np.abs(c.euler)))
            for name, m in masks.items():
                for key, v in c.quantities.items():
                    x, path = v[:, m], f"windows.{name}.{key}"
                    self._keep(f"{path}.max_pos", _row_max(x))
                    self._keep(f"{path}.max_neg", -_row_max(-x))
                    self._keep(f"{path}.std", np.nanstd(x, axis=1) if x.shape[1] else np.full(len(x), np.nan))
                    self._keep(f"{path}.p95_abs", row_percentiles(x, 95))
        self._keep("convergence_s", convergence_times(h.t_s, np.linalg.norm(h.pos_err_m[good], axis=-1), own_end=True))
        if h.resets is not None:
            self._keep("resets.mean_per_run", [len(r) for r, g in zip(h.resets, good) if g])

    def add_wind(self, err) -> None:
        """Feed the wind estimate's errors ``(B, epochs, 3)`` from the settling time on (NaN on
        an axis not estimated; a closed-loop run's records end at its landing)."""
        hor2 = np.sum(err[..., :2] ** 2, axis=-1)
        end = np.full(hor2.shape[0], np.nan)
        finite = np.isfinite(hor2)
        if hor2.shape[1]:
            end = np.where(finite.any(axis=1), hor2[np.arange(len(end)), last_finite(finite)], np.nan)
        self._s("wind_axes", 1).add(err ** 2)
        self._s("wind_hor").add(hor2)
        self._s("wind_end").add(np.reshape(end, (-1, 1)))

    def wind(self) -> WindStats | None:
        """The wind estimate's error (:class:`~navsim.records.metrics.WindStats`), None without one."""
        if "wind_hor" not in self.sums:
            return None
        def rms(key):                  # over every run's sums (an axis not estimated: NaN)
            s, n = self.sums[key].arrays()
            with np.errstate(invalid="ignore", divide="ignore"):
                return np.sqrt(np.sum(s, axis=0) / np.sum(n, axis=0))
        return WindStats(float(rms("wind_hor")), float(rms("wind_end")),
                         [float(a) if np.isfinite(a) else None for a in rms("wind_axes")])

    def add_normalised(self, z2) -> None:
        """Feed the squared normalised errors ``(e / sigma)^2``, ``(B, epochs, 9)``."""
        self._s("nsq", 1).add(z2)

    def add_final(self, squares) -> None:
        """Feed the squared last-epoch errors of the runs, one ``(B, 3)`` per quantity."""
        self.final.append(squares)

    def table(self) -> EstimatorSamples:
        """The metrics that are ratios of per-run sums, run by run
        (:mod:`navsim.records.samples`: what a paired comparison reads)."""
        m = {f"rms.{n}": (self.sums[("sq", n)], True) for n in ERRORS}
        if "e_sq" in self.sums:
            m["attitude.rms_deg"] = (self.sums["e_sq"], True)
        if "nees_run" in self.sums:
            m["nees.average"] = (self.sums["nees_run"], False)
        if "nsq" in self.sums:
            m["nees.per_state"] = (self.sums["nsq"], False)
        if "wind_hor" in self.sums:
            m.update({"wind.rms_mps": (self.sums["wind_hor"], True), "wind.final_mps": (self.sums["wind_end"], True)})
        for key in self.sums:
            if key[0] == "wsq":
                m[f"windows.{key[1]}.{key[2]}.rms"] = (self.sums[key], True)
            elif key[0] in _HORIZONTAL:
                m[f"windows.{key[1]}.horizontal_m.{_HORIZONTAL[key[0]]}"] = (self.sums[key], True)
        out = {path: MetricSamples(*_columns(acc), root) for path, (acc, root) in m.items()}
        for n, i in zip(ERRORS, range(3)):
            sq = np.concatenate([f[i] for f in self.final]) if self.final else np.zeros((0, 3))
            out[f"final.{n}"] = MetricSamples(np.nan_to_num(sq), np.isfinite(sq).astype(float), True)
        runs = np.concatenate(self.runs) if self.runs else np.zeros(0, np.int64)
        per_run = {path: np.concatenate(v) for path, v in self.values.items()}
        return EstimatorSamples(runs, out, {p: v for p, v in per_run.items() if len(v) == len(runs)})

    def intervals(self, t_s, settle_s: float, good: int, bands: dict) -> dict:
        """The intervals, in the metrics' shape (sections that were not scored left out).
        ``bands``: ``"nees"`` -> each scored epoch's band ``(lo, hi)``, ``("nis", key)`` ->
        ``(epochs scored, lo, hi)``, as the point values use them."""
        if good < MIN_RUNS:                   # no interval from one run
            return {}
        out = {"rms": {n: _rms(self.sums[("sq", n)]) for n in ERRORS}}
        fin = [np.concatenate([f[i] for f in self.final]) for i in range(3)]
        out["final"] = {n: [_sqrt(mean_square_interval(np.nan_to_num(f[:, j]), np.isfinite(f[:, j])))
                            for j in range(3)] for n, f in zip(ERRORS, fin)}   # f: squares
        conv = lambda mean: convergence_times(t_s, np.sqrt(mean))        # never: inf (an open end)
        out["convergence_s"] = self._boot("conv", conv)
        if "e_sq" in self.sums:
            out["attitude"] = {"rms_deg": _rms(self.sums["e_sq"])}
        if "nsq" in self.sums:
            s, n = self.sums["nsq"].arrays()
            out.setdefault("nees", {})["per_state"] = [mean_square_interval(s[:, j], n[:, j]) for j in range(s.shape[1])]
        if "nees" in self.boot:
            out.setdefault("nees", {}).update(self._nees(t_s, settle_s, bands["nees"]))
            out["nis"] = self._nis({k[1]: v for k, v in bands.items() if k != "nees"})
        out["windows"] = {name: self._window(name, t_s, good, a, b) for name, a, b in self.windows}
        if "wind_hor" in self.sums:
            s, n = self.sums["wind_axes"].arrays()
            out["wind"] = {"rms_mps": _sqrt(mean_square_interval(*self.sums["wind_hor"].arrays())),
                           "final_mps": _sqrt(mean_square_interval(*self.sums["wind_end"].arrays())),
                           "rms_axes_mps": [_sqrt(mean_square_interval(s[:, j], n[:, j])) for j in range(3)]}
        return out

    def _window(self, name: str, t_s, good: int, a: float, b: float) -> dict:
        out = {}
        for key in [k[2] for k in self.sums if k[0] == "w1" and k[1] == name]:
            s1, n = self.sums[("w1", name, key)].arrays()
            s2, _ = self.sums[("wsq", name, key)].arrays()
            out[key] = {"std": std_interval(s1, s2, n), "rms": _sqrt(mean_square_interval(s2, n))}
        hor = {stat: _sqrt(mean_square_interval(*self.sums[key, name].arrays()))
               for key, stat in _HORIZONTAL.items() if (key, name) in self.sums}
        if hor:
            out["horizontal_m"] = hor
        if "nees" in self.boot:
            m = (t_s >= a) & (t_s <= b)
            if m.any():
                out["nees"] = self._shares("nees", m, chi2_band(9, good))
        return out

    def _boot(self, key, stat, bounds=(-math.inf, math.inf)) -> list[float]:
        """The interval of ``stat`` (replicates' per-epoch means -> one value per replicate)
        over the bootstrap of ``key``, bias-shifted to its value on the runs themselves."""
        b = self.boot[key]
        return bootstrap_interval(stat(b.mean()), float(stat(b.point())[0]), bounds)

    def _shares(self, key, cols, band) -> dict:
        """The average over the epochs ``cols`` and the share of them inside ``band``."""
        lo, hi = band
        return {"average": self._boot(key, lambda m: _nanmean(m[:, cols])),
                "fraction_inside": self._boot(key, lambda m: np.mean((m[:, cols] > lo) & (m[:, cols] < hi), axis=1),
                                              (0.0, 1.0))}

    def _nees(self, t_s, settle_s: float, band) -> dict:
        cols = (t_s >= settle_s) & (t_s > 0)
        out = self._shares("nees", cols, band)
        # every run has every scored epoch (an open loop): the average of the per-epoch means is
        # the runs' pooled mean, a ratio of per-run sums with the studentized interval of an RMS's
        # mean square (the bootstrap's percentile interval covers it in 90 % at 20 runs)
        s, n = self.sums["nees_run"].arrays()
        point = float(_nanmean(self.boot["nees"].point()[:, cols])[0])
        if n.sum() > 0 and math.isclose(float(s.sum() / n.sum()), point, rel_tol=1e-6):
            out["average"] = mean_square_interval(s, n)
        return {**out, "average_from_start": self._boot("nees", lambda m: _nanmean(m[:, 1:]))}

    def _nis(self, nis_cols: dict) -> dict:
        return {key: self._shares(("nis", key), cols, (lo, hi)) for key, (cols, lo, hi) in nis_cols.items()}


def _columns(acc: RunSums) -> tuple[np.ndarray, np.ndarray]:
    """A run sum's arrays as ``(B, k)`` (one column where no axis was kept)."""
    s, n = acc.arrays()
    k = int(np.prod(s.shape[1:]))                 # 1 for one number per run; also with no run
    return s.reshape(len(s), k).astype(float), n.reshape(len(n), k).astype(float)


def _row_max(x) -> np.ndarray:
    """Each run's ``nanmax`` over its epochs (axis 1); NaN for a run without a finite value."""
    x = np.asarray(x, float)
    return np.nanmax(x, axis=1) if x.shape[1] else np.full((len(x), *x.shape[2:]), np.nan)


def _nanmean(a) -> np.ndarray:
    """Each row's ``np.nanmean`` (NaN for a row without a finite value), all rows at once: the
    NaN set to 0, the row summed, divided by its count of numbers."""
    a = np.ascontiguousarray(a, float)                # rows summed as numpy sums a 1-D row
    nan = np.isnan(a)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = np.where(nan, 0.0, a).sum(axis=1) / (~nan).sum(axis=1)
    return np.where(np.isfinite(a).any(axis=1), means, math.nan)


def _sqrt(interval) -> list[float]:
    return [math.sqrt(v) if math.isfinite(v) and v >= 0 else math.nan for v in interval]



def value_interval(metrics, samples: EstimatorSamples | None, path: str) -> list[float] | None:
    """The 95 % interval of the value a sweep plots for ``path``: a scalar's own (``ci95``); a
    vector's norm (``rms.pos_m``: the RMS of the 3-D error) from the runs' summed mean squares
    where the runs' samples keep the metric (an RMS, all axes counted alike); else None."""
    value = metrics.get(path)
    if isinstance(value, list):
        m = None if samples is None else samples.metrics.get(path)
        if m is None or not m.root or not np.all(m.n == m.n[:, :1]):
            return None
        return _sqrt(mean_square_interval(m.s.sum(axis=1), m.n[:, 0]))
    iv = metrics.interval(path)
    if isinstance(iv, list) and len(iv) == 2 and all(isinstance(v, (int, float)) for v in iv):
        return [float(v) for v in iv]
    return None
