"""Barometric altimeter and air data system (P0's ADS) emulators.

Barometer values ``(B, M)``: ``h_baro_m`` (altitude), ``p_static_pa`` (the ISA pressure of that
altitude). The altitude error is ``offset + offset_sigma N + Markov(sigma, tau) + white`` (P0's
first-order Markov model); ``errors['h_error_m']`` is it.

ADS values ``(B, M)``: ``p_static_pa``, ``p_total_pa``, ``temp_k`` (sensors with noise and a
per-run bias), and what the ADS computes from them: ``h_pressure_m`` (pressure altitude),
``cas_mps``, ``tas_mps``, and ``vel_n_mps`` ``(B, M, 3)``, the ground velocity P0 feeds its filter:
the true airspeed along the body x axis rotated to NED with the attitude, plus a wind estimate
(zero, as in P0, unless ``wind_estimate_n_mps`` is given). With ``velocity_axis: air`` the
airspeed is along the air-relative direction measured by angle-of-attack and sideslip vanes
(``alpha_rad``, ``beta_rad`` values), which removes P0's angle-of-attack error (about 1 m/s
at cruise). ``pitot: differential`` measures the dynamic pressure directly, so that the static
sensor's bias no longer enters the airspeed. ``formula: p0`` uses P0's printed
formulas (``H_p = 145442 (1 - (Ps/29.9213)^0.19026)`` ft and ``V = sqrt(2 q / rho)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.foundations import atmosphere as atm
from navsim.foundations.transform import dcm_from_euler, dcm_from_quat
from navsim.sensors.base import SensorData, apply_outages, gauss_markov, normals, sampling
from navsim.sensors.registry import ErrorTerm, Field, InLoop, Output, SensorKind, register


@dataclass(frozen=True)
class BaroSpec:
    """Barometric altimeter: ISA pressure at the true height, plus a weather offset, a first-order
    Markov altitude error (P0) and white noise."""

    rate_hz: float = 10.0
    offset: float = 0.0                       #: fixed altitude offset (weather / QNH), m
    offset_sigma: float = 0.0                 #: random altitude offset per run, m
    markov_sigma: float = 0.0                 #: Markov altitude error std, m
    markov_tau_s: float = 300.0
    noise: float = 0.0                        #: white altitude noise std, m


@dataclass(frozen=True)
class AdsSpec:
    """Air data system (P0): static and total pressure and temperature sensors.

    ``pitot: absolute`` measures the total pressure with its own absolute sensor (its error and
    the static sensor's both enter the dynamic pressure); ``differential`` measures the dynamic
    pressure ``pt - ps`` with a differential sensor, ``total_*`` then being that sensor's noise
    and bias. ``velocity_axis: body_x`` gives P0's ground velocity (airspeed along the body x
    axis); ``air`` uses angle-of-attack and sideslip vanes (``vane_noise``) for the direction."""

    rate_hz: float = 10.0
    static_noise: float = 0.0                 #: Pa
    static_bias_sigma: float = 0.0            #: Pa, per run
    total_noise: float = 0.0                  #: Pa
    total_bias_sigma: float = 0.0             #: Pa, per run
    temperature_noise: float = 0.0            #: K
    formula: str = "isa"                      #: "isa" (exact) or "p0" (P0's printed formulas)
    pitot: str = "absolute"                   #: "absolute" or "differential"
    velocity_axis: str = "body_x"             #: "body_x" (P0) or "air" (alpha/beta vanes)
    vane_noise: float = 0.0                   #: rad, alpha and beta vanes


def emulate_baro(truth, spec: BaroSpec, seed: int, runs, faults=(), name: str = "baro") -> SensorData:
    smp = sampling(truth, spec.rate_hz, seed, runs, name)
    runs, B, step, t, M = smp.runs, smp.B, smp.step, smp.t, smp.M
    err = np.full((B, M), spec.offset)
    if spec.offset_sigma:
        err += normals(smp.rng("offset"), (1,)) * spec.offset_sigma
    if spec.markov_sigma:
        err += gauss_markov(smp.rng("markov"), M, step * truth.dt_s, [spec.markov_sigma], spec.markov_tau_s)[..., 0]
    factor = np.ones(M)
    for f in faults:
        if f.type == "degraded":
            factor[f.active(t)] *= f.factor
        elif f.type == "bias":
            err[:, f.active(t)] += f.value
    if spec.noise:
        err += normals(smp.rng("noise"), (M,)) * spec.noise * factor
    h = truth.h_m[::step][None] + err
    valid = np.ones((B, M), bool)
    apply_outages(valid, t, faults)
    return SensorData(name=name, kind="baro", t_s=t,
                      values={"h_baro_m": h, "p_static_pa": atm.pressure(h)}, valid=valid,
                      errors={"h_error_m": err}, meta={"rate_hz": spec.rate_hz, "runs": runs, "seed": seed})


def emulate_ads(truth, spec: AdsSpec, seed: int, runs, faults=(), name: str = "ads",
                wind_estimate_n_mps=(0.0, 0.0, 0.0)) -> SensorData:
    smp = sampling(truth, spec.rate_hz, seed, runs, name)
    runs, B, step, t, M = smp.runs, smp.B, smp.step, smp.t, smp.M

    def sensor(channel, x, noise, bias_sigma):
        """``x`` with the channel's per-run bias and white noise, each from its own stream."""
        out = np.broadcast_to(x, (B, M)).copy()
        if bias_sigma:
            out += normals(smp.rng(f"{channel}.bias"), (1,)) * bias_sigma
        if noise:
            out += normals(smp.rng(f"{channel}.noise"), (M,)) * noise
        return out

    ps = sensor("static", truth.p_static_pa[::step], spec.static_noise, spec.static_bias_sigma)
    if spec.pitot == "differential":
        qc_true = truth.p_total_pa[::step] - truth.p_static_pa[::step]
        pt = ps + sensor("total", qc_true, spec.total_noise, spec.total_bias_sigma)
    else:
        pt = sensor("total", truth.p_total_pa[::step], spec.total_noise, spec.total_bias_sigma)
    temp = sensor("temperature", truth.temp_k[::step], spec.temperature_noise, 0.0)
    # the pitot's own error, before a reading below static is read as static (the loop's fill)
    pitot_error = pt - ps - (truth.p_total_pa[::step] - truth.p_static_pa[::step]) if spec.pitot == "differential" \
        else pt - truth.p_total_pa[::step]
    pt = np.maximum(pt, ps)          # a pitot never reads below static
    h_p, tas, cas = _air_data(spec.formula, ps, pt, temp)
    C_nb = dcm_from_quat(truth.quat_nb[::step])
    values = {}
    if spec.velocity_axis == "air":
        alpha = sensor("alpha", truth.alpha_rad[::step], spec.vane_noise, 0.0)
        beta = sensor("beta", truth.beta_rad[::step], spec.vane_noise, 0.0)
        dir_n = np.einsum("mij,bmj->bmi", C_nb, _vane_axis(alpha, beta))
        values = {"alpha_rad": alpha, "beta_rad": beta}
    else:
        dir_n = C_nb[None, :, :, 0]                                # body x axis in NED
    vel = tas[..., None] * dir_n + np.asarray(wind_estimate_n_mps, float)
    valid = np.ones((B, M), bool)
    apply_outages(valid, t, faults)
    return SensorData(name=name, kind="ads", t_s=t,
                      values={"p_static_pa": ps, "p_total_pa": pt, "temp_k": temp,
                              "h_pressure_m": h_p, "cas_mps": cas, "tas_mps": tas, "vel_n_mps": vel,
                              **values},
                      valid=valid,
                      errors={"h_error_m": h_p - truth.h_m[::step], "tas_error_mps": tas - truth.tas_mps[::step],
                              "vel_error_n_mps": vel - truth.vel_n_mps[::step], "pitot_error_pa": pitot_error},
                      meta={"rate_hz": spec.rate_hz, "runs": runs, "seed": seed, "formula": spec.formula,
                            "pitot": spec.pitot, "velocity_axis": spec.velocity_axis,
                            "wind_estimate_n_mps": np.asarray(wind_estimate_n_mps, float)})


