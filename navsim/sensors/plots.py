"""Pictures of the sensors: each sensor's output against the truth and its error over a flight
(the channels each kind declares, :class:`navsim.sensors.registry.SensorKind`), an IMU's error
spectrum with the flight's rotor frequencies marked, and an IMU's Allan deviation against its
datasheet."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from navsim.flight.truth import Truth
from navsim.foundations.outputs import write_atomic
from navsim.sensors import registry
from navsim.sensors.base import SensorData, truth_step
from navsim.sensors.imu import FLICKER_FLOOR, emulate_imu


def channels(data: SensorData, truth, run: int = 0):
    """``(label, unit, t, measured, true)`` series to plot for ``data`` (run ``run``): its kind's
    ``channels``, or else each of its outputs that names a ``truth`` field against that field
    (:class:`~navsim.sensors.registry.Output`)."""
    kind = registry.get(data.kind)
    if kind.channels is not None:
        return kind.channels(data, truth, run)
    s = truth_step(data, truth)
    out = []
    for o in kind.outputs:
        if o.truth is None or o.name not in data.values:
            continue
        meas, true = data.values[o.name][run], getattr(truth, o.truth)[s]
        label = o.label or o.name
        if meas.ndim == 1:
            out.append((label, o.unit, data.t_s, meas, true))
        else:
            axes = o.axes or tuple(str(j) for j in range(meas.shape[-1]))
            out += [(f"{label} {a}", o.unit, data.t_s, meas[:, j], true[:, j]) for j, a in enumerate(axes)]
    return out


def plot_sensor(data: SensorData, truth, path: str | Path, run: int = 0) -> Path:
    """One PNG: each channel's output and truth (left) and its error (right); gaps where the
    sensor gave no output."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    chans = channels(data, truth, run)
    valid = data.valid[run]
    fig, axs = plt.subplots(len(chans), 2, figsize=(12, 2.1 * len(chans) + 0.8), sharex=True,
                            squeeze=False)
    for (label, unit, t, meas, true), (a, b) in zip(chans, axs):
        m = np.where(valid, meas, np.nan)
        a.plot(t, true, color="k", lw=1.0, label="truth")
        a.plot(t, m, ".", ms=1.5 if len(t) > 2000 else 3, alpha=0.6, label="sensor")
        a.set_ylabel(f"{label}, {unit}", fontsize=8)
        err = m - true
        b.plot(t, err, lw=0.6 if len(t) > 2000 else 1.0, color="tab:red")
        b.axhline(0.0, color="k", lw=0.5)
        b.set_ylabel(f"error, {unit}", fontsize=8)
        finite = err[np.isfinite(err)]
        if finite.size:
            b.set_title(f"error: mean {finite.mean():.3g}, std {finite.std():.3g} {unit}", fontsize=8)
        for ax in (a, b):
            ax.grid(alpha=0.3)
            if (~valid).any():
                ax.fill_between(t, 0, 1, where=~valid, transform=ax.get_xaxis_transform(),
                                color="0.85", zorder=0, label="no output")
    axs[0, 0].legend(fontsize=7, loc="best")
    axs[-1, 0].set_xlabel("time, s")
    axs[-1, 1].set_xlabel("time, s")
    fig.suptitle(f"{data.name} ({data.kind}, {data.meta.get('rate_hz', 0):g} Hz): output and error, run {run}",
                 fontsize=10)
    fig.tight_layout()
    path = write_atomic(Path(path), lambda p: fig.savefig(p, dpi=110))
    plt.close(fig)
    return path


#: the orders of a rotor's turning frequency marked on an IMU's spectrum where its vibration
#: names none (the shaft's, the blade pass of two blades)
MARKED_ORDERS = (1.0, 2.0)


def rotor_hz(truth, t_s: np.ndarray) -> float | None:
    """The flight's rotors' median turning frequency over the times ``t_s`` (Hz), None where no
    rotor turns."""
    rpm = truth.rotor_rpm
    if rpm.shape[1] == 0 or not np.any(rpm):
        return None
    k = np.clip(np.searchsorted(truth.t_s, t_s), 0, len(truth.t_s) - 1)
    turning = rpm[k][rpm[k] > 0.0]
    return float(np.median(turning)) / 60.0 if turning.size else None


