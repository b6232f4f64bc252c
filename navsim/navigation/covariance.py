"""Covariance analysis: each truth-model error source's contribution to an error-state filter's
navigation errors, by one linear propagation instead of a Monte Carlo (the sensitivity analysis
of a suboptimal filter: Maybeck, *Stochastic models, estimation and control* vol. 1, 6.8; Gelb,
*Applied optimal estimation*, ch. 7).

The filter runs once along the flown trajectory on ideal sensors (a batch of one run, its own
code: its discretization, measurement models and noise), so its covariance and gains are those
a real run has to first order. The truth is the linear error model of the INS along the same
trajectory, driven by one error source's linear form
(:class:`~navsim.sensors.registry.LinearError`) or initial error block. Per source, the
augmented state ``a`` holds

========= ================================================================================
``nav``   the INS's navigation errors (9): attitude phi (rad), velocity (m/s), latitude,
          longitude (rad), height (m), estimate minus truth, as the filter's blocks
``comp``  the IMU compensation's errors, minus the biases fed back so far (3 per fed-back
          bias block of the filter; its Markov blocks decay with the filter's tau)
``kept``  the filter's estimates of the states it does not feed back (``baro``, ``pitot_bias``)
``src``   the source's own states (a random constant, a Markov process, a random walk)
========= ================================================================================

Between epochs ``a' = F_a a + w`` (``F_a`` from the strapdown error dynamics at the period's
averaged ``C_nb`` and specific force, the couplings of the body rate and specific force errors,
the sources' correlation times), discretized over the period. At an epoch with measurements
(stacked) the filter's gain is ``K = P^- H^T (H P^- H^T + R)^-1``; the truth's measured error is
``z = H_t a + v`` (the model's ``H`` on the navigation errors, the source's error through the
model's own ``z``, by differences), and

    x = W kept + K (z - H W kept),    nav, comp -= x (fed-back blocks),    kept = x (the others),

a linear map ``a <- A a + B v``, so ``P_a <- A P_a A^T + B R_t B^T``. Each source alone is
propagated through the same gains (the sources' covariances as a batch, one per row): the system
being linear, their covariances add up to that of all of them, exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag

from navsim.foundations import earth
from navsim.foundations.transform import dcm_from_quat
from navsim.navigation.estimators import kalman
from navsim.navigation.estimators.base import sample
from navsim.navigation.estimators.eskf import FEEDBACK
from navsim.navigation.estimators.error_model import Layout, add_markov_decay, system_matrix
from navsim.navigation.strapdown import NavState
from navsim.sensors.base import Measurements
from navsim.sensors.registry import LinearError, Motion

#: the navigation blocks of the augmented state, in order
NAV = ("att", "vel", "pos")
#: the layout whose ``F`` gives the body rate and specific force errors' couplings
_FULL = Layout(("att", "vel", "pos", "gyro_bias", "accel_bias"))
#: the quantity each fed-back bias block of a filter compensates, and its own decay (None: a constant)
_COMPENSATED = {"gyro_bias": ("rate_b", None), "accel_bias": ("force_b", None),
                "gyro_markov": ("rate_b", "gyro_markov_tau_s"), "accel_markov": ("force_b", "accel_markov_tau_s")}
#: the series order of the truth's transition over a period (exact to rounding over 1 s), and the
#: largest ``|F_ii| T`` it takes before Van Loan's method is used instead
_ORDER, _SERIES_MAX_DECAY = 10, 0.5


@dataclass(frozen=True)
class SourceModel:
    """One error source as a covariance analysis takes it: its sensor's error term in its linear
    form (``error``; ``sensor`` the sensor it corrupts), or an initial error block (``P0_nav``
    ``(9, 9)``, the filter's units)."""

    name: str
    sensor: str | None = None
    error: LinearError | None = None
    P0_nav: np.ndarray | None = None

    @property
    def n(self) -> int:
        return self.error.n if self.error is not None else 0


@dataclass(frozen=True)
class Contributions:
    """Each source's variance of the navigation errors at the filter's epochs.

    ``var`` ``(K, E, 9)``: attitude about N, E, D (rad^2), velocity N, E, D ((m/s)^2), position
    N, E, D (m^2), source by source (``sources``), at ``t_s`` ``(E,)`` (the start and each epoch,
    after its update): what the Monte Carlo's errors have as their mean square with that source
    alone on."""

    sources: list[str]
    t_s: np.ndarray
    var: np.ndarray


class _Augmented:
    """Where each block of the augmented state lies, for one filter layout and the sources'
    largest state count."""

    def __init__(self, layout: Layout | None, n_src: int):
        self.layout = layout
        blocks = layout.blocks if layout is not None else ()
        self.comp = [b for b in blocks if b in _COMPENSATED]
        self.kept = [b for b in blocks if b not in FEEDBACK]       # the sensor-error states the filter keeps
        i = 9
        self.at = {}
        for b in self.comp + self.kept:
            size = layout.slice(b).stop - layout.slice(b).start
            self.at[b] = slice(i, i + size)
            i += size
        self.src = slice(i, i + n_src)
        self.n = i + n_src

    def nav_cols(self) -> np.ndarray:
        """The filter's columns of the navigation blocks, in the augmented state's order."""
        return np.r_[tuple(self.layout.slice(b) for b in NAV)]

    def feedback(self) -> tuple[np.ndarray, np.ndarray]:
        """``J`` and ``Rsel`` ``(n_a, n_f)``: the fed-back blocks of the filter's estimate
        subtracted from the navigation and compensation errors, the kept ones taken as they are."""
        n_f = self.layout.n
        J, R = np.zeros((self.n, n_f)), np.zeros((self.n, n_f))
        J[np.arange(9), self.nav_cols()] = 1.0
        for b in self.comp:
            s = self.layout.slice(b)
            J[np.arange(self.at[b].start, self.at[b].stop), np.arange(s.start, s.stop)] = 1.0
        for b in self.kept:
            s = self.layout.slice(b)
            R[np.arange(self.at[b].start, self.at[b].stop), np.arange(s.start, s.stop)] = 1.0
        return J, R


class _Flown:
    """The truth on the IMU's grid as a covariance analysis reads it: per period, the state at its
    end, the sums of ``C_nb`` and of the specific-force increments in NED (as the strapdown
    mechanization adds them up), the mean body rate and specific force."""

    def __init__(self, truth, dt_s: float):
        self.truth, self.step = truth, max(1, int(round(dt_s / truth.dt_s)))
        self.dt_s = dt_s
        k = slice(None, None, self.step)
        self.C = dcm_from_quat(truth.quat_nb[k])
        f_n = np.einsum("kij,kj->ki", self.C, truth.f_b_mps2[k]) * dt_s
        cum = lambda x: np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])
        self._C, self._f_n = cum(self.C), cum(f_n)
        self._w, self._f = cum(truth.omega_ib_b_rps[k]), cum(truth.f_b_mps2[k])
        self.n = len(truth.t_s[k])
        self.t0 = float(truth.t_s[0])

    def nav(self, b: int) -> NavState:
        """The true state at IMU sample ``b``, one run."""
        k = b * self.step
        tr = self.truth
        return NavState(tr.lat_rad[k:k + 1].astype(float), tr.lon_rad[k:k + 1].astype(float),
                        tr.h_m[k:k + 1].astype(float), tr.vel_n_mps[k:k + 1].astype(float), self.C[b:b + 1].copy())

    def period(self, a: int, b: int):
        """The IMU samples ``a+1 .. b``: the state at ``b``, the sums, the :class:`Motion`."""
        K = b - a
        motion = Motion((self._w[b + 1] - self._w[a + 1]) / K, (self._f[b + 1] - self._f[a + 1]) / K)
        return self.nav(b), (self._C[b + 1] - self._C[a + 1])[None], (self._f_n[b + 1] - self._f_n[a + 1])[None], motion


