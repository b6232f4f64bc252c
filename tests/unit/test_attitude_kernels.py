"""P4's compiled per-sample propagation against the same formulas written with numpy (one
sample at a time over the batch, as P4's equations read), bit for bit, and a batch of 3 against
3 single runs bit for bit."""

import numpy as np
import pytest

from navsim.foundations.transform import cross, dcm_from_quat, euler_from_quat
from navsim.navigation.estimators.attitude import LocalFrame, normalize, rk4_step, rotate_b_to_n, rotate_n_to_b
from navsim.navigation.estimators.attitude import euler_distance2 as numpy_distance2
from navsim.navigation.estimators.attitude_kernels import (GAIN_NAMES, cpf_block, cpf_ekf_block, cpf_heading_error,
                                                           dcm_of, euler_angles, euler_distance2)

GAINS = dict(kp_acc=0.5, kp_mag=0.4, ki=0.05, accel_tau_s=0.2, acc_gate=0.1)


def _ekf_step(x, sum_w, sum_f, frame, dtheta_b, dv_b, dt):
    """The CPF-EKF's prediction of one sample (P4 eq. 5-7)."""
    q = x[:, 0:4]
    w_b = dtheta_b / dt - x[:, 14:17] - rotate_n_to_b(q, frame.w_ie_n)
    f_b = dv_b / dt
    f_b[:, 2] -= x[:, 10]
    q_new = rk4_step(q, w_b, dt)
    v = x[:, 4:7].copy()
    a_n = rotate_b_to_n(normalize(q + q_new), f_b) + frame.g_n - 2.0 * cross(frame.w_ie_n, v)
    v_new = v + a_n * dt
    x[:, 7:10] += 0.5 * (v + v_new) * dt
    x[:, 4:7] = v_new
    x[:, 0:4] = q_new
    sum_w += w_b * dt
    sum_f += f_b * dt


def _cpf_step(s, frame, dtheta_b, dv_b, dt):
    """The complementary filter's step (P4's CPF, Mahony form) on the state dict ``s``."""
    f = dv_b / dt
    s["f_lp"] = f.copy() if s["f_lp"] is None else s["f_lp"] + (f - s["f_lp"]) * min(dt / GAINS["accel_tau_s"], 1.0)
    f_ref_b = rotate_n_to_b(s["q"], s["a_n"] - frame.g_n)
    nm, nr = np.linalg.norm(s["f_lp"], axis=-1), np.linalg.norm(f_ref_b, axis=-1)
    use = (np.abs(nm - nr) <= GAINS["acc_gate"] * np.linalg.norm(frame.g_n, axis=-1)) & (nm > 0) & (nr > 0)
    safe = lambda n: np.where(use, n, 1.0)[:, None]
    e_acc = np.where(use[:, None], cross(s["f_lp"] / safe(nm), f_ref_b / safe(nr)), 0.0)
    w = dtheta_b / dt - s["b"] - rotate_n_to_b(s["q"], frame.w_ie_n)
    w = w + GAINS["kp_acc"] * e_acc + GAINS["kp_mag"] * s["e_mag"]
    s["b"] = s["b"] - GAINS["ki"] * (e_acc + s["e_mag"]) * dt
    s["q"] = rk4_step(s["q"], w, dt)


