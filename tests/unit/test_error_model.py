"""The analytic error model against finite differences of the nonlinear SINS equations, and
every registered measurement type's H against finite differences of its ``z``."""

import dataclasses
import zlib

import numpy as np
import pytest
from model_result import unpack

from navsim.experiment.driver import Batch, run_batch
from navsim.experiment.runner import cached_flight
from navsim.experiment.scenario import load_scenario
from navsim.foundations import earth
from navsim.foundations.atmosphere import R_AIR
from navsim.foundations.config import Node
from navsim.foundations.transform import rotation, skew
from navsim.navigation.estimators import kalman
from navsim.navigation.estimators.error_model import BLOCK_SIZES, PRESETS, Layout, system_matrix
from navsim.navigation.estimators.eskf import _covariance_series_fits
from navsim.navigation.estimators.measurements import (
    GnssPosition,
    _own,
    build_measurements,
    compiled_form,
    measurement_class,
    measurement_types,
    parse_measurements,
)
from navsim.navigation.estimators.factory import build
from navsim.navigation.strapdown import NavState, rates_n
from navsim.sensors import emulate

LAYOUT = Layout(PRESETS["p3_15"])


def nominal():
    rng = np.random.default_rng(4)
    lat, lon, h = 0.65, 2.06, 350.0
    v = np.array([12.0, -7.0, 1.5])
    C = rotation(np.array([0.2, -0.1, 2.5]))
    omega_ib_b = rng.normal(size=3) * 0.2
    f_b = np.array([0.5, 0.3, -9.6])
    return lat, lon, h, v, C, omega_ib_b, f_b


def derivatives(lat, lon, h, v, C, omega_ib_b, f_b):
    w_ie, w_en, r_m, r_n = rates_n(np.array([lat]), np.array([h]), v[None])
    w_ie, w_en = w_ie[0], w_en[0]
    g = earth.gravity_n(lat, h)
    C_dot = C @ skew(omega_ib_b) - skew(w_ie + w_en) @ C
    v_dot = C @ f_b - np.cross(2 * w_ie + w_en, v) + g
    pos_dot = np.array([v[0] / (r_m[0] + h), v[1] / ((r_n[0] + h) * np.cos(lat)), -v[2]])
    return C_dot, v_dot, pos_dot


def error_rate(dx):
    """d/dt of the error state dx (estimate minus truth) at the nominal truth."""
    lat, lon, h, v, C, w, f = nominal()
    phi, dv, dp, dbg, dba = dx[0:3], dx[3:6], dx[6:9], dx[9:12], dx[12:15]
    C_est = rotation(-phi) @ C
    # the estimate sees the measured rate minus its bias estimate: true rate + residual bias
    Ct, vt, pt = derivatives(lat, lon, h, v, C, w, f)
    Ce, ve, pe = derivatives(lat + dp[0], lon + dp[1], h + dp[2], v + dv, C_est, w + dbg, f + dba)
    # C_est = exp(-[phi x]) C  =>  [phi_dot x] ~ -(C_est_dot - exp(-[phi x]) C_dot) C^T
    E = -(Ce - rotation(-phi) @ Ct) @ C.T
    phi_dot = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    return np.concatenate([phi_dot, ve - vt, pe - pt, np.zeros(6)])


def test_F_matches_finite_differences():
    lat, lon, h, v, C, w, f = nominal()
    F = system_matrix(LAYOUT, np.array([lat]), np.array([h]), v[None], C[None], (C @ f)[None])[0]
    steps = np.array([1e-6] * 3 + [1e-3] * 3 + [1e-8, 1e-8, 1e-2] + [1e-6] * 3 + [1e-4] * 3)
    J = np.column_stack([(error_rate(s * e) - error_rate(-s * e)) / (2 * s)
                         for s, e in zip(steps, np.eye(15))])
    # compare column by column, relative to the column's size
    for j in range(15):
        scale = max(np.abs(J[:, j]).max(), 1e-9)
        np.testing.assert_allclose(F[:, j], J[:, j], atol=1e-3 * scale + 1e-12,
                                   err_msg=f"column {LAYOUT.labels()[j]}")


def nav(lat, lon, h, v, C):
    return NavState(np.array([lat]), np.array([lon]), np.array([h]), v[None].copy(), C[None].copy())