class CovarianceAnalysis:
    """The analysis of one estimator of the ES-KF family (or free inertial: no measurement,
    no feedback) over a flight.

    Parameters
    ----------
    truth : Truth
        The flown trajectory.
    estimator : object
        A freshly built estimator (``layout``, ``measurements``, ``follow``, ``predict``,
        ``feedback`` of :class:`~navsim.navigation.estimators.eskf.ErrorStateKF`; or one without
        ``layout``: free inertial).
    dt_s : float
        The IMU interval, s.
    sensors : dict
        Sensor name -> the ideal sensor's :class:`~navsim.sensors.base.SensorData` of one run
        (sample times and outages as flown).
    sigma0 : dict
        The filter's initial 1-sigma per block (as the Monte Carlo hands it).
    """

    def __init__(self, truth, estimator, dt_s: float, sensors: dict, sigma0: dict):
        self.est, self.flown = estimator, _Flown(truth, dt_s)
        self.sensors = {k: d.measurements() for k, d in sensors.items()}
        self.sigma0 = sigma0
        self.layout = getattr(estimator, "layout", None)

    def run(self, sources: list[SourceModel]) -> Contributions:
        """Propagate every source of ``sources`` from the start to the last filter epoch."""
        aug = _Augmented(self.layout, max([s.n for s in sources] + [0]))
        nav0 = self.flown.nav(0)
        if self.layout is not None:
            self.est.initialize(nav0, self.sigma0)
        P = np.stack([_initial(s, aug) for s in sources])
        every = max(1, int(round(self.est.period_s / self.flown.dt_s)))
        ends = list(range(every, self.flown.n, every))
        taken = self._taken(ends) if self.layout is not None else [[] for _ in ends]
        self._D = self._sensitivities(sources, ends, taken)
        self._F0, self._Q0 = self._static(sources, aug)
        t, out = [0.0], [_nav_variance(P, nav0)]
        for e, b in enumerate(ends):
            P, nav = self._epoch(P, sources, aug, b - every, b, e, taken[e])
            t.append(b * self.flown.dt_s + self.flown.t0)
            out.append(_nav_variance(P, nav))
        return Contributions([s.name for s in sources], np.array(t), np.stack(out, axis=1))

    def _taken(self, ends: list[int]) -> list[list]:
        """Each epoch's samples, as the filter takes them: ``(index, model, data, j)``."""
        out, t_prev = [], -np.inf
        for b in ends:
            t = b * self.flown.dt_s + self.flown.t0
            since = t_prev if getattr(self.est, "latest_sample", False) else None
            t_prev = t
            out.append([(i, m, data, j) for i, m in enumerate(self.est.measurements)
                        for data, j in [sample(self.sensors, m.sensor, t, since)] if j is not None])
        return out

    def _sensitivities(self, sources, ends: list[int], taken: list[list]) -> dict:
        """(measurement index, quantity) -> ``(E, m, 3)``: each epoch's ``dz/de``
        (:func:`_sensitivity`) for the fixes the sources corrupt, all epochs in one call."""
        wanted = {(src.sensor, src.error.quantity) for src in sources
                  if src.error is not None and src.error.quantity in _PERTURB}
        out = {}
        for i, m in enumerate(getattr(self.est, "measurements", [])):
            for sensor, q in wanted:
                if sensor != m.sensor:
                    continue
                at = [(e, data, j) for e, row in enumerate(taken) for k, _, data, j in row if k == i]
                if at:
                    navs = [self.flown.nav(ends[e]) for e, _, _ in at]
                    D = _sensitivity(m, navs, self.layout, [(data, j) for _, data, j in at], q)
                    out[i, q] = dict(zip((e for e, _, _ in at), D))
        return out

    # --- one epoch ------------------------------------------------------------------------------
    def _epoch(self, P, sources, aug, a: int, b: int, e: int, taken: list):
        nav, sum_C, sum_dv, motion = self.flown.period(a, b)
        T = (b - a) * self.flown.dt_s
        C_mean, f_mean = sum_C / (b - a), sum_dv / T
        F_full = system_matrix(_FULL, nav.lat_rad, nav.h_m, nav.vel_n_mps, C_mean, f_mean)[0]
        F_kept = None
        if aug.kept:
            F_kept = add_markov_decay(system_matrix(self.layout, nav.lat_rad, nav.h_m, nav.vel_n_mps, C_mean, f_mean),
                                      self.layout, self.est.noise)[0]
        F, Qc = self._continuous(F_full, F_kept, sources, aug, motion)
        P = _propagate(P, F, Qc, T)
        self._motion = motion
        if self.layout is None:             # free inertial: nothing measured, nothing fed back
            return P, nav
        self.est.follow(nav, sum_C, sum_dv, b - a, self.flown.dt_s)
        self.est.predict()
        models = [(i, m, m.model(nav, self.layout, data, j)) for i, m, data, j in taken]
        models = [(i, m, lin) for i, m, lin in models if lin.valid is None or bool(lin.valid[0])]
        if models:
            P = self._update(P, sources, aug, models, e)
            kalman.update_in_place(self.est.x, self.est.P, [lin for _, _, lin in models])
        self.est.feedback()
        return P, nav

    def _static(self, sources, aug: _Augmented):
        """``F_a`` and ``Qc_a`` ``(K, n_a, n_a)``: the parts that do not change along the flight
        (the compensation's and the sources' own decay, the sources' driving noise)."""
        K, n = len(sources), aug.n
        F, Qc = np.zeros((K, n, n)), np.zeros((K, n, n))
        for b in aug.comp:
            tau = _COMPENSATED[b][1]
            if tau is not None:
                F[:, aug.at[b], aug.at[b]] = -np.eye(3) / getattr(self.est.noise, tau)
        for k, src in enumerate(sources):
            e = src.error
            if e is not None and e.n:
                ns = slice(aug.src.start, aug.src.start + e.n)
                F[k, ns, ns] = np.diag(-1.0 / np.asarray(e.tau_s, float))
                Qc[k, ns, ns] = np.diag(np.asarray(e.q, float))
        return F, Qc

    def _continuous(self, F_full, F_kept, sources, aug: _Augmented, motion: Motion):
        """``F_a`` and ``Qc_a`` ``(K, n_a, n_a)`` of each source over the period."""
        F, Qc = self._F0.copy(), self._Q0.copy()
        nav = slice(0, 9)
        G = {"rate_b": F_full[:9, _FULL.slice("gyro_bias")], "force_b": F_full[:9, _FULL.slice("accel_bias")]}
        F[:, nav, nav] = F_full[:9, :9]
        for b in aug.comp:
            F[:, nav, aug.at[b]] = G[_COMPENSATED[b][0]]
        for b in aug.kept:
            s = self.layout.slice(b)
            F[:, aug.at[b], aug.at[b]] = F_kept[s, s]
        for k, src in enumerate(sources):
            e = src.error
            if e is None or e.quantity not in G:
                continue
            g = G[e.quantity]
            if e.n:
                F[k, nav, aug.src.start:aug.src.start + e.n] = g @ e.coupling(motion) if e.coupling is not None else g
            if np.any(e.white):
                Qc[k, nav, nav] = (g * np.asarray(e.white, float)) @ g.T
        return F, Qc

    def _update(self, P, sources, aug: _Augmented, models, e: int):
        """The filter's stacked update at its gain, applied to each source's augmented state."""
        lins = [lin for _, _, lin in models]
        H_f = np.concatenate([lin.H[0] for lin in lins])
        R_f = block_diag(*[lin.R[0] for lin in lins])
        Pf = self.est.P[0]
        S = H_f @ Pf @ H_f.T + R_f
        Kg = np.linalg.solve(S, H_f @ Pf).T                          # (n_f, M)
        K, M, n = len(sources), H_f.shape[0], aug.n
        H_t, R_t = np.zeros((K, M, n)), np.zeros((K, M, M))
        H_t[:, :, :9] = H_f[:, aug.nav_cols()]
        row = 0
        for i, m, lin in models:
            rows = slice(row, row + lin.H.shape[1])
            for k, src in enumerate(sources):
                e_ = src.error
                if e_ is None or src.sensor != m.sensor or (i, e_.quantity) not in self._D:
                    continue
                D = self._D[i, e_.quantity][e]
                if e_.n:
                    C = e_.coupling(self._motion) if e_.coupling is not None else np.eye(3)
                    H_t[k, rows, aug.src.start:aug.src.start + e_.n] = D @ C
                R_t[k, rows, rows] += D @ np.diag(np.asarray(e_.white, float)) @ D.T
            row = rows.stop
        J, Rsel = aug.feedback()
        W = Rsel.T                                                   # kept entries into the filter's slots
        L = Kg @ H_t + ((np.eye(self.layout.n) - Kg @ H_f) @ W)[None]
        keep = np.eye(n)
        for b in aug.kept:
            keep[aug.at[b], aug.at[b]] = 0.0
        A = keep[None] + (Rsel - J)[None] @ L
        Bv = (Rsel - J) @ Kg
        return kalman.symmetrize(A @ P @ np.swapaxes(A, 1, 2) + Bv[None] @ R_t @ Bv.T[None])


