"""A scenario's emulated run as a log (:func:`emulated_log`), written in the formats navsim
replays (:data:`WRITERS`): ``navsim sensors --export``. Replayed with the same scenario, the
log gives the numbers of the run itself (the IMU, the fixes and the start written to the last
bit)."""

from __future__ import annotations

import numpy as np

from navsim.experiment.driver import perturbed_start
from navsim.foundations.errors import UsageError
from navsim.replay import csvlog, kfgins
from navsim.replay.csvlog import write_csv_log
from navsim.replay.kfgins import write_kfgins
from navsim.replay.navlog import GnssLog, ImuLog, NavLog, Trajectory, start_of
from navsim.sensors import emulate
from navsim.sensors.imu import emulate_imu
from navsim.sensors.registry import INERTIAL

#: format -> the function writing a log into a folder (returns role -> path)
WRITERS = {"kfgins": write_kfgins, "csv": write_csv_log}
#: format -> the files its writer may write
EXPORTED = {"kfgins": tuple(kfgins.FILES.values()), "csv": tuple(csvlog.FILES.values())}


def emulated_log(scenario, truth, seed: int, run: int = 0) -> NavLog:
    """Run ``run`` of ``scenario`` on its flight ``truth`` as a log: the IMU's increments, the
    first GNSS receiver's valid fixes with its datasheet 1-sigma, the truth at the IMU's times as
    the reference, and the run's perturbed start with the scenario's initial 1-sigma."""
    imu_cfg = next(c for c in scenario.sensors if c.role == INERTIAL)
    gnss_cfg = next((c for c in scenario.sensors if c.kind == "gnss"), None)
    if gnss_cfg is None:
        raise UsageError(f"the scenario '{scenario.name}' has no GNSS receiver: a log needs one")
    imu = emulate_imu(truth, imu_cfg.spec, seed, [run], name=imu_cfg.name, keep_rates=False)
    g = emulate(truth, gnss_cfg, seed, [run])
    ok = g.valid[0]
    spec = gnss_cfg.spec
    sigma = np.hypot(spec.position_sigma, spec.markov_sigma)
    vel = g.values.get("vel_n_mps")
    fixes = GnssLog(g.t_s[ok], g.values["lat_rad"][0, ok], g.values["lon_rad"][0, ok], g.values["h_m"][0, ok],
                    np.broadcast_to(sigma, (int(ok.sum()), 3)).copy(),
                    None if vel is None else vel[0, ok], None if vel is None else
                    np.broadcast_to(spec.velocity_sigma, (int(ok.sum()), 3)).copy())
    k = np.searchsorted(truth.t_s, imu.t_s - 1e-9)
    ref = Trajectory(truth.t_s[k], truth.lat_rad[k], truth.lon_rad[k], truth.h_m[k], truth.vel_n_mps[k],
                     truth.euler_rad[k])
    nav0 = perturbed_start(truth, scenario.initial.draw(seed, [run]), 0)
    t0 = float(imu.t_s[0])
    return NavLog(f"{scenario.name}_run{run}", "emulated", t0,
                  ImuLog(imu.t_s - t0, imu.values["dtheta_b_rad"][0], imu.values["dv_b_mps"][0]),
                  _shifted(fixes, t0), _shifted(ref, t0), start_of(nav0, scenario.initial))


def _shifted(x, t0: float):
    x.t_s = x.t_s - t0
    return x
