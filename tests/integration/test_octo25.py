"""aircraft/octo25, P4's octocopter, as JSBSim flies it: its weight carried at the hover throttle
its navsim.yaml declares, the coaxial pairs' yaw torques cancelling, and the rotor table of
navsim.yaml (positions, spins, tilts, thrust and torque coefficients) giving the force and
moment JSBSim computes, so that a mixer derived from that table commands what JSBSim flies."""

import math

import numpy as np
import pytest

from navsim.flight.airframe import load_airframe
from navsim.flight.properties import AIRCRAFT_DIR, JSBSimIO

LBF_N, LBFFT_NM, FT_M, G = 4.4482216152605, 1.3558179483314, 0.3048, 9.80665


def octo(throttles, steps: int):
    """JSBSim's octo25 released at 20 m, level and still, each motor at its throttle for
    ``steps`` steps of 10 ms; returns the instance."""
    io = JSBSimIO("octo25", 0.01)
    fdm = io.fdm
    for name, value in (("ic/lat-geod-deg", 45.0), ("ic/long-gc-deg", 10.0), ("ic/terrain-elevation-ft", 0.0),
                        ("ic/h-agl-ft", 20.0 / FT_M), ("ic/psi-true-deg", 0.0), ("ic/u-fps", 0.0),
                        ("ic/v-fps", 0.0), ("ic/w-fps", 0.0)):
        fdm[name] = value
    fdm.run_ic()
    fdm["propulsion/set-running"] = -1
    for _ in range(steps):
        for i, t in enumerate(throttles):
            fdm[f"fcs/throttle-cmd-norm[{i}]"] = t
        fdm.run()
    return fdm


@pytest.fixture(scope="module")
def airframe():
    return load_airframe(AIRCRAFT_DIR / "octo25")


def test_the_declared_hover_throttle_carries_the_weight_and_the_yaw_torques_cancel(airframe):
    fdm = octo([airframe.hover_throttle] * len(airframe.rotors), 100)
    thrust_n = -fdm["forces/fbz-prop-lbs"] * LBF_N
    assert thrust_n == pytest.approx(airframe.mass_kg * G, rel=0.02)        # 1 s after release
    assert abs(fdm["moments/n-prop-lbsft"] * LBFFT_NM) < 1e-6               # N m, 16 equal rotors
    assert abs(fdm["velocities/r-rad_sec"]) < 1e-6
    rpm = [fdm[f"propulsion/engine[{i}]/propeller-rpm"] for i in range(len(airframe.rotors))]
    assert max(rpm) - min(rpm) < 0.01 and 5500 < rpm[0] < 6500                # P4: 6000 r/min


def test_navsim_yaml_rotor_table_gives_jsbsims_force_and_moment(airframe):
    """Random throttles 0.45-0.75 (seeded): each rotor's thrust k_T w^2 along its tilted axis
    and its reaction torque k_Q w^2, summed, against JSBSim's propulsion force and moment."""
    throttles = np.random.default_rng(1).uniform(0.45, 0.75, len(airframe.rotors))
    fdm = octo(throttles, 20)
    force, moment = np.zeros(3), np.zeros(3)
    for i, r in enumerate(airframe.rotors):
        w = fdm[f"propulsion/engine[{i}]/propeller-rpm"] * 2 * math.pi / 60
        p = np.asarray(r.position_m, float)
        az, tilt = math.atan2(p[1], p[0]), math.radians(r.tilt_deg)
        axis = np.array([-math.sin(tilt) * math.sin(az), math.sin(tilt) * math.cos(az), -math.cos(tilt)])
        thrust = r.thrust_coefficient * w ** 2
        force += thrust * axis
        moment += np.cross(p, thrust * axis) + r.spin * r.torque_coefficient * w ** 2 * axis
    jsb_force = np.array([fdm[f"forces/fb{a}-prop-lbs"] for a in "xyz"]) * LBF_N
    jsb_moment = np.array([fdm[f"moments/{a}-prop-lbsft"] for a in "lmn"]) * LBFFT_NM
    assert np.allclose(force, jsb_force, rtol=0.03, atol=0.5), (force, jsb_force)
    assert np.allclose(moment, jsb_moment, rtol=0.03, atol=0.3), (moment, jsb_moment)
