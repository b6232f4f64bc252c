"""Online magnetometer calibration: hard-iron offset and soft-iron matrix by recursive least
squares on the ellipsoid the measured field draws (P1, "Full INS/GPS/magnetometer
integration").

Model and parametrisation
    The magnetometer measures ``m = S C_bn m_n + b + e`` (:mod:`navsim.sensors.magnetometer`):
    as the aircraft turns, ``C_bn m_n`` stays on a sphere of radius ``r = |m_n|`` and ``m`` on
    the ellipsoid ``(m - b)^T A (m - b) = r^2``, ``A = S^-T S^-1``. The fit alone gives the
    ellipsoid up to scale; the field model's magnitude ``r`` (WMM, the filter's own model) is
    the scale reference. With ``u = m / r = (x, y, z)`` the quadric ``u^T Q u + 2 q^T u + k = 0``,
    scaled so that ``trace Q = 3``, is linear in nine parameters::

        -(x^2 + y^2 + z^2) = phi^T theta,
        phi = [x^2 - z^2, y^2 - z^2, 2xy, 2xz, 2yz, 2x, 2y, 2z, 1]

    ``Q = I + [[t0, t2, t3], [t2, t1, t4], [t3, t4, -t0 - t1]]``, ``q = t5:8``, ``k = t8``:
    centre ``c = -Q^-1 q``, ``A / r^2 = Q / (c^T Q c - k)``, ``b = r c``. (The other common
    normalisation, ``k = -1``, fails when the hard iron is as large as the field: the origin
    then lies on the ellipsoid and ``k = 0``.)

Estimator
    Recursive least squares in information form: the normal equations are accumulated sample
    by sample, each sample weighted by the forgetting factor ``lambda`` per sample period
    (``lambda = 1``: plain least squares over all samples), starting from a weak prior on the
    unit sphere; ``theta`` is solved when an estimate is asked for (equal to the covariance-form
    RLS, test). The noise enters the regressors (errors in variables): ``E[x^2] = x0^2 +
    sigma^2``, and the plain algebraic fit is biased by ``O(sigma^2)`` divided by the
    excitation of the weakest direction, which is large for an aircraft (below). Every
    monomial of the normal equations is therefore replaced by its unbiased Hermite form
    (``x^2 - s2``, ``x^4 - 6 s2 x^2 + 3 s2^2``, ...; adjusted least squares, Kukush, Markovsky
    and Van Huffel, *Consistent estimation in an implicit quadratic measurement error model*,
    CSDA 47(1), 2004) with ``s2 = (sigma / r)^2`` from the filter's own model of the
    magnetometer noise.

Soft iron up to a rotation
    The fit recovers ``A = S^-T S^-1`` only: ``S = P U`` (polar decomposition, ``P = (S S^T)^1/2``
    symmetric positive definite, ``U`` orthogonal) and ``U`` looks like a misalignment of the
    sensor axes, which no ellipsoid fit sees. The estimate is the symmetric ``P_est = A^-1/2``,
    scored against the truth's symmetric factor (:func:`symmetric_soft_iron`), which is the
    truth itself when the truth is symmetric (as ``sensors/p1_magnetometer.yaml``).

Observability
    In level flight the body field draws a horizontal circle (one plane section of the
    ellipsoid) and a family of ellipsoids fits it. A full turn at bank ``phi`` draws a circle
    in a plane tilted by ``phi``; two circles still leave a one-parameter family (the pencil of
    the sphere and the pair of planes ``L1 L2``), whatever the two bank angles. It is broken by
    samples far from both planes: straight flight across the field (heading east or west, where
    ``|L1 L2| ~ sin^2(phi) H^2``) and the roll-in and roll-out. ``navsim/tracks/p1_magcal.yaml``
    flies east, a full left turn at 32 deg bank, east, a full right turn, east.
"""

from __future__ import annotations

import itertools

import numpy as np

from navsim.sensors.magnetometer import WMM_DATE, wmm_field_n_T

N_PARAMS = 9
#: the monomials of degree <= 2 of (x, y, z) the regressors are written in: 1, x, y, z, x^2,
#: y^2, z^2, xy, xz, yz
_BASIS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [2, 0, 0], [0, 2, 0], [0, 0, 2],
                   [1, 1, 0], [1, 0, 1], [0, 1, 1]])
