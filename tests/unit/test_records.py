"""The records layer (:mod:`navsim.records`): the sigma states' named blocks, the driver's
recorder filling every epoch array the history declares, and the chunk's documented keys."""

import inspect
import re
from dataclasses import fields
from pathlib import Path
from types import SimpleNamespace

import numpy as np

import navsim
import navsim.api
import navsim.scoring
from navsim.experiment.closed_loop import _truth_bias
from navsim.experiment.driver import Driver
from navsim.navigation.estimators.base import Solution
from navsim.navigation.strapdown import state_from_truth
from navsim.records.chunk import ChunkPart
from navsim.records.history import ARRAYS, BLOCK_ERRORS, EPOCH_ARRAYS
from navsim.records.states import ATT, BLOCKS, DIM_SIZES, POS, POS_NE, SIGMA_STATES, VEL
from navsim.records.truth import TruthBias


def test_the_named_blocks_are_the_sigma_states():
    assert [SIGMA_STATES[s] for s in (ATT, VEL, POS)] == [
        ("att_N", "att_E", "att_D"), ("vel_N", "vel_E", "vel_D"), ("pos_N", "pos_E", "pos_D")]
    assert SIGMA_STATES[POS_NE] == ("pos_N", "pos_E")
    assert BLOCKS == {"att": ATT, "vel": VEL, "pos": POS}
    assert list(BLOCK_ERRORS) == list(BLOCKS) and all(ARRAYS[n][0] == ("run", "epoch", "axis")
                                                      for n in BLOCK_ERRORS.values())
    assert DIM_SIZES["state"] == len(SIGMA_STATES)


def test_no_module_slices_the_sigma_states_by_number():
    """``sigma[..., 6:9]`` named its block by number (report pages, the closed-loop score)."""
    package = Path(navsim.__file__).resolve().parent
    by_number = re.compile(r"sigma\w*\[[^\]]*\b\d+\s*:\s*\d+")
    found = [f"{p.relative_to(package)}:{i}" for p in sorted(package.rglob("*.py"))
             for i, line in enumerate(p.read_text().splitlines(), 1) if by_number.search(line)]
    assert found == []
    assert by_number.search("s = h.sigma[rows, k, 6:8]") and not by_number.search("h.sigma[..., POS]")


class _Stub:
    """An estimator at the truth with a covariance and gyro bias sigmas (no accelerometer's),
    raising at its third epoch."""

    period_s = 0.1

    def initialize(self, nav0, sigma0):
        self.nav, self.epochs = nav0, 0

    def propagate(self, dtheta_b, dv_b, dt):
        pass

    def epoch(self, t, sensors):
        self.epochs += 1
        if self.epochs == 3:
            raise RuntimeError("stub")
        return []

    def solution(self):
        B = self.nav.lat_rad.shape[0]
        return Solution(self.nav, P_nav=np.broadcast_to(np.eye(9) * 1e-6, (B, 9, 9)).copy(),
                        gyro_bias=np.zeros((B, 3)), accel_bias=np.zeros((B, 3)),
                        gyro_bias_sigma=np.full((B, 3), 1e-5), wind_n_mps=np.zeros((B, 3)),
                        wind_sigma_mps=np.ones((B, 3)))


def test_the_recorder_fills_every_declared_epoch_array():
    B, one = 2, lambda *shape: np.zeros((1, *shape))
    truth = SimpleNamespace(lat_rad=one() + 0.8, lon_rad=one(), h_m=one() + 100, vel_n_mps=one(3),
                            euler_rad=one(3), quat_nb=np.array([[1.0, 0, 0, 0]]), wind_steady_n_mps=one(3))
    driver = Driver({"stub": _Stub()}, 0.1, B)
    assert list(driver.rec["stub"].records) == list(EPOCH_ARRAYS)      # one list per declared array
    driver.start(state_from_truth(truth, 0, B), {}, truth, 0)
    for i in range(1, 5):
        driver.advance(np.zeros((B, 1, 3)), np.zeros((B, 1, 3)), 0.1 * i, {}, truth, 0)
    h = driver.histories()["stub"]
    assert h.t_s.tolist() == [0.0, 0.1, 0.2, 0.30000000000000004, 0.4]
    for name in EPOCH_ARRAYS:                     # every array the history declares, recorded
        value = getattr(h, name)
        assert value is not None and value.shape == (B, 5, *(DIM_SIZES[d] for d in ARRAYS[name][0][2:])), name
        assert np.isnan(value[:, 3:]).all() and not np.isnan(value[:, :3]).any() or name == "accel_bias_sigma", name
    assert np.isnan(h.accel_bias_sigma).all() and (h.gyro_bias_sigma[:, :3] == 1e-5).all()
    assert h.diverged.all() and h.divergence[0] == (0.30000000000000004, "RuntimeError: stub")


def test_the_chunk_names_the_truth_bias_fields_it_holds():
    """``truth_bias``'s comment named ``gyro_rad_s``/``accel_mps2``, keys nothing makes; it is a
    :class:`TruthBias` now, whose fields the comment names."""
    hist = SimpleNamespace(t_s=np.array([0.0, 0.1]))
    bias = _truth_bias({"gyro_bias": np.zeros((1, 1, 3)), "accel_bias": np.zeros((1, 1, 3))}, {"a": hist}, 0.1, 2)
    assert isinstance(bias, TruthBias) and list(bias.arrays()) == ["gyro_bias", "accel_bias"]
    assert bias.gyro_bias.shape == (2, 2, 3) and bias.gyro_bias_seen is None
    assert navsim.scoring.ChunkPart is ChunkPart and navsim.api.ChunkPart is ChunkPart     # one class
    doc = inspect.getsource(navsim.scoring.ChunkPart)
    for key in (f.name for f in fields(TruthBias)):
        assert f"``{key}``" in doc, key
    assert "gyro_rad_s" not in doc and "accel_mps2" not in doc
