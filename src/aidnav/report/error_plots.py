"""Figures of navigation errors and filter consistency (PNG files).

Uses matplotlib's object API with the Agg canvas (``matplotlib.figure.Figure``), never pyplot, so
it changes no global backend or state and works headless.

Time axis of every figure: seconds since the first plotted epoch; the absolute time of that epoch is
stated in the axis label, in the inputs' time scale (``time_scale``, default "GPS SOW": GPS seconds
of week, docs/conventions.md "Time"), e.g. ``time since 345600.000 s (GPS SOW) [s]``.
Errors are estimate − reference (see :mod:`aidnav.analysis.errors`); envelopes are ±k·σ from the
estimate's own standard deviations (k = 3 by default) where the estimate has them.

Y-limits are robust (:func:`robust_limit`): set by the 99th percentile of the errors, widened to show
the typical (median) envelope but never beyond 5× the error scale, so that a large initial σ (e.g. an
unaligned heading at ±540°) does not flatten errors of a tenth of a degree; the envelope is clipped to
the view and the epochs whose error lies outside it are counted on the axis.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from aidnav.analysis.consistency import chi2_band
from aidnav.analysis.errors import ErrorSeries

DPI = 120


def _new_figure(nrows: int, height: float = 2.4) -> tuple[Figure, list]:
    fig = Figure(figsize=(9.0, 0.8 + height * nrows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, 1, sharex=True, squeeze=False)[:, 0]
    return fig, list(axes)


def time_axis(time: np.ndarray, time_scale: str = "GPS SOW") -> tuple[np.ndarray, str]:
    """Seconds since the first epoch and the axis label naming that epoch's absolute time."""
    t = np.asarray(time, dtype=float)
    t0 = float(t[0]) if len(t) else 0.0
    return t - t0, f"time since {t0:.3f} s ({time_scale}) [s]"


def _save(fig: Figure, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI)
    return path


def robust_limit(values, envelope=None, pct: float = 99.0, margin: float = 1.25,
                 envelope_cap: float = 5.0) -> float:
    """Half-range of a y-axis centred on 0 for ``values`` (errors) and an optional ``envelope``
    (k·σ ≥ 0, same unit).

    error scale e = ``margin`` · (``pct``-th percentile of |values|); envelope scale s = median of the
    finite positive envelope values; limit = max(e, min(s, ``envelope_cap``·e)); e alone when there is
    no envelope, s when all errors are 0 or missing, 1 when both are empty. Percentiles, not the
    maximum: a few outliers (or the first epochs of an unaligned filter) do not set the scale."""
    v = np.abs(np.asarray(values, dtype=float)).ravel()
    v = v[np.isfinite(v)]
    e = margin * float(np.percentile(v, pct)) if v.size else 0.0
    s = 0.0
    if envelope is not None:
        env = np.asarray(envelope, dtype=float).ravel()
        env = env[np.isfinite(env) & (env > 0)]
        if env.size:
            s = float(np.median(env))
    if e > 0:
        return max(e, min(s, envelope_cap * e))
    return s if s > 0 else 1.0


def _note_outside(ax, values, lo, hi, unit) -> int:
    v = np.asarray(values, dtype=float)
    fin = np.isfinite(v)
    out = fin & ((v < lo) | (v > hi))
    n = int(out.sum())
    if n:
        ax.text(0.01, 0.03, f"{n} epoch(s) outside the view (max |e| {np.max(np.abs(v[out])):.3g} {unit})",
                transform=ax.transAxes, fontsize="x-small", color="tab:red", va="bottom")
    return n


def _component_figure(t, xlabel, err, std, names, unit, title, nsigma) -> Figure:
    fig, axes = _new_figure(len(names))
    for i, (ax, name) in enumerate(zip(axes, names, strict=True)):
        s = None
        if std is not None and np.any(np.isfinite(std[:, i])):
            s = nsigma * std[:, i]
        lim = robust_limit(err[:, i], s)
        if s is not None:
            sc = np.minimum(s, 1.05 * lim)  # envelope clipped to the view
            ax.fill_between(t, -sc, sc, color="tab:orange", alpha=0.25, lw=0,
                            label=f"±{nsigma:g}σ (estimate)")
        ax.plot(t, err[:, i], color="tab:blue", lw=0.8, label="error")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylim(-lim, lim)
        _note_outside(ax, err[:, i], -lim, lim, unit)
        ax.set_ylabel(f"{name} [{unit}]")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="upper right", fontsize="small")
    axes[0].set_title(title)
    axes[-1].set_xlabel(xlabel)
    return fig


def position_error_figure(errors: ErrorSeries, nsigma: float = 3.0, time_scale: str = "GPS SOW") -> Figure:
    """The figure of :func:`plot_position_errors` (not saved)."""
    t, xl = time_axis(errors.time, time_scale)
    return _component_figure(t, xl, errors.pos, errors.std_pos, ["dE", "dN", "dU"], "m",
                             "Position error (estimate − reference), ENU", nsigma)


def velocity_error_figure(errors: ErrorSeries, nsigma: float = 3.0,
                          time_scale: str = "GPS SOW") -> Figure | None:
    """The figure of :func:`plot_velocity_errors` (not saved); None without velocity errors."""
    if errors.vel is None:
        return None
    t, xl = time_axis(errors.time, time_scale)
    return _component_figure(t, xl, errors.vel, errors.std_vel, ["dvE", "dvN", "dvU"], "m/s",
                             "Velocity error (estimate − reference), ENU", nsigma)


