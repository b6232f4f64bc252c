"""Attitude conversions: Euler angles, quaternions (scalar first), direction-cosine matrices.

All functions broadcast over leading axes. Euler angles are roll, pitch, yaw of frame ``b``
relative to frame ``n`` (z-y-x sequence); ``quat_nb`` and ``C_nb`` take ``b`` vectors to ``n``.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.foundations.compiled import njit


def quat_from_euler(roll, pitch, yaw):
    """``quat_nb`` ``(..., 4)`` from roll, pitch, yaw (rad)."""
    cr, sr = np.cos(0.5 * np.asarray(roll)), np.sin(0.5 * np.asarray(roll))
    cp, sp = np.cos(0.5 * np.asarray(pitch)), np.sin(0.5 * np.asarray(pitch))
    cy, sy = np.cos(0.5 * np.asarray(yaw)), np.sin(0.5 * np.asarray(yaw))
    return np.stack([cr * cp * cy + sr * sp * sy,
                     sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy], axis=-1)


def euler_from_quat(quat):
    """Roll, pitch, yaw (rad) from ``quat_nb``; returns an ``(..., 3)`` array."""
    w, x, y, z = np.moveaxis(np.asarray(quat, float), -1, 0)
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=-1)


def dcm_from_quat(quat):
    """``C_nb`` ``(..., 3, 3)`` from ``quat_nb``."""
    q = np.asarray(quat, float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    C = np.empty(q.shape[:-1] + (3, 3))          # filled entry by entry: a third of np.stack's time
    C[..., 0, 0], C[..., 0, 1], C[..., 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    C[..., 1, 0], C[..., 1, 1], C[..., 1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    C[..., 2, 0], C[..., 2, 1], C[..., 2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    return C


def euler_from_dcm(C_nb):
    """Roll, pitch, yaw (rad) ``(..., 3)`` from ``C_nb`` ``(..., 3, 3)``."""
    C = np.asarray(C_nb, float)
    return np.stack([np.arctan2(C[..., 2, 1], C[..., 2, 2]),
                     np.arcsin(np.clip(-C[..., 2, 0], -1.0, 1.0)),
                     np.arctan2(C[..., 1, 0], C[..., 0, 0])], axis=-1)


def dcm_from_euler(roll, pitch, yaw):
    """``C_nb`` ``(..., 3, 3)`` from roll, pitch, yaw (rad)."""
    return dcm_from_quat(quat_from_euler(roll, pitch, yaw))


def dcm_from_euler_one(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``C_nb`` ``(3, 3)`` of one attitude's roll, pitch, yaw (rad), in scalar arithmetic: what a
    controller stepping one vehicle needs every step (3 us, a tenth of :func:`dcm_from_euler`'s)."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([[cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
                     [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
                     [-sp, sr * cp, cr * cp]])


def quat_multiply(q, r):
    """Hamilton product ``q * r`` of ``(..., 4)`` quaternions."""
    q, r = np.asarray(q, float), np.asarray(r, float)
    w1, x1, y1, z1 = np.moveaxis(q, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(r, -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def quat_from_rotvec(rotvec):
    """Quaternion of a rotation vector ``(..., 3)`` (rad), exact for any angle."""
    rotvec = np.asarray(rotvec, float)
    angle = np.linalg.norm(rotvec, axis=-1)
    half = 0.5 * angle
    # sin(half)/angle, with its series near zero
    k = np.where(angle > 1e-8, np.sin(half) / np.where(angle > 1e-8, angle, 1.0),
                 0.5 - angle ** 2 / 48.0)
    return np.concatenate([np.cos(half)[..., None], rotvec * k[..., None]], axis=-1)


def wrap_angle(angle):
    """Wrap an angle to [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def cross(a, b):
    """Cross product of ``(..., 3)`` arrays (faster than ``np.cross`` for small batches)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def skew(v):
    """``[v x]`` of ``(..., 3)`` vectors, ``(..., 3, 3)``."""
    v = np.asarray(v, float)
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    return K


def rotation(rotvec):
    """Rotation matrix ``exp([rotvec x])`` of ``(..., 3)`` rotation vectors (Rodrigues):
    ``I + s K + c K^2`` with ``K^2 = v v^T - |v|^2 I``; the Taylor series of ``s`` and ``c``
    (exact to 1e-16) for angles below 0.05 rad, as IMU steps are, :mod:`math`'s sine and cosine
    above, vector by vector (a batch of rotations equals the rotations one by one, bit for
    bit: numpy's vectorised sine may round differently for another array length)."""
    rotvec = np.asarray(rotvec, float)
    x, y, z = rotvec[..., 0], rotvec[..., 1], rotvec[..., 2]
    a2 = np.asarray(x * x + y * y + z * z)
    with np.errstate(invalid="ignore", over="ignore"):      # a diverged run: its own NaN
        s = np.array(1.0 - a2 * (1.0 / 6.0) + a2 * a2 * (1.0 / 120.0) - a2 ** 3 * (1.0 / 5040.0))
        c = np.array(0.5 - a2 * (1.0 / 24.0) + a2 * a2 * (1.0 / 720.0) - a2 ** 3 * (1.0 / 40320.0))
    for i in np.flatnonzero(a2 >= 2.5e-3):     # rare: element by element, so no run's
        a = math.sqrt(a2.flat[i])               # rotation depends on the others'
        if math.isfinite(a):
            s.flat[i], c.flat[i] = math.sin(a) / a, (1.0 - math.cos(a)) / a2.flat[i]
        else:                                   # a diverged run: NaN, its own only
            s.flat[i] = c.flat[i] = math.nan
    R = np.empty(rotvec.shape[:-1] + (3, 3))
    cx, cy = c * x, c * y
    R[..., 0, 0] = 1.0 - c * (y * y + z * z)
    R[..., 1, 1] = 1.0 - c * (x * x + z * z)
    R[..., 2, 2] = 1.0 - c * (x * x + y * y)
    R[..., 0, 1] = cx * y - s * z
    R[..., 1, 0] = cx * y + s * z
    R[..., 0, 2] = cx * z + s * y
    R[..., 2, 0] = cx * z - s * y
    R[..., 1, 2] = cy * z - s * x
    R[..., 2, 1] = cy * z + s * x
    return R


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
