"""The one scorer: an estimator's :class:`~navsim.records.metrics.EstimatorMetrics` from its
histories, fed chunk by chunk so that the memory does not grow with the number of runs (10 000
runs score in the memory of one chunk); runs held in memory are a stream of one chunk
(:func:`score`).

The quantities (per run, per epoch) are the NED position error ``pos_m``, the velocity error
``vel_mps``, the attitude error ``att_deg`` and, for windows, ``north_m``, ``east_m``,
``height_m`` (height error, up positive), ``speed_mps`` (horizontal speed error norm),
``heading_deg`` (yaw error, estimate minus truth, ``-phi_D``) and, with Euler errors recorded,
``roll_deg``, ``pitch_deg``, ``yaw_deg``. Every chunk is fed twice (:meth:`EstimatorScore.add`,
:meth:`~EstimatorScore.second_pass`, :meth:`~EstimatorScore.add` again): the second pass picks
the exact percentiles (:class:`~navsim.scoring.stats.AbsPercentiles`). The results do not
depend on the chunking, bit for bit: every sum over runs is taken in run order
(:mod:`navsim.scoring.stats`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from navsim.records.cost import sum_cost
from navsim.records.history import BLOCK_ERRORS, EstimatorHistory, in_double
from navsim.records.samples import EstimatorSamples, MetricSamples
from navsim.records.states import BLOCKS
from navsim.records.truth import CalibrationHistory
from navsim.scoring.calibration import calibration_score, thin_calibration
from navsim.scoring.landmarks import SightingEpochs, sighting_intervals, sighting_metrics, sighting_sums, thin_for_sightings
from navsim.scoring.intervals import rounded
from navsim.scoring.samples import RunSamples
from navsim.records.metrics import (
    AttitudeStats,
    CalibrationScore,
    Cost,
    DivergedRun,
    Divergence,
    ErrorStats,
    EstimatorMetrics,
    HorizontalStats,
    Nees,
    Nis,
    QuantityStats,
    Resets,
    Window,
    WindowNees,
)
from navsim.scoring.stats import (
    AbsPercentiles,
    Extreme,
    Moments,
    Sum,
    chi2_band,
    chi2_bands,
    convergence_time,
    last_finite,
    run_nansums,
)

#: diverged runs listed by run in an estimator's ``divergence`` metrics (all are counted)
DIVERGENCE_LISTED = 20
#: the errors scored per axis, their names in :class:`~navsim.records.metrics.ErrorStats`
ERRORS = ("pos_m", "vel_mps", "att_deg")
#: the dimension of the NEES (the 9 navigation errors)
NEES_DIM = 9


class DivergenceLog:
    """The runs of an estimator left out of its statistics, fed one history at a time: their
    count, the count per cause, and the first :data:`DIVERGENCE_LISTED` with when and why
    (:attr:`~navsim.records.history.EstimatorHistory.divergence`; ``"not recorded"`` where the
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
                self.listed.append(DivergedRun(int(runs[b]), t_s, cause))

    def result(self) -> Divergence:
        return Divergence(self.count, dict(self.causes), list(self.listed))


#: the windows' quantities that are norms (never negative: no "largest negative" to show)
NORM_QUANTITIES = frozenset({"speed_mps"})
#: the windows' quantities (:func:`window_quantities`), and those where the Euler errors are recorded
WINDOW_QUANTITIES = ("north_m", "east_m", "height_m", "speed_mps", "heading_deg")
EULER_QUANTITIES = ("roll_deg", "pitch_deg", "yaw_deg")


def window_quantities(h, good) -> dict:
    """The windows' quantities of the runs ``good`` of history ``h``, ``(R, E)`` each."""
    pos = h.pos_err_m[good]
    out = dict(zip(WINDOW_QUANTITIES, (pos[..., 0], pos[..., 1], -pos[..., 2],
                                       np.linalg.norm(h.vel_err_mps[good][..., :2], axis=-1),
                                       -np.degrees(h.att_err_rad[good][..., 2]))))
    if h.euler_err_rad is not None:
        e = np.degrees(h.euler_err_rad[good])
        out.update(zip(EULER_QUANTITIES, (e[..., 0], e[..., 1], e[..., 2])))
    return out


def reset_metrics(resets: list) -> Resets:
    """The divergence monitor's resets (per run, a list of ``(t_s, cause)``)."""
    return Resets(int(sum(len(r) for r in resets)), int(sum(bool(r) for r in resets)),
                  float(np.mean([len(r) for r in resets])) if resets else 0.0,
                  [[round(float(t), 2) for t, _ in r] for r in resets], sorted({c for r in resets for _, c in r}))


def cost_metrics(cost: dict | None) -> Cost | None:
    """The CPU cost per run and per epoch of a summed :attr:`EstimatorHistory.cost`, and apart
    the seconds compiling its kernels (never inside the per-run figures)."""
    if cost is None or not cost["runs"]:
        return None
    runs = cost["runs"]
    return Cost((cost["propagate_s"] + cost["epoch_s"]) / runs * 1e3, cost["propagate_s"] / runs * 1e3,
                cost["epoch_s"] / max(cost["epochs"], 1) / runs * 1e6, runs / cost["batches"],
                cost.get("compile_s"))


class _Chunk:
    """The arrays of one chunk that are scored: the counted runs, from the settling time on."""

    def __init__(self, h: EstimatorHistory, good: np.ndarray, settle_s: float):
        self.h, self.good = h, good
        self.after = h.t_s >= settle_s
        self.errors = {"pos_m": h.pos_err_m[good][:, self.after], "vel_mps": h.vel_err_mps[good][:, self.after],
                       "att_deg": np.degrees(h.att_err_rad[good][:, self.after])}
        self.euler = self.about = None
        if h.euler_err_rad is not None:
            self.euler = np.degrees(h.euler_err_rad[good][:, self.after])
            s, n = run_nansums(self.euler, 1)      # each run's mean, whatever its chunk
            with np.errstate(invalid="ignore", divide="ignore"):   # a run without a finite epoch: NaN
                self.about = np.abs(self.euler - (s / n)[:, None, :]) if self.euler.shape[1] else self.euler
        self.quantities = window_quantities(h, good)


class EstimatorScore:
    """The metrics of one estimator, fed one chunk's history at a time, twice.

    Parameters
    ----------
    settle_s : float
        Errors, NEES and NIS are scored from this time on.
    windows : sequence of (name, start_s, end_s)
        The time windows scored apart.
    """

    def __init__(self, settle_s: float = 0.0, windows=()):
        self.settle_s, self.windows = settle_s, [tuple(w) for w in windows]
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
        self.quantities: list = []          # the window quantities, in their order
        self.passes = 1
        self.samples = RunSamples(self.windows)
        self.rows = 0                       # runs fed so far: the default run numbers

    def _a(self, key, make):
        if key not in self.acc:
            self.acc[key] = make()
        return self.acc[key]

    def _mask(self, a: float, b: float) -> np.ndarray:
        return (self.t_s >= a) & (self.t_s <= b)

    def add(self, h: EstimatorHistory, good=None, runs=None) -> None:
        """Feed one chunk's history (``good``: the runs counted, default those not diverged;
        ``runs``: their run numbers, default the runs fed so far counted from 0)."""
        good = ~np.asarray(h.diverged, bool) if good is None else np.asarray(good, bool)
        h = in_double(h)
        chunk = _Chunk(h, good, self.settle_s)
        if self.passes == 1:
            self._first_pass(chunk, runs)
        self._percentiles(chunk)

    def _percentiles(self, c: _Chunk) -> None:
        for name, x in c.errors.items():
            for j in range(3):
                self.pct.add(("p99", name, j), x[..., j], 99)
        if c.euler is not None:
            for j in range(3):
                self.pct.add(("att_p95", j), c.euler[..., j], 95)
                self.pct.add(("att_about", j), c.about[..., j], 95)
        for name, a, b in self.windows:
            m = self._mask(a, b)
            if m.any():
                for key, v in c.quantities.items():
                    self.pct.add(("win", name, key), v[:, m], 95)

    def _first_pass(self, c: _Chunk, runs) -> None:
        h, good = c.h, c.good
        self.t_s = h.t_s
        runs = np.arange(self.rows, self.rows + good.size) if runs is None else np.asarray(runs)
        self.rows += good.size
        self.samples.add(c, runs[good], {n: self._mask(a, b) for n, a, b in self.windows if self._mask(a, b).any()})
        self.good += int(good.sum())
        self.bad += int((~good).sum())
        self.divergence.add(h, good, runs)
        self.has_nees, self.has_euler = h.nees is not None, c.euler is not None
        self.nis_dim.update(h.nis_dim)
        self.quantities += [k for k in c.quantities if k not in self.quantities]
        for name, x in c.errors.items():
            self._a(("sq", name), Sum).add(x ** 2, (0, 1))
            self._a(("max", name), lambda: Extreme(np.nanmax)).add(np.abs(x), (0, 1))
        self._a("conv", Sum).add(np.sum(h.pos_err_m[good] ** 2, axis=-1), 0)
        # each run's last epoch (a closed-loop run's records end at its own landing)
        last = last_finite(np.isfinite(h.pos_err_m[good][..., 0]))
        rows = np.arange(len(last))
        self.final.append((h.pos_err_m[good][rows, last], h.vel_err_mps[good][rows, last],
                           np.degrees(h.att_err_rad[good][rows, last])))
        self.samples.add_final([f ** 2 for f in self.final[-1]])
        if c.euler is not None:
            self._a("e_sq", Sum).add(c.euler ** 2, (0, 1))
            self._a("e_max", lambda: Extreme(np.nanmax)).add(np.abs(c.euler), (0, 1))
        if h.resets is not None:
            self.resets = (self.resets or []) + [r for r, g in zip(h.resets, good) if g]
        self.costs.append(h.cost)
        self._window_sums(c)
        if h.wind_err_mps is not None:
            self.samples.add_wind(h.wind_err_mps[good][:, c.after])
        if h.sigma is not None:
            e = np.concatenate([getattr(h, BLOCK_ERRORS[block]) for block in BLOCKS], -1)[good][:, c.after]
            with np.errstate(invalid="ignore", divide="ignore"):
                z2 = (e / h.sigma[good][:, c.after]) ** 2
            self._a("nsq", Sum).add(z2, (0, 1))
            self.samples.add_normalised(z2)
        if h.nees is not None:
            self._a("nees", Sum).add(h.nees[good], 0)
            self._a("nees_finite", Sum).add(np.where(np.isfinite(h.nees[good]), 1.0, np.nan), 0)
            for key, nis in h.nis.items():
                self._a(("nis", key), Sum).add(nis[good][:, c.after], 0)

    def _window_sums(self, c: _Chunk) -> None:
        for name, a, b in self.windows:
            m = self._mask(a, b)
            if not m.any():
                continue
            for key, v in c.quantities.items():
                x = v[:, m]
                self._a(("wmax", name, key), lambda: Extreme(np.nanmax)).add(x)
                self._a(("wmin", name, key), lambda: Extreme(np.nanmin)).add(x)
                self._a(("wmom", name, key), Moments).add(x)
                self._a(("wsq", name, key), Sum).add(x ** 2, (0, 1))
            hor2 = np.sum(c.h.pos_err_m[c.good][:, m, :2] ** 2, axis=-1)
            self._a(("whor", name), Sum).add(hor2, (0, 1))
            self._a(("whor_end", name), Sum).add(hor2[:, -1], 0)
            with warnings.catch_warnings():               # a run without a finite epoch there: NaN, left out
                warnings.simplefilter("ignore", RuntimeWarning)
                self._a(("whor_max", name), Sum).add(np.nanmax(hor2, axis=1) if hor2.shape[0] else hor2[:, 0], 0)
            if c.h.nees is not None:
                self._a(("wnees", name), Sum).add(c.h.nees[c.good][:, m], 0)

    def second_pass(self) -> None:
        """Start feeding the same chunks again (for the percentiles)."""
        self.pct.second_pass()
        self.passes = 2

    def result(self) -> EstimatorMetrics:
        """The metrics of the runs fed."""
        out = dict(runs_counted=self.good, diverged_runs=self.bad, settle_s=self.settle_s,
                   divergence=self.divergence.result() if self.bad else None)
        if self.good == 0 or not (self.t_s >= self.settle_s).any():
            return EstimatorMetrics(**out)
        acc, p = self.acc, self.pct.value
        fin = [np.concatenate([f[i] for f in self.final]) for i in range(3)]
        out.update(
            rms=ErrorStats(*(np.sqrt(acc[("sq", n)].mean()).tolist() for n in ERRORS)),
            max_abs=ErrorStats(*(acc[("max", n)].value(3).tolist() for n in ERRORS)),
            p99=ErrorStats(*([p(("p99", n, j)) for j in range(3)] for n in ERRORS)),
            convergence_s=convergence_time(self.t_s, np.sqrt(acc["conv"].mean())),
            final=ErrorStats(*(np.sqrt(np.nanmean(f ** 2, axis=0)).tolist() for f in fin)),
            resets=None if self.resets is None else reset_metrics(self.resets),
            cost=cost_metrics(sum_cost(self.costs)),
            windows={name: self._window(name, a, b) for name, a, b in self.windows},
            wind=self.samples.wind())
        if self.has_euler:
            out["attitude"] = AttitudeStats([p(("att_p95", j)) for j in range(3)],
                                            np.sqrt(acc["e_sq"].mean()).tolist(), acc["e_max"].value(3).tolist(),
                                            [p(("att_about", j)) for j in range(3)])
        if self.has_nees:
            out.update(nees=self._nees(), nis=self._nis())
        out["ci95"] = self._intervals()
        return EstimatorMetrics(**out)

    def _intervals(self) -> dict:
        """The 95 % intervals of the metrics (:mod:`navsim.scoring.samples`), the percentiles'
        (Woodruff's) among them; a maximum has none."""
        bands = {}
        if self.has_nees:
            bands["nees"] = self._nees_bands()[1:]
            for key, d in self.nis_dim.items():
                s = self.acc.get(("nis", key))
                if s is not None and (s.n > 0).any():
                    bands[("nis", key)] = (s.n > 0, *chi2_band(d, int(np.median(s.n[s.n > 0]))))
        out = self.samples.intervals(self.t_s, self.settle_s, self.good, bands)
        if not out:
            return None
        iv = self.pct.interval
        out["p99"] = {n: [iv(("p99", n, j)) for j in range(3)] for n in ERRORS}
        if self.has_euler:
            out["attitude"].update(p95_deg=[iv(("att_p95", j)) for j in range(3)],
                                   p95_about_run_mean_deg=[iv(("att_about", j)) for j in range(3)])
        for name, _, _ in self.windows:
            for key in self.quantities:
                if ("win", name, key) in self.pct.q:
                    out["windows"].setdefault(name, {}).setdefault(key, {})["p95_abs"] = iv(("win", name, key))
        return rounded(out)

    def _nees_bands(self):
        """The epochs the NEES is scored at, and each one's band (its own number of runs)."""
        sel = (self.t_s >= self.settle_s) & (self.t_s > 0)
        return (sel, *chi2_bands(NEES_DIM, np.maximum(self.acc["nees_finite"].n[sel], 1)))

    def _window(self, name: str, a: float, b: float) -> Window:
        acc = self.acc
        stats = {key: QuantityStats(float(acc[("wmax", name, key)].value()), float(acc[("wmin", name, key)].value()),
                                    acc[("wmom", name, key)].std(), float(np.sqrt(acc[("wsq", name, key)].mean())),
                                    self.pct.value(("win", name, key)))
                 for key in self.quantities if ("wmom", name, key) in acc}
        if not self._mask(a, b).any():
            return Window(stats)
        nees = None
        if self.has_nees:
            lo, hi = chi2_band(NEES_DIM, self.good)
            mean = acc[("wnees", name)].mean()
            nees = WindowNees(float(np.nanmean(mean)), float(np.mean((mean > lo) & (mean < hi))))
        root = lambda key: float(np.sqrt(acc[key, name].mean()))
        return Window(stats, HorizontalStats(root("whor"), root("whor_end"), root("whor_max")), nees)

    def _nees(self) -> Nees:
        mean_all = self.acc["nees"].mean()
        # the band of each epoch's own number of runs (closed-loop runs end at their landing)
        sel, lo_e, hi_e = self._nees_bands()
        mean = mean_all[sel]
        return Nees(float(np.nanmean(mean)), list(chi2_band(NEES_DIM, self.good)),
                    float(np.mean((mean > lo_e) & (mean < hi_e))), NEES_DIM, float(np.nanmean(mean_all[1:])),
                    self.acc["nsq"].mean().tolist() if "nsq" in self.acc else None)

    def _nis(self) -> dict:
        out = {}
        for key, d in self.nis_dim.items():
            s = self.acc.get(("nis", key))
            cols = s.n > 0 if s is not None else np.zeros(0, bool)
            if not cols.any():
                continue
            per_epoch = s.s[cols] / s.n[cols]
            lo, hi = chi2_band(d, int(np.median(s.n[cols])))
            out[key] = Nis(float(np.nanmean(per_epoch)), [lo, hi], d,
                           float(np.mean((per_epoch > lo) & (per_epoch < hi))))
        return out


def score(h: EstimatorHistory, settle_s: float = 0.0, windows=(), good=None, runs=None) -> EstimatorMetrics:
    """The metrics of one history held in memory (a stream of one chunk).

    Parameters
    ----------
    h : EstimatorHistory
    settle_s, windows
        As :class:`EstimatorScore`.
    good : (B,) bool, optional
        The runs counted (default: those not diverged).
    runs : (B,) int, optional
        The run numbers of the rows, for the diverged runs' list (default 0, 1, ...).
    """
    s = EstimatorScore(settle_s, windows)
    s.add(h, good, runs)
    s.second_pass()
    s.add(h, good, runs)
    return s.result()


@dataclass(frozen=True)
class RunScores:
    """What :func:`score_run` finds: per estimator label its metrics and its runs' samples
    (the ratio-of-sums metrics run by run, :mod:`navsim.records.samples`), per calibrated
    magnetometer its score."""

    estimators: dict[str, EstimatorMetrics]
    calibration: dict[str, CalibrationScore]
    samples: dict[str, EstimatorSamples]


def score_run(parts, settle_s: float = 0.0, windows=(), sightings=()) -> RunScores:
    """What a run is scored on, from its chunk parts: estimator label ->
    :class:`~navsim.records.metrics.EstimatorMetrics` (with ``landmarks`` for an estimator with
    a covariance when there are ``sightings``) and its runs' samples, and magnetometer name ->
    :class:`~navsim.records.metrics.CalibrationScore`.

    Parameters
    ----------
    parts : callable
        ``parts()`` yields the :class:`~navsim.records.chunk.ChunkPart` in run order; called
        twice.
    settle_s, windows
        As :class:`EstimatorScore`.
    sightings : sequence of (name, start_s, end_s, sigma_m)
        The landmark sightings (:func:`~navsim.sensors.camera.flight_sightings`).
    """
    scores, thin, calib = {}, {}, {}
    for part in parts():
        for label, h in part.histories.items():
            scores.setdefault(label, EstimatorScore(settle_s, windows)).add(h, runs=part.runs)
            if sightings and h.sigma is not None:
                thin.setdefault(label, []).append(thin_for_sightings(h, sightings))
        for name, c in part.calibration.items():
            calib.setdefault(name, []).append(thin_calibration(c))
    for s in scores.values():
        s.second_pass()
    for part in parts():
        for label, h in part.histories.items():
            scores[label].add(h, runs=part.runs)
    out = {label: s.result() for label, s in scores.items()}
    samples = {label: s.samples.table() for label, s in scores.items()}
    for label, pieces in thin.items():
        joined = SightingEpochs(pieces[0].t_s, np.concatenate([p.pos_err_m for p in pieces]),
                                np.concatenate([p.diverged for p in pieces]))
        m, ci = out[label], sighting_intervals(joined, sightings)
        out[label] = replace(m, landmarks=sighting_metrics(joined, sightings),
                             ci95={**m.ci95, "landmarks": rounded(ci)} if m.ci95 is not None and ci else m.ci95)
        s, n = sighting_sums(joined, sightings)
        if len(s) == len(samples[label].runs):
            samples[label].metrics["landmarks.rms_after_m"] = MetricSamples(s[:, None], n[:, None], True)
    cal = {name: calibration_score(CalibrationHistory.concatenate(ps)) for name, ps in calib.items()}
    return RunScores(out, cal, samples)


def score_parts(parts, settle_s: float = 0.0, windows=()) -> dict:
    """Label -> :class:`~navsim.records.metrics.EstimatorMetrics` over chunk parts (as
    :func:`score_run`)."""
    return score_run(parts, settle_s, windows).estimators

