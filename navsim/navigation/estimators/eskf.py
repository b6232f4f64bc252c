"""Closed-loop error-state Kalman filter for SINS aided by any set of measurement models
(P3's 15 states, P0's 16, P2's 18, or any :class:`Layout`).

The strapdown mechanization (:class:`~navsim.navigation.strapdown.BlockStrapdown`, compiled) runs at the
IMU rate on bias-compensated increments, a block of them per ``propagate``; every
``period_s`` the filter predicts with ``F`` built from the navigation state averaged over the
period (``C_nb`` and the specific force in NED), by the matrix-exponential series (P3) or
Van Loan (from the sixth order, the Taylor series of the covariance equation itself, compiled,
in place: :func:`_covariance_series_fits`), then applies each available
measurement with the Joseph form (all of them in one compiled call), and feeds the
estimated errors back: attitude, velocity and position into the mechanization, biases into the
IMU compensation. The sensor-error states ``baro`` and ``pitot_bias`` stay in the filter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navsim.foundations.config import MAX_DURATION_S, MAX_TIME_CONSTANT_S, MAX_WIND_MPS, Node, close_match
from navsim.foundations.jsonschema import MEASUREMENT, POS, obj
from navsim.navigation.estimators import kalman
from navsim.navigation.estimators.base import Innovation, Solution, register, sample
from navsim.navigation.estimators.error_model import (
    BLOCK_SIZES,
    GUST_AXES,
    WIND_AXES,
    PRESETS,
    Layout,
    ProcessNoise,
    add_markov_decay,
    process_noise,
    system_matrix,
)
from navsim.navigation.estimators.measurements import (
    build_measurements,
    check_observed_states,
    compiled_form,
    parse_measurements,
    stack_models,
)
from navsim.navigation.kernels.update import feed_back
from navsim.navigation.strapdown import BlockStrapdown, NavState
from navsim.sensors.catalog import load_spec
from navsim.sensors.specs import ImuSpec

FEEDBACK = ("att", "vel", "pos", "gyro_bias", "accel_bias", "gyro_markov", "accel_markov")
#: the models of a wind state
WIND_MODELS = ("markov", "random_walk")


@dataclass(frozen=True)
class EpochSettings:
    """How an :class:`ErrorStateKF` runs its epochs: their period, how the covariance is carried
    over one, which sample of a sensor it takes and how it evaluates the measurement models
    (the parameters of the same names in :class:`ErrorStateKF`)."""

    period_s: float = 1.0           #: the filter period, s
    discretization: str = "series"  #: ``series`` or ``van_loan``
    series_order: int = 6           #: the order of the ``series``
    latest_sample: bool = False     #: each sensor's latest sample since the last epoch, not the one at it
    compiled_models: bool = True    #: each measurement model by its compiled form where it has one


@dataclass(frozen=True)
class ExtraStates:
    """The models of the error states an IMU spec does not give (:meth:`ErrorStateKF.from_imu_spec`):
    the baro error's (first-order Markov) and the air mass's, as :func:`filter_params` reads them."""

    baro_sigma_m: float = 0.0       #: the baro error's 1-sigma, m (0: no baro state)
    baro_tau_s: float = 300.0       #: its correlation time, s
    wind: dict | None = None        #: the wind's model (:func:`filter_params`' ``wind``); None: none
    gust: dict | None = None        #: the gusts' model (:func:`filter_params`' ``gust``); None: none


@register("eskf")
class ErrorStateKF:
    """Parameters
    ----------
    layout : Layout
        The error-state blocks.
    noise : ProcessNoise
        The filter's own noise model.
    measurements : list
        Measurement models (see :mod:`navsim.navigation.estimators.measurements`).
    epochs : EpochSettings
        How it runs its epochs:

        ``period_s``: the filter period (P0, P3: 1 s).
        ``latest_sample``: False, a measurement is taken when its sensor has a sample at the
        epoch (simulated sensors, on the truth's grid); True, each sensor's latest sample since
        the last epoch (a replayed log, whose sensors do not fall on the epochs).
        ``discretization``: ``series``, the matrix-exponential series to ``series_order`` (P3
        uses 3; over a 1 s period the noise reaching the position through attitude and velocity
        needs 6); from order 6, with no state decaying faster than 5 % per period, the
        propagated covariance is the Taylor series of its own equation instead (the same to
        rounding, a third of the work: :data:`SERIES_MIN_ORDER`); ``van_loan``, exact, about
        six times slower.
        ``compiled_models``: True, each measurement model is evaluated by its compiled form
        where it has one (the shipped types all do; the same numbers to rounding); False, by
        its Python ``model``.
    initial_sigma : dict or None
        Initial 1-sigma of the sensor-error blocks (:meth:`noise_sigma0`), beside those the
        measurement models' ``state_sigma`` give.
    """

    #: the JSON Schema of its entry's keys (beside ``label`` and ``type``), for ``navsim schema``
    SCHEMA = {"states": {"oneOf": [{"enum": list(PRESETS)}, {"type": "array", "items": {"enum": list(BLOCK_SIZES)}}]},
              "period_s": POS, "discretization": {"enum": ["series", "van_loan"]},
              "series_order": {"type": "integer", "minimum": 1}, "latest_sample": {"type": "boolean"},
              "noise": obj({"imu": {"type": "string"}, "override": {"type": "object"}}, ["imu"]),
              "baro": obj({"sigma_m": POS, "tau_s": POS}),
              "wind": obj({"model": {"enum": list(WIND_MODELS)}, "sigma_mps": POS, "sigma_down_mps": POS,
                           "tau_s": POS, "walk_mps_per_rts": POS, "walk_down_mps_per_rts": POS}, ["sigma_mps"]),
              "gust": obj({"sigma_mps": POS, "sigma_down_mps": POS, "tau_s": POS, "tau_down_s": POS},
                          ["sigma_mps", "tau_s"]),
              "measurements": {"type": "array", "items": MEASUREMENT}}

    def __init__(self, layout: Layout, noise: ProcessNoise, measurements,
                 epochs: EpochSettings = EpochSettings(), initial_sigma: dict | None = None):
        if epochs.discretization not in ("series", "van_loan"):
            raise ValueError(f"discretization '{epochs.discretization}': expected series or van_loan")
        self.layout, self.noise, self.measurements = layout, noise, list(measurements)
        self.period_s, self.discretization = epochs.period_s, epochs.discretization
        self.series_order, self.latest_sample = epochs.series_order, epochs.latest_sample
        self.compiled_models, self._forms = epochs.compiled_models, None
        self.initial_sigma = dict(initial_sigma or {})
        for m in self.measurements:         # the sensor-error states a measurement model observes
            self.initial_sigma.update(getattr(m, "state_sigma", {}))
        self.Qc = process_noise(layout, noise)

    @classmethod
    def from_imu_spec(cls, layout: Layout, imu_spec, measurements,
                      extra_states: ExtraStates = ExtraStates(), **kw):
        """A filter whose noise model and initial bias uncertainty come from an IMU spec (a
        catalog entry of its own: it need not be the spec that corrupted the data), those of the
        other states from ``extra_states`` (the baro error, the wind, the gusts); ``kw``: the
        constructor's other arguments (``epochs``, a subclass's own)."""
        g, a = imu_spec.gyro, imu_spec.accel
        baro_sigma_m, baro_tau_s = extra_states.baro_sigma_m, extra_states.baro_tau_s
        w = extra_states.wind or {"walk_mps_per_rts": 0.0, "walk_down_mps_per_rts": 0.0, "tau_s": math.inf,
                                  "sigma_mps": 0.0, "sigma_down_mps": 0.0}
        gu = extra_states.gust or {"sigma_mps": 0.0, "sigma_down_mps": 0.0, "tau_s": 1.0, "tau_down_s": 1.0}
        noise = ProcessNoise(
            gyro_white=g.noise_density, accel_white=a.noise_density,
            gyro_bias_walk=g.random_walk, accel_bias_walk=a.random_walk,
            gyro_markov_sigma=np.maximum(g.markov_sigma, 1e-12), gyro_markov_tau_s=g.markov_tau_s,
            accel_markov_sigma=np.maximum(a.markov_sigma, 1e-12), accel_markov_tau_s=a.markov_tau_s,
            baro_sigma=baro_sigma_m, baro_tau_s=baro_tau_s, wind_walk=w["walk_mps_per_rts"],
            wind_down_walk=w["walk_down_mps_per_rts"], wind_tau_s=w["tau_s"],
            gust_sigma=gu["sigma_mps"], gust_down_sigma=gu["sigma_down_mps"], gust_tau_s=gu["tau_s"],
            gust_down_tau_s=gu["tau_down_s"])
        sigma = {"gyro_bias": np.hypot(g.bias_sigma, g.bias), "accel_bias": np.hypot(a.bias_sigma, a.bias),
                 "gyro_markov": g.markov_sigma, "accel_markov": a.markov_sigma,
                 "baro": np.array([baro_sigma_m]), "wind": np.full(2, w["sigma_mps"]),
                 "wind_down": np.array([w["sigma_down_mps"]]), "gust": np.full(2, gu["sigma_mps"]),
                 "gust_down": np.array([gu["sigma_down_mps"]])}
        return cls(layout, noise, measurements, initial_sigma=sigma, **kw)

    # --- from a scenario entry -----------------------------------------------------------------
    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """The entry's ``states`` (a preset or a list of blocks), ``period_s`` (1 s),
        ``discretization`` (``series``), ``series_order`` (6), ``noise: {imu, override}`` (the
        filter's own IMU model, a catalog entry), ``baro: {sigma_m, tau_s}`` (the baro Markov
        state's model) and ``measurements`` (registered models); a subclass adds its keys."""
        params = {**filter_params(node), "measurements": parse_measurements(node, sensors)}
        check_observed_states(node, params["states"], params["measurements"])
        return params

    @classmethod
    def from_params(cls, params: dict):
        """The filter of :meth:`parse`'s parameters, with :meth:`options`."""
        p = params
        return cls.from_imu_spec(Layout(tuple(p["states"])), load_spec(p["noise"]["imu"], p["noise"]["override"]),
                                 build_measurements(p["measurements"]), **filter_options(p), **cls.options(p))

    #: the key of :meth:`parse`'s parameters that holds a subclass's own constructor arguments
    #: (None: it has none)
    OPTIONS: str | None = None

    @classmethod
    def options(cls, params: dict) -> dict:
        """A subclass's own constructor arguments from its parameters: those under its
        :attr:`OPTIONS` key (none here)."""
        return {} if cls.OPTIONS is None else params[cls.OPTIONS]

    def noise_sigma0(self) -> dict:
        """Initial 1-sigma of the sensor-error blocks (the runner adds the navigation blocks)."""
        return self.initial_sigma

    # --- contract -----------------------------------------------------------------------------
    def initialize(self, nav0: NavState, sigma0: dict) -> None:
        """``sigma0``: 1-sigma per block (arrays of the block's size), e.g. ``{"att": ...}``."""
        B = nav0.lat_rad.shape[0]
        self.sd = BlockStrapdown(nav0.copy())
        n = self.layout.n
        self.x = np.zeros((B, n))
        var = np.zeros(n)
        for block in self.layout.blocks:
            if block in sigma0:
                var[self.layout.slice(block)] = np.asarray(sigma0[block], float) ** 2
        self.P = np.broadcast_to(np.diag(var), (B, n, n)).copy()
        self.b_gyro = np.zeros((B, 3))
        self.b_accel = np.zeros((B, 3))
        self.m_gyro = np.zeros((B, 3))      # Markov parts, decaying
        self.m_accel = np.zeros((B, 3))
        self._reset_accumulators()
        self.diverged = np.zeros(B, bool)
        self._t_prev = -np.inf              # the last epoch (latest_sample: the window's start)
        self._forms = None                  # the compiled forms, built at the first epoch

    def propagate(self, dtheta_b: np.ndarray, dv_b: np.ndarray, dt: float) -> None:
        """Mechanize the increments ``(B, K, 3)`` less the estimated biases."""
        self.sd.block(dtheta_b, dv_b, dt, self.b_gyro + self.m_gyro, self.b_accel + self.m_accel)
        self._elapsed = self.sd.steps * dt          # whatever the blocks the period was cut into

    def follow(self, nav: NavState, sum_C_nb: np.ndarray, sum_dv_n_mps: np.ndarray, steps: int, dt: float) -> None:
        """Take ``steps`` IMU intervals of ``dt`` as flown instead of mechanizing increments (a
        covariance analysis along the truth, :mod:`navsim.navigation.covariance`): ``nav`` the
        state at their end, their sums of ``C_nb`` and of the specific-force increments in NED."""
        self.sd.follow(nav, sum_C_nb, sum_dv_n_mps, steps)
        self._elapsed = self.sd.steps * dt

    def epoch(self, t: float, sensors: dict) -> list[Innovation]:
        self.predict()
        since = self._since(t)
        taken = [(m, c, data, j) for m, c in zip(self.measurements, self._compiled_forms())
                 for data, j in [sample(sensors, m.sensor, t, since)] if j is not None]
        if self._own_corrections():         # all of them in one compiled call
            st = stack_models(taken, self.sd.state, self.layout)
            u = kalman.update_stacked(self.x, self.P, st.z, st.H, st.R, st.valid, st.ends)
            self.diverged |= u.bad
            out = [Innovation(m.name, m.sensor, t, y, S, nis)
                   for (m, _, _, _), y, S, nis in zip(taken, u.y, u.S, u.nis)]
        else:
            out = [self.correct(m, data, j, t) for m, _, data, j in taken]
        self.feedback()
        return out

    def _compiled_forms(self) -> list:
        """Each measurement model's compiled form (None: its Python ``model``), in the order of
        ``measurements``, built at the first epoch; all None with ``compiled_models`` False or
        when a subclass corrects one model at a time."""
        if getattr(self, "_forms", None) is None:     # a subclass may not have called __init__
            own = getattr(self, "compiled_models", True) and self._own_corrections()
            self._forms = [compiled_form(m, self.layout) if own else None for m in self.measurements]
        return self._forms

    def _since(self, t: float) -> float | None:
        """The start of the window :func:`~navsim.navigation.estimators.base.sample` reads at the
        epoch ``t``: the last epoch with ``latest_sample``, else None (the sample at ``t``)."""
        since = self._t_prev if self.latest_sample else None
        self._t_prev = t
        return since

    def _own_corrections(self) -> bool:
        """Whether ``correct`` and ``measurement_noise`` are this class's (a subclass that
        adapts them gets its corrections one at a time)."""
        cls = type(self)
        return cls.correct is ErrorStateKF.correct and cls.measurement_noise is ErrorStateKF.measurement_noise

    def navigation(self) -> NavState:
        """The navigation state alone (the estimator contract's optional hook); a subclass that
        overrides :meth:`solution` gets its ``solution().nav``."""
        if type(self).solution is not ErrorStateKF.solution:
            return self.solution().nav
        return self.sd.state

    def solution(self) -> Solution:
        idx = np.r_[self.layout.slice("att"), self.layout.slice("vel"), self.layout.slice("pos")]
        if np.array_equal(idx, np.arange(9)):           # the navigation blocks first: one copy
            P_nav = self.P[:, :9, :9].copy()
        else:
            P_nav = self.P[:, idx][:, :, idx]
        sg, sa = self._bias_sigma()
        return Solution(nav=self.sd.state, P_nav=P_nav,
                        gyro_bias=self.b_gyro + self.m_gyro, accel_bias=self.b_accel + self.m_accel,
                        gyro_bias_sigma=sg, accel_bias_sigma=sa, **self._wind(),
                        extra={"P": self.P, "diverged": self.diverged})

    def _wind(self) -> dict:
        """The wind states' estimate and 1-sigma ``(B, 3)`` NED (NaN on an axis without a
        state; the estimate on the prior of the ``air_velocity`` model observing it), or
        nothing without a wind state."""
        blocks = [b for b in WIND_AXES if self.layout.has(b)]
        if not blocks:
            return {}
        B = self.x.shape[0]
        prior = next((np.asarray(m.wind_n_mps, float) for m in self.measurements if hasattr(m, "wind_n_mps")),
                     np.zeros(3))
        wind, sigma = np.full((B, 3), np.nan), np.full((B, 3), np.nan)
        for b in blocks:
            sl, axes = self.layout.slice(b), list(WIND_AXES[b])
            wind[:, axes] = prior[axes] + self.x[:, sl]
            sigma[:, axes] = np.sqrt(np.maximum(np.diagonal(self.P[:, sl, sl], axis1=1, axis2=2), 0.0))
        return {"wind_n_mps": wind, "wind_sigma_mps": sigma}

    def _bias_sigma(self):
        """1-sigma of the estimated gyro and accelerometer biases ``(B, 3)`` each: of the sum of
        their constant and Markov blocks (the estimate), their cross-covariance included (only
        the sum is observed, so the two are strongly anti-correlated); NaN where neither is a
        state."""
        out = []
        for blocks in (("gyro_bias", "gyro_markov"), ("accel_bias", "accel_markov")):
            sl = [self.layout.slice(b) for b in blocks if self.layout.has(b)]
            var = sum(np.diagonal(self.P[:, a, b], axis1=1, axis2=2) for a in sl for b in sl) if sl else None
            out.append(np.sqrt(np.maximum(var, 0.0)) if sl else np.full((self.P.shape[0], 3), np.nan))
        return out

    # --- filter steps -------------------------------------------------------------------------
    def _system(self):
        """``F`` from the period's averaged ``C_nb`` and ``f_n``, and the elapsed period ``T``."""
        s = self.sd.state
        C_mean = self.sd.sum_C_nb / self.sd.steps
        f_mean = self.sd.sum_dv_n_mps / self._elapsed
        F = system_matrix(self.layout, s.lat_rad, s.h_m, s.vel_n_mps, C_mean, f_mean)
        return add_markov_decay(F, self.layout, self.noise), self._elapsed

    def _transition(self):
        """Phi, Qd over the elapsed period (for the filters that need them)."""
        F, T = self._system()
        if self.discretization == "series":
            Phi, Qd = kalman.discretize_series(F, self.Qc, T, order=self.series_order)
        else:
            Phi, Qd = kalman.discretize_van_loan(F, self.Qc, T)
        return Phi, Qd, T

    def _decay_markov(self, T: float) -> None:
        """The fed-back Markov bias estimates decay like the process."""
        if self.layout.has("gyro_markov"):
            self.m_gyro *= np.exp(-T / self.noise.gyro_markov_tau_s)
        if self.layout.has("accel_markov"):
            self.m_accel *= np.exp(-T / self.noise.accel_markov_tau_s)

    def predict(self) -> None:
        """``x``, ``P`` over the elapsed period: the series in place (compiled), or Van Loan."""
        if self.sd.steps == 0:
            return
        F, T = self._system()
        if self.discretization == "series" and _covariance_series_fits(F, T, self.series_order):
            kalman.propagate_in_place(self.x, self.P, F, self.Qc, T, self.series_order)
        else:
            if self.discretization == "series":
                Phi, Qd = kalman.discretize_series(F, self.Qc, T, order=self.series_order)
            else:
                Phi, Qd = kalman.discretize_van_loan(F, self.Qc, T)
            self.x, self.P = kalman.predict(self.x, self.P, Phi, Qd)
        self._decay_markov(T)
        self._reset_accumulators()

    def correct(self, model, data, j: int, t: float) -> Innovation:
        lin = model.model(self.sd.state, self.layout, data, j)
        R = self.measurement_noise(model, lin.z, lin.H, lin.R, lin.valid)
        self.x, self.P, y, S, nis = kalman.update(self.x, self.P, lin.z, lin.H, R, lin.valid)
        bad = ~np.all(np.isfinite(self.P), axis=(1, 2)) | (np.diagonal(self.P, axis1=1, axis2=2) < 0).any(-1)
        self.diverged |= bad
        return Innovation(model.name, model.sensor, t, y, S, nis)

    def measurement_noise(self, model, z, H, R, valid):
        """The R used for this update: the model's own here; adaptive filters override it
        (``z, H, R, valid`` the fields of the model's
        :class:`~navsim.navigation.estimators.measurements.Linearised`: ``valid`` the runs that
        have a sample)."""
        return R

    def feedback(self) -> None:
        """Inject the estimated errors into the mechanization and the IMU compensation."""
        L, x = self.layout, self.x
        s = self.sd.state.contiguous()      # changed in place, as the strapdown changes it
        feed_back(x, L.slice("att").start, L.slice("vel").start, L.slice("pos").start, s.C_nb, s.vel_n_mps,
                  s.lat_rad, s.lon_rad, s.h_m)
        if L.has("gyro_bias"):
            self.b_gyro = self.b_gyro + x[:, L.slice("gyro_bias")]
        if L.has("accel_bias"):
            self.b_accel = self.b_accel + x[:, L.slice("accel_bias")]
        if L.has("gyro_markov"):
            self.m_gyro = self.m_gyro + x[:, L.slice("gyro_markov")]
        if L.has("accel_markov"):
            self.m_accel = self.m_accel + x[:, L.slice("accel_markov")]
        for block in FEEDBACK:
            if L.has(block):
                x[:, L.slice(block)] = 0.0

    def _reset_accumulators(self) -> None:
        self.sd.reset_sums()
        self._elapsed = 0.0


#: the covariance's Taylor series is used from this order on, when no state decays faster than
#: this fraction of the period (Markov states): there it equals Van Loan to rounding (1e-15 at
#: order 6 on P0); below, a truncated series of P(T) expands in 2 F T and need not stay positive
#: semi-definite, so Phi P Phi^T + Qd (the series' Phi and Qd) is used instead
SERIES_MIN_ORDER, SERIES_MAX_DECAY = 6, 0.05


def _covariance_series_fits(F: np.ndarray, T: float, order: int) -> bool:
    """Whether the covariance's Taylor series is as good as ``Phi P Phi^T + Qd`` here."""
    return order >= SERIES_MIN_ORDER and float(np.abs(np.diagonal(F, axis1=1, axis2=2)).max()) * T <= SERIES_MAX_DECAY


def _states(node: Node) -> list:
    """``states``: a preset name or a list of blocks, each once."""
    states = node.data.get("states", "p3_15")
    node._seen.add("states")
    if isinstance(states, str):
        if states not in PRESETS:
            raise node.error(f"is '{states}'", "states", expected="a preset (" + ", ".join(PRESETS)
                             + ") or a list of blocks", hint=close_match(states, PRESETS))
        return list(PRESETS[states])
    if not (isinstance(states, list) and all(isinstance(b, str) for b in states)):
        raise node.error("is malformed", "states", expected="a preset name or a list of blocks")
    twice = sorted({b for b in states if states.count(b) > 1})
    if twice:
        raise node.error(f"names the block '{twice[0]}' twice", "states", expected="each state block once")
    for b in states:
        if b not in BLOCK_SIZES:
            raise node.error(f"block '{b}' is unknown", "states", expected=", ".join(BLOCK_SIZES),
                             hint=close_match(b, BLOCK_SIZES))
    try:
        Layout(tuple(states))
    except ValueError as exc:
        raise node.error(str(exc), "states") from None
    return states


def filter_params(node: Node) -> dict:
    """The keys every filter of the ES-KF family reads (all of :meth:`ErrorStateKF.parse` but
    the measurements)."""
    blocks = _states(node)
    params = {"states": blocks,
              "period_s": node.get("period_s", float, 1.0, exclusive_minimum=0.0, maximum=MAX_DURATION_S),
              "discretization": node.get("discretization", str, "series", choices=("series", "van_loan")),
              "series_order": node.get("series_order", int, 6, minimum=1, maximum=12),
              "latest_sample": node.get("latest_sample", bool, False)}
    noise = node.child("noise")
    imu = noise.get("imu", str)
    override = noise.child("override", None)
    spec = load_spec(imu, override.data if override else None, (), node.file, noise.path)
    if not isinstance(spec, ImuSpec):
        raise noise.error(f"'{imu}' is not an IMU", "imu", expected="an imu catalog entry")
    noise.done()
    params["noise"] = {"imu": imu, "override": override.data if override else None}
    baro = node.child("baro", None)
    params["baro"] = {"sigma_m": 0.0, "tau_s": 300.0}
    if baro is not None:
        params["baro"] = {"sigma_m": baro.get("sigma_m", float, exclusive_minimum=0.0),
                          "tau_s": baro.get("tau_s", float, 300.0, exclusive_minimum=0.0, maximum=MAX_TIME_CONSTANT_S)}
        baro.done()
    if "baro" in blocks and params["baro"]["sigma_m"] == 0.0:
        raise node.error("the 'baro' state needs its model", "baro", expected="{sigma_m: ..., tau_s: ...}")
    params["wind"] = _wind(node, blocks)
    params["gust"] = _gust(node, blocks)
    return params


def _wind(node: Node, blocks) -> dict | None:
    """``wind: {model: markov, sigma_mps, tau_s}`` or ``{model: random_walk, sigma_mps,
    walk_mps_per_rts}`` (``sigma_mps`` the wind's std, the initial uncertainty; the vertical
    block's ``sigma_down_mps`` and, for a random walk, ``walk_down_mps_per_rts``, default the
    horizontal ones), the model of the ``wind`` and ``wind_down`` states; None without one."""
    wind = node.child("wind", None)
    wanted = [b for b in WIND_AXES if b in blocks]
    if wind is None:
        if wanted:
            raise node.error(f"the '{wanted[0]}' state needs its model", "wind",
                             expected="{model: markov, sigma_mps: ..., tau_s: ...} or {model: random_walk, sigma_mps: "
                                      "..., walk_mps_per_rts: ...}")
        return None
    if not wanted:
        raise node.error("has a wind model but no wind state", "wind", expected="'wind' in the states")
    model = wind.get("model", str, "markov", choices=WIND_MODELS)
    sigma = wind.get("sigma_mps", float, exclusive_minimum=0.0, maximum=MAX_WIND_MPS)
    out = {"model": model, "sigma_mps": sigma,
           "sigma_down_mps": wind.get("sigma_down_mps", float, sigma, exclusive_minimum=0.0, maximum=MAX_WIND_MPS)}
    if model == "markov":
        tau = wind.get("tau_s", float, exclusive_minimum=0.0, maximum=MAX_TIME_CONSTANT_S)
        out.update(tau_s=tau, walk_mps_per_rts=sigma * math.sqrt(2.0 / tau),
                   walk_down_mps_per_rts=out["sigma_down_mps"] * math.sqrt(2.0 / tau))
    else:
        walk = wind.get("walk_mps_per_rts", float, exclusive_minimum=0.0, maximum=MAX_WIND_MPS)
        out.update(tau_s=math.inf, walk_mps_per_rts=walk,
                   walk_down_mps_per_rts=wind.get("walk_down_mps_per_rts", float, walk, exclusive_minimum=0.0,
                                                  maximum=MAX_WIND_MPS))
    wind.done()
    return out


def _gust(node: Node, blocks) -> dict | None:
    """``gust: {sigma_mps, tau_s}`` (the gusts' std and correlation time ``L / V``, Dryden's
    first-order form: :func:`navsim.flight.environment.turbulence_sigma_mps` and
    :func:`~navsim.flight.environment.turbulence_scale_m` give both for MIL-HDBK-1797's
    low-altitude model; ``sigma_down_mps`` and ``tau_down_s``, default the horizontal ones, the
    vertical gust's), the model of the ``gust`` and ``gust_down`` states; None without one."""
    gust = node.child("gust", None)
    wanted = [b for b in GUST_AXES if b in blocks]
    if gust is None:
        if wanted:
            raise node.error(f"the '{wanted[0]}' state needs its model", "gust",
                             expected="{sigma_mps: ..., tau_s: ...}")
        return None
    if not wanted:
        raise node.error("has a gust model but no gust state", "gust", expected="'gust' in the states")
    sigma = gust.get("sigma_mps", float, exclusive_minimum=0.0, maximum=MAX_WIND_MPS)
    out = {"sigma_mps": sigma,
           "sigma_down_mps": gust.get("sigma_down_mps", float, sigma, exclusive_minimum=0.0, maximum=MAX_WIND_MPS),
           "tau_s": gust.get("tau_s", float, exclusive_minimum=0.0, maximum=MAX_TIME_CONSTANT_S)}
    out["tau_down_s"] = gust.get("tau_down_s", float, out["tau_s"], exclusive_minimum=0.0, maximum=MAX_TIME_CONSTANT_S)
    gust.done()
    return out


def filter_options(params: dict) -> dict:
    """The arguments of :meth:`ErrorStateKF.from_imu_spec` of :func:`filter_params`' values but
    the states and the IMU: ``extra_states`` (:class:`ExtraStates`) and ``epochs``
    (:class:`EpochSettings`)."""
    return dict(extra_states=ExtraStates(baro_sigma_m=params["baro"]["sigma_m"], baro_tau_s=params["baro"]["tau_s"],
                                         wind=params.get("wind"), gust=params.get("gust")),
                epochs=EpochSettings(period_s=params["period_s"], discretization=params["discretization"],
                                     series_order=params["series_order"], latest_sample=params["latest_sample"]))
