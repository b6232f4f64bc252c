"""Compiled kernels (numba ``njit(cache=True)``): per-sample work over a block of IMU samples.

Python is entered once per block of ``K`` samples, not once per IMU sample, and a run's
arithmetic never depends on the other runs (a batch of 3 equals 3 single runs bit for bit):
the Kalman kernels loop over the runs and, inside, over the samples; the strapdown
integrates tiles of 64 runs side by side in vector lanes, which round as scalar code does.

Strapdown mechanization (:func:`strapdown_block`, behind :class:`navsim.navigation.strapdown.BlockStrapdown`)
in the local-level NED frame, per IMU interval with the
increments ``dtheta``, ``dv`` and the previous interval's ``dtheta_p``, ``dv_p``:

* coning: ``dtheta_c = dtheta + dtheta_p x dtheta / 12``;
* rotation and sculling: ``dv_c = dv + (dtheta / 2 + dtheta_p / 12) x dv + (dv_p x dtheta) / 12``;
* ``dv_n = C_nb dv_c - (omega_in dt / 2) x (C_nb dv_c)``;
  ``v <- v + dv_n + (g - (2 omega_ie + omega_en) x v) dt``;
* ``C_nb <- (I - [omega_in dt x]) C_nb exp([dtheta_c x])`` (Rodrigues, Taylor series of its
  coefficients below 0.05 rad), re-orthonormalised every 1000 steps;
* position: trapezoid on the old and new velocities with the WGS-84 radii (the cosine of the
  mid latitude by its Taylor series about the last refresh's latitude, exact to rounding).

Gravity (WGS-84 with J2, as :func:`navsim.foundations.earth.gravity_n`), Earth rate, transport rate and the
radii are evaluated every ``gravity_every`` steps and kept in the run's ``cache`` row between
blocks.

Kalman filter epochs, per run over the ``n`` states: :func:`discretize_series` (the
matrix-exponential series of ``Phi`` and ``Qd``), :func:`predict` (``Phi P Phi^T + Qd``) and
:func:`joseph_update` (the Joseph form in ``O(n^2 m)``); :func:`gravity_gradient` for the
error model's ``F``. Products skip the zeros of their left factor (most of an error-state
``F``), and their innermost loops run along rows so that LLVM vectorises them; the tests hold
each to the same formula written with numpy.

The IMU's error processes are in :mod:`navsim.sensors.kernels`. The compiled code is cached in
``<navsim cache>/numba`` (:mod:`navsim.foundations.compiled`), or in ``$NUMBA_CACHE_DIR``.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.foundations import earth
from navsim.foundations.compiled import njit

A_M, E2, OMEGA, GM, J2 = earth.A_M, earth.E2, earth.OMEGA_IE_RPS, earth.GM_M3PS2, earth.J2


@njit(cache=True)
def radii(lat):
    """Meridian and transverse radii ``R_M``, ``R_N`` at ``lat`` (:func:`navsim.foundations.earth.radii`), m."""
    s = math.sin(lat)
    w = math.sqrt(1.0 - E2 * s * s)
    return A_M * (1.0 - E2) / (w * w * w), A_M / w


@njit(cache=True)
def _gravity_n(lat, h, out):
    """Gravity in NED at latitude ``lat`` (rad), height ``h`` (m), into ``out`` (3,):
    :func:`navsim.foundations.earth.gravity_n` for one point."""
    _, r_n = radii(lat)
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


# The strapdown works on tiles of _TILE runs, each field of the state a row of _TILE lanes
# in one flat array, ``X[row * _TILE + b]`` (the names below are the rows' offsets). The rows
# are fixed at compile time, so each interval is a few loops over the lanes that LLVM
# vectorises without run-time overlap checks (no calls, no branches, divisions without
# Python's zero check). Vector lanes round as
# scalar code does (no fused multiply-add without fastmath), so a run's numbers do not depend
# on its place in the batch; the last tile's spare lanes repeat its first run. The rare cases
# (an angle above 0.05 rad, a non-finite value, a latitude far from the last refresh), the
# refresh and the re-orthonormalisation run in scalar loops of their own.
_TILE = 64


def _rows(first: int, count: int = 1):
    """The offsets of ``count`` rows of a tile from row ``first``."""
    return tuple((first + i) * _TILE for i in range(count)) if count > 1 else first * _TILE


_LAT, _LON, _H = _rows(0, 3)                                       # the state
_V0, _V1, _V2 = _rows(3, 3)
_C00, _C01, _C02, _C10, _C11, _C12, _C20, _C21, _C22 = _rows(6, 9)
_SC, _SV0, _SV1, _SV2 = _rows(15), *_rows(24, 3)                   # sums of C_nb (9 rows), dv_n
_PT0, _PT1, _PT2 = _rows(27, 3)                                    # the previous increments
_PV0, _PV1, _PV2 = _rows(30, 3)
_TH0, _TH1, _TH2 = _rows(33, 3)                                    # this interval's
_DV0, _DV1, _DV2 = _rows(36, 3)
_ROT0, _ROT1, _ROT2, _S, _CC, _A2 = _rows(39, 6)                   # rotation vector, s, c, |a|^2
_MID, _COSM, _DEN, _NUM = _rows(45, 4)                             # the longitude step
#: a run's cache: gravity (3), omega_in (3), 2 omega_ie + omega_en (3), r_m, r_n, and the
#: refresh's latitude with its sine and cosine
CACHE_SIZE = 14
_CACHE_ROW = 49                 # the first row of the cache, after the 49 above
(_GN, _GE, _GD, _WIN0, _WIN1, _WIN2, _COR0, _COR1, _COR2, _RM, _RN, _LAT0, _SLAT0,
 _CLAT0) = _rows(_CACHE_ROW, CACHE_SIZE)
_NX = _CACHE_ROW + CACHE_SIZE
#: below this offset (rad) from the refresh's latitude, the cosine of the mid latitude is its
#: Taylor series to the third order (the next term, d^4 / 24 < 5e-18, is below rounding)
_COS_TAYLOR_RAD = 1e-4
_VECTOR = dict(cache=True, error_model="numpy")


@njit(cache=True)
def _refresh(X, b, g):
    """Gravity, rates and radii of run ``b`` into its cache rows of ``X`` (``g`` (3,) scratch)."""
    lat, h, v0, v1 = X[_LAT + b], X[_H + b], X[_V0 + b], X[_V1 + b]
    _gravity_n(lat, h, g)
    r_m, r_n = radii(lat)
    cl, sl = math.cos(lat), math.sin(lat)
    w_ie0, w_ie2 = OMEGA * cl, -OMEGA * sl
    w_en0, w_en1, w_en2 = v1 / (r_n + h), -v0 / (r_m + h), -v1 * math.tan(lat) / (r_n + h)
    row = (g[0], g[1], g[2], w_ie0 + w_en0, w_en1, w_ie2 + w_en2, 2.0 * w_ie0 + w_en0, w_en1,
           2.0 * w_ie2 + w_en2, r_m, r_n, lat, sl, cl)
    for i in range(CACHE_SIZE):
        X[_GN + i * _TILE + b] = row[i]


@njit(**_VECTOR)
def _velocity_position(X, dt):
    """One interval of every run: coning and sculling, velocity, height and latitude, the
    rotation vector with its Taylor coefficients, and the parts of the longitude step."""
    for b in range(_TILE):
        t0, t1, t2 = X[_TH0 + b], X[_TH1 + b], X[_TH2 + b]
        v0, v1, v2 = X[_DV0 + b], X[_DV1 + b], X[_DV2 + b]
        p0, p1, p2 = X[_PT0 + b], X[_PT1 + b], X[_PT2 + b]
        q0, q1, q2 = X[_PV0 + b], X[_PV1 + b], X[_PV2 + b]
        u0, u1, u2 = 0.5 * t0 + p0 * (1.0 / 12.0), 0.5 * t1 + p1 * (1.0 / 12.0), 0.5 * t2 + p2 * (1.0 / 12.0)
        c0 = v0 + (u1 * v2 - u2 * v1) + (q1 * t2 - q2 * t1) * (1.0 / 12.0)
        c1 = v1 + (u2 * v0 - u0 * v2) + (q2 * t0 - q0 * t2) * (1.0 / 12.0)
        c2 = v2 + (u0 * v1 - u1 * v0) + (q0 * t1 - q1 * t0) * (1.0 / 12.0)
        a0 = t0 + (p1 * t2 - p2 * t1) * (1.0 / 12.0)
        a1 = t1 + (p2 * t0 - p0 * t2) * (1.0 / 12.0)
        a2 = t2 + (p0 * t1 - p1 * t0) * (1.0 / 12.0)
        n0 = X[_C00 + b] * c0 + X[_C01 + b] * c1 + X[_C02 + b] * c2
        n1 = X[_C10 + b] * c0 + X[_C11 + b] * c1 + X[_C12 + b] * c2
        n2 = X[_C20 + b] * c0 + X[_C21 + b] * c1 + X[_C22 + b] * c2
        i0, i1, i2 = X[_WIN0 + b], X[_WIN1 + b], X[_WIN2 + b]
        m0 = n0 - 0.5 * dt * (i1 * n2 - i2 * n1)
        m1 = n1 - 0.5 * dt * (i2 * n0 - i0 * n2)
        m2 = n2 - 0.5 * dt * (i0 * n1 - i1 * n0)
        X[_SV0 + b] += m0
        X[_SV1 + b] += m1
        X[_SV2 + b] += m2
        r0, r1, r2 = X[_COR0 + b], X[_COR1 + b], X[_COR2 + b]
        o0, o1, o2 = X[_V0 + b], X[_V1 + b], X[_V2 + b]
        w0 = o0 + m0 + (X[_GN + b] - (r1 * o2 - r2 * o1)) * dt
        w1 = o1 + m1 + (X[_GE + b] - (r2 * o0 - r0 * o2)) * dt
        w2 = o2 + m2 + (X[_GD + b] - (r0 * o1 - r1 * o0)) * dt
        x2 = a0 * a0 + a1 * a1 + a2 * a2
        X[_ROT0 + b], X[_ROT1 + b], X[_ROT2 + b], X[_A2 + b] = a0, a1, a2, x2
        X[_S + b] = 1.0 - x2 * (1.0 / 6.0) + x2 * x2 * (1.0 / 120.0) - x2 * x2 * x2 * (1.0 / 5040.0)
        X[_CC + b] = 0.5 - x2 * (1.0 / 24.0) + x2 * x2 * (1.0 / 720.0) - x2 * x2 * x2 * (1.0 / 40320.0)
        h, lat = X[_H + b], X[_LAT + b]
        h_new = h - 0.5 * (o2 + w2) * dt
        h_mid = 0.5 * (h + h_new)
        lat_new = lat + 0.5 * (o0 + w0) * dt / (X[_RM + b] + h_mid)
        mid = 0.5 * (lat + lat_new)
        d = mid - X[_LAT0 + b]
        sl0, cl0 = X[_SLAT0 + b], X[_CLAT0 + b]
        X[_MID + b] = mid
        X[_COSM + b] = cl0 - sl0 * d - cl0 * (d * d) * 0.5 + sl0 * (d * d * d) * (1.0 / 6.0)
        X[_NUM + b] = 0.5 * (o1 + w1) * dt
        X[_DEN + b] = X[_RN + b] + h_mid
        X[_LAT + b], X[_H + b] = lat_new, h_new
        X[_V0 + b], X[_V1 + b], X[_V2 + b] = w0, w1, w2
        X[_PT0 + b], X[_PT1 + b], X[_PT2 + b] = t0, t1, t2
        X[_PV0 + b], X[_PV1 + b], X[_PV2 + b] = v0, v1, v2


@njit(cache=True)
def _exact_cases(X):
    """The rotation coefficients of angles above 0.05 rad (or not finite) and the cosines of
    mid latitudes far from the refresh's (or not finite), by :mod:`math`."""
    for b in range(_TILE):
        x2 = X[_A2 + b]
        if not x2 < 2.5e-3:
            a = math.sqrt(x2)
            X[_S + b], X[_CC + b] = math.sin(a) / a, (1.0 - math.cos(a)) / x2
        if not abs(X[_MID + b] - X[_LAT0 + b]) < _COS_TAYLOR_RAD:
            X[_COSM + b] = math.cos(X[_MID + b])


