"""The shipped measurement models compiled (numba): each fills its rows of the stacked ``z``,
``H``, ``R`` of every run in one call, the forms :mod:`navsim.navigation.estimators.measurements`'
types give as their ``compiled`` model (:class:`~navsim.navigation.estimators.measurements.CompiledModel`).

Every kernel has one signature::

    kernel(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid)

``lat``, ``lon``, ``h`` ``(B,)``, ``vel`` ``(B, 3)``, ``C`` ``(B, 3, 3)``: the INS state; ``inp``
``(B, k)``: what the model reads of the sample, per run (its Python side gathers it); ``par``
``(p,)`` floats and ``cols`` ``(q,)`` ints: the model's constants and its columns in the error
state (``-1``: no such state); ``r0``: its first row in the stacked ``z`` ``(B, M)``, ``H``
``(B, M, n)`` and ``R`` ``(B, M, M)``, which arrive zeroed: a kernel writes its nonzero entries
only; ``valid`` ``(B,)``: the runs with a sample, which a kernel may narrow. The formulas are
those of the Python models, term for term (the same to rounding: a test holds them to 1e-12),
with numpy's error model: a division by zero gives inf or NaN as in the Python models.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.foundations.compiled import njit
from navsim.navigation.kernels import radii


@njit(cache=True, error_model="numpy")
def position_fix(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS minus a position ``inp`` ``(lat, lon, h)``, NED metres, the first ``len(par)`` rows
    (``par`` the variances, ``cols[0]`` the position block): ``gnss_position``, ``gnss_horizontal``."""
    m, p = par.shape[0], cols[0]
    for b in range(lat.shape[0]):
        r_m, r_n = radii(lat[b])
        k_n, k_e = r_m + h[b], (r_n + h[b]) * math.cos(lat[b])
        row = ((lat[b] - inp[b, 0]) * k_n, (lon[b] - inp[b, 1]) * k_e, -(h[b] - inp[b, 2]))
        gain = (k_n, k_e, -1.0)
        for i in range(m):
            z[b, r0 + i] = row[i]
            H[b, r0 + i, p + i] = gain[i]
            R[b, r0 + i, r0 + i] = par[i]


