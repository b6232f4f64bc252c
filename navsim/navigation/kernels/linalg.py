"""The small dense linear algebra the Kalman kernels share, per run: a product that skips the
zeros of its left factor (:func:`_matmul`), the symmetric part in place (:func:`_symmetrize`),
a copy (:func:`_copy`), a solve by Gaussian elimination with partial pivoting (:func:`_solve`)
and the rotation matrix of a quaternion (:func:`quat_dcm`).

The kernels copy arrays element by element, never by a slice (``A[:, :] = S``): a slice copy
between arrays makes numba compile its shape-mismatch error, string formatting and all, about
3 s in every process that compiles the kernels afresh (a fresh clone, a fresh cache)."""

from __future__ import annotations

import math

from navsim.foundations.compiled import njit


@njit(cache=True)
def _matmul(A, B, out):
    """``out = A @ B`` (``out`` distinct from both), the zeros of ``A`` skipped."""
    n, m, p = A.shape[0], A.shape[1], B.shape[1]
    for i in range(n):
        for j in range(p):
            out[i, j] = 0.0
        for k in range(m):
            a = A[i, k]
            if a != 0.0:
                for j in range(p):
                    out[i, j] += a * B[k, j]


@njit(cache=True)
def _copy(dst, src):
    """``dst[:, :] = src`` of two matrices of one shape, element by element."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[i, j] = src[i, j]


@njit(cache=True)
def _symmetrize(A):
    """``A <- (A + A^T) / 2`` of a square matrix, in place."""
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (A[i, j] + A[j, i])
            A[i, j] = v
            A[j, i] = v


@njit(cache=True)
def _solve(S, Y, A, X):
    """``X = S^-1 Y`` by Gaussian elimination with partial pivoting (``S`` ``(m, m)``, ``Y``
    ``(m, r)``; ``A`` ``(m, m)`` scratch, ``X`` ``(m, r)`` out); False when ``S`` is singular."""
    m, r = S.shape[0], Y.shape[1]
    _copy(A, S)
    _copy(X, Y)
    for c in range(m):
        p = c
        for i in range(c + 1, m):
            if abs(A[i, c]) > abs(A[p, c]):
                p = i
        if A[p, c] == 0.0 or not math.isfinite(A[p, c]):
            return False
        if p != c:
            for j in range(m):
                A[c, j], A[p, j] = A[p, j], A[c, j]
            for j in range(r):
                X[c, j], X[p, j] = X[p, j], X[c, j]
        for i in range(c + 1, m):
            f = A[i, c] / A[c, c]
            for j in range(c, m):
                A[i, j] -= f * A[c, j]
            for j in range(r):
                X[i, j] -= f * X[c, j]
    for c in range(m - 1, -1, -1):
        d = A[c, c]
        for j in range(r):
            s = X[c, j]
            for k in range(c + 1, m):
                s -= A[c, k] * X[k, j]
            X[c, j] = s / d
    return True


@njit(cache=True)
def quat_dcm(w, x, y, z, C):
    """``C_nb`` ``(3, 3)`` of ``q_nb = (w, x, y, z)`` into ``C``: the compiled twin of
    :func:`navsim.foundations.transform.dcm_from_quat`, its operations in its order."""
    C[0, 0], C[0, 1], C[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    C[1, 0], C[1, 1], C[1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    C[2, 0], C[2, 1], C[2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
