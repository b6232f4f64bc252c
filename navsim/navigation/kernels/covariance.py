"""The Kalman filter's prediction compiled, per run over the ``n`` states:
:func:`discretize_series` (the matrix-exponential series of ``Phi`` and ``Qd``), :func:`predict`
(``Phi P Phi^T + Qd``) and :func:`propagate_covariance` (the series of the covariance equation
itself). Products with ``F`` on the left skip its zeros (most of an error-state ``F``), listed
once per run (:func:`_nonzeros`, :func:`_sparse_left`), and their innermost loops run along rows
so that LLVM vectorises them."""

from __future__ import annotations

import numpy as np

from navsim.foundations.compiled import njit
from navsim.navigation.kernels.linalg import _matmul, _symmetrize


@njit(cache=True)
def discretize_series(F, Qc, T, order, Phi, Qd):
    """``Phi = sum_k (F T)^k / k!`` and ``Qd = sum_k M_k T^k / k!`` (``M_1 = Qc``,
    ``M_k+1 = F M_k + (F M_k)^T``, symmetric as ``Qc`` is), to ``order``, of each run. The
    products have ``F`` on the left and run over its nonzero entries only (listed once per run:
    59 of 256 in P0's 16-state model), which leaves the sums' order, so the result, unchanged.

    Parameters
    ----------
    F : (B, n, n) array
        The continuous system matrices.
    Qc : (B, n, n) or (1, n, n) array
        The continuous process-noise densities, symmetric (one for every run).
    T : float
        The interval, s.
    order : int
        The last power of the series.
    Phi, Qd : (B, n, n) arrays
        Out: the transition matrices and the (symmetrised) process noise.
    """
    B, n = F.shape[0], F.shape[1]
    term = np.empty((n, n))
    nxt = np.empty((n, n))
    M = np.empty((n, n))
    FM = np.empty((n, n))
    rows = np.empty(n * n, np.int64)
    cols = np.empty(n * n, np.int64)
    vals = np.empty(n * n)
    for b in range(B):
        Fb, P, Q, Qb = F[b], Phi[b], Qd[b], Qc[b if Qc.shape[0] > 1 else 0]
        nz = _nonzeros(Fb, rows, cols, vals)
        for i in range(n):
            for j in range(n):
                term[i, j] = 1.0 if i == j else 0.0
                P[i, j] = term[i, j]
                M[i, j] = Qb[i, j]
                Q[i, j] = Qb[i, j] * T
        c = T
        for k in range(1, order + 1):
            _sparse_left(rows, cols, vals, nz, term, nxt)       # F^k = F F^k-1
            s = T / k
            for i in range(n):
                for j in range(n):
                    term[i, j] = nxt[i, j] * s
                    P[i, j] += term[i, j]
            if k < order:
                _sparse_left(rows, cols, vals, nz, M, FM)
                c = c * T / (k + 1)
                for i in range(n):
                    for j in range(n):
                        M[i, j] = FM[i, j] + FM[j, i]
                        Q[i, j] += M[i, j] * c
        _symmetrize(Q)


@njit(cache=True)
def _nonzeros(A, rows, cols, vals) -> int:
    """The nonzero entries of a square ``A`` into ``rows``, ``cols``, ``vals`` (row by row);
    returns their count, ``nz`` for :func:`_sparse_left`."""
    n, nz = A.shape[0], 0
    for i in range(n):
        for k in range(n):
            if A[i, k] != 0.0:
                rows[nz], cols[nz], vals[nz] = i, k, A[i, k]
                nz += 1
    return nz


@njit(cache=True)
def _sparse_left(rows, cols, vals, nz, X, out):
    """``out = A @ X`` for the ``nz`` nonzero entries ``A[rows, cols] = vals`` of a square ``A``."""
    out[:, :] = 0.0
    n = X.shape[1]
    for z in range(nz):
        i, k, a = rows[z], cols[z], vals[z]
        for j in range(n):
            out[i, j] += a * X[k, j]


