"""Federated Kalman filter (Carlson 1990; P1, Liang): local error-state filters on one common
strapdown solution, each with its own measurements, fused by a master filter.

Information sharing: the common process information is divided among the local filters and the
master by factors ``beta_i`` with ``sum(beta_i) + beta_m = 1``: local ``i`` starts from
``P0 / beta_i`` and predicts with ``Q / beta_i`` (the master, when ``beta_m > 0``, likewise and
without measurements). After the local updates the master fuses the estimates in information
form::

    P_f^-1 = sum_i P_i^-1 (+ P_m^-1),   x_f = P_f sum_i P_i^-1 x_i (+ P_m^-1 x_m)

* ``reset: true`` (fusion-reset): every fusion resets ``x_i = x_f``, ``P_i = P_f / beta_i``. Fused
  every filter epoch with ``beta_m = 0`` this is the centralized filter on the same
  measurements (tested to 1e-6 relative): ``sum_i (P / beta_i)^-1 = P^-1`` and the local
  information gains add.
* ``reset: false`` (no-reset): the local filters run on their own and only the output is fused;
  fault-tolerant, but not optimal (the common process noise is counted once per filter).

The fused error estimate is fed back into the common strapdown and the biases; each local
estimate is shifted by the same amount (its error is now relative to the corrected solution).

Fault isolation (``isolation``): for every local filter and run the NIS per degree of freedom of
its measurements is smoothed over ``window`` epochs; a local filter whose smoothed NIS exceeds the
``p`` quantile of ``chi2(dim * window) / (dim * window)`` leaves the fusion and is readmitted once
it is back below. An isolated filter's measurements are left out but its prediction (its share
of the process information) is still fused, so the fused covariance does not grow by the lost
share. Isolated filters keep updating (with reset, they restart from the fused solution every
epoch, so their innovations keep showing the fault until it ends).
"""

from __future__ import annotations

import numpy as np

from navsim.foundations.config import MAX_WINDOW, Node
from navsim.foundations.distributions import chi2_ppf
from navsim.foundations.jsonschema import MEASUREMENT, NUM, POS, obj
from navsim.navigation.estimators import kalman
from navsim.navigation.estimators.base import Innovation, Solution, register, sample
from navsim.navigation.estimators.error_model import Layout
from navsim.navigation.estimators.eskf import ErrorStateKF, filter_options, filter_params
from navsim.navigation.estimators.measurements import (
    build_measurements,
    check_observed_states,
    parse_measurements,
)
from navsim.sensors.catalog import load_spec


def _information(P):
    """``P^-1`` of a stack, through the correlation matrix (the position blocks in radians are
    ~1e-12 while attitude and biases are ~1e-6: inverting ``P`` directly loses digits)."""
    d = 1.0 / np.sqrt(np.diagonal(P, axis1=1, axis2=2))
    C = P * d[:, :, None] * d[:, None, :]
    eye = np.broadcast_to(np.eye(P.shape[-1]), P.shape)
    return kalman.solve_runs(C, eye) * d[:, :, None] * d[:, None, :]     # NaN in a singular run only


