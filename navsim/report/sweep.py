"""The figure of a ``navsim sweep``: the metric of every estimator at every point."""

from __future__ import annotations

import numpy as np

from navsim.experiment.sweep import SweepResult
from navsim.foundations.outputs import OutputFolder
from navsim.report.pages import pyplot


def write_sweep_figure(folder: OutputFolder, sweep: SweepResult, title: str) -> None:
    """``sweep.png`` in ``folder``: each estimator's metric (vectors by their norm) over the
    points, on a log scale when the values are positive."""
    plt = pyplot()
    rows = sweep.rows
    labels = list(rows[0][1]) if rows else []
    fig, ax = plt.subplots(figsize=(max(6, 1.2 * len(rows)), 4.5))
    for lb in labels:
        ax.plot(range(len(rows)), [v.get(lb, np.nan) if v.get(lb) is not None else np.nan for _, v in rows],
                "o-", label=lb)
    ax.set_xticks(range(len(rows)))
    ax.set_xticklabels(["\n".join(f"{k.split('.')[-1]}={v}" for k, v in p.items()) for p, _ in rows], fontsize=7)
    ax.set_ylabel(sweep.metric + " (norm)")
    if any(v is not None and v > 0 for _, vals in rows for v in vals.values()):
        ax.set_yscale("log")
    ax.grid(alpha=0.3)
    if labels:
        ax.legend(fontsize=8)
    ax.set_title(title)
    fig.tight_layout()
    folder.write("sweep.png", lambda p: fig.savefig(p, dpi=110))
    plt.close(fig)
