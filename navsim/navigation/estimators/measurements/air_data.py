"""The air data's ground velocity (``air_velocity``: the ADS's airspeed turned by the INS
attitude, plus the wind), the filter's ADS model it derives ``R`` from, the checks of the states
it alone observes (wind, gusts, pitot bias), and its compiled form (:func:`air_velocity`)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from navsim.foundations import atmosphere
from navsim.foundations.compiled import njit
from navsim.foundations.config import MAX_WIND_MPS, Node, check_numbers
from navsim.foundations.transform import skew
from navsim.navigation.estimators.error_model import AIR_MASS_AXES, GUST_AXES, WIND_AXES, Layout
from navsim.navigation.estimators.measurements.model import CompiledModel, Linearised, _columns, _compiled, _valid
from navsim.navigation.estimators.measurements.registry import measurement, sensor_of_kind
from navsim.navigation.strapdown import NavState
from navsim.sensors.catalog import load_spec
from navsim.sensors.specs import AdsSpec


@measurement("air_velocity")
@dataclass
class AirVelocity:
    """INS velocity minus the ground velocity the air data make with the INS attitude, m/s:
    ``z = v - (C_nb u V + w)``, ``V`` the ADS's true airspeed, ``u`` its direction in the body,
    ``[cos a cos b, sin b, sin a cos b]``, from the angle-of-attack and sideslip vanes when the
    filter's ADS model has them (``velocity_axis: air``), else the body x axis (P0's ground
    velocity), ``w`` the filter's wind (``wind_n_mps``, default calm).

    ``model`` (and ``override``) is the filter's own model of the ADS, a catalog entry as the
    ES-KF's ``noise.imu``: ``R`` is derived from it at each epoch, from the measured airspeed
    and density, in the air axes: along ``u`` the airspeed's std ``sigma_qc / (rho V)`` (the
    dynamic-pressure sensor's noise and per-run bias, the static one's too with an absolute
    pitot) with the density's share ``V/2 sqrt((sigma_ps/ps)^2 + (sigma_T/T)^2)``; across it
    ``V sigma_angle``, ``sigma_angle`` the vanes' noise, or without vanes ``angle_sigma_deg``,
    what the filter allows for the angles it does not measure (about 4 deg on P0's track: the
    mean angle of attack and its spread; that mean is a bias, not white, so this mode is not
    consistent: P0's ES-KF with it has NEES 12.5 on 200 runs). With ``C_nb_est = (I - [phi x]) C_nb`` the
    attitude row is ``-[a x]``, ``a = C_nb u V``: the INS attitude error turns the air velocity.

    With ``wind`` (and ``wind_down``) states the wind is estimated: ``z = v - C_nb u V -
    wind_n_mps`` is the wind the filter has not been told plus the errors, so the wind block's
    columns are the identity on N, E (and D); ``wind_n_mps`` is then a prior the state adds to.
    Turbulence the filter does not model is white to it: ``turbulence_sigma_mps`` (the gusts'
    std, taken isotropic: the larger of MIL-HDBK-1797's low-altitude intensities,
    :func:`navsim.flight.environment.turbulence_sigma_mps`) adds its variance to ``R`` on
    every axis a ``gust`` (``gust_down``) state does not carry. A gust state models them as
    coloured (Dryden's first-order form, :mod:`~navsim.navigation.estimators.error_model`):
    its columns are the identity too, and the wind state is then the steady wind.

    With a ``pitot_bias`` state in the filter (the dynamic pressure's per-run bias ``b``, Pa, a
    random constant whose initial std is the ADS model's), ``V = V_true + b / (rho V)``: its
    column is ``-C_nb u / (rho V)`` and ``R`` leaves the bias out. Without it, the bias is in
    ``R`` as if it were white. With an absolute pitot the static sensor's bias is in both
    ``pitot_bias`` and a ``baro`` state (their correlation is not in the initial covariance):
    the shipped ``p0_ads`` is differential.
    """

    sensor: str
    spec: AdsSpec                        #: the filter's model of the ADS
    angle_sigma_rad: float = 0.0         #: the unmeasured angles' std (an ADS model without vanes)
    wind_n_mps: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    turbulence_sigma_mps: float = 0.0    #: the gusts' std the filter takes as white, m/s
    SCHEMA = {"model": {"type": "string"}, "override": {"type": "object"}, "angle_sigma_deg": {"type": "number", "minimum": 0},
              "wind_n_mps": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
              "turbulence_sigma_mps": {"type": "number", "minimum": 0}}

    @classmethod
    def parse(cls, node: Node, sensors: dict) -> dict:
        sensor_of_kind(node, sensors, "ads")
        name = node.get("model", str)
        override = node.child("override", None)
        spec = _ads_spec(name, override.data if override else None, node)
        vanes = spec.velocity_axis == "air"
        given = node.data.get("angle_sigma_deg") is not None
        angle = node.get("angle_sigma_deg", float, 0.0, minimum=0.0)
        if vanes and given:
            raise node.error(f"the ADS model '{name}' has vanes: their noise is the angles' sigma", "angle_sigma_deg",
                             expected="no angle_sigma_deg with a vane-fitted ADS model (its vane_noise is used)")
        if not vanes and angle == 0.0:
            raise node.error(f"the ADS model '{name}' has no vanes: the angles it leaves out need a sigma",
                             "angle_sigma_deg", expected="a number > 0 (about 4 deg at a cruise angle of attack)")
        wind = node.data.get("wind_n_mps", [0.0, 0.0, 0.0])
        node._seen.add("wind_n_mps")
        wind = check_numbers(wind, 3, minimum=-MAX_WIND_MPS, maximum=MAX_WIND_MPS, error=lambda m, e: node.error(
            m, "wind_n_mps", expected=f"[north, east, down] in m/s ({e})"))
        return {"model": name, "override": override.data if override else None, "angle_sigma_deg": angle,
                "wind_n_mps": [float(w) for w in wind],
                "turbulence_sigma_mps": node.get("turbulence_sigma_mps", float, 0.0, minimum=0.0, maximum=MAX_WIND_MPS)}

    @classmethod
    def from_entry(cls, entry: dict):
        return cls(entry["sensor"], _ads_spec(entry["model"], entry["override"]),
                   math.radians(entry["angle_sigma_deg"]), np.asarray(entry["wind_n_mps"], float),
                   float(entry.get("turbulence_sigma_mps", 0.0)))

    @classmethod
    def reads(cls, entry: dict) -> tuple:
        """The sensor values the model of ``entry`` reads: the vanes' angles when its ADS model
        has vanes, the air data always (checked against the sensor before anything runs)."""
        return _air_values(_ads_spec(entry["model"], entry["override"]).velocity_axis == "air")

    def axes_b(self, data, j: int) -> tuple:
        """The air axes in the body ``(B, 3)`` each (along the airspeed, the sideslip's and the
        angle of attack's directions) and their angles' std."""
        v = data.values
        if self.spec.velocity_axis == "air":
            a, b, sigma = v["alpha_rad"][:, j], v["beta_rad"][:, j], self.spec.vane_noise
        else:
            a = b = np.zeros(data.valid.shape[0])
            sigma = self.angle_sigma_rad
        ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
        u = np.stack([ca * cb, sb, sa * cb], -1)
        e_b = np.stack([-ca * sb, cb, -sa * sb], -1)
        e_a = np.stack([-sa, np.zeros_like(a), ca], -1)
        return u, e_b, e_a, sigma

    @property
    def state_sigma(self) -> dict:
        """The initial std of the sensor-error state this model observes: ``pitot_bias``, the
        dynamic pressure's per-run bias by the filter's ADS model, Pa."""
        s = self.spec
        static = s.static_bias_sigma if s.pitot == "absolute" else 0.0
        return {"pitot_bias": np.array([math.hypot(s.total_bias_sigma, static)])}

    def airspeed_sigma(self, data, j: int, bias_state: bool) -> tuple:
        """The std of the ADS's true airspeed ``(B,)`` by the filter's model, m/s (the
        dynamic pressure's bias in it unless a ``bias_state`` carries it), and ``dV/dq_c =
        1 / (rho V)`` ``(B,)``, (m/s)/Pa."""
        s, v = self.spec, data.values
        V, ps, T = v["tas_mps"][:, j], v["p_static_pa"][:, j], v["temp_k"][:, j]
        dv_dqc = 1.0 / (ps / (atmosphere.R_AIR * T) * np.maximum(V, 1.0))
        var_ps, var_qc = self.pressure_variances(bias_state)
        density = 0.5 * V * np.sqrt(var_ps / ps ** 2 + (s.temperature_noise / T) ** 2)
        return np.hypot(np.sqrt(var_qc) * dv_dqc, density), dv_dqc

    def pressure_variances(self, bias_state: bool) -> tuple[float, float]:
        """The variances of the static pressure and of the dynamic pressure by the filter's
        ADS model, Pa^2 (the dynamic pressure's bias in it unless a ``bias_state`` carries it)."""
        s = self.spec
        var_ps = s.static_noise ** 2 + s.static_bias_sigma ** 2
        var_qc = s.total_noise ** 2 + (s.static_noise ** 2 if s.pitot == "absolute" else 0.0)
        if not bias_state:
            var_qc = var_qc + self.state_sigma["pitot_bias"][0] ** 2
        return var_ps, var_qc

    def model(self, nav: NavState, layout: Layout, data, j: int):
        B = nav.lat_rad.shape[0]
        V = data.values["tas_mps"][:, j]
        u, e_b, e_a, sigma = self.axes_b(data, j)
        u_n = np.einsum("bij,bj->bi", nav.C_nb, u)            # the airspeed's direction, NED
        air_n = u_n * V[:, None]
        z = nav.vel_n_mps - air_n - self.wind_n_mps
        H = np.zeros((B, 3, layout.n))
        s = layout.slice("vel").start
        H[:, [0, 1, 2], [s, s + 1, s + 2]] = 1.0
        H[:, :, layout.slice("att")] = -skew(air_n)
        bias_state = layout.has("pitot_bias")
        sv, dv_dqc = self.airspeed_sigma(data, j, bias_state)
        if bias_state:                   # V = V_true + b / (rho V): z = ... - C_nb u b / (rho V)
            H[:, :, layout.slice("pitot_bias").start] = -u_n * dv_dqc[:, None]
        white = np.full(3, self.turbulence_sigma_mps ** 2)   # the gusts no state carries
        for block, axes in AIR_MASS_AXES.items():    # the wind and gusts the filter estimates
            if layout.has(block):
                cols = layout.slice(block)
                H[:, list(axes), list(range(cols.start, cols.stop))] = 1.0
                if block in GUST_AXES:
                    white[list(axes)] = 0.0
        s_across = V * sigma
        R_b = (sv[:, None, None] ** 2 * np.einsum("bi,bj->bij", u, u)
               + s_across[:, None, None] ** 2 * (np.einsum("bi,bj->bij", e_b, e_b) + np.einsum("bi,bj->bij", e_a, e_a)))
        R = nav.C_nb @ R_b @ np.swapaxes(nav.C_nb, 1, 2) + np.diag(white)
        return Linearised(z, H, R, data.valid[:, j])

    def compiled(self, layout: Layout) -> CompiledModel:
        """The compiled form (:func:`~navsim.navigation.estimators.air_velocity`)."""
        s, bias_state = self.spec, layout.has("pitot_bias")
        var_ps, var_qc = self.pressure_variances(bias_state)
        vanes = s.velocity_axis == "air"
        white = np.full(3, self.turbulence_sigma_mps ** 2)
        cols = [layout.slice("vel").start, layout.slice("att").start,
                layout.slice("pitot_bias").start if bias_state else -1] + [-1] * 6
        for k, group in enumerate((WIND_AXES, GUST_AXES)):
            for block, axes in group.items():
                if layout.has(block):
                    for a, col in zip(axes, range(layout.slice(block).start, layout.slice(block).stop)):
                        cols[3 + 3 * k + a] = col
                        white[a] = 0.0 if group is GUST_AXES else white[a]
        values = {"vanes": float(vanes), "angle_sigma": s.vane_noise if vanes else self.angle_sigma_rad,
                  "var_ps": var_ps, "var_qc": var_qc,
                  "temperature_noise": s.temperature_noise, "r_air": atmosphere.R_AIR,
                  **dict(zip(("wind_n", "wind_e", "wind_d"), np.asarray(self.wind_n_mps, float))),
                  **dict(zip(("white_n", "white_e", "white_d"), white))}
        keys = _air_values(vanes)

        def inputs(nav, data, j):
            inp = np.zeros((nav.lat_rad.shape[0], 5))
            inp[:, :len(keys)] = _columns(data, j, keys)
            return inp, _valid(data, j)
        return _compiled(air_velocity, 3, [values[k] for k in AIR_PARAMS], cols, inputs)


def _air_values(vanes: bool) -> tuple:
    """The ADS values the air-velocity model reads: airspeed, static pressure, temperature, and
    the vanes' angles where it has vanes."""
    return ("tas_mps", "p_static_pa", "temp_k") + (("alpha_rad", "beta_rad") if vanes else ())


def check_observed_states(node: Node, blocks, entries: list) -> None:
    """A ``pitot_bias`` state needs the one ``air_velocity`` model that observes it, with an
    ADS model whose bias is not zero (its initial std); a wind state an ``air_velocity`` model
    (nothing else observes the wind or the gusts)."""
    air = [e for e in entries if e["type"] == "air_velocity"]
    wind = [b for b in AIR_MASS_AXES if b in blocks]
    if wind and not air:
        raise node.error(f"the '{wind[0]}' state is observed by no measurement", "states",
                         expected="an air_velocity measurement with a wind or gust state (or no such state)")
    if wind and len({tuple(e["wind_n_mps"]) for e in air}) > 1:
        raise node.error("the air_velocity measurements give different wind_n_mps", "measurements",
                         expected="one wind prior for the one wind state they observe")
    if "pitot_bias" not in blocks:
        return
    if len(air) != 1:
        raise node.error(f"the 'pitot_bias' state is observed by {len(air)} air_velocity measurements", "states",
                         expected="exactly one air_velocity measurement with a pitot_bias state")
    if not AirVelocity.from_entry(air[0]).state_sigma["pitot_bias"][0] > 0:
        raise node.error(f"the ADS model '{air[0]['model']}' has no pitot bias for the 'pitot_bias' state", "states",
                         expected="an ADS model with total_bias_sigma > 0, or no pitot_bias state")


def reject_rotating_R(node: Node, entries: list, adapted, who: str) -> None:
    """An adaptive filter that estimates R in NED from the innovations cannot adapt
    ``air_velocity``'s, which turns with the attitude and grows with the airspeed."""
    for e in entries:
        if e["type"] == "air_velocity" and (adapted is None or e["sensor"] in adapted):
            raise node.error(f"{who} adapts the R of sensor '{e['sensor']}' in NED; air_velocity's R turns with "
                             "the attitude and the airspeed", "measurements",
                             expected="air_velocity on a sensor that is not adapted (or another filter)")


def _ads_spec(name: str, override, node: Node | None = None):
    """The filter's ADS model, catalog entry ``name`` with ``override``."""
    spec = load_spec(name, override, (), node.file if node else None, node.path if node else "")
    if not isinstance(spec, AdsSpec):
        if node is None:
            raise ValueError(f"'{name}' is not an ADS")
        raise node.error(f"'{name}' is not an ADS", "model", expected="an ads catalog entry")
    return spec


#: ``par`` of :func:`air_velocity`, by name (the Python model fills it in this order)
AIR_PARAMS = ("vanes", "angle_sigma", "var_ps", "var_qc", "temperature_noise", "r_air", "wind_n", "wind_e",
              "wind_d", "white_n", "white_e", "white_d")


@njit(cache=True, error_model="numpy")
def air_velocity(lat, lon, h, vel, C, inp, par, cols, r0, z, H, R, valid):
    """INS velocity minus the air data's ground velocity ``C u V + w``
    (:class:`AirVelocity`). ``inp``: ``V``, ``p_s``,
    ``T``, ``alpha``, ``beta`` (the last two read with vanes, ``par[0]``); ``par``:
    :data:`AIR_PARAMS`; ``cols``: the velocity block, the attitude block, the pitot bias's column,
    the wind's column per axis N, E, D, then the gusts' (-1: none)."""
    u, e_b, e_a, air = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    Rb = np.empty((3, 3))
    for b in range(lat.shape[0]):
        V = inp[b, 0]
        alpha, beta = (inp[b, 3], inp[b, 4]) if par[0] != 0.0 else (0.0, 0.0)
        ca, sa, cb, sb = math.cos(alpha), math.sin(alpha), math.cos(beta), math.sin(beta)
        u[0], u[1], u[2] = ca * cb, sb, sa * cb
        e_b[0], e_b[1], e_b[2] = -ca * sb, cb, -sa * sb
        e_a[0], e_a[1], e_a[2] = -sa, 0.0, ca
        ps, T = inp[b, 1], inp[b, 2]
        dv_dqc = 1.0 / (ps / (par[5] * T) * max(V, 1.0))
        density = 0.5 * V * math.sqrt(par[2] / ps ** 2 + (par[4] / T) ** 2)
        sv = math.hypot(math.sqrt(par[3]) * dv_dqc, density)
        s_across = V * par[1]
        for i in range(3):
            un = C[b, i, 0] * u[0] + C[b, i, 1] * u[1] + C[b, i, 2] * u[2]
            air[i] = un * V
            z[b, r0 + i] = vel[b, i] - air[i] - par[6 + i]
            H[b, r0 + i, cols[0] + i] = 1.0
            if cols[2] >= 0:
                H[b, r0 + i, cols[2]] = -un * dv_dqc
            for c in (cols[3 + i], cols[6 + i]):
                if c >= 0:
                    H[b, r0 + i, c] = 1.0
        a = cols[1]
        H[b, r0, a + 1], H[b, r0, a + 2] = air[2], -air[1]          # -[air x]
        H[b, r0 + 1, a], H[b, r0 + 1, a + 2] = -air[2], air[0]
        H[b, r0 + 2, a], H[b, r0 + 2, a + 1] = air[1], -air[0]
        for i in range(3):
            for j in range(3):
                Rb[i, j] = sv ** 2 * (u[i] * u[j]) + s_across ** 2 * (e_b[i] * e_b[j] + e_a[i] * e_a[j])
        for i in range(3):
            for j in range(3):
                s = 0.0
                for k in range(3):
                    t = 0.0
                    for q in range(3):
                        t += Rb[k, q] * C[b, j, q]
                    s += C[b, i, k] * t
                R[b, r0 + i, r0 + j] = s + (par[9 + i] if i == j else 0.0)
