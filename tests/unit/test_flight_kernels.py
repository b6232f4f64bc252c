"""The compiled autopilot, segments and watchdog (navsim.flight.autopilot, .segments, .fleet)
against the scalar Python they replaced (tests/reference_flight.py), bit for bit: a closed loop
amplifies any difference in the last bit into a different flight. And CPython's float arithmetic
in numba (navsim.foundations.pymath) against CPython's own."""

import math

import numpy as np
import pytest

from navsim.flight import FlightConfig, load_track
from navsim.flight import properties as P
from navsim.flight import segments
from navsim.flight.autopilot import AP_FIELDS, Autopilot, Sensed
from navsim.flight.fleet import Watchdog
from navsim.flight.segments import State
from navsim.flight.simulator import load_limits
from navsim.flight.track import Segment
from navsim.foundations.errors import FlightError
from navsim.foundations.pymath import py_hypot, py_pow
from tests import reference_flight as ref

DT = 0.01


def test_py_hypot_and_py_pow_round_as_cpython():
    rng = np.random.default_rng(3)
    for scale in (1e-3, 1.0, 30.0, 1e5, 1e200):
        x, y = rng.normal(0, scale, 20000), rng.normal(0, scale, 20000) * rng.choice([1e-6, 1.0, 1e3], 20000)
        assert [py_hypot(a, b) for a, b in zip(x, y)] == [math.hypot(a, b) for a, b in zip(x, y)]
    special = [0.0, -0.0, math.inf, -math.inf, 5e-324, 2.2250738585072014e-308, 1e308, -3.0]
    for a in special + [math.nan]:
        for b in special + [math.nan]:
            want, got = math.hypot(a, b), py_hypot(a, b)
            assert got == want or (math.isnan(want) and math.isnan(got)), (a, b)
    base, two = rng.uniform(0.2, 5.0, 20000), np.array([2.0])
    assert [py_pow(v, two) for v in base] == [v ** 2.0 for v in base]
    # the reason py_pow exists: x * x rounds otherwise for some of these
    assert any(v * v != v ** 2.0 for v in base)


def _random_autopilots(rng, n):
    """Pairs (reference, compiled) of autopilots in the same random state."""
    pairs = []
    for _ in range(n):
        old, new = ref.Autopilot(), Autopilot()
        values = dict(speed_cmd=rng.uniform(10, 20), alt_cmd=rng.uniform(50, 300),
                      climb_rate=rng.choice([0.0, rng.uniform(0.5, 3.0)]), course_cmd=rng.uniform(-4, 4),
                      bank_ff=rng.uniform(-0.3, 0.3), i_speed=rng.uniform(-0.2, 1.2), i_climb=rng.uniform(-0.2, 0.2),
                      i_pitch=rng.uniform(-0.5, 0.5), i_roll=rng.uniform(-0.5, 0.5), i_beta=rng.uniform(-0.2, 0.2),
                      idle=bool(rng.integers(2)),
                      pitch_hold=None if rng.random() < 0.7 else rng.uniform(-0.3, 0.5),
                      throttle_hold=None if rng.random() < 0.7 else rng.uniform(0, 1))
        for k, v in values.items():
            setattr(old, k, v)
            setattr(new, k, v)
        pairs.append((old, new))
    return pairs


def test_autopilot_kernel_steps_as_the_python_one():
    rng = np.random.default_rng(11)
    for old, new in _random_autopilots(rng, 60):
        for _ in range(150):
            s = Sensed(tas=rng.uniform(3, 30), h=rng.uniform(0, 400), climb=rng.normal(0, 3), roll=rng.normal(0, 0.6),
                       pitch=rng.normal(0, 0.4), p=rng.normal(0, 1), q=rng.normal(0, 1), beta=rng.normal(0, 0.1),
                       course=rng.uniform(-7, 7))
            assert new.step(DT, s) == old.step(DT, s)
            assert [getattr(new, k) for k in AP_FIELDS] == [getattr(old, k) for k in AP_FIELDS]


def _kinematics(s: State, ap, dt: float) -> None:
    """A point mass that follows the autopilot's commands with lags (the same for both runners)."""
    err = (ap.course_cmd - s.course + math.pi) % (2 * math.pi) - math.pi
    s.course += 0.8 * err * dt + 0.2 * ap.bank_ff * dt
    s.tas += 0.5 * (ap.speed_cmd - s.tas) * dt
    s.ground_speed = s.tas + 0.3 * math.sin(0.05 * s.t)
    rate = ap.climb_rate if ap.climb_rate > 0 else 3.0
    s.h += min(max(0.3 * (ap.alt_cmd - s.h), -rate), rate) * dt
    s.north += s.ground_speed * math.cos(s.course) * dt
    s.east += s.ground_speed * math.sin(s.course) * dt
    s.t += dt