@njit(cache=True, error_model="numpy")
def landmark_fix(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS minus the camera's position fix ``inp[:, :3]`` ``(lat, lon, h)``, NED metres, with
    the std ``par[0] + par[1] * range`` to the anchor ``inp[:, 3:6]`` ``(lat, lon in degrees,
    h)``; ``cols[0]`` the position block."""
    position_fix(lat, lon, h, vel, C, inp, par[2:5], cols, r0, z, H, R, valid)
    for b in range(lat.shape[0]):
        r_m, r_n = radii(lat[b])
        dn = (math.radians(inp[b, 3]) - lat[b]) * (r_m + h[b])
        de = (math.radians(inp[b, 4]) - lon[b]) * (r_n + h[b]) * math.cos(lat[b])
        dd = h[b] - inp[b, 5]
        sigma = par[0] + par[1] * math.sqrt(dn * dn + de * de + dd * dd)
        for i in range(3):
            R[b, r0 + i, r0 + i] = sigma * sigma


@njit(cache=True, error_model="numpy")
def velocity(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS minus a NED velocity ``inp``, the first ``len(par)`` axes (``par`` the variances,
    ``cols[0]`` the velocity block): ``velocity``, ``zero_velocity`` (``inp`` zeros)."""
    m, s = par.shape[0], cols[0]
    for b in range(lat.shape[0]):
        for i in range(m):
            z[b, r0 + i] = vel[b, i] - inp[b, i]
            H[b, r0 + i, s + i] = 1.0
            R[b, r0 + i, r0 + i] = par[i]


@njit(cache=True, error_model="numpy")
def height(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS height minus ``inp[:, 0]``, m (``par[0]`` its variance; ``cols`` the height's column
    and the baro state's, or -1)."""
    for b in range(lat.shape[0]):
        z[b, r0] = h[b] - inp[b, 0]
        H[b, r0, cols[0]] = 1.0
        if cols[1] >= 0:
            H[b, r0, cols[1]] = -1.0
        R[b, r0, r0] = par[0]


@njit(cache=True, error_model="numpy")
def magnetic_heading(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS minus magnetic heading, rad, from the calibrated sample ``inp[:, :3]`` (body) and
    the filter's Earth field ``inp[:, 3:6]`` (NED); ``par[0]`` its variance, ``cols[0]`` the
    attitude block. A run whose heading is not finite is dropped from ``valid``; an invalid
    run's ``z`` is 0."""
    a = cols[0]
    for b in range(lat.shape[0]):
        v0 = C[b, 0, 0] * inp[b, 0] + C[b, 0, 1] * inp[b, 1] + C[b, 0, 2] * inp[b, 2]
        v1 = C[b, 1, 0] * inp[b, 0] + C[b, 1, 1] * inp[b, 1] + C[b, 1, 2] * inp[b, 2]
        f0, f1, f2 = inp[b, 3], inp[b, 4], inp[b, 5]
        d = (math.atan2(v1, v0) - math.atan2(f1, f0) + math.pi) % (2 * math.pi) - math.pi
        valid[b] = valid[b] and math.isfinite(d)
        z[b, r0] = d if valid[b] else 0.0
        h2 = f0 * f0 + f1 * f1
        H[b, r0, a], H[b, r0, a + 1], H[b, r0, a + 2] = f0 * f2 / h2, f1 * f2 / h2, -1.0
        R[b, r0, r0] = par[0]


#: ``par`` of :func:`air_velocity`, by name (the Python model fills it in this order)
AIR_PARAMS = ("vanes", "angle_sigma", "var_ps", "var_qc", "temperature_noise", "r_air", "wind_n", "wind_e",
              "wind_d", "white_n", "white_e", "white_d")


@njit(cache=True, error_model="numpy")
def air_velocity(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS velocity minus the air data's ground velocity ``C u V + w``
    (:class:`~navsim.navigation.estimators.measurements.AirVelocity`). ``inp``: ``V``, ``p_s``,
    ``T``, ``alpha``, ``beta`` (the last two read with vanes, ``par[0]``); ``par``:
    :data:`AIR_PARAMS`; ``cols``: the velocity block, the attitude block, the pitot bias's column,
    the wind's column per axis N, E, D, then the gusts' (-1: none)."""
    u, e_b, e_a, air = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    Rb = np.empty((3, 3))
    for b in range(lat.shape[0]):
        V = inp[b, 0]
        alpha, beta = (inp[b, 3], inp[b, 4]) if par[0] != 0.0 else (0.0, 0.0)
        ca, sa, cb, sb = math.cos(alpha), math.sin(alpha), math.cos(beta), math.sin(beta)
        u[0], u[1], u[2] = ca * cb, sb, sa * cb
        e_b[0], e_b[1], e_b[2] = -ca * sb, cb, -sa * sb
        e_a[0], e_a[1], e_a[2] = -sa, 0.0, ca
        ps, T = inp[b, 1], inp[b, 2]
        dv_dqc = 1.0 / (ps / (par[5] * T) * max(V, 1.0))
        density = 0.5 * V * math.sqrt(par[2] / ps ** 2 + (par[4] / T) ** 2)
        sv = math.hypot(math.sqrt(par[3]) * dv_dqc, density)
        s_across = V * par[1]
        for i in range(3):
            un = C[b, i, 0] * u[0] + C[b, i, 1] * u[1] + C[b, i, 2] * u[2]
            air[i] = un * V
            z[b, r0 + i] = vel[b, i] - air[i] - par[6 + i]
            H[b, r0 + i, cols[0] + i] = 1.0
            if cols[2] >= 0:
                H[b, r0 + i, cols[2]] = -un * dv_dqc
            for c in (cols[3 + i], cols[6 + i]):
                if c >= 0:
                    H[b, r0 + i, c] = 1.0
        a = cols[1]
        H[b, r0, a + 1], H[b, r0, a + 2] = air[2], -air[1]          # -[air x]
        H[b, r0 + 1, a], H[b, r0 + 1, a + 2] = -air[2], air[0]
        H[b, r0 + 2, a], H[b, r0 + 2, a + 1] = air[1], -air[0]
        for i in range(3):
            for j in range(3):
                Rb[i, j] = sv ** 2 * (u[i] * u[j]) + s_across ** 2 * (e_b[i] * e_b[j] + e_a[i] * e_a[j])
        for i in range(3):
            for j in range(3):
                s = 0.0
                for k in range(3):
                    t = 0.0
                    for q in range(3):
                        t += Rb[k, q] * C[b, j, q]
                    s += C[b, i, k] * t
                R[b, r0 + i, r0 + j] = s + (par[9 + i] if i == j else 0.0)