@njit(**_VECTOR)
def _attitude_longitude(X, dt):
    """``C_nb <- (I - [omega_in dt x]) C_nb exp([a x])`` (Rodrigues) and the longitude of
    every run."""
    for b in range(_TILE):
        x, y, z, s, c = X[_ROT0 + b], X[_ROT1 + b], X[_ROT2 + b], X[_S + b], X[_CC + b]
        cx, cy = c * x, c * y
        R00, R11, R22 = 1.0 - c * (y * y + z * z), 1.0 - c * (x * x + z * z), 1.0 - c * (x * x + y * y)
        R01, R10 = cx * y - s * z, cx * y + s * z
        R02, R20 = cx * z + s * y, cx * z - s * y
        R12, R21 = cy * z - s * x, cy * z + s * x
        C00, C01, C02 = X[_C00 + b], X[_C01 + b], X[_C02 + b]
        C10, C11, C12 = X[_C10 + b], X[_C11 + b], X[_C12 + b]
        C20, C21, C22 = X[_C20 + b], X[_C21 + b], X[_C22 + b]
        T00 = C00 * R00 + C01 * R10 + C02 * R20
        T01 = C00 * R01 + C01 * R11 + C02 * R21
        T02 = C00 * R02 + C01 * R12 + C02 * R22
        T10 = C10 * R00 + C11 * R10 + C12 * R20
        T11 = C10 * R01 + C11 * R11 + C12 * R21
        T12 = C10 * R02 + C11 * R12 + C12 * R22
        T20 = C20 * R00 + C21 * R10 + C22 * R20
        T21 = C20 * R01 + C21 * R11 + C22 * R21
        T22 = C20 * R02 + C21 * R12 + C22 * R22
        e0, e1, e2 = X[_WIN0 + b] * dt, X[_WIN1 + b] * dt, X[_WIN2 + b] * dt
        X[_C00 + b], X[_C10 + b], X[_C20 + b] = (T00 - (e1 * T20 - e2 * T10), T10 - (e2 * T00 - e0 * T20),
                                                 T20 - (e0 * T10 - e1 * T00))
        X[_C01 + b], X[_C11 + b], X[_C21 + b] = (T01 - (e1 * T21 - e2 * T11), T11 - (e2 * T01 - e0 * T21),
                                                 T21 - (e0 * T11 - e1 * T01))
        X[_C02 + b], X[_C12 + b], X[_C22 + b] = (T02 - (e1 * T22 - e2 * T12), T12 - (e2 * T02 - e0 * T22),
                                                 T22 - (e0 * T12 - e1 * T02))
        X[_LON + b] = X[_LON + b] + X[_NUM + b] / (X[_DEN + b] * X[_COSM + b])


