"""Compiled kernels (numba ``njit(cache=True)``): per-sample work over a block of IMU samples.

Each kernel loops over the runs of a batch and, inside, over the ``K`` samples of a block, so a
run's arithmetic never depends on the other runs (a batch of 3 equals 3 single runs bit for
bit) and Python is entered once per block, not once per IMU sample.

Strapdown mechanization (:func:`strapdown_block`, behind :class:`navsim.strapdown.BlockStrapdown`)
in the local-level NED frame, per IMU interval with the
increments ``dtheta``, ``dv`` and the previous interval's ``dtheta_p``, ``dv_p``:

* coning: ``dtheta_c = dtheta + dtheta_p x dtheta / 12``;
* rotation and sculling: ``dv_c = dv + (dtheta / 2 + dtheta_p / 12) x dv + (dv_p x dtheta) / 12``;
* ``dv_n = C_nb dv_c - (omega_in dt / 2) x (C_nb dv_c)``;
  ``v <- v + dv_n + (g - (2 omega_ie + omega_en) x v) dt``;
* ``C_nb <- (I - [omega_in dt x]) C_nb exp([dtheta_c x])`` (Rodrigues, Taylor series of its
  coefficients below 0.05 rad), re-orthonormalised every 1000 steps;
* position: trapezoid on the old and new velocities with the WGS-84 radii.

Gravity (WGS-84 with J2, as :func:`navsim.earth.gravity_n`), Earth rate, transport rate and the
radii are evaluated every ``gravity_every`` steps and kept in the run's ``cache`` row between
blocks.

Kalman filter epochs, per run over the ``n`` states: :func:`discretize_series` (the
matrix-exponential series of ``Phi`` and ``Qd``), :func:`predict` (``Phi P Phi^T + Qd``) and
:func:`joseph_update` (the Joseph form in ``O(n^2 m)``); :func:`gravity_gradient` for the
error model's ``F``. Products skip the zeros of their left factor (most of an error-state
``F``), and their innermost loops run along rows so that LLVM vectorises them; the tests hold
each to the same formula written with numpy.

IMU errors: :func:`imu_triad` (a triad's rates and increments in one pass), :func:`bias_block`
(Gauss-Markov and random-walk biases carried from block to block), :func:`draw_normals` and
:func:`skip_normals` (numpy's standard-normal stream of a run's generator, drawn inside numba).

The compiled code is cached in ``<navsim cache>/numba`` (:func:`navsim.config.cache_dir`), or
in ``$NUMBA_CACHE_DIR`` when that is set.
"""

from __future__ import annotations

import math
import os

import numba
import numpy as np
from numba import njit

from navsim import earth
from navsim.config import cache_dir

if "NUMBA_CACHE_DIR" not in os.environ:      # compiled kernels in navsim's cache, not the package
    numba.config.CACHE_DIR = str(cache_dir() / "numba")

A_M, E2, OMEGA, GM, J2 = earth.A_M, earth.E2, earth.OMEGA_IE_RPS, earth.GM_M3PS2, earth.J2
#: a run's cache row: gravity (3), omega_in (3), 2 omega_ie + omega_en (3), r_m, r_n
CACHE_SIZE = 11


@njit(cache=True)
def _radii(lat):
    s = math.sin(lat)
    w = math.sqrt(1.0 - E2 * s * s)
    return A_M * (1.0 - E2) / (w * w * w), A_M / w