class FakeData:
    def __init__(self, values, meta=None):
        self.values = {k: np.asarray(val)[None, None] for k, val in values.items()}
        self.valid = np.ones((1, 1), bool)
        self.meta = dict(meta or {})


#: an Earth field (NED, tesla) with a declination and an inclination
FIELD_N_T = np.array([2.2e-5, -0.4e-5, 4.5e-5])


def _air_data(v, C):
    """ADS values that agree with the nominal state in calm air: the air velocity's angles in
    the body, its speed, ISA pressure and temperature near 350 m."""
    u = C.T @ v / np.linalg.norm(v)
    return {"tas_mps": np.linalg.norm(v), "alpha_rad": np.arctan2(u[2], u[0]), "beta_rad": np.arcsin(u[1]),
            "p_static_pa": 97000.0, "temp_k": 286.0}


def sensor_values():
    """Every sensor value the cases read, agreeing with the nominal state (the linearisation
    point of a closed-loop filter), and the sensors' meta (the camera's anchor)."""
    lat, lon, h, v, C, _, _ = nominal()
    values = {"lat_rad": lat, "lon_rad": lon, "h_m": h, "vel_n_mps": v, "h_baro_m": h,
              "h_agl_m": h + 20.0,            # over a surface 20 m up: offset_m -20
              "mag_b_T": C.T @ FIELD_N_T, "landmark": 0, **_air_data(v, C)}
    meta = {"landmarks": [(np.degrees(lat) + 0.002, np.degrees(lon) - 0.003, 30.0)]}
    return values, meta


def _baro_error(values, b):
    """The barometer reading with an error ``b`` (sensor minus truth), m."""
    return {**values, "h_baro_m": values["h_baro_m"] + b[0]}


def _pitot_bias(values, b):
    """The ADS's airspeed with a dynamic-pressure bias ``b``, Pa: moved by ``b / (rho V)``."""
    rho_v = values["p_static_pa"] / (R_AIR * values["temp_k"]) * values["tas_mps"]
    return {**values, "tas_mps": values["tas_mps"] + b[0] / rho_v}


def _wind(axes):
    """The air data with a wind ``b`` more on ``axes`` (N, E; or D): the air velocity the
    values hold less the wind, seen in the body at the true attitude."""
    def move(values, b):
        C = nominal()[4]
        a, s, V = values["alpha_rad"], values["beta_rad"], values["tas_mps"]
        air_n = C @ np.array([np.cos(a) * np.cos(s), np.sin(s), np.sin(a) * np.cos(s)]) * V
        w = np.zeros(3)
        w[list(axes)] = b
        return {**values, **_air_data(air_n - w, C)}
    return move


@dataclasses.dataclass(frozen=True)
class FdCase:
    """One finite-difference case of a measurement type: a small valid scenario entry (its
    ``type`` aside), the filter's state blocks, and the sensor-error states the model observes,
    block -> how an error ``b`` of that state moves the sensor values (their columns are checked
    by perturbing the data; the navigation blocks by perturbing the INS state)."""

    id: str
    entry: dict
    blocks: tuple = PRESETS["p3_15"]
    sensor_errors: dict = dataclasses.field(default_factory=dict)


#: the scenario's sensors the cases name (name -> kind, what ``parse`` checks the entries against)
FD_SENSORS = {"gps": "gnss", "baro": "baro", "radar": "radar_altimeter", "ads": "ads", "camera": "camera",
              "mag": "magnetometer"}
