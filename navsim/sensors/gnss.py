"""BeiDou / GNSS receiver emulator (position and velocity fixes).

Values, ``(B, M)`` unless noted: ``lat_rad``, ``lon_rad``, ``h_m``, ``vel_n_mps`` ``(B, M, 3)``;
quality as a receiver reports it: ``fix_type`` (3: 3-D fix, 0: none), ``h_acc_m``, ``v_acc_m``,
``s_acc_mps`` (the receiver's own 1-sigma accuracy estimates, which grow with interference and
degradation). ``errors``: ``pos_error_n_m`` ``(B, M, 3)``, the NED error of the reported position
against the true centre of gravity (noise, Markov error, faults, lever arm and latency effects),
and ``vel_error_n_mps``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navsim.foundations import earth
from navsim.foundations.transform import dcm_from_quat
from navsim.sensors.base import (
    Sampling,
    SensorData,
    apply_outages,
    gauss_markov,
    normals,
    sampling,
    truth_step,
    zeros3,
)
from navsim.sensors.registry import ErrorTerm, Field, InLoop, LinearError, Output, Refusal, SensorKind, register


@dataclass(frozen=True)
class GnssSpec:
    """GNSS receiver. Position errors NED (m), velocity errors NED (m/s)."""

    rate_hz: float = 1.0
    position_sigma: np.ndarray = zeros3()
    velocity_sigma: np.ndarray = zeros3()
    markov_sigma: np.ndarray = zeros3()       #: Gauss-Markov position error, m
    markov_tau_s: float = 300.0
    latency_s: float = 0.0
    lever_arm_b: np.ndarray = zeros3()        #: antenna position from the CG, body axes, m
    velocity_output: bool = True              #: False: a position-only receiver (P0's BD-2)


def _interp(t_query, t, x):
    """Linear interpolation of ``x`` ``(N, ...)`` at ``t_query``."""
    if x.ndim == 1:
        return np.interp(t_query, t, x)
    return np.stack([np.interp(t_query, t, x[:, j]) for j in range(x.shape[1])], axis=-1)


def _distance_to_polyline(north, east, down, pts):
    """Distance (m) of points ``(M,)`` to a polyline of local NED points ``(K, 3)``."""
    p = np.stack([north, east, down], axis=-1)
    if len(pts) == 1:
        return np.linalg.norm(p - pts[0], axis=-1)
    best = np.full(len(p), np.inf)
    for a, b in zip(pts[:-1], pts[1:]):
        ab = b - a
        s = np.clip(((p - a) @ ab) / max(ab @ ab, 1e-12), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(p - (a + s[:, None] * ab), axis=-1))
    return best


def _antenna_offset(truth, spec: GnssSpec, smp: Sampling, k_n, k_e) -> tuple[np.ndarray, np.ndarray]:
    """The antenna's position ``(M, 3)`` (NED, m) and velocity (m/s) at the latency-delayed time
    of validity, less the centre of gravity's at the fix times of ``smp`` (``k_n``, ``k_e``: m
    per rad of latitude and longitude)."""
    t, step = smp.t, smp.step
    t_valid = np.maximum(t - spec.latency_s, truth.t_s[0])
    if spec.latency_s:
        lat = _interp(t_valid, truth.t_s, truth.lat_rad)
        lon = _interp(t_valid, truth.t_s, truth.lon_rad)
        h = _interp(t_valid, truth.t_s, truth.h_m)
        vel = _interp(t_valid, truth.t_s, truth.vel_n_mps)
    else:
        lat, lon, h, vel = (truth.lat_rad[::step], truth.lon_rad[::step], truth.h_m[::step],
                            truth.vel_n_mps[::step])
    offset_n = (np.stack([(lat - truth.lat_rad[::step]) * k_n, (lon - truth.lon_rad[::step]) * k_e,
                          -(h - truth.h_m[::step])], axis=-1))
    vel_off = vel - truth.vel_n_mps[::step]
    if np.any(spec.lever_arm_b):
        C_nb = dcm_from_quat(truth.quat_nb[::step])
        offset_n = offset_n + C_nb @ spec.lever_arm_b
        vel_off = vel_off + np.einsum("nij,nj->ni", C_nb,
                                      np.cross(truth.omega_ib_b_rps[::step], spec.lever_arm_b))
    return offset_n, vel_off


def _fault_effects(truth, faults, smp: Sampling) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the faults do at the fix times of ``smp``: the noise scale factor ``(M,)``
    (degradation, interference), the fixes kept ``(B, M)`` (lock lost near an interferer,
    outages) and the position bias ``(M, 3)``."""
    B, step, t, M = smp.B, smp.step, smp.t, smp.M
    lat0, lon0 = truth.lat_rad[0], truth.lon_rad[0]
    factor = np.ones(M)
    valid = np.ones((B, M), bool)
    pos_bias = np.zeros((M, 3))
    north, east = earth.local_ne(truth.lat_rad[::step], truth.lon_rad[::step], lat0, lon0)
    for f in faults:
        act = f.active(t)
        if f.type == "degraded":
            factor[act] *= f.factor
        elif f.type == "bias":
            pos_bias[act] += f.value
        elif f.type == "interference":
            pts = np.array([[*earth.local_ne(np.radians(p[0]), np.radians(p[1]), lat0, lon0), -p[2]]
                            for p in f.source])
            d = _distance_to_polyline(north, east, -truth.h_m[::step], pts)
            grow = 1.0 + (f.radius_m / np.maximum(d, 1e-3)) ** 2
            factor[act] *= grow[act]
            valid[:, act & (d < f.lost_m)] = False
    apply_outages(valid, t, faults)
    return factor, valid, pos_bias


