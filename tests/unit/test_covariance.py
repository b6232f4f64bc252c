"""Covariance analysis (navsim.navigation.covariance): free inertial error growth against its
analytic form, a matched filter's covariance reproduced as the sum of its sources, the linear
forms of the IMU's terms against the emulator's own draws, a measurement's sensitivity to its
sensor's errors."""

import math

import numpy as np
import pytest

from navsim.flight.truth import ARRAY_FIELDS, Truth
from navsim.foundations import earth
from navsim.navigation.covariance import CovarianceAnalysis, SourceModel, _sensitivity
from navsim.navigation.estimators.error_model import Layout
from navsim.navigation.estimators.eskf import EpochSettings, ErrorStateKF
from navsim.navigation.estimators.measurements import GnssPosition, Velocity
from navsim.navigation.estimators.sins import FreeInertial
from navsim.navigation.strapdown import state_from_truth
from navsim.sensors.base import run_generators
from navsim.sensors.gnss import GnssSpec, emulate_gnss, linear_forms
from navsim.sensors.imu import AxisErrors, ImuSpec, _constants, _OFF_DIAGONAL, triad_linear
from navsim.sensors.registry import Motion

LAT, H, G = math.radians(30.0), 100.0, 9.7933


def _at_rest(duration_s: float, rate_hz: float = 100.0) -> Truth:
    """A level aircraft at rest, heading north: the body rate is the Earth's."""
    n = int(round(duration_s * rate_hz)) + 1
    w_ie = earth.OMEGA_IE_RPS * np.array([math.cos(LAT), 0.0, -math.sin(LAT)])
    data = {name: np.zeros(n) for name in ARRAY_FIELDS}
    data.update(t_s=np.arange(n) / rate_hz, lat_rad=np.full(n, LAT), h_m=np.full(n, H),
                vel_n_mps=np.zeros((n, 3)), quat_nb=np.tile([1.0, 0, 0, 0], (n, 1)), euler_rad=np.zeros((n, 3)),
                omega_ib_b_rps=np.tile(w_ie, (n, 1)), f_b_mps2=np.tile([0.0, 0.0, -G], (n, 1)),
                wind_n_mps=np.zeros((n, 3)), wind_steady_n_mps=np.zeros((n, 3)), segment=np.zeros(n, int))
    return Truth(**data, segment_labels=["rest"], meta={"rate_hz": rate_hz})


def _imu_sources(spec: ImuSpec, terms) -> list[SourceModel]:
    return [SourceModel(f"imu.{g}.{t}", "imu", triad_linear(g, t)(spec)) for g, t in terms]


def test_free_inertial_errors_grow_as_the_analytic_model():
    """At rest, 60 s: an accelerometer bias b gives b t^2 / 2 of position, a gyro bias e about
    east g e t^3 / 6 (Schuler's correction below 1e-3 there)."""
    truth = _at_rest(60.0)
    spec = ImuSpec(gyro=AxisErrors(bias_sigma=np.array([0.0, 1e-5, 0.0])),
                   accel=AxisErrors(bias_sigma=np.array([1e-3, 0.0, 0.0])))
    sources = _imu_sources(spec, [("accel", "bias_sigma"), ("gyro", "bias_sigma")])
    c = CovarianceAnalysis(truth, FreeInertial(1.0), 0.01, {}, {}).run(sources)
    t = c.t_s[-1]
    north = np.sqrt(c.var[:, -1, 6])
    assert north[0] == pytest.approx(1e-3 * t * t / 2, rel=2e-3)
    assert north[1] == pytest.approx(G * 1e-5 * t ** 3 / 6, rel=2e-3)
    assert np.sqrt(c.var[0, -1, 3]) == pytest.approx(1e-3 * t, rel=2e-3)      # velocity north
    assert np.sqrt(c.var[1, -1, 1]) == pytest.approx(1e-5 * t, rel=2e-3)      # tilt about east


#: the matched filters' layouts and the IMU terms of their truth: P3's 15 states (random-constant
#: biases), P2's 18 (a gyro constant, gyro and accelerometer Markov biases: fed back and decaying)
MATCHED = {"p3_15": (("att", "vel", "pos", "gyro_bias", "accel_bias"),
                     [(g, t) for g in ("gyro", "accel") for t in ("bias_sigma", "noise_density")]),
           "p2_18": (("att", "vel", "pos", "gyro_bias", "gyro_markov", "accel_markov"),
                     [("gyro", "bias_sigma"), ("gyro", "markov_sigma"), ("gyro", "noise_density"),
                      ("accel", "markov_sigma"), ("accel", "noise_density")])}


