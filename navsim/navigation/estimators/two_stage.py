"""P0's improved two-step adaptive Kalman filter: a two-stage (bias-separated) filter after
Friedland with innovation-based adaptation of the measurement noise.

Two stages (Friedland, "Treatment of bias in recursive filtering", IEEE TAC 14(4), 1969):
the error state is split into the navigation part ``x`` (attitude, velocity, position and any
non-bias state such as P0's barometer error) and the constant IMU biases ``b``. A bias-free
filter runs on ``x`` as if ``b = 0`` (``x~``, ``P~``), a separate filter estimates ``b``
(``b^``, ``P_b``), and the blending matrix ``V`` (the sensitivity of ``x~`` to ``b``) combines
them: ``x^ = x~ + V b^``, ``P = P~ + V P_b V^T``. With constant biases (no bias process noise) this
is algebraically the augmented filter (tested to 1e-9) while working on two smaller matrices.

Adaptation: P0 estimates the innovation autocorrelations ``C_i(k) = C_i(k-1) + (y_k y_k-i^T -
C_i(k-1))/k`` to adapt the gain (Mehra). Its printed equations (10)-(32) are partly garbled; this
filter implements the sound core of the idea instead, covariance matching on the zero-lag
term, where this departs from P0:

* each measurement model's R is re-estimated per run from its innovations,
  ``R^_k = (1 - a) R^_k-1 + a diag(y y^T - H P- H^T)`` with ``a = 1/window`` (an exponential
  window instead of P0's growing ``1/k`` average, so that the filter can follow a change);
* only the diagonal of R is adapted and the gain is the Kalman gain of the adapted R (P0 adapts
  the gain through the lag-i autocorrelations, which needs a steady-state filter);
* ``R^`` is floored at ``floor * R`` (default 1: never trust a sensor more than its noise model
  says). Covariance matching cannot tell a slowly varying unmodelled error (the ADS velocity's
  angle of attack, a bias) from white noise: ``y y^T`` then shrinks R toward the square of the
  error and the filter over-trusts that sensor. With a floor of 0.2, P0's experiment loses
  consistency in the vertical channel (NEES 12 instead of 8).

With a right model R^ stays at R (slightly above: the floor clips the low side of its
fluctuation); with an R that is too small it grows to the real noise and keeps the filter
consistent where the standard filter becomes overconfident. ``adaptive: false`` gives the pure
two-stage filter.
"""

from __future__ import annotations

import numpy as np

from navsim.foundations.config import MAX_WINDOW, Node
from navsim.foundations.jsonschema import POS, obj
from navsim.navigation.estimators import kalman
from navsim.navigation.estimators.base import Innovation, Solution, register
from navsim.navigation.estimators.eskf import ErrorStateKF
from navsim.navigation.estimators.measurements.air_data import reject_rotating_R

BIAS_BLOCKS = ("gyro_bias", "accel_bias")


