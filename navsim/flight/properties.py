"""Every JSBSim property navsim touches, declared once with its unit, and the conversions to SI.

This is the only module that knows JSBSim's property names and its imperial units (ft, slug,
lbf, psf, degrees Rankine). Everything it hands out is SI.

The hot loop reads :data:`RAW_PROPERTIES` as one row of floats (:meth:`JSBSimIO.read_row`),
scaled to SI by :data:`RAW_TO_SI`; column indices are the ``COL_*`` constants.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from navsim.foundations.errors import ScenarioError
from navsim.foundations.resources import data_folder

FT_TO_M = 0.3048
IN_TO_M = FT_TO_M / 12.0
SLUG_TO_KG = 14.59390293720636
LBF_TO_N = 4.4482216152605
PSF_TO_PA = 47.88025898033584
RANKINE_TO_K = 5.0 / 9.0

# --- properties read every step: (name, factor to SI) ------------------------------------------
RAW_PROPERTIES: tuple[tuple[str, float], ...] = (
    ("position/lat-geod-rad", 1.0),
    ("position/long-gc-rad", 1.0),
    ("position/geod-alt-ft", FT_TO_M),
    ("velocities/v-north-fps", FT_TO_M),
    ("velocities/v-east-fps", FT_TO_M),
    ("velocities/v-down-fps", FT_TO_M),
    ("attitude/phi-rad", 1.0),
    ("attitude/theta-rad", 1.0),
    ("attitude/psi-rad", 1.0),
    ("velocities/pi-rad_sec", 1.0),
    ("velocities/qi-rad_sec", 1.0),
    ("velocities/ri-rad_sec", 1.0),
    ("forces/fbx-total-lbs", LBF_TO_N),
    ("forces/fby-total-lbs", LBF_TO_N),
    ("forces/fbz-total-lbs", LBF_TO_N),
    ("inertia/mass-slugs", SLUG_TO_KG),
    ("velocities/vt-fps", FT_TO_M),
    ("velocities/vc-fps", FT_TO_M),
    ("atmosphere/P-psf", PSF_TO_PA),
    ("propulsion/pt-lbs_sqft", PSF_TO_PA),
    ("atmosphere/T-R", RANKINE_TO_K),
    ("position/h-agl-ft", FT_TO_M),
    ("position/terrain-elevation-asl-ft", FT_TO_M),
    ("atmosphere/total-wind-north-fps", FT_TO_M),
    ("atmosphere/total-wind-east-fps", FT_TO_M),
    ("atmosphere/total-wind-down-fps", FT_TO_M),
    ("aero/alpha-rad", 1.0),
    ("aero/beta-rad", 1.0),
    ("velocities/p-rad_sec", 1.0),
    ("velocities/q-rad_sec", 1.0),
    ("velocities/r-rad_sec", 1.0),
    ("fcs/throttle-pos-norm", 1.0),
    ("propulsion/engine/propeller-rpm", 1.0),
    ("atmosphere/wind-north-fps", FT_TO_M),
    ("atmosphere/wind-east-fps", FT_TO_M),
    ("atmosphere/wind-down-fps", FT_TO_M),
)
RAW_NAMES = tuple(name for name, _ in RAW_PROPERTIES)
RAW_TO_SI = tuple(factor for _, factor in RAW_PROPERTIES)
(COL_LAT, COL_LON, COL_H, COL_VN, COL_VE, COL_VD, COL_ROLL, COL_PITCH, COL_YAW,
 COL_PI, COL_QI, COL_RI, COL_FX, COL_FY, COL_FZ, COL_MASS, COL_TAS, COL_CAS, COL_PS, COL_PT,
 COL_TEMP, COL_HAGL, COL_TERRAIN, COL_WN, COL_WE, COL_WD, COL_ALPHA, COL_BETA,
 COL_P, COL_Q, COL_R, COL_THROTTLE, COL_RPM, COL_WSN, COL_WSE, COL_WSD) = range(len(RAW_PROPERTIES))

# --- properties written ------------------------------------------------------------------------
ELEVATOR_CMD_NORM = "fcs/elevator-cmd-norm"
AILERON_CMD_NORM = "fcs/aileron-cmd-norm"
RUDDER_CMD_NORM = "fcs/rudder-cmd-norm"
THROTTLE_CMD_NORM = "fcs/throttle-cmd-norm"
BOOSTER_LBS = "external_reactions/booster/magnitude"
HOLD_DOWN = "simulation/hold-down"
WIND_NORTH_FPS = "atmosphere/wind-north-fps"
WIND_EAST_FPS = "atmosphere/wind-east-fps"
WIND_DOWN_FPS = "atmosphere/wind-down-fps"
TURB_TYPE = "atmosphere/turb-type"
TURB_WIND20_FPS = "atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps"
TURB_SEVERITY = "atmosphere/turbulence/milspec/severity"
RANDOM_SEED = "simulation/randomseed"
TERRAIN_FT = "position/terrain-elevation-asl-ft"
IC_LAT_GEOD_DEG = "ic/lat-geod-deg"
IC_LON_DEG = "ic/long-gc-deg"
IC_H_SL_FT = "ic/h-sl-ft"
IC_TERRAIN_FT = "ic/terrain-elevation-ft"
IC_VN_FPS = "ic/vn-fps"
IC_VE_FPS = "ic/ve-fps"
IC_VD_FPS = "ic/vd-fps"
IC_PSI_DEG = "ic/psi-true-deg"
IC_THETA_DEG = "ic/theta-deg"
IC_PHI_DEG = "ic/phi-deg"

#: a multirotor's motors' command and speed properties are its rotor table's
#: (:data:`navsim.flight.airframe.ROTOR_PROPERTIES`)
RUN_ALL_ENGINES = "propulsion/set-running"        #: -1 starts every engine
#: the propulsive force along body z (the rotors' thrust is its negative), lbf
PROPULSIVE_FZ_LBS = "forces/fbz-prop-lbs"
MASS_SLUGS = "inertia/mass-slugs"
#: the ground contacts' count, a wheel's or skid's (``BOGEY``) height and the centre of gravity's
#: in the structural frame (inches, z up), and whether one of them carries weight
GEAR_UNITS = "gear/num-units"
GEAR_Z_IN = "gear/unit[{i}]/z-position"
CG_Z_IN = "inertia/cg-z-in"
GEAR_WOW = "gear/wow"
#: the inertia tensor's moments and products (JSBSim's products are positive integrals)
INERTIA_SLUGFT2 = {k: f"inertia/i{k}-slugs_ft2" for k in ("xx", "yy", "zz", "xy", "xz", "yz")}
SLUGFT2_TO_KGM2 = SLUG_TO_KG * FT_TO_M ** 2

TURBULENCE_TYPES = {"none": 0, "milspec": 3, "tustin": 4}
#: the turbulence models that divide by the time step: JSBSim's Tustin (bilinear) discretisation
#: (``C_BL = 1 / tau / tan(dt / 2 tau)``, ``sqrt(2 tau / dt)``) turns its state into NaN, for good,
#: on a step that does not advance time (its initial conditions' step, :meth:`JSBSimIO.run_ic`)
ZERO_STEP_UNSAFE_TURBULENCE = ("tustin",)

#: JSBSim integrators, all Adams-Bashforth 3 (JSBSim's code 4): the recorded trajectory then
#: approximates the continuous-time solution to third order, so that an IMU integrating the
#: recorded rates and specific forces (trapezoid, coning and sculling) reproduces it. JSBSim's
#: defaults (rectangular Euler for the attitude) lag the attitude by half a step.
INTEGRATORS = {"simulation/integrator/rate/rotational": 4,
               "simulation/integrator/rate/translational": 4,
               "simulation/integrator/position/rotational": 4,
               "simulation/integrator/position/translational": 4}

#: The aircraft shipped with navsim live here: the package ``navsim.data.aircraft`` (edited in the
#: repository's ``aircraft/`` folder), read through importlib.resources.
AIRCRAFT_DIR = data_folder("aircraft")


class InitialCondition(NamedTuple):
    """Where and how JSBSim starts the aircraft (:meth:`JSBSimIO.set_initial`), SI: geodetic
    position, attitude, and an air velocity of ``tas_mps`` along the heading at flight-path angle
    ``gamma_rad`` (no sideslip), over terrain ``terrain_m`` high."""

    lat_rad: float              #: geodetic latitude
    lon_rad: float              #: longitude
    h_m: float                  #: geodetic height (= JSBSim's above sea level), m
    tas_mps: float              #: true airspeed, m/s
    yaw_rad: float              #: true heading, the air velocity's azimuth too
    pitch_rad: float            #: pitch attitude
    roll_rad: float = 0.0       #: roll attitude
    gamma_rad: float = 0.0      #: flight-path angle of the air velocity, up
    terrain_m: float = 0.0      #: terrain height above the ellipsoid, m


class JSBSimIO:
    """One JSBSim instance, spoken to in SI units.

    Parameters
    ----------
    aircraft : str
        Model name, a folder of ``aircraft_dir``.
    dt_s : float
        Integration step of JSBSim, s.
    aircraft_dir : path, optional
        Where the aircraft folder is; navsim's own ``aircraft/`` by default. JSBSim's shipped
        engines, propellers and systems stay reachable whatever this is.
    """

    def __init__(self, aircraft: str, dt_s: float, aircraft_dir: str | os.PathLike | None = None):
        import jsbsim

        root = Path(jsbsim.get_default_root_dir())
        adir = Path(aircraft_dir) if aircraft_dir is not None else AIRCRAFT_DIR
        if not (adir / aircraft / f"{aircraft}.xml").is_file():
            known = sorted(p.name for p in adir.iterdir() if (p / f"{p.name}.xml").is_file()) \
                if adir.is_dir() else []
            raise FileNotFoundError(
                f"aircraft '{aircraft}' not found in {adir} (known: {', '.join(known) or 'none'})")
        jsbsim.FGJSBBase().debug_lvl = 0          # no banner on stdout
        self.fdm = fdm = jsbsim.FGFDMExec(str(root))
        fdm.set_debug_level(0)
        fdm.disable_output()
        fdm.set_aircraft_path(str(adir))
        fdm.set_engine_path(str(root / "engine"))
        fdm.set_systems_path(str(root / "systems"))
        try:
            loaded, reason = fdm.load_model(aircraft), "its load failed (JSBSim's reason above)"
        except jsbsim.BaseError as exc:       # JSBSim's reason (it prints it on stdout too)
            loaded, reason = False, " ".join(str(exc).split())
        if not loaded:
            raise ScenarioError(f"JSBSim cannot load the model: {reason}", file=str(adir / aircraft / f"{aircraft}.xml"),
                                expected="a JSBSim aircraft model (<fdm_config>)",
                                hint="the line JSBSim names; a model beside a scenario reaches JSBSim's "
                                     "engines and systems by name")
        fdm.set_dt(dt_s)
        self.dt_s = dt_s
        pm = fdm.get_property_manager()
        self._read_nodes = [pm.get_node(name, False) for name in RAW_NAMES]
        self._get = [n.get_double_value for n in self._read_nodes]
        self._node = {name: pm.get_node(name, True) for name in (
            ELEVATOR_CMD_NORM, AILERON_CMD_NORM, RUDDER_CMD_NORM, THROTTLE_CMD_NORM, BOOSTER_LBS)}
        self._set_elev = self._node[ELEVATOR_CMD_NORM].set_double_value
        self._set_ail = self._node[AILERON_CMD_NORM].set_double_value
        self._set_rud = self._node[RUDDER_CMD_NORM].set_double_value
        self._set_thr = self._node[THROTTLE_CMD_NORM].set_double_value
        self._run = fdm.run
        self._wind_fps = (0.0, 0.0, 0.0)
        self._turbulence = "none"

    # --- the hot loop -------------------------------------------------------------------------
    def run(self) -> bool:
        """Advance JSBSim by one step."""
        return self._run()

    def read_row(self) -> list[float]:
        """Every property of :data:`RAW_PROPERTIES`, in SI, as a list (index with ``COL_*``)."""
        return [get() * k for get, k in zip(self._get, RAW_TO_SI)]

    def read_raw(self) -> list[float]:
        """The same properties in JSBSim's own units (times :data:`RAW_TO_SI` gives
        :meth:`read_row`, to the bit): for a fleet that scales all its rows at once."""
        return [get() for get in self._get]

    def set_controls(self, elevator: float, aileron: float, rudder: float, throttle: float) -> None:
        """Normalised commands: surfaces in [-1, 1], throttle in [0, 1]."""
        self._set_elev(elevator)
        self._set_ail(aileron)
        self._set_rud(rudder)
        self._set_thr(throttle)

    # --- set-up --------------------------------------------------------------------------------
    def set_initial(self, ic: InitialCondition, still: bool = False) -> None:
        """Start from ``ic`` (:class:`InitialCondition`): its air velocity plus the wind set by
        :meth:`set_wind_ned` gives the velocity over the ground; ``still``: no velocity over the
        ground (a hovering multirotor; ``ic``'s airspeed and flight-path angle unused)."""
        lat_rad, lon_rad, h_m, tas_mps, yaw_rad, pitch_rad, roll_rad, gamma_rad, terrain_m = ic
        fdm = self.fdm
        fdm[IC_TERRAIN_FT] = terrain_m / FT_TO_M
        fdm[IC_LAT_GEOD_DEG] = np.degrees(lat_rad)
        fdm[IC_LON_DEG] = np.degrees(lon_rad)
        fdm[IC_H_SL_FT] = h_m / FT_TO_M
        cg = np.cos(gamma_rad)
        v_air = tas_mps * np.array([cg * np.cos(yaw_rad), cg * np.sin(yaw_rad), -np.sin(gamma_rad)])
        vn, ve, vd = (0.0, 0.0, 0.0) if still else v_air / FT_TO_M + np.array(self._wind_fps)
        fdm[IC_VN_FPS], fdm[IC_VE_FPS], fdm[IC_VD_FPS] = vn, ve, vd
        fdm[IC_THETA_DEG] = np.degrees(pitch_rad)
        fdm[IC_PHI_DEG] = np.degrees(roll_rad)
        fdm[IC_PSI_DEG] = np.degrees(yaw_rad)
        self.run_ic()
        # JSBSim's initial altitude is above its sea-level radius; correct it to the geodetic
        # height asked for (they differ by millimetres)
        for _ in range(3):
            err_ft = h_m / FT_TO_M - fdm["position/geod-alt-ft"]
            if abs(err_ft) < 1e-7:
                break
            fdm[IC_H_SL_FT] = fdm[IC_H_SL_FT] + err_ft
            self.run_ic()
        got = fdm["attitude/psi-rad"]
        if abs((got - yaw_rad + np.pi) % (2 * np.pi) - np.pi) > 1e-6:
            raise RuntimeError(f"JSBSim initialised heading {np.degrees(got):.3f} deg, "
                               f"asked {np.degrees(yaw_rad):.3f} deg")

    def use_accurate_integrators(self) -> None:
        """Switch JSBSim to :data:`INTEGRATORS` (done once the aircraft is free: JSBSim's
        hold-down does not work with them)."""
        for name, code in INTEGRATORS.items():
            self.fdm[name] = code

    def set_terrain(self, terrain_m: float) -> None:
        self.fdm[TERRAIN_FT] = terrain_m / FT_TO_M

    def set_wind_ned(self, wind_n_mps) -> None:
        """Steady wind, NED components of the air mass velocity (m/s)."""
        self._wind_fps = tuple(float(v) / FT_TO_M for v in wind_n_mps)
        self._apply_wind()

    def _apply_wind(self) -> None:
        wn, we, wd = self._wind_fps
        self.fdm[WIND_NORTH_FPS], self.fdm[WIND_EAST_FPS], self.fdm[WIND_DOWN_FPS] = wn, we, wd

    def set_turbulence(self, kind: str, wind20_mps: float, severity: int, seed: int) -> None:
        """JSBSim turbulence: ``kind`` in :data:`TURBULENCE_TYPES`, MIL-spec wind at 20 ft and
        severity (0 none .. 7 extreme); ``seed`` fixes its random stream."""
        self.fdm[RANDOM_SEED] = int(seed)
        self.fdm[TURB_TYPE] = TURBULENCE_TYPES[kind]
        self._turbulence = kind
        self.fdm[TURB_WIND20_FPS] = wind20_mps / FT_TO_M
        self.fdm[TURB_SEVERITY] = int(severity)

    # --- a multirotor's motors -----------------------------------------------------------------
    def _nodes(self, names) -> list:
        """The property nodes of ``names``; KeyError naming the first the model does not have."""
        pm = self.fdm.get_property_manager()
        nodes = [pm.get_node(name, False) for name in names]
        for name, node in zip(names, nodes):
            if node is None:
                raise KeyError(name)
        return nodes

    def rotor_commands(self, names):
        """A function setting the motors' commands (a sequence in [0, 1], one per property of
        ``names``) at once, all engines running. KeyError naming a property the model lacks."""
        setters = [node.set_double_value for node in self._nodes(names)]
        self.fdm[RUN_ALL_ENGINES] = -1

        def set_all(u) -> None:
            for set_u, ui in zip(setters, u):
                set_u(float(ui))
        return set_all

    def rotor_rpm(self, names):
        """A function reading the rotors' speeds (r/min, the properties ``names``) as a list.
        KeyError naming a property the model lacks."""
        getters = [node.get_double_value for node in self._nodes(names)]
        return lambda: [get() for get in getters]

    def engine_count(self) -> int:
        """The number of engines of the model."""
        return self.fdm.get_propulsion().get_num_engines()

    def rotor_thrust_n(self) -> float:
        """The rotors' total thrust along body -z, N."""
        return -self.fdm[PROPULSIVE_FZ_LBS] * LBF_TO_N

    def mass_properties(self) -> tuple[float, np.ndarray]:
        """The model's mass (kg) and inertia tensor about its centre of gravity (kg m^2, body)."""
        i = {k: self.fdm[name] * SLUGFT2_TO_KGM2 for k, name in INERTIA_SLUGFT2.items()}
        J = np.array([[i["xx"], -i["xy"], -i["xz"]], [-i["xy"], i["yy"], -i["yz"]], [-i["xz"], -i["yz"], i["zz"]]])
        return self.fdm[MASS_SLUGS] * SLUG_TO_KG, J

    def rest_height_m(self) -> float | None:
        """The centre of gravity's height above the model's lowest wheel or skid (a JSBSim
        ``BOGEY`` contact: those that carry the weight :meth:`on_ground` reads; a ``STRUCTURE``
        contact is not one to stand on), the height it stands at on level ground, m; None for a
        model without one."""
        pm = self.fdm.get_property_manager()
        nodes = [pm.get_node(GEAR_Z_IN.format(i=i), False) for i in range(int(self.fdm[GEAR_UNITS]))]
        heights_in = [node.get_double_value() for node in nodes if node is not None]
        if not heights_in:
            return None
        return (self.fdm[CG_Z_IN] - min(heights_in)) * IN_TO_M

    def on_ground(self) -> bool:
        """Whether a ground contact carries weight now."""
        return bool(self.fdm[GEAR_WOW])

    def set_booster_n(self, thrust_n: float) -> None:
        """Thrust of the launch booster along body x, N."""
        self._node[BOOSTER_LBS].set_double_value(thrust_n / LBF_TO_N)

    def set_hold_down(self, hold: bool) -> None:
        """Hold the airframe still (the motor can run up on the launcher)."""
        self.fdm[HOLD_DOWN] = 1.0 if hold else 0.0

    def run_ic(self) -> None:
        """Re-apply the initial conditions, keeping the motor and servo states (and the wind,
        which JSBSim's initial conditions would reset). A turbulence of
        :data:`ZERO_STEP_UNSAFE_TURBULENCE` is off over these steps of zero time, its state kept."""
        fdm = self.fdm
        unsafe = self._turbulence in ZERO_STEP_UNSAFE_TURBULENCE
        if unsafe:
            fdm[TURB_TYPE] = TURBULENCE_TYPES["none"]
        if not fdm.run_ic():
            raise RuntimeError("JSBSim rejected the initial conditions")
        self._apply_wind()
        # one step without time advancing, so that every derived property (total wind,
        # airspeed, forces) reflects the wind before the first sample is read
        fdm.suspend_integration()
        fdm.run()
        fdm.resume_integration()
        if unsafe:
            fdm[TURB_TYPE] = TURBULENCE_TYPES[self._turbulence]