_VANES = {"sensor": "ads", "model": "p0_ads", "override": {"velocity_axis": "air", "vane_noise": "0.6 deg"}}
#: every registered measurement type's cases; a type without one fails
#: :func:`test_H_matches_finite_differences`. ``mag_heading`` is tested with ``calibration: none``:
#: the online calibration (tested in test_magcal.py) only changes the sample its H is taken of,
#: and needs a calibration manoeuvre before it is valid.
FD_CASES = {
    "air_velocity": [FdCase("vanes", _VANES),
                     FdCase("no_vanes", {"sensor": "ads", "model": "p0_ads", "angle_sigma_deg": 4.0}),
                     FdCase("pitot_bias", _VANES, PRESETS["p3_15"] + ("pitot_bias",), {"pitot_bias": _pitot_bias}),
                     FdCase("wind", {**_VANES, "turbulence_sigma_mps": 1.5}, PRESETS["p3_15"] + ("wind", "wind_down"),
                            {"wind": _wind((0, 1)), "wind_down": _wind((2,))}),
                     FdCase("wind_gust", {**_VANES, "turbulence_sigma_mps": 1.5},
                            PRESETS["p3_15"] + ("wind", "gust", "gust_down"),
                            {"wind": _wind((0, 1)), "gust": _wind((0, 1)), "gust_down": _wind((2,))})],
    "gnss_horizontal": [FdCase("", {"sensor": "gps", "sigma_m": [1.0, 2.0, 3.0]})],
    "gnss_position": [FdCase("", {"sensor": "gps", "sigma_m": [1.0, 2.0, 3.0]})],
    "height": [FdCase("baro", {"sensor": "baro", "sigma_m": 1.0}),
               FdCase("baro_state", {"sensor": "baro", "sigma_m": 1.0, "baro_state": True}, PRESETS["p0_16"],
                      {"baro": _baro_error}),
               FdCase("radar_offset", {"sensor": "radar", "sigma_m": 0.3, "offset_m": -20.0})],
    "landmark": [FdCase("", {"sensor": "camera", "sigma_m": 3.0, "ratio": 0.01})],
    "mag_heading": [FdCase("", {"sensor": "mag", "sigma_deg": 1.0, "calibration": "none",
                                "field_uT": [float(x) for x in FIELD_N_T * 1e6]})],
    "velocity": [FdCase("", {"sensor": "gps", "sigma_mps": [0.1, 0.1, 0.2]})],
    "zero_velocity": [FdCase("horizontal", {"sensor": "gps", "sigma_mps": [0.05, 0.05, 0.1]}),
                      FdCase("ned", {"sensor": "gps", "sigma_mps": [0.05, 0.05, 0.1], "axes": "ned"})],
}
#: the finite-difference step of each state block's components
FD_STEPS = {"att": [1e-6] * 3, "vel": [1e-3] * 3, "pos": [1e-8, 1e-8, 1e-2], "baro": [1e-2], "pitot_bias": [0.5],
            "wind": [1e-3] * 2, "wind_down": [1e-3], "gust": [1e-3] * 2, "gust_down": [1e-3]}


def _fd_params():
    out = []
    for mtype in measurement_types():
        cases = FD_CASES.get(mtype) or [None]
        out += [pytest.param(mtype, c, id=mtype if c is None or not c.id else f"{mtype}-{c.id}") for c in cases]
    return out


def _model_of(mtype: str, case: FdCase):
    """The model of ``case``'s entry, read and built as a scenario's (``parse``, ``from_entry``)."""
    node = Node({"measurements": [{"type": mtype, **case.entry}]}, "estimators[0]", "fd_case.yaml")
    entries = parse_measurements(node, FD_SENSORS)
    return entries[0], build_measurements(entries)[0]


@pytest.mark.parametrize("mtype, case", _fd_params())
def test_H_matches_finite_differences(mtype, case):
    """Every registered measurement type's H against central differences of its ``z``: the
    navigation blocks by moving the INS state, the sensor-error blocks by moving the sensor
    values, every other column zero."""
    if case is None:
        pytest.fail(f"no finite-difference case for measurement type '{mtype}': add one to FD_CASES "
                    "in tests/unit/test_error_model.py")
    lat, lon, h, v, C, _, _ = nominal()
    values, meta = sensor_values()
    entry, model = _model_of(mtype, case)
    reads = getattr(measurement_class(mtype), "reads", None)
    assert reads is None or set(reads(entry)) <= set(values), reads(entry)
    layout = Layout(case.blocks)
    steps = np.concatenate([FD_STEPS.get(b, [1e-6] * BLOCK_SIZES[b]) for b in layout.blocks])

    def z_of(dx):
        att, dv, dp = (dx[layout.slice(b)] for b in ("att", "vel", "pos"))
        moved = values
        for block, move in case.sensor_errors.items():
            moved = move(moved, dx[layout.slice(block)])
        state = nav(lat + dp[0], lon + dp[1], h + dp[2], v + dv, rotation(-att) @ C)
        return unpack(model.model(state, layout, FakeData(moved, meta), 0))[0][0]

    _, H, R, valid = unpack(model.model(nav(lat, lon, h, v, C), layout, FakeData(values, meta), 0))
    assert H.shape[0] == 1 and H.shape[2] == layout.n, H.shape
    J = np.column_stack([(z_of(s * e) - z_of(-s * e)) / (2 * s) for s, e in zip(steps, np.eye(layout.n))])
    for j, label in enumerate(layout.labels()):
        np.testing.assert_allclose(H[0][:, j], J[:, j], rtol=1e-5, atol=1e-6, err_msg=f"{mtype}: column {label}")
    m = H.shape[1]
    assert (valid is None or np.all(valid)) and R.shape == (1, m, m)
    assert np.allclose(R[0], R[0].T) and np.all(np.linalg.eigvalsh(R[0]) > 0), R[0]