#: how a fix's quantity perturbs its sensor's outputs, by ``delta`` ``(3,)`` in NED
_PERTURB = {"pos_n": ("lat_rad", "lon_rad", "h_m"), "vel_n": ("vel_n_mps",)}


def _samples(data: Measurements, j: int, quantity: str) -> dict:
    """Sample ``j`` of ``data``'s values as 4 runs of one sample: as it is, then moved by 1 (m
    or m/s) along N, E and D in ``quantity``."""
    values = {k: np.repeat(v[:, j:j + 1], 4, axis=0) for k, v in data.values.items()}
    delta = np.vstack([np.zeros(3), np.eye(3)])
    if quantity == "pos_n":
        lat, h = values["lat_rad"][:, 0], values["h_m"][:, 0]
        r_m, r_n = earth.radii(lat)
        values["lat_rad"][:, 0] += delta[:, 0] / (r_m + h)
        values["lon_rad"][:, 0] += delta[:, 1] / ((r_n + h) * np.cos(lat))
        values["h_m"][:, 0] -= delta[:, 2]
    else:
        values["vel_n_mps"][:, 0] += delta
    return values


def _sensitivity(m, navs: list, layout, samples: list, quantity: str) -> np.ndarray:
    """``dz/de`` ``(E, m, 3)``: how the model's measured error moves with an error ``e`` of its
    sensor's ``quantity``, at each of the ``E`` states ``navs`` and samples ``(data, j)``, from its
    own ``z`` in one call (each sample and its three moves as runs; a model is linear in its
    sensor's values, so the differences are exact to rounding); zero where the sensor does not
    output the quantity."""
    data = samples[0][0]
    if not all(key in data.values for key in _PERTURB[quantity]):
        return np.zeros((len(samples), m.model(navs[0], layout, data, samples[0][1]).z.shape[1], 3))
    parts = [_samples(d, j, quantity) for d, j in samples]
    values = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    four = NavState(*(np.repeat(np.concatenate([getattr(n, f) for n in navs]), 4, axis=0)
                      for f in ("lat_rad", "lon_rad", "h_m", "vel_n_mps", "C_nb")))
    batch = Measurements(data.name, data.kind, data.t_s[:1], values, np.ones((len(values[next(iter(values))]), 1), bool),
                         data.meta)
    z = m.model(four, layout, batch, 0).z.reshape(len(samples), 4, -1)
    return np.swapaxes(z[:, 1:] - z[:, :1], 1, 2)


