"""An IMU's vibration: what :class:`Vibration` declares (a sine, a band of random noise, or the
tones of the flight's own rotors) and its signal at the IMU's samples, ``(B, n, 3)`` per triad,
added to the measured rates and specific forces by :mod:`navsim.sensors.imu`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from navsim.foundations.errors import ScenarioError
from navsim.sensors.base import normals, zeros3
from navsim.sensors.units import UnitError


@dataclass(frozen=True)
class Tone:
    """One tone of a rotor vibration: at ``order`` times each rotor's turning frequency, its
    amplitude ``level`` relative to the other tones'."""

    order: float = 1.0
    level: float = 1.0


#: a rotor vibration's tones where its entry gives none: the shaft's frequency (an unbalanced
#: rotor), the blade pass of a two-bladed propeller and its harmonic
ROTOR_TONES = (Tone(1.0, 1.0), Tone(2.0, 0.5), Tone(4.0, 0.25))


@dataclass(frozen=True)
class Vibration:
    """Vibration seen by the accelerometers (and, if ``gyro_amplitude``, the gyros).

    ``type: sine``: ``amplitude`` (peak, m/s^2 per axis) at ``frequency_hz``, random phase per run.
    ``type: random``: band-limited Gaussian noise in ``band_hz`` whose peak (3 sigma) is
    ``amplitude``.
    ``type: rotor``: made by the flight's rotors (the truth's ``rotor_rpm``): on each axis, each
    rotor's ``tones`` at their orders of its turning frequency, each tone of rotor and axis with
    a phase of its own per run, growing with the rotor's speed squared (an unbalanced rotor's
    force); ``amplitude`` is the peak (3 sigma over runs and time) of their sum with every
    rotor turning at ``reference_hz``.
    """

    type: str = "sine"
    amplitude: np.ndarray = zeros3()
    gyro_amplitude: np.ndarray = zeros3()
    frequency_hz: float = 30.0
    band_hz: tuple[float, float] = (10.0, 40.0)
    tones: tuple[Tone, ...] = ROTOR_TONES
    reference_hz: float = 0.0

    def __post_init__(self):
        if self.type == "rotor" and not self.reference_hz > 0.0:
            raise UnitError("a rotor vibration needs reference_hz: the rotor frequency (Hz) at which amplitude is "
                            "its peak, e.g. a hover's")
        if self.type == "rotor" and not self.tones:
            raise UnitError("a rotor vibration needs at least one tone ({order, level})")


class RotorMotion(NamedTuple):
    """The flight's rotors at the IMU's samples (:class:`~navsim.sensors.imu.SampledMotion`):
    their speeds and angles, and the IMU's name for messages."""

    rpm: np.ndarray | None           #: (n, R) each rotor's speed, r/min (None: no rotor)
    angle_rad: np.ndarray | None     #: (n, R) each rotor's angle turned, rad
    sensor: str                      #: the IMU's name in the scenario


def band_vibration(gens, t: np.ndarray, vib: Vibration, rate_hz: float, amp: np.ndarray):
    """A ``sine`` or ``random`` vibration (:class:`Vibration`) at the IMU's sample times ``t``,
    ``(B, n, 3)`` (or 0 where ``amp``, the peak per axis, is), from the runs' generators ``gens``;
    one at or above the IMU's Nyquist frequency is refused."""
    if not np.any(amp):
        return 0.0
    if vib.type == "sine":
        if vib.frequency_hz >= 0.5 * rate_hz:
            raise ScenarioError(f"vibration at {vib.frequency_hz:g} Hz is above the IMU's Nyquist "
                                f"frequency ({0.5 * rate_hz:g} Hz)", key="sensors.imu.vibration")
        phase = np.stack([g.uniform(0.0, 2 * np.pi, 3) for g in gens])
        return amp * np.sin(2 * np.pi * vib.frequency_hz * t[None, :, None] + phase[:, None, :])
    lo, hi = vib.band_hz
    if hi >= 0.5 * rate_hz:
        raise ScenarioError(f"vibration band {lo:g}-{hi:g} Hz reaches the IMU's Nyquist frequency "
                            f"({0.5 * rate_hz:g} Hz)", key="sensors.imu.vibration")
    # scipy.signal only here: a Monte Carlo chunk without band-limited vibration does not load
    # it (76 MB on top of numpy alone; 3 MB in a worker, whose imports load scipy.stats)
    from scipy.signal import butter, sosfilt
    sos = butter(4, [lo, hi], btype="bandpass", fs=rate_hz, output="sos")
    w = normals(gens, (len(t) + 200, 3))
    x = sosfilt(sos, w, axis=1)[:, 200:, :]
    # scale to peak = 3 sigma, using the filter's exact noise gain
    x /= x.std(axis=1, keepdims=True)
    return x * (amp / 3.0)


def rotor_vibration(gens, rotors: RotorMotion, vib: Vibration, rate_hz: float, amp: np.ndarray):
    """A rotor vibration (:class:`Vibration`, ``type: rotor``) at the IMU's samples, ``(B, n, 3)``
    (or 0 where ``amp`` is, or no rotor turns): the tones of every rotor of the flight, point-sampled (so a tone
    at or above the IMU's Nyquist frequency is refused: it would alias, as a MEMS IMU read
    slower than its rotors see)."""
    rpm, angle = rotors.rpm, rotors.angle_rad
    if not np.any(amp) or rpm is None or not np.any(rpm):      # no rotor turning (a parked vehicle): none
        return 0.0
    top = max(t.order for t in vib.tones) * rpm.max() / 60.0
    if top >= 0.5 * rate_hz:
        raise ScenarioError(f"rotor tones up to {top:.0f} Hz reach the IMU's Nyquist frequency ({0.5 * rate_hz:g} Hz): "
                            "point-sampled, they would alias", key=f"sensors.{rotors.sensor}.vibration",
                            expected=f"an IMU rate above {2 * top:.0f} Hz, or a random vibration in its band")
    R, levels = rpm.shape[1], np.array([t.level for t in vib.tones])
    # each tone of each rotor and axis a sinusoid of random phase: their sum's variance is
    # R sum(level^2) / 2 (scale)^2, its 3 sigma the amplitude
    scale = np.asarray(amp, float) / (3.0 * math.sqrt(0.5 * R * float(np.sum(levels ** 2))))
    phase = np.stack([g.uniform(0.0, 2.0 * np.pi, (R, len(levels), 3)) for g in gens])    # (B, R, K, 3)
    gain = (rpm / (60.0 * vib.reference_hz)) ** 2
    out = np.zeros((len(gens), len(rpm), 3))
    for r in range(R):
        for k, tone in enumerate(vib.tones):
            arg = tone.order * angle[:, r]
            s, c = (gain[:, r] * np.sin(arg))[None, :, None], (gain[:, r] * np.cos(arg))[None, :, None]
            out += tone.level * (s * np.cos(phase[:, None, r, k]) + c * np.sin(phase[:, None, r, k]))
    return out * scale