@pytest.mark.parametrize("blocks, white", [((), [1, 1, 1]), (("gust",), [0, 0, 1]),
                                           (("gust", "gust_down"), [0, 0, 0])])
def test_a_gust_state_takes_the_gusts_out_of_R(blocks, white):
    """The air-velocity R with ``turbulence_sigma_mps`` less R without it: the gusts' variance
    on every axis no gust state carries (N, E: ``gust``; D: ``gust_down``), nothing elsewhere."""
    lat, lon, h, v, C, _, _ = nominal()
    values, meta = sensor_values()
    layout = Layout(PRESETS["p3_15"] + ("wind",) + blocks)
    R = [unpack(_model_of("air_velocity", FdCase("", {**_VANES, "turbulence_sigma_mps": t}))[1].model(
         nav(lat, lon, h, v, C), layout, FakeData(values, meta), 0))[2][0] for t in (0.0, 2.0)]
    np.testing.assert_allclose(R[1] - R[0], 4.0 * np.diag(white), atol=1e-12)


class BatchData:
    """Sensor data of ``B`` runs, two samples each (the model reads sample 1)."""

    def __init__(self, values, meta=None):
        self.values = {k: np.asarray(v) for k, v in values.items()}
        self.valid = np.ones((len(next(iter(values.values()))), 2), bool)
        self.valid[::3, 1] = False
        self.meta = dict(meta or {})


def _batch_case(rng, B: int = 7):
    """``B`` INS states scattered about the nominal one (attitude by up to 0.3 rad, velocity by
    3 m/s, position by 100 m) and sensor values of each, 2 samples per run."""
    lat, lon, h, v, C, _, _ = nominal()
    values, meta = sensor_values()
    C_b = np.stack([rotation(rng.normal(0, 0.1, 3)) @ C for _ in range(B)])
    state = NavState(lat + rng.normal(0, 1e-5, B), lon + rng.normal(0, 1e-5, B), h + rng.normal(0, 100.0, B),
                     v + rng.normal(0, 3.0, (B, 3)), C_b)
    batch = {}
    for k, x in values.items():
        x = np.broadcast_to(np.asarray(x), (B,) + np.shape(x))
        if x.dtype.kind == "f":          # lat, lon by 1e-5 rad, the others by 1 %
            x = x + (rng.normal(0, 1e-5, x.shape) if k in ("lat_rad", "lon_rad")
                     else rng.normal(0, 0.01, x.shape) * np.abs(x))
        batch[k] = np.stack([x, x], 1)
    return state, BatchData(batch, meta)


@pytest.mark.parametrize("mtype, case", _fd_params())
def test_every_compiled_model_equals_its_python_model(mtype, case):
    """The compiled form of every shipped measurement type (``compiled(layout)``, filled for
    all runs in one call) gives the Python model's ``z``, ``H``, ``R`` and valid runs to 1e-12
    (of each matrix's largest entry), for a batch of scattered INS states and samples, some
    runs without a sample; its rows are placed at their offset in the stacked arrays."""
    if case is None:
        pytest.skip("no case (test_H_matches_finite_differences fails for it)")
    entry, model = _model_of(mtype, case)
    if not model.__module__.startswith("navsim.navigation.estimators.measurements."):
        pytest.skip("not a shipped type")
    rng = np.random.default_rng(zlib.crc32((mtype + case.id).encode()))
    state, data = _batch_case(rng)
    layout = Layout(case.blocks)
    lin = model.model(state, layout, data, 1)
    form = compiled_form(_model_of(mtype, case)[1], layout)
    assert form is not None, f"{mtype} has no compiled form"
    B, m, r0 = state.lat_rad.shape[0], lin.H.shape[1], 2
    z, H, R = np.zeros((B, m + 3)), np.zeros((B, m + 3, layout.n)), np.zeros((B, m + 3, m + 3))
    valid = form.fill(state, data, 1, r0, z, H, R)
    assert form.rows == m
    rows = slice(r0, r0 + m)
    for got, want in ((z[:, rows], lin.z), (H[:, rows], lin.H), (R[:, rows, rows], lin.R)):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())
    np.testing.assert_array_equal(valid, np.ones(B, bool) if lin.valid is None else lin.valid)
    assert not z[:, :r0].any() and not H[:, :r0].any() and not R[:, :r0].any()


