"""The Kalman filter's measurement update compiled, and the error-state filter's feedback:
:func:`joseph_update` (the Joseph form in ``O(n^2 m)``, one measurement after the other, per
run), and :func:`feed_back` of the estimated errors into the navigation state
(:func:`rodrigues` for the attitude)."""

from __future__ import annotations

import math

import numpy as np

from navsim.foundations.compiled import njit
from navsim.foundations.transform import rodrigues
from navsim.navigation.kernels.linalg import _matmul, _solve, _symmetrize


@njit(cache=True)
def joseph_update(x, P, z, H, R, valid, ends, y, S, nis, bad):
    """Joseph-form updates of the runs where ``valid``, in place, one measurement after the
    other: measurement ``g`` is the rows ``ends[g]:ends[g+1]`` of ``z``, ``H`` and the diagonal
    block of ``R``. Each is ``y = z - H x``, ``S = H P H^T + R`` (symmetrised),
    ``K = P H^T S^-1``, ``x <- x + K y``, ``P <- (I - K H) P (I - K H)^T + K R K^T``
    (symmetrised), evaluated as ``A = P - K (H P)``, ``A - (A H^T) K^T + K R K^T`` row by row
    (``O(n^2 m)``, the zeros of ``H`` skipped in ``A H^T``), and ``nis = y^T S^-1 y``. A valid
    run whose ``S`` is singular gets NaN state and covariance; an invalid one keeps them, with
    NaN NIS. After each measurement a run whose ``P`` has a non-finite entry or a negative
    variance is flagged in ``bad``.

    Parameters
    ----------
    x : (B, n), P : (B, n, n)
        State and covariance (symmetric); updated.
    z : (B, M), H : (B, M, n), R : (B, M, M), valid : (B, G) bool, ends : (G + 1,) int
        The ``G`` measurements, stacked (``M`` rows in all).
    y : (B, M), S : (B, M, M), nis : (B, G), bad : (B,) bool
        Out: innovations, the diagonal blocks of their covariances, the NIS, the flags (set,
        never cleared).
    """
    B, n, G = P.shape[0], P.shape[1], ends.shape[0] - 1
    for g in range(G):
        r0, m = ends[g], ends[g + 1] - ends[g]
        zg, yg = np.empty(m), np.empty(m)
        Hg = np.empty((m, n))
        Rg, Sg = np.empty((m, m)), np.empty((m, m))
        HP, Kt, W, work, index = joseph_scratch(n, m)
        acc = np.empty(n)
        for b in range(B):
            for i in range(m):
                zg[i] = z[b, r0 + i]
                for j in range(n):
                    Hg[i, j] = H[b, r0 + i, j]
                for j in range(m):
                    Rg[i, j] = R[b, r0 + i, r0 + j]
            nis[b, g] = joseph_run(x[b], P[b], zg, Hg, Rg, valid[b, g], yg, Sg, HP, Kt, W, work, index)
            for i in range(m):
                y[b, r0 + i] = yg[i]
                for j in range(m):
                    S[b, r0 + i, r0 + j] = Sg[i, j]
            bad[b] = bad[b] or not _is_covariance_like(P[b], acc)


@njit(cache=True)
def _is_covariance_like(P, acc):
    """Every entry of ``P`` finite and no variance negative (``acc``: scratch of ``P``'s
    size). The rows are summed column by column first, in vector lanes: a sum is finite when
    its terms are, unless it overflows, and only then are the entries looked at one by one."""
    n = P.shape[0]
    for j in range(n):
        acc[j] = 0.0
    for i in range(n):
        if P[i, i] < 0.0:
            return False
        for j in range(n):
            acc[j] += P[i, j]
    for j in range(n):
        if not math.isfinite(acc[j]):
            for i in range(n):
                if not math.isfinite(P[i, j]):
                    return False
    return True


@njit(cache=True)
def _innovation(x, P, z, H, R, y, S, HP):
    """One run's innovation ``y = z - H x`` (also ``HP``'s last column), ``HP = H P`` (its
    first ``n`` columns) and ``S = H P H^T + R`` (made exactly symmetric), in place."""
    n, m = P.shape[0], H.shape[0]
    _matmul(H, P, HP)              # columns 0..n-1
    for i in range(m):
        s = z[i]
        for k in range(n):
            s -= H[i, k] * x[k]
        y[i] = s
        HP[i, n] = s
    for i in range(m):
        for j in range(m):
            s = 0.0
            for k in range(n):
                s += HP[i, k] * H[j, k]
            S[i, j] = s + R[i, j]
    _symmetrize(S)


