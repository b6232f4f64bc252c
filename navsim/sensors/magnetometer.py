"""Magnetometer emulator: the World Magnetic Model field, hard and soft iron, noise.

``values['mag_b_T']`` ``(B, M, 3)`` in tesla, body axes: ``S (C_bn m_n) + b + n``, with ``m_n``
the WMM field (from the ``ahrs`` package's WMM coefficients) at the true position and the spec's
date, ``S`` the soft-iron matrix (fixed plus a random deviation per run) and ``b`` the hard-iron
offset (fixed plus random). ``errors``: ``hard_iron_T`` ``(B, 1, 3)``, ``soft_iron`` ``(B, 3, 3)``,
``field_n_T`` ``(M, 3)``, the true Earth field, ``disturbance_T`` ``(M, 3)`` the body-fixed
field of ``disturbance`` faults (P4's magnetic disturbance).
"""

from __future__ import annotations

import datetime
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from navsim.foundations.transform import dcm_from_euler_one, dcm_from_quat
from navsim.sensors.base import SensorData, apply_outages, normals, sampling, truth_step, zeros3
from navsim.sensors.registry import ErrorTerm, Field, InLoop, Output, SensorKind, register


#: the date of the WMM field where a magnetometer's spec or data does not give one
WMM_DATE = "2025-01-01"


@dataclass(frozen=True)
class MagnetometerSpec:
    """Magnetometer: WMM Earth field, hard-iron offset, soft-iron matrix, white noise (tesla)."""

    rate_hz: float = 10.0
    hard_iron: np.ndarray = zeros3()          #: fixed offset, T
    hard_iron_sigma: np.ndarray = zeros3()    #: random offset per run, T
    soft_iron: np.ndarray = field(default_factory=lambda: np.eye(3))   #: fixed matrix
    soft_iron_sigma: float = 0.0              #: random deviation of the matrix per run
    noise: np.ndarray = zeros3()              #: white noise std, T
    date: str = WMM_DATE                      #: epoch of the WMM field

WMM_SPACING_S = 10.0      #: the field is evaluated this often along the track and interpolated


@lru_cache(maxsize=4096)
def wmm_field_n_T(lat_deg: float, lon_deg: float, h_m: float, date: str) -> tuple[float, float, float]:
    """WMM field (north, east, down), tesla."""
    from ahrs.utils import WMM
    # ahrs' WMM computes nothing when the latitude or the longitude is exactly 0 (it takes 0 for
    # "not given"): 1e-9 deg off (0.1 mm) is the same field
    lat_deg, lon_deg = lat_deg or 1e-9, lon_deg or 1e-9
    w = WMM(date=datetime.date.fromisoformat(date), latitude=lat_deg, longitude=lon_deg,
            height=h_m / 1000.0)
    return (w.X * 1e-9, w.Y * 1e-9, w.Z * 1e-9)


def field_along(truth, t, date: str) -> np.ndarray:
    """WMM field at the truth positions at times ``t`` ``(M, 3)``."""
    knots = np.arange(truth.t_s[0], truth.t_s[-1] + WMM_SPACING_S, WMM_SPACING_S)
    lat = np.degrees(np.interp(knots, truth.t_s, truth.lat_rad))
    lon = np.degrees(np.interp(knots, truth.t_s, truth.lon_rad))
    h = np.interp(knots, truth.t_s, truth.h_m)
    f = np.array([wmm_field_n_T(round(a, 4), round(b, 4), round(c, 0), date) for a, b, c in zip(lat, lon, h)])
    return np.stack([np.interp(t, knots, f[:, j]) for j in range(3)], axis=-1)