def _matched(truth, spec: ImuSpec, gnss: GnssSpec, sigma_nav: dict, states: str = "p3_15"):
    """An ES-KF whose model is the truth's, its GNSS data ideal, and the sources of the truth."""
    blocks, terms = MATCHED[states]
    est = ErrorStateKF.from_imu_spec(Layout(blocks), spec,
                                     [GnssPosition("gps", np.asarray(gnss.position_sigma)),
                                      Velocity("gps", np.asarray(gnss.velocity_sigma))],
                                     epochs=EpochSettings(series_order=8))
    ideal = emulate_gnss(truth, GnssSpec(rate_hz=gnss.rate_hz), 1, [0], name="gps")
    sources = _imu_sources(spec, terms)
    sources += [SourceModel(f"gps.{t}", "gps", linear_forms(t)(gnss)) for t in ("position_sigma", "velocity_sigma")]
    r_m, r_n = earth.radii(LAT)
    to_filter = np.r_[np.ones(6), 1 / (r_m + H), 1 / ((r_n + H) * math.cos(LAT)), 1.0]
    for i, block in enumerate(("att", "vel", "pos")):
        P0 = np.zeros((9, 9))
        P0[3 * i:3 * i + 3, 3 * i:3 * i + 3] = np.diag((sigma_nav[block] * to_filter[3 * i:3 * i + 3]) ** 2)
        sources.append(SourceModel(f"initial.{block}", P0_nav=P0))
    sigma0 = {k: v * to_filter[3 * i:3 * i + 3] for i, (k, v) in enumerate(sigma_nav.items())}
    return est, {"gps": ideal}, sources, {**sigma0, **est.noise_sigma0()}


@pytest.mark.parametrize("states", list(MATCHED))
def test_a_matched_filters_sources_add_up_to_its_own_covariance(states):
    """Truth model = filter model: the sources' variances add up to the filter's own P (its
    navigation block, NED metres), however the gains came out; with Markov biases fed back too
    (their compensation decaying as the filter's model has it)."""
    truth = _at_rest(120.0)
    markov = dict(markov_sigma=np.full(3, 2e-5), markov_tau_s=60.0)
    spec = ImuSpec(gyro=AxisErrors(bias_sigma=np.full(3, 1e-5), noise_density=np.full(3, 3e-5), **markov),
                   accel=AxisErrors(bias_sigma=np.full(3, 1e-3) if states == "p3_15" else np.zeros(3),
                                    noise_density=np.full(3, 1e-4),
                                    **(dict(markov_sigma=np.full(3, 3e-3), markov_tau_s=30.0) if states != "p3_15" else {})))
    if states == "p3_15":
        spec = ImuSpec(gyro=AxisErrors(bias_sigma=np.full(3, 1e-5), noise_density=np.full(3, 3e-5)), accel=spec.accel)
    gnss = GnssSpec(position_sigma=np.array([2.0, 2.0, 3.0]), velocity_sigma=np.full(3, 0.1))
    sigma_nav = {"att": np.radians([0.05, 0.05, 0.5]), "vel": np.full(3, 0.3), "pos": np.array([5.0, 5.0, 8.0])}
    est, sensors, sources, sigma0 = _matched(truth, spec, gnss, sigma_nav, states)
    c = CovarianceAnalysis(truth, est, 0.01, sensors, sigma0).run(sources)
    r_m, r_n = earth.radii(LAT)
    to_ned = np.r_[np.ones(6), r_m + H, (r_n + H) * math.cos(LAT), 1.0]
    own = np.diagonal(est.P[0, :9, :9]) * to_ned ** 2
    total = c.var[:, -1].sum(axis=0)
    np.testing.assert_allclose(total, own, rtol=1e-6)
    assert own[6] < 2.0 ** 2 and c.var[:, -1, 6].argmax() == [s.name for s in sources].index("gps.position_sigma")


def test_the_linear_forms_of_scale_factors_and_misalignments_are_the_emulators():
    """The coupling times the states is ``(I + M) x - x`` for the matrix the emulator draws."""
    x = np.array([0.3, -1.2, 9.5])
    motion = Motion(x, x)
    for field, states in (("misalignment_sigma", lambda m: m[[i for i, _ in _OFF_DIAGONAL], [j for _, j in _OFF_DIAGONAL]]),
                          ("scale_factor_sigma", lambda m: np.diagonal(m) - 1.0)):
        e = AxisErrors(**{field: 1e-3 if field == "misalignment_sigma" else np.full(3, 1e-3)})
        matrix, _ = _constants(lambda process: run_generators(4, [0, 1], "imu", process), 2, e)
        form = triad_linear("accel", field)(ImuSpec(accel=e))
        for m in matrix:
            np.testing.assert_allclose(form.coupling(motion) @ states(m), m @ x - x, rtol=1e-12, atol=1e-15)
        assert form.P0.shape == (form.n, form.n) and np.allclose(np.diag(form.P0), 1e-6)


def test_a_measurements_sensitivity_to_its_sensors_error():
    """INS minus sensor: an error of the fix enters ``z`` with minus one, in NED."""
    truth = _at_rest(3.0)
    data = emulate_gnss(truth, GnssSpec(), 1, [0], name="gps").measurements()
    nav = state_from_truth(truth, 100, 1)
    layout = Layout(("att", "vel", "pos"))
    D = _sensitivity(GnssPosition("gps", np.ones(3)), [nav, nav], layout, [(data, 1), (data, 2)], "pos_n")
    np.testing.assert_allclose(D, np.broadcast_to(-np.eye(3), (2, 3, 3)), atol=1e-6)
    D = _sensitivity(Velocity("gps", np.ones(3)), [nav], layout, [(data, 1)], "vel_n")
    np.testing.assert_allclose(D[0], -np.eye(3), atol=1e-12)
    assert not _sensitivity(Velocity("gps", np.ones(3)), [nav], layout, [(data, 1)], "pos_n").any()
