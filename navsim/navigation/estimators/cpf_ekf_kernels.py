"""P4's CPF-EKF epoch compiled, one loop per run (numba, cached): the covariance prediction
(:func:`predict_covariance`, P4 eq. 8-10), the sequential scalar magnetometer updates
(:func:`correct_magnetometer`, eq. 11-16) with P4's classical divergence test on their prior
innovations (:func:`innovation_test`, eq. 20), the linear Kalman filter's GNSS and baro updates
(:func:`correct_linear`, eq. 17-19), each correction followed by the quaternion's
renormalisation with its covariance projected onto the sphere's tangent space
(:func:`renormalize_run`), the divergence flags (:func:`flag_diverged`) and the navigation
covariance handed to the runner (:func:`navigation_covariance`).

The formulas are :mod:`.cpf_ekf`'s (its module docstring): the Jacobians of ``C(q) f`` written
out entry by entry; the series discretisation is the ES-KF's kernel
(:mod:`navsim.navigation.kernels`), ``Phi P Phi^T`` taken over ``Phi``'s nonzero entries; the
linear updates are the ES-KF's Joseph update (``joseph_run``), the magnetometer's its evaluation
for one row (:func:`scalar_joseph`). ``tests/unit/test_cpf_ekf_kernels.py`` holds each to the
same formula written with numpy (dense batched products) to 1e-12 (a covariance entry by entry
relative to ``sqrt(P_ii P_jj)``), a whole flight of the filter to the numpy filter, and a batch of 3 to 3 single runs bit for bit (with
the magnetometer; ``tests/unit/test_attitude_filters.py`` on GNSS alone). A run's arithmetic
never depends on the other runs.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.foundations.compiled import njit
from navsim.navigation.estimators.attitude_kernels import AZ, MB0, ME0, N_STATES, Q0, S0, V0, WB0
from navsim.navigation.kernels.covariance import _nonzeros, _sparse_left, discretize_series
from navsim.navigation.kernels.update import joseph_run, joseph_scratch

_OPTIONS = dict(cache=True, error_model="numpy")     # a diverged run gives NaN, as numpy does

#: the filter's noise densities (1-sigma) in the order :func:`predict_covariance` reads them
NOISE_NAMES = ("gyro_rad_s_rthz", "accel_mps2_rthz", "gyro_bias_walk", "accel_bias_walk", "mag_bias_walk_uT",
               "field_walk_uT", "quat_stab")
#: the order of the series that discretises ``F`` and ``Qc`` over the epoch
ORDER = 2


@njit(**_OPTIONS)
def rotation_jacobian(q, f, s, J, r0, c0):
    """``d (C(q) f) / dq`` into ``J[r0:r0+3, c0:c0+4]`` for
    ``C(q) = (w^2 - v.v) I + 2 v v^T + 2 w [v x]`` (``C_nb``, ``s = 1``) or its transpose
    (``C_bn``, ``s = -1``): ``d/dw = 2 w f + 2 s v x f``,
    ``d/dv = -2 f v^T + 2 (v.f) I + 2 v f^T - 2 s w [f x]``."""
    w, v0, v1, v2 = q[0], q[1], q[2], q[3]
    f0, f1, f2 = f[0], f[1], f[2]
    vf = v0 * f0 + v1 * f1 + v2 * f2
    J[r0, c0] = 2.0 * w * f0 + s * 2.0 * (v1 * f2 - v2 * f1)
    J[r0 + 1, c0] = 2.0 * w * f1 + s * 2.0 * (v2 * f0 - v0 * f2)
    J[r0 + 2, c0] = 2.0 * w * f2 + s * 2.0 * (v0 * f1 - v1 * f0)
    sw = s * 2.0 * w
    v = (v0, v1, v2)
    fs = (f0, f1, f2)
    for i in range(3):
        for j in range(3):
            k = 0.0                        # [f x][i, j]
            if i == 0 and j == 1:
                k = -f2
            elif i == 0 and j == 2:
                k = f1
            elif i == 1 and j == 0:
                k = f2
            elif i == 1 and j == 2:
                k = -f0
            elif i == 2 and j == 0:
                k = -f1
            elif i == 2 and j == 1:
                k = f0
            d = 2.0 * vf if i == j else 0.0
            J[r0 + i, c0 + 1 + j] = -2.0 * (fs[i] * v[j]) + d + 2.0 * (v[i] * fs[j]) - sw * k


@njit(**_OPTIONS)
def _xi(q, X):
    """``Xi(q)`` ``(4, 3)`` with ``q * [0, w] = Xi(q) w``, into ``X``."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    X[0, 0], X[0, 1], X[0, 2] = -x, -y, -z
    X[1, 0], X[1, 1], X[1, 2] = w, -z, y
    X[2, 0], X[2, 1], X[2, 2] = z, w, -x
    X[3, 0], X[3, 1], X[3, 2] = -y, x, w


