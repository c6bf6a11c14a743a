"""Seed 004: the figures of the reproduction (seed Figs. 2-3, the sweeps, the design tool, the flexure
generator), each written as a PNG into the output folder; the functions return the file name."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from aidnav.nav.earth import lla_to_enu
from aidnav.sim.distributed_pos import FlexureSpec, flexure_autocorrelation

from .seed_004_tables import LABEL, MODES, PAPER_T4, PAPER_T5, T1_VALUES

__all__ = ["fig_trajectories", "fig_attitude", "fig_sweeps", "fig_design", "fig_flexure", "fig_heading_sigma"]


# ----------------------------------------------------------------------------------------- figures
def _save(fig: Figure, path: Path) -> str:
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=110)
    return path.name


def _legs(ax, segments, names=("AB", "CD")):
    for r in segments:
        if r["name"] in names:
            ax.axvspan(r["start_s"], r["end_s"], color="0.9", zorder=0)


def fig_trajectories(out: Path, bundles: dict) -> str:
    fig = Figure(figsize=(15, 3.6))
    for i, mode in enumerate(MODES):
        ax = fig.add_subplot(1, 5, i + 1)
        tr, _, segs = bundles[mode]
        e, n, _ = lla_to_enu(tr.lat, tr.lon, tr.height, tr.lat[0], tr.lon[0], tr.height[0])
        ax.plot(e / 1e3, n / 1e3, color="0.5", lw=0.8)
        for name, c in (("AB", "tab:blue"), ("CD", "tab:red")):
            r = next(r for r in segs if r["name"] == name)
            m = (tr.time >= r["start_s"]) & (tr.time <= r["end_s"])
            ax.plot(e[m] / 1e3, n[m] / 1e3, color=c, lw=2, label=name)
        ax.plot(e[0] / 1e3, n[0] / 1e3, "k^")
        ax.set_title(f"mode {i + 1}: {LABEL[mode]}" + (" (climb 0→2.4 km)" if mode == "climb" else ""))
        ax.set_xlabel("East [km]")
        if i == 0:
            ax.set_ylabel("North [km]")
            ax.legend(loc="best", fontsize=8)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    fig.suptitle("Fig. 2 (seed): the five motion modes; imaging legs AB and CD")
    fig.tight_layout()
    return _save(fig, out / "fig2_trajectories.png")


def fig_attitude(out: Path, results: dict) -> str:
    fig = Figure(figsize=(15, 8))
    names = ("heading", "pitch", "roll")
    for j, mode in enumerate(MODES):
        fr = results[mode].first
        for i, (k, q) in enumerate(zip((2, 1, 0), names, strict=True)):
            ax = fig.add_subplot(3, 5, 1 + i * 5 + j)
            _legs(ax, fr["segments"])
            ax.plot(fr["time"], fr["rph"][:, k], lw=0.7, label="error (run 1)")
            if q == "heading":
                lim = 0.8 if mode in ("none", "climb") else 0.05
            else:
                lim = 0.05 if mode == "none" else 0.01
            ax.set_ylim(-lim, lim)
            ps = PAPER_T4[mode][i]  # the paper's Table 4 STD on the imaging legs: ± lines
            ax.axhline(ps, color="C3", ls="--", lw=0.8, label=f"paper Table 4 STD ±{ps:g}")
            ax.axhline(-ps, color="C3", ls="--", lw=0.8)
            if i == 0 and j == 0:
                ax.legend(fontsize=6, loc="upper right")
            if j == 0:
                ax.set_ylabel(f"{q} error [deg]")
            if i == 0:
                ax.set_title(f"{LABEL[mode]}")
            if i == 2:
                ax.set_xlabel("time [s]")
            ax.grid(alpha=0.3)
    fig.suptitle("Fig. 3 (seed): sub-IMU attitude errors, 24-state filter, run 1 (AB, CD shaded)")
    fig.tight_layout()
    return _save(fig, out / "fig3_attitude_errors.png")


def fig_sweeps(out: Path, sweeps: dict) -> str:
    fig = Figure(figsize=(15, 8))
    for i, (title, (xs, rows, paper, xlabel)) in enumerate(sweeps.items()):
        ax = fig.add_subplot(2, 3, i + 1)
        xi = np.arange(len(xs))
        for q, c in (("heading", "tab:blue"), ("pitch", "tab:orange"), ("roll", "tab:green")):
            ax.plot(xi, [r[q] for r in rows], "o-", color=c, label=f"{q} (ours)")
            if paper is not None:
                ax.plot(xi, [p[q] for p in paper], "s--", color=c, alpha=0.6, label=f"{q} (paper)")
        ax.set_xticks(xi, [str(x) for x in xs])
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("STD on AB, CD [deg]")
        ax.set_title(title)
        ax.grid(alpha=0.3, which="both")
        if i == 0:
            ax.legend(fontsize=7)
    fig.suptitle("Seed Table 2 factors, one at a time (mean over runs of the imaging-leg STD)")
    fig.tight_layout()
    return _save(fig, out / "sweeps.png")


def fig_design(out: Path, analyses: dict, pred: dict, mc_std: dict, mc_rms: dict) -> str:
    fig = Figure(figsize=(13, 4.5))
    ax = fig.add_subplot(1, 2, 1)
    for mode in MODES:
        a = analyses[mode]
        ax.semilogy(a.time, np.degrees(a.rph_sigma[:, 2]), label=LABEL[mode])
    ax.set_xlabel("time [s]")
    ax.set_ylabel("predicted heading 1σ [deg]")
    ax.set_title("covariance analysis (no Monte Carlo)")
    ax.legend()
    ax.grid(alpha=0.3, which="both")
    ax = fig.add_subplot(1, 2, 2)
    for mode in MODES:
        ax.loglog(pred[mode], mc_rms[mode], "o", label=f"{LABEL[mode]} RMS")
        ax.loglog(pred[mode], mc_std[mode], "x", color=ax.lines[-1].get_color(), label=f"{LABEL[mode]} STD")
    lo, hi = 1e-4, 1.0
    ax.plot([lo, hi], [lo, hi], "k:", lw=0.8)
    ax.set_xlabel("predicted heading σ, RMS over AB, CD [deg]")
    ax.set_ylabel("Monte Carlo heading error [deg]")
    ax.set_title("prediction vs Monte Carlo (o: RMS, x: STD)")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return _save(fig, out / "design_tool.png")


def fig_flexure(out: Path, chk: dict, spec: FlexureSpec) -> str:
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot(1, 1, 1)
    th = flexure_autocorrelation(spec, chk["lags"]) / spec.sigma[None, :] ** 2
    for a, c in zip(range(3), ("tab:blue", "tab:orange", "tab:green"), strict=True):
        ax.plot(chk["lags"], chk["acf"][:, a], color=c, label=f"axis {'xyz'[a]} generated")
        ax.plot(chk["lags"], th[:, a], "--", color=c, lw=0.8)
    ax.axhline(math.exp(-1), color="k", lw=0.6)
    ax.set_xlabel("lag [s]")
    ax.set_ylabel("autocorrelation")
    ax.set_title("flexure generator vs (1+β|t|)e^{-β|t|} (dashed)")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, out / "flexure.png")


def _maneuver_end(segments) -> float:
    """Start of the straight leg after the maneuver: the T1 leg when there is one, else AB [s]."""
    names = [r["name"] for r in segments]
    key = "T1" if "T1" in names else "AB"
    return float(next(r["start_s"] for r in segments if r["name"] == key))


def fig_heading_sigma(out: Path, t5: dict) -> str:
    """Heading σ(t) of the filter (run 1) across the end of the figure-8 maneuver for each T1 of Table 5: the
    seed's mechanism for T1 (the heading keeps settling on the straight leg before AB), with the paper's
    Table 5 heading STD beside each curve's AB start."""
    fig = Figure(figsize=(11, 4.5))
    ax = fig.add_subplot(1, 1, 1)
    for i, t1 in enumerate(T1_VALUES):
        fr = t5[t1].first
        t0 = _maneuver_end(fr["segments"])
        ab = float(next(r["start_s"] for r in fr["segments"] if r["name"] == "AB")) - t0
        tt = fr["time"] - t0
        m = (tt >= -300) & (tt <= ab + 400)
        ax.semilogy(tt[m], fr["sigma"][m, 2], color=f"C{i}", lw=1.0, label=f"T1 = {t1} s (AB from {ab:g} s)")
        ax.axvline(ab, color=f"C{i}", ls=":", lw=0.8)
        ax.plot([ab], [PAPER_T5[t1][0]], marker="*", ms=9, color=f"C{i}", ls="none")
    ax.plot([], [], marker="*", ls="none", color="k", label="paper Table 5 heading STD (at AB)")
    ax.axvline(0.0, color="k", lw=1.0)
    ax.set_xlabel("time since the end of the figure-8 maneuver [s]")
    ax.set_ylabel("filter heading σ [deg]")
    ax.set_title("Heading σ(t) across the end of the maneuver (run 1): the seed's mechanism for T1")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return _save(fig, out / "heading_sigma_t1.png")