#: rows: the nine regressors x^2 - z^2, y^2 - z^2, 2xy, 2xz, 2yz, 2x, 2y, 2z, 1 and the target
#: -(x^2 + y^2 + z^2), as coefficients of the basis
_G = np.zeros((N_PARAMS + 1, len(_BASIS)))
for _row, _terms in enumerate([{4: 1, 6: -1}, {5: 1, 6: -1}, {7: 2}, {8: 2}, {9: 2}, {1: 2}, {2: 2}, {3: 2},
                               {0: 1}, {4: -1, 5: -1, 6: -1}]):
    for _col, _c in _terms.items():
        _G[_row, _col] = _c
#: the unit sphere: Q = I, q = 0, k = -1
SPHERE = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0])
#: every monomial of degree <= 4 (products of two basis monomials), and where each product reads
_MONO = np.array([e for e in itertools.product(range(5), repeat=3) if sum(e) <= 4])
_INDEX = {tuple(e): i for i, e in enumerate(_MONO)}
_IDX = np.array([[_INDEX[tuple(a + b)] for b in _BASIS] for a in _BASIS])


def regressor(u: np.ndarray):
    """Regressors ``phi`` ``(..., 9)`` and target ``y`` ``(...)`` of normalised measurements
    ``u`` ``(..., 3)``: ``y = phi^T theta`` on the ellipsoid."""
    basis = np.prod(u[..., None, :] ** _BASIS, axis=-1)
    z = basis @ _G.T
    return z[..., :N_PARAMS], z[..., N_PARAMS]


def _hermite(x: np.ndarray, s2: np.ndarray) -> np.ndarray:
    """Unbiased forms of ``x^0 .. x^4`` for ``x = x0 + N(0, s2)``: ``E[He_k(x)] = x0^k``."""
    return np.stack([np.ones_like(x), x, x * x - s2, x ** 3 - 3 * s2 * x,
                     x ** 4 - 6 * s2 * x * x + 3 * s2 * s2], -1)


def monomials(u: np.ndarray, s2) -> np.ndarray:
    """The monomials of degree <= 4 of ``u`` ``(B, K, 3)``, noise-compensated, ``(B, K, 35)``."""
    s2 = np.asarray(s2, float).reshape(-1, *([1] * (u.ndim - 1)))
    h = _hermite(u, s2)
    return h[..., 0, _MONO[:, 0]] * h[..., 1, _MONO[:, 1]] * h[..., 2, _MONO[:, 2]]


def normal_equations(moments: np.ndarray):
    """``sum phi phi^T`` ``(B, 9, 9)`` and ``sum phi y`` ``(B, 9)`` from the monomial sums."""
    W = _G @ moments[:, _IDX] @ _G.T
    return W[:, :N_PARAMS, :N_PARAMS], W[:, :N_PARAMS, N_PARAMS]


def ellipsoid(theta: np.ndarray):
    """Centre ``c`` ``(B, 3)`` and shape ``A_n`` ``(B, 3, 3)`` (``(u - c)^T A_n (u - c) = 1``)
    of parameters ``theta`` ``(B, 9)``: ``u^T Q u + 2 q^T u + k = 0`` with ``trace Q = 3``;
    NaN where ``Q`` is singular."""
    t = theta
    Q = np.stack([np.stack([1 + t[:, 0], t[:, 2], t[:, 3]], -1),
                  np.stack([t[:, 2], 1 + t[:, 1], t[:, 4]], -1),
                  np.stack([t[:, 3], t[:, 4], 1 - t[:, 0] - t[:, 1]], -1)], -2)
    ok = np.abs(np.linalg.det(Q)) > 1e-12
    c = -np.linalg.solve(np.where(ok[:, None, None], Q, np.eye(3)), t[:, 5:8, None])[..., 0]
    c[~ok] = np.nan
    k = -np.einsum("bi,bi->b", c, t[:, 5:8]) - t[:, 8]          # c^T Q c - k
    return c, Q / k[:, None, None]


def sqrt_inverse_spd(A: np.ndarray):
    """``A^-1/2`` (symmetric) of symmetric ``A`` ``(B, 3, 3)`` and whether ``A`` is positive
    definite (NaN where it is not)."""
    A = np.where(np.isfinite(A), A, 0.0)
    w, V = np.linalg.eigh(0.5 * (A + np.swapaxes(A, -1, -2)))
    pd = w.min(-1) > 0
    inv_root = 1.0 / np.sqrt(np.where(pd[:, None], w, np.nan))
    return np.einsum("bij,bj,bkj->bik", V, inv_root, V), pd