@njit(**_OPTIONS)
def _system(x, w, f, w_ie, noise, F, Qc, X):
    """One run's ``F`` (eq. 8) and ``Qc`` (eq. 9-10, symmetric) at the epoch's mean corrected
    rate ``w`` and specific force ``f`` ``(3,)``, into the zeroed ``F``, ``Qc`` ``(20, 20)``;
    ``X`` ``(4, 3)`` scratch."""
    q = x[Q0:Q0 + 4]
    wx, wy, wz = 0.5 * w[0], 0.5 * w[1], 0.5 * w[2]
    F[0, 1], F[0, 2], F[0, 3] = -wx, -wy, -wz              # Omega(w) / 2
    F[1, 0], F[1, 2], F[1, 3] = wx, wz, -wy
    F[2, 0], F[2, 1], F[2, 3] = wy, -wz, wx
    F[3, 0], F[3, 1], F[3, 2] = wz, wy, -wx
    _xi(q, X)
    for i in range(4):
        for j in range(3):
            F[Q0 + i, WB0 + j] = -0.5 * X[i, j]
    rotation_jacobian(q, f, 1.0, F, V0, Q0)
    qw, qx, qy, qz = q[0], q[1], q[2], q[3]
    F[V0, AZ] = -(2 * (qx * qz + qw * qy))                 # -C_nb[:, 2]
    F[V0 + 1, AZ] = -(2 * (qy * qz - qw * qx))
    F[V0 + 2, AZ] = -(1 - 2 * (qx * qx + qy * qy))
    F[V0, V0 + 1], F[V0, V0 + 2] = -2.0 * -w_ie[2], -2.0 * w_ie[1]      # -2 [w_ie x]
    F[V0 + 1, V0], F[V0 + 1, V0 + 2] = -2.0 * w_ie[2], -2.0 * -w_ie[0]
    F[V0 + 2, V0], F[V0 + 2, V0 + 1] = -2.0 * -w_ie[1], -2.0 * w_ie[0]
    for i in range(3):
        F[S0 + i, V0 + i] = 1.0
    g, a, gbw, abw, mbw, fw, qs = noise[0], noise[1], noise[2], noise[3], noise[4], noise[5], noise[6]
    c = 0.25 * g ** 2
    for i in range(4):
        for j in range(i, 4):
            s = (c * X[i, 0]) * X[j, 0] + (c * X[i, 1]) * X[j, 1] + (c * X[i, 2]) * X[j, 2]
            if i == j:
                s += qs ** 2
            Qc[Q0 + i, Q0 + j] = s
            Qc[Q0 + j, Q0 + i] = s
    Qc[AZ, AZ] = abw ** 2
    for i in range(3):
        Qc[V0 + i, V0 + i] = a ** 2
        Qc[MB0 + i, MB0 + i] = mbw ** 2
        Qc[WB0 + i, WB0 + i] = gbw ** 2
        Qc[ME0 + i, ME0 + i] = fw ** 2


@njit(**_OPTIONS)
def predict_covariance(x, P, sum_w, sum_f, T, w_ie_n, noise):
    """``P <- Phi P Phi^T + Qd`` (symmetrised) of every run over the epoch's ``T`` s, in place:
    ``F`` and ``Qc`` at the mean rate ``sum_w / T`` and specific force ``sum_f / T``
    (``(B, 3)``, zeroed after), discretised by the series to :data:`ORDER`. ``noise``: the
    densities of :data:`NOISE_NAMES`, in that order."""
    B, n = x.shape[0], N_STATES
    F, Qc = np.zeros((B, n, n)), np.zeros((B, n, n))
    Phi, Qd = np.empty((B, n, n)), np.empty((B, n, n))
    X, w, f = np.empty((4, 3)), np.empty(3), np.empty(3)
    for b in range(B):
        for i in range(3):
            w[i] = sum_w[b, i] / T
            f[i] = sum_f[b, i] / T
            sum_w[b, i] = 0.0
            sum_f[b, i] = 0.0
        _system(x[b], w, f, w_ie_n[b], noise, F[b], Qc[b], X)
    discretize_series(F, Qc, T, ORDER, Phi, Qd)
    A, At, Ct = np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
    rows, cols, vals = np.empty(n * n, np.int64), np.empty(n * n, np.int64), np.empty(n * n)
    for b in range(B):
        _sandwich(Phi[b], P[b], Qd[b], (rows, cols, vals), A, At, Ct)


