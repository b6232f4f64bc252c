"""What a record keeps of each run, compiled: the navigation errors against the truth
(:func:`nav_errors`), why a covariance is not one (:func:`covariance_codes`), and the 1-sigma,
NEES and divergence code of the navigation covariance (:func:`covariance_record`)."""

from __future__ import annotations

import math

import numpy as np

from navsim.foundations.compiled import njit
from navsim.navigation.kernels.earth import radii
from navsim.navigation.kernels.linalg import _solve, quat_dcm


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
        quat_dcm(truth[t, 9], truth[t, 10], truth[t, 11], truth[t, 12], Ct)
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
