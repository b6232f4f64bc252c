"""The batched Monte Carlo loop: one Python loop over time, every estimator and run inside it.

:func:`run_batch` draws each run's initial navigation errors from its own random stream, starts
every estimator from them, feeds the IMU increments at the IMU rate and the other sensors at
each estimator's filter epochs, and records at every epoch the errors against the truth, the
filter's 1-sigma, NEES and the innovations' NIS (:class:`EstimatorHistory`).

A run of an estimator is flagged diverged, and stays flagged, at the first recorded epoch where
its solution is not finite, its navigation covariance is not a covariance
(:func:`covariance_faults`: not finite, not symmetric, or not positive semi-definite by a
Cholesky factorisation), its NEES exceeds :data:`NEES_BOUND`, or the estimator itself reports
it; the time and the cause go to :attr:`EstimatorHistory.divergence`. An exception raised by an
estimator flags all its runs of the batch with the exception as the cause, and the loop goes on
without it (NaN errors from there) while the other estimators continue.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from navsim.foundations import earth
from navsim.foundations.transform import rotation
from navsim.navigation.kernels import records as kernels
from navsim.navigation.strapdown import NavState, state_from_truth
from navsim.records.cost import compile_seconds, compute_clock
from navsim.records.history import EPOCH_ARRAYS, RECORD_DTYPES, EstimatorHistory, epoch_shape
from navsim.records.states import ATT, BLOCKS, POS, SIGMA_STATES, VEL
from navsim.sensors.base import Measurements, run_generators

log = logging.getLogger(__name__)
ARCSEC = math.pi / 180 / 3600
#: NEES (9 navigation errors) above which a run is flagged diverged: an error of 1e6 sigma,
#: which no working filter reaches (a consistent one averages 9)
NEES_BOUND = 1e12
#: largest asymmetry of a covariance scaled to a unit diagonal, relative to its largest entry
SYMMETRY_TOL = 1e-6
#: the scaled covariance plus this times the identity must have a Cholesky factorisation
#: (positive semi-definite up to rounding: a zero initial uncertainty is not a divergence)
PSD_TOL = 1e-9


#: the field of :class:`InitialErrors` that holds each block of the states (as an error budget names them)
DRAWN_FIELDS = {"att": "att_rad", "vel": "vel_mps", "pos": "pos_m"}


@dataclass(frozen=True)
class InitialErrors:
    """1-sigma initial errors drawn per run: position NED (m), velocity NED (m/s), attitude
    (rad, about N, E, D). P0: 5, 5, 10 m; 0.1 m/s; 20", 20", 50". P3: 5, 5, 3 m; 0.2, 0.2,
    0.1 m/s; 1', 1', 1'. ``fixed``: use the sigmas as the errors themselves. ``drawn``: the
    blocks the truth starts off by (an error budget's run of one source leaves the others at
    0, each block's draw the one it has with all drawn); a filter's initial covariance keeps
    every sigma."""

    pos_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    vel_mps: np.ndarray = field(default_factory=lambda: np.zeros(3))
    att_rad: np.ndarray = field(default_factory=lambda: np.zeros(3))
    fixed: bool = False
    drawn: tuple[str, ...] = ("att", "vel", "pos")

    def draw(self, seed: int, runs) -> np.ndarray:
        """``(B, 9)`` errors of the runs, in the order of
        :data:`~navsim.records.states.SIGMA_STATES` (att rad, vel m/s, pos NED m)."""
        sig = np.empty(len(SIGMA_STATES))
        for name, block in BLOCKS.items():
            sig[block] = getattr(self, DRAWN_FIELDS[name]) if name in self.drawn else 0.0
        if self.fixed:
            return np.broadcast_to(sig, (len(list(runs)), sig.size)).copy()
        return np.stack([g.standard_normal(sig.size) for g in run_generators(seed, runs, "initial")]) * sig

    def sigma_blocks(self, lat_rad: float, h_m: float) -> dict:
        """The 1-sigma of each block of :data:`~navsim.records.states.BLOCKS` for a filter's
        initial covariance: attitude (rad), velocity (m/s), position as latitude and longitude
        (rad) and height (m) at ``lat_rad``, ``h_m``."""
        r_m, r_n = earth.radii(lat_rad)
        pos = np.array([self.pos_m[0] / (r_m + h_m), self.pos_m[1] / ((r_n + h_m) * math.cos(lat_rad)),
                        self.pos_m[2]])
        return {name: pos if name == "pos" else getattr(self, field) for name, field in DRAWN_FIELDS.items()}


def perturbed_start(truth, errors: np.ndarray, k: int = 0) -> NavState:
    """The true state at sample ``k`` with the drawn errors (estimate minus truth) applied."""
    B = errors.shape[0]
    nav = state_from_truth(truth, k, B)
    nav.C_nb = rotation(-errors[:, ATT]) @ nav.C_nb           # C_est = (I - [phi x]) C
    nav.vel_n_mps = nav.vel_n_mps + errors[:, VEL]
    pos = errors[:, POS]                                       # N, E, D (m)
    r_m, r_n = earth.radii(nav.lat_rad)
    nav.lat_rad = nav.lat_rad + pos[:, 0] / (r_m + nav.h_m)
    nav.lon_rad = nav.lon_rad + pos[:, 1] / ((r_n + nav.h_m) * np.cos(nav.lat_rad))
    nav.h_m = nav.h_m - pos[:, 2]
    return nav


def nav_errors(nav: NavState, truth, k: int):
    """Errors of ``nav`` against truth sample ``k``: attitude phi (rad, ``(B, 3)``), velocity
    (m/s), position NED (m), the position error in the filter's units (dL, dlambda, dh) and
    roll, pitch, yaw minus the truth's, wrapped to [-pi, pi) (compiled, run by run:
    :func:`navsim.navigation.kernels.records.nav_errors`). The truth's sample may be one for all runs or ``(B, ...)``."""
    out = _errors(nav, truth, k)[0]
    return tuple(out[:, c] for c in (_PHI, _DV, _POS_M, _POS_FILTER, _EULER))