@register("federated")
class FederatedKF(ErrorStateKF):
    """Parameters as :class:`ErrorStateKF` (``measurements`` unused), plus ``locals``: a list
    of ``{"name", "beta", "measurements"}``, ``master_beta``, ``reset`` and ``isolation``
    (``None`` or ``{"window": epochs, "p": quantile}``)."""

    SCHEMA = {**{k: v for k, v in ErrorStateKF.SCHEMA.items() if k != "measurements"},
              "locals": {"type": "array", "items": obj({"name": {"type": "string"}, "beta": POS,
                                                        "measurements": {"type": "array", "items": MEASUREMENT}},
                                                       ["name", "beta", "measurements"])},
              "master_beta": NUM, "reset": {"type": "boolean"},
              "isolation": obj({"window": {"type": "number", "minimum": 1}, "p": POS})}

    def __init__(self, layout, noise, locals_, master_beta: float = 0.0, reset: bool = True,
                 isolation: dict | None = None, **kw):
        all_models = [m for loc in locals_ for m in loc["measurements"]]
        super().__init__(layout, noise, all_models, **kw)
        betas = np.array([loc["beta"] for loc in locals_] + [master_beta], float)
        if np.any(betas[:-1] <= 0) or master_beta < 0 or abs(betas.sum() - 1.0) > 1e-9:
            raise ValueError(f"information-sharing factors {betas.tolist()}: expected beta_i > 0, "
                             "beta_m >= 0 and a sum of 1")
        self.locals = [dict(loc) for loc in locals_]
        self.beta = betas[:-1]
        self.master_beta = float(master_beta)
        self.reset = reset
        self.isolation = isolation

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """The ES-KF's keys with ``locals: [{name, beta, measurements}, ...]`` (at least two)
        instead of ``measurements``, ``master_beta`` (0), ``reset`` (true) and ``isolation:
        {window: 5, p: 0.999}`` (optional); the betas and ``master_beta`` add up to 1."""
        raw = node.items("locals", 2, "a list of at least two {name, beta, measurements}",
                         "e.g. [{name: SINS/GPS, beta: 0.5, measurements: [...]}, ...]")
        params, locals_ = filter_params(node), []
        for i, item in enumerate(raw):
            loc = Node(item, node.key(f"locals[{i}]"), node.file)
            locals_.append({"name": loc.get("name", str), "beta": loc.get("beta", float, exclusive_minimum=0.0),
                            "measurements": parse_measurements(loc, sensors)})
            loc.done()
        check_observed_states(node, params["states"], [m for o in locals_ for m in o["measurements"]])
        master = node.get("master_beta", float, 0.0, minimum=0.0)
        total = sum(o["beta"] for o in locals_) + master
        if abs(total - 1.0) > 1e-6:
            raise node.error(f"the information-sharing factors add up to {total:g}", "locals",
                             expected="sum of the locals' beta + master_beta = 1")
        iso = node.child("isolation", None)
        isolation = None
        if iso is not None:
            isolation = {"window": iso.get("window", float, 5.0, minimum=1.0, maximum=MAX_WINDOW),
                         "p": iso.get("p", float, 0.999, exclusive_minimum=0.5, maximum=0.999999)}
            iso.done()
        params["federated"] = {"locals": locals_, "master_beta": master, "reset": node.get("reset", bool, True),
                               "isolation": isolation}
        return params

    @classmethod
    def from_params(cls, params: dict):
        p, f = params, params["federated"]
        locals_ = [{**loc, "measurements": build_measurements(loc["measurements"])} for loc in f["locals"]]
        return cls.from_imu_spec(Layout(tuple(p["states"])), load_spec(p["noise"]["imu"], p["noise"]["override"]),
                                 locals_, master_beta=f["master_beta"], reset=f["reset"], isolation=f["isolation"],
                                 **filter_options(p))

    def initialize(self, nav0, sigma0):
        super().initialize(nav0, sigma0)
        B, n = self.x.shape
        L = len(self.locals)
        self.xl = np.zeros((L, B, n))
        self.Pl = np.stack([self.P / b for b in self.beta])
        if self.master_beta > 0:
            self.xm, self.Pm = np.zeros((B, n)), self.P / self.master_beta
        self.active = np.ones((L, B), bool)
        self.nis_avg = np.ones((L, B))

    def predict(self) -> None:
        if self.sd.steps == 0:
            return
        Phi, Qd, T = self._transition()
        for i, b in enumerate(self.beta):
            self.xl[i], self.Pl[i] = kalman.predict(self.xl[i], self.Pl[i], Phi, Qd / b)
        if self.master_beta > 0:
            self.xm, self.Pm = kalman.predict(self.xm, self.Pm, Phi, Qd / self.master_beta)
        self._decay_markov(T)
        self._reset_accumulators()

    def epoch(self, t: float, sensors: dict) -> list[Innovation]:
        self.predict()
        self.xl_prior, self.Pl_prior = self.xl.copy(), self.Pl.copy()
        since = self._since(t)
        out = []
        for i, loc in enumerate(self.locals):
            nis_sum, dof = np.zeros(self.x.shape[0]), np.zeros(self.x.shape[0])
            for m in loc["measurements"]:
                data, j = sample(sensors, m.sensor, t, since)
                if j is None:
                    continue
                lin = m.model(self.sd.state, self.layout, data, j)
                self.xl[i], self.Pl[i], y, S, nis = kalman.update(self.xl[i], self.Pl[i], lin.z, lin.H, lin.R,
                                                                  lin.valid)
                out.append(Innovation(m.name, m.sensor, t, y, S, nis))
                ok = np.isfinite(nis)
                nis_sum += np.where(ok, nis, 0.0)
                dof += np.where(ok, y.shape[-1], 0)
            self._judge(i, nis_sum, dof)
        self._fuse()
        self.feedback()
        return out

    def _judge(self, i, nis_sum, dof):
        if self.isolation is None:
            return
        w = float(self.isolation.get("window", 5))
        has = dof > 0
        per_dof = np.where(has, nis_sum / np.maximum(dof, 1), 1.0)
        self.nis_avg[i] = np.where(has, self.nis_avg[i] + (per_dof - self.nis_avg[i]) / w, self.nis_avg[i])
        d = max(float(np.max(dof)), 1.0) * w
        limit = chi2_ppf(self.isolation.get("p", 0.999), d) / d
        self.active[i] = self.nis_avg[i] <= limit

    def _fuse(self) -> None:
        B, n = self.x.shape
        Y = np.zeros((B, n, n))
        y = np.zeros((B, n))
        act = self.active.copy()
        act[:, ~act.any(0)] = True                  # never fuse nothing: keep all if all are out
        for i in range(len(self.locals)):
            # an isolated filter still holds its share of the process information: fuse its
            # prediction, leave out only its measurements
            a = act[i][:, None]
            xi = np.where(a, self.xl[i], self.xl_prior[i])
            Yi = _information(np.where(a[..., None], self.Pl[i], self.Pl_prior[i]))
            Y += Yi
            y += (Yi @ xi[..., None])[..., 0]
        if self.master_beta > 0:
            Ym = _information(self.Pm)
            Y += Ym
            y += (Ym @ self.xm[..., None])[..., 0]
        self.P = kalman.symmetrize(_information(Y))
        self.x = (self.P @ y[..., None])[..., 0]
        if self.reset:
            for i, b in enumerate(self.beta):
                self.xl[i] = self.x.copy()
                self.Pl[i] = self.P / b
            if self.master_beta > 0:
                self.xm, self.Pm = self.x.copy(), self.P / self.master_beta
        bad = ~np.all(np.isfinite(self.P), axis=(1, 2)) | (np.diagonal(self.P, axis1=1, axis2=2) < 0).any(-1)
        self.diverged |= bad

    def feedback(self) -> None:
        fed = self.x.copy()
        super().feedback()                           # zeroes the fed-back blocks of self.x
        shift = fed - self.x
        self.xl -= shift[None]
        if self.master_beta > 0:
            self.xm -= shift

    def solution(self) -> Solution:
        sol = super().solution()
        sol.extra["active"] = self.active.copy()
        return sol