@njit(cache=True)
def _gravity_n(lat, h, out):
    """Gravity in NED at latitude ``lat`` (rad), height ``h`` (m), into ``out`` (3,):
    :func:`navsim.earth.gravity_n` for one point."""
    _, r_n = _radii(lat)
    sl, cl = math.sin(lat), math.cos(lat)
    x = (r_n + h) * cl
    z = (r_n * (1.0 - E2) + h) * sl
    rn2 = x * x + z * z
    rn = math.sqrt(rn2)
    k = 1.5 * J2 * (A_M * A_M / rn2)
    zr2 = z * z / rn2
    c = -GM / (rn2 * rn)
    gx = c * x * (1.0 + k * (1.0 - 5.0 * zr2)) + OMEGA * OMEGA * x
    gz = c * z * (1.0 + k * (3.0 - 5.0 * zr2))
    # NED from ECEF at longitude 0: north = (-sl, 0, cl), east = (0, 1, 0), down = (-cl, 0, -sl)
    out[0] = -sl * gx + cl * gz
    out[1] = 0.0
    out[2] = -cl * gx - sl * gz


@njit(cache=True)
def gravity_gradient(lat, h, dlat, dh, out):
    """Derivatives of gravity in NED (:func:`_gravity_n`) by central differences of ``dlat``
    (rad) and ``dh`` (m), at each run's latitude ``lat`` and height ``h`` ``(B,)``: ``out``
    ``(B, 3, 2)``, per radian of latitude and per metre of height."""
    gp, gm = np.empty(3), np.empty(3)
    for b in range(lat.shape[0]):
        _gravity_n(lat[b] + dlat, h[b], gp)
        _gravity_n(lat[b] - dlat, h[b], gm)
        for i in range(3):
            out[b, i, 0] = (gp[i] - gm[i]) / (2.0 * dlat)
        _gravity_n(lat[b], h[b] + dh, gp)
        _gravity_n(lat[b], h[b] - dh, gm)
        for i in range(3):
            out[b, i, 1] = (gp[i] - gm[i]) / (2.0 * dh)


@njit(cache=True)
def _refresh(lat, h, vel, cache):
    """Gravity, rates and radii of one run into its cache row."""
    _gravity_n(lat, h, cache[0:3])
    r_m, r_n = _radii(lat)
    cl, sl = math.cos(lat), math.sin(lat)
    w_ie0, w_ie2 = OMEGA * cl, -OMEGA * sl
    w_en0, w_en1, w_en2 = vel[1] / (r_n + h), -vel[0] / (r_m + h), -vel[1] * math.tan(lat) / (r_n + h)
    cache[3], cache[4], cache[5] = w_ie0 + w_en0, w_en1, w_ie2 + w_en2
    cache[6], cache[7], cache[8] = 2.0 * w_ie0 + w_en0, w_en1, 2.0 * w_ie2 + w_en2
    cache[9], cache[10] = r_m, r_n


@njit(cache=True)
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True)
def _rotation(x, y, z, R):
    """``exp([v x])`` of the rotation vector ``(x, y, z)`` into ``R`` (3, 3), as
    :func:`navsim.strapdown.rotation`."""
    a2 = x * x + y * y + z * z
    if a2 < 2.5e-3:
        s = 1.0 - a2 * (1.0 / 6.0) + a2 * a2 * (1.0 / 120.0) - a2 ** 3 * (1.0 / 5040.0)
        c = 0.5 - a2 * (1.0 / 24.0) + a2 * a2 * (1.0 / 720.0) - a2 ** 3 * (1.0 / 40320.0)
    else:
        a = math.sqrt(a2)
        s, c = math.sin(a) / a, (1.0 - math.cos(a)) / a2
    cx, cy = c * x, c * y
    R[0, 0] = 1.0 - c * (y * y + z * z)
    R[1, 1] = 1.0 - c * (x * x + z * z)
    R[2, 2] = 1.0 - c * (x * x + y * y)
    R[0, 1], R[1, 0] = cx * y - s * z, cx * y + s * z
    R[0, 2], R[2, 0] = cx * z + s * y, cx * z - s * y
    R[1, 2], R[2, 1] = cy * z - s * x, cy * z + s * x


