"""The IMU's error processes compiled (numba): a block of samples of every run per call, one
loop per run, so that a batch of runs equals the runs one by one, bit for bit
(:mod:`navsim.sensors.imu` calls them).
"""

from __future__ import annotations

import numpy as np

from navsim.foundations.compiled import njit


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
