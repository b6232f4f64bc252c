"""The Earth compiled for one point: the WGS-84 radii (:func:`radii`), gravity in NED with J2
(:func:`_gravity_n`, as :func:`navsim.foundations.earth.gravity_n`) and its derivatives in
latitude and height (:func:`gravity_gradient`, for the error model's ``F``)."""

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