@njit(cache=True)
def _attitude(C, w_in, dt, R, T):
    """``C <- (I - [w_in dt x]) C R`` in place (``T`` scratch)."""
    for i in range(3):
        for j in range(3):
            T[i, j] = C[i, 0] * R[0, j] + C[i, 1] * R[1, j] + C[i, 2] * R[2, j]
    a0, a1, a2 = w_in[0] * dt, w_in[1] * dt, w_in[2] * dt
    for j in range(3):        # (I - [a x]) T: row i minus (a x column j)_i
        t0, t1, t2 = T[0, j], T[1, j], T[2, j]
        C[0, j] = t0 - (a1 * t2 - a2 * t1)
        C[1, j] = t1 - (a2 * t0 - a0 * t2)
        C[2, j] = t2 - (a0 * t1 - a1 * t0)


@njit(cache=True)
def _orthonormalise(C, T):
    """``C <- 1.5 C - 0.5 C C^T C``."""
    for i in range(3):
        for j in range(3):
            T[i, j] = C[i, 0] * C[j, 0] + C[i, 1] * C[j, 1] + C[i, 2] * C[j, 2]
    D = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            D[i, j] = 1.5 * C[i, j] - 0.5 * (T[i, 0] * C[0, j] + T[i, 1] * C[1, j] + T[i, 2] * C[2, j])
    C[:, :] = D


