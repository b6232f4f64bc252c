"""Report pieces for attitude estimators (P4): roll, pitch and yaw errors with the divergence
monitor's resets marked, and the attitude table of the summary page. Every estimator's
``metrics.json`` has the ``attitude`` block (Euler errors are recorded for all); the table and
the pages are for the estimators that report resets (``cpf_ekf``)."""

from __future__ import annotations

import numpy as np

AXES = ("roll", "pitch", "yaw")


def attitude_metrics(euler_err_rad: np.ndarray) -> dict:
    """Roll, pitch, yaw error statistics (deg) of ``(B, E, 3)`` errors: 95th percentile, RMS and
    maximum of the absolute error, and the 95th percentile of the error about each run's own
    mean -- what a reference sharing the vehicle's bench, level and field sees (P4's MTi)."""
    e = np.degrees(np.asarray(euler_err_rad, float))
    a = np.abs(e)
    about = np.abs(e - np.nanmean(e, axis=1, keepdims=True))
    return {"p95_deg": np.nanpercentile(a, 95, axis=(0, 1)).tolist(),
            "rms_deg": np.sqrt(np.nanmean(e ** 2, axis=(0, 1))).tolist(),
            "max_abs_deg": np.nanmax(a, axis=(0, 1)).tolist(),
            "p95_about_run_mean_deg": np.nanpercentile(about, 95, axis=(0, 1)).tolist()}


def reset_metrics(resets: list) -> dict:
    """The divergence monitor's resets: count, runs reset, per-run times (s) and causes."""
    return {"count": int(sum(len(r) for r in resets)), "runs_with_reset": int(sum(bool(r) for r in resets)),
            "mean_per_run": float(np.mean([len(r) for r in resets])) if resets else 0.0,
            "times_s": [[round(float(t), 2) for t, _ in r] for r in resets],
            "causes": sorted({c for r in resets for _, c in r})}


def attitude_lines(metrics: dict, table) -> list[str]:
    """The attitude table of the summary page (estimators with ``attitude`` metrics)."""
    rows = []
    for label, m in metrics["estimators"].items():
        a = m.get("attitude")
        if not a or "resets" not in m:          # the attitude estimators (every one has Euler errors)
            continue
        f = lambda v: "/".join(f"{x:.3g}" for x in v)
        r = m.get("resets")
        rows.append([label, f(a["p95_deg"]), f(a["p95_about_run_mean_deg"]), f(a["rms_deg"]),
                     f(a["max_abs_deg"]), "-" if r is None else f"{r['count']} in {r['runs_with_reset']} runs"])
    if not rows:
        return []
    return ["", "attitude error after the settling time, roll/pitch/yaw in deg (95th percentile of |error|; "
            "about each run's own mean; RMS; max) and the divergence monitor's resets:", ""] + \
        table(["estimator", "p95", "p95 about run mean", "RMS", "max", "resets"], rows)


def attitude_figure(histories: dict, settle_s: float, runs_plotted: int = 5, spans=()):
    """Roll, pitch, yaw error of each attitude estimator: a few runs, the 95th percentile of
    |error| over the runs, and a tick per reset of the divergence monitor (red, with its time
    listed for the first run)."""
    from navsim.report import _plt, _shade
    labels = [k for k, h in histories.items() if h.euler_err_rad is not None and h.resets is not None]
    if not labels:
        return []
    plt = _plt()
    figs = []
    for label in labels:
        h = histories[label]
        e = np.degrees(h.euler_err_rad)
        fig, axes = plt.subplots(3, 1, figsize=(10, 8.5), sharex=True)
        for j, ax in enumerate(axes):
            for r in range(min(runs_plotted, e.shape[0])):
                ax.plot(h.t_s, e[r, :, j], lw=0.5, alpha=0.7)
            p95 = np.nanpercentile(np.abs(e[:, :, j]), 95, axis=0)
            ax.plot(h.t_s, p95, "k", lw=1.0, label="95th pct of |error| over the runs")
            ax.plot(h.t_s, -p95, "k", lw=1.0)
            after = h.t_s >= settle_s
            lim = max(3 * float(np.nanpercentile(np.abs(e[:, after, j]), 99)), 0.05) if after.any() else None
            if lim and np.isfinite(lim):
                ax.set_ylim(-lim, lim)
            _shade(ax, spans)
            ax.set_ylabel(f"{AXES[j]} error, deg")
            ax.grid(alpha=0.3)
        times = [t for r in h.resets for t, _ in r]
        for t in sorted(set(round(t, 1) for t in times)):
            for ax in axes:
                ax.axvline(t, color="r", lw=0.6, alpha=0.5)
        first = ", ".join(f"{t:.0f}" for t, _ in h.resets[0]) if h.resets and h.resets[0] else "none"
        title = f"{label}: attitude error; resets (red) {len(times)} in {sum(bool(r) for r in h.resets)} runs"
        axes[0].set_title(title + f"; run 0 at {first} s" if times else title)
        axes[0].legend(fontsize=7, loc="upper right")
        axes[-1].set_xlabel("time, s")
        fig.tight_layout()
        figs.append((f"attitude_{_slug(label)}", fig))
    return figs


def _slug(label: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in label).strip("_").lower()
