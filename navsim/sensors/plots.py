"""Pictures of the sensors: each sensor's output against the truth and its error over a flight."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from navsim.foundations import earth
from navsim.foundations.outputs import write_atomic
from navsim.foundations.transform import dcm_from_quat
from navsim.sensors.base import SensorData


def channels(data: SensorData, truth, run: int = 0):
    """``(label, unit, t, measured, true)`` series to plot for ``data`` (run ``run``)."""
    s = slice(None, None, round(len(truth.t_s) / len(data.t_s))) if len(data.t_s) else slice(None)
    v = data.values
    t = data.t_s
    out = []
    if data.kind == "imu":
        k = max(1, round(truth.meta.get("rate_hz", 100.0) / data.meta["rate_hz"]))
        for j, axis in enumerate("xyz"):
            out.append((f"gyro {axis}", "deg/s", t, np.degrees(v["omega_ib_b_rps"][run, :, j]),
                        np.degrees(truth.omega_ib_b_rps[::k, j])))
        for j, axis in enumerate("xyz"):
            out.append((f"accel {axis}", "m/s²", t, v["f_b_mps2"][run, :, j], truth.f_b_mps2[::k, j]))
    elif data.kind in ("gnss", "camera"):
        lat0, lon0 = truth.lat_rad[0], truth.lon_rad[0]
        n_m, e_m = earth.local_ne(v["lat_rad"][run], v["lon_rad"][run], lat0, lon0)
        n_t, e_t = earth.local_ne(truth.lat_rad[s], truth.lon_rad[s], lat0, lon0)
        out += [("north", "m", t, n_m, n_t), ("east", "m", t, e_m, e_t),
                ("height", "m", t, v["h_m"][run], truth.h_m[s])]
        if "vel_n_mps" in v:
            out.append(("speed north", "m/s", t, v["vel_n_mps"][run, :, 0], truth.vel_n_mps[s, 0]))
    elif data.kind == "baro":
        out.append(("baro height", "m", t, v["h_baro_m"][run], truth.h_m[s]))
    elif data.kind == "ads":
        out += [("static pressure", "Pa", t, v["p_static_pa"][run], truth.p_static_pa[s]),
                ("pressure altitude", "m", t, v["h_pressure_m"][run], truth.h_m[s]),
                ("true airspeed", "m/s", t, v["tas_mps"][run], truth.tas_mps[s]),
                ("ground speed north", "m/s", t, v["vel_n_mps"][run, :, 0], truth.vel_n_mps[s, 0])]
    elif data.kind == "radar_altimeter":
        out.append(("height above surface", "m", t, v["h_agl_m"][run], truth.h_agl_m[s]))
    elif data.kind == "magnetometer":
        m_n = data.errors["field_n_T"]
        clean = np.einsum("nji,nj->ni", dcm_from_quat(truth.quat_nb[s]), m_n) * 1e6
        for j, axis in enumerate("xyz"):
            out.append((f"field {axis}", "µT", t, v["mag_b_T"][run, :, j] * 1e6, clean[:, j]))
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
    fig.suptitle(f"{data.name} ({data.kind}, {data.meta.get('rate_hz', 0):g} Hz): output and error, run {run}")
    fig.tight_layout()
    path = write_atomic(Path(path), lambda p: fig.savefig(p, dpi=110))
    plt.close(fig)
    return path
