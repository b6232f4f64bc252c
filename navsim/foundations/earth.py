"""WGS-84 Earth: ellipsoid, radii of curvature, rotation, J2 gravitation, geodetic <-> ECEF.

The constants are those JSBSim uses (``simulation/gravity-model`` 1: WGS-84 with J2), so that
integrating JSBSim's specific force reproduces its trajectory. Functions broadcast over leading
axes.
"""

from __future__ import annotations

import numpy as np

A_M = 6378137.0                      #: semi-major axis, m
F = 1.0 / 298.257223563              #: flattening
E2 = F * (2.0 - F)                   #: first eccentricity squared
B_M = A_M * (1.0 - F)                #: semi-minor axis, m
OMEGA_IE_RPS = 7.292115e-5           #: Earth rotation rate, rad/s
GM_M3PS2 = 3.986004418e14            #: gravitational constant times Earth mass, m^3/s^2
J2 = 1.08262982e-3                   #: second zonal harmonic (JSBSim's value)


def radii(lat_rad):
    """Meridian radius ``R_M`` and transverse (prime vertical) radius ``R_N``, m."""
    s2 = np.sin(lat_rad) ** 2
    w = np.sqrt(1.0 - E2 * s2)
    r_n = A_M / w
    r_m = A_M * (1.0 - E2) / w ** 3
    return r_m, r_n


def lla_to_ecef(lat_rad, lon_rad, h_m):
    """Geodetic latitude, longitude, height -> ECEF position ``(..., 3)``, m."""
    lat, lon, h = np.broadcast_arrays(np.asarray(lat_rad, float), np.asarray(lon_rad, float),
                                      np.asarray(h_m, float))
    _, r_n = radii(lat)
    cl = np.cos(lat)
    return np.stack([(r_n + h) * cl * np.cos(lon),
                     (r_n + h) * cl * np.sin(lon),
                     (r_n * (1.0 - E2) + h) * np.sin(lat)], axis=-1)


def ecef_to_lla(r_e):
    """ECEF position ``(..., 3)`` -> geodetic latitude, longitude (rad), height (m).

    Iterates Bowring's formula to well below a micrometre for heights under 1000 km.
    """
    r_e = np.asarray(r_e, float)
    x, y, z = r_e[..., 0], r_e[..., 1], r_e[..., 2]
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1.0 - E2))
    for _ in range(5):
        _, r_n = radii(lat)
        h = p / np.cos(lat) - r_n
        lat = np.arctan2(z, p * (1.0 - E2 * r_n / (r_n + h)))
    _, r_n = radii(lat)
    cl, sl = np.cos(lat), np.sin(lat)
    h = p * cl + z * sl - A_M * np.sqrt(1.0 - E2 * sl * sl)
    return lat, lon, h


def C_en(lat_rad, lon_rad):
    """Rotation matrix NED -> ECEF, ``(..., 3, 3)``."""
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    so, co = np.sin(lon_rad), np.cos(lon_rad)
    return np.stack([
        np.stack([-sl * co, -so, -cl * co], axis=-1),
        np.stack([-sl * so, co, -cl * so], axis=-1),
        np.stack([cl, np.zeros_like(sl), -sl], axis=-1),
    ], axis=-2)


def gravitation(r):
    """J2 gravitational acceleration (no centrifugal term) at position ``r`` ``(..., 3)``, m/s^2.

    Valid in any frame whose z axis is the Earth's rotation axis (ECEF or ECI).
    """
    r = np.asarray(r, float)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    rn2 = x * x + y * y + z * z
    rn = np.sqrt(rn2)
    k = 1.5 * J2 * (A_M * A_M / rn2)
    zr2 = z * z / rn2
    c = -GM_M3PS2 / (rn2 * rn)
    return np.stack([c * x * (1.0 + k * (1.0 - 5.0 * zr2)),
                     c * y * (1.0 + k * (1.0 - 5.0 * zr2)),
                     c * z * (1.0 + k * (3.0 - 5.0 * zr2))], axis=-1)


def gravity_n(lat_rad, h_m):
    """Gravity (gravitation plus centrifugal) in NED at a geodetic position, ``(..., 3)``, m/s^2."""
    lat_rad = np.asarray(lat_rad, float)
    r_e = lla_to_ecef(lat_rad, np.zeros_like(lat_rad), h_m)
    g_e = gravitation(r_e)
    g_e = g_e + OMEGA_IE_RPS ** 2 * np.stack(
        [r_e[..., 0], r_e[..., 1], np.zeros_like(r_e[..., 2])], axis=-1)
    C = C_en(lat_rad, np.zeros_like(lat_rad))
    return np.einsum("...ji,...j->...i", C, g_e)


def local_ne(lat_rad, lon_rad, lat0_rad, lon0_rad):
    """North and east offsets (m) of a position from a reference point, on the ellipsoid's
    local radii at the reference (good to centimetres over tens of kilometres)."""
    r_m, r_n = radii(lat0_rad)
    north = (lat_rad - lat0_rad) * r_m
    east = (lon_rad - lon0_rad) * r_n * np.cos(lat0_rad)
    return north, east