@njit(cache=True)
def strapdown_block(lat, lon, h, vel, C, dth_prev, dv_prev, cache, dth, dv, bias_g, bias_a, dt, k0,
                    gravity_every, sum_C, sum_dv_n):
    """Integrate ``K`` IMU intervals of ``B`` runs in place, the increments less the biases
    times ``dt``.

    Parameters
    ----------
    lat, lon, h : (B,) arrays
        Geodetic latitude, longitude (rad) and height (m); updated.
    vel : (B, 3) array
        NED velocity, m/s; updated.
    C : (B, 3, 3) array
        ``C_nb``; updated.
    dth_prev, dv_prev : (B, 3) arrays
        The previous interval's increments (equal to the first ones at the start); updated.
    cache : (B, :data:`CACHE_SIZE`) array
        Gravity, rates and radii of the last refresh; updated.
    dth, dv : (B, K, 3) arrays
        The block's angle (rad) and velocity (m/s) increments (any strides).
    bias_g, bias_a : (B, 3) arrays
        The gyro (rad/s) and accelerometer (m/s^2) biases to take off.
    dt : float
        The IMU interval, s.
    k0 : int
        Steps taken before this block (gravity refresh and re-orthonormalisation cadence).
    gravity_every : int
        Steps between two evaluations of gravity, rates and radii.
    sum_C : (B, 3, 3) array
        ``C_nb`` after each interval, added up (for a filter's averaged attitude); updated.
    sum_dv_n : (B, 3) array
        Each interval's specific-force velocity increment in NED, ``dv_n``, added up; updated.
    """
    B, K = dth.shape[0], dth.shape[1]
    R = np.empty((3, 3))
    T = np.empty((3, 3))
    for b in range(B):
        Cb, cb = C[b], cache[b]
        w_in = np.empty(3)
        bg0, bg1, bg2 = bias_g[b, 0] * dt, bias_g[b, 1] * dt, bias_g[b, 2] * dt
        ba0, ba1, ba2 = bias_a[b, 0] * dt, bias_a[b, 1] * dt, bias_a[b, 2] * dt
        for j in range(K):
            k = k0 + j
            if k % gravity_every == 0:
                _refresh(lat[b], h[b], vel[b], cb)
            g0, g1, g2 = cb[0], cb[1], cb[2]
            w_in[0], w_in[1], w_in[2] = cb[3], cb[4], cb[5]
            r0, r1, r2 = cb[6], cb[7], cb[8]
            r_m, r_n = cb[9], cb[10]
            t0, t1, t2 = dth[b, j, 0] - bg0, dth[b, j, 1] - bg1, dth[b, j, 2] - bg2
            v0, v1, v2 = dv[b, j, 0] - ba0, dv[b, j, 1] - ba1, dv[b, j, 2] - ba2
            p0, p1, p2 = dth_prev[b, 0], dth_prev[b, 1], dth_prev[b, 2]
            q0, q1, q2 = dv_prev[b, 0], dv_prev[b, 1], dv_prev[b, 2]
            e0, e1, e2 = _cross(0.5 * t0 + p0 * (1.0 / 12.0), 0.5 * t1 + p1 * (1.0 / 12.0),
                                0.5 * t2 + p2 * (1.0 / 12.0), v0, v1, v2)
            f0, f1, f2 = _cross(q0, q1, q2, t0, t1, t2)
            c0 = v0 + e0 + f0 * (1.0 / 12.0)
            c1 = v1 + e1 + f1 * (1.0 / 12.0)
            c2 = v2 + e2 + f2 * (1.0 / 12.0)
            h0, h1, h2 = _cross(p0, p1, p2, t0, t1, t2)
            a0, a1, a2 = t0 + h0 * (1.0 / 12.0), t1 + h1 * (1.0 / 12.0), t2 + h2 * (1.0 / 12.0)
            n0 = Cb[0, 0] * c0 + Cb[0, 1] * c1 + Cb[0, 2] * c2
            n1 = Cb[1, 0] * c0 + Cb[1, 1] * c1 + Cb[1, 2] * c2
            n2 = Cb[2, 0] * c0 + Cb[2, 1] * c1 + Cb[2, 2] * c2
            x0, x1, x2 = _cross(w_in[0], w_in[1], w_in[2], n0, n1, n2)
            n0, n1, n2 = n0 - 0.5 * dt * x0, n1 - 0.5 * dt * x1, n2 - 0.5 * dt * x2
            sum_dv_n[b, 0] += n0
            sum_dv_n[b, 1] += n1
            sum_dv_n[b, 2] += n2
            o0, o1, o2 = vel[b, 0], vel[b, 1], vel[b, 2]
            y0, y1, y2 = _cross(r0, r1, r2, o0, o1, o2)
            w0, w1, w2 = o0 + n0 + (g0 - y0) * dt, o1 + n1 + (g1 - y1) * dt, o2 + n2 + (g2 - y2) * dt
            _rotation(a0, a1, a2, R)
            _attitude(Cb, w_in, dt, R, T)
            m0, m1, m2 = 0.5 * (o0 + w0), 0.5 * (o1 + w1), 0.5 * (o2 + w2)
            h_new = h[b] - m2 * dt
            h_mid = 0.5 * (h[b] + h_new)
            lat_new = lat[b] + m0 * dt / (r_m + h_mid)
            lon[b] = lon[b] + m1 * dt / ((r_n + h_mid) * math.cos(0.5 * (lat[b] + lat_new)))
            lat[b], h[b] = lat_new, h_new
            vel[b, 0], vel[b, 1], vel[b, 2] = w0, w1, w2
            if (k + 1) % 1000 == 0:
                _orthonormalise(Cb, T)
            for r in range(3):
                for c in range(3):
                    sum_C[b, r, c] += Cb[r, c]
            dth_prev[b, 0], dth_prev[b, 1], dth_prev[b, 2] = t0, t1, t2
            dv_prev[b, 0], dv_prev[b, 1], dv_prev[b, 2] = v0, v1, v2


# --- Kalman filter epochs (see the module docstring) ---------------------------------------


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
        nz = 0
        for i in range(n):
            for k in range(n):
                if Fb[i, k] != 0.0:
                    rows[nz], cols[nz], vals[nz] = i, k, Fb[i, k]
                    nz += 1
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
def _symmetrize(A):
    """``A <- (A + A^T) / 2`` of a square matrix, in place."""
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (A[i, j] + A[j, i])
            A[i, j] = v
            A[j, i] = v


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
        x[b, :] = xn
        _matmul(Fb, Pb, A)
        _matmul(A, Ft, C)
        for i in range(n):
            for j in range(i, n):
                v = 0.5 * ((C[i, j] + Qd[b, i, j]) + (C[j, i] + Qd[b, j, i]))
                Pb[i, j] = v
                Pb[j, i] = v