def test_the_filter_with_compiled_models_equals_the_python_models(repo_root):
    """P0's matched-ADS ES-KF (GNSS position, air velocity with vanes and a pitot-bias state,
    height with a baro state) over 60 s of 3 runs: the state and covariance with the compiled
    models equal those with the Python models to 1e-12 of each diagonal's scale."""
    scenario = load_scenario(repo_root / "scenarios" / "p0_matched_ads.yaml")
    truth = cached_flight(scenario.flight)[0].slice(0, 6001)
    data = {c.name: emulate(truth, c, scenario.seed, range(3)) for c in scenario.sensors}
    imu = data.pop(next(c.name for c in scenario.sensors if c.kind == "imu"))
    spec = next(e for e in scenario.estimators if e.type == "eskf")
    out = []
    for compiled in (True, False):
        est = build(spec)
        est.compiled_models = compiled
        run_batch(truth, imu, data, {spec.label: est}, Batch(scenario.initial, scenario.seed, range(3)))
        out.append((est.x.copy(), est.P.copy()))
    scale = np.sqrt(np.diagonal(out[1][1], axis1=1, axis2=2))
    np.testing.assert_allclose(out[0][0] / scale, out[1][0] / scale, rtol=0, atol=1e-12)
    np.testing.assert_allclose(out[0][1] / (scale[:, :, None] * scale[:, None, :]),
                               out[1][1] / (scale[:, :, None] * scale[:, None, :]), rtol=0, atol=1e-12)


def test_every_finite_difference_case_is_a_registered_type():
    assert set(FD_CASES) <= set(measurement_types()), set(FD_CASES) - set(measurement_types())


def test_series_and_van_loan_agree():
    lat, lon, h, v, C, w, f = nominal()
    F = system_matrix(LAYOUT, np.array([lat] * 2), np.array([h] * 2), np.stack([v, -v]), np.stack([C, C.T]),
                      np.stack([C @ f, f]))
    Qc = np.diag(np.r_[np.full(3, 1e-8), np.full(3, 1e-6), np.zeros(9)])
    P1, Q1 = kalman.discretize_series(F, Qc, 1.0, order=3)
    P2, Q2 = kalman.discretize_van_loan(F, Qc, 1.0)
    # third order over 1 s: the truncation is O((|F| T)^4 / 24)
    np.testing.assert_allclose(P1, P2, rtol=1e-2, atol=1e-6)
    # the noise reaches the position through attitude and velocity: four integrations, so the
    # third-order series misses part of Qd over 1 s; the sixth order has it
    _, Q6 = kalman.discretize_series(F, Qc, 1.0, order=6)
    for b in range(2):          # correlation-scaled, on the driven (navigation) states
        d = np.sqrt(np.diag(Q2[b]))[:9]
        np.testing.assert_allclose(Q6[b][:9, :9] / np.outer(d, d), Q2[b][:9, :9] / np.outer(d, d), atol=2e-3)
    P8, Q8 = kalman.discretize_series(F, Qc, 1.0, order=8)
    np.testing.assert_allclose(P8, P2, atol=1e-9)


def _random_covariance(rng, sigma):
    A = rng.normal(size=(len(sigma), len(sigma))) * 0.3 + np.eye(len(sigma))
    C = A @ A.T
    d = np.sqrt(np.diag(C))
    return C / np.outer(d, d) * np.outer(sigma, sigma)