TRACK = [Segment("straight", "a", {"time_s": 4.0}), Segment("speed", "b", {"to_mps": 16.0, "accel_mps2": 1.0}),
         Segment("climb", "c", {"to_m": 130.0, "rate_mps": 2.0}, speed_mps=15.0),
         Segment("turn", "d", {"by_deg": -90.0, "bank_deg": 25.0}), Segment("straight", "e", {"distance_m": 60.0}),
         Segment("circle", "f", {"radius_m": 60.0, "laps": 0.5, "direction": "right"}),
         Segment("turn", "g", {"by_deg": 45.0, "rate_dps": 10.0}),
         Segment("descend", "h", {"to_m": 110.0, "rate_mps": 1.5}),
         Segment("circle", "i", {"radius_m": 70.0, "time_s": 5.0, "direction": "left"}),
         Segment("goto", "j", {"north_m": 100.0, "east_m": -150.0, "acceptance_m": 5.0, "alt_m": 120.0}),
         Segment("goto", "k", {"lat_deg": 30.0005, "lon_deg": 120.0, "acceptance_m": 0.0}),
         Segment("straight", "l", {"until_s": 140.0})]


def _runner(module, ap_cls, segments):
    limits = load_limits(FlightConfig(track=load_track("p0")))
    k_n, k_e = 6.37e6, 5.5e6
    local = lambda lat, lon: ((lat - math.radians(30.0)) * k_n, (lon - math.radians(120.0)) * k_e)
    ap = ap_cls()
    ap.speed_cmd, ap.course_cmd, ap.alt_cmd = 14.0, 0.3, 100.0
    runner = module.SegmentRunner(segments, ap, limits, local)
    runner.course_ref, runner.speed_target = 0.3, 14.0
    return runner


def _fly_segments(module, ap_cls, segments, steps):
    """The runner's commands and segment index at every step of the point mass, and how it ended."""
    runner = _runner(module, ap_cls, segments)
    s = State(h=100.0, tas=14.0, ground_speed=14.0, course=0.3)
    out = []
    for _ in range(steps):
        try:
            if runner.index < 0:
                runner.next(s)
            if runner.finished:
                return out, "flown"
            runner.update(s, DT)
        except FlightError as exc:
            return out, str(exc)
        ap = runner.ap
        out.append((runner.index, ap.course_cmd, ap.bank_ff, ap.speed_cmd, ap.alt_cmd, ap.climb_rate, runner.line))
        _kinematics(s, ap, DT)
    return out, "steps"


def test_segment_kernel_flies_every_kind_as_the_python_one():
    old, how_old = _fly_segments(ref, ref.Autopilot, TRACK, 20000)
    new, how_new = _fly_segments(segments, Autopilot, TRACK, 20000)
    assert how_new == how_old == "flown" and len(new) == len(old)
    assert set(range(len(TRACK))) <= {step[0] for step in new}        # every segment flown
    assert new == old


@pytest.mark.parametrize("segment", [Segment("straight", "x", {"time_s": 1000.0}),
                                     Segment("climb", "y", {"to_m": 900.0, "rate_mps": 0.5})])
def test_segment_time_outs_raise_alike(segment):
    short = [segment]
    runner_old, runner_new = _runner(ref, ref.Autopilot, short), _runner(segments, Autopilot, short)
    s = State(h=100.0, tas=14.0, ground_speed=14.0, course=0.3)
    for r in (runner_old, runner_new):
        r.next(s)
        r.timeout = 0.5
    late = State(t=0.6, h=100.0, tas=14.0, ground_speed=14.0, course=0.3)
    with pytest.raises(FlightError) as e_old:
        runner_old.update(late, DT)
    with pytest.raises(FlightError) as e_new:
        runner_new.update(late, DT)
    assert str(e_new.value) == str(e_old.value)