def _air_data(formula: str, ps, pt, temp):
    """What the ADS computes from its static and total pressures (``pt >= ps``) and temperature:
    the pressure altitude, true and calibrated airspeed."""
    if formula == "p0":
        h_p, tas = atm.pressure_altitude_p0_ft(ps) * 0.3048, atm.tas_incompressible(pt, ps, temp)
    else:
        h_p, tas = atm.pressure_altitude(ps), atm.tas_from_air_data(pt, ps, temp)
    return h_p, tas, atm.cas_from_qc(pt - ps)


def _vane_axis(alpha, beta):
    """The air-relative direction in the body of the vanes' angle of attack and sideslip."""
    return np.stack([np.cos(alpha) * np.cos(beta), np.sin(beta), np.sin(alpha) * np.cos(beta)], -1)


def fill_baro_in_loop(data: SensorData, j: int, sample) -> None:
    """Sample ``j`` of a barometer in the closed loop: the runs' true height of ``sample`` (a
    :class:`~navsim.sensors.registry.LoopSample`) plus each run's own drawn error."""
    v = data.values
    v["h_baro_m"][:, j] = sample.h_m + data.errors["h_error_m"][:, j]
    v["p_static_pa"][:, j] = atm.pressure(v["h_baro_m"][:, j])


def prepare_ads_in_loop(data: SensorData, static) -> None:
    """An ADS emulated on the closed loop's static record ``static`` (a
    :class:`~navsim.flight.truth.Truth` at rest: no dynamic pressure, no angles) made ready to
    fly: each run's drawn sensor errors (static and dynamic or total pressure, temperature,
    vanes) kept in ``errors`` for :func:`fill_ads_in_loop`."""
    v = data.values
    e = {"p_static_pa": v["p_static_pa"] - static.p_static_pa[0], "temp_k": v["temp_k"] - static.temp_k[0],
         "pitot_pa": data.errors["pitot_error_pa"]}
    if "alpha_rad" in v:
        e.update(alpha_rad=v["alpha_rad"].copy(), beta_rad=v["beta_rad"].copy())
    data.errors = {f"sensor_{k}": x for k, x in e.items()}


