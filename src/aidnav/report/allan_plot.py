"""Figure of an IMU characterisation: the six Allan deviation curves with the fitted noise terms.

Matplotlib object API on the Agg canvas (no pyplot state). Units: τ in seconds; gyro ADEV in deg/h,
accelerometer ADEV in µg (CONVENTIONS boundary units). Each panel shows the overlapping ADEV with its 95%
chi-square interval (filled markers: fitted; open: shown only), the maximum-likelihood model, and each
term's own ADEV with its slope: quantisation −1, white noise (ARW/VRW) −1/2, the Gauss-Markov bias
instability (its bump; the dotted line at 0.6643·B is the flicker floor with the same height), random
walk +1/2. Terms that the log does not resolve are drawn faint and marked "not resolved".
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

__all__ = ["plot_allan"]

DPI = 120
_COLORS = {"Q": "tab:purple", "N": "tab:green", "GM": "tab:orange", "K": "tab:red"}


def _term_labels(a, sensor: str) -> dict:
    from aidnav.analysis import characterise as C

    if sensor == "gyro":
        u = {"Q": (1.0, "rad", "quantisation"), "N": (C.DEG_SQRT_H, "deg/√h", "ARW"),
             "GM": (C.DEG_H, "deg/h", "bias instability B"), "K": (C.DEG_H_SQRT_H, "deg/h/√h", "RRW")}
    else:
        u = {"Q": (1.0, "m/s", "quantisation"), "N": (C.M_S_SQRT_H, "m/s/√h", "VRW"),
             "GM": (C.UG, "µg", "bias instability B"), "K": (C.UG_SQRT_H, "µg/√h", "acc. RW")}
    keys = {"Q": "quantisation", "N": "white", "GM": "bias_instability", "K": "rrw"}
    slope = {"Q": "−1", "N": "−1/2", "GM": "bump", "K": "+1/2"}
    out = {}
    for t, k in keys.items():
        f, unit, name = u[t]
        te = a.terms[k]
        if te.fitted:
            txt = f"{name} {te.value / f:.3g} [{te.lo / f:.3g}, {te.hi / f:.3g}] {unit} (slope {slope[t]})"
            if t == "GM":
                tt = a.terms["gm_tau"]
                txt += (f", T {tt.value:.3g} s" if tt.fitted else ", T not resolved")
        else:
            ub = "" if te.upper is None else f" < {te.upper / f:.3g} {unit}"
            txt = f"{name} not resolved{ub} (slope {slope[t]})"
        out[t] = (te.fitted, txt)
    return out


def plot_allan(ch, path, title: str | None = None) -> Path:
    """Write the 2 × 3 panel Allan deviation figure of a characterisation
    (:class:`aidnav.analysis.characterise.Characterisation`) to ``path`` (PNG) and return the path."""
    from aidnav.analysis import characterise as C

    fig = Figure(figsize=(16.0, 9.5), layout="constrained")
    FigureCanvasAgg(fig)
    axs = fig.subplots(2, 3, squeeze=False)
    for i, a in enumerate(ch.axes):
        ax = axs[i // 3, i % 3]
        sensor = a.sensor
        f, unit = (C.DEG_H, "deg/h") if sensor == "gyro" else (C.UG, "µg")
        tau = a.taus
        y = a.adev / f
        lo = np.where(np.isfinite(a.adev_lo), a.adev_lo / f, y)
        hi = np.where(np.isfinite(a.adev_hi), a.adev_hi / f, y)
        err = np.vstack((y - lo, hi - y))
        u = a.used
        ax.errorbar(tau[u], y[u], yerr=err[:, u], fmt="o", ms=4, color="tab:blue", ecolor="tab:blue",
                    elinewidth=0.8, capsize=2, label="ADEV (95%)")
        if (~u).any():
            ax.errorbar(tau[~u], y[~u], yerr=err[:, ~u], fmt="o", ms=4, mfc="none", color="tab:blue",
                        ecolor="tab:blue", elinewidth=0.5, capsize=2, alpha=0.6, label="not fitted")
        tf = tau[u] if u.any() else tau  # the model is drawn over the fitted τ range
        tt = np.exp(np.linspace(math.log(tf[0]), math.log(tf[-1]), 200))
        ax.plot(tt, a.model_adev(tt) / f, color="k", lw=1.2, label="fitted model")
        labels = _term_labels(a, sensor)
        for t in ("Q", "N", "GM", "K"):
            comp = a.model_adev(tt, t) / f
            fitted, txt = labels[t]
            if not np.any(comp > 0):
                ax.plot([], [], color=_COLORS[t], ls=":", lw=1.0, alpha=0.5, label=txt)
                continue
            ax.plot(tt, comp, color=_COLORS[t], ls="--" if fitted else ":", lw=1.3 if fitted else 0.9,
                    alpha=1.0 if fitted else 0.5, label=txt)
            if t == "GM" and fitted:
                b = a.terms["bias_instability"].value
                ax.axhline(C.FLICKER_ADEV * b / f, color=_COLORS[t], ls=":", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ymin = max(np.nanmin(lo[lo > 0]) if np.any(lo > 0) else y.min(), 1e-300) / 3.0
        ax.set_ylim(ymin, np.nanmax(hi) * 3.0)
        ax.set_xlabel("τ [s]")
        ax.set_ylabel(f"Allan deviation [{unit}]")
        ax.set_title(a.axis.replace("_", " "))
        ax.grid(True, which="both", alpha=0.25)
        ax.legend(fontsize="x-small", loc="upper right")
    if title:
        fig.suptitle(title)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI)
    return path