@njit(cache=True)
def predict(x, P, Phi, Qd):
    """``x <- Phi x``, ``P <- Phi P Phi^T + Qd`` (symmetrised) of each run, in place."""
    B, n = P.shape[0], P.shape[1]
    A = np.empty((n, n))
    C = np.empty((n, n))
    Ft = np.empty((n, n))
    xn = np.empty(n)
    for b in range(B):
        Fb, Pb = Phi[b], P[b]
        for i in range(n):
            s = 0.0
            for k in range(n):
                s += Fb[i, k] * x[b, k]
            xn[i] = s
            for j in range(n):
                Ft[i, j] = Fb[j, i]
        for i in range(n):             # element by element (see linalg)
            x[b, i] = xn[i]
        _matmul(Fb, Pb, A)
        _matmul(A, Ft, C)
        for i in range(n):
            for j in range(i, n):
                v = 0.5 * ((C[i, j] + Qd[b, i, j]) + (C[j, i] + Qd[b, j, i]))
                Pb[i, j] = v
                Pb[j, i] = v


@njit(cache=True)
def _state_series(xb, sparse, T, order, xk, xn):
    """``xb <- xb + sum_k (F T)^k xb / k!`` to ``order``, in place; ``sparse``: ``F``'s nonzero
    entries ``(rows, cols, vals, nz)`` (:func:`_nonzeros`); ``xk``, ``xn``: work rows."""
    rows, cols, vals, nz = sparse
    n = xb.shape[0]
    for i in range(n):
        xk[i] = xb[i]
    for k in range(1, order + 1):
        s = T / k
        for i in range(n):
            xn[i] = 0.0
        for z in range(nz):
            xn[rows[z]] += vals[z] * xk[cols[z]]
        for i in range(n):
            xk[i] = xn[i] * s
            xb[i] += xk[i]


@njit(cache=True)
def propagate_covariance(x, P, F, Qc, T, order):
    """``x <- Phi x`` and ``P <- Phi P Phi^T + Qd`` of each run over ``T``, in place, by the
    Taylor series in ``T`` to ``order`` of the covariance equation ``P' = F P + P F^T + Qc``:
    ``P(T) = sum_k X_k T^k / k!`` with ``X_0 = P``, ``X_1 = F P + (F P)^T + Qc``,
    ``X_k+1 = F X_k + (F X_k)^T`` (each exactly symmetric), and ``x(T) = sum_k (F T)^k x / k!``.

    This is the series of :func:`discretize_series` followed by :func:`predict` with the terms
    above ``T^order`` left out: at order 6 over P0's 1 s epochs both agree with Van Loan's exact
    discretisation to rounding (1e-15 of ``sqrt(P_ii P_jj)``), and it costs ``order`` products
    with the nonzero entries of ``F`` instead of ``2 order + 1`` products and two dense ones.

    Parameters
    ----------
    x : (B, n), P : (B, n, n) arrays
        State and covariance (symmetric); updated.
    F : (B, n, n) array
        The continuous system matrices.
    Qc : (B, n, n) or (1, n, n) array
        The continuous process-noise densities, symmetric.
    T : float
        The interval, s.
    order : int
        The last power of ``T``.
    """
    B, n = P.shape[0], P.shape[1]
    X = np.empty((n, n))
    FX = np.empty((n, n))
    xk = np.empty(n)
    xn = np.empty(n)
    rows = np.empty(n * n, np.int64)
    cols = np.empty(n * n, np.int64)
    vals = np.empty(n * n)
    for b in range(B):
        Fb, Pb, Qb = F[b], P[b], Qc[b if Qc.shape[0] > 1 else 0]
        nz = _nonzeros(Fb, rows, cols, vals)
        _state_series(x[b], (rows, cols, vals, nz), T, order, xk, xn)
        _sparse_left(rows, cols, vals, nz, Pb, FX)
        for i in range(n):         # X and P symmetric: the upper triangle, then mirrored
            for j in range(i, n):
                v = (FX[i, j] + FX[j, i]) + Qb[i, j]
                X[i, j] = v
                X[j, i] = v
        c = T
        for k in range(1, order + 1):
            for i in range(n):
                for j in range(i, n):
                    Pb[i, j] += c * X[i, j]
            if k < order:
                _sparse_left(rows, cols, vals, nz, X, FX)
                for i in range(n):
                    for j in range(i, n):
                        v = FX[i, j] + FX[j, i]
                        X[i, j] = v
                        X[j, i] = v
                c = c * T / (k + 1)
        for i in range(n):
            for j in range(i + 1, n):
                Pb[j, i] = Pb[i, j]