@njit(**_OPTIONS)
def _sandwich(Phi, P, Qd, sparse, A, At, Ct):
    """One run's ``P <- Phi P Phi^T + Qd``, symmetrised, in place, both products over the
    nonzero entries of ``Phi`` (about a third of them: ``F``'s blocks and their squares):
    ``A = Phi P``, then ``(A Phi^T)^T = Phi A^T``. ``sparse``: scratch for ``Phi``'s nonzero
    entries; ``A``, ``At``, ``Ct`` ``(n, n)`` scratch."""
    rows, cols, vals = sparse
    n = P.shape[0]
    nz = _nonzeros(Phi, rows, cols, vals)
    _sparse_left(rows, cols, vals, nz, P, A)
    for i in range(n):
        for j in range(n):
            At[i, j] = A[j, i]
    _sparse_left(rows, cols, vals, nz, At, Ct)
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * ((Ct[j, i] + Qd[i, j]) + (Ct[i, j] + Qd[j, i]))
            P[i, j] = v
            P[j, i] = v


@njit(**_OPTIONS)
def renormalize_run(x, P, Jq, A):
    """``q <- q / |q|`` and ``P <- J P J^T`` (symmetrised) with ``J = blockdiag((I - u u^T) / |q|,
    I)`` of one run, in place; ``Jq`` ``(4, 4)``, ``A`` ``(4, 20)`` scratch."""
    n = P.shape[0]
    norm = math.sqrt(x[Q0] * x[Q0] + x[Q0 + 1] * x[Q0 + 1] + x[Q0 + 2] * x[Q0 + 2] + x[Q0 + 3] * x[Q0 + 3])
    for i in range(4):
        x[Q0 + i] = x[Q0 + i] / norm
    for i in range(4):
        for j in range(4):
            Jq[i, j] = ((1.0 if i == j else 0.0) - x[Q0 + i] * x[Q0 + j]) / norm
    for i in range(4):                     # the quaternion's rows of J P
        for j in range(n):
            A[i, j] = Jq[i, 0] * P[Q0, j] + Jq[i, 1] * P[Q0 + 1, j] + Jq[i, 2] * P[Q0 + 2, j] + Jq[i, 3] * P[Q0 + 3, j]
    for i in range(4):                     # J P J^T: the quaternion's rows
        for j in range(n):
            P[Q0 + i, j] = A[i, j]
        for j in range(4):
            P[Q0 + i, Q0 + j] = (A[i, Q0] * Jq[j, 0] + A[i, Q0 + 1] * Jq[j, 1] + A[i, Q0 + 2] * Jq[j, 2]
                                 + A[i, Q0 + 3] * Jq[j, 3])
    for i in range(4):                     # symmetrised: the quaternion block, its columns mirrored
        for j in range(i + 1, 4):
            v = 0.5 * (P[Q0 + i, Q0 + j] + P[Q0 + j, Q0 + i])
            P[Q0 + i, Q0 + j] = v
            P[Q0 + j, Q0 + i] = v
        for j in range(n):
            if j < Q0 or j >= Q0 + 4:
                P[j, Q0 + i] = P[Q0 + i, j]


@njit(**_OPTIONS)
def magnetometer_model(x, h, H, C):
    """``h = C_bn M + m_bias`` (uT, ``(3,)``) and its Jacobian ``H`` ``(3, 20)`` of one run, in
    place (``C_bn`` the homogeneous form's transpose, whose derivative ``H`` is; ``C`` ``(3, 3)``
    scratch, left holding ``C_nb``)."""
    w, v0, v1, v2 = x[Q0], x[Q0 + 1], x[Q0 + 2], x[Q0 + 3]
    d = w * w - (v0 * v0 + v1 * v1 + v2 * v2)
    v = (v0, v1, v2)
    for i in range(3):
        for j in range(3):
            C[i, j] = (d if i == j else 0.0) + 2.0 * (v[i] * v[j])
    C[0, 1] += 2.0 * w * -v2
    C[0, 2] += 2.0 * w * v1
    C[1, 0] += 2.0 * w * v2
    C[1, 2] += 2.0 * w * -v0
    C[2, 0] += 2.0 * w * -v1
    C[2, 1] += 2.0 * w * v0
    for i in range(3):
        for j in range(N_STATES):
            H[i, j] = 0.0
        h[i] = (C[0, i] * x[ME0] + C[1, i] * x[ME0 + 1] + C[2, i] * x[ME0 + 2]) + x[MB0 + i]
        H[i, MB0 + i] = 1.0
        for j in range(3):
            H[i, ME0 + j] = C[j, i]
    rotation_jacobian(x[Q0:Q0 + 4], x[ME0:ME0 + 3], -1.0, H, 0, Q0)