def test_covariance_series_is_the_exact_discretised_predict():
    """``propagate_in_place`` (the covariance equation's Taylor series) against Van Loan's exact
    ``Phi P Phi^T + Qd`` over 1 s, on P0's 16 states (the baro Markov decay included)."""
    layout = Layout(PRESETS["p0_16"])
    lat, lon, h, v, C, w, f = nominal()
    F = system_matrix(layout, np.array([lat] * 2), np.array([h] * 2), np.stack([v, -v]), np.stack([C, C.T]),
                      np.stack([C @ f, f]))
    F[:, 15, 15] = -1.0 / 600.0
    Qc = np.diag(np.r_[np.full(3, 1e-12), np.full(3, 1e-6), np.zeros(3), np.full(6, 1e-14), 0.03])
    rng = np.random.default_rng(11)
    sigma = np.r_[np.full(3, 1e-4), np.full(3, 0.1), 1e-6, 1e-6, 5.0, np.full(3, 1e-6), np.full(3, 1e-3), 3.0]
    P0 = np.stack([_random_covariance(rng, sigma) for _ in range(2)])
    x0 = rng.normal(size=(2, 16)) * sigma
    Phi, Qd = kalman.discretize_van_loan(F, Qc, 1.0)
    exact_P = Phi @ P0 @ np.swapaxes(Phi, -1, -2) + Qd
    exact_x = (Phi @ x0[..., None])[..., 0]
    scale = np.sqrt(np.einsum("bii->bi", exact_P))
    errors = {}
    for order in (3, 6, 8):
        x, P = x0.copy(), P0.copy()
        kalman.propagate_in_place(x, P, F, Qc, 1.0, order)
        assert np.array_equal(P, np.swapaxes(P, -1, -2))
        errors[order] = np.abs((P - exact_P) / (scale[:, :, None] * scale[:, None, :])).max()
        np.testing.assert_allclose(x / sigma, exact_x / sigma, atol=1e-6 if order == 3 else 1e-12)
    assert errors[3] > 1e-9            # the order is honoured: third order truncates visibly
    assert errors[6] < 1e-12 and errors[8] < 1e-12
    # the same as the series' Phi and Qd, then predict
    Phi6, Qd6 = kalman.discretize_series(F, Qc, 1.0, order=8)
    _, P_series = kalman.predict(x0, P0, Phi6, Qd6)
    x, P = x0.copy(), P0.copy()
    kalman.propagate_in_place(x, P, F, Qc, 1.0, 8)
    np.testing.assert_allclose(P / (scale[:, :, None] * scale[:, None, :]),
                               P_series / (scale[:, :, None] * scale[:, None, :]), atol=1e-13)


