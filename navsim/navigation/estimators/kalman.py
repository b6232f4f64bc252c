"""Batched Kalman filter functions (after filterpy's ``predict``/``update``): pure ones that
return new arrays, and ``*_in_place`` ones, one compiled call per epoch, that change the
filter's own ``x`` and ``P``.

All arrays carry a leading run axis ``B``: ``x`` ``(B, n)``, ``P`` ``(B, n, n)``, ``F`` ``(B, n, n)``,
``z`` ``(B, m)``, ``H`` ``(B, m, n)``, ``R`` ``(B, m, m)``, ``valid`` ``(B,)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from navsim.navigation.kernels import covariance
from navsim.navigation.kernels.update import joseph_update


def symmetrize(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def discretize_series(F: np.ndarray, Qc: np.ndarray, T: float, order: int = 3):
    """Transition matrix and process noise over ``T`` by the matrix-exponential series
    (P3: third order): ``Phi = sum (F T)^k / k!``, ``Qd = sum M_k T^k / k!`` with
    ``M_1 = Qc``, ``M_{k+1} = F M_k + M_k F^T`` (compiled, one run at a time:
    :func:`navsim.navigation.kernels.covariance.discretize_series`).

    Parameters
    ----------
    F : (B, n, n) continuous system matrix.
    Qc : (B, n, n) or (n, n) continuous process-noise spectral density, symmetric.
    """
    F = np.ascontiguousarray(F, float)
    Phi, Qd = np.empty_like(F), np.empty_like(F)
    Qc = np.asarray(Qc, float)
    Qc = 0.5 * (Qc + np.swapaxes(Qc, -1, -2))       # the kernel's recursion needs it symmetric
    Qc = Qc[None] if Qc.ndim == 2 else Qc
    covariance.discretize_series(F, np.ascontiguousarray(Qc), float(T), int(order), Phi, Qd)
    return Phi, Qd


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
    """``x <- Phi x``, ``P <- Phi P Phi^T + Qd`` (symmetrised; compiled:
    :func:`navsim.navigation.kernels.covariance.predict`). The inputs are left as they are."""
    x, P = np.array(x, float), np.array(P, float)
    covariance.predict(x, P, np.ascontiguousarray(Phi, float), _batch(Qd, P.shape))
    return x, P


def _batch(a, shape) -> np.ndarray:
    """``a`` broadcast to ``shape`` as a contiguous float array."""
    a = np.asarray(a, float)
    return np.ascontiguousarray(np.broadcast_to(a, shape)) if a.shape != shape else np.ascontiguousarray(a)


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


def propagate_in_place(x, P, F, Qc, T: float, order: int) -> None:
    """``x <- Phi x``, ``P <- Phi P Phi^T + Qd`` over ``T`` by the Taylor series in ``T`` of the
    covariance equation ``P' = F P + P F^T + Qc`` to ``order`` (compiled:
    :func:`navsim.navigation.kernels.covariance.propagate_covariance`): the same as :func:`discretize_series` then
    :func:`predict` less the terms above ``T^order``, in about a third of the work.

    ``x`` ``(B, n)`` and ``P`` ``(B, n, n)`` are contiguous float arrays, changed in place.
    """
    Qc = np.asarray(Qc, float)
    Qc = 0.5 * (Qc + np.swapaxes(Qc, -1, -2))
    covariance.propagate_covariance(x, P, np.ascontiguousarray(F, float),
                                 np.ascontiguousarray(Qc[None] if Qc.ndim == 2 else Qc), float(T), int(order))


@dataclass
class Updates:
    """The outcome of :func:`update_in_place`: per measurement, its innovation ``y`` ``(B, m)``,
    covariance ``S`` ``(B, m, m)`` and NIS ``(B,)``, and ``bad`` ``(B,)``, the runs whose
    covariance had a non-finite entry or a negative variance after any of them."""

    y: list
    S: list
    nis: list
    bad: np.ndarray


def update_in_place(x, P, measurements) -> Updates:
    """Joseph-form updates with each measurement in turn, as :func:`update` applied one after
    the other, in one compiled call (:func:`update_stacked`). Each measurement is a model's
    :class:`~navsim.navigation.estimators.measurements.Linearised`, or the plain arrays
    ``(z, H, R, valid)`` as a tuple (``valid``: the runs that have a sample, or None for all).
    ``x`` ``(B, n)`` and ``P`` ``(B, n, n)`` are contiguous float arrays, changed in place."""
    B, n = x.shape
    models = [m if isinstance(m, tuple) else (m.z, m.H, m.R, m.valid) for m in measurements]
    ends = np.cumsum([0] + [np.shape(H)[-2] for _, H, _, _ in models])
    M, G = int(ends[-1]), len(models)
    z_all, H_all = np.empty((B, M)), np.empty((B, M, n))
    R_all, valid_all = np.zeros((B, M, M)), np.empty((B, G), bool)
    for g, (z, H, R, valid) in enumerate(models):
        r = slice(ends[g], ends[g + 1])
        z_all[:, r], H_all[:, r], R_all[:, r, r] = z, H, R
        valid_all[:, g] = True if valid is None else valid
    return update_stacked(x, P, z_all, H_all, R_all, valid_all, ends)


def update_stacked(x, P, z, H, R, valid, ends) -> Updates:
    """The updates of :func:`update_in_place` from the measurements stacked already: ``z``
    ``(B, M)``, ``H`` ``(B, M, n)``, ``R`` ``(B, M, M)`` (its diagonal blocks read), ``valid``
    ``(B, G)``, measurement ``g`` the rows ``ends[g]:ends[g + 1]`` (compiled:
    :func:`navsim.navigation.kernels.update.joseph_update`)."""
    B, M = z.shape
    G = len(ends) - 1
    y, S, nis, bad = np.empty((B, M)), np.zeros((B, M, M)), np.empty((B, G)), np.zeros(B, bool)
    joseph_update(x, P, z, H, R, valid, np.asarray(ends, np.int64), y, S, nis, bad)
    cut = [slice(ends[g], ends[g + 1]) for g in range(G)]
    return Updates([y[:, r] for r in cut], [S[:, r, r] for r in cut], [nis[:, g] for g in range(G)], bad)


def update(x, P, z, H, R, valid=None):
    """Joseph-form measurement update of the runs where ``valid`` (compiled:
    :func:`navsim.navigation.kernels.update.joseph_update`).

    Returns ``x, P, y, S, nis`` with the innovation ``y = z - H x``, its covariance
    ``S = H P H^T + R`` and the normalised innovation squared ``y^T S^-1 y`` (NaN where not
    valid). A valid run whose ``S`` is singular gets NaN state and covariance; the other runs
    are updated as they would be alone. The inputs are left as they are.
    """
    x, P = np.array(x, float), np.array(P, float)
    B, n = x.shape
    H = _batch(H, (B,) + np.shape(H)[-2:])
    m = H.shape[1]
    valid = np.ones(B, bool) if valid is None else _batch(valid, (B,)).astype(bool)
    y, S, nis = np.empty((B, m)), np.empty((B, m, m)), np.empty((B, 1))
    joseph_update(x, P, _batch(z, (B, m)), H, _batch(R, (B, m, m)), valid[:, None],
                          np.array([0, m]), y, S, nis, np.zeros(B, bool))
    return x, P, y, S, nis[:, 0]