#: the columns of :func:`navsim.navigation.kernels.records.nav_errors`' output
_PHI, _DV, _POS_FILTER, _POS_M, _EULER = (slice(i, i + 3) for i in range(0, 15, 3))
#: the errors recorded at every epoch: the :class:`EstimatorHistory` array each fills, and its
#: columns of :func:`navsim.navigation.kernels.records.nav_errors`' output
_RECORDED = {"att_err_rad": _PHI, "vel_err_mps": _DV, "pos_err_m": _POS_M, "euler_err_rad": _EULER}


def _errors(nav: NavState, truth, k: int):
    """The ``(B, 15)`` output of :func:`navsim.navigation.kernels.records.nav_errors` and the truth's ``(1 or B, 13)``
    rows it was computed against."""
    parts = (truth.lat_rad[k], truth.lon_rad[k], truth.h_m[k], truth.vel_n_mps[k], truth.euler_rad[k],
             truth.quat_nb[k])
    if np.ndim(parts[0]) == 0:                       # one true state for all runs
        rows = np.concatenate(parts, axis=None)[None]
    else:
        B = np.shape(parts[0])[0]
        rows = np.concatenate([np.reshape(p, (B, -1)) for p in parts], -1)
    B = nav.lat_rad.shape[0]
    if rows.shape[0] not in (1, B):
        raise ValueError(f"the truth has {rows.shape[0]} runs at sample {k}, the estimate {B}")
    out = np.empty((B, 15))
    f = lambda x: np.ascontiguousarray(x, float)
    kernels.nav_errors(f(nav.lat_rad), f(nav.lon_rad), f(nav.h_m), f(nav.vel_n_mps), f(nav.C_nb), f(rows), out)
    return out, rows


#: the causes of a divergence flag, by code (0: none); :func:`covariance_codes` gives 1-3
CAUSES = (None, "covariance not finite", "covariance not symmetric", "covariance not positive definite",
          "non-finite state", "NEES above bound", "flagged by the estimator")


def covariance_codes(P: np.ndarray) -> np.ndarray:
    """Per run, why the covariance ``P`` is not a covariance: a code of :data:`CAUSES` (0 where
    it is one, 1 not finite, 2 not symmetric, 3 not positive definite).

    The checks run on ``P`` scaled to a unit diagonal (``P_ij / sqrt(P_ii P_jj)``, a zero
    variance left unscaled), so that the attitude (rad), velocity (m/s) and position (rad, m)
    blocks weigh alike: a non-finite entry, a negative variance, an asymmetry above
    :data:`SYMMETRY_TOL` of the largest entry, or no Cholesky factorisation of the scaled
    matrix plus :data:`PSD_TOL` times the identity (not positive semi-definite). Compiled, run
    by run: :func:`navsim.navigation.kernels.records.covariance_codes`.

    Parameters
    ----------
    P : (B, n, n) array
        The covariances of the runs.

    Returns
    -------
    (B,) int array
    """
    codes = np.empty(P.shape[0], np.int64)
    kernels.covariance_codes(np.ascontiguousarray(P, float), SYMMETRY_TOL, PSD_TOL, codes)
    return codes


