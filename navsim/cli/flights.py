"""The flight as the commands show and keep it (``fly``, ``run``, ``sensors``): its summary table,
its files in an output folder, and the scenario's flight from the cache or flown, the part flown
kept when it fails."""

from __future__ import annotations

import shutil
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from navsim.cli.output import progress, table
from navsim.experiment.runner import cached_flight
from navsim.flight.plots import plot_flight
from navsim.foundations.errors import FlightError
from navsim.foundations.outputs import OutputFolder
from navsim.foundations.overrides import set_comments
from navsim.foundations.provenance import provenance


def flight_summary(truth) -> str:
    """A table of the flight's segments: their times, heights, airspeed and bank."""
    rows = []
    for _, label, a, b in truth.segment_spans():
        m = (truth.t_s >= a) & (truth.t_s <= b)
        rows.append([label, f"{a:.1f}", f"{b:.1f}", f"{truth.h_m[m].min():.1f}",
                     f"{truth.h_m[m].max():.1f}", f"{truth.tas_mps[m].mean():.2f}",
                     f"{np.degrees(np.abs(truth.euler_rad[m, 0])).max():.1f}"])
    return table(["segment", "t0 s", "t1 s", "h min m", "h max m", "TAS m/s", "|bank| max°"], rows)


def save_flight(out: OutputFolder, truth, scenario_file, scenario, wall_s: float, failure=None) -> list[Path]:
    """Write a flight (or the part flown before ``failure``) into ``out``: ``truth.npz``, the
    flight PNGs, ``scenario.yaml`` (a copy; with ``--set`` changes, the changed mapping) and
    ``run.json``; returns the files written."""
    if scenario.overrides:
        files = [out.text("scenario.yaml", f"# {scenario_file}, changed by\n" + set_comments(scenario.overrides)
                          + yaml.safe_dump(scenario.raw, sort_keys=False))]
    else:
        files = [out.write("scenario.yaml", lambda p: shutil.copyfile(scenario_file, p))]
    record = {"scenario": str(scenario_file), "name": scenario.name, **provenance(),
              "wall_s": wall_s, "failure": str(failure) if failure else None}
    if scenario.overrides:
        record["overrides"] = list(scenario.overrides)
    if truth is not None:
        files.append(out.write("truth.npz", truth.save))
        plots = plot_flight(truth, out.path)
        out.record(plots)
        files += plots
        record.update(duration_s=truth.duration_s, samples=truth.n,
                      real_time_factor=truth.duration_s / max(wall_s, 1e-9))
    files.append(out.json("run.json", record))
    return files


def fly_or_save(scenario, scenario_file, out: OutputFolder):
    """The scenario's flight from the cache or flown; a flight that fails saves the part flown
    in ``out/flight`` (as ``navsim fly`` does) before its :class:`FlightError` goes on."""
    bar, update = progress(f"flight {scenario.flight.track.name}")
    t0 = time.perf_counter()
    try:
        return cached_flight(scenario.flight, progress=update)
    except FlightError as exc:
        out.clear_earlier()               # an earlier run's results do not stand beside this failure
        with OutputFolder(out.path / "flight", command="fly", force=True) as folder:    # inside the locked folder
            folder.clear_earlier()
            save_flight(folder, getattr(exc, "truth", None), scenario_file, scenario, time.perf_counter() - t0, exc)
        print(f"the part flown is saved in {folder.path}/", file=sys.stderr)
        raise
    finally:
        bar.close()
