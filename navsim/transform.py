"""Attitude conversions: Euler angles, quaternions (scalar first), direction-cosine matrices.

All functions broadcast over leading axes. Euler angles are roll, pitch, yaw of frame ``b``
relative to frame ``n`` (z-y-x sequence); ``quat_nb`` and ``C_nb`` take ``b`` vectors to ``n``.
"""

from __future__ import annotations

import numpy as np


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
    w, x, y, z = np.moveaxis(np.asarray(quat, float), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def euler_from_dcm(C_nb):
    """Roll, pitch, yaw (rad) ``(..., 3)`` from ``C_nb`` ``(..., 3, 3)``."""
    C = np.asarray(C_nb, float)
    return np.stack([np.arctan2(C[..., 2, 1], C[..., 2, 2]),
                     np.arcsin(np.clip(-C[..., 2, 0], -1.0, 1.0)),
                     np.arctan2(C[..., 1, 0], C[..., 0, 0])], axis=-1)


def dcm_from_euler(roll, pitch, yaw):
    """``C_nb`` ``(..., 3, 3)`` from roll, pitch, yaw (rad)."""
    return dcm_from_quat(quat_from_euler(roll, pitch, yaw))


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

