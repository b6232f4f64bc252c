"""The closed loop: every run's true path with the landings, and the miss distances."""

from __future__ import annotations

import numpy as np

from navsim.report.figures import Page, ReportInput, page_figure, titled

def pages(inp: ReportInput) -> list[Page]:
    """Plan view of every run's true path with the landings and CEP circles (the scorer's), and
    the miss distances' distribution against the truth-guided flight."""
    loop, reference, scenario = inp.loop, inp.reference, inp.scenario
    if loop is None:
        return []
    rtl = scenario.closed_loop.return_to_land
    scored = (inp.metrics.closed_loop or {}).get("return_to_land") or {}
    ceps = {q: (scored.get("miss") or {}).get(f"cep{q}_m") for q in (50, 95)}
    fig, (ax, bx) = page_figure(2, 1, gridspec_kw={"height_ratios": [1.4, 1]})
    paths = loop.path_n_m
    for p in paths:
        ax.plot(p[:, 1], p[:, 0], lw=0.5, color="tab:blue", alpha=0.35)
    ref = reference.path_n_m[0]
    ax.plot(ref[:, 1], ref[:, 0], lw=1.5, color="k", label="guided on the truth")
    if rtl is not None and reference.point_n_m is not None:
        pn, pe = reference.point_n_m
        land = loop.landing_n_m
        ax.plot(land[:, 1], land[:, 0], "x", color="tab:red", ms=4, label="landing (truth)")
        ax.plot([pe], [pn], "*", color="tab:green", ms=12, label="recovery point")
        miss = np.asarray(loop.miss_m, float)
        th = np.linspace(0, 2 * np.pi, 200)
        for q, ls in ((50, "--"), (95, ":")):
            if (r := ceps[q]) is not None:
                ax.plot(pe + r * np.sin(th), pn + r * np.cos(th), ls, color="tab:red", lw=1,
                        label=f"CEP{q} {r:.1f} m")
        ax.plot(pe + rtl.area_m * np.sin(th), pn + rtl.area_m * np.cos(th), "-", color="tab:green",
                lw=0.8, label=f"recovery area {rtl.area_m:g} m")
        zoom = ax.inset_axes([0.03, 0.03, 0.36, 0.36])          # the recovery area, magnified
        zoom.plot(land[:, 1], land[:, 0], "x", color="tab:red", ms=3)
        zoom.plot([pe], [pn], "*", color="tab:green", ms=9)
        for q, ls in ((50, "--"), (95, ":")):
            if (r := ceps[q]) is not None:
                zoom.plot(pe + r * np.sin(th), pn + r * np.cos(th), ls, color="tab:red", lw=0.8)
        zoom.plot(pe + rtl.area_m * np.sin(th), pn + rtl.area_m * np.cos(th), "-", color="tab:green", lw=0.8)
        half = 1.15 * max(rtl.area_m, float(np.nanmax(miss)) if np.isfinite(miss).any() else 0.0)
        zoom.set(xlim=(pe - half, pe + half), ylim=(pn - half, pn + half), aspect="equal")
        zoom.tick_params(labelsize=6)
        srt = np.sort(miss[np.isfinite(miss)])
        if srt.size:
            bx.step(srt, np.arange(1, srt.size + 1) / srt.size, where="post", color="tab:blue",
                    label=f"guided on the solution ({srt.size} runs)")
            for q, ls in ((50, "--"), (95, ":")):
                if ceps[q] is not None:
                    bx.axvline(ceps[q], ls=ls, color="tab:red", lw=1, label=f"CEP{q} {ceps[q]:.1f} m")
        guided = (scored.get("truth_guided") or {}).get("miss_m")
        if guided is not None:
            bx.axvline(guided, color="k", lw=1.5, label=f"guided on the truth {guided:.2f} m")
        bx.set(xlabel="true miss distance at the landing (parachute or touchdown), m", ylabel="fraction of runs",
               title="miss distance")
        bx.legend(fontsize=7, loc="lower right")
        bx.grid(alpha=0.3)
    ax.set(xlabel="east, m", ylabel="north, m", title=f"true paths, flown on '{scenario.closed_loop.fly_on}'")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7, loc="best")
    ax.grid(alpha=0.3)
    return [titled(fig, "closed_loop", "Navigation in the loop: return to land")]

