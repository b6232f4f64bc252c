"""Truth-model specifications of the sensors, in SI.

A spec says how a sensor corrupts the truth. It is *not* what an estimator assumes: the filter's
noise model is a separate object (built from a catalog entry of its own), so model mismatch can
be studied. Every field is SI; three-axis fields are ``(3,)`` arrays (x, y, z body axes, or
north, east, down for position errors). :func:`disable` switches error sources off by name;
:func:`ideal` switches all of them off.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np


def _zeros():
    return field(default_factory=lambda: np.zeros(3))


@dataclass(frozen=True)
class AxisErrors:
    """Errors of a triad (gyros or accelerometers). Units: rad/s (gyro) or m/s^2 (accel)."""

    bias: np.ndarray = _zeros()               #: fixed constant bias
    bias_sigma: np.ndarray = _zeros()         #: random constant, drawn per run and axis
    bias_instability: np.ndarray = _zeros()   #: Allan-deviation floor B (flicker convention)
    bias_instability_tau_s: float = 100.0     #: correlation time of its Gauss-Markov model
    markov_sigma: np.ndarray = _zeros()       #: first-order Gauss-Markov bias, std
    markov_tau_s: float = 3600.0              #: its correlation time
    noise_density: np.ndarray = _zeros()      #: white noise: ARW rad/s/rtHz, VRW m/s^2/rtHz
    random_walk: np.ndarray = _zeros()        #: rate / acceleration random walk, per rt(s)
    scale_factor: np.ndarray = _zeros()       #: fixed scale-factor error (ratio)
    scale_factor_sigma: np.ndarray = _zeros() #: random scale-factor error per run (ratio)
    misalignment_sigma: float = 0.0           #: random axis misalignment per run, rad
    quantization: float = 0.0                 #: LSB of the output, 0: none
    range: float = math.inf                   #: saturation, +/-


@dataclass(frozen=True)
class Vibration:
    """Vibration seen by the accelerometers (and, if ``gyro_amplitude``, the gyros).

    ``type: sine``: ``amplitude`` (peak, m/s^2 per axis) at ``frequency_hz``, random phase per run.
    ``type: random``: band-limited Gaussian noise in ``band_hz`` whose peak (3 sigma) is
    ``amplitude``.
    """

    type: str = "sine"
    amplitude: np.ndarray = _zeros()
    gyro_amplitude: np.ndarray = _zeros()
    frequency_hz: float = 30.0
    band_hz: tuple[float, float] = (10.0, 40.0)


@dataclass(frozen=True)
class ImuSpec:
    rate_hz: float = 100.0
    gyro: AxisErrors = field(default_factory=AxisErrors)
    accel: AxisErrors = field(default_factory=AxisErrors)
    vibration: tuple[Vibration, ...] = ()


@dataclass(frozen=True)
class GnssSpec:
    """GNSS receiver. Position errors NED (m), velocity errors NED (m/s)."""

    rate_hz: float = 1.0
    position_sigma: np.ndarray = _zeros()
    velocity_sigma: np.ndarray = _zeros()
    markov_sigma: np.ndarray = _zeros()       #: Gauss-Markov position error, m
    markov_tau_s: float = 300.0
    latency_s: float = 0.0
    lever_arm_b: np.ndarray = _zeros()        #: antenna position from the CG, body axes, m
    velocity_output: bool = True              #: False: a position-only receiver (P0's BD-2)


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


@dataclass(frozen=True)
class RadarAltimeterSpec:
    """Radar altimeter (P2): sigma = noise + noise_ratio * H, range limits, slant error."""

    rate_hz: float = 10.0
    noise: float = 0.3                        #: m
    noise_ratio: float = 0.03                 #: of the height
    min_range: float = 0.0                    #: m
    max_range: float = 1500.0                 #: m
    beam_half_width: float = math.radians(20.0)  #: rad; tilt beyond this lengthens the range
    tilt_noise_gain: float = 1.0              #: extra sigma factor per rad of tilt
    wave_height: float = 0.0                  #: significant wave height (sea state), m


@dataclass(frozen=True)
class MagnetometerSpec:
    """Magnetometer: WMM Earth field, hard-iron offset, soft-iron matrix, white noise (tesla)."""

    rate_hz: float = 10.0
    hard_iron: np.ndarray = _zeros()          #: fixed offset, T
    hard_iron_sigma: np.ndarray = _zeros()    #: random offset per run, T
    soft_iron: np.ndarray = field(default_factory=lambda: np.eye(3))   #: fixed matrix
    soft_iron_sigma: float = 0.0              #: random deviation of the matrix per run
    noise: np.ndarray = _zeros()              #: white noise std, T
    date: str = "2025-01-01"                  #: epoch of the WMM field


@dataclass(frozen=True)
class CameraSpec:
    """Landmark camera (P1): a downward camera sees anchor points of known position."""

    rate_hz: float = 1.0
    half_fov: float = math.radians(30.0)      #: rad
    max_range: float = 1500.0                 #: m
    noise: float = 2.0                        #: position-fix std at 0 m, m
    noise_ratio: float = 0.01                 #: extra std per metre of range
    landmarks: tuple[tuple[float, float, float], ...] = ()   #: (lat_deg, lon_deg, h_m)


SPEC_TYPES = {"imu": ImuSpec, "gnss": GnssSpec, "baro": BaroSpec, "ads": AdsSpec,
              "radar_altimeter": RadarAltimeterSpec, "magnetometer": MagnetometerSpec,
              "camera": CameraSpec}

#: error sources that :func:`ideal` switches off, per kind (dotted paths)
ERROR_FIELDS = {
    "imu": [f"{g}.{f}" for g in ("gyro", "accel") for f in (
        "bias", "bias_sigma", "bias_instability", "markov_sigma", "noise_density", "random_walk",
        "scale_factor", "scale_factor_sigma", "misalignment_sigma", "quantization", "range")]
    + ["vibration"],
    "gnss": ["position_sigma", "velocity_sigma", "markov_sigma", "latency_s", "lever_arm_b"],
    "baro": ["offset", "offset_sigma", "markov_sigma", "noise"],
    "ads": ["static_noise", "static_bias_sigma", "total_noise", "total_bias_sigma",
            "temperature_noise", "vane_noise"],
    "radar_altimeter": ["noise", "noise_ratio", "tilt_noise_gain", "wave_height",
                        "beam_half_width"],
    "magnetometer": ["hard_iron", "hard_iron_sigma", "soft_iron", "soft_iron_sigma", "noise"],
    "camera": ["noise", "noise_ratio"],
}


def _off_value(current):
    if isinstance(current, tuple):
        return ()
    if isinstance(current, np.ndarray):
        return np.eye(3) if current.shape == (3, 3) else np.zeros_like(current)
    if isinstance(current, float) and math.isinf(current):
        return math.inf
    return 0.0


def disable(spec, paths):
    """A copy of ``spec`` with the error sources at dotted ``paths`` switched off
    (``range`` and ``beam_half_width`` off mean no saturation / no slant error)."""
    for path in paths:
        head, _, rest = path.partition(".")
        current = getattr(spec, head)
        if rest:
            spec = dataclasses.replace(spec, **{head: disable(current, [rest])})
        else:
            off = _off_value(current)
            if head in ("range",):
                off = math.inf
            if head == "beam_half_width":
                off = math.pi / 2
            spec = dataclasses.replace(spec, **{head: off})
    return spec


def kind_of(spec) -> str:
    for kind, typ in SPEC_TYPES.items():
        if isinstance(spec, typ):
            return kind
    raise TypeError(type(spec))


def ideal(spec):
    """The spec with every error source off: the sensor reproduces the truth."""
    return disable(spec, ERROR_FIELDS[kind_of(spec)])