@njit(cache=True)
def _solve(S, Y, A, X):
    """``X = S^-1 Y`` by Gaussian elimination with partial pivoting (``S`` ``(m, m)``, ``Y``
    ``(m, r)``; ``A`` ``(m, m)`` scratch, ``X`` ``(m, r)`` out); False when ``S`` is singular."""
    m, r = S.shape[0], Y.shape[1]
    A[:, :] = S
    X[:, :] = Y
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
def joseph_update(x, P, z, H, R, valid, y, S, nis):
    """Joseph-form update of the runs where ``valid``, in place: ``y = z - H x``,
    ``S = H P H^T + R`` (symmetrised), ``K = P H^T S^-1``, ``x <- x + K y``,
    ``P <- (I - K H) P (I - K H)^T + K R K^T`` (symmetrised), evaluated as
    ``A = P - K (H P)``, ``A - (A H^T) K^T + K R K^T`` (``O(n^2 m)``), and
    ``nis = y^T S^-1 y``. A valid run whose ``S`` is singular gets NaN state and covariance;
    an invalid one keeps them, with NaN NIS.

    Parameters
    ----------
    x : (B, n), P : (B, n, n)
        State and covariance (symmetric); updated.
    z : (B, m), H : (B, m, n), R : (B, m, m), valid : (B,) bool
        The measurement.
    y : (B, m), S : (B, m, m), nis : (B,)
        Out: innovation, its covariance and the NIS.
    """
    B, n, m = P.shape[0], P.shape[1], H.shape[1]
    HP = np.empty((m, n))          # H P = (P H^T)^T
    Kt = np.empty((m, n))          # K^T = S^-1 H P
    D = np.empty((n, m))           # K R - A H^T
    Ab = np.empty((n, n))
    W = np.empty((m, m))
    yy = np.empty((m, 1))
    sy = np.empty((m, 1))
    for b in range(B):
        Pb, Hb, Rb, Sb = P[b], H[b], R[b], S[b]
        for i in range(m):
            s = z[b, i]
            for k in range(n):
                s -= Hb[i, k] * x[b, k]
            y[b, i] = s
            yy[i, 0] = s
        _matmul(Hb, Pb, HP)
        for i in range(m):
            for j in range(m):
                s = 0.0
                for k in range(n):
                    s += HP[i, k] * Hb[j, k]
                Sb[i, j] = s + Rb[i, j]
        _symmetrize(Sb)
        if not valid[b]:
            nis[b] = np.nan
            continue
        if not (_solve(Sb, HP, W, Kt) and _solve(Sb, yy, W, sy)):
            x[b, :] = np.nan
            Pb[:, :] = np.nan
            nis[b] = np.nan
            continue
        s = 0.0
        for i in range(m):
            s += yy[i, 0] * sy[i, 0]
        nis[b] = s
        for k in range(m):
            for i in range(n):
                x[b, i] += Kt[k, i] * yy[k, 0]
        for i in range(n):             # A = P - K H P
            for j in range(n):
                Ab[i, j] = Pb[i, j]
            for k in range(m):
                c = Kt[k, i]
                for j in range(n):
                    Ab[i, j] -= c * HP[k, j]
        for i in range(n):             # D = K R - A H^T
            for j in range(m):
                s = 0.0
                for k in range(m):
                    s += Kt[k, i] * Rb[k, j]
                for k in range(n):
                    s -= Ab[i, k] * Hb[j, k]
                D[i, j] = s
        for i in range(n):             # P = A + D K^T
            for j in range(n):
                Pb[i, j] = Ab[i, j]
            for k in range(m):
                c = D[i, k]
                for j in range(n):
                    Pb[i, j] += c * Kt[k, j]
        _symmetrize(Pb)


# --- IMU errors ------------------------------------------------------------------------------


