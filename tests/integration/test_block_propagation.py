"""P0's estimators propagated by the compiled kernel a block per epoch, against the same
estimators propagated by the numpy mechanization one IMU sample at a time (the reference):
every history field over the whole p0 track."""

import numpy as np
import pytest
from reference_strapdown import Strapdown

from navsim.experiment import driver
from navsim.experiment.driver import Batch, run_batch
from navsim.navigation.estimators.factory import build
from navsim.navigation.estimators.sins import FreeInertial
from navsim.records.history import ARRAY_FIELDS
from navsim.scoring.scorer import score
from navsim.sensors import emulate
from navsim.sensors.imu import emulate_imu

RUNS = range(3)


class PerSample:
    """:class:`navsim.navigation.strapdown.BlockStrapdown`'s interface over the numpy reference, one call
    per IMU interval."""

    def __init__(self, state):
        self.sd = Strapdown(state)
        self.reset_sums()

    @property
    def state(self):
        return self.sd.state

    def reset_sums(self):
        B = self.sd.state.lat_rad.shape[0]
        self.sum_C_nb, self.sum_dv_n_mps, self.steps = np.zeros((B, 3, 3)), np.zeros((B, 3)), 0

    def block(self, dtheta_b, dv_b, dt, gyro_bias=None, accel_bias=None):
        if gyro_bias is not None:
            dtheta_b = dtheta_b - gyro_bias[:, None, :] * dt
        if accel_bias is not None:
            dv_b = dv_b - accel_bias[:, None, :] * dt
        for j in range(dtheta_b.shape[1]):
            s = self.sd.step(dtheta_b[:, j], dv_b[:, j], dt)
            self.sum_C_nb += s.C_nb
            self.sum_dv_n_mps += self.sd.dv_n
            self.steps += 1
        return self.sd.state


def per_sample(est):
    """``est`` with its mechanization swapped for the reference after ``initialize``."""
    init = est.initialize

    def initialize(nav0, sigma0):
        init(nav0, sigma0)
        est.sd = PerSample(est.sd.state)
    est.initialize = initialize
    return est


@pytest.mark.slow
def test_p0_histories_of_the_kernel_equal_the_per_sample_reference(shipped_flight):
    """Both P0 estimators (free SINS, 16-state ES-KF) over the 500 s p0 track, 3 runs: every
    array of the histories (errors, sigmas, NEES, NIS, biases, Euler errors) agrees to 1e-9 of
    that array's largest value (to its last place for the records kept in single precision);
    the free SINS drifts by hundreds of metres, so agreement is not two integrators standing
    still."""
    scenario, truth, _ = shipped_flight("p0_bd_sins_ads")
    imu_cfg = next(c for c in scenario.sensors if c.kind == "imu")
    imu = emulate_imu(truth, imu_cfg.spec, scenario.seed, RUNS, name=imu_cfg.name, keep_rates=False)
    others = {c.name: emulate(truth, c, scenario.seed, RUNS) for c in scenario.sensors if c.kind != "imu"}

    def histories(wrap):
        ests = {e.label: wrap(build(e)) for e in scenario.estimators}
        return run_batch(truth, imu, others, ests, Batch(scenario.initial, scenario.seed, RUNS))

    got, ref = histories(lambda e: e), histories(per_sample)
    for label in ref:
        g, r = got[label], ref[label]
        for name in ARRAY_FIELDS:
            a, b = getattr(g, name), getattr(r, name)
            if b is None:
                assert a is None, (label, name)
                continue
            scale = np.nanmax(np.abs(b)) if np.issubdtype(b.dtype, np.floating) else 1
            # a record kept in single precision (the errors, the sigmas) may round the two
            # values' last 1e-9 of difference to neighbouring floats: one unit in its last place
            single = np.finfo(np.float32).eps if a.dtype == np.float32 else 0.0
            np.testing.assert_allclose(a, b, rtol=single, atol=1e-9 * scale, err_msg=f"{label}: {name}")
        assert g.nis.keys() == r.nis.keys()
        for key in r.nis:
            np.testing.assert_allclose(g.nis[key], r.nis[key], rtol=0, atol=1e-9 * np.nanmax(r.nis[key]))
    free = ref["free SINS"]
    assert np.abs(free.pos_err_m[:, -1]).max() > 100.0


