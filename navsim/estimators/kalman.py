"""Pure, batched Kalman filter functions (after filterpy's ``predict``/``update``).

All arrays carry a leading run axis ``B``: ``x`` ``(B, n)``, ``P`` ``(B, n, n)``, ``F`` ``(B, n, n)``,
``z`` ``(B, m)``, ``H`` ``(B, m, n)``, ``R`` ``(B, m, m)``, ``valid`` ``(B,)``.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg


def symmetrize(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def discretize_series(F: np.ndarray, Qc: np.ndarray, T: float, order: int = 3):
    """Transition matrix and process noise over ``T`` by the matrix-exponential series
    (P3: third order): ``Phi = sum (F T)^k / k!``, ``Qd = sum M_k T^k / k!`` with
    ``M_1 = Qc``, ``M_{k+1} = F M_k + M_k F^T``.

    Parameters
    ----------
    F : (B, n, n) continuous system matrix.
    Qc : (B, n, n) or (n, n) continuous process-noise spectral density.
    """
    n = F.shape[-1]
    Phi = np.broadcast_to(np.eye(n), F.shape).copy()
    term = Phi.copy()
    M = np.broadcast_to(Qc, F.shape).copy()
    Qd = M * T
    Ft = np.swapaxes(F, -1, -2)
    for k in range(1, order + 1):
        term = term @ F * (T / k)
        Phi += term
        if k < order:
            M = F @ M + M @ Ft
            Qd += M * (T ** (k + 1) / math.factorial(k + 1))
    return Phi, symmetrize(Qd)


def discretize_van_loan(F: np.ndarray, Qc: np.ndarray, T: float):
    """Transition matrix and process noise by Van Loan's method:
    ``expm([[-F, Qc], [0, F^T]] T) = [[., Phi^-1 Qd], [0, Phi^T]]``."""
    B, n, _ = F.shape
    A = np.zeros((B, 2 * n, 2 * n))
    A[:, :n, :n] = -F
    A[:, :n, n:] = Qc
    A[:, n:, n:] = np.swapaxes(F, -1, -2)
    E = scipy.linalg.expm(A * T)
    Phi = np.swapaxes(E[:, n:, n:], -1, -2)
    Qd = Phi @ E[:, :n, n:]
    return Phi, symmetrize(Qd)


def predict(x, P, Phi, Qd):
    """``x <- Phi x``, ``P <- Phi P Phi^T + Qd``."""
    x = (Phi @ x[..., None])[..., 0]
    P = Phi @ P @ np.swapaxes(Phi, -1, -2) + Qd
    return x, symmetrize(P)


def solve_runs(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.linalg.solve(A, b)`` of a batch of runs, where a singular ``A`` spoils its own run only.

    :func:`numpy.linalg.solve` raises for the whole batch when one matrix is singular; then the
    runs are solved one at a time (bit for bit the batch's values) and a singular run's solution
    is NaN, so that the Monte Carlo loop flags that run diverged and the others go on.

    Parameters
    ----------
    A : (B, m, m) array
        The matrices.
    b : (B, m, k) array
        The right-hand sides.

    Returns
    -------
    (B, m, k) array
        The solutions; NaN in the runs whose ``A`` is singular.
    """
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        pass
    out = np.full(np.broadcast_shapes(A.shape[:-2], b.shape[:-2]) + b.shape[-2:], np.nan,
                  np.result_type(A, b))
    for i in range(out.shape[0]):
        try:
            out[i:i + 1] = np.linalg.solve(A[i:i + 1], b[i:i + 1])
        except np.linalg.LinAlgError:
            continue
    return out


def update(x, P, z, H, R, valid=None):
    """Joseph-form measurement update of the runs where ``valid``.

    Returns ``x, P, y, S, nis`` with the innovation ``y = z - H x``, its covariance
    ``S = H P H^T + R`` and the normalised innovation squared ``y^T S^-1 y`` (NaN where not
    valid). A valid run whose ``S`` is singular gets NaN state and covariance (:func:`solve_runs`);
    the other runs are updated as they would be alone.
    """
    Ht = np.swapaxes(H, -1, -2)
    y = z - (H @ x[..., None])[..., 0]
    PHt = P @ Ht
    S = H @ PHt + R
    S = symmetrize(S)
    # K = P H^T S^-1, via a solve on S (symmetric positive definite); a singular S gives NaN in
    # its own run only
    K = np.swapaxes(solve_runs(S, np.swapaxes(PHt, -1, -2)), -1, -2)
    nis = np.einsum("bi,bi->b", y, solve_runs(S, y[..., None])[..., 0])
    n = P.shape[-1]
    IKH = np.eye(n) - K @ H
    P_new = IKH @ P @ np.swapaxes(IKH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
    x_new = x + (K @ y[..., None])[..., 0]
    if valid is not None and not np.all(valid):
        v = np.asarray(valid, bool)
        x_new = np.where(v[:, None], x_new, x)
        P_new = np.where(v[:, None, None], P_new, P)
        nis = np.where(v, nis, np.nan)
    return x_new, symmetrize(P_new), y, S, nis