def fill_ads_in_loop(data: SensorData, j: int, sample) -> None:
    """Sample ``j`` of an ADS in the closed loop: the runs' true air data in ``sample`` (a
    :class:`~navsim.sensors.registry.LoopSample`) through each run's own sensor errors
    (:func:`prepare_ads_in_loop`), and what the ADS computes from them, as :func:`emulate_ads`."""
    v, e = data.values, {k[len("sensor_"):]: x[:, j] for k, x in data.errors.items()}
    ps = sample.p_static_pa + e["p_static_pa"]
    if data.meta["pitot"] == "differential":
        pt = ps + (sample.p_total_pa - sample.p_static_pa) + e["pitot_pa"]
    else:
        pt = sample.p_total_pa + e["pitot_pa"]
    temp = sample.temp_k + e["temp_k"]
    pt = np.maximum(pt, ps)
    h_p, tas, cas = _air_data(data.meta["formula"], ps, pt, temp)
    C_nb = dcm_from_euler(sample.euler_rad[:, 0], sample.euler_rad[:, 1], sample.euler_rad[:, 2])
    if "alpha_rad" in e:
        alpha, beta = sample.alpha_rad + e["alpha_rad"], sample.beta_rad + e["beta_rad"]
        v["alpha_rad"][:, j], v["beta_rad"][:, j] = alpha, beta
        dir_n = np.einsum("bij,bj->bi", C_nb, _vane_axis(alpha, beta))
    else:
        dir_n = C_nb[:, :, 0]
    for name, x in (("p_static_pa", ps), ("p_total_pa", pt), ("temp_k", temp), ("h_pressure_m", h_p),
                    ("cas_mps", cas), ("tas_mps", tas)):
        v[name][:, j] = x
    v["vel_n_mps"][:, j] = tas[:, None] * dir_n + data.meta["wind_estimate_n_mps"]


BARO = register(SensorKind(
    name="baro", spec=BaroSpec, role="altimeter", description="barometric altimeter",
    fields={"rate_hz": Field("rate_hz", None, "plain"), "offset": Field("offset", "length", "1", signed=True),
            "offset_sigma": Field("offset_sigma", "length", "1"), "markov_sigma": Field("markov_sigma", "length", "1"),
            "markov_tau": Field("markov_tau_s", "time", "1"), "noise": Field("noise", "length", "1")},
    outputs=(Output("h_baro_m", "m", role="height", truth="h_m", label="baro height"), Output("p_static_pa", "Pa")),
    errors=tuple(ErrorTerm(n) for n in ("offset", "offset_sigma", "markov_sigma", "noise")),
    emulate=emulate_baro, faults=("outage", "bias", "degraded"), in_loop=InLoop(fill_baro_in_loop)))

_AXES = ("north", "east", "down")
ADS = register(SensorKind(
    name="ads", spec=AdsSpec, role="air_data", description="air data system: static, total pressure, temperature (P0)",
    fields={"rate_hz": Field("rate_hz", None, "plain"),
            **{key: Field(key, "pressure", "1")
               for key in ("static_noise", "static_bias_sigma", "total_noise", "total_bias_sigma")},
            "temperature_noise": Field("temperature_noise", "temperature", "1"),
            "formula": Field("formula", ("isa", "p0"), "str"),
            "pitot": Field("pitot", ("absolute", "differential"), "str"),
            "velocity_axis": Field("velocity_axis", ("body_x", "air"), "str"),
            "vane_noise": Field("vane_noise", "angle", "1")},
    outputs=(Output("p_static_pa", "Pa", truth="p_static_pa", label="static pressure"), Output("p_total_pa", "Pa"),
             Output("temp_k", "K"), Output("h_pressure_m", "m", role="height", truth="h_m", label="pressure altitude"),
             Output("cas_mps", "m/s"), Output("tas_mps", "m/s", truth="tas_mps", label="true airspeed"),
             Output("vel_n_mps", "m/s", role="velocity", truth="vel_n_mps", label="ground velocity", axes=_AXES),
             Output("alpha_rad", "rad", when=lambda spec: spec.velocity_axis == "air"),
             Output("beta_rad", "rad", when=lambda spec: spec.velocity_axis == "air")),
    errors=tuple(ErrorTerm(n) for n in ("static_noise", "static_bias_sigma", "total_noise", "total_bias_sigma",
                                        "temperature_noise", "vane_noise")),
    emulate=emulate_ads, in_loop=InLoop(fill_ads_in_loop, prepare=prepare_ads_in_loop)))