@njit(cache=True)
def _orthonormalise(X, b):
    """``C <- 1.5 C - 0.5 C C^T C`` of run ``b``."""
    C = np.empty((3, 3))
    T = np.empty((3, 3))
    for i in range(9):
        C[i // 3, i % 3] = X[_C00 + i * _TILE + b]
    for i in range(3):
        for j in range(3):
            T[i, j] = C[i, 0] * C[j, 0] + C[i, 1] * C[j, 1] + C[i, 2] * C[j, 2]
    for i in range(3):
        for j in range(3):
            TC = T[i, 0] * C[0, j] + T[i, 1] * C[1, j] + T[i, 2] * C[2, j]
            X[_C00 + (3 * i + j) * _TILE + b] = 1.5 * C[i, j] - 0.5 * TC


@njit(**_VECTOR)
def _increments(X, dth, dv, bias_g, bias_a, j, dt, b0, nb):
    """Interval ``j``'s increments of every run, less the biases times ``dt``."""
    for b in range(_TILE):
        c = b0 + (b if b < nb else 0)
        for i in range(3):
            X[_TH0 + i * _TILE + b] = dth[c, j, i] - bias_g[c, i] * dt
            X[_DV0 + i * _TILE + b] = dv[c, j, i] - bias_a[c, i] * dt


@njit(**_VECTOR)
def _sum_attitude(X):
    """Add every run's ``C_nb`` to its sum."""
    for b in range(_TILE):
        for i in range(9):
            X[_SC + i * _TILE + b] += X[_C00 + i * _TILE + b]


@njit(cache=True)
def _to_tile(X, b0, nb, lat, lon, h, vel, C, dth_prev, dv_prev, cache, sum_C, sum_dv_n):
    """Runs ``b0`` to ``b0 + nb`` into the lanes of tile ``X`` (the spare lanes: run ``b0``)."""
    for b in range(_TILE):
        r = b0 + (b if b < nb else 0)
        X[_LAT + b], X[_LON + b], X[_H + b] = lat[r], lon[r], h[r]
        for i in range(3):
            X[_V0 + i * _TILE + b], X[_SV0 + i * _TILE + b] = vel[r, i], sum_dv_n[r, i]
            X[_PT0 + i * _TILE + b], X[_PV0 + i * _TILE + b] = dth_prev[r, i], dv_prev[r, i]
            for j in range(3):
                X[_C00 + (3 * i + j) * _TILE + b], X[_SC + (3 * i + j) * _TILE + b] = C[r, i, j], sum_C[r, i, j]
        for i in range(CACHE_SIZE):
            X[_GN + i * _TILE + b] = cache[r, i]


@njit(cache=True)
def _from_tile(X, b0, nb, lat, lon, h, vel, C, dth_prev, dv_prev, cache, sum_C, sum_dv_n):
    """The first ``nb`` lanes of tile ``X`` back into runs ``b0`` to ``b0 + nb``."""
    for b in range(nb):
        r = b0 + b
        lat[r], lon[r], h[r] = X[_LAT + b], X[_LON + b], X[_H + b]
        for i in range(3):
            vel[r, i], sum_dv_n[r, i] = X[_V0 + i * _TILE + b], X[_SV0 + i * _TILE + b]
            dth_prev[r, i], dv_prev[r, i] = X[_PT0 + i * _TILE + b], X[_PV0 + i * _TILE + b]
            for j in range(3):
                C[r, i, j], sum_C[r, i, j] = X[_C00 + (3 * i + j) * _TILE + b], X[_SC + (3 * i + j) * _TILE + b]
        for i in range(CACHE_SIZE):
            cache[r, i] = X[_GN + i * _TILE + b]


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
    X = np.empty(_NX * _TILE)
    g = np.empty(3)
    state = (lat, lon, h, vel, C, dth_prev, dv_prev, cache, sum_C, sum_dv_n)
    for b0 in range(0, B, _TILE):
        nb = min(_TILE, B - b0)
        _to_tile(X, b0, nb, *state)
        for j in range(K):
            k = k0 + j
            if k % gravity_every == 0:
                for b in range(_TILE):
                    _refresh(X, b, g)
            _increments(X, dth, dv, bias_g, bias_a, j, dt, b0, nb)
            _velocity_position(X, dt)
            _exact_cases(X)
            _attitude_longitude(X, dt)
            if (k + 1) % 1000 == 0:
                for b in range(_TILE):
                    _orthonormalise(X, b)
            _sum_attitude(X)
        _from_tile(X, b0, nb, *state)


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
def _symmetrize(A):
    """``A <- (A + A^T) / 2`` of a square matrix, in place."""
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (A[i, j] + A[j, i])
            A[i, j] = v
            A[j, i] = v


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
        for i in range(n):
            xk[i] = x[b, i]
        for k in range(1, order + 1):
            s = T / k
            for i in range(n):
                xn[i] = 0.0
            for z in range(nz):
                xn[rows[z]] += vals[z] * xk[cols[z]]
            for i in range(n):
                xk[i] = xn[i] * s
                x[b, i] += xk[i]
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
        HP = np.empty((m, n + 1))      # H P = (P H^T)^T | y
        Kt = np.empty((m, n + 1))      # K^T = S^-1 H P | S^-1 y
        work = np.empty(n + n * m + m)
        index = np.empty(n * m + m + 1, np.int64)
        W = np.empty((m, m))
        acc = np.empty(n)
        for b in range(B):
            for i in range(m):
                zg[i] = z[b, r0 + i]
                for j in range(n):
                    Hg[i, j] = H[b, r0 + i, j]
                for j in range(m):
                    Rg[i, j] = R[b, r0 + i, r0 + j]
            nis[b, g] = _joseph_run(x[b], P[b], zg, Hg, Rg, valid[b, g], yg, Sg, HP, Kt, W, work, index)
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
def _joseph_run(x, P, z, H, R, valid, y, S, HP, Kt, W, work, index):
    """One run's Joseph update of :func:`joseph_update`; returns the NIS. Scratch: ``HP``,
    ``Kt`` ``(m, n + 1)`` (``H P`` and ``S^-1 H P``, the innovation and ``S^-1 y`` in the last
    column: one elimination for both), ``W`` ``(m, m)``, ``work`` ``(n + n m + m)`` floats,
    ``index`` ``(n m + m + 1)`` ints."""
    n, m = P.shape[0], H.shape[0]
    row, vals, D = work[:n], work[n:n + n * m], work[n + n * m:n + n * m + m]
    cols, first = index[:n * m], index[n * m:]
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
def rodrigues(x, y, z, R):
    """``R = exp([v x])`` of the rotation vector ``v = (x, y, z)``, the compiled twin of
    :func:`navsim.foundations.transform.rotation` (its series below 0.05 rad, sine and cosine
    above; NaN for a non-finite vector)."""
    a2 = x * x + y * y + z * z
    s = 1.0 - a2 * (1.0 / 6.0) + a2 * a2 * (1.0 / 120.0) - a2 ** 3 * (1.0 / 5040.0)
    c = 0.5 - a2 * (1.0 / 24.0) + a2 * a2 * (1.0 / 720.0) - a2 ** 3 * (1.0 / 40320.0)
    if not a2 < 2.5e-3:
        a = math.sqrt(a2)
        if math.isfinite(a):
            s, c = math.sin(a) / a, (1.0 - math.cos(a)) / a2
        else:
            s = c = math.nan
    cx, cy = c * x, c * y
    R[0, 0], R[1, 1], R[2, 2] = 1.0 - c * (y * y + z * z), 1.0 - c * (x * x + z * z), 1.0 - c * (x * x + y * y)
    R[0, 1], R[1, 0] = cx * y - s * z, cx * y + s * z
    R[0, 2], R[2, 0] = cx * z + s * y, cx * z - s * y
    R[1, 2], R[2, 1] = cy * z - s * x, cy * z + s * x


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


# --- records ---------------------------------------------------------------------------------


@njit(cache=True)
def nav_errors(lat, lon, h, vel, C, truth, out):
    """The errors (estimate minus truth) of each run's navigation state, into ``out``
    ``(B, 15)``: the attitude error ``phi`` (``C_nb C_true^T = I - [phi x]``, rad), the velocity
    error (m/s), the position error in the filter's units (``dL``, ``dlambda`` rad, ``dh`` m),
    the position error NED (m, on the truth's radii) and roll, pitch, yaw minus the truth's,
    wrapped to [-pi, pi).

    ``truth`` ``(1 or B, 13)``: one true state for all runs, or one each: latitude, longitude
    (rad), height (m), velocity NED (m/s), roll, pitch, yaw (rad), ``quat_nb`` (scalar first).
    """
    B = lat.shape[0]
    E = np.empty((3, 3))
    Ct = np.empty((3, 3))
    for b in range(B):
        t = 0 if truth.shape[0] == 1 else b
        w, x, y, z = truth[t, 9], truth[t, 10], truth[t, 11], truth[t, 12]
        Ct[0, 0], Ct[0, 1], Ct[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
        Ct[1, 0], Ct[1, 1], Ct[1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
        Ct[2, 0], Ct[2, 1], Ct[2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
        for i in range(3):
            for j in range(3):
                E[i, j] = C[b, i, 0] * Ct[j, 0] + C[b, i, 1] * Ct[j, 1] + C[b, i, 2] * Ct[j, 2]
        out[b, 0] = 0.5 * (E[1, 2] - E[2, 1])
        out[b, 1] = 0.5 * (E[2, 0] - E[0, 2])
        out[b, 2] = 0.5 * (E[0, 1] - E[1, 0])
        for i in range(3):
            out[b, 3 + i] = vel[b, i] - truth[t, 3 + i]
        lat_t, h_t = truth[t, 0], truth[t, 2]
        dlat, dlon, dh = lat[b] - lat_t, lon[b] - truth[t, 1], h[b] - h_t
        out[b, 6], out[b, 7], out[b, 8] = dlat, dlon, dh
        r_m, r_n = radii(lat_t)
        out[b, 9] = dlat * (r_m + h_t)
        out[b, 10] = dlon * (r_n + h_t) * math.cos(lat_t)
        out[b, 11] = -dh
        euler = (math.atan2(C[b, 2, 1], C[b, 2, 2]), math.asin(min(max(-C[b, 2, 0], -1.0), 1.0)),
                 math.atan2(C[b, 1, 0], C[b, 0, 0]))
        for i in range(3):
            out[b, 12 + i] = (euler[i] - truth[t, 6 + i] + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True)
def covariance_codes(P, symmetry_tol, psd_tol, codes):
    """Per run, why ``P`` ``(B, n, n)`` is not a covariance, into ``codes`` ``(B,)``: 0 it is
    one, 1 an entry is not finite, 2 ``P`` scaled to a unit diagonal (``P_ij / sqrt(P_ii
    P_jj)``, a variance not above zero left unscaled) is asymmetric by more than
    ``symmetry_tol`` of its largest entry (or of 1), 3 a variance is negative or the scaled
    matrix, symmetrised, plus ``psd_tol`` times the identity has no Cholesky factor."""
    B, n = P.shape[0], P.shape[1]
    s = np.empty(n)
    L = np.empty((n, n))
    for b in range(B):
        codes[b] = _covariance_code(P[b], symmetry_tol, psd_tol, s, L)


@njit(cache=True)
def _covariance_code(P, symmetry_tol, psd_tol, s, L):
    """One run's code of :func:`covariance_codes` (``s`` ``(n,)``, ``L`` ``(n, n)``: scratch)."""
    n = P.shape[0]
    for i in range(n):
        for j in range(n):
            if not math.isfinite(P[i, j]):
                return 1
    negative = False
    for i in range(n):             # s: the reciprocal scales
        d = P[i, i]
        s[i] = 1.0 / math.sqrt(d) if d > 0 else 1.0
        negative = negative or d < 0
    asym, big = 0.0, 1.0
    for i in range(n):             # the lower triangle, which the Cholesky factor reads
        for j in range(i + 1):
            w = s[i] * s[j]
            a, at = P[i, j] * w, P[j, i] * w
            asym = max(asym, abs(a - at))
            big = max(big, abs(a), abs(at))
            L[i, j] = 0.5 * (a + at) + (psd_tol if i == j else 0.0)
    if asym > symmetry_tol * big:
        return 2
    if negative or not _cholesky_in_place(L):
        return 3
    return 0


@njit(cache=True)
def _cholesky_in_place(A):
    """The lower Cholesky factor of the symmetric ``A`` into its lower triangle; False when a
    pivot is not above zero (not positive definite) or not finite."""
    n = A.shape[0]
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= A[j, k] * A[j, k]
        if not d > 0.0:
            return False
        d = math.sqrt(d)
        A[j, j] = d
        for i in range(j + 1, n):
            v = A[i, j]
            for k in range(j):
                v -= A[i, k] * A[j, k]
            A[i, j] = v / d
    return True


@njit(cache=True)
def _nees_run(P, e, A, y, x):
    """One run's NEES ``e^T P^-1 e`` by :func:`_solve`, NaN where ``P`` is singular (``A``
    ``(n, n)``, ``y``, ``x`` ``(n, 1)``: scratch)."""
    n = P.shape[0]
    for i in range(n):
        y[i, 0] = e[i]
    if not _solve(P, y, A, x):
        return np.nan
    v = 0.0
    for i in range(n):
        v += e[i] * x[i, 0]
    return v


@njit(cache=True)
def covariance_record(P, errors, truth, limits, sigma, nees, code):
    """What a record keeps of each run's navigation covariance ``P`` ``(B, 9, 9)`` (attitude
    rad, velocity m/s, position rad, rad, m) against its ``errors`` (the first 9 columns of
    :func:`nav_errors`' output): the 1-sigma ``sigma`` ``(B, 9)`` with the position NED in m (on
    the truth's radii; ``truth`` as in :func:`nav_errors`), the NEES (:func:`_nees_run`) and a
    divergence ``code``: 4 an error is not finite, else the covariance's code
    (:func:`covariance_codes`) when above 0, else 5 when the NEES is above ``limits[2]``, else
    0. ``limits``: the symmetry and positive-definiteness tolerances and the NEES bound."""
    B, n = P.shape[0], P.shape[1]
    s = np.empty(n)
    L = np.empty((n, n))
    y = np.empty((n, 1))
    x = np.empty((n, 1))
    for b in range(B):
        t = 0 if truth.shape[0] == 1 else b
        r_m, r_n = radii(truth[t, 0])
        for i in range(n):
            sigma[b, i] = math.sqrt(max(P[b, i, i], 0.0))
        sigma[b, 6] *= r_m + truth[t, 2]
        sigma[b, 7] *= (r_n + truth[t, 2]) * math.cos(truth[t, 0])
        nees[b] = _nees_run(P[b], errors[b, :n], L, y, x)
        finite = True
        for i in range(errors.shape[1]):
            finite = finite and math.isfinite(errors[b, i])
        c = _covariance_code(P[b], limits[0], limits[1], s, L)
        code[b] = 4 if not finite else c if c > 0 else 5 if nees[b] > limits[2] else 0


@njit(cache=True)
def error_dynamics(lat, h, vel, C, f, blocks, dlat, dh, F):
    """The SINS error model's continuous ``F`` of each run into ``F`` ``(B, n, n)`` (zeroed
    first), as documented in :func:`navsim.navigation.estimators.error_model.system_matrix`.

    ``blocks`` ``(7,)``: the first state of the attitude, velocity, position, gyro bias, gyro
    Markov, accelerometer bias and accelerometer Markov blocks (-1: the state has none);
    ``dlat`` (rad), ``dh`` (m): the steps of the gravity gradient's central differences."""
    B = F.shape[0]
    a, v, p = blocks[0], blocks[1], blocks[2]
    g = np.empty((1, 3, 2))
    D = np.empty((3, 3))           # d(omega_ie + omega_en)/d(L, lambda, h)
    E = np.empty((3, 3))           # d(2 omega_ie + omega_en)/d(L, lambda, h)
    M = np.zeros((3, 3))           # d(omega_en)/d(v)
    for b in range(B):
        Fb = F[b]
        Fb[:, :] = 0.0
        r_m, r_n = radii(lat[b])
        Rm, Rn = r_m + h[b], r_n + h[b]
        sl, cl, tl = math.sin(lat[b]), math.cos(lat[b]), math.tan(lat[b])
        vn, ve, vd = vel[b, 0], vel[b, 1], vel[b, 2]
        wie0, wie2 = OMEGA * cl, -OMEGA * sl
        wen0, wen1, wen2 = ve / Rn, -vn / Rm, -ve * tl / Rn
        M[0, 1], M[1, 0], M[2, 1] = 1.0 / Rn, -1.0 / Rm, -tl / Rn
        D[:, :] = 0.0
        D[0, 0], D[2, 0] = -OMEGA * sl, -OMEGA * cl
        D[2, 0] += -ve / (Rn * cl * cl)
        D[0, 2], D[1, 2], D[2, 2] = -ve / (Rn * Rn), vn / (Rm * Rm), ve * tl / (Rn * Rn)
        E[:, :] = D                    # 2 d(omega_ie) + d(omega_en)
        E[0, 0] = 2.0 * (-OMEGA * sl)
        E[2, 0] = 2.0 * (-OMEGA * cl) + -ve / (Rn * cl * cl)
        _skew_into(Fb, a, a, -(wie0 + wen0), -wen1, -(wie2 + wen2))
        _skew_into(Fb, v, a, f[b, 0], f[b, 1], f[b, 2])
        _skew_into(Fb, v, v, -(2.0 * wie0 + wen0), -wen1, -(2.0 * wie2 + wen2))
        for i in range(3):
            for j in range(3):
                Fb[a + i, v + j] = M[i, j]
                Fb[a + i, p + j] = D[i, j]
        # + [v x] M and [v x] E: row i of [v x] is (v x e_j)_i
        X = ((0.0, -vd, ve), (vd, 0.0, -vn), (-ve, vn, 0.0))
        for i in range(3):
            for j in range(3):
                Fb[v + i, v + j] += X[i][0] * M[0, j] + X[i][1] * M[1, j] + X[i][2] * M[2, j]
                Fb[v + i, p + j] = X[i][0] * E[0, j] + X[i][1] * E[1, j] + X[i][2] * E[2, j]
        gravity_gradient(lat[b:b + 1], h[b:b + 1], dlat, dh, g)
        for i in range(3):
            Fb[v + i, p] += g[0, i, 0]
            Fb[v + i, p + 2] += g[0, i, 1]
        Fb[p, v] = 1.0 / Rm
        Fb[p, p + 2] = -vn / (Rm * Rm)
        Fb[p + 1, v + 1] = 1.0 / (Rn * cl)
        Fb[p + 1, p] = ve * tl / (Rn * cl)
        Fb[p + 1, p + 2] = -ve / (Rn * Rn * cl)
        Fb[p + 2, v + 2] = -1.0
        for k in range(3, 7):          # sensor errors: -C_nb into the attitude, C_nb the velocity
            if blocks[k] >= 0:
                row, sign = (a, -1.0) if k < 5 else (v, 1.0)
                for i in range(3):
                    for j in range(3):
                        Fb[row + i, blocks[k] + j] = sign * C[b, i, j]


@njit(cache=True)
def _skew_into(F, r, c, x, y, z):
    """``F[r:r+3, c:c+3] = [(x, y, z) x]``."""
    F[r, c + 1], F[r, c + 2] = -z, y
    F[r + 1, c], F[r + 1, c + 2] = z, -x
    F[r + 2, c], F[r + 2, c + 1] = -y, x
