"""The multirotor controller (:mod:`navsim.flight.multirotor`) alone and flying the jsbsim wheel's
F450 quadrotor.

The F450 is read from the wheel's own aircraft folder: its rotors from ``Propulsion.xml`` (each
thruster's location, orientation and ``<sense>``; the propeller file's static C_T, C_P and
diameter give the torque per thrust), its mass and inertia from JSBSim. Its flight control
system has a rate loop (``fcs/ScasEngage`` gates its errors) and a mixer fed by the pilot's
throttle and sticks; the tests keep ``ScasEngage`` at its default 0 and the pilot's inputs at 0,
so that the FCS adds nothing, and write each motor's command to the model's external inputs
``fcs/cmd{FR,AL,FL,AR}_ext_nd`` (summed into ``fcs/cmdEsc*_nd``, the ESC actuators'
inputs, engines 0..3 in that order).
"""

import math
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import jsbsim
import numpy as np
import pytest

from navsim.flight.multirotor import (GRAVITY_MPS2, Mixer, MultirotorController, MultirotorGains, MultirotorState,
                                      Rotor, Setpoint, YawMode, tilted_axis)
from navsim.foundations.earth import radii

WHEEL_ROOT = Path(jsbsim.get_default_root_dir())
F450_DIR = WHEEL_ROOT / "aircraft" / "F450"
F450_MOTORS = ("FR", "AL", "FL", "AR")         #: the FCS's names of engines 0..3
FT_M, LBF_N, SLUGFT2_KGM2, SLUG_KG = 0.3048, 4.4482216152605, 1.3558179483314, 14.593902937206
LENGTH_M = {"M": 1.0, "IN": 0.0254, "FT": 0.3048}
RATE_HZ = 100.0                 #: JSBSim's step and the controller's rate
HOVER_AGL_M = 20.0              #: the issue's hover height
CALIBRATION_S = 1.0             #: motors run up at the hover command with the airframe held


def _length_m(el, unit: str = "IN") -> float:
    """A JSBSim length element in m (its ``unit``, else ``unit``, JSBSim's default inches)."""
    return float(el.text) * LENGTH_M[el.get("unit", unit).upper()]


def _xyz_m(loc) -> list[float]:
    """A JSBSim ``<location>`` in m (the unit on the location or on each coordinate)."""
    return [_length_m(loc.find(a), loc.get("unit", "IN")) for a in "xyz"]


def _location_b_m(loc, cg_s_m) -> tuple:
    """A JSBSim structural location (x aft, y right, z up) as body axes from the CG, m."""
    x, y, z = _xyz_m(loc)
    return (-(x - cg_s_m[0]), y - cg_s_m[1], -(z - cg_s_m[2]))


def _propeller_torque_per_thrust_m(name: str) -> float:
    """``C_P D / (2 pi C_T)`` of a JSBSim propeller file at zero advance ratio."""
    prop = ET.parse(WHEEL_ROOT / "engine" / f"{name}.xml").getroot()
    d_m = _length_m(prop.find("diameter"))
    rows = {t.get("name"): t.find("tableData").text.split() for t in prop.iter("table")}
    return float(rows["C_POWER"][1]) * d_m / (2.0 * math.pi * float(rows["C_THRUST"][1]))


def jsbsim_rotors(folder: Path, thrust_per_cmd2_n: float) -> list[Rotor]:
    """The rotors of a JSBSim multirotor model: each thruster's location, thrust axis (its
    ``orient``: the thruster's x axis turned by yaw, then pitch) and ``<sense>``."""
    cg = ET.parse(folder / "Mass.xml").getroot().find("location")
    cg_s_m = _xyz_m(cg)
    rotors = []
    for thruster in ET.parse(folder / "Propulsion.xml").getroot().iter("thruster"):
        o = thruster.find("orient")
        pitch, yaw = (math.radians(float(o.find(a).text)) for a in ("pitch", "yaw"))
        axis = (math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), -math.sin(pitch))
        rotors.append(Rotor(pos_b_m=_location_b_m(thruster.find("location"), cg_s_m),
                            spin=int(float(thruster.find("sense").text)),
                            thrust_per_cmd2_n=thrust_per_cmd2_n,
                            torque_per_thrust_m=_propeller_torque_per_thrust_m(thruster.get("file")),
                            axis_b=axis))
    return rotors


