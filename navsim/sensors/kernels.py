"""The IMU's error processes compiled (numba): a block of samples of every run per call, one
loop per run, so that a batch of runs equals the runs one by one, bit for bit
(:mod:`navsim.sensors.imu` calls them).
"""

from __future__ import annotations

import numpy as np

from navsim.foundations.compiled import njit
from navsim.foundations.transform import rodrigues


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
def draw_normals(gens, out, k0, k1):
    """Rows ``k0`` to ``k1`` of ``out[b]`` (``out`` ``(B, K, 3)``) with standard normals from
    run ``b``'s generator ``gens[b]`` (numpy's stream; ``gens`` a :class:`numba.typed.List`,
    built once: the generators are typed once, not at each call), in C order."""
    for b in range(len(gens)):
        g = gens[b]
        for k in range(k0, k1):
            for i in range(out.shape[2]):
                out[b, k, i] = g.standard_normal()


@njit(cache=True)
def first_order(w, a):
    """``w[:, j] <- w[:, j] + a w[:, j - 1]`` along the samples of ``w`` ``(B, n, k)``, in place:
    the first-order recursive filter ``1 / (1 - a z^-1)`` of each run and axis (what
    ``scipy.signal.lfilter([1], [1, -a], w, axis=1)`` gives, bit for bit)."""
    B, n, k = w.shape
    for b in range(B):
        for j in range(1, n):
            for i in range(k):
                w[b, j, i] = w[b, j, i] + a * w[b, j - 1, i]


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


@njit(cache=True)
def _rotate(R: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """``out = R v``, summed as numpy's einsum ``bij,bj->bi`` sums (first, third, then second)."""
    for i in range(3):
        out[i] = (R[i, 0] * v[0] + R[i, 2] * v[2]) + R[i, 1] * v[1]


@njit(cache=True)
def _cross(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    out[0], out[1], out[2] = a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@njit(cache=True)
def online_increments(om: np.ndarray, f: np.ndarray, R: np.ndarray, prev: np.ndarray, j: int, dt: float,
                      out: np.ndarray) -> None:
    """Sample ``j`` of :class:`navsim.sensors.imu.OnlineIncrements`, run by run: ``om``, ``f``
    ``(B, 4, 3)`` the rates and specific forces of samples ``j``, ``j-1``, ``j-2``, ``j-3`` (the
    new one first, shifted here), ``R`` ``(B, 2, 3, 3)`` the rotations over the last two
    intervals, ``prev`` ``(B, 2, 3)`` the last interval's ``dtheta`` and compensated ``dv``
    (updated); ``out`` ``(B, 2, 3)`` gets the increments (``dtheta``, measured ``dv``)."""
    tmp, tmp2, c1, c2 = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    dth, dvc = np.empty(3), np.empty(3)
    for b in range(om.shape[0]):
        o, g = om[b], f[b]
        if j == 0:                        # the history starts filled with the first sample
            for k in range(1, 4):
                o[k], g[k] = o[0], g[0]
            for k in range(2):
                R[b, k] = np.eye(3)
            dth[:], dvc[:] = 0.0, 0.0
            out[b, 0], out[b, 1] = 0.0, 0.0
        else:
            for i in range(3):
                dth[i] = (23 * o[1, i] - 16 * o[2, i] + 5 * o[3, i]) / 12.0 * dt
            if j == 1:
                for i in range(3):
                    dvc[i] = g[1, i] * dt
            else:
                _rotate(R[b, 0], g[2], c1)                         # f_{k-1}
                if j > 2:
                    _rotate(R[b, 1], g[3], tmp)
                    _rotate(R[b, 0], tmp, c2)                      # f_{k-2}
                else:
                    _rotate(R[b, 0], g[3], c2)
                for i in range(3):
                    dvc[i] = dt * (23 * g[1, i] - 16 * c1[i] + 5 * c2[i]) / 12.0
            # the strapdown's rotation and sculling compensation undone (to third order)
            _cross(dth, dvc, tmp)
            _cross(prev[b, 0], dvc, c1)
            _cross(prev[b, 1], dth, c2)
            for i in range(3):
                tmp2[i] = c1[i] + c2[i]
                out[b, 0, i] = dth[i]
                out[b, 1, i] = dvc[i] - 0.5 * tmp[i] - tmp2[i] / 12.0
        R[b, 1] = R[b, 0]
        rodrigues(-dth[0], -dth[1], -dth[2], R[b, 0])
        for k in range(3, 0, -1):
            o[k], g[k] = o[k - 1], g[k - 1]
        prev[b, 0], prev[b, 1] = dth, dvc


@njit(cache=True)
def measured_increments(ideal: np.ndarray, M_g: np.ndarray, M_a: np.ndarray, err_g: np.ndarray,
                        err_a: np.ndarray, q: np.ndarray, out: np.ndarray) -> None:
    """The IMU's increments of ``ideal`` ``(B, 2, 3)`` (``dtheta``, ``dv``): ``M @ ideal + err``
    (``M`` ``(B, 3, 3)`` the triad's ``I`` plus scale factors and misalignments, summed left to
    right; ``err`` ``(B, 3)``), rounded to the quantum ``q[0]`` (gyro), ``q[1]`` (accel), none
    where 0; into ``out`` ``(B, 2, 3)``."""
    for b in range(ideal.shape[0]):
        for t in range(2):
            M, e, v = (M_g[b], err_g[b], ideal[b, 0]) if t == 0 else (M_a[b], err_a[b], ideal[b, 1])
            for i in range(3):
                x = M[i, 0] * v[0] + M[i, 1] * v[1] + M[i, 2] * v[2] + e[i]
                out[b, t, i] = np.rint(x / q[t]) * q[t] if q[t] != 0.0 else x