def _initial(src: SourceModel, aug: _Augmented) -> np.ndarray:
    """The source's augmented covariance at the start."""
    P = np.zeros((aug.n, aug.n))
    if src.P0_nav is not None:
        P[:9, :9] = src.P0_nav
    if src.n:
        ns = slice(aug.src.start, aug.src.start + src.n)
        P[ns, ns] = src.error.P0
    return P


def _propagate(P, F, Qc, T: float):
    """``Phi P Phi^T + Qd`` over ``T``: the series (compiled) where no state decays fast, else
    Van Loan."""
    if float(np.abs(np.diagonal(F, axis1=1, axis2=2)).max()) * T <= _SERIES_MAX_DECAY:
        Phi, Qd = kalman.discretize_series(F, Qc, T, order=_ORDER)
    else:
        Phi, Qd = kalman.discretize_van_loan(F, Qc, T)
    return kalman.symmetrize(Phi @ P @ np.swapaxes(Phi, 1, 2) + Qd)


def _nav_variance(P, nav) -> np.ndarray:
    """``(K, 9)``: the navigation errors' variances, position in NED metres, at ``nav``'s place."""
    lat, h = float(nav.lat_rad[0]), float(nav.h_m[0])
    r_m, r_n = earth.radii(lat)
    scale = np.r_[np.ones(6), (r_m + h), (r_n + h) * np.cos(lat), -1.0]
    return np.diagonal(P[:, :9, :9], axis1=1, axis2=2) * scale ** 2