@njit(**_OPTIONS)
def innovation_test(x, P, z, r, nu2, trace_S):
    """P4's classical divergence test's two sides (eq. 20) of every run at the prior: ``nu^T nu``
    of the three magnetometer innovations and ``tr(H P H^T + r I)``, into ``nu2``, ``trace_S``
    ``(B,)``; ``z`` ``(B, 3)`` uT, ``r`` the variance of each axis, uT^2."""
    n = N_STATES
    h, H, C = np.empty(3), np.empty((3, n)), np.empty((3, 3))
    for b in range(x.shape[0]):
        magnetometer_model(x[b], h, H, C)
        nu2[b] = 0.0
        trace_S[b] = 0.0
        for i in range(3):
            nu = z[b, i] - h[i]
            nu2[b] += nu * nu
            t = r
            for j in range(n):
                if H[i, j] != 0.0:
                    c = 0.0
                    for k in range(n):
                        c += P[b, j, k] * H[i, k]
                    t += H[i, j] * c
            trace_S[b] += t


@njit(**_OPTIONS)
def correct_magnetometer(x, P, z, valid, r, y, S, nis):
    """The magnetometer's three sequential scalar EKF updates of every run (P4 eq. 11-16), each
    axis relinearised at the estimate the previous one left, then :func:`renormalize_run`.

    Parameters
    ----------
    x : (B, 20), P : (B, 20, 20)
        State and covariance; updated where ``valid`` (renormalised in every run).
    z : (B, 3) array
        The field measured, body, uT.
    valid : (B,) bool
    r : float
        The variance of each axis, uT^2.
    y : (B, 3) array
        Out: each axis's innovation.
    S : (B, 3, 3) array
        Out: the innovations' variances on the diagonal (each axis's at its own prior), zeros
        off it.
    nis : (B,) array
        Out: ``sum(y^2 / S_ii)`` where ``valid``, NaN elsewhere.
    """
    n = N_STATES
    h, H, C = np.empty(3), np.empty((3, n)), np.empty((3, 3))
    cols, hp, k, row = np.empty(n, np.int64), np.empty(n), np.empty(n), np.empty(n)
    Jq, A = np.empty((4, 4)), np.empty((4, n))
    for b in range(x.shape[0]):
        xb, Pb = x[b], P[b]
        nis[b] = 0.0
        for axis in range(3):
            magnetometer_model(xb, h, H, C)
            y[b, axis] = z[b, axis] - h[axis]
            for j in range(3):
                S[b, axis, j] = 0.0
            S[b, axis, axis] = scalar_joseph(xb, Pb, y[b, axis], H[axis], r, valid[b], cols, hp, k, row)
            nis[b] += y[b, axis] * y[b, axis] / S[b, axis, axis]
        if not valid[b]:
            nis[b] = np.nan
        renormalize_run(xb, Pb, Jq, A)


@njit(**_OPTIONS)
def scalar_joseph(x, P, y, H, r, valid, cols, hp, k, row):
    """One run's Joseph update with a single measurement row, in place: innovation ``y``,
    ``H`` ``(n,)``, variance ``r``; ``S = H P H^T + r``, ``K = P H^T / S``, ``x <- x + K y``,
    ``P <- (I - K H) P (I - K H)^T + K r K^T`` evaluated as ``joseph_update`` does (``A = P -
    K (H P)``, ``A - (A H^T) K^T + K r K^T`` row by row, ``H``'s zeros skipped), symmetrised.
    Returns ``S``; an invalid run keeps its state. Scratch: ``cols`` (ints), ``hp``, ``k``,
    ``row`` ``(n,)``."""
    n = P.shape[0]
    nh = 0
    for j in range(n):
        hp[j] = 0.0
        if H[j] != 0.0:
            cols[nh] = j
            nh += 1
    for z in range(nh):                     # H P (a row: P is symmetric)
        c = cols[z]
        for j in range(n):
            hp[j] += H[c] * P[c, j]
    S = 0.0
    for z in range(nh):
        S += hp[cols[z]] * H[cols[z]]
    S += r
    if not valid:
        return S
    for j in range(n):                      # K = (H P)^T / S
        k[j] = hp[j] / S
        x[j] += k[j] * y
    for i in range(n):                      # row i of A = P - K H P, then of A - (A H^T) K^T + K r K^T
        for j in range(n):
            row[j] = P[i, j] - k[i] * hp[j]
        d = k[i] * r
        for z in range(nh):
            d -= row[cols[z]] * H[cols[z]]
        for j in range(n):
            P[i, j] = row[j] + d * k[j]
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = v
            P[j, i] = v
    return S