def emulate_magnetometer(truth, spec: MagnetometerSpec, seed: int, runs, faults=(),
                         name: str = "magnetometer") -> SensorData:
    smp = sampling(truth, spec.rate_hz, seed, runs, name)
    runs, B, step, t, M = smp.runs, smp.B, smp.step, smp.t, smp.M
    m_n = field_along(truth, t, spec.date)
    C_nb = dcm_from_quat(truth.quat_nb[::step])
    m_b = np.einsum("nji,nj->ni", C_nb, m_n)
    soft = np.broadcast_to(spec.soft_iron, (B, 3, 3)).copy()
    if spec.soft_iron_sigma:
        soft += normals(smp.rng("soft_iron"), (3, 3)) * spec.soft_iron_sigma
    hard = np.broadcast_to(spec.hard_iron, (B, 1, 3)).copy()
    if np.any(spec.hard_iron_sigma):
        hard += (normals(smp.rng("hard_iron"), (3,)) * spec.hard_iron_sigma)[:, None, :]
    out = np.einsum("bij,nj->bni", soft, m_b) + hard
    disturbance = np.zeros((M, 3))
    for f in faults:
        if f.type == "disturbance":
            disturbance += f.ramp(t)[:, None] * f.value
    out += disturbance
    if np.any(spec.noise):
        out += normals(smp.rng("noise"), (M, 3)) * spec.noise
    valid = np.ones((B, M), bool)
    apply_outages(valid, t, faults)
    return SensorData(name=name, kind="magnetometer", t_s=t, values={"mag_b_T": out}, valid=valid,
                      errors={"hard_iron_T": hard, "soft_iron": soft, "field_n_T": m_n,
                              "disturbance_T": disturbance},
                      meta={"rate_hz": spec.rate_hz, "runs": runs, "seed": seed, "date": spec.date})


def prepare_magnetometer_in_loop(data: SensorData, static) -> None:
    """A magnetometer emulated on the closed loop's static record ``static`` made ready to fly:
    each run's white noise (its output less the static attitude's field through its soft and
    hard iron and the disturbance) kept in ``errors`` for :func:`fill_magnetometer_in_loop`."""
    e = data.errors
    s = truth_step(data, static)
    m_b = np.einsum("nji,nj->ni", dcm_from_quat(static.quat_nb[s]), e["field_n_T"])
    e["noise_T"] = data.values["mag_b_T"] - np.einsum("bij,nj->bni", e["soft_iron"], m_b) - e["hard_iron_T"] \
        - e["disturbance_T"]


def fill_magnetometer_in_loop(data: SensorData, j: int, sample) -> None:
    """Sample ``j`` of a magnetometer in the closed loop: the Earth's field at the start (WMM;
    a flight of a few kilometres sees it change by nanotesla) in each run's true body axes
    (``sample``: a :class:`~navsim.sensors.registry.LoopSample`), through its soft and hard iron,
    plus the disturbance and its drawn noise. The attitude is turned run by run (scalar
    arithmetic: a batch gives each run what it would give alone)."""
    e = data.errors
    m_n = e["field_n_T"][j]
    for b, (roll, pitch, yaw) in enumerate(sample.euler_rad.tolist()):
        m_b = dcm_from_euler_one(roll, pitch, yaw).T @ m_n
        data.values["mag_b_T"][b, j] = e["soft_iron"][b] @ m_b + e["hard_iron_T"][b, 0] + e["disturbance_T"][j] \
            + e["noise_T"][b, j]


def magnetometer_channels(data: SensorData, truth, run: int = 0) -> list:
    """The plot's channels: each axis's field (µT) against the Earth's field in body axes."""
    s = truth_step(data, truth)
    clean = np.einsum("nji,nj->ni", dcm_from_quat(truth.quat_nb[s]), data.errors["field_n_T"]) * 1e6
    return [(f"field {axis}", "µT", data.t_s, data.values["mag_b_T"][run, :, j] * 1e6, clean[:, j])
            for j, axis in enumerate("xyz")]


KIND = register(SensorKind(
    name="magnetometer", spec=MagnetometerSpec, role="heading",
    description="three-axis magnetometer (WMM field, hard and soft iron)",
    fields={"rate_hz": Field("rate_hz", None, "plain"),
            "hard_iron": Field("hard_iron", "magnetic_field", "3", signed=True),
            "hard_iron_sigma": Field("hard_iron_sigma", "magnetic_field", "3"),
            "soft_iron": Field("soft_iron", "dimensionless", "33", signed=True),
            "soft_iron_sigma": Field("soft_iron_sigma", "dimensionless", "1"),
            "noise": Field("noise", "magnetic_field", "3"), "date": Field("date", None, "str")},
    outputs=(Output("mag_b_T", "T", axes=("x", "y", "z")),),
    errors=tuple(ErrorTerm(n) for n in ("hard_iron", "hard_iron_sigma", "soft_iron", "soft_iron_sigma", "noise")),
    emulate=emulate_magnetometer, faults=("outage", "disturbance"), channels=magnetometer_channels,
    in_loop=InLoop(fill_magnetometer_in_loop, prepare=prepare_magnetometer_in_loop)))