def test_watchdog_kernel_fails_as_the_python_one():
    limits = load_limits(FlightConfig(track=load_track("p0")))
    rng = np.random.default_rng(5)
    old, new = ref.Watchdog(limits, DT), Watchdog(limits, DT)
    row = np.zeros(len(P.RAW_PROPERTIES))
    seen = set()
    for k in range(30000):
        row[:] = rng.normal(0, 1, row.size)
        row[P.COL_H], row[P.COL_TAS], row[P.COL_HAGL] = 100.0, 14.0 + rng.normal(0, 3), 50.0
        row[P.COL_ROLL], row[P.COL_PITCH] = rng.normal(0, 0.5), rng.normal(0, 0.3)
        row[P.COL_ALPHA] = rng.normal(0.2, 0.05)
        row[P.COL_WSN], row[P.COL_WSE] = rng.normal(0, 10), rng.normal(0, 10)
        if 5000 <= k < 5200:                     # a stall: alpha high for two seconds, nothing else
            row[P.COL_ALPHA], row[P.COL_ROLL], row[P.COL_PITCH], row[P.COL_WSN] = 0.6, 0.0, 0.0, 0.0
        if k % 997 == 0:
            row[P.COL_HAGL] = 0.2
        if k % 1499 == 0:
            row[P.COL_TAS] = math.nan
        ground_ok, stall_ok = bool(k % 7 == 0), bool(k % 11 == 0) and not 5000 <= k < 5200
        reason = new.check(row.tolist(), ground_ok, stall_ok)
        assert reason == old.check(row.tolist(), ground_ok, stall_ok)
        seen.add(reason.split(" ")[0] if reason else None)
    assert {None, "the", "ground", "stall", "loss"} <= seen


class NumpyOnlineIncrements:
    """The numpy form of :class:`navsim.sensors.imu.OnlineIncrements` (as it was before it was
    compiled): the reference its kernel is held to."""

    def __init__(self, B, dt):
        self.dt, self.j = dt, 0
        self.dth_prev, self.dvc_prev = np.zeros((B, 3)), np.zeros((B, 3))

    def update(self, omega, f_b):
        from navsim.foundations.transform import cross, rotation
        j, dt = self.j, self.dt
        omega, f_b = np.array(omega, float), np.array(f_b, float)
        if j == 0:
            self.om, self.f = [omega] * 3, [f_b] * 3
            eye = np.broadcast_to(np.eye(3), omega.shape + (3,))
            self.R = [eye, eye]
            dth, dv_c = np.zeros_like(omega), np.zeros_like(f_b)
            dv_m = dv_c
        else:
            om, f = self.om, self.f
            dth = (23 * om[0] - 16 * om[1] + 5 * om[2]) / 12.0 * dt
            if j == 1:
                dv_c = f[0] * dt
            else:
                R1, R2 = self.R
                f_km1 = np.einsum("bij,bj->bi", R1, f[1])
                f_km2 = np.einsum("bij,bj->bi", R1, np.einsum("bij,bj->bi", R2, f[2]) if j > 2 else f[2])
                dv_c = dt * (23 * f[0] - 16 * f_km1 + 5 * f_km2) / 12.0
            dv_m = dv_c - 0.5 * cross(dth, dv_c) - (cross(self.dth_prev, dv_c) + cross(self.dvc_prev, dth)) / 12.0
        self.R = [rotation(-dth), self.R[0]]
        self.om, self.f = [omega, self.om[0], self.om[1]], [f_b, self.f[0], self.f[1]]
        self.dth_prev, self.dvc_prev = dth, dv_c
        self.j += 1
        return dth, dv_m


def test_online_increments_kernel_equals_its_numpy_form_and_measures_as_numpy():
    from navsim.sensors.imu import OnlineIncrements
    from navsim.sensors.kernels import measured_increments
    rng = np.random.default_rng(7)
    B, dt = 5, 0.01
    ref_inc, inc = NumpyOnlineIncrements(B, dt), OnlineIncrements(B, dt)
    M = np.eye(3) + rng.normal(0, 1e-3, (2, B, 3, 3))
    q = np.array([1e-4 * dt, 0.0])                 # a gyro quantum, an accelerometer without one
    out = np.zeros((B, 2, 3))
    for j in range(3000):
        omega = rng.normal(0, 0.4, (B, 3)) * (8.0 if j % 300 == 5 else 1.0)   # some steps above 0.05 rad
        f_b = rng.normal(0, 2, (B, 3)) + [0.0, 0.0, -9.8]
        want, got = ref_inc.update(omega, f_b), inc.update(omega, f_b)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
        err = rng.normal(0, 1e-5, (2, B, 3))
        measured_increments(inc.out, M[0], M[1], err[0], err[1], q, out)
        mv = lambda A, v: A[:, :, 0] * v[:, None, 0] + A[:, :, 1] * v[:, None, 1] + A[:, :, 2] * v[:, None, 2]
        gyro = mv(M[0], want[0]) + err[0]
        assert np.array_equal(out[:, 0], np.round(gyro / q[0]) * q[0])
        assert np.array_equal(out[:, 1], mv(M[1], want[1]) + err[1])
