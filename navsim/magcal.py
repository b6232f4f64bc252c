"""Online magnetometer calibration by recursive least squares (P1, "full INS/GPS/magnetometer
integration"), batched over runs.

The magnetometer reads ``m = S m_b + b + n``: the Earth field in body axes ``m_b`` distorted by
the soft-iron matrix ``S`` and offset by the hard iron ``b``. As the aircraft turns, ``m_b``
sweeps a sphere of radius ``|m_n|`` and the readings an ellipsoid centred on ``b``:
``(m - b)^T A (m - b) = 1`` with ``A = (S S^T)^-1 / |m_n|^2``. Two estimators:

* :class:`EllipsoidRLS` fits that quadric, P1's method (an ellipse in the horizontal plane there,
  the ellipsoid here, as a fixed-wing banks in its turns): linear in the nine parameters
  ``theta`` of ``x^T A' x + 2 v^T x = 1`` (``A' = A / k``, ``v = -A' b``), recursive least squares
  with an optional forgetting factor. It needs no attitude, and so cannot tell a rotation inside
  ``S``: it returns the symmetric ``S`` (``S S^T = |m_n|^2 A^-1``); the field magnitude ``|m_n|``
  (World Magnetic Model) fixes the scale.
* :class:`AttitudeRLS` uses the navigation attitude and the model field: ``m = S (C_bn m_n) + b``
  is linear in ``S`` and ``b``, four parameters per axis sharing one regressor ``[m_b, 1]``; it
  recovers the whole ``S``, rotation included, as well as the attitude is known.

Both keep per run a ``(B, p, p)`` covariance and ``(B, p)`` parameters; a batch of ``B`` runs
equals ``B`` single runs.
"""

from __future__ import annotations

import numpy as np


class _RLS:
    """Recursive least squares on a scalar target per output, batched: ``y = phi^T theta``."""

    def __init__(self, B: int, p: int, outputs: int, forgetting: float = 1.0, p0: float = 1e6):
        self.theta = np.zeros((B, p, outputs))
        self.P = np.broadcast_to(np.eye(p) * p0, (B, p, p)).copy()
        self.lam = forgetting
        self.count = np.zeros(B, int)

    def update(self, phi: np.ndarray, y: np.ndarray, valid: np.ndarray) -> None:
        """``phi`` ``(B, p)``, ``y`` ``(B, outputs)``; runs where ``valid`` is False are kept."""
        Pphi = np.einsum("bij,bj->bi", self.P, phi)
        denom = self.lam + np.einsum("bi,bi->b", phi, Pphi)
        K = Pphi / denom[:, None]
        err = y - np.einsum("bi,bio->bo", phi, self.theta)
        theta = self.theta + K[:, :, None] * err[:, None, :]
        P = (self.P - K[:, :, None] * Pphi[:, None, :]) / self.lam
        P = 0.5 * (P + np.swapaxes(P, 1, 2))
        v = np.asarray(valid, bool)
        self.theta[v], self.P[v] = theta[v], P[v]
        self.count += v


class EllipsoidRLS:
    """Attitude-free ellipsoid fit (see the module docstring). ``field_T``: the Earth field
    magnitude that scales ``S`` (scalar or ``(B,)``)."""

    def __init__(self, B: int, forgetting: float = 1.0, scale_T: float = 50e-6):
        self.rls = _RLS(B, 9, 1, forgetting, p0=1e4)
        self.scale = scale_T          # readings are divided by this to keep the problem well scaled

    def update(self, mag_T: np.ndarray, valid: np.ndarray) -> None:
        x, y, z = np.moveaxis(np.asarray(mag_T, float) / self.scale, -1, 0)
        phi = np.stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z], -1)
        self.rls.update(phi, np.ones((len(x), 1)), valid)

    def estimate(self, field_T) -> tuple[np.ndarray, np.ndarray]:
        """Hard iron ``(B, 3)`` (tesla) and symmetric soft iron ``(B, 3, 3)``."""
        t = self.rls.theta[..., 0]
        A = np.stack([np.stack([t[:, 0], t[:, 3], t[:, 4]], -1), np.stack([t[:, 3], t[:, 1], t[:, 5]], -1),
                      np.stack([t[:, 4], t[:, 5], t[:, 2]], -1)], -2)
        v = t[:, 6:9]
        b = -np.linalg.solve(A, v[..., None])[..., 0]
        k = 1.0 + np.einsum("bi,bij,bj->b", b, A, b)
        M = A / k[:, None, None]                              # (m - b)^T M (m - b) = 1
        w, V = np.linalg.eigh(M)
        w = np.maximum(w, 1e-12)
        field = np.broadcast_to(np.asarray(field_T, float) / self.scale, (len(b),))
        S = np.einsum("bij,bj,bkj->bik", V, 1.0 / np.sqrt(w), V) / field[:, None, None]
        return b * self.scale, S


class AttitudeRLS:
    """Attitude-aided calibration ``m = S m_b + b`` (see the module docstring)."""

    def __init__(self, B: int, forgetting: float = 1.0, scale_T: float = 50e-6):
        self.rls = _RLS(B, 4, 3, forgetting, p0=1e4)
        self.scale = scale_T

    def update(self, mag_T: np.ndarray, field_b_T: np.ndarray, valid: np.ndarray) -> None:
        """``mag_T`` the readings, ``field_b_T`` the model field in body axes, ``(B, 3)``."""
        phi = np.concatenate([np.asarray(field_b_T, float) / self.scale, np.ones((len(mag_T), 1))], -1)
        self.rls.update(phi, np.asarray(mag_T, float) / self.scale, valid)

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        th = self.rls.theta                                    # (B, 4, 3): rows S^T, then b
        return th[:, 3, :] * self.scale, np.swapaxes(th[:, :3, :], 1, 2).copy()


def calibrate(readings_T: np.ndarray, hard_iron_T: np.ndarray, soft_iron: np.ndarray) -> np.ndarray:
    """Calibrated field ``S^-1 (m - b)`` of readings ``(B, M, 3)`` (or ``(B, 3)``)."""
    m = np.asarray(readings_T, float)
    b = hard_iron_T[:, None, :] if m.ndim == 3 else hard_iron_T
    d = m - b
    Sinv = np.linalg.inv(soft_iron)
    return np.einsum("bij,bnj->bni", Sinv, d) if m.ndim == 3 else np.einsum("bij,bj->bi", Sinv, d)


def symmetric_part(S: np.ndarray) -> np.ndarray:
    """``sqrt(S S^T)``: the symmetric factor of the polar decomposition ``S = P U`` (what an
    attitude-free fit can see)."""
    w, V = np.linalg.eigh(S @ np.swapaxes(S, -1, -2))
    return np.einsum("...ij,...j,...kj->...ik", V, np.sqrt(np.maximum(w, 0.0)), V)


def errors(hard_est_T, soft_est, hard_true_T, soft_true, field_T) -> tuple[np.ndarray, np.ndarray]:
    """Hard-iron error relative to the field magnitude and soft-iron error (Frobenius,
    relative), per run."""
    hard = np.linalg.norm(hard_est_T - hard_true_T, axis=-1) / np.asarray(field_T, float)
    soft = np.linalg.norm(soft_est - soft_true, axis=(-2, -1)) / np.linalg.norm(soft_true, axis=(-2, -1))
    return hard, soft
