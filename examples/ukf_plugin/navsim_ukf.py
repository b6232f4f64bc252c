"""An error-state unscented Kalman filter (UKF) for navsim, as an out-of-tree plug-in.

The filter is navsim's error-state Kalman filter (:class:`~navsim.navigation.estimators.eskf.ErrorStateKF`:
the strapdown, the error model and its covariance prediction, the feedback of the estimated
errors) whose measurement update is the unscented transform instead of the linearisation.

Sigma points of the error state ``dx`` (``n`` states, ``B`` runs)::

    X_0 = x,   X_i = x + (sqrt((n + lambda) P))_i,   X_n+i = x - (sqrt((n + lambda) P))_i
    lambda = alpha^2 (n + kappa) - n

with the weights of Wan and van der Merwe (``alpha``, ``beta``, ``kappa``; defaults 1, 2, 0). For
each sigma point the navigation state it stands for (the estimate with the errors ``X_i``
removed: ``C_nb <- exp([phi x]) C_nb``, ``v <- v - dv``, ``L, lambda, h <- ... - dp``) goes through
the registered measurement model: the model's ``z`` (INS minus sensor) at the estimate minus its
``z`` there is what the hypothesis predicts, ``z_i = z(nav) - z(nav_i)``; the states the
navigation state does not carry (biases, the baro error) enter through the model's ``H``. Then::

    z^ = sum w_m z_i,   S = sum w_c (z_i - z^)(z_i - z^)^T + R,   C = sum w_c (X_i - x)(z_i - z^)^T
    K = C S^-1,   x <- x + K (z - z^),   P <- P - K S K^T

A model that keeps a state between calls (the magnetic heading's online calibration) is
evaluated once, at the estimate, and its sigma points use its ``H``.

Parameters in a scenario: the ES-KF's keys (``states``, ``noise``, ``measurements``, ...) and
``unscented: {alpha: 1.0, beta: 2.0, kappa: 0.0}``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from navsim.foundations.config import Node
from navsim.foundations.jsonschema import NUM, POS, obj
from navsim.foundations.transform import rotation
from navsim.navigation.estimators import Innovation
from navsim.navigation.estimators.error_model import Layout
from navsim.navigation.estimators.eskf import ErrorStateKF
from navsim.navigation.estimators.kalman import symmetrize

#: the unscented transform's defaults: the spread ``alpha``, ``beta`` = 2 (Gaussian), ``kappa``
UNSCENTED = {"alpha": 1.0, "beta": 2.0, "kappa": 0.0}
NAV_BLOCKS = ("att", "vel", "pos")


def weights(n: int, alpha: float, beta: float, kappa: float) -> tuple[float, np.ndarray, np.ndarray]:
    """``lambda`` and the mean and covariance weights of the ``2n + 1`` sigma points."""
    lam = alpha ** 2 * (n + kappa) - n
    wm = np.full(2 * n + 1, 0.5 / (n + lam))
    wc = wm.copy()
    wm[0] = lam / (n + lam)
    wc[0] = wm[0] + 1.0 - alpha ** 2 + beta
    return lam, wm, wc


def square_root(A: np.ndarray) -> np.ndarray:
    """``L`` with ``L L^T = A`` ``(n, n)``: the Cholesky factor, or ``V diag(sqrt(w))`` of the
    eigenvalues ``w`` clipped at 0 where ``A`` is not positive definite to rounding; NaN where
    ``A`` is not finite (a diverged run keeps its own NaN)."""
    if not np.all(np.isfinite(A)):
        return np.full_like(A, np.nan)
    try:
        return np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(symmetrize(A))
        return V * np.sqrt(np.clip(w, 0.0, None))[None, :]


def solve(S: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``S^-1 B`` for each run's ``S`` ``(B, m, m)``; NaN for a run whose ``S`` is singular (it
    is flagged diverged, the others are updated)."""
    try:
        return np.linalg.solve(S, B)
    except np.linalg.LinAlgError:
        out = np.full(np.broadcast_shapes(S.shape[:-1], B.shape[:-1]) + B.shape[-1:], np.nan)
        for b in range(S.shape[0]):
            try:
                out[b] = np.linalg.solve(S[b], B[b])
            except np.linalg.LinAlgError:
                pass
        return out


def sigma_points(x: np.ndarray, P: np.ndarray, scale: float) -> np.ndarray:
    """``(2n + 1, B, n)`` sigma points of ``x`` ``(B, n)``, ``P`` ``(B, n, n)``, spread by a
    square root of ``scale P`` (:func:`square_root`, run by run where the batch has no Cholesky
    factor, so that a run's points never depend on the others')."""
    try:
        L = np.linalg.cholesky(scale * P)
    except np.linalg.LinAlgError:
        L = np.stack([square_root(scale * Pb) for Pb in P])
    cols = np.swapaxes(L, 1, 2)                         # (B, n, n): column i of each run's factor
    return np.concatenate([x[None], x[None] + np.moveaxis(cols, 1, 0), x[None] - np.moveaxis(cols, 1, 0)])


