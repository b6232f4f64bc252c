"""The R adaptation laws of the Sage-Husa and fuzzy adaptive filters, on innovations of known
statistics (the filters' ``measurement_noise`` step in isolation)."""

from dataclasses import dataclass

import numpy as np
import pytest

from navsim.navigation.estimators.fuzzy_adaptive import DEFAULT_RULES, FuzzyAdaptiveKF, infer, memberships
from navsim.navigation.estimators.sage_husa import SageHusaKF


@dataclass
class Model:
    sensor: str = "gps"
    name: str = "gnss_position"


def bare(cls, B, n=4, p_var=0.25, **params):
    """A filter object with only the state the adaptation reads (x, P)."""
    f = cls.__new__(cls)
    for k, v in params.items():
        setattr(f, k, v)
    f.x = np.zeros((B, n))
    f.P = np.broadcast_to(np.eye(n) * p_var, (B, n, n)).copy()
    return f


def innovations(rng, f, H, R_true, steps):
    S = H @ f.P[0] @ H.T + R_true
    return rng.multivariate_normal(np.zeros(H.shape[0]), S, size=(steps, f.x.shape[0]))


def test_sage_husa_recovers_the_true_R_and_stays_positive_definite():
    rng = np.random.default_rng(5)
    B = 400
    # H P H^T = 20 I is a large part of the innovation covariance: forgetting to subtract it fails
    f = bare(SageHusaKF, B, p_var=20.0, forgetting=0.98, floor=0.01, sensors=None, R_hat={}, count={})
    H = np.zeros((3, 4))
    H[:, :3] = np.eye(3)
    R_model = np.diag([4.0, 4.0, 1.0])
    R_true = 25.0 * np.array([[4.0, 1.0, 0.0], [1.0, 4.0, 0.0], [0.0, 0.0, 1.0]])   # x25, correlated
    Hs, Rs = np.broadcast_to(H, (B, 3, 4)), np.broadcast_to(R_model, (B, 3, 3))
    for y in innovations(rng, f, H, R_true, 300):
        R_hat = f.measurement_noise(Model(), y, Hs, Rs, np.ones(B, bool))
        assert np.all(np.linalg.eigvalsh(R_hat) > 0)
    # fading memory of ~50 epochs: each run's estimate scatters by ~sqrt(2/(2*50)) ~ 15 %,
    # the average over the runs recovers R
    np.testing.assert_allclose(R_hat.mean(0), R_true, atol=0.05 * np.abs(R_true).max())
    assert np.median(np.abs(R_hat[:, 0, 0] / R_true[0, 0] - 1)) < 0.2


def test_sage_husa_floor_keeps_R_at_least_the_model():
    rng = np.random.default_rng(6)
    B = 200
    f = bare(SageHusaKF, B, forgetting=0.95, floor=1.0, sensors=None, R_hat={}, count={})
    H = np.eye(2, 4)
    R_model = np.diag([4.0, 9.0])
    Hs, Rs = np.broadcast_to(H, (B, 2, 4)), np.broadcast_to(R_model, (B, 2, 2))
    for y in innovations(rng, f, H, 0.01 * R_model, 100):          # a sensor better than its model
        R_hat = f.measurement_noise(Model(), y, Hs, Rs, np.ones(B, bool))
    assert np.linalg.eigvalsh(R_hat).min() >= 4.0 - 1e-9
    # invalid epochs leave the estimate alone; other sensors are not adapted
    f.sensors = {"gps"}
    before = R_hat.copy()
    again = f.measurement_noise(Model(), 100 * np.ones((B, 2)), Hs, Rs, np.zeros(B, bool))
    np.testing.assert_array_equal(again, before)
    assert f.measurement_noise(Model(sensor="baro"), np.ones((B, 2)), Hs, Rs, np.ones(B, bool)) is Rs


def test_fuzzy_memberships_partition_and_rules():
    r = np.linspace(0.0, 15.0, 301)
    centres = [c for c, _ in DEFAULT_RULES]
    mu = memberships(r, centres)
    np.testing.assert_allclose(mu.sum(-1), 1.0)
    assert np.all(mu >= 0)
    s = infer(r, DEFAULT_RULES)
    assert np.all(np.diff(s) >= 0)                                  # monotone credibility
    np.testing.assert_allclose(infer(np.array(centres), DEFAULT_RULES), [s for _, s in DEFAULT_RULES])
    assert infer(np.array([0.2]), DEFAULT_RULES)[0] == 1.0 and infer(np.array([50.0]), DEFAULT_RULES)[0] == 100.0


@pytest.mark.parametrize("factor", [1.0, 5.0])
def test_fuzzy_scale_follows_the_noise_ratio(factor):
    rng = np.random.default_rng(7)
    B = 300
    f = bare(FuzzyAdaptiveKF, B, rules=np.asarray(DEFAULT_RULES), window=3.0, sensors=None,
             nis_smoothed={}, scale={})
    H = np.eye(3, 4)
    R_model = np.diag([4.0, 4.0, 1.0])
    Hs, Rs = np.broadcast_to(H, (B, 3, 4)), np.broadcast_to(R_model, (B, 3, 3))
    for y in innovations(rng, f, H, factor ** 2 * R_model, 40):
        R_used = f.measurement_noise(Model(), y, Hs, Rs, np.ones(B, bool))
    scale = R_used[:, 0, 0] / 4.0
    # with R dominating S, r ~ factor and the rules give s ~ factor^2 (a little under: P adds
    # to S); a consistent sensor keeps s near 1
    if factor == 1.0:
        assert np.median(scale) < 1.5
    else:
        assert 0.6 * factor ** 2 < np.median(scale) < 1.2 * factor ** 2