def test_updates_in_turn_in_one_call_equal_single_updates():
    rng = np.random.default_rng(12)
    P = np.stack([_random_covariance(rng, np.linspace(0.5, 3.0, 6)) for _ in range(3)])
    x = rng.normal(size=(3, 6))
    first = (rng.normal(size=(3, 2)), rng.normal(size=(3, 2, 6)), np.broadcast_to(np.diag([0.5, 2.0]), (3, 2, 2)),
             np.array([True, False, True]))
    second = (rng.normal(size=(3, 1)), rng.normal(size=(3, 1, 6)), np.full((3, 1, 1), 0.3), None)
    x1, P1, y1, S1, nis1 = kalman.update(x, P, *first)
    x2, P2, y2, S2, nis2 = kalman.update(x1, P1, *second)
    xi, Pi = x.copy(), P.copy()
    u = kalman.update_in_place(xi, Pi, [first, second])
    np.testing.assert_allclose(xi, x2, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Pi, P2, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(u.y[0], y1, rtol=1e-12)
    np.testing.assert_allclose(u.S[1], S2, rtol=1e-12)
    np.testing.assert_allclose(u.nis[0], nis1, rtol=1e-12)
    assert np.isnan(u.nis[0][1]) and not u.bad.any()
    # a run whose S is singular is spoiled and flagged alone
    singular = (np.zeros((3, 1)), np.zeros((3, 1, 6)), np.zeros((3, 1, 1)), np.array([False, True, False]))
    xi, Pi = x.copy(), P.copy()
    u = kalman.update_in_place(xi, Pi, [singular, second])
    assert u.bad.tolist() == [False, True, False] and np.isnan(Pi[1]).all()
    np.testing.assert_allclose(Pi[[0, 2]], kalman.update(x, P, *second)[1][[0, 2]], rtol=1e-12)


def test_joseph_update_is_the_optimal_update_and_keeps_P_psd():
    rng = np.random.default_rng(7)
    A = rng.normal(size=(4, 6, 6))
    P = A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(6)
    H = rng.normal(size=(4, 2, 6))
    R = np.broadcast_to(np.diag([0.5, 2.0]), (4, 2, 2))
    x = rng.normal(size=(4, 6))
    z = rng.normal(size=(4, 2))
    x1, P1, y, S, nis = kalman.update(x, P, z, H, R)
    K = P @ np.swapaxes(H, -1, -2) @ np.linalg.inv(S)
    np.testing.assert_allclose(P1, P - K @ H @ P, atol=1e-9)
    np.testing.assert_allclose(x1, x + (K @ y[..., None])[..., 0], atol=1e-12)
    assert np.all(np.linalg.eigvalsh(P1) > 0)
    np.testing.assert_allclose(nis, np.einsum("bi,bij,bj->b", y, np.linalg.inv(S), y))
    valid = np.array([True, False, True, False])
    x2, P2, _, _, nis2 = kalman.update(x, P, z, H, R, valid)
    assert np.array_equal(x2[1], x[1]) and np.array_equal(P2[3], P[3]) and np.isnan(nis2[1])


def test_the_filter_falls_back_to_phi_p_phi_where_the_covariance_series_would_not_hold():
    """Below order 6, or with a state decaying faster than 5 % per period, the ES-KF predicts
    with the series' Phi and Qd (P3's third order keeps its numbers); from order 6 on slow
    states, with the covariance's own series."""
    layout = Layout(PRESETS["p0_16"])
    lat, lon, h, v, C, w, f = nominal()
    F = system_matrix(layout, np.array([lat]), np.array([h]), v[None], C[None], (C @ f)[None])
    F[:, 15, 15] = -1.0 / 600.0
    assert _covariance_series_fits(F, 1.0, 6) and not _covariance_series_fits(F, 1.0, 3)
    F[:, 15, 15] = -1.0                                  # a 1 s Markov state over a 1 s period
    assert not _covariance_series_fits(F, 1.0, 6)


def test_the_bias_sigma_is_the_sigma_of_the_estimated_sum():
    """P2's gyro bias estimate is its constant plus its Markov part: the sigma reported is that
    of the sum, their cross-covariance included (``T P T^T`` with ``T = [I I]``)."""
    from navsim.navigation.estimators.eskf import ErrorStateKF
    layout = Layout(PRESETS["p2_18"])
    A = np.random.default_rng(1).normal(size=(2, 18, 18))
    P = A @ np.swapaxes(A, 1, 2)
    holder = type("Holder", (), {"layout": layout, "P": P})()
    gyro, accel = ErrorStateKF._bias_sigma(holder)
    T = np.zeros((3, 18))
    T[:, layout.slice("gyro_bias")] = T[:, layout.slice("gyro_markov")] = np.eye(3)
    np.testing.assert_allclose(gyro, np.sqrt(np.diagonal(T @ P @ T.T, axis1=1, axis2=2)), rtol=1e-12)
    T = np.zeros((3, 18))
    T[:, layout.slice("accel_markov")] = np.eye(3)             # no constant accelerometer block in p2_18
    np.testing.assert_allclose(accel, np.sqrt(np.diagonal(T @ P @ T.T, axis1=1, axis2=2)), rtol=1e-12)


def test_a_subclass_that_changes_the_model_inherits_no_compiled_form_nor_reads():
    """A plug-in subclassing a shipped type with its own ``model`` is evaluated by that model
    (its parent's kernel would compute the parent's) and its sensor's values are all kept in
    double (its parent's ``reads`` need not cover what it reads); one that keeps the model
    keeps both."""
    class Scaled(GnssPosition):
        def model(self, nav, layout, data, j):
            lin = super().model(nav, layout, data, j)
            return dataclasses.replace(lin, z=2.0 * lin.z)

    class Same(GnssPosition):
        pass

    layout = Layout(PRESETS["p3_15"])
    assert compiled_form(Scaled("gps", np.ones(3)), layout) is None
    assert compiled_form(Same("gps", np.ones(3)), layout) is not None
    assert _own(Scaled, "reads") is None and _own(Same, "reads") is not None
