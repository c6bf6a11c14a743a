"""Reproduction of seed 004: distributed-POS transfer alignment and flight-trajectory design (SPEC §5).

What is rebuilt (seed §3, Tables 4–8, Figs. 2–3, and SPEC §5.3's acceptance targets):

* **Table 4** — sub-IMU roll/pitch/heading error STD on the imaging legs for the five motion modes of
  seed Table 3 (``examples/none.yaml``, ``s_turns.yaml``, ``o_circle.yaml``, ``figure8.yaml``,
  ``climb.yaml``; AB and CD are their named legs), T1 = 0, T2 = 400 s.
* **Table 5** — figure-8, T1 = 0 … 500 s (a straight leg "T1" inserted between the maneuver and AB).
* **Table 6** — figure-8, T1 = 200 s, T2 = 100/200/400 s (the lengths of AB and of CD).
* **Table 8** — figure-8, T1 = 200 s, T2 = 400 s, GNSS baseline 20/40/60 km (master position accuracy
  of seed Table 7); attitude, velocity, position and master–sub baseline-length errors.
* **Sweeps** of seed Table 2, one factor at a time around the baseline (figure-8, T1 = 200 s,
  T2 = 400 s, 20 km, the §3.1 sub-IMU): maneuver (Table 4), sub-IMU grade (Table 1: high/medium/low),
  T1 (Table 5), T2 (Table 6), baseline (Table 8) — ``sweeps.png`` and the tables.
* **21 vs 24 states** — Table 4 again with the seed's 21-state filter (first-order flexure).
* **Master-error model** — Table 4 again with Gauss-Markov (τ = 100 s) instead of white master errors.
* **Noise reading** — the sub-IMU's "random drift 0.1°/h" is read as an angle random walk of 0.1°/√h
  (``sub_arw``: the seed's own attitude STDs need that much gyro noise); Tables 4, 5, 6 again with the
  seed004_sub preset's white-noise density 0.1°/h/√Hz (ARW 0.0017°/√h), as a sensitivity case.
* **Design tool** — the covariance-only prediction (:mod:`aidnav.experiments.design`) of each mode's
  accuracy, ranked against the Monte Carlo.
* **Flexure generator** — σ and 1/e time of the second-order Markov generator against the spec.
* **Figures** — ``fig2_trajectories.png`` (seed Fig. 2), ``fig3_attitude_errors.png`` (seed Fig. 3),
  ``sweeps.png``, ``design_tool.png``, ``flexure.png``.

Statistic (seed §3.2): for each run, the standard deviation over time of each error on AB and on CD
(the seed's "STD"), averaged over the two legs, then averaged over the Monte Carlo runs (10 in the
seed). The RMS about zero is computed too (``runs.csv``); the design tool predicts that one.
Errors are estimate − truth at the 1-s filter epochs (after the update). Latitude/longitude errors are
in metres (north/east); the baseline error is that of the master–sub distance |p̃_sub − p̃_master|.

Random numbers: ``numpy.random.SeedSequence(base_seed).spawn(runs)``; run i uses the same child in every
case (common random numbers: a factor's effect is not hidden by different draws), split into the
flexure, sub-IMU and master streams by :func:`aidnav.sim.distributed_pos.run_streams`.

SPEC errata followed: 5.2-1 (eqs. 1–10 reconstructed as SPEC §5.1: velocity + attitude matching with
lever-arm compensation, DCM attitude difference), 5.2-2 (24 states with θ̇; the seed's 21 states run as
the first-order-flexure variant), 5.2-3 (heading 40° clockwise from North), 5.2-4 (OCR cells read as
0.0038 and 0.5192). Trajectory details not in the seed (turn rates, S amplitude, climb) are those of the
example files (SPEC §5.1 suggestions). ``holds`` is the verdict of the SPEC §5.3 predicates, computed.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from rich.console import Console
from rich.table import Table

from aidnav.experiments.design import predict_accuracy
from aidnav.experiments.reproduce.summary import summary_row, summary_table, write_summary
from aidnav.filters.transfer import TransferConfig, run_transfer, segment_statistic, transfer_errors
from aidnav.sim.distributed_pos import (
    DistributedPosConfig,
    FlexureSpec,
    MasterPosSpec,
    simulate_distributed_pos,
    simulate_flexure,
    sub_geometry,
)
from aidnav.sim.imu import ImuSpec
from aidnav.sim.scenario import Scenario, StraightSegment, load_scenario
from aidnav.sim.trajectory import generate_truth

SEED = "004"
TITLE = ("Design and comparative analysis of flight trajectories for airborne Earth observation "
         "(distributed POS transfer alignment)")
MODES = ("none", "s_turns", "o_circle", "figure8", "climb")
LABEL = {"none": "none", "s_turns": "S", "o_circle": "O", "figure8": "8", "climb": "climb"}
#: sub-IMU grades: seed Table 1 (high/medium/low) and §3.1 (sub), with the "random drift X°/h" read as an
#: angle random walk of X°/√h (``*_arw``, the reading the reproduction uses) or as the preset's
#: white-noise density X°/h/√Hz (no suffix; 60× less ARW)
GRADES = {"sub": "seed004_sub", "high": "seed004_high", "medium": "seed004_medium", "low": "seed004_low",
          "sub_arw": "seed004_sub with ARW 0.1 deg/sqrt(h)",
          "high_arw": "seed004_high with ARW 0.01 deg/sqrt(h)",
          "medium_arw": "seed004_medium with ARW 0.05 deg/sqrt(h)",
          "low_arw": "seed004_low with ARW 0.1 deg/sqrt(h)"}
#: the sub-IMU of the reproduction's tables (see the module docstring: "Noise reading")
BASE_GRADE = "sub_arw"
SWEEP_GRADES = ("high_arw", "medium_arw", "low_arw", "sub_arw")
T1_VALUES = (0, 100, 200, 300, 400, 500)
T2_VALUES = (100, 200, 400)
BASELINES = (20, 40, 60)
MASTER_TAU_S = 100.0
#: the per-run statistics, in this order: attitude [deg], velocity [m/s], position [m], baseline [m]
QUANTS = ("heading", "pitch", "roll", "vE", "vN", "vU", "lat", "lon", "h", "baseline")
UNITS = ("deg", "deg", "deg", "m/s", "m/s", "m/s", "m", "m", "m", "m")

# ------------------------------------------------------------------------------------ seed's numbers
PAPER_T4 = {"none": (0.2483, 0.0376, 0.0404), "s_turns": (0.0120, 0.0082, 0.0041),
            "o_circle": (0.0209, 0.0082, 0.0041), "figure8": (0.0116, 0.0084, 0.0040),
            "climb": (0.1521, 0.0092, 0.0038)}
PAPER_T5 = {0: (0.0116, 0.0084, 0.0040), 100: (0.0116, 0.0083, 0.0040), 200: (0.0091, 0.0085, 0.0038),
            300: (0.0093, 0.0082, 0.0038), 400: (0.0099, 0.0081, 0.0038), 500: (0.0102, 0.0082, 0.0038)}
PAPER_T6 = {100: (0.0083, 0.0076, 0.0038), 200: (0.0086, 0.0077, 0.0039), 400: (0.0091, 0.0085, 0.0038)}
PAPER_T8 = {"heading": (0.0101, 0.0098, 0.0098), "pitch": (0.0080, 0.0080, 0.0081),
            "roll": (0.0037, 0.0038, 0.0038), "vE": (0.0137, 0.0162, 0.0181), "vN": (0.0162, 0.0171, 0.0189),
            "vU": (0.0194, 0.0194, 0.0201), "lat": (0.2057, 0.2445, 0.2465), "lon": (0.1688, 0.2308, 0.2782),
            "h": (0.4942, 0.4849, 0.5192), "baseline": (0.2180, 0.5972, 1.2757)}
FACTOR2 = "paper / 2 <= ours <= 2 * paper"


# ------------------------------------------------------------------------------------------ cases
@dataclass(frozen=True)
class Case:
    """One Monte Carlo cell: trajectory (mode, T1, T2 [s]; T2 None = as in the example file), sub-IMU
    grade (key of ``GRADES``), GNSS baseline [km], filter states, master error correlation time [s]."""

    mode: str = "figure8"
    t1: float = 0.0
    t2: float | None = None
    grade: str = BASE_GRADE
    baseline_km: float = 20.0
    nstate: int = 24
    master_tau: float = 0.0

    @property
    def traj_key(self):
        return (self.mode, self.t1, self.t2)


BASE = Case(mode="figure8", t1=200.0, t2=400.0)


def scenario_path(mode: str):
    """The scenario file of a motion mode: packaged (``aidnav/sim/scenarios``) or ``examples/`` of the
    source tree."""
    pkg = resources.files("aidnav.sim").joinpath("scenarios", f"{mode}.yaml")
    if pkg.is_file():
        return pkg
    p = Path(__file__).resolve().parents[4] / "examples" / f"{mode}.yaml"
    if p.is_file():
        return p
    raise FileNotFoundError(f"seed 004: scenario {mode}.yaml not found (packaged or in examples/)")


def load_mode(mode: str) -> Scenario:
    """The validated scenario of a motion mode (seed Table 3)."""
    p = scenario_path(mode)
    with resources.as_file(p) as f:
        return load_scenario(f)


def variant(scn: Scenario, t1: float = 0.0, t2: float | None = None) -> Scenario:
    """The scenario with a straight leg "T1" of ``t1`` [s] inserted before AB and AB, CD lasting ``t2``."""
    segs = list(scn.segments)
    names = [s.name for s in segs]
    if "AB" not in names or "CD" not in names:
        raise ValueError(f"scenario {scn.name}: needs legs named AB and CD")
    if t2 is not None:
        segs = [s.model_copy(update={"duration_s": float(t2)}) if s.name in ("AB", "CD") else s for s in segs]
    if t1 > 0:
        i = names.index("AB")
        segs.insert(i, StraightSegment(type="straight", duration_s=float(t1), name="T1"))
    return scn.model_copy(update={"segments": segs, "name": f"{scn.name}_T1_{t1:g}_T2_{t2}"})


def imu_spec(grade: str) -> ImuSpec:
    """Sub-IMU spec of a grade key of ``GRADES``: the seed004_* presets (seed Table 1, §3.1; "random
    drift X°/h" read as X°/h/√Hz), or ``<preset>_arw``: the same with the gyro's random drift read as an
    angle random walk of X°/√h (60× the preset's ARW; accelerometer unchanged)."""
    if grade not in GRADES:
        raise ValueError(f"seed 004: unknown sub-IMU grade {grade!r}; use one of {', '.join(GRADES)}")
    if grade.endswith("_arw"):
        base = ImuSpec.grade(GRADES[grade.removesuffix("_arw")])
        return replace(base, gyro_arw=base.gyro_arw * 60.0, name=f"{base.name}_arw")
    return ImuSpec.grade(GRADES[grade])


def sim_config(case: Case) -> DistributedPosConfig:
    master = MasterPosSpec.for_gnss_baseline(case.baseline_km, corr_time_s=case.master_tau)
    return DistributedPosConfig(sub_imu=imu_spec(case.grade), master=master)


# ------------------------------------------------------------------------------------- Monte Carlo
@dataclass
class CaseResult:
    """Per-run statistics of a case: ``std`` and ``rms`` (runs, 10) in the order of ``QUANTS`` (angles in
    deg), and the first run's error time series (for the figures)."""

    case: Case
    std: np.ndarray
    rms: np.ndarray
    first: dict

    def mean(self, stat: str = "std") -> dict:
        a = getattr(self, stat).mean(axis=0)
        return dict(zip(QUANTS, a.tolist(), strict=True))


def _run_stats(res, run) -> tuple[np.ndarray, np.ndarray, object]:
    e = transfer_errors(res, run)
    cols = np.column_stack([np.degrees(e.rph[:, [2, 1, 0]]), e.vel, e.pos[:, [1, 0, 2]], e.baseline])
    s = segment_statistic(e.time, cols, run.segments, stat="std")
    r = segment_statistic(e.time, cols, run.segments, stat="rms")
    return s, r, e


class _Runner:
    def __init__(self, run_seeds, say):
        self.run_seeds = run_seeds
        self.say = say
        self._traj: dict = {}
        self.results: dict[Case, CaseResult] = {}

    def bundle(self, key):
        if key not in self._traj:
            mode, t1, t2 = key
            tb = generate_truth(variant(load_mode(mode), t1, t2))
            geo = sub_geometry(tb[0], tb[1], DistributedPosConfig().lever_arm)
            self._traj = {key: (tb, geo)}  # one trajectory (and its 30-MB geometry) at a time
        return self._traj[key]

    def run(self, case: Case) -> CaseResult:
        if case in self.results:
            return self.results[case]
        tb, geo = self.bundle(case.traj_key)
        cfg = sim_config(case)
        fcfg = TransferConfig.from_sim(cfg, nstate=case.nstate)
        S, R, first = [], [], {}
        for i, ss in enumerate(self.run_seeds):
            run = simulate_distributed_pos(tb, cfg, ss, geo)
            res = run_transfer(run, fcfg)
            s, r, e = _run_stats(res, run)
            S.append(s)
            R.append(r)
            if i == 0:
                first = {"time": e.time, "rph": np.degrees(e.rph),
                         "sigma": np.degrees(np.sqrt(res.pdiag[:, :3])), "segments": run.segments}
        out = CaseResult(case, np.array(S), np.array(R), first)
        self.results[case] = out
        h, p, r_ = out.mean()["heading"], out.mean()["pitch"], out.mean()["roll"]
        self.say(f"{case.mode:8s} T1={case.t1:5g} T2={case.t2!s:5s} {case.grade:6s} L0={case.baseline_km:g} "
                 f"n={case.nstate} tau={case.master_tau:g}: heading {h:.4f} pitch {p:.4f} roll {r_:.4f} deg")
        return out


# ------------------------------------------------------------------------------------- flexure check
def flexure_check(spec: FlexureSpec | None = None, dt: float = 0.1, duration_s: float = 1.0e5,
                  seed: int = 4) -> dict:
    """Generator statistics: σ̂ and the 1/e lag τ̂ per axis, and their relative errors.

    The lag is the first crossing of 1/e by the sample autocorrelation (FFT, linear interpolation).
    Returns {sigma_deg, tau_s, sigma_rel_err, tau_rel_err, lags, acf} (per axis arrays).
    """
    spec = spec or FlexureSpec()
    n = int(duration_s / dt)
    th, _ = simulate_flexure(spec, dt, n, np.random.default_rng(seed))
    x = th - th.mean(axis=0)
    sig = x.std(axis=0)
    nfft = 1 << int(math.ceil(math.log2(2 * len(x))))
    f = np.fft.rfft(x, nfft, axis=0)
    acov = np.fft.irfft(f * np.conj(f), nfft, axis=0)[: int(4 * max(spec.tau_s) / dt)] / len(x)
    acf = acov / acov[0]
    tau = np.empty(3)
    for a in range(3):
        k = int(np.argmax(acf[:, a] < math.exp(-1.0)))
        y0, y1 = acf[k - 1, a], acf[k, a]
        tau[a] = dt * (k - 1 + (y0 - math.exp(-1.0)) / (y0 - y1))
    return {"sigma_deg": np.degrees(sig), "tau_s": tau,
            "sigma_rel_err": np.degrees(sig) / spec.sigma_deg - 1.0, "tau_rel_err": tau / spec.tau - 1.0,
            "lags": np.arange(len(acf)) * dt, "acf": acf}


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
    from aidnav.nav.earth import lla_to_enu

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
    from aidnav.sim.distributed_pos import flexure_autocorrelation

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


# ------------------------------------------------------------------------------------------ tables
def _spread(vals) -> float:
    v = np.asarray(vals, float)
    return float(np.max(np.abs(v / v.mean() - 1.0)))


def _att(d) -> tuple:
    return d["heading"], d["pitch"], d["roll"]


def _t4_rows(t4: dict, suffix: str) -> list[dict]:
    """Table-4 rows (values against the paper, factor 2) and the SPEC §5.3 Table-4 predicates."""
    names = ("heading", "pitch", "roll")
    rows = []
    for m in MODES:
        for q, p in zip(names, PAPER_T4[m], strict=True):
            rows.append(summary_row(f"{q} STD, {LABEL[m]}{suffix}", "deg", t4[m][q], p, FACTOR2))
    h = {m: t4[m]["heading"] for m in MODES}
    ph = {m: PAPER_T4[m][0] for m in MODES}
    for a, b, target in (("none", "figure8", "ours >= 5"), ("none", "climb", "ours > 1"),
                         ("climb", "o_circle", "ours > 1"), ("o_circle", "s_turns", "ours > 1")):
        rows.append(summary_row(f"heading {LABEL[a]} / {LABEL[b]}{suffix}", "-", h[a] / h[b], ph[a] / ph[b],
                                target))
    rows.append(summary_row(f"heading S / 8 (S ≈ 8: within 30 %){suffix}", "-", h["s_turns"] / h["figure8"],
                            ph["s_turns"] / ph["figure8"], "abs(ours - 1) <= 0.3"))
    four = ("s_turns", "o_circle", "figure8", "climb")
    for k, q in ((1, "pitch"), (2, "roll")):
        ours = [t4[m][q] for m in four]
        pap = [PAPER_T4[m][k] for m in four]
        rows.append(summary_row(f"{q}: largest deviation of the 4 maneuvers from their mean{suffix}", "-",
                                _spread(ours), _spread(pap), "ours <= 0.3"))
        rows.append(summary_row(f"{q}: none / mean of the 4 maneuvers{suffix}", "-",
                                t4["none"][q] / np.mean(ours),
                                PAPER_T4["none"][k] / np.mean(pap), "ours >= 2"))
    return rows


def _t5_rows(t5: dict, suffix: str) -> list[dict]:
    """Table-5 rows (values, factor 2) and the SPEC §5.3 Table-5 predicates."""
    names = ("heading", "pitch", "roll")
    rows = []
    for t in T1_VALUES:
        for q, p in zip(names, PAPER_T5[t], strict=True):
            rows.append(summary_row(f"{q} STD, T1 = {t} s{suffix}", "deg", t5[t][q], p, FACTOR2))
    hs = [t5[t]["heading"] for t in T1_VALUES]
    rows.append(summary_row(f"T1 of the lowest heading STD{suffix}", "s", T1_VALUES[int(np.argmin(hs))], 200,
                            "100 <= ours <= 300"))
    for k, q, tol in ((0, "heading", 0.3), (1, "pitch", 0.1), (2, "roll", 0.1)):
        rows.append(summary_row(f"{q}: largest deviation across T1 from the mean{suffix}", "-",
                                _spread([t5[t][q] for t in T1_VALUES]),
                                _spread([PAPER_T5[t][k] for t in T1_VALUES]), f"ours <= {tol}"))
    return rows


def _t6_rows(t6: dict, suffix: str) -> list[dict]:
    """Table-6 rows (values, factor 2) and the SPEC §5.3 Table-6 predicate."""
    names = ("heading", "pitch", "roll")
    rows = []
    for t in T2_VALUES:
        for q, p in zip(names, PAPER_T6[t], strict=True):
            rows.append(summary_row(f"{q} STD, T2 = {t} s{suffix}", "deg", t6[t][q], p, FACTOR2))
    hs = [t6[t]["heading"] for t in T2_VALUES]
    phs = [PAPER_T6[t][0] for t in T2_VALUES]
    rows.append(summary_row(f"heading: smallest ratio of successive T2 (non-decreasing: >= 1){suffix}", "-",
                            min(hs[1] / hs[0], hs[2] / hs[1]), min(phs[1] / phs[0], phs[2] / phs[1]),
                            "ours >= 1"))
    return rows


def _tables(res: dict, cov_pred: dict, flex: dict, flex_spec: FlexureSpec) -> list[dict]:
    tables = []
    names = ("heading", "pitch", "roll")
    # ---------------------------------------------------------------- Table 4
    t4 = {m: res["T4"][m].mean() for m in MODES}
    tables.append(summary_table("Table 4", "imaging-leg attitude error STD by maneuver (T1 = 0, T2 = 400 s; "
                                "mean over AB and CD and over the runs)", _t4_rows(t4, "")))
    ph = {m: PAPER_T4[m][0] for m in MODES}
    # ---------------------------------------------------------------- Tables 5 and 6
    tables.append(summary_table("Table 5", "figure-8, attitude error STD vs T1 (straight flight after the "
                                "maneuver before entering the survey area), T2 = 400 s",
                                _t5_rows({t: res["T5"][t].mean() for t in T1_VALUES}, "")))
    rows6 = _t6_rows({t: res["T6"][t].mean() for t in T2_VALUES}, "")
    for a, b in zip(T2_VALUES[:-1], T2_VALUES[1:], strict=True):
        d = res["T6"][b].std[:, 0] - res["T6"][a].std[:, 0]  # paired: common random numbers
        se = d.std(ddof=1) / np.sqrt(len(d)) if len(d) > 1 else float("nan")
        rows6.append(summary_row(f"heading STD change T2 = {a} -> {b} s in standard errors (paired over the "
                                 f"{len(d)} runs; |value| < 2: not resolved by the Monte Carlo)", "-",
                                 float(d.mean() / se) if se > 0 else float("nan")))
    tables.append(summary_table("Table 6", "figure-8, T1 = 200 s, attitude error STD vs T2 (length of the "
                                "imaging legs)", rows6))
    # ---------------------------------------------------------------- Table 8
    t8 = {b: res["T8"][b].mean() for b in BASELINES}
    rows = []
    for q, u in zip(QUANTS, UNITS, strict=True):
        for i, b in enumerate(BASELINES):
            rows.append(summary_row(f"{q} STD, L0 = {b} km", u, t8[b][q], PAPER_T8[q][i], FACTOR2))
    for q in ("heading", "pitch", "roll"):
        rows.append(summary_row(f"{q}: largest deviation across L0 from the mean", "-",
                                _spread([t8[b][q] for b in BASELINES]), _spread(PAPER_T8[q]), "ours <= 0.1"))
    for q in ("vE", "vN", "vU", "lat", "lon"):
        o = [t8[b][q] for b in BASELINES]
        p = PAPER_T8[q]
        rows.append(summary_row(f"{q}: smallest ratio of successive L0 (non-decreasing: >= 1)", "-",
                                min(o[1] / o[0], o[2] / o[1]), min(p[1] / p[0], p[2] / p[1]), "ours >= 1"))
    gps = [0.1, 0.5, 1.0]
    ob = [t8[b]["baseline"] for b in BASELINES]
    pb = PAPER_T8["baseline"]
    for i in (1, 2):
        rows.append(summary_row(f"baseline error ratio {BASELINES[i]} / 20 km over GPS accuracy ratio "
                                f"{gps[i] / gps[0]:g} (about proportional: 0.5 … 2)", "-",
                                ob[i] / ob[0] / (gps[i] / gps[0]), pb[i] / pb[0] / (gps[i] / gps[0]),
                                "0.5 <= ours <= 2"))
    tables.append(summary_table("Table 8", "figure-8, T1 = 200 s, T2 = 400 s: error STD vs GNSS baseline "
                                "(master position accuracy of seed Table 7)", rows))
    # ---------------------------------------------------------------- sweeps / variants (no SPEC targets)
    rows = []
    for g in SWEEP_GRADES:
        d = res["grade"][g].mean()
        for q in names:
            rows.append(summary_row(f"{q} STD, sub-IMU {g} ({GRADES[g]})", "deg", d[q]))
    tables.append(summary_table("Grade sweep", "figure-8, T1 = 200 s, T2 = 400 s, 20 km: sub-IMU grade of "
                                "seed Table 1 (sub = the §3.1 sub-IMU, the baseline); the seed prints no "
                                "numbers", rows))
    rows = []
    for m in MODES:
        d21 = res["T4-21"][m].mean()
        for q in names:
            rows.append(summary_row(f"{q} STD, {LABEL[m]}, 21 states", "deg", d21[q],
                                    PAPER_T4[m][names.index(q)]))
        rows.append(summary_row(f"heading STD 21 / 24 states, {LABEL[m]}", "-",
                                d21["heading"] / t4[m]["heading"]))
    tables.append(summary_table("21 vs 24 states", "Table 4 with the seed's 21-state filter (first-order "
                                "flexure "
                                "model, the truth stays second order); paper = the seed's Table 4", rows))
    gm = {m: res["T4-GM"][m].mean() for m in MODES}
    tables.append(summary_table("Table 4, GM master",
                                "Table 4 with first-order Gauss-Markov master errors "
                                f"(τ = {MASTER_TAU_S:g} s, "
                                "same σ) instead of white; the filter still assumes white (sensitivity case)",
                                _t4_rows(gm, ", GM master")))
    dens = {m: res["T4-density"][m].mean() for m in MODES}
    sfx = ", ARW 0.0017°/√h"
    tables.append(summary_table("Table 4, density reading",
                                "Table 4 with the sub-IMU's 'random drift 0.1°/h' read as a white-noise "
                                "density of 0.1°/h/√Hz (ARW 0.0017°/√h, the seed004_sub preset) instead of "
                                "an ARW of 0.1°/√h (sensitivity case; filter matched)", _t4_rows(dens, sfx)))
    tables.append(summary_table("Table 5, density reading", "Table 5 with the density reading of the sub-IMU",
                                _t5_rows({t: res["T5-density"][t].mean() for t in T1_VALUES}, sfx)))
    tables.append(summary_table("Table 6, density reading", "Table 6 with the density reading of the sub-IMU",
                                _t6_rows({t: res["T6-density"][t].mean() for t in T2_VALUES}, sfx)))
    # ---------------------------------------------------------------- design tool
    rows = []
    pr = {m: cov_pred[m]["heading_deg"] for m in MODES}
    mc_rms = {m: float(res["T4"][m].rms.mean(axis=0)[0]) for m in MODES}
    for m in MODES:
        rows.append(summary_row(f"predicted heading σ (covariance), {LABEL[m]}", "deg", pr[m]))
        rows.append(summary_row(f"Monte Carlo heading RMS, {LABEL[m]}", "deg", mc_rms[m]))
    rows += [
        summary_row("predicted heading none / 8", "-", pr["none"] / pr["figure8"], ph["none"] / ph["figure8"],
                    "ours >= 5"),
        summary_row("predicted heading none / climb", "-", pr["none"] / pr["climb"], ph["none"] / ph["climb"],
                    "ours > 1"),
        summary_row("predicted heading climb / O", "-", pr["climb"] / pr["o_circle"],
                    ph["climb"] / ph["o_circle"], "ours > 1"),
        summary_row("predicted heading O / S", "-", pr["o_circle"] / pr["s_turns"],
                    ph["o_circle"] / ph["s_turns"], "ours > 1"),
        summary_row("predicted heading S / 8 (within 30 %)", "-", pr["s_turns"] / pr["figure8"],
                    ph["s_turns"] / ph["figure8"], "abs(ours - 1) <= 0.3"),
        summary_row("Spearman rank correlation, predicted σ vs Monte Carlo RMS (heading, 5 modes)", "-",
                    _spearman([pr[m] for m in MODES], [mc_rms[m] for m in MODES])),
        summary_row("Spearman rank correlation, predicted σ vs Monte Carlo STD (heading, 5 modes)", "-",
                    _spearman([pr[m] for m in MODES], [t4[m]["heading"] for m in MODES])),
    ]
    tables.append(summary_table("Design tool", "covariance-only prediction of the imaging-leg heading "
                                "accuracy "
                                "(aidnav.experiments.design) against the Monte Carlo of Table 4; the SPEC "
                                "Table 4 ordering applied to the prediction", rows))
    # ---------------------------------------------------------------- flexure
    rows = []
    for a in range(3):
        ax = "xyz"[a]
        rows.append(summary_row(f"flexure σ_{ax}", "deg", flex["sigma_deg"][a], flex_spec.sigma_deg[a],
                                "abs(ours - paper) <= 0.05 * paper"))
        rows.append(summary_row(f"flexure 1/e time τ_{ax}", "s", flex["tau_s"][a], flex_spec.tau_s[a],
                                "abs(ours - paper) <= 0.05 * paper"))
    tables.append(summary_table("Flexure", "second-order Markov flexure generator (exact discretisation), "
                                "1e5 s at 0.1 s: σ and 1/e lag against the seed's values", rows))
    return tables


def _spearman(a, b) -> float:
    ra = np.argsort(np.argsort(a))
    rb = np.argsort(np.argsort(b))
    return float(np.corrcoef(ra, rb)[0, 1])


def _print_tables(console: Console, tables: list[dict]):
    for t in tables:
        tab = Table(title=f"{t['name']}: {t['caption']}", title_justify="left")
        for c in ("quantity", "unit", "paper", "ours", "target", "holds"):
            tab.add_column(c)
        for r in t["rows"]:
            def f(v):
                return "" if v is None else (f"{v:.4g}" if isinstance(v, float) else str(v))
            tab.add_row(r["quantity"], r["unit"], f(r["paper"]), f(r["ours"]), r["target"] or "",
                        "" if r["holds"] is None else ("yes" if r["holds"] else "NO"))
        console.print(tab)


def _write_report(out: Path, tables: list[dict], notes: list[str], figures: list[str]) -> Path:
    lines = [f"# Seed {SEED} reproduction: {TITLE}", ""]
    for t in tables:
        lines += [f"## {t['name']}", "", t["caption"], "",
                  "| quantity | unit | paper | ours | target | holds |",
                  "|---|---|---|---|---|---|"]
        for r in t["rows"]:
            def f(v):
                return "" if v is None else f"{v:.4g}"
            h = "" if r["holds"] is None else ("yes" if r["holds"] else "**no**")
            lines.append(f"| {r['quantity']} | {r['unit']} | {f(r['paper'])} | {f(r['ours'])} | "
                         f"{r['target'] or ''} | {h} |")
        lines.append("")
    lines += ["## Figures", ""] + [f"![{f}]({f})" for f in figures] + ["", "## Notes", ""]
    lines += [f"- {n}" for n in notes]
    p = out / "report.md"
    p.write_text("\n".join(lines) + "\n")
    return p


def _write_runs(out: Path, runner: _Runner) -> Path:
    p = out / "runs.csv"
    with p.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["mode", "t1_s", "t2_s", "grade", "baseline_km", "nstate", "master_tau_s", "run", "stat",
                    *[f"{q}_{u.replace('/', '_')}" for q, u in zip(QUANTS, UNITS, strict=True)]])
        for c, r in runner.results.items():
            for stat in ("std", "rms"):
                for i, row in enumerate(getattr(r, stat)):
                    w.writerow([c.mode, c.t1, c.t2, c.grade, c.baseline_km, c.nstate, c.master_tau, i, stat,
                                *[repr(float(v)) for v in row]])
    return p


# --------------------------------------------------------------------------------------------- run
def run(out_dir, runs: int | None = 10, base_seed: int = 1, console: Console | None = None,
        quick: bool = False) -> dict:
    """Reproduce seed 004 into ``out_dir``: figures, ``report.md``, ``runs.csv`` and ``summary.json``.

    runs: Monte Carlo runs per case (10 as in the seed; None → 10, or 2 with ``quick``).
    quick: fewer runs (2 unless given) for tests; the same cases and tables.
    Returns the summary document (a dict, as written).
    """
    t_start = time.perf_counter()
    console = console or Console()
    runs = int(runs) if runs is not None else (2 if quick else 10)
    if runs < 1:
        raise ValueError("seed_004.run: runs must be >= 1")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    run_seeds = np.random.SeedSequence(int(base_seed)).spawn(runs)
    runner = _Runner(run_seeds, lambda m: console.log(m))

    # Monte Carlo cases, grouped by trajectory so that each trajectory is generated once
    res: dict[str, dict] = {k: {} for k in ("T4", "T4-21", "T4-GM", "T4-density", "T5", "T6", "T8", "grade",
                                            "T5-density", "T6-density")}
    bundles = {}
    for m in MODES:
        base = Case(mode=m, t1=0.0, t2=400.0)
        bundles[m] = runner.bundle(base.traj_key)[0]
        res["T4"][m] = runner.run(base)
        res["T4-21"][m] = runner.run(replace(base, nstate=21))
        res["T4-GM"][m] = runner.run(replace(base, master_tau=MASTER_TAU_S))
        res["T4-density"][m] = runner.run(replace(base, grade="sub"))
    for t1 in T1_VALUES:
        c = Case(mode="figure8", t1=float(t1), t2=400.0)
        res["T5"][t1] = runner.run(c)
        res["T5-density"][t1] = runner.run(replace(c, grade="sub"))
    for t2 in T2_VALUES:
        c = Case(mode="figure8", t1=200.0, t2=float(t2))
        res["T6"][t2] = runner.run(c)
        res["T6-density"][t2] = runner.run(replace(c, grade="sub"))
    for b in BASELINES:
        res["T8"][b] = runner.run(replace(BASE, baseline_km=float(b)))
    for g in SWEEP_GRADES:
        res["grade"][g] = runner.run(replace(BASE, grade=g))
    t_mc = time.perf_counter() - t_start

    # design tool (covariance only) and flexure check
    t0 = time.perf_counter()
    cov_pred, analyses = {}, {}
    for m in MODES:
        cov_pred[m], analyses[m] = predict_accuracy(bundles[m])
    t_design = time.perf_counter() - t0
    flex_spec = FlexureSpec()
    flex = flexure_check(flex_spec, duration_s=2.0e4 if quick else 1.0e5)

    tables = _tables(res, cov_pred, flex, flex_spec)

    # figures
    figures = [fig_trajectories(out, bundles), fig_attitude(out, res["T4"])]
    att = ("heading", "pitch", "roll")

    def rows_of(d, keys):
        return [d[k].mean() for k in keys]

    def paper_of(d, keys):
        return [dict(zip(att, d[k], strict=True)) for k in keys]

    p8 = [dict(zip(att, (PAPER_T8["heading"][i], PAPER_T8["pitch"][i], PAPER_T8["roll"][i]), strict=True))
          for i in range(3)]
    sweeps = {
        "maneuver (Table 4)": ([LABEL[m] for m in MODES], rows_of(res["T4"], MODES),
                               paper_of(PAPER_T4, MODES),
                               "maneuver before the survey area"),
        "sub-IMU grade (Table 1)": ([g.removesuffix("_arw") for g in SWEEP_GRADES],
                                    rows_of(res["grade"], SWEEP_GRADES), None, "grade"),
        "T1 (Table 5)": (list(T1_VALUES), rows_of(res["T5"], T1_VALUES), paper_of(PAPER_T5, T1_VALUES),
                         "T1 [s]"),
        "T2 (Table 6)": (list(T2_VALUES), rows_of(res["T6"], T2_VALUES), paper_of(PAPER_T6, T2_VALUES),
                         "T2 [s]"),
        "GNSS baseline (Table 8)": (list(BASELINES), rows_of(res["T8"], BASELINES), p8, "L0 [km]"),
        "21 vs 24 states (Table 4 modes)": ([LABEL[m] for m in MODES], rows_of(res["T4-21"], MODES), None,
                                            "maneuver, 21-state filter"),
    }
    figures.append(fig_sweeps(out, sweeps))
    mc_std = {m: res["T4"][m].mean()["heading"] for m in MODES}
    mc_rms = {m: float(res["T4"][m].rms.mean(axis=0)[0]) for m in MODES}
    figures.append(fig_design(out, analyses, {m: cov_pred[m]["heading_deg"] for m in MODES}, mc_std, mc_rms))
    figures.append(fig_flexure(out, flex, flex_spec))
    _write_runs(out, runner)

    elapsed = time.perf_counter() - t_start
    r2124 = [res["T4-21"][m].mean()["heading"] / res["T4"][m].mean()["heading"] for m in MODES]
    b8 = [res["T8"][b].mean()["baseline"] for b in BASELINES]
    t8v = [res["T8"][b].mean()["vE"] for b in BASELINES]
    pred = [cov_pred[m]["heading_deg"] for m in MODES]
    pess = [cov_pred[m]["heading_deg"] / mc_rms[m] for m in MODES]

    def holding(name):
        t = next(t for t in tables if t["name"] == name)
        hs = [r["holds"] for r in t["rows"] if r["holds"] is not None and "paper / 2" not in r["target"]]
        return f"{sum(hs)} of {len(hs)}"

    def within2(name):
        t = next(t for t in tables if t["name"] == name)
        hs = [r["holds"] for r in t["rows"] if r["target"] == FACTOR2]
        return f"{sum(hs)} of {len(hs)}"

    h5 = [res["T5"][t].mean()["heading"] for t in T1_VALUES]
    four = ("s_turns", "o_circle", "figure8")
    att = ("heading", "pitch", "roll")
    below = [PAPER_T4[m][i] / res["T4-density"][m].mean()[q] for m in four for i, q in enumerate(att)]
    gm_up = [res["T4-GM"][m].mean()[q] / res["T4"][m].mean()[q] for m in four for q in att]
    notes = [
        "Statistic: per run, the standard deviation over time of each error on AB and on CD (the seed's "
        "STD), averaged over the two legs and then over the runs; errors at the 1-s filter epochs after "
        "the update. runs.csv also has the RMS about zero.",
        "SPEC 5.2-1: eqs. 1-10 reconstructed as SPEC 5.1 (aidnav.filters.transfer): 15 INS states, "
        "mounting rho, flexure theta and theta-dot; velocity + attitude matching, DCM attitude difference "
        "(formed about the current mounting estimate, left Jacobian of SO(3) in H), master velocity "
        "lever-arm compensated with the master's body rate.",
        "SPEC 5.2-2: 24 states (second-order flexure) for every table; the seed's 21 states (first-order "
        "flexure with the same sigma and 1/e time) in '21 vs 24 states' (heading STD ratio 21/24 states "
        f"{min(r2124):.3f}-{max(r2124):.3f}).",
        "SPEC 5.2-3: initial heading 40 deg clockwise from North. SPEC 5.2-4: OCR cells '0. 0038' and "
        "'0. 519 2' read as 0.0038 and 0.5192.",
        "Trajectories: examples/{none,s_turns,o_circle,figure8,climb}.yaml (SPEC 5.1 suggestions: U-turn "
        "0.9 deg/s, O 360 deg in 400 s, S +-30 deg in two cycles, figure-8 two opposite circles, climb "
        "5 m/s with a 90 deg turn); T1 is a straight leg inserted between the maneuver and AB; T2 sets the "
        "lengths of AB and CD.",
        "Master POS output = truth + errors of the POS/AV610 accuracies at 1 Hz (the seed's 'measurement "
        "noise'): white attitude and velocity errors; position errors half white, half a smooth second-order "
        "Gauss-Markov drift (tau 300 s: the baseline-dependent residual of differential GNSS) whose rate the "
        "master velocity carries, so that the master's velocity is consistent with its position "
        "(aidnav.sim.distributed_pos.MasterPosSpec). The filter's R uses the white sigmas. Lever arm "
        "[5, 0.1, 0.1] m, mounting 0.5 deg per axis, flexure sigma (0.01, 0.15, 0.01) deg, tau (2, 5, 2) s.",
        "Noise reading (SPEC 1.1 reads a seed's 'random drift X deg/h' as a white-noise density; the unit is "
        "ambiguous): the tables use the sub-IMU's 'random drift 0.1 deg/h' as an angle random walk of "
        "0.1 deg/sqrt(h) (grade sub_arw; 0.1 deg/h constant bias, 50 ug + 50 ug/sqrt(Hz)). Reason: the "
        "seed's own pitch/roll STDs after the maneuvers (0.004-0.009 deg) need that much gyro noise. "
        "With the other reading (0.1 deg/h/sqrt(Hz), ARW 0.0017 deg/sqrt(h), the seed004_sub preset) our "
        f"attitude STDs after the S, O and 8 maneuvers are {min(below):.0f}-{max(below):.0f}x below the "
        "seed's, and the climb's pitch/roll, limited by the accelerometer bias its gentle turn leaves "
        "unresolved instead of by gyro noise, are much worse than the other maneuvers'. Factor-2 cells, "
        f"ARW / density reading: Table 4 {within2('Table 4')} / {within2('Table 4, density reading')}, "
        f"Table 5 {within2('Table 5')} / {within2('Table 5, density reading')}; SPEC predicates holding: "
        f"Table 4 {holding('Table 4')} / {holding('Table 4, density reading')}, Table 5 {holding('Table 5')}"
        f" / {holding('Table 5, density reading')}, Table 6 {holding('Table 6')} / "
        f"{holding('Table 6, density reading')}. Gauss-Markov master errors (tau = {MASTER_TAU_S:g} s, "
        f"all channels) change the maneuver STDs by {min(gm_up):.1f}-{max(gm_up):.1f}x.",
        f"Table 5: heading STD {', '.join(f'{v:.5f}' for v in h5)} deg for T1 = "
        f"{', '.join(str(t) for t in T1_VALUES)} s.",
        "Table 6: the heading STD changes with T2 by less than the Monte Carlo resolves (see the paired rows "
        "in standard errors); the seed's growth (0.0083, 0.0086, 0.0091 deg) is of the same size as that "
        "noise with its 10 runs, so the 'non-decreasing' predicate compares nearly equal numbers.",
        "Table 8: velocity + attitude matching passes the master's velocity error to the sub, and the sub's "
        "position (its integral) follows the master's smooth position drift, so the sub's velocity and "
        f"position STDs grow with L0 (vE {t8v[0]:.5f}, {t8v[1]:.5f}, {t8v[2]:.5f} m/s); the white part of "
        "the master's position error makes the master-sub baseline-length error follow the master's "
        f"accuracy ({b8[0]:.3f}, {b8[1]:.3f}, {b8[2]:.3f} m against the seed's 0.218, 0.597, 1.276 m).",
        f"Design tool: the covariance analysis ({t_design / len(MODES):.2f} s per trajectory once compiled, "
        "against seconds per Monte Carlo case) predicts the ensemble RMS; Spearman correlation of its "
        f"heading ranking with the Monte Carlo: {_spearman(pred, [mc_rms[m] for m in MODES]):.2f} (RMS), "
        f"{_spearman(pred, [mc_std[m] for m in MODES]):.2f} (STD); predicted / Monte Carlo RMS "
        f"{min(pess):.2f}-{max(pess):.2f} (the Monte Carlo mounting is a fixed 0.5 deg, inside the filter's "
        "1-deg prior).",
        f"Runs: {runs} per case, base seed {base_seed}, common random numbers across cases. Monte Carlo "
        f"{t_mc:.0f} s, design tool {t_design:.1f} s, whole reproduction {elapsed:.0f} s on this machine.",
    ]
    _write_report(out, tables, notes, figures)
    path = write_summary(out, seed=SEED, title=TITLE, runs=runs, base_seed=int(base_seed), tables=tables,
                         figures=figures, notes=notes)
    _print_tables(console, tables[:4])
    console.log(f"wrote {path} ({elapsed:.0f} s)")
    import json

    return json.loads(path.read_text())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m aidnav.experiments.reproduce.seed_004",
                                 description="Reproduce seed 004 (distributed POS transfer alignment).")
    ap.add_argument("out_dir")
    ap.add_argument("--runs", type=int, default=None,
                    help="Monte Carlo runs per case (default 10; 2 with --quick)")
    ap.add_argument("--base-seed", type=int, default=1)
    ap.add_argument("--quick", action="store_true", help="2 runs per case (tests)")
    a = ap.parse_args(argv)
    doc = run(a.out_dir, runs=a.runs, base_seed=a.base_seed, quick=a.quick)
    bad = [r["quantity"] for t in doc["tables"] for r in t["rows"] if r["holds"] is False]
    print(f"wrote {a.out_dir}/summary.json; {len(bad)} rows not holding" + "".join("\n  " + b for b in bad))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