def covariance_faults(P: np.ndarray) -> list:
    """Per run, the cause (:data:`CAUSES`) why ``P`` is not a covariance, or None
    (:func:`covariance_codes`)."""
    return [CAUSES[c] for c in covariance_codes(P)]


@dataclass(frozen=True)
class _Block:
    """What :meth:`Driver.advance` hands every estimator: the ``(B, K, 3)`` IMU increments of
    the block, the time of its last sample (s), the measurements seen (empty off an epoch), and
    the truth with the sample ``k`` the epochs are recorded against (``truth`` None: no record)."""

    dtheta_b: np.ndarray
    dv_b: np.ndarray
    t_s: float
    sensors: dict
    truth: object
    k: int


class Driver:
    """The time loop of a set of estimators over a batch of runs, shared by open-loop Monte
    Carlo (:func:`run_batch`), the closed loop (:func:`navsim.experiment.closed_loop.fly_batch`) and log
    replay (:func:`navsim.replay.replay`): the initialisation (the navigation blocks of the
    initial uncertainty plus each estimator's ``noise_sigma0``), the epoch cadence (every
    ``period_s`` on the IMU grid), the CPU time of ``propagate`` and of the epochs, and the
    records against the truth (:class:`EstimatorHistory`).

    Parameters
    ----------
    estimators : dict
        Label -> estimator object.
    dt_s : float
        The IMU interval, s.
    runs : int, optional
        The batch size (known before the first record: an estimator that fails at once).
    isolate : bool
        True: an estimator that raises an ``Exception`` has its runs flagged diverged, at the
        time of the block's last sample when ``propagate`` raised, and is not called again (NaN
        records from there), the others go on; False: the exception propagates.
    keep_nis : bool
        Keep every epoch's NIS (:attr:`nis`), also without a truth to record against.
    """

    def __init__(self, estimators: dict, dt_s: float, runs: int | None = None, isolate: bool = True,
                 keep_nis: bool = False):
        self.estimators, self.dt_s, self.isolate = estimators, dt_s, isolate
        self.every = {label: max(1, int(round(est.period_s / dt_s))) for label, est in estimators.items()}
        self.rec = {label: _Recorder(label, runs) for label in estimators}
        self.i = 0          #: the IMU sample the estimators have reached
        self._sensors, self._seen = None, {}
        #: with ``keep_nis``, label -> ``[(t_s, "measurement:sensor", nis (B,), rows)]`` of every
        #: epoch, records against a truth or not (a log replayed without one); else None
        self.nis = {label: [] for label in estimators} if keep_nis else None

    def start(self, nav0: NavState, sigma0: dict, truth=None, k: int = 0) -> None:
        """Initialise every estimator at ``nav0`` with the 1-sigma blocks ``sigma0`` and record
        it against truth sample ``k`` (no record without ``truth``)."""
        for label, est in self.estimators.items():
            rec = self.rec[label]
            try:
                est.initialize(nav0, {**sigma0, **est.noise_sigma0()} if hasattr(est, "noise_sigma0") else sigma0)
                if truth is not None:
                    rec.add(est, truth, k, 0.0, [])
            except Exception as exc:  # one estimator's failure must not stop the others
                self._fail(rec, 0.0, exc, truth is not None and not rec.t)

    def stops(self, n: int) -> np.ndarray:
        """The IMU samples in ``1 .. n-1`` where a block must end: every epoch of every
        estimator, and the last sample."""
        ends = [np.arange(e, n, e) for e in self.every.values()] + [np.array([n - 1])]
        out = np.unique(np.concatenate(ends))
        return out[out >= 1]

    def advance(self, dtheta_b: np.ndarray, dv_b: np.ndarray, t_s: float, sensors: dict, truth=None,
                k: int = 0) -> list:
        """Propagate every estimator over the ``K`` intervals ``(B, K, 3)`` that follow the
        sample reached, and run the epochs that fall on the block's last sample (at ``t_s``, s),
        recorded against truth sample ``k`` (no record without ``truth``). A block must not
        cross an epoch (:meth:`stops`). Returns the labels whose epoch this was."""
        i = self.i + dtheta_b.shape[1]
        for label, e in self.every.items():
            if (self.i // e + 1) * e < i:
                raise ValueError(f"a block of samples {self.i + 1}-{i} crosses an epoch of '{label}'")
        due = [label for label, e in self.every.items() if i % e == 0]
        seen = self._measurements(sensors) if due else {}
        block = _Block(dtheta_b, dv_b, t_s, seen, truth, k)
        for label, est in self.estimators.items():
            self._advance(self.rec[label], est, block, label in due)
        self.i = i
        return due

    def _measurements(self, sensors: dict) -> dict:
        """What the estimators are handed of ``sensors``: their measurements, never the true
        errors (:meth:`~navsim.sensors.base.SensorData.measurements`; the same objects while the
        closed loop fills the same sensors in place)."""
        key = tuple((k, id(d)) for k, d in sensors.items())
        if key != self._sensors:
            self._sensors = key
            self._seen = {k: d if isinstance(d, Measurements) else d.measurements() for k, d in sensors.items()}
        return self._seen

    def _advance(self, rec, est, block: _Block, is_epoch: bool) -> None:
        """One block of one estimator: ``propagate``, and at its epoch ``epoch`` and the record;
        a stopped estimator gets a NaN record at its epochs."""
        dtheta_b, dv_b, t_s, truth = block.dtheta_b, block.dv_b, block.t_s, block.truth
        record = truth is not None
        if rec.failed:
            if is_epoch and record:
                rec.add_nan(t_s)
            return
        clock = compute_clock               # without the kernels' compilation (rec.compile_s)
        recorded = len(rec.t)
        k0 = compile_seconds()
        try:
            c0 = clock()
            est.propagate(dtheta_b, dv_b, self.dt_s)
            c1 = clock()
            rec.propagate_s += c1 - c0
            rec.steps += dtheta_b.shape[1]
            if is_epoch:
                innov = est.epoch(t_s, block.sensors)
                rec.epoch_s += clock() - c1
                rec.epochs += 1
                if self.nis is not None:
                    self.nis[rec.label] += [(t_s, f"{i.measurement}:{i.sensor}", np.array(i.nis), i.y.shape[-1])
                                            for i in innov or []]
                if record:
                    rec.add(est, truth, block.k, t_s, innov)
        except Exception as exc:  # one estimator's failure must not stop the others
            self._fail(rec, t_s, exc, is_epoch and record and len(rec.t) == recorded)
        finally:
            rec.compile_s += compile_seconds() - k0

    def _fail(self, rec, t_s: float, exc: Exception, blank: bool) -> None:
        if not self.isolate:
            raise exc
        rec.fail(t_s, exc)
        if blank:
            rec.add_nan(t_s)

    def cost(self, label: str) -> dict:
        """CPU seconds in ``propagate`` and the epochs of one estimator, with the IMU intervals
        and the epochs they covered."""
        r = self.rec[label]
        return {"propagate_s": r.propagate_s, "epoch_s": r.epoch_s, "steps": r.steps, "epochs": r.epochs}

    def histories(self) -> dict[str, EstimatorHistory]:
        """Label -> :class:`EstimatorHistory` of the records so far, once: the recorders hand
        their records over (``_Recorder._stacked``); call it at the end of the batch."""
        return {label: r.history(self.estimators[label]) for label, r in self.rec.items()}


@dataclass(frozen=True)
class Batch:
    """The runs of a batch: the initial errors drawn for each (``initial``), the seed of their
    random streams and the run indices (:meth:`InitialErrors.draw`); ``start``, when given, the
    state the runs start from instead of the truth's first with the drawn errors (a log's
    start), the filters' initial 1-sigma still ``initial``'s."""

    initial: InitialErrors
    seed: int
    runs: Sequence[int]
    start: NavState | None = None


def run_batch(truth, imu, sensors: dict, estimators: dict, batch: Batch, progress=None) -> dict[str, EstimatorHistory]:
    """Run ``estimators`` (label -> estimator object) on the runs of ``batch``.

    ``imu`` is the IMU :class:`~navsim.sensors.base.SensorData` of these runs, or an
    :class:`~navsim.sensors.imu.ImuStream` generating it block by block, ``sensors`` the other
    sensors' data by name. All estimators share the time loop (:class:`Driver`) and the
    initial errors; each ``propagate`` gets the IMU increments up to the next epoch of any
    estimator, so Python runs once per filter epoch, not once per IMU sample. An estimator that
    raises (an ``Exception``) in ``initialize``, ``propagate``, ``epoch`` or ``solution`` has
    all its runs flagged diverged with the exception as the cause and is not called again; its
    errors are NaN from there, and the other estimators go on.
    """
    runs = list(batch.runs)
    errors = batch.initial.draw(batch.seed, runs)
    dt = imu.meta["dt_s"]
    step = int(round(dt / truth.dt_s))
    driver = Driver(estimators, dt, len(runs))
    nav0 = perturbed_start(truth, errors, 0) if batch.start is None else batch.start
    driver.start(nav0, batch.initial.sigma_blocks(truth.lat_rad[0], truth.h_m[0]), truth, 0)
    if hasattr(imu, "block"):                    # an ImuStream: generated block by block
        blocks = lambda a, b: imu.block(a, b)[0]
    else:
        dth, dv = imu.values["dtheta_b_rad"], imu.values["dv_b_mps"]
        blocks = lambda a, b: (dth[:, a:b], dv[:, a:b])
    n = len(imu.t_s)
    for i in driver.stops(n):
        i0 = driver.i + 1
        driver.advance(*blocks(i0, i + 1), imu.t_s[i], sensors, truth, i * step)
        if progress is not None and i // 1000 > (i0 - 1) // 1000:
            progress(i, n)
    return driver.histories()


#: the limits of :func:`navsim.navigation.kernels.records.covariance_record`
_LIMITS = np.array([SYMMETRY_TOL, PSD_TOL, NEES_BOUND])


class _Recorder:
    """The records of one estimator over the batch, its divergence flags and their causes."""

    def __init__(self, label, runs: int | None = None):
        self.label = label
        self.t: list = []
        #: per epoch array of the history (:data:`~navsim.records.history.EPOCH_ARRAYS`), its
        #: ``(B, ...)`` records, one per epoch (none: the estimator has no such array)
        self.records: dict = {name: [] for name in EPOCH_ARRAYS}
        self.nis: dict = {}
        self.nis_dim: dict = {}
        self.propagate_s = self.epoch_s = self.compile_s = 0.0
        self.steps = self.epochs = 0
        self.runs = runs
        self.flagged = None if runs is None else np.zeros(runs, bool)
        self.why: list = [None] * (runs or 0)
        self.failed = False          #: the estimator raised: not called again
        self.extra: dict = {}        #: its last solution's ``extra``

    def add(self, est, truth, k, t, innovations):
        """Record the estimator's solution against truth sample ``k`` at time ``t`` (s)."""
        sol = est.solution()
        err, rows = _errors(sol.nav, truth, k)
        row = {name: err[:, c] for name, c in _RECORDED.items()}
        B = err.shape[0]
        code, nees, sig = np.zeros(B, np.int64), None, None
        if sol.P_nav is not None:
            nees, sig = np.empty(B), np.empty((B, 9))
            kernels.covariance_record(np.ascontiguousarray(sol.P_nav, float), err, rows, _LIMITS, sig, nees, code)
        else:
            code[~np.isfinite(err).all(-1)] = 4
        nis = [(f"{inn.measurement}:{inn.sensor}", inn.nis, inn.y.shape[-1]) for inn in innovations]
        self._check(t, sol, code)
        self.t.append(t)
        if sol.gyro_bias is not None:
            row.update(gyro_bias=sol.gyro_bias.copy(), accel_bias=sol.accel_bias.copy())
        if sol.gyro_bias_sigma is not None or sol.accel_bias_sigma is not None:
            row.update({name: np.full(epoch_shape(name, B), np.nan) if s is None else np.array(s, dtype=np.float64)
                        for name, s in (("gyro_bias_sigma", sol.gyro_bias_sigma),
                                        ("accel_bias_sigma", sol.accel_bias_sigma))})
        if sol.wind_n_mps is not None:
            wind = np.array(sol.wind_n_mps, float)
            row.update(wind_n_mps=wind, wind_sigma_mps=np.array(sol.wind_sigma_mps, float),
                       wind_err_mps=wind - truth.wind_steady_n_mps[k])
        if nees is not None:
            row.update(nees=nees, sigma=sig)
        for name, v in row.items():          # in the dtype of the record: the lists hold no more
            self.records[name].append(np.asarray(v, RECORD_DTYPES[name]))     # than the array
        for key, v, dim in nis:
            self.nis.setdefault(key, []).append((len(self.t) - 1, v))
            self.nis_dim[key] = dim
        self.extra = sol.extra

    def _check(self, t, sol, code: np.ndarray) -> None:
        """Flag the runs not flagged yet whose solution at ``t`` has diverged, with the cause:
        ``code`` (:data:`CAUSES`) from the errors and the covariance, then the estimated
        biases (not finite: 4) and the estimator's own flag (6)."""
        B = code.shape[0]
        if self.flagged is None:
            self.runs, self.flagged, self.why = B, np.zeros(B, bool), [None] * B
        if self.flagged.all():
            return
        biases = [x for x in (sol.gyro_bias, sol.accel_bias) if x is not None]
        if biases:
            code[~np.isfinite(np.concatenate(biases, -1)).all(-1)] = 4
        own = np.asarray(sol.extra.get("diverged", False), bool)
        code[(code == 0) & own] = 6
        code[self.flagged] = 0
        why = [CAUSES[c] for c in code]
        for b, raised in enumerate(sol.extra.get("causes") or ()):     # a run's own exception
            if raised and code[b]:
                why[b] = f"raised {raised}"
        self._flag(t, why if code.any() else [])

    def _flag(self, t, cause: list) -> None:
        for b, c in enumerate(cause):
            if c is not None and not self.flagged[b]:
                self.flagged[b] = True
                self.why[b] = (float(t), c)

    def fail(self, t, exc: Exception) -> None:
        """The estimator raised ``exc`` at ``t`` (s): flag every run not flagged yet with it,
        and log it with its traceback (a bug in an estimator must not pass for a divergence).
        A :class:`MemoryError` is raised again: it is the machine's, not the filter's."""
        if isinstance(exc, MemoryError):
            raise exc
        log.warning("estimator '%s' raised at t = %.2f s; its %s runs of this batch are flagged diverged",
                    self.label, t, self.runs, exc_info=exc)
        self.failed = True
        if self.flagged is not None:
            self._flag(t, [f"{type(exc).__name__}: {exc}"] * self.runs)

    def add_nan(self, t) -> None:
        """A record of NaN errors at ``t`` (s), for an estimator that has stopped."""
        self.t.append(t)
        for name, xs in self.records.items():
            if xs or name in _RECORDED:          # the errors always, the others if recorded
                xs.append(np.full(epoch_shape(name, self.runs), np.nan, RECORD_DTYPES[name]))

    def _stacked(self, name: str) -> np.ndarray | None:
        """The epoch records of ``name`` as one ``(B, E, ...)`` array of its record dtype
        (:data:`~navsim.records.history.RECORD_DTYPES`), the per-epoch arrays dropped as they are
        copied (the chunk's peak memory: one copy, not two); None if never recorded. The records
        are handed over once: :meth:`history` is the recorder's last call."""
        xs = self.records[name]
        if not xs:
            return None
        out = np.empty((xs[0].shape[0], len(xs), *xs[0].shape[1:]), RECORD_DTYPES[name])
        for e in range(len(xs)):
            out[:, e] = xs[e]
            xs[e] = None
        xs.clear()
        return out

    def history(self, est) -> EstimatorHistory:
        E = len(self.t)
        nis = {}
        for key, items in self.nis.items():
            arr = np.full((items[0][1].shape[0], E), np.nan)
            for e, v in items:
                arr[:, e] = v
            nis[key] = arr
        extra = self.extra
        if not self.failed:
            try:
                extra = est.solution().extra
            except Exception as exc:  # one estimator's failure must not stop the others
                self.fail(self.t[-1], exc)
        arrays = {name: self._stacked(name) for name in self.records}
        diverged = np.asarray(extra.get("diverged", False)) | ~np.all(np.isfinite(arrays["pos_err_m"]), axis=(1, 2))
        self._flag(self.t[-1], ["flagged by the estimator" if d else None
                                for d in np.broadcast_to(diverged, (self.runs,))])
        return EstimatorHistory(
            label=self.label, t_s=np.array(self.t), **arrays, nis=nis, nis_dim=self.nis_dim,
            diverged=diverged | self.flagged,
            cost={"propagate_s": self.propagate_s, "epoch_s": self.epoch_s, "runs": len(arrays["pos_err_m"]),
                  "epochs": E - 1, "batches": 1, "compile_s": self.compile_s},
            resets=_copy_resets(extra.get("resets")), divergence=list(self.why))


def _copy_resets(resets):
    return None if resets is None else [list(r) for r in resets]
