"""The report of a ``navsim replay``: ``attitude.png`` and ``replay.pdf`` (summary + the plot)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from navsim.flight.plots import plot_drawn
from navsim.foundations.outputs import write_atomic
from navsim.replay.metrics import AXES, ReplayMetrics
from navsim.replay.run import ReplayResult
from navsim.report.figures import pyplot
from navsim.report.tables import Heading, Paragraph, Table, layout


def attitude_figure(result: ReplayResult):
    """Roll, pitch, yaw of the estimator and PX4 (left) and their difference (right); the
    settling time shaded, the estimator's resets as vertical lines."""
    plt = pyplot()
    r = result
    est, px4, diff = np.degrees(r.euler_rad), np.degrees(r.euler_px4_rad), np.degrees(r.diff_rad)
    fig, axes = plt.subplots(3, 2, figsize=(11.69, 8.27), sharex=True)
    for j, name in enumerate(AXES):
        left, right = axes[j]
        plot_drawn(left, r.t_s, px4[:, j], color="0.3", lw=1.2, label="PX4 vehicle_attitude")
        plot_drawn(left, r.t_s, est[:, j], color="C0", lw=1.0, label=r.estimator)
        plot_drawn(right, r.t_s, diff[:, j], color="C3", lw=1.0)
        right.axhline(0.0, color="0.5", lw=0.6)
        left.set_ylabel(f"{name} (deg)")
        right.set_ylabel(f"{name} difference (deg)")
        for ax in (left, right):
            ax.axvspan(r.t_s[0], r.settle_s, color="0.9", zorder=0)
            for k, (t, cause) in enumerate(r.resets):
                ax.axvline(t, color="C1", lw=0.8, ls="--", label="reset" if k == 0 else None)
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="best")
    if r.resets:
        axes[0, 1].legend(fontsize=8, loc="best")
    for ax in axes[-1]:
        ax.set_xlabel("time from the first IMU sample (s)")
    fig.suptitle(f"{r.log.path.name}: {r.estimator} against PX4's estimate (shaded: first "
                 f"{r.settle_s:g} s, not scored)", fontsize=11)
    fig.tight_layout()
    return fig


def summary_blocks(metrics: ReplayMetrics, record: dict) -> list:
    """The summary page's blocks: the differences to PX4, the replay's setup, the cost, the
    resets and the log's notes. ``record``: the replay's provenance."""
    m, log, a = metrics, metrics.log, metrics.alignment
    deg = lambda v: " / ".join(f"{x:.2f}" for x in v)
    setup = [["log", f"{log.file} ({log.duration_s:.1f} s, {log.info.get('ver_hw')}, PX4 {str(log.info.get('ver_sw'))[:10]})"],
             ["rates", f"IMU {log.imu_rate_hz:.1f} Hz (grid {m.imu_grid_hz:g} Hz), magnetometer "
                       f"{log.mag_rate_hz:.1f} Hz, baro {log.baro_rate_hz:.1f} Hz, PX4 attitude "
                       f"{log.px4_attitude_rate_hz:.1f} Hz"],
             ["estimator", f"{m.estimator}, epochs every {m.period_s:g} s"],
             ["parameters", str(m.params)],
             ["alignment", f"first {a.window_s:g} s: roll / pitch / yaw {deg(a.euler_deg)} deg (PX4 "
                           f"{deg(a.px4_euler_deg)}), field N / E / D "
                           + " / ".join(f"{x * 1e6:.1f}" for x in a.field_n_T) + " µT"],
             ["declination", f"{log.declination_deg:.2f} deg ({log.declination_source})"],
             ["scored", f"after {m.settle_s:g} s, {m.samples_scored} samples "
                        f"(every {m.record_s:g} s)"],
             ["navsim", f"{record['versions']['navsim']} at git {record['git_revision']}"]]
    c = m.cost
    blocks = [Heading(f"{m.estimator} against PX4's vehicle_attitude"), Table(*difference_table(m)),
              Heading("Replay"), Table(["item", "value"], setup, align=["l", "l"], max_column=0.85),
              Paragraph(f"Cost: {c.us_per_imu_step_propagated:.1f} µs per IMU step propagated, "
                        f"{c.us_per_epoch:.0f} µs per epoch, {c.us_per_imu_cycle:.0f} µs per IMU cycle "
                        f"({c.real_time_factor:.0f}x real time).", size=8)]
    if m.resets:
        blocks += [Heading("Resets"), Table(["t, s", "cause"], [[f"{x.t_s:.2f}", x.cause] for x in m.resets])]
    if log.notes:
        blocks += [Heading("Notes on the log")] + [Paragraph(f"- {n}", size=8) for n in log.notes]
    return blocks


def difference_table(metrics: ReplayMetrics) -> tuple[list[str], list[list[str]]]:
    """Headers and rows: |estimator - PX4| RMS, 95 %, max per axis (degrees)."""
    rows = []
    for ax in AXES:
        d = metrics.attitude_diff_deg.axis(ax)
        rows.append([ax] + (["-"] * 3 if d is None else [f"{v:.3f}" for v in (d.rms, d.p95, d.max)]))
    return ["axis", "RMS deg", "95% deg", "max deg"], rows


def write_replay_report(out: Path, result: ReplayResult, metrics: ReplayMetrics, record: dict) -> list[Path]:
    """Write ``attitude.png`` and ``replay.pdf`` into ``out``; returns their paths."""
    plt = pyplot()
    from matplotlib.backends.backend_pdf import PdfPages
    out = Path(out)
    fig = attitude_figure(result)
    png = write_atomic(out / "attitude.png", lambda p: fig.savefig(p, dpi=110))
    pages = layout(f"navsim replay: {result.log.path.name}, {result.estimator}", summary_blocks(metrics, record))
    def write_pdf(path):
        with PdfPages(path) as pdf:
            for page in pages:
                pdf.savefig(page)
            pdf.savefig(fig)
            pdf.infodict()["Title"] = f"navsim replay {result.log.path.name}"
    pdf_path = write_atomic(out / "replay.pdf", write_pdf)
    for page in pages:
        plt.close(page)
    plt.close(fig)
    return [png, pdf_path]
