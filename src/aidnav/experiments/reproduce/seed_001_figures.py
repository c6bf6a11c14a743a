"""Seed 001: the figures (the seed's Figs. 2-5 from run 0, DGPS vs SPP, the common-mode relative LS),
written as PNGs; returns the file names."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .seed_001_setup import APP_S, OUT_S, PRE_S


# ----------------------------------------------------------------------------------------- figures
def seed_figures(out: Path, s, curves, rel, curves_c=None) -> list[str]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # lazy: matplotlib is heavy to import
    from matplotlib.figure import Figure  # lazy: matplotlib is heavy to import

    names = []

    def save(fig, name):
        FigureCanvasAgg(fig)
        fig.savefig(out / name, dpi=110)
        names.append(name)

    t = s["t_a"]
    for name, key, ylab, labels in (
        ("fig2_attitude_error.png", "att_err", "deg", ("roll", "pitch", "heading")),
        ("fig3_position_error.png", "pos_err", "m", ("E", "N", "U")),
        ("fig4_velocity_error.png", "vel_err", "m/s", ("E", "N", "U")),
    ):
        fig = Figure(figsize=(9, 6))
        axs = fig.subplots(3, 1, sharex=True)
        for i in range(3):
            axs[i].plot(t, s[key][:, i], lw=0.8)
            axs[i].set_ylabel(f"{labels[i]} [{ylab}]")
            axs[i].axvspan(PRE_S, PRE_S + APP_S, color="0.9")
            axs[i].grid(alpha=0.3)
        axs[-1].set_xlabel("time [s] (shaded: the 92 s approach)")
        fig.suptitle(
            f"Tight DGPS/SINS integration, all satellites: {name.split('_', 1)[1][:-4].replace('_', ' ')}"
        )
        save(fig, name)
    fig = Figure(figsize=(9, 6))
    ax = fig.subplots(2, 1)
    tc = np.arange(0, APP_S + 0.01, 1.0)
    ax[0].plot(s["t_b"], s["dr_err"], lw=0.8)
    ax[0].plot(s["t_b"], np.linalg.norm(s["dr_err"], axis=1), "k", lw=1.2)
    ax[0].axvline(OUT_S, color="r", ls="--")
    ax[0].legend(["E", "N", "U", "|e|"], fontsize=8)
    ax[0].set_ylabel("DR error [m] (run 1)")
    ax[0].set_title("Relative-position dead reckoning: 0 satellites for 20 s, then 2 satellites")
    ax[1].plot(tc, np.median(curves, 0), "k", label="median")
    ax[1].fill_between(
        tc, np.percentile(curves, 10, 0), np.percentile(curves, 90, 0), color="0.8", label="10-90 %"
    )
    if curves_c is not None:  # pure dead reckoning (case C: no satellites for the whole approach)
        ax[1].plot(tc, np.median(curves_c, 0), "C3--", label="pure dead reckoning (no satellites), median")
        ax[1].fill_between(tc, np.percentile(curves_c, 10, 0), np.percentile(curves_c, 90, 0), color="C3",
                           alpha=0.12, label="pure DR 10-90 %")
    ax[1].axvline(OUT_S, color="r", ls="--")
    ax[1].set_xlabel("time since the start of the approach [s]")
    ax[1].set_ylabel("|DR error| [m], all runs")
    ax[1].set_title("median over the runs: 0 then 2 satellites (case B) vs pure dead reckoning (case C); "
                    "the seed prints no numbers", fontsize=9)
    ax[1].legend(fontsize=8)
    for a in ax:
        a.grid(alpha=0.3)
    save(fig, "fig5_relative_position_error.png")
    fig = Figure(figsize=(8, 4.5))
    ax = fig.subplots()
    ax.plot(s["dg_t"], np.linalg.norm(s["dg_err"], axis=1), label="DGPS single differences (iterated)")
    ax.plot(s["dg_t"], np.linalg.norm(s["spp_err"], axis=1), label="SPP of the rover")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("3-D error [m]")
    ax.set_title("Relative (DGPS) vs absolute (SPP) position error during the approach, run 1")
    ax.legend()
    ax.grid(alpha=0.3)
    save(fig, "dgps_vs_spp.png")
    fig = Figure(figsize=(7, 4))
    ax = fig.subplots()
    b = sorted(rel["err_iter"])
    ax.semilogy(b, [max(rel["err_iter"][x], 1e-12) for x in b], "o-", label="iterated, common-mode only")
    ax.axhline(1e-3, color="r", ls="--", label="target 1 mm")
    ax.set_xlabel("baseline [km]")
    ax.set_ylabel("max error [m]")
    ax.legend()
    ax.grid(alpha=0.3)
    save(fig, "relative_ls_common_mode.png")
    return names