def plot_spectrum(data: SensorData, truth, path: str | Path, orders=MARKED_ORDERS, run: int = 0) -> Path:
    """One PNG: an IMU's error spectrum (its output less the truth: noise, vibration, biases) on
    each accelerometer and gyro axis, run ``run``, amplitude spectral density by Welch's method;
    the flight's rotor frequency times each of ``orders`` marked (a tone at or above the
    Nyquist frequency would alias: named in the title)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.signal import welch

    rate = float(data.meta["rate_hz"])
    f_rotor = rotor_hz(truth, data.t_s)
    fig, axs = plt.subplots(2, 1, figsize=(10, 7.5), sharex=True)
    chans = channels(data, truth, run)           # the gyro's three axes, then the accelerometer's
    for ax, (label, unit, picked) in zip(axs, (("accelerometer", "m/s²", chans[3:6]), ("gyro", "deg/s", chans[:3]))):
        for name, _, _, meas, true in picked:
            err = np.asarray(meas - true, float)
            f, psd = welch(err - err.mean(), fs=rate, nperseg=min(len(err), 4096))
            ax.semilogy(f[1:], np.sqrt(psd[1:]), lw=0.8, label=name)
        ax.set_ylabel(f"{label} error, {unit}/√Hz")
        ax.grid(alpha=0.3, which="both")
    marked = [(o, o * f_rotor) for o in orders] if f_rotor is not None else []
    for ax in axs:
        for order, f in marked:
            if f < 0.5 * rate:
                ax.axvline(f, color="k", ls="--", lw=0.7, alpha=0.6)
                ax.text(f, 1.0, f" {order:g}× rotor, {f:.1f} Hz", transform=ax.get_xaxis_transform(),
                        rotation=90, va="top", ha="left", fontsize=7,
                        bbox=dict(facecolor="white", alpha=0.8, lw=0, pad=1))
        ax.legend(fontsize=7, loc="lower left")
    axs[-1].set_xlabel("frequency, Hz")
    above = [f for _, f in marked if f >= 0.5 * rate]
    note = (f"rotors at {f_rotor:.1f} Hz" + (f"; tones at {', '.join(f'{f:.0f}' for f in above)} Hz above the "
                                             f"Nyquist frequency" if above else "")) if f_rotor else "no rotors turning"
    fig.suptitle(f"{data.name} ({data.meta.get('rate_hz', 0):g} Hz): error spectrum, run {run}; {note}", fontsize=10)
    fig.tight_layout()
    path = write_atomic(Path(path), lambda p: fig.savefig(p, dpi=110))
    plt.close(fig)
    return path


#: the record an IMU's Allan deviation is computed over, s (the vehicle at rest)
ALLAN_RECORD_S = 2000.0
#: per triad: the rate's key, the plot's scale from SI and unit, the white noise's name and unit
_TRIADS = (("gyro", "omega_ib_b_rps", 180 / np.pi * 3600, "deg/h", "ARW"),
           ("accel", "f_b_mps2", 1e6 / 9.80665, "µg", "VRW"))


def allan_deviation(spec, seed: int, duration_s: float = ALLAN_RECORD_S):
    """The overlapping Allan deviation of each axis of an IMU emulated at rest for
    ``duration_s``: ``{triad: (tau_s (K,), adev (3, K) in SI)}`` (allantools, octave taus)."""
    # allantools only here: a Monte Carlo worker, which imports every sensor kind and so this
    # module, does not load it (76 MB on top of numpy alone; 3 MB in a worker, whose imports
    # load scipy.stats)
    import allantools
    truth = Truth.static(duration_s, rate_hz=spec.rate_hz)
    data = emulate_imu(truth, spec, seed, [0])
    out = {}
    for triad, key, *_ in _TRIADS:
        err = data.values[key][0] - (truth.omega_ib_b_rps if key == "omega_ib_b_rps" else truth.f_b_mps2)
        curves = [allantools.oadev(err[:, j] - err[:, j].mean(), rate=spec.rate_hz, data_type="freq",
                                   taus="octave") for j in range(3)]
        tau = curves[0][0]
        out[triad] = (tau, np.stack([np.interp(tau, c[0], c[1]) for c in curves]))
    return out


def datasheet_lines(e, tau: np.ndarray) -> dict:
    """The datasheet's Allan lines of a triad (SI, the axes' mean): white noise ``N / sqrt(tau)``,
    the bias-instability floor ``0.664 B``, the random walk ``K sqrt(tau / 3)``; those it gives."""
    lines = {}
    for name, value, shape in (("white noise", e.noise_density, lambda v: v / np.sqrt(tau)),
                               ("bias instability", e.bias_instability, lambda v: FLICKER_FLOOR * v * np.ones_like(tau)),
                               ("random walk", e.random_walk, lambda v: v * np.sqrt(tau / 3.0))):
        v = float(np.mean(value))
        if v > 0:
            lines[name] = shape(v)
    return lines


def plot_allan(name: str, spec, seed: int, path: str | Path) -> tuple[Path, dict]:
    """``allan_<name>.png``: each axis's Allan deviation of the emulated IMU at rest against the
    datasheet's lines, gyros (deg/h) and accelerometers (µg) against tau (s). Returns the path
    and, per triad, the white-noise density read at the shortest tau over the datasheet's."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    adev = allan_deviation(spec, seed)
    fig, axs = plt.subplots(1, 2, figsize=(12, 5))
    ratios = {}
    for ax, (triad, _, scale, unit, white) in zip(axs, _TRIADS):
        tau, dev = adev[triad]
        e = getattr(spec, triad)
        for j, axis in enumerate("xyz"):
            ax.loglog(tau, dev[j] * scale, lw=1.2, label=f"emulated, {axis}")
        for label, line in datasheet_lines(e, tau).items():
            ax.loglog(tau, line * scale, "--", lw=1.0, color="k" if label == "white noise" else "0.45",
                      label=f"datasheet: {white if label == 'white noise' else label}")
        if np.mean(e.noise_density) > 0:
            ratios[triad] = float(np.mean(dev[:, 0] * np.sqrt(tau[0])) / np.mean(e.noise_density))
        ax.set_xlabel("averaging time tau, s")
        ax.set_ylabel(f"Allan deviation, {unit}")
        ax.set_title(f"{'gyros' if triad == 'gyro' else 'accelerometers'} at rest", fontsize=9)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.suptitle(f"{name}: Allan deviation of the emulated IMU ({ALLAN_RECORD_S:g} s at rest, "
                 f"{spec.rate_hz:g} Hz) against its datasheet", fontsize=10)
    fig.tight_layout()
    path = write_atomic(Path(path), lambda p: fig.savefig(p, dpi=110))
    plt.close(fig)
    return path, ratios