def _stateless(model) -> bool:
    """Whether evaluating the model changes nothing: a dataclass all of whose fields are its
    constructor's (navsim's models keep what they learn, as the magnetic heading's calibration,
    in fields out of the constructor). Any other model is linearised (its ``H``)."""
    return all(f.init for f in dataclasses.fields(model)) if dataclasses.is_dataclass(model) else False


class ErrorStateUKF(ErrorStateKF):
    """The ES-KF with the unscented measurement update (see the module docstring)."""

    SCHEMA = {**ErrorStateKF.SCHEMA, "unscented": obj({"alpha": POS, "beta": {"type": "number", "minimum": 0},
                                                       "kappa": NUM})}

    def __init__(self, layout, noise, measurements, alpha: float = UNSCENTED["alpha"],
                 beta: float = UNSCENTED["beta"], kappa: float = UNSCENTED["kappa"], **kw):
        super().__init__(layout, noise, measurements, **kw)
        if not (alpha > 0 and layout.n + kappa > 0):
            raise ValueError(f"unscented alpha {alpha}, kappa {kappa}: expected alpha > 0 and n + kappa > 0")
        self.lam, self.wm, self.wc = weights(layout.n, alpha, beta, kappa)
        self.nav_idx = np.r_[tuple(np.arange(layout.slice(b).start, layout.slice(b).stop) for b in NAV_BLOCKS)]
        self.other_idx = np.setdiff1d(np.arange(layout.n), self.nav_idx)

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        """The ES-KF's keys plus ``unscented: {alpha, beta, kappa}`` (optional)."""
        params = super().parse(node, sensors)
        n = Layout(tuple(params["states"])).n
        read = lambda sub: {"alpha": sub.get("alpha", float, UNSCENTED["alpha"], exclusive_minimum=0.0),
                            "beta": sub.get("beta", float, UNSCENTED["beta"], minimum=0.0),
                            "kappa": sub.get("kappa", float, UNSCENTED["kappa"], exclusive_minimum=-n)}
        return {**params, "unscented": node.section("unscented", read)}

    @classmethod
    def options(cls, params: dict) -> dict:
        return params["unscented"]

    def _hypothesis(self, nav, dx: np.ndarray):
        """The navigation state with the errors ``dx`` ``(B, n)`` removed."""
        L, out = self.layout, nav.copy()
        out.C_nb = rotation(dx[:, L.slice("att")]) @ nav.C_nb
        out.vel_n_mps = nav.vel_n_mps - dx[:, L.slice("vel")]
        p = dx[:, L.slice("pos")]
        out.lat_rad, out.lon_rad, out.h_m = nav.lat_rad - p[:, 0], nav.lon_rad - p[:, 1], nav.h_m - p[:, 2]
        return out

    def _predicted(self, model, data, j: int, lin, X: np.ndarray) -> np.ndarray:
        """``(2n + 1, B, m)``: what each sigma point predicts the model measures (``lin``: the
        model at the estimate, a :class:`~navsim.navigation.estimators.Linearised`)."""
        if not _stateless(model):
            return np.einsum("bmn,sbn->sbm", lin.H, X)
        nav, other = self.sd.state, self.other_idx
        Z = np.stack([lin.z - model.model(self._hypothesis(nav, Xi), self.layout, data, j).z for Xi in X])
        return Z + np.einsum("bmk,sbk->sbm", lin.H[:, :, other], X[:, :, other])

    def correct(self, model, data, j: int, t: float) -> Innovation:
        lin = model.model(self.sd.state, self.layout, data, j)           # z, H, R, valid at the estimate
        X = sigma_points(self.x, self.P, self.layout.n + self.lam)
        Z = self._predicted(model, data, j, lin, X)
        z_hat = np.einsum("s,sbm->bm", self.wm, Z)
        dZ, dX = Z - z_hat, X - self.x
        S = symmetrize(np.einsum("s,sbm,sbk->bmk", self.wc, dZ, dZ) + lin.R)
        C = np.einsum("s,sbn,sbm->bnm", self.wc, dX, dZ)
        K = np.swapaxes(solve(S, np.swapaxes(C, 1, 2)), 1, 2)          # C S^-1
        y = lin.z - z_hat
        ok = np.asarray(lin.valid, bool)
        x_new = self.x + np.einsum("bnm,bm->bn", K, y)
        P_new = symmetrize(self.P - K @ S @ np.swapaxes(K, 1, 2))
        self.x = np.where(ok[:, None], x_new, self.x)
        self.P = np.where(ok[:, None, None], P_new, self.P)
        nis = np.where(ok, np.einsum("bm,bm->b", y, solve(S, y[..., None])[..., 0]), np.nan)
        bad = ~np.all(np.isfinite(self.P), axis=(1, 2)) | (np.diagonal(self.P, axis1=1, axis2=2) < 0).any(-1)
        self.diverged |= bad
        return Innovation(model.name, model.sensor, t, y, S, nis)