@njit(cache=True)
def joseph_run(x, P, z, H, R, valid, y, S, HP, Kt, W, work, index):
    """One run's Joseph update of :func:`joseph_update` (``x`` ``(n,)``, ``P`` ``(n, n)``, ``z``
    ``(m,)``, ``H`` ``(m, n)``, ``R`` ``(m, m)``; out: ``y`` ``(m,)``, ``S`` ``(m, m)``); returns
    the NIS. Scratch (:func:`joseph_scratch`): ``HP``,
    ``Kt`` ``(m, n + 1)`` (``H P`` and ``S^-1 H P``, the innovation and ``S^-1 y`` in the last
    column: one elimination for both), ``W`` ``(m, m)``, ``work`` ``(n + n m + m)`` floats,
    ``index`` ``(n m + m + 1)`` ints."""
    n, m = P.shape[0], H.shape[0]
    row, vals, D = work[:n], work[n:n + n * m], work[n + n * m:n + n * m + m]
    cols, first = index[:n * m], index[n * m:]
    _innovation(x, P, z, H, R, y, S, HP)
    if not valid:
        return np.nan
    if not _solve(S, HP, W, Kt):
        x[:] = np.nan
        P[:, :] = np.nan
        return np.nan
    nis = 0.0
    for i in range(m):
        nis += y[i] * Kt[i, n]
    for k in range(m):
        for i in range(n):
            x[i] += Kt[k, i] * y[k]
    nz = 0                         # the nonzero entries of H, row by row, in column order
    for j in range(m):
        first[j] = nz
        for k in range(n):
            if H[j, k] != 0.0:
                cols[nz], vals[nz] = k, H[j, k]
                nz += 1
    first[m] = nz
    for i in range(n):
        for j in range(n):         # row i of A = P - K H P
            row[j] = P[i, j]
        for k in range(m):
            c = Kt[k, i]
            for j in range(n):
                row[j] -= c * HP[k, j]
        for j in range(m):         # row i of D = K R - A H^T (H's zeros skipped)
            s = 0.0
            for k in range(m):
                s += Kt[k, i] * R[k, j]
            for z in range(first[j], first[j + 1]):
                s -= row[cols[z]] * vals[z]
            D[j] = s
        for j in range(n):         # row i of P = A + D K^T
            P[i, j] = row[j]
        for k in range(m):
            c = D[k]
            for j in range(n):
                P[i, j] += c * Kt[k, j]
    _symmetrize(P)
    return nis


@njit(cache=True)
def joseph_scratch(n, m):
    """The scratch arrays of :func:`joseph_run` for ``n`` states and ``m`` rows, in its order
    ``(HP, Kt, W, work, index)``."""
    return (np.empty((m, n + 1)), np.empty((m, n + 1)), np.empty((m, m)), np.empty(n + n * m + m),
            np.empty(n * m + m + 1, np.int64))


@njit(cache=True)
def feed_back(x, att, vel, pos, C, vel_n, lat, lon, h):
    """The error-state filter's navigation feedback of every run, in place: ``C_nb <-
    exp([phi x]) C_nb``, ``v <- v - dv``, ``(L, lambda, h) <- (L, lambda, h) - dp``, the
    errors read from ``x`` ``(B, n)`` at the blocks starting at ``att``, ``vel``, ``pos``."""
    R, T = np.empty((3, 3)), np.empty((3, 3))
    for b in range(x.shape[0]):
        rodrigues(x[b, att], x[b, att + 1], x[b, att + 2], R)
        for i in range(3):
            for j in range(3):
                T[i, j] = R[i, 0] * C[b, 0, j] + R[i, 1] * C[b, 1, j] + R[i, 2] * C[b, 2, j]
        for i in range(3):
            for j in range(3):
                C[b, i, j] = T[i, j]
            vel_n[b, i] -= x[b, vel + i]
        lat[b] -= x[b, pos]
        lon[b] -= x[b, pos + 1]
        h[b] -= x[b, pos + 2]
