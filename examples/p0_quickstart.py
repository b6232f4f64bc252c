# %% [markdown]
# # P0 in a notebook: run, score, plot from an xarray Dataset
#
# A notebook in the percent format (VS Code, Jupyter with jupytext, or `python
# examples/p0_quickstart.py`). It runs P0's BD/SINS/ADS experiment through the Python API, prints
# the scores `navsim run` writes to `metrics.json`, and plots the horizontal position error of
# every run from the labelled Dataset. `NAVSIM_EXAMPLE_RUNS` sets the number of runs (20 by
# default; the test runs 4).

# %%
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import navsim  # noqa: E402

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd()
runs = int(os.environ.get("NAVSIM_EXAMPLE_RUNS", "20"))
scenario = navsim.load_scenario(ROOT / "scenarios" / "p0_bd_sins_ads.yaml")
result = navsim.run(scenario, runs=runs, seed=1, workers=2)   # nothing is written

# %% the scores, typed (result.to_dict() is metrics.json)
for label, m in result.metrics.estimators.items():
    print(f"{label:24s} RMS position N E D {np.round(m.rms.pos_m, 2)} m, "
          f"{m.diverged_runs} of {result.metrics.runs} runs diverged")

# %% the histories as a Dataset: estimator x run x epoch x axis, units in the attributes
ds = result.to_xarray()
print(ds)
horizontal = np.hypot(ds.pos_err_m.sel(axis="N"), ds.pos_err_m.sel(axis="E"))

# %% every run's horizontal error, and the RMS over the runs
fig, axes = plt.subplots(1, ds.sizes["estimator"], figsize=(11, 3.5), sharex=True)
for ax, label in zip(np.atleast_1d(axes), ds.estimator.values):
    err = horizontal.sel(estimator=label)
    ax.plot(ds.t_s, err.T, color="0.75", lw=0.6)
    ax.plot(ds.t_s, np.sqrt((err ** 2).mean("run")), color="C0", lw=1.5, label="RMS over the runs")
    ax.set(title=str(label), xlabel="t (s)", ylabel="horizontal error (m)")
    ax.legend(loc="upper left")
fig.tight_layout()
out = Path(os.environ.get("NAVSIM_EXAMPLE_OUT", "reports/p0_quickstart"))
out.mkdir(parents=True, exist_ok=True)
fig.savefig(out / "horizontal_error.png", dpi=110)
print(f"wrote {out / 'horizontal_error.png'}")