def emulate_gnss(truth, spec: GnssSpec, seed: int, runs, faults=(), name: str = "gnss") -> SensorData:
    """Fixes of ``spec`` at its rate along ``truth`` for the Monte Carlo ``runs`` (see the module
    docstring): the antenna's offset (latency, lever arm), the faults' effects, then the noise
    and Markov error drawn per run."""
    smp = sampling(truth, spec.rate_hz, seed, runs, name)
    runs, B, step, t, M = smp.runs, smp.B, smp.step, smp.t, smp.M
    r_m, r_n = earth.radii(truth.lat_rad[::step])
    k_n, k_e = r_m + truth.h_m[::step], (r_n + truth.h_m[::step]) * np.cos(truth.lat_rad[::step])
    offset_n, vel_off = _antenna_offset(truth, spec, smp, k_n, k_e)
    factor, valid, pos_bias = _fault_effects(truth, faults, smp)

    pos_err = offset_n[None] + pos_bias[None]
    if np.any(spec.position_sigma):
        pos_err = pos_err + normals(smp.rng("position_noise"), (M, 3)) * spec.position_sigma * factor[None, :, None]
    if np.any(spec.markov_sigma):
        pos_err = pos_err + gauss_markov(smp.rng("position_markov"), M, step * truth.dt_s, spec.markov_sigma,
                                         spec.markov_tau_s)
    vel_err = np.broadcast_to(vel_off, (B, M, 3)).copy()
    if np.any(spec.velocity_sigma):
        vel_err = vel_err + normals(smp.rng("velocity_noise"), (M, 3)) * spec.velocity_sigma * factor[None, :, None]
    pos_err = np.broadcast_to(pos_err, (B, M, 3))

    lat_t, lon_t, h_t = truth.lat_rad[::step], truth.lon_rad[::step], truth.h_m[::step]
    h_acc = np.hypot(spec.position_sigma[0], spec.position_sigma[1]) * factor
    v_acc = spec.position_sigma[2] * factor
    s_acc = np.linalg.norm(spec.velocity_sigma) * factor
    data = SensorData(
        name=name, kind="gnss", t_s=t,
        values={"lat_rad": lat_t + pos_err[..., 0] / k_n, "lon_rad": lon_t + pos_err[..., 1] / k_e,
                "h_m": h_t - pos_err[..., 2],
                "fix_type": np.where(valid, 3, 0).astype(np.int8),
                "h_acc_m": np.broadcast_to(h_acc, (B, M)).copy(),
                "v_acc_m": np.broadcast_to(v_acc, (B, M)).copy(),
                "s_acc_mps": np.broadcast_to(s_acc, (B, M)).copy()},
        valid=valid, errors={"pos_error_n_m": np.array(pos_err), "vel_error_n_mps": vel_err},
        meta={"rate_hz": spec.rate_hz, "runs": runs, "seed": seed})
    if spec.velocity_output:
        data.values["vel_n_mps"] = truth.vel_n_mps[::step] + vel_err
    return data


