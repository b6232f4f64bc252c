import numpy as np
from scipy.spatial.transform import Rotation

from navsim.foundations import transform as tf


def test_euler_quat_dcm_agree_with_scipy():
    rng = np.random.default_rng(2)
    eul = np.column_stack([rng.uniform(-np.pi, np.pi, 50), rng.uniform(-1.5, 1.5, 50),
                           rng.uniform(-np.pi, np.pi, 50)])
    q = tf.quat_from_euler(eul[:, 0], eul[:, 1], eul[:, 2])
    ref = Rotation.from_euler("ZYX", eul[:, ::-1])
    np.testing.assert_allclose(tf.dcm_from_quat(q), ref.as_matrix(), atol=1e-12)
    np.testing.assert_allclose(tf.euler_from_quat(q), eul, atol=1e-9)
    np.testing.assert_allclose(tf.euler_from_dcm(tf.dcm_from_quat(q)), eul, atol=1e-9)
    one = np.array([tf.dcm_from_euler_one(*e) for e in eul])
    np.testing.assert_allclose(one, ref.as_matrix(), atol=1e-12)


def test_quat_multiply_composes_rotations():
    rng = np.random.default_rng(3)
    a, b = Rotation.random(10, random_state=4), Rotation.random(10, random_state=5)
    qa = np.roll(a.as_quat(), 1, axis=-1)
    qb = np.roll(b.as_quat(), 1, axis=-1)
    np.testing.assert_allclose(tf.dcm_from_quat(tf.quat_multiply(qa, qb)), (a * b).as_matrix(),
                               atol=1e-12)
    v = rng.normal(size=(10, 3))
    np.testing.assert_allclose(tf.dcm_from_quat(tf.quat_from_rotvec(v)),
                               Rotation.from_rotvec(v).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(tf.quat_from_rotvec(np.zeros(3)), [1, 0, 0, 0])


def test_wrap_angle():
    np.testing.assert_allclose(tf.wrap_angle([3 * np.pi / 2, -3 * np.pi / 2, 0.1]),
                               [-np.pi / 2, np.pi / 2, 0.1])
