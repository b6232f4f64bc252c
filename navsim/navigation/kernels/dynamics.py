"""The SINS error model's continuous system matrix ``F`` compiled, run by run
(:func:`error_dynamics`, documented in
:func:`navsim.navigation.estimators.error_model.system_matrix`)."""

from __future__ import annotations

import math

import numpy as np

from navsim.foundations.compiled import njit
from navsim.navigation.kernels.earth import OMEGA, gravity_gradient, radii
from navsim.navigation.kernels.linalg import _copy


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
        _copy(E, D)                    # 2 d(omega_ie) + d(omega_en)
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