@njit(**_OPTIONS)
def correct_linear(x, P, z, rows, r, valid, y, S, nis):
    """One linear Kalman update of every run (P4 eq. 17-19: ``z = H x``, ``H`` the selection of
    the states ``rows`` ``(m,)``, ``R = diag(r)``), then :func:`renormalize_run`; out: the
    innovations ``y`` ``(B, m)``, their covariances ``S`` ``(B, m, m)``, the NIS ``(B,)``."""
    n, m = N_STATES, rows.shape[0]
    H, R, zb = np.zeros((m, n)), np.zeros((m, m)), np.empty(m)
    for i in range(m):
        H[i, rows[i]] = 1.0
        R[i, i] = r[i]
    HP, Kt, W, work, index = joseph_scratch(n, m)
    Jq, A = np.empty((4, 4)), np.empty((4, n))
    for b in range(x.shape[0]):
        for i in range(m):
            zb[i] = z[b, i]
        nis[b] = joseph_run(x[b], P[b], zb, H, R, valid[b], y[b], S[b], HP, Kt, W, work, index)
        renormalize_run(x[b], P[b], Jq, A)


@njit(**_OPTIONS)
def flag_diverged(x, P, q_cpf, diverged):
    """``diverged[b] |= ...`` where run ``b``'s state, covariance or CPF attitude has a
    non-finite entry or a variance below ``-1e-12``."""
    n = P.shape[1]
    for b in range(x.shape[0]):
        ok = True
        for i in range(n):
            ok = ok and math.isfinite(x[b, i]) and P[b, i, i] >= -1e-12
            for j in range(n):
                ok = ok and math.isfinite(P[b, i, j])
        for i in range(q_cpf.shape[1]):
            ok = ok and math.isfinite(q_cpf[b, i])
        if not ok:
            diverged[b] = True


@njit(**_OPTIONS)
def navigation_covariance(x, P, pos_scale, P_nav):
    """``P_nav = T P T^T`` ``(B, 9, 9)`` of every run: the attitude error ``phi = -2 Psi(q)^T dq``
    (NED), velocity, and position scaled to the runner's units by ``pos_scale`` ``(B, 3)``.
    ``T`` reads the quaternion, velocity and position only (the first 10 states): the products
    run over those columns."""
    m = max(Q0 + 4, V0 + 3, S0 + 3)         # the states T reads: those below m
    T = np.zeros((9, m))
    TP = np.empty((9, m))
    for b in range(x.shape[0]):
        w, qx, qy, qz = x[b, Q0], x[b, Q0 + 1], x[b, Q0 + 2], x[b, Q0 + 3]
        # Psi(q) = [[-x,-y,-z],[w,z,-y],[-z,w,x],[y,-x,w]]; T[0:3, Q] = -2 Psi^T
        T[0, Q0], T[0, Q0 + 1], T[0, Q0 + 2], T[0, Q0 + 3] = -2.0 * -qx, -2.0 * w, -2.0 * -qz, -2.0 * qy
        T[1, Q0], T[1, Q0 + 1], T[1, Q0 + 2], T[1, Q0 + 3] = -2.0 * -qy, -2.0 * qz, -2.0 * w, -2.0 * -qx
        T[2, Q0], T[2, Q0 + 1], T[2, Q0 + 2], T[2, Q0 + 3] = -2.0 * -qz, -2.0 * -qy, -2.0 * qx, -2.0 * w
        for i in range(3):
            T[3 + i, V0 + i] = 1.0
            T[6 + i, S0 + i] = pos_scale[b, i]
        for i in range(9):
            for j in range(m):
                c = 0.0
                for k in range(m):
                    if T[i, k] != 0.0:
                        c += T[i, k] * P[b, k, j]
                TP[i, j] = c
        for i in range(9):
            for j in range(9):
                c = 0.0
                for k in range(m):
                    if T[j, k] != 0.0:
                        c += TP[i, k] * T[j, k]
                P_nav[b, i, j] = c


__all__ = ["NOISE_NAMES", "ORDER", "correct_linear", "correct_magnetometer", "flag_diverged", "innovation_test",
           "magnetometer_model", "navigation_covariance", "predict_covariance", "renormalize_run", "rotation_jacobian",
           "scalar_joseph"]
