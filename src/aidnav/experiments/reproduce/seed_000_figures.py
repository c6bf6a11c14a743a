"""Seed 000: the figures (the seed's Figs. 1-6 from run 0, the Monte Carlo heading RMS of every filter
variant, the SAPV-loss and GPS-outage runs), written as PNGs; each function returns the file names."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._study import figure
from .seed_000_setup import FED, GPS_ONLY, GPS_OUTAGE, PAPER_T2, SAPV_LOSS, SETTLE_S, VARIANTS

# ============================================================================ figures
_fig = figure


def _finish(fig, ax, xlabel: str, ylabel: str, title: str, path: Path, fontsize: int = 8,
            which: str = "major") -> str:
    """Label, grid and legend the one axes ``ax`` of ``fig``, lay it out and save it to ``path`` (110 dpi);
    returns the file name."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3, which=which)
    ax.legend(fontsize=fontsize)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path.name


def plot_seed_figs(mc, out: Path) -> list[str]:
    """Figs. 1-6 of the seed: run 0, SINS/GPS vs SINS/GPS/SAPV (federated, fusion-reset, β = 1/2)."""
    names = [("heading", "Fig. 1 azimuth (heading) error", "arcmin", "fig1_heading_error.png"),
             ("roll", "Fig. 2 roll error", "arcmin", "fig2_roll_error.png"),
             ("pitch", "Fig. 3 pitch error", "arcmin", "fig3_pitch_error.png"),
             ("vE", "Fig. 4 east velocity error", "m/s", "fig4_east_velocity_error.png"),
             ("vN", "Fig. 5 north velocity error", "m/s", "fig5_north_velocity_error.png"),
             ("vU", "Fig. 6 up velocity error", "m/s", "fig6_up_velocity_error.png")]
    a, b = mc["series"][GPS_ONLY][0], mc["series"][FED][0]
    files = []
    for q, title, unit, fname in names:
        fig, axs = _fig(2 if q == "heading" else 1, 1, h=6.0 if q == "heading" else 4.0)
        ax = axs[0, 0]
        ax.plot(a["t"], a[q], label="SINS/GPS (state 1)", lw=1.0)
        ax.plot(b["t"], b[q], label="SINS/GPS/SAPV federated (state 2)", lw=1.0)
        for col, c in ((0, "C0"), (1, "C1")):  # the paper's printed Table 2: mean (dashed) ± std (dotted)
            m, sd = PAPER_T2[q]["mean"][col], PAPER_T2[q]["std"][col]
            ax.axhline(m, color=c, ls="--", lw=0.9,
                       label=f"paper Table 2 state {col + 1}: mean {m:g}, std {sd:g}")
            for y in (m - sd, m + sd):
                ax.axhline(y, color=c, ls=":", lw=0.8)
        ax.set_ylabel(f"{q} error [{unit}]")
        ax.set_title(f"{title} (run 0)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        if q == "heading":
            ax2 = axs[1, 0]
            ax2.plot(b["t"], b[q], color="C1", lw=1.0, label="SINS/GPS/SAPV federated")
            ax2.fill_between(b["t"], -3 * b["heading_sigma"], 3 * b["heading_sigma"], color="C1", alpha=0.2,
                             label="±3σ (fused P)")
            ax2.axhline(10, color="k", ls=":", lw=0.8)
            ax2.axhline(-10, color="k", ls=":", lw=0.8, label="±10′")
            ax2.set_ylim(-15, 15)
            ax2.set_ylabel("heading error [arcmin]")
            ax2.grid(alpha=0.3)
            ax2.legend(fontsize=8)
        axs[-1, 0].set_xlabel("time [s]")
        fig.tight_layout()
        fig.savefig(out / fname, dpi=110)
        files.append(fname)
    return files


def plot_variants(mc, out: Path) -> str:
    fig, axs = _fig(1, 1, h=4.5)
    ax = axs[0, 0]
    for i, k in enumerate(VARIANTS):
        h = np.array([s["heading"] for s in mc["series"][k]])
        ax.semilogy(mc["series"][k][0]["t"], np.sqrt(np.mean(h**2, 0)), label=k, lw=1.2 if i < 2 else 0.9,
                    ls="-" if VARIANTS[k].mode != "no_reset" else "--")
    return _finish(fig, ax, "time [s]", "heading error RMS over runs [arcmin]",
                   f"Heading error, {mc['runs']} Monte Carlo runs (reset variants coincide with centralized)",
                   out / "fig7_heading_rms_variants.png", fontsize=7, which="both")


def plot_loss(mc, out: Path) -> list[str]:
    fig, axs = _fig(1, 1, h=4.5)
    ax = axs[0, 0]
    for key, lab in (("none", "no loss"), ("reset", "SAPV lost, fusion-reset"),
                     ("no_reset", "SAPV lost, no-reset")):
        s = mc["loss"][key][0]
        ax.plot(s["t"], s["heading"], label=lab, lw=1.0)
    s = mc["loss"]["reset"][0]
    ax.fill_between(s["t"], -3 * s["heading_sigma"], 3 * s["heading_sigma"], color="C1", alpha=0.15,
                    label="±3σ (fusion-reset)")
    ax.axvspan(*SAPV_LOSS, color="0.6", alpha=0.25, zorder=0, label="SAPV lost")
    ax.set_ylim(-15, 15)
    _finish(fig, ax, "time [s]", "heading error [arcmin]",
            "SINS/GPS/SAPV with the antenna losing the satellite (run 0)", out / "fig8_sapv_loss.png")
    fig, axs = _fig(2, 1, h=6.0)
    for key, lab in (("gps_only", "SINS/GPS"), ("reset", "SINS/GPS/SAPV federated")):
        s = mc["outage"][key][0]
        axs[0, 0].plot(s["t"], s["heading"], label=lab, lw=1.0)
        axs[1, 0].plot(s["t"], np.hypot(s["vE"], s["vN"]), label=lab, lw=1.0)
    for ax in axs[:, 0]:
        ax.axvspan(*GPS_OUTAGE, color="0.6", alpha=0.25, zorder=0, label="GPS outage")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axs[0, 0].set_ylabel("heading error [arcmin]")
    axs[1, 0].set_ylabel("horizontal velocity error [m/s]")
    axs[1, 0].set_xlabel("time [s]")
    axs[0, 0].set_title("GPS outage: the federated solution continues on SAPV (run 0)")
    fig.tight_layout()
    fig.savefig(out / "fig9_gps_outage.png", dpi=110)
    return ["fig8_sapv_loss.png", "fig9_gps_outage.png"]


def plot_pitch_rms(d, out: Path) -> str:
    """Per-epoch RMS of the pitch error over runs (biases drawn per run) with the seed's 精度 < 2′ and 30 s
    marked, the fixed-bias reading and the largest |pitch| of any run."""
    fig, axs = _fig(1, 1, h=4.5)
    ax = axs[0, 0]
    t = d["t"]
    ax.plot(t, d["rms"], lw=1.3, label=f"per-epoch RMS over {d['runs']} runs, biases drawn per run (SPEC)")
    ax.fill_between(t, d["rms"] - 2 * d["se"], d["rms"] + 2 * d["se"], alpha=0.2, color="C0", label="±2 se")
    ax.plot(t, d["fixed_rms"], lw=1.0, ls="--",
            label=f"fixed +500 µg on every axis, {d['n_fixed']} runs (sensitivity)")
    ax.plot(t, d["max_abs"], lw=0.8, color="0.5", label="largest |pitch| of any run (no target)")
    ax.axhline(2.0, color="k", ls=":", lw=1.0, label="seed: level 精度 < 2′")
    ax.axhline(abs(PAPER_T2["pitch"]["std"][1]), color="C3", ls="-.", lw=0.9,
               label=f"seed Table 2 state 2 pitch std {PAPER_T2['pitch']['std'][1]:g}′")
    ax.axvline(SETTLE_S, color="k", lw=0.8, ls="--")
    ax.set_ylim(0, 6)
    return _finish(fig, ax, "time [s]", "pitch error [arcmin]",
                   "SINS/GPS/SAPV pitch error: per-epoch RMS over runs (seed: 精度 < 2′ within 30 s)",
                   out / "fig10_pitch_rms.png", fontsize=7)


def plot_fit(sweep: dict, phi_u: float, paper, out: Path) -> str:
    """SINS/GPS heading mean and std against φ_U0 with the seed's Table 2 state 1 marked (the fit)."""
    fig, axs = _fig(1, 1, h=4.0)
    ax = axs[0, 0]
    p = np.array(sorted(sweep))
    for key, lab, c, pv in (("h_mean", "|mean|", "C0", abs(paper[0])), ("h_std", "std", "C1", paper[1])):
        y = np.array([abs(sweep[x][key]) for x in p])
        se = np.array([sweep[x][f"{key}_se"] for x in p])
        ax.errorbar(p, y, yerr=2 * se, marker="o", color=c,
                    label=f"ours: SINS/GPS heading error {lab} (±2 se)")
        ax.axhline(pv, color=c, ls="--", lw=1.0, label=f"paper Table 2 state 1: {lab} {pv:g}′")
    ax.axvline(abs(phi_u), color="k", ls=":", lw=1.0, label=f"fitted |φ_U0| (signed: {phi_u:g}°)")
    return _finish(fig, ax, "initial heading error φ_U0 [deg]", "heading error [arcmin]",
                   "φ_U0 fitted to the seed's Table 2 state 1 (SINS/GPS heading mean and std)",
                   out / "fig0_phi_u0_fit.png", fontsize=7)