def symmetric_soft_iron(S: np.ndarray) -> np.ndarray:
    """The symmetric positive-definite factor ``P = (S S^T)^1/2`` of ``S = P U`` ``(..., 3, 3)``:
    what an ellipsoid fit can recover of a soft-iron matrix."""
    w, V = np.linalg.eigh(S @ np.swapaxes(S, -1, -2))
    return np.einsum("...ij,...j,...kj->...ik", V, np.sqrt(np.maximum(w, 0.0)), V)


class EllipsoidRLS:
    """Batched recursive least-squares ellipsoid fit (information form, noise-compensated).

    Parameters
    ----------
    field_T : array_like
        ``(B,)`` magnitude of the Earth field of the filter's own model (WMM), tesla.
    noise_T : float
        The filter's model of the magnetometer white noise, 1-sigma per axis, tesla (0: the
        plain algebraic fit).
    forgetting : float
        Forgetting factor ``lambda`` per sample period (1: none). Below 1 the information of
        directions a manoeuvre excites fades in straight flight, until the prior holds them.
    prior_sigma : float
        1-sigma of the prior on ``theta`` (normalised units) about the unit sphere.
    """

    def __init__(self, field_T, noise_T: float = 0.0, forgetting: float = 1.0,
                 prior_sigma: float = 1e3):
        if not 0.0 < forgetting <= 1.0:
            raise ValueError(f"forgetting factor {forgetting}: expected 0 < lambda <= 1")
        self.field_T = np.asarray(field_T, float)
        self.s2 = (float(noise_T) / self.field_T) ** 2
        self.forgetting = forgetting
        B = self.field_T.shape[0]
        self.moments = np.zeros((B, len(_MONO)))       #: weighted sums of the monomials
        self.prior_weight = 1.0                          #: lambda^n of the prior
        self.prior_info = 1.0 / prior_sigma ** 2
        self.samples = np.zeros(B, int)

    def update(self, mag_b_T: np.ndarray, valid: np.ndarray | None = None) -> None:
        """Samples ``(B, K, 3)`` in time order (or one, ``(B, 3)``), tesla; samples whose
        ``valid`` is False carry no weight (the forgetting still runs)."""
        m = np.asarray(mag_b_T, float)
        if m.ndim == 2:
            m = m[:, None]
            valid = None if valid is None else np.asarray(valid)[:, None]
        K = m.shape[1]
        ok = np.all(np.isfinite(m), -1)
        if valid is not None:
            ok &= np.asarray(valid, bool)
        u = np.where(ok[..., None], m, 0.0) / self.field_T[:, None, None]
        w = self.forgetting ** np.arange(K - 1, -1, -1.0) * ok
        self.moments = self.forgetting ** K * self.moments + np.einsum(
            "bk,bkj->bj", w, monomials(u, self.s2))
        self.prior_weight *= self.forgetting ** K
        self.samples += ok.sum(1)

    def theta(self) -> np.ndarray:
        """The least-squares parameters ``(B, 9)``."""
        M, eta = normal_equations(self.moments)
        lam0 = self.prior_weight * self.prior_info
        return np.linalg.solve(M + lam0 * np.eye(N_PARAMS), (eta + lam0 * SPHERE)[..., None])[..., 0]

    def estimate(self):
        """``hard_iron_T`` ``(B, 3)``, the symmetric ``soft_iron`` ``(B, 3, 3)`` and ``ok``
        ``(B,)`` (False, with NaN estimates, where the fitted quadric is not an ellipsoid)."""
        c, A_n = ellipsoid(self.theta())
        soft, ok = sqrt_inverse_spd(A_n)
        ok &= np.all(np.isfinite(c), -1)
        hard = np.where(ok[:, None], c * self.field_T[:, None], np.nan)
        return hard, soft, ok


def calibrate(mag_b_T: np.ndarray, hard_iron_T: np.ndarray, soft_iron: np.ndarray) -> np.ndarray:
    """``S^-1 (m - b)`` ``(B, 3)``: the Earth field in body axes (NaN without a calibration)."""
    soft = np.where(np.isfinite(soft_iron), soft_iron, np.eye(3))
    out = np.linalg.solve(soft, (mag_b_T - hard_iron_T)[..., None])[..., 0]
    return np.where(np.all(np.isfinite(soft_iron), (-2, -1))[:, None], out, np.nan)


