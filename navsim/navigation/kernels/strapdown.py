"""The strapdown compiled: :func:`strapdown_block`, behind
:class:`navsim.navigation.strapdown.BlockStrapdown`, integrates a block of IMU intervals of every
run in the local-level NED frame, per interval with the increments ``dtheta``, ``dv`` and the
previous interval's ``dtheta_p``, ``dv_p``:

* coning: ``dtheta_c = dtheta + dtheta_p x dtheta / 12``;
* rotation and sculling: ``dv_c = dv + (dtheta / 2 + dtheta_p / 12) x dv + (dv_p x dtheta) / 12``;
* ``dv_n = C_nb dv_c - (omega_in dt / 2) x (C_nb dv_c)``;
  ``v <- v + dv_n + (g - (2 omega_ie + omega_en) x v) dt``;
* ``C_nb <- (I - [omega_in dt x]) C_nb exp([dtheta_c x])`` (Rodrigues, Taylor series of its
  coefficients below 0.05 rad), re-orthonormalised every 1000 steps;
* position: trapezoid on the old and new velocities with the WGS-84 radii (the cosine of the
  mid latitude by its Taylor series about the last refresh's latitude, exact to rounding).

Gravity (WGS-84 with J2, :mod:`navsim.navigation.kernels.earth`), Earth rate, transport rate and
the radii are evaluated every ``gravity_every`` steps and kept in the run's ``cache`` row
between blocks. The runs are integrated in tiles of 64 side by side in vector lanes, which round
as scalar code does.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.foundations.compiled import njit
from navsim.navigation.kernels.earth import OMEGA, _gravity_n, radii

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