def position_channels(data: SensorData, truth, run: int = 0) -> list:
    """The plot's channels of a position fix (GNSS, the landmark camera): north and east from
    the track's start and the height, m, and the NED velocity where there is one."""
    s, v, t = truth_step(data, truth), data.values, data.t_s
    lat0, lon0 = truth.lat_rad[0], truth.lon_rad[0]
    n_m, e_m = earth.local_ne(v["lat_rad"][run], v["lon_rad"][run], lat0, lon0)
    n_t, e_t = earth.local_ne(truth.lat_rad[s], truth.lon_rad[s], lat0, lon0)
    out = [("north", "m", t, n_m, n_t), ("east", "m", t, e_m, e_t), ("height", "m", t, v["h_m"][run], truth.h_m[s])]
    if "vel_n_mps" in v:
        out += [(f"velocity {a}", "m/s", t, v["vel_n_mps"][run, :, j], truth.vel_n_mps[s, j])
                for j, a in enumerate(("north", "east", "down"))]
    return out


def fill_in_loop(data: SensorData, j: int, sample) -> None:
    """Fix ``j`` in the closed loop: the runs' true position (and velocity) of ``sample`` (a
    :class:`~navsim.sensors.registry.LoopSample`) plus each run's own drawn error."""
    v, lat, h = data.values, sample.lat_rad, sample.h_m
    err = data.errors["pos_error_n_m"][:, j]
    r_m, r_n = earth.radii(lat)
    v["lat_rad"][:, j] = lat + err[:, 0] / (r_m + h)
    v["lon_rad"][:, j] = sample.lon_rad + err[:, 1] / ((r_n + h) * np.cos(lat))
    v["h_m"][:, j] = h - err[:, 2]
    if "vel_n_mps" in v:
        v["vel_n_mps"][:, j] = sample.vel_n_mps + data.errors["vel_error_n_mps"][:, j]


def refuse_in_loop(config) -> Refusal | None:
    """Latency, a lever arm and interference depend on the trajectory: not in the closed loop."""
    spec = config.spec
    if spec.latency_s or np.any(spec.lever_arm_b) or any(f.type == "interference" for f in config.faults):
        return Refusal("has latency, a lever arm or interference, which depend on the trajectory",
                       "with closed_loop, a GNSS whose errors do not",
                       "override latency: 0 s and lever_arm: [0, 0, 0] m")
    return None


def linear_forms(term: str):
    """The linear form (:class:`~navsim.sensors.registry.LinearError`) of the GNSS error
    ``term`` as :func:`emulate_gnss` applies it (NED, per fix), or None: the latency and the
    lever arm (errors set by the trajectory, left to Monte Carlo)."""
    def form(spec: GnssSpec) -> LinearError | None:
        if term == "position_sigma":
            return LinearError("pos_n", white=np.asarray(spec.position_sigma, float) ** 2)
        if term == "velocity_sigma":
            return LinearError("vel_n", white=np.asarray(spec.velocity_sigma, float) ** 2)
        if term == "markov_sigma":
            s2 = np.asarray(spec.markov_sigma, float) ** 2
            return LinearError("pos_n", np.diag(s2), np.full(3, spec.markov_tau_s), 2.0 * s2 / spec.markov_tau_s)
        return None
    return form


KIND = register(SensorKind(
    name="gnss", spec=GnssSpec, role="position_fix", description="GNSS / BeiDou receiver: position and velocity fixes",
    fields={"rate_hz": Field("rate_hz", None, "plain"), "position_sigma": Field("position_sigma", "length", "3"),
            "horizontal_sigma": Field("position_sigma", "length", "h"),
            "vertical_sigma": Field("position_sigma", "length", "v"),
            "velocity_sigma": Field("velocity_sigma", "speed", "3"),
            "markov_sigma": Field("markov_sigma", "length", "3"), "markov_tau": Field("markov_tau_s", "time", "1"),
            "latency": Field("latency_s", "time", "1"), "lever_arm": Field("lever_arm_b", "length", "3", signed=True),
            "velocity_output": Field("velocity_output", None, "bool")},
    outputs=(Output("lat_rad", "rad"), Output("lon_rad", "rad"), Output("h_m", "m", role="height"),
             Output("fix_type", "1"), Output("h_acc_m", "m"), Output("v_acc_m", "m"), Output("s_acc_mps", "m/s"),
             Output("vel_n_mps", "m/s", role="velocity", when=lambda spec: spec.velocity_output,
                    axes=("north", "east", "down"))),
    errors=tuple(ErrorTerm(n, linear=linear_forms(n)) for n in ("position_sigma", "velocity_sigma", "markov_sigma",
                                                                 "latency_s", "lever_arm_b")),
    emulate=emulate_gnss, faults=("outage", "bias", "degraded", "interference"), channels=position_channels,
    vector_bias=True, in_loop=InLoop(fill_in_loop, refuse_in_loop)))