def test_a_chunk_does_not_depend_on_how_the_imu_is_cut_into_blocks(shipped_flight):
    """The open-loop driver hands each estimator the samples up to the next epoch of any
    estimator: adding an estimator with a 0.37 s or a 0.3 s period cuts P0's blocks elsewhere,
    and P0's histories stay the same bit for bit (0.3 s: blocks of 30, 30, 30, 10 samples, whose
    ``dt`` times ``K`` do not add up to 1.0 exactly)."""
    scenario, truth, _ = shipped_flight("p0_bd_sins_ads")
    short = truth.slice(0, 6001)
    runs = range(2)
    imu_cfg = next(c for c in scenario.sensors if c.kind == "imu")
    imu = emulate_imu(short, imu_cfg.spec, scenario.seed, runs, name=imu_cfg.name, keep_rates=False)
    others = {c.name: emulate(short, c, scenario.seed, runs) for c in scenario.sensors if c.kind != "imu"}
    ests = lambda: {e.label: build(e) for e in scenario.estimators}
    alone = run_batch(short, imu, others, ests(), Batch(scenario.initial, scenario.seed, runs))
    for period in (0.37, 0.3):
        mixed = run_batch(short, imu, others, {**ests(), "odd": FreeInertial(period_s=period)},
                          Batch(scenario.initial, scenario.seed, runs))
        for label, h in alone.items():
            for name in ARRAY_FIELDS:
                a, b = getattr(h, name), getattr(mixed[label], name)
                assert (a is None and b is None) or np.array_equal(a, b, equal_nan=True), (label, name, period)
            for key, v in h.nis.items():
                assert np.array_equal(v, mixed[label].nis[key], equal_nan=True), (label, key, period)
        assert mixed["odd"].t_s.size == 1 + 6000 // round(period * 100)


def test_single_precision_records_leave_the_metrics_as_printed(shipped_flight, monkeypatch):
    """The errors and 1-sigmas are recorded in single precision (RECORD_DTYPES): P0's metrics
    over 20 runs of the first 120 s equal those of double-precision records to 1e-5 relative
    (the summary prints 3 to 4 digits), every number of metrics.json's estimator sections."""
    scenario, truth, _ = shipped_flight("p0_bd_sins_ads")
    short, runs = truth.slice(0, 12001), range(20)
    imu_cfg = next(c for c in scenario.sensors if c.kind == "imu")
    imu = emulate_imu(short, imu_cfg.spec, scenario.seed, runs, name=imu_cfg.name, keep_rates=False)
    others = {c.name: emulate(short, c, scenario.seed, runs) for c in scenario.sensors if c.kind != "imu"}

    def metrics():
        ests = {e.label: build(e) for e in scenario.estimators}
        hist = run_batch(short, imu, others, ests, Batch(scenario.initial, scenario.seed, runs))
        return {k: score(h, 20.0).to_dict() for k, h in hist.items()}, hist

    single, hist = metrics()
    assert hist["BD/SINS/ADS ES-KF 16"].pos_err_m.dtype == np.float32
    monkeypatch.setattr(driver, "RECORD_DTYPES", {k: np.float64 for k in driver.RECORD_DTYPES})
    double, hist = metrics()
    assert hist["BD/SINS/ADS ES-KF 16"].pos_err_m.dtype == np.float64

    def numbers(d, path=""):
        if isinstance(d, dict):
            return [x for k in sorted(d) for x in numbers(d[k], f"{path}.{k}")]
        if isinstance(d, (list, tuple)):
            return [x for i, v in enumerate(d) for x in numbers(v, f"{path}[{i}]")]
        return [(path, d)] if isinstance(d, float) and path.split(".")[2] != "cost" else []
    a, b = numbers(single), numbers(double)
    assert [p for p, _ in a] == [p for p, _ in b] and len(a) > 100
    for (path, x), (_, y) in zip(a, b):
        assert x == pytest.approx(y, rel=1e-5, abs=1e-9, nan_ok=True), path