@njit(cache=True)
def imu_triad(w, noise_scale, M, identity, truth_x, incr_x, bias, dt, rate, incr):
    """A triad over ``K`` samples of ``B`` runs in one pass (:mod:`navsim.sensors.imu`):
    ``rate = w noise_scale + M x + b``, ``incr = rate dt + M (incr_x - x dt)``.

    Parameters
    ----------
    w : (B, K, 3) or (B, 0, 3) array
        Standard normals of the white noise (none: no white noise).
    noise_scale : (3,) array
        White-noise standard deviation per axis (density / sqrt(dt)).
    M : (B, 3, 3) array
        ``I + M`` (scale factors and misalignments); ``identity``: they are the identity.
    truth_x, incr_x : (K, 3) arrays
        The true rates and increments.
    bias : (B, nb, 3) array
        The bias, constant (``nb = 1``) or per sample (``nb = K``).
    dt : float
        The interval, s.
    rate : (B, K, 3) or (B, 0, 3) array
        Out: the rates (not written when it has no rows).
    incr : (B, K, 3) array
        Out: the increments.
    """
    B, K = incr.shape[0], incr.shape[1]
    per_sample = bias.shape[1] > 1
    keep = rate.shape[1] > 0
    noisy = w.shape[1] > 0
    y = np.empty(3)
    c = np.empty(3)
    for b in range(B):
        Mb = M[b]
        for j in range(K):
            jb = j if per_sample else 0
            for i in range(3):
                if identity:
                    y[i] = truth_x[j, i]
                    c[i] = incr_x[j, i] - truth_x[j, i] * dt
                else:
                    y[i] = Mb[i, 0] * truth_x[j, 0] + Mb[i, 1] * truth_x[j, 1] + Mb[i, 2] * truth_x[j, 2]
                    c[i] = (Mb[i, 0] * (incr_x[j, 0] - truth_x[j, 0] * dt)
                            + Mb[i, 1] * (incr_x[j, 1] - truth_x[j, 1] * dt)
                            + Mb[i, 2] * (incr_x[j, 2] - truth_x[j, 2] * dt))
                r = ((w[b, j, i] * noise_scale[i] if noisy else 0.0) + y[i]) + bias[b, jb, i]
                if keep:
                    rate[b, j, i] = r
                incr[b, j, i] = r * dt + c[i]


@njit(cache=True)
def draw_normals(g, out):
    """Fill ``out`` (any shape, C order) with standard normals from ``g`` (numpy's stream)."""
    flat = out.reshape(-1)
    for k in range(flat.size):
        flat[k] = g.standard_normal()


@njit(cache=True)
def skip_normals(g, count):
    """Draw ``count`` standard normals from ``g`` and drop them."""
    for _ in range(count):
        g.standard_normal()


@njit(cache=True)
def bias_block(w, j0, first_scale, step_scale, a, kind, state, out):
    """Add one bias process over a block to ``out`` ``(B, K, 3)`` in place, from its standard
    normals ``w`` ``(B, >= j0 + K, 3)`` starting at row ``j0``. ``kind`` 0: first-order
    Gauss-Markov, ``x_0 = first_scale w_0``, ``x_k = a x_k-1 + step_scale w_k``; 1: random
    walk, ``x_0 = 0``, ``x_k = x_k-1 + step_scale w_k``. ``state`` ``(B, 4)``: the last value
    of each axis and whether a sample was drawn (column 3); updated."""
    B, K = out.shape[0], out.shape[1]
    for b in range(B):
        for j in range(K):
            started = state[b, 3] != 0.0
            for i in range(3):
                x = w[b, j0 + j, i]
                if not started:
                    v = first_scale[i] * x if kind == 0 else 0.0
                elif kind == 0:
                    v = a * state[b, i] + step_scale[i] * x
                else:
                    v = state[b, i] + step_scale[i] * x
                state[b, i] = v
                out[b, j, i] += v
            state[b, 3] = 1.0