def attitude_error_figure(errors: ErrorSeries, nsigma: float = 3.0,
                          time_scale: str = "GPS SOW") -> Figure | None:
    """The figure of :func:`plot_attitude_errors` (not saved); None without attitude errors."""
    if errors.att is None:
        return None
    t, xl = time_axis(errors.time, time_scale)
    std = None if errors.std_att is None else np.degrees(errors.std_att)
    return _component_figure(t, xl, np.degrees(errors.att), std, ["droll", "dpitch", "dheading"], "deg",
                             "Attitude error (estimate − reference)", nsigma)


def horizontal_error_figure(errors: ErrorSeries, nsigma: float = 3.0, time_scale: str = "GPS SOW") -> Figure:
    """The figure of :func:`plot_horizontal_error` (not saved)."""
    t, xl = time_axis(errors.time, time_scale)
    fig, (ax,) = _new_figure(1, height=3.2)
    sh = None
    if errors.std_pos is not None:
        sh = nsigma * np.hypot(errors.std_pos[:, 0], errors.std_pos[:, 1])
        if not np.any(np.isfinite(sh)):
            sh = None
    top = robust_limit(np.concatenate([errors.horizontal, errors.pos3d]), sh)
    if sh is not None:
        ax.fill_between(t, 0.0, np.minimum(sh, 1.05 * top), color="tab:orange", alpha=0.25, lw=0,
                        label=f"{nsigma:g}·√(σE²+σN²) (estimate)")
    ax.plot(t, errors.horizontal, color="tab:blue", lw=0.8, label="horizontal")
    ax.plot(t, errors.pos3d, color="tab:gray", lw=0.6, alpha=0.8, label="3D")
    ax.set_ylabel("position error [m]")
    ax.set_xlabel(xl)
    ax.set_ylim(0.0, top)
    _note_outside(ax, errors.pos3d, -np.inf, top, "m")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize="small")
    ax.set_title("Horizontal position error")
    return fig


def plot_position_errors(errors: ErrorSeries, path, nsigma: float = 3.0, time_scale: str = "GPS SOW") -> Path:
    """dE, dN, dU [m] vs time with ±nsigma·σ envelopes; writes ``path`` (PNG), returns it."""
    return _save(position_error_figure(errors, nsigma, time_scale), path)


def plot_velocity_errors(errors: ErrorSeries, path, nsigma: float = 3.0,
                         time_scale: str = "GPS SOW") -> Path | None:
    """dvE, dvN, dvU [m/s] vs time with ±nsigma·σ; None (no file) without velocity errors."""
    fig = velocity_error_figure(errors, nsigma, time_scale)
    return None if fig is None else _save(fig, path)


def plot_attitude_errors(errors: ErrorSeries, path, nsigma: float = 3.0,
                         time_scale: str = "GPS SOW") -> Path | None:
    """droll, dpitch, dheading [deg] vs time with ±nsigma·σ; None (no file) without attitude."""
    fig = attitude_error_figure(errors, nsigma, time_scale)
    return None if fig is None else _save(fig, path)


def plot_horizontal_error(errors: ErrorSeries, path, nsigma: float = 3.0,
                          time_scale: str = "GPS SOW") -> Path:
    """Horizontal and 3D position error [m] vs time, with nsigma·√(σE²+σN²) when available."""
    return _save(horizontal_error_figure(errors, nsigma, time_scale), path)


def plot_nees(time: np.ndarray, values: np.ndarray, dof: int, path, prob: float = 0.95,
              label: str = "NEES", time_scale: str = "GPS SOW") -> Path:
    """NEES (or NIS) vs time with its two-sided χ² ``prob`` band.

    values : (N,) one run, or (R, N) runs (their per-epoch average is plotted against the band of
        the R-run average, R·ε̄ ~ χ²(R·dof)); dof : dimension n of each value.
    """
    v = np.asarray(values, dtype=float)
    if v.ndim == 1:
        v = v[None, :]
    r = v.shape[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN epochs stay NaN
        m = np.nanmean(v, axis=0)
    lo, hi = chi2_band(dof, r, prob)
    t, xl = time_axis(time, time_scale)
    fig, (ax,) = _new_figure(1, height=3.2)
    ax.fill_between(t, lo, hi, color="tab:green", alpha=0.15, lw=0,
                    label=f"{100 * prob:g}% χ² band ({lo:.3g}, {hi:.3g})")
    ax.plot(t, m, color="tab:blue", lw=0.8, label=label if r == 1 else f"{label}, mean of {r} runs")
    ax.axhline(dof, color="k", lw=0.6, ls="--", label=f"expected {dof}")
    fin = np.isfinite(m)
    inside = float(np.mean((m[fin] >= lo) & (m[fin] <= hi))) if fin.any() else float("nan")
    ax.set_title(f"{label} (dof {dof}); {100 * inside:.1f}% of epochs inside the band")
    if fin.any() and np.max(m[fin]) > 50 * hi:
        ax.set_yscale("log")
    ax.set_ylabel(label)
    ax.set_xlabel(xl)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize="small")
    return _save(fig, path)


def plot_errors(errors: ErrorSeries, out_dir, prefix: str = "", nsigma: float = 3.0,
                time_scale: str = "GPS SOW") -> list[Path]:
    """All error figures into ``out_dir``: ``<prefix>position_errors.png``, ``velocity_errors.png``
    (with velocity), ``attitude_errors.png`` (with attitude), ``horizontal_error.png``.
    Returns the paths written."""
    out = Path(out_dir)
    paths = [plot_position_errors(errors, out / f"{prefix}position_errors.png", nsigma, time_scale),
             plot_velocity_errors(errors, out / f"{prefix}velocity_errors.png", nsigma, time_scale),
             plot_attitude_errors(errors, out / f"{prefix}attitude_errors.png", nsigma, time_scale),
             plot_horizontal_error(errors, out / f"{prefix}horizontal_error.png", nsigma, time_scale)]
    return [p for p in paths if p is not None]