def _inputs(seed, B=5, K=25):
    rng = np.random.default_rng(seed)
    frame = LocalFrame(np.radians(rng.uniform(-60, 60, B)), np.radians(rng.uniform(0, 90, B)),
                       rng.uniform(0, 2000, B))
    q = rng.normal(size=(B, 4))
    dt = 0.02
    # a slow turn plus noise; specific force near 1 g up, some runs pulling 1.3 g (gate closed)
    dth = (rng.normal(size=(B, K, 3)) * 0.05 + [0.01, -0.02, 0.1]) * dt
    dv = (rng.normal(size=(B, K, 3)) * 0.3 + [0.5, 0.0, -9.8]) * dt
    dv[B // 2:, :, 2] *= 1.3
    return rng, frame, normalize(q), dth, dv, dt


@pytest.mark.parametrize("seed", [1, 2])
def test_cpf_ekf_prediction_equals_the_numpy_form(seed):
    rng, frame, q, dth, dv, dt = _inputs(seed)
    B = q.shape[0]
    x = np.concatenate([q, rng.normal(size=(B, 3)) * 20, rng.normal(size=(B, 3)) * 100,
                        rng.normal(size=(B, 1)) * 0.1, rng.normal(size=(B, 3)), rng.normal(size=(B, 3)) * 1e-3,
                        rng.normal(size=(B, 3)) * 30], axis=1)
    sums = rng.normal(size=(2, B, 3))
    ref_x, ref_w, ref_f = x.copy(), sums[0].copy(), sums[1].copy()
    for j in range(dth.shape[1]):
        _ekf_step(ref_x, ref_w, ref_f, frame, dth[:, j], dv[:, j], dt)
    got_w, got_f = sums[0].copy(), sums[1].copy()
    cpf_ekf_block(x, got_w, got_f, frame.g_n, frame.w_ie_n, dth, dv, dt)
    for got, ref in ((x, ref_x), (got_w, ref_w), (got_f, ref_f)):
        np.testing.assert_array_equal(got, ref)
    # the sample-by-sample position integration did move the state (the check is not vacuous)
    assert np.abs(ref_x[:, 7:10]).max() > 1.0


@pytest.mark.parametrize("seed", [3, 4])
def test_cpf_step_equals_the_numpy_form_gate_open_and_closed(seed):
    rng, frame, q, dth, dv, dt = _inputs(seed)
    B = q.shape[0]
    ref = dict(q=q.copy(), b=rng.normal(size=(B, 3)) * 1e-3, f_lp=None, a_n=rng.normal(size=(B, 3)) * 0.2,
               e_mag=rng.normal(size=(B, 3)) * 0.01)
    q_k, b_k, f_lp = ref["q"].copy(), ref["b"].copy(), np.zeros((B, 3))
    gains = np.array([GAINS[k] for k in GAIN_NAMES])
    half = dth.shape[1] // 2                      # two blocks: the low-pass starts in the first only
    for block in (slice(0, half), slice(half, None)):
        cpf_block(q_k, b_k, f_lp, block.start > 0, ref["a_n"], ref["e_mag"], frame.g_n, frame.w_ie_n, gains,
                  dth[:, block], dv[:, block], dt)
    for j in range(dth.shape[1]):
        _cpf_step(ref, frame, dth[:, j], dv[:, j], dt)
    for got, key in ((q_k, "q"), (b_k, "b"), (f_lp, "f_lp")):
        np.testing.assert_array_equal(got, ref[key])
    # the gate: open where the specific force is 1 g, closed in the runs pulling 1.3 g
    f_ref_b = rotate_n_to_b(ref["q"], ref["a_n"] - frame.g_n)
    gap = np.abs(np.linalg.norm(ref["f_lp"], axis=-1) - np.linalg.norm(f_ref_b, axis=-1))
    assert np.any(gap <= 0.1 * 9.8) and np.any(gap > 0.1 * 9.8), gap


def test_a_batch_of_three_equals_three_single_runs_bit_for_bit():
    rng, frame, q, dth, dv, dt = _inputs(5, B=3)
    gains = np.array([GAINS[k] for k in GAIN_NAMES])
    state = [q.copy(), rng.normal(size=(3, 3)) * 1e-3, np.zeros((3, 3))]
    a_n, e_mag = rng.normal(size=(3, 3)) * 0.2, rng.normal(size=(3, 3)) * 0.01
    batch = [s.copy() for s in state]
    cpf_block(*batch, False, a_n, e_mag, frame.g_n, frame.w_ie_n, gains, dth, dv, dt)
    for b in range(3):
        one = [s[b:b + 1].copy() for s in state]
        cpf_block(*one, False, a_n[b:b + 1], e_mag[b:b + 1], frame.g_n[b:b + 1], frame.w_ie_n[b:b + 1], gains,
                  dth[b:b + 1], dv[b:b + 1], dt)
        for got, whole in zip(one, batch):
            assert np.array_equal(got[0], whole[b])


def test_the_ekf_prediction_of_a_batch_equals_its_single_runs_bit_for_bit():
    rng, frame, q, dth, dv, dt = _inputs(6, B=3)
    x = np.concatenate([q, rng.normal(size=(3, 16))], axis=1)
    sums = rng.normal(size=(2, 3, 3))
    batch = [x.copy(), sums[0].copy(), sums[1].copy()]
    cpf_ekf_block(*batch, frame.g_n, frame.w_ie_n, dth, dv, dt)
    for b in range(3):
        one = [x[b:b + 1].copy(), sums[0, b:b + 1].copy(), sums[1, b:b + 1].copy()]
        cpf_ekf_block(*one, frame.g_n[b:b + 1], frame.w_ie_n[b:b + 1], dth[b:b + 1], dv[b:b + 1], dt)
        for got, whole in zip(one, batch):
            assert np.array_equal(got[0], whole[b])


def test_the_divergence_distance_equals_the_numpy_form_wrapped_and_nan():
    """P4's eq. 21 between two attitudes, compiled, against the Euler angles' numpy form: yaws
    across +-180 deg, a pitch at the pole (its sine clipped) and a NaN quaternion."""
    rng = np.random.default_rng(9)
    q1, q2 = normalize(rng.normal(size=(7, 4))), normalize(rng.normal(size=(7, 4)))
    q1[0], q2[0] = [np.cos(1.56), 0, 0, np.sin(1.56)], [np.cos(-1.56), 0, 0, np.sin(-1.56)]     # 178.8, -178.8 deg
    q1[1] = [np.sqrt(0.5), 0, np.sqrt(0.5) * (1 + 1e-16), 0]                                   # pitch 90 deg
    q2[2] = np.nan
    got = np.empty(7)
    euler_distance2(q1, q2, got)
    ref = numpy_distance2(euler_from_quat(q1), euler_from_quat(q2))
    assert np.allclose(got, ref, rtol=1e-14, atol=0, equal_nan=True) and np.isnan(got[2])
    assert got[0] == pytest.approx(np.radians(2 * (180 - np.degrees(1.56) * 2)) ** 2, rel=1e-9)


def test_the_compiled_euler_angles_and_dcm_equal_the_numpy_forms_bit_for_bit():
    rng = np.random.default_rng(10)
    q = rng.normal(size=(9, 4))                  # not unit: the same formulas all the same
    q[0] = [np.sqrt(0.5), 0, np.sqrt(0.5) * (1 + 1e-16), 0]                  # pitch past 90 deg: clipped
    q[1] = np.nan
    e, C = np.empty((9, 3)), np.empty((9, 3, 3))
    euler_angles(q, e)
    dcm_of(q, C)
    assert np.array_equal(e, euler_from_quat(q), equal_nan=True)
    assert np.array_equal(C, dcm_from_quat(q), equal_nan=True)


def _numpy_heading_error(q, m_b, valid, ref, mag_gate, dip_gate, on_course, t, e_mag, heading_t, rejected):
    """The CPF's heading error from a magnetometer sample, numpy (as ComplementaryCore.aid was
    written before it was compiled); returns the new ``e_mag, heading_t, rejected``."""
    m_n = np.einsum("bij,bj->bi", dcm_from_quat(q), m_b)
    dpsi = np.arctan2(m_n[:, 1], m_n[:, 0]) - np.arctan2(ref[:, 1], ref[:, 0])
    dpsi = (dpsi + np.pi) % (2 * np.pi) - np.pi
    dip = lambda v: np.arctan2(v[:, 2], np.hypot(v[:, 0], v[:, 1]))
    ok = (valid & (np.abs(np.linalg.norm(m_b, axis=-1) / np.linalg.norm(ref, axis=-1) - 1.0) <= mag_gate)
          & (np.abs(dip(m_n) - dip(ref)) <= dip_gate))
    e_n = np.zeros_like(m_b)
    e_n[:, 2] = -np.where(ok, dpsi, 0.0)
    return (np.where(on_course[:, None], e_mag, rotate_n_to_b(q, e_n)), np.where(ok, t, heading_t),
            rejected + (valid & ~ok))


def test_the_cpf_heading_error_equals_the_numpy_form_with_its_gates():
    """Accepted, rejected by magnitude, by dip, invalid, steered by the course, and a heading
    across +-180 deg: the error, the time of the last reference and the rejection count."""
    rng = np.random.default_rng(11)
    B = 8
    q = normalize(rng.normal(size=(B, 4)))
    ref = np.tile([20.0, -3.0, 45.0], (B, 1))
    m_b = np.einsum("bji,bj->bi", dcm_from_quat(q), ref)           # the reference field, seen in the body
    m_b[0] = np.einsum("ji,j->i", dcm_from_quat(q[:1])[0], [20.0 * np.cos(0.1) + 3.0 * np.sin(0.1),
                                                              20.0 * np.sin(0.1) - 3.0 * np.cos(0.1), 45.0])
    m_b[1] *= 1.2                                                   # magnitude gate
    m_b[2] += np.einsum("ji,j->i", dcm_from_quat(q[2:3])[0], [0.0, 0.0, 8.0])      # dip gate
    valid = np.ones(B, bool)
    valid[3] = False
    on_course = np.zeros(B, bool)
    on_course[4] = True
    ref[5] = [-20.0, 0.5, 45.0]                                     # the reference near 180 deg
    m_b[5] = np.einsum("ji,j->i", dcm_from_quat(q[5:6])[0], [-20.0, -0.5, 45.0])
    e_mag, heading_t, rejected = rng.normal(size=(B, 3)) * 0.01, np.zeros(B), np.zeros(B, int)
    want = _numpy_heading_error(q, m_b, valid, ref, 0.05, np.radians(3.0), on_course, 2.5, e_mag, heading_t, rejected)
    cpf_heading_error(q, m_b, valid, ref, np.array([0.05, np.radians(3.0)]), on_course, 2.5, e_mag, heading_t, rejected)
    np.testing.assert_allclose(e_mag, want[0], rtol=1e-13, atol=1e-16)
    assert np.array_equal(heading_t, want[1]) and np.array_equal(rejected, want[2])
    assert rejected.tolist() == [0, 1, 1, 0, 0, 0, 0, 0] and heading_t.tolist() == [2.5, 0, 0, 0] + [2.5] * 4
    assert abs(e_mag[0]).max() > 0.05 and np.array_equal(e_mag[1], np.zeros(3))