class F450:
    """The wheel's F450 in JSBSim at ``agl_m`` above flat terrain, motors at the hover command."""

    def __init__(self, agl_m: float = HOVER_AGL_M):
        jsbsim.FGJSBBase().debug_lvl = 0
        self.fdm = fdm = jsbsim.FGFDMExec(str(WHEEL_ROOT))
        fdm.set_debug_level(0)
        fdm.disable_output()
        assert fdm.load_model("F450")
        fdm.set_dt(1.0 / RATE_HZ)
        fdm["ic/terrain-elevation-ft"] = 0.0
        fdm["ic/h-agl-ft"] = agl_m / FT_M
        fdm["ic/lat-geod-deg"], fdm["ic/long-gc-deg"], fdm["ic/psi-true-deg"] = 45.0, 7.0, 0.0
        fdm.run_ic()
        assert fdm["fcs/ScasEngage"] == 0.0          # the model's own rate loop stays off
        pm = fdm.get_property_manager()
        self._cmd = [pm.get_node(f"fcs/cmd{m}_ext_nd", True).set_double_value for m in F450_MOTORS]
        names = ("position/lat-geod-rad", "position/long-gc-rad", "position/h-sl-ft",
                 "velocities/v-north-fps", "velocities/v-east-fps", "velocities/v-down-fps",
                 "attitude/phi-rad", "attitude/theta-rad", "attitude/psi-rad",
                 "velocities/p-rad_sec", "velocities/q-rad_sec", "velocities/r-rad_sec")
        self._get = [pm.get_node(n, False).get_double_value for n in names]
        self.lat0, self.lon0, self.h0_m = fdm["position/lat-geod-rad"], fdm["position/long-gc-rad"], fdm["position/h-sl-ft"] * FT_M
        r_m, r_n = radii(self.lat0)
        self.k_north, self.k_east = float(r_m), float(r_n) * math.cos(self.lat0)
        self.mass_kg = fdm["inertia/mass-slugs"] * SLUG_KG
        # JSBSim's products of inertia are positive integrals (the tensor's off-diagonal is minus)
        i = {k: fdm[f"inertia/i{k}-slugs_ft2"] * SLUGFT2_KGM2 for k in ("xx", "yy", "zz", "xy", "xz", "yz")}
        self.inertia_b_kgm2 = np.array([[i["xx"], -i["xy"], -i["xz"]], [-i["xy"], i["yy"], -i["yz"]],
                                        [-i["xz"], -i["yz"], i["zz"]]])
        self.thrust_per_cmd2_n = self.calibrate(0.42)

    def set_commands(self, u) -> None:
        for set_u, ui in zip(self._cmd, u):
            set_u(float(ui))

    def held(self, u, seconds: float) -> None:
        """Run the motors at ``u`` with the airframe held at its initial state (re-applied each
        step: JSBSim keeps the engines' state across ``run_ic``)."""
        self.set_commands(u)
        for _ in range(int(round(seconds * RATE_HZ))):
            self.fdm.run()
            self.fdm.run_ic()

    def calibrate(self, u: float) -> float:
        """Static thrust per command squared (N) of the four rotors at command ``u``, held."""
        self.held([u] * 4, CALIBRATION_S)
        self.fdm.run_ic()
        thrust_n = -self.fdm["forces/fbz-prop-lbs"] * LBF_N / 4.0
        return thrust_n / u ** 2

    def wrench_held(self) -> np.ndarray:
        """JSBSim's propulsive wrench now: thrust up (N), roll, pitch, yaw moments (N m)."""
        f = self.fdm
        return np.array([-f["forces/fbz-prop-lbs"] * LBF_N,
                         *(f[f"moments/{a}-prop-lbsft"] * LBF_N * FT_M for a in "lmn")])

    def state(self) -> MultirotorState:
        lat, lon, h_ft, vn, ve, vd, phi, theta, psi, p, q, r = (g() for g in self._get)
        cr, sr, cp, sp, cy, sy = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta), math.cos(psi), math.sin(psi)
        C_nb = np.array([[cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
                         [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
                         [-sp, sr * cp, cr * cp]])
        pos = np.array([(lat - self.lat0) * self.k_north, (lon - self.lon0) * self.k_east, self.h0_m - h_ft * FT_M])
        return MultirotorState(pos, np.array([vn, ve, vd]) * FT_M, C_nb, np.array([p, q, r]))

    def controller(self, gains: MultirotorGains = MultirotorGains()) -> MultirotorController:
        mixer = Mixer.from_rotors(jsbsim_rotors(F450_DIR, self.thrust_per_cmd2_n))
        return MultirotorController(mixer, self.mass_kg, self.inertia_b_kgm2, gains)

    def fly(self, ctrl: MultirotorController, setpoint, seconds: float) -> np.ndarray:
        """Fly ``setpoint`` (or a function of time giving one) for ``seconds``: rows of time,
        position NED, velocity NED, heading, commands."""
        dt, rows = 1.0 / RATE_HZ, []
        for k in range(int(round(seconds * RATE_HZ))):
            s = self.state()
            u = ctrl.command(s, setpoint(k * dt) if callable(setpoint) else setpoint, dt)
            self.set_commands(u)
            assert self.fdm.run()
            rows.append([k * dt, *s.pos_n_m, *s.vel_n_mps, math.atan2(s.C_nb[1, 0], s.C_nb[0, 0]), *u])
        return np.array(rows)


@pytest.fixture(scope="module")
def f450_template():
    """Geometry, mass and calibration of the F450 (one JSBSim load for the module)."""
    return F450()


def coaxial_octo(tilt_rad: float = math.radians(5.0)) -> list[Rotor]:
    """8 arms x 2 coaxial counter-rotating rotors (upper and lower 0.1 m apart), each rotor tilted
    sideways about its arm by +-tilt, alternating round the arms."""
    rotors = []
    for i in range(8):
        az = (i + 0.5) * math.pi / 4.0
        for upper, spin in ((True, 1 if i % 2 else -1), (False, -1 if i % 2 else 1)):
            tilt = tilt_rad if (i + upper) % 2 else -tilt_rad
            # tilt about the arm: a rotation about body z by az of a tilt about x
            ax, ay, az_ = tilted_axis(tilt, 0.0)
            axis = (ax * math.cos(az) - ay * math.sin(az), ax * math.sin(az) + ay * math.cos(az), az_)
            rotors.append(Rotor(pos_b_m=(0.6 * math.cos(az), 0.6 * math.sin(az), -0.05 if upper else 0.05),
                                spin=spin, thrust_per_cmd2_n=60.0, torque_per_thrust_m=0.02, axis_b=axis))
    return rotors


def random_wrenches(mixer: Mixer, n: int, seed: int) -> np.ndarray:
    """Wrenches below saturation: thrusts drawn in (20 %, 80 %) of each rotor's maximum."""
    rng = np.random.default_rng(seed)
    return (mixer.effectiveness @ (rng.uniform(0.2, 0.8, (n, len(mixer.rotors))) * mixer.max_thrust_n).T).T


def test_f450_geometry_read_from_the_wheel(f450_template):
    rotors = jsbsim_rotors(F450_DIR, f450_template.thrust_per_cmd2_n)
    assert [r.spin for r in rotors] == [1, 1, -1, -1]
    assert np.allclose([r.pos_b_m for r in rotors],
                       [(0.1651, 0.1651, -0.025), (-0.1651, -0.1651, -0.025),
                        (0.1651, -0.1651, -0.025), (-0.1651, 0.1651, -0.025)], atol=1e-12)
    assert np.allclose([r.axis_b for r in rotors], (0.0, 0.0, -1.0), atol=1e-12)
    assert rotors[0].torque_per_thrust_m == pytest.approx(0.0666 * 9.4 * 0.0254 / (2 * math.pi * 0.1288))
    # hover near 0.42 command: the calibration sees a thrust-to-weight ratio above 2 at full command
    assert 4 * f450_template.thrust_per_cmd2_n > 2.0 * f450_template.mass_kg * GRAVITY_MPS2


@pytest.mark.parametrize("geometry", ["f450", "octo"])
def test_mixer_reproduces_wrench_below_saturation(geometry, f450_template):
    rotors = jsbsim_rotors(F450_DIR, f450_template.thrust_per_cmd2_n) if geometry == "f450" else coaxial_octo()
    mixer = Mixer.from_rotors(rotors)
    for w in random_wrenches(mixer, 200, seed=52):
        f = mixer.thrusts(w)
        assert np.all(f >= 0) and np.all(f <= mixer.max_thrust_n)
        assert np.allclose(mixer.wrench(f), w, rtol=0, atol=1e-9)
        assert np.allclose(mixer.commands(f) ** 2 * mixer.max_thrust_n, f, atol=1e-9)


def test_mixer_gives_up_yaw_first_then_roll_pitch():
    mixer = Mixer.from_rotors(coaxial_octo())
    hover = 0.5 * mixer.max_thrust_n.sum() * 0.99
    yaw_only_max = mixer.wrench(mixer.thrusts([hover, 0, 0, 1e3]))[3]
    w = [hover, 20.0, -15.0, 1e3]                      # far more yaw than the rotors can give
    got = mixer.wrench(mixer.thrusts(w))
    assert got[:3] == pytest.approx(w[:3], abs=1e-9)   # thrust, roll and pitch kept exactly
    assert 0.0 < got[3] < yaw_only_max                 # yaw gave way to roll and pitch
    f = mixer.thrusts([hover, 1e4, 0.0, 0.0])            # roll beyond reach: scaled, thrusts in range
    assert np.all(f >= -1e-12) and np.all(f <= mixer.max_thrust_n + 1e-12)
    got = mixer.wrench(f)
    assert got[1] > 0.0 and got[2:] == pytest.approx([0.0, 0.0], abs=1e-9)   # the direction kept


def test_f450_mixer_wrench_in_jsbsim(f450_template):
    """The commands of the mixer, run in JSBSim with the airframe held, give the wrench asked
    (the thrust map is a quadratic fitted at hover: a few per cent off elsewhere)."""
    sim = F450()
    mixer = sim.controller().mixer
    weight_n = sim.mass_kg * GRAVITY_MPS2
    for w in ([weight_n, 0.05, -0.04, 0.01], [1.2 * weight_n, -0.08, 0.0, -0.02]):
        sim.held(mixer.commands(mixer.thrusts(w)), 1.0)
        sim.fdm.run_ic()
        got = sim.wrench_held()
        print(f"F450 held: asked {np.round(w, 4)}, JSBSim gave {np.round(got, 4)}")
        assert got[0] == pytest.approx(w[0], rel=0.03)
        assert got[1:] == pytest.approx(w[1:], abs=0.15 * np.max(np.abs(w[1:])))
        assert sim.fdm["fcs/cmdFR_nd"] == 0.0      # the model's FCS adds nothing


def hold_errors(rows: np.ndarray, point) -> np.ndarray:
    return np.linalg.norm(rows[:, 1:4] - np.asarray(point), axis=1)


def test_f450_hovers_60_s_within_0_3_m(f450_template):
    sim = F450()
    rows = sim.fly(sim.controller(), Setpoint(pos_n_m=(0.0, 0.0, 0.0)), 60.0)
    err = hold_errors(rows, (0.0, 0.0, 0.0))
    print(f"F450 hover 60 s: RMS {np.sqrt(np.mean(err ** 2)):.4f} m, max {err.max():.4f} m")
    assert err.max() < 0.3


def test_f450_step_10_m_settles_without_overshoot(f450_template):
    """10 m north at the default 5 m/s limit: within 0.2 m of the point after 6 s (the position
    loop's bandwidth, 20/27 = 0.74 rad/s, asks 5 m/s beyond 6.8 m, then closes with a 1.35 s
    time constant), overshoot under 0.1 m, height held within 0.35 m on the way."""
    sim = F450()
    target = (10.0, 0.0, 0.0)
    rows = sim.fly(sim.controller(), Setpoint(pos_n_m=target), 15.0)
    north = rows[:, 1]
    settled = rows[np.flatnonzero(hold_errors(rows, target) > 0.2)[-1] + 1, 0]
    print(f"F450 10 m step: settled (0.2 m) at {settled:.2f} s, overshoot {north.max() - 10:.3f} m, "
          f"height error max {np.abs(rows[:, 3]).max():.3f} m")
    assert settled < 6.0
    assert north.max() - 10.0 < 0.1
    assert np.abs(rows[:, 3]).max() < 0.35


def test_f450_nose_along_the_course(f450_template):
    """A straight line north-east at 4 m/s with the nose along the course (the F450 starts
    facing north, 37 degrees off): from 3 s on (about 2.5 time constants of the 0.83 rad/s
    heading loop), at speed, the heading is the course within 4 degrees, within 0.5 degree
    on average."""
    sim = F450()
    course = math.atan2(30.0, 40.0)

    def setpoint(t):
        d = min(4.0 * t, 50.0)
        return Setpoint(pos_n_m=(d * math.cos(course), d * math.sin(course), 0.0),
                        vel_n_mps=(4.0 * math.cos(course), 4.0 * math.sin(course), 0.0) if d < 50 else (0, 0, 0),
                        speed_max_mps=6.0, yaw=YawMode("course"))

    rows = sim.fly(sim.controller(), setpoint, 14.0)
    speed = np.hypot(rows[:, 4], rows[:, 5])
    fast = (rows[:, 0] > 3.0) & (speed > 3.0)
    err = np.degrees(np.abs((rows[fast, 7] - course + math.pi) % (2 * math.pi) - math.pi))
    print(f"F450 nose along the course: {fast.sum()} samples, heading error max {err.max():.2f} deg, "
          f"mean {err.mean():.2f} deg")
    assert fast.sum() > 500 and err.max() < 4.0 and err.mean() < 0.5


def test_yaw_modes_heading_and_point():
    """The yaw setpoint of each mode, and the held heading where a mode cannot say."""
    ctrl = MultirotorController(Mixer.from_rotors(coaxial_octo()), 24.5, np.diag([1.0, 1.0, 1.8]))
    still = MultirotorState(np.zeros(3), np.zeros(3), np.eye(3), np.zeros(3))
    assert ctrl.yaw_setpoint(still, Setpoint((0, 0, 0), yaw=YawMode("heading", heading_rad=1.0))) == 1.0
    assert ctrl.yaw_setpoint(still, Setpoint((0, 0, 0), yaw=YawMode("course"))) == 1.0   # too slow: held
    east = MultirotorState(np.zeros(3), np.array([0.0, 3.0, 0.0]), np.eye(3), np.zeros(3))
    assert ctrl.yaw_setpoint(east, Setpoint((0, 0, 0), yaw=YawMode("course"))) == pytest.approx(math.pi / 2)
    point = YawMode("point", target_n_m=(-10.0, 0.0, 0.0))
    assert abs(ctrl.yaw_setpoint(still, Setpoint((0, 0, 0), yaw=point))) == pytest.approx(math.pi)


def test_steps_per_second(f450_template):
    """JSBSim and the controller together on one core (printed; a loose floor)."""
    sim = F450()
    ctrl = sim.controller()
    t0 = time.perf_counter()
    sim.fly(ctrl, Setpoint(pos_n_m=(0.0, 0.0, 0.0)), 10.0)
    rate = 10.0 * RATE_HZ / (time.perf_counter() - t0)
    print(f"F450 + controller: {rate:.0f} steps/s ({rate / RATE_HZ:.0f}x real time at {RATE_HZ:.0f} Hz)")
    assert rate > 1000.0