@register("two_stage_adaptive")
class TwoStageAdaptiveKF(ErrorStateKF):
    """Parameters as :class:`ErrorStateKF`, plus ``adaptive`` (bool), ``window`` (epochs of
    the innovation average) and ``floor`` (lowest R as a fraction of the model's)."""

    SCHEMA = {**ErrorStateKF.SCHEMA, "adaptive": obj({"enabled": {"type": "boolean"},
                                                      "window": {"type": "integer", "minimum": 1}, "floor": POS})}
    OPTIONS = "adaptive"                 #: its constructor arguments: parse's "adaptive"

    def __init__(self, layout, noise, measurements, adaptive: bool = True, window: int = 30,
                 floor: float = 1.0, **kw):
        super().__init__(layout, noise, measurements, **kw)
        if not all(layout.has(b) for b in BIAS_BLOCKS):
            raise ValueError("the two-stage filter needs the gyro_bias and accel_bias blocks")
        self.adaptive, self.window, self.floor = adaptive, window, floor
        bidx = np.r_[tuple(np.arange(layout.slice(b).start, layout.slice(b).stop) for b in BIAS_BLOCKS)]
        self.bidx = bidx
        self.xidx = np.array([i for i in range(layout.n) if i not in set(bidx)])

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """The ES-KF's keys (its states with both bias blocks) plus ``adaptive: {enabled: true,
        window: 30, floor: 1.0}`` (optional)."""
        params = super().parse(node, sensors)
        for block in BIAS_BLOCKS:
            if block not in params["states"]:
                raise node.error(f"the two-stage filter needs the '{block}' block", "states")
        ad = node.child("adaptive", None)
        params["adaptive"] = {"adaptive": True, "window": 30, "floor": 1.0}
        if ad is not None:
            params["adaptive"] = {"adaptive": ad.get("enabled", bool, True),
                                  "window": ad.get("window", int, 30, minimum=1, maximum=MAX_WINDOW),
                                  "floor": ad.get("floor", float, 1.0, exclusive_minimum=0.0)}
            ad.done()
        if params["adaptive"]["adaptive"]:
            reject_rotating_R(node, params["measurements"], None, "the two-stage adaptive filter")
        return params

    def initialize(self, nav0, sigma0):
        super().initialize(nav0, sigma0)
        xi, bi = self.xidx, self.bidx
        B = self.x.shape[0]
        self.xt = np.zeros((B, xi.size))
        self.Pt = self.P[:, xi][:, :, xi].copy()
        self.bh = np.zeros((B, bi.size))
        self.Pb = self.P[:, bi][:, :, bi].copy()
        self.V = np.zeros((B, xi.size, bi.size))          # P_xb P_b^-1 of a block-diagonal P0
        self.R_hat = {}

    # the augmented mean and covariance, for the solution and the feedback
    def _augmented(self):
        B, n = self.x.shape
        x = np.zeros((B, n))
        x[:, self.xidx] = self.xt + (self.V @ self.bh[..., None])[..., 0]
        x[:, self.bidx] = self.bh
        VPb = self.V @ self.Pb
        P = np.zeros((B, n, n))
        P[:, self.xidx[:, None], self.xidx] = self.Pt + VPb @ np.swapaxes(self.V, -1, -2)
        P[:, self.xidx[:, None], self.bidx] = VPb
        P[:, self.bidx[:, None], self.xidx] = np.swapaxes(VPb, -1, -2)
        P[:, self.bidx[:, None], self.bidx] = self.Pb
        return x, P

    def predict(self) -> None:
        if self.sd.steps == 0:
            return
        Phi, Qd, T = self._transition()
        xi, bi = self.xidx, self.bidx
        A = Phi[:, xi][:, :, xi]
        Bm = Phi[:, xi][:, :, bi]
        Q = Qd[:, xi][:, :, xi]
        self.xt = (A @ self.xt[..., None])[..., 0]
        self.Pt = kalman.symmetrize(A @ self.Pt @ np.swapaxes(A, -1, -2) + Q)
        self.V = A @ self.V + Bm
        self._decay_markov(T)
        self._reset_accumulators()

    def correct(self, model, data, j: int, t: float) -> Innovation:
        lin = model.model(self.sd.state, self.layout, data, j)
        z, H, R, valid = lin.z, lin.H, lin.R, lin.valid
        xi, bi = self.xidx, self.bidx
        Hx, C = H[:, :, xi], H[:, :, bi]
        Sens = Hx @ self.V + C
        r0 = z - (Hx @ self.xt[..., None])[..., 0]
        y = r0 - (Sens @ self.bh[..., None])[..., 0]
        key = f"{model.name}:{model.sensor}"
        if self.adaptive:
            R = self._adapt_R(key, y, Hx, Sens, R, valid)
        HxT = np.swapaxes(Hx, -1, -2)
        Sx = kalman.symmetrize(Hx @ self.Pt @ HxT + R)
        Kx = np.swapaxes(kalman.solve_runs(Sx, (self.Pt @ HxT).swapaxes(-1, -2)), -1, -2)
        SensT = np.swapaxes(Sens, -1, -2)
        Sb = kalman.symmetrize(Sens @ self.Pb @ SensT + Sx)
        Kb = np.swapaxes(kalman.solve_runs(Sb, (self.Pb @ SensT).swapaxes(-1, -2)), -1, -2)
        nis = np.einsum("bi,bi->b", y, kalman.solve_runs(Sb, y[..., None])[..., 0])
        bh = self.bh + (Kb @ y[..., None])[..., 0]
        IKb = np.eye(bi.size) - Kb @ Sens
        Pb = IKb @ self.Pb @ np.swapaxes(IKb, -1, -2) + Kb @ Sx @ np.swapaxes(Kb, -1, -2)
        xt = self.xt + (Kx @ r0[..., None])[..., 0]
        IKx = np.eye(xi.size) - Kx @ Hx
        Pt = IKx @ self.Pt @ np.swapaxes(IKx, -1, -2) + Kx @ R @ np.swapaxes(Kx, -1, -2)
        V = self.V - Kx @ Sens
        v = np.asarray(valid, bool)
        self.bh = np.where(v[:, None], bh, self.bh)
        self.Pb = np.where(v[:, None, None], kalman.symmetrize(Pb), self.Pb)
        self.xt = np.where(v[:, None], xt, self.xt)
        self.Pt = np.where(v[:, None, None], kalman.symmetrize(Pt), self.Pt)
        self.V = np.where(v[:, None, None], V, self.V)
        nis = np.where(v, nis, np.nan)
        bad = ~np.all(np.isfinite(self.Pt), axis=(1, 2)) | (np.diagonal(self.Pt, axis1=1, axis2=2) < 0).any(-1)
        self.diverged |= bad
        return Innovation(model.name, model.sensor, t, y, Sb, nis)

    def _adapt_R(self, key, y, Hx, Sens, R, valid):
        """Covariance matching of the diagonal of R from the innovations of each run."""
        HPH = Hx @ self.Pt @ np.swapaxes(Hx, -1, -2) + Sens @ self.Pb @ np.swapaxes(Sens, -1, -2)
        r_nom = np.diagonal(R, axis1=1, axis2=2)
        est = self.R_hat.get(key, r_nom.copy())
        sample = y * y - np.diagonal(HPH, axis1=1, axis2=2)
        a = 1.0 / self.window
        new = np.maximum((1 - a) * est + a * sample, self.floor * r_nom)
        est = np.where(np.asarray(valid, bool)[:, None], new, est)
        self.R_hat[key] = est
        out = np.zeros_like(R)
        idx = np.arange(R.shape[-1])
        out[:, idx, idx] = est
        return out

    def feedback(self) -> None:
        x, _ = self._augmented()
        self.x = x
        super().feedback()            # injects, then zeroes the fed-back blocks of self.x
        self.xt = self.x[:, self.xidx].copy()
        self.bh = np.zeros_like(self.bh)
        self.x = np.zeros_like(self.x)

    def solution(self) -> Solution:
        _, P = self._augmented()
        self.P = P
        return super().solution()