def calibration_errors(hard_est_T, soft_est, hard_true_T, soft_true, field_T):
    """Relative errors against the truth: ``|b_est - b| / |m_n|`` and
    ``||S_est - P||_F / ||P||_F`` with ``P`` the symmetric factor of the true soft iron.
    Shapes ``(B, ..., 3)``, ``(B, ..., 3, 3)``; ``field_T`` broadcast to ``(B, ...)``."""
    P = symmetric_soft_iron(np.asarray(soft_true, float))
    hard = np.linalg.norm(hard_est_T - hard_true_T, axis=-1) / field_T
    soft = np.linalg.norm(soft_est - P, axis=(-2, -1)) / np.linalg.norm(P, axis=(-2, -1))
    return hard, soft


def turns(yaw_rad: np.ndarray) -> np.ndarray:
    """Full turns completed along the last axis: accumulated absolute heading change / 2 pi."""
    d = np.abs(np.diff(np.unwrap(yaw_rad, axis=-1), axis=-1))
    return np.concatenate([np.zeros_like(d[..., :1]), np.cumsum(d, axis=-1)], -1) / (2 * np.pi)


def field_model_n_T(lat_rad, lon_rad, h_m, date: str, grid: bool = True) -> np.ndarray:
    """The filter's own field model: WMM (north, east, down), tesla, ``(B, 3)`` at the given
    (estimated) positions, evaluated on a 0.01 deg, 100 m grid (the field changes by a few nT
    per km) or, with ``grid=False``, at the positions themselves (one evaluation per run: for
    the calibration's scale reference, once); each run's value depends on its own position
    only."""
    lat, lon, h = np.degrees(lat_rad), np.degrees(lon_rad), np.asarray(h_m, float)
    key = np.stack([np.round(lat, 2), np.round(lon, 2), np.round(h, -2)] if grid else [lat, lon, h], -1)
    cells, inverse = np.unique(key, axis=0, return_inverse=True)
    values = np.array([wmm_field_n_T(float(a), float(b), float(c), date) for a, b, c in cells])
    return values[np.asarray(inverse).reshape(-1)]


def calibration_history(truth, data, noise_T: float, forgetting: float = 1.0, every_s: float = 1.0) -> dict:
    """The online fit of a magnetometer's :class:`~navsim.sensors.base.SensorData` (the fit
    the ``mag_heading`` measurement runs, scale from the field model at the start), scored
    every ``every_s`` against the data's true errors.

    Returns ``t_s`` ``(E,)``, ``turns`` ``(E,)`` (full turns of the true heading),
    ``hard_iron_err`` and ``soft_iron_err`` ``(B, E)`` (:func:`calibration_errors`, fractions)."""
    field0 = field_model_n_T(truth.lat_rad[:1], truth.lon_rad[:1], truth.h_m[:1], data.meta.get("date", WMM_DATE),
                             grid=False)
    B = data.valid.shape[0]
    fit = EllipsoidRLS(np.full(B, np.linalg.norm(field0)), noise_T, forgetting)
    t_s = np.arange(0.0, data.t_s[-1] + 1e-9, every_s)
    ends = np.searchsorted(data.t_s, t_s + 1e-9)
    mag, start = data.values["mag_b_T"], 0
    hard_true, soft_true = data.errors["hard_iron_T"][:, 0], data.errors["soft_iron"]
    field_true = np.linalg.norm(data.errors["field_n_T"], axis=-1)
    hard_err, soft_err = np.full((B, len(t_s)), np.nan), np.full((B, len(t_s)), np.nan)
    for e, end in enumerate(ends):
        fit.update(mag[:, start:end], data.valid[:, start:end])
        start = end
        hard, soft, _ = fit.estimate()
        hard_err[:, e], soft_err[:, e] = calibration_errors(hard, soft, hard_true, soft_true,
                                                            field_true[max(end - 1, 0)])
    yaw = np.interp(t_s, truth.t_s, np.unwrap(truth.euler_rad[:, 2]))
    return {"t_s": t_s, "turns": turns(yaw), "hard_iron_err": hard_err, "soft_iron_err": soft_err}
