"""What a run of an estimator cost: the CPU seconds of its ``propagate`` and epochs added up over
batches (:func:`sum_cost`), read on a clock that leaves numba's one-off compilation out
(:func:`compute_clock`; the compilation apart, :func:`compile_seconds`)."""

from __future__ import annotations

import threading
import time

from numba.core import event as numba_event


def sum_cost(costs):
    """The :attr:`~navsim.records.history.EstimatorHistory.cost` of several batches added up
    (None if one is None)."""
    if any(c is None for c in costs):
        return None
    return {"propagate_s": sum(c["propagate_s"] for c in costs), "epoch_s": sum(c["epoch_s"] for c in costs),
            "runs": sum(c["runs"] for c in costs), "epochs": costs[0]["epochs"],
            "batches": sum(c["batches"] for c in costs),
            "compile_s": None if any(c.get("compile_s") is None for c in costs) else sum(c["compile_s"] for c in costs)}


class _CompileTimer(numba_event.Listener):
    """Seconds this process spent in numba's compiler (compiling kernels, or loading them from
    its cache): the outermost holds of its compiler lock, summed, per thread."""

    def __init__(self):
        self._local = threading.local()
        self.total_s = 0.0

    def on_start(self, event):
        local = self._local
        local.depth = getattr(local, "depth", 0) + 1
        if local.depth == 1:
            local.t0 = time.perf_counter()

    def on_end(self, event):
        local = self._local
        local.depth -= 1
        if local.depth == 0:
            self.total_s += time.perf_counter() - local.t0


_COMPILE_TIMER = _CompileTimer()
numba_event.register("numba:compiler_lock", _COMPILE_TIMER)


def compile_seconds() -> float:
    """Seconds this process has spent compiling (or loading compiled) numba kernels so far."""
    return _COMPILE_TIMER.total_s


def compute_clock() -> float:
    """:func:`time.perf_counter` less :func:`compile_seconds`: the differences of two readings
    are the time spent computing, without the kernels' one-off compilation (the cost of a run,
    :attr:`~navsim.records.history.EstimatorHistory.cost`, never counts it; its ``compile_s``
    does, apart)."""
    return time.perf_counter() - _COMPILE_TIMER.total_s
