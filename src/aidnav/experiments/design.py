"""Flight-trajectory design for a distributed POS (seed 004): rank candidate trajectories by the
predicted accuracy of the transfer alignment, from the filter covariance alone (no Monte Carlo).

For each candidate (a :class:`~aidnav.sim.scenario.Scenario`, a scenario file, or the
``(truth, imu, segments)`` of :func:`aidnav.sim.trajectory.generate_truth`) the truth trajectory is
generated and the transfer-alignment covariance recursion (:func:`aidnav.filters.transfer.
covariance_analysis`: the same F, Φ, Qd, H and Joseph update as the filter, evaluated on the truth)
is run once. The predicted 1σ of the sub-IMU's roll, pitch and heading errors is summarised over the
imaging legs (default AB and CD) as the root mean square of σ over each leg, averaged over the legs:
the prediction of the Monte Carlo RMS error of those legs. A candidate takes about a second
(trajectory generation included), against minutes for a Monte Carlo of ten runs.

What it predicts, and what it does not: the covariance is the ensemble spread of a consistent filter,
so it predicts the RMS error over runs; the seed's "STD" (the standard deviation of each run's error
over a leg) leaves out the part of the error that is constant over the leg. Where a maneuver makes
the heading observable before the leg, both are close; where it does not (no maneuver), the heading
error is a slowly changing offset and the covariance predicts it, the per-leg STD does not. The
seed-004 reproduction (``aidnav.experiments.reproduce.seed_004``; the cases: ``experiments.transfer_cases``)
compares both rankings with the
Monte Carlo.

Units: angles in degrees in the returned rows (``*_deg``), radians inside.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aidnav.filters.transfer import (
    CovarianceAnalysis,
    TransferConfig,
    covariance_analysis,
    run_transfer,
    segment_statistic,
    transfer_errors,
)
from aidnav.sim.distributed_pos import MasterPosSpec, simulate_distributed_pos, sub_geometry

__all__ = ["predict_accuracy", "rank_trajectories", "TrajectoryDesign", "design_trajectory", "write_design",
           "print_design", "DESIGN_MODES"]


def _bundle(candidate):
    from aidnav.sim.scenario import Scenario, load_scenario  # lazy: pulls in pydantic, yaml
    from aidnav.sim.trajectory import generate_truth  # lazy: pulls in pydantic, yaml

    if isinstance(candidate, tuple):
        return candidate
    if isinstance(candidate, (str, Path)):
        candidate = load_scenario(candidate)
    if isinstance(candidate, Scenario):
        return generate_truth(candidate)
    raise TypeError(f"rank_trajectories: a candidate must be a Scenario, a path or a generate_truth tuple, "
                    f"not {type(candidate).__name__}")


def predict_accuracy(candidate, cfg: TransferConfig | None = None, master: MasterPosSpec | None = None,
                     legs=("AB", "CD")) -> tuple[dict, CovarianceAnalysis]:
    """Predicted sub-IMU attitude accuracy on the imaging ``legs`` of one candidate trajectory.

    Returns ``(row, analysis)``: row = {roll_deg, pitch_deg, heading_deg} (mean over the legs of the
    RMS of the predicted 1σ [deg]) and the :class:`~aidnav.filters.transfer.CovarianceAnalysis`.
    """
    ana = covariance_analysis(_bundle(candidate), cfg, master)
    rms = np.degrees(ana.segment_rms(legs))
    return {"roll_deg": float(rms[0]), "pitch_deg": float(rms[1]), "heading_deg": float(rms[2])}, ana


def rank_trajectories(candidates: dict, cfg: TransferConfig | None = None,
                      master: MasterPosSpec | None = None, legs=("AB", "CD"),
                      key: str = "heading_deg") -> list[dict]:
    """Rank candidate trajectories by predicted accuracy (best first).

    candidates: {name: Scenario | path | (truth, imu, segments)}; every candidate needs segments named
    as in ``legs``. cfg: filter settings (default :class:`~aidnav.filters.transfer.TransferConfig`,
    24 states, the seed's sub-IMU and master). key: the column to rank by.
    Returns rows {name, rank, roll_deg, pitch_deg, heading_deg} sorted by ``key``.
    """
    rows = []
    for name, cand in candidates.items():
        row, _ = predict_accuracy(cand, cfg, master, legs)
        rows.append({"name": name, **row})
    rows.sort(key=lambda r: r[key])
    for i, r in enumerate(rows):
        r["rank"] = i + 1
    return rows


# ------------------------------------------------------------------------- trajectory design (issue 18)
#: motion modes the design searches (seed Table 3), scenario names as in ``examples/``
DESIGN_MODES = ("none", "s_turns", "o_circle", "figure8", "climb")
_AXES = ("heading_deg", "pitch_deg", "roll_deg")


def _grade_key(grade: str) -> str:
    """'seed004_high' / 'high' / 'sub_arw' … → the key of ``seed_004.GRADES``."""
    from aidnav.experiments.transfer_cases import GRADES  # lazy: pulls in pydantic, yaml

    g = str(grade).strip().lower()
    g = g[len("seed004_"):] if g.startswith("seed004_") else g
    if g not in GRADES:
        raise ValueError(f"design_trajectory: unknown IMU grade {grade!r}; use one of "
                         f"{', '.join(k if k.endswith('_arw') else 'seed004_' + k for k in GRADES)}")
    return g


@dataclass
class TrajectoryDesign:
    """Result of :func:`design_trajectory`.

    summary: the JSON-ready plan (keys below); analysis: the :class:`~aidnav.filters.transfer.
    CovarianceAnalysis` of the recommended plan (or, when no plan meets the requirement, of the
    candidate closest to it; None if there was no candidate).

    summary keys: grade, imu, requirement {heading_deg, pitch_deg, roll_deg}, legs, baseline_km, nstate,
    feasible, t2_at_candidate_limit, recommended (None or {mode, label, t1_s, t2_s, flight_time_s,
    predicted {…_deg}, worst_ratio}), closest (the candidate with the smallest worst ratio), per_mode
    (the best plan of each mode: longest T2 that meets, or None), candidates (every (mode, T1, T2)
    evaluated), monte_carlo (None or {runs, base_seed, rms {…_deg}, std {…_deg}, meets,
    ratio_to_predicted {…}}), message, method.
    """

    summary: dict
    analysis: CovarianceAnalysis | None


def design_trajectory(requirement: dict, grade: str = "sub_arw", modes=DESIGN_MODES,
                      t1_values=(0.0, 200.0, 400.0), t2_values=(100.0, 200.0, 400.0, 600.0, 800.0),
                      legs=("AB", "CD"), baseline_km: float = 20.0, nstate: int = 24, mc_runs: int = 3,
                      base_seed: int = 1, say=None) -> TrajectoryDesign:
    """Recommend a flight trajectory (maneuver, T1, T2) for a distributed POS (seed 004).

    requirement: {"heading_deg", "pitch_deg", "roll_deg"}: the 1σ attitude accuracy [deg] required on
    the imaging legs (mean over ``legs`` of the RMS of the predicted σ, see :func:`predict_accuracy`).
    grade: sub-IMU grade, ``seed004_high|medium|low|sub`` (or without the prefix), or with ``_arw`` appended
    (``sub_arw``, …: the gyro's "random drift" read as an ARW; see ``seed_004.GRADES``).
    modes: scenario names of seed Table 3 (``examples/<mode>.yaml``). t1_values [s]: straight leg
    between the maneuver and AB; t2_values [s]: candidate lengths of AB and CD (each).
    baseline_km: GNSS baseline of seed Table 7 (master position accuracy). nstate: 21 or 24.

    Method: the covariance analysis is run for every (mode, T1, T2) (all of them: the predicted σ is
    not monotonic in T2, since the turn between the legs restores observability); a mode's plan is its
    longest passing T2 (ties: shortest flight, then largest margin). The recommendation is the plan with the
    longest T2, then the shortest total flight time, then the smallest worst ratio predicted/required.
    ``mc_runs`` > 0 confirms it with that many simulated runs of :func:`~aidnav.filters.transfer.
    run_transfer` (RMS and STD of the errors on the legs, mean over the legs, RMS over the runs).
    Returns a :class:`TrajectoryDesign`; angles in degrees, times in seconds.
    """
    # lazy: pulls in pydantic, yaml
    from aidnav.experiments.transfer_cases import LABEL, Case, imu_spec, load_mode, sim_config, variant
    from aidnav.sim.trajectory import generate_truth  # lazy: pulls in pydantic, yaml

    say = say or (lambda msg: None)
    req = {k: float(requirement[k]) for k in _AXES}
    if min(req.values()) <= 0:
        raise ValueError("design_trajectory: the required accuracies must be > 0 deg")
    gkey = _grade_key(grade)
    t1s = sorted(float(t) for t in t1_values)
    t2s = sorted(float(t) for t in t2_values)
    if not t1s or not t2s or min(t1s) < 0 or min(t2s) <= 0:
        raise ValueError("design_trajectory: need T1 >= 0 and T2 > 0 values")
    sim_cfg = sim_config(Case(grade=gkey, baseline_km=baseline_km))
    fcfg = TransferConfig.from_sim(sim_cfg, nstate=nstate)
    cands: list[dict] = []
    for mode in modes:
        base = load_mode(mode)
        for t1 in t1s:
            for t2 in t2s:
                bundle = generate_truth(variant(base, t1, t2))
                row, _ = predict_accuracy(bundle, fcfg, legs=legs)
                worst = max(row[k] / req[k] for k in _AXES)
                c = {"mode": mode, "label": LABEL.get(mode, mode), "t1_s": t1, "t2_s": t2,
                     "flight_time_s": float(max(r["end_s"] for r in bundle[2])),
                     "predicted": {k: row[k] for k in _AXES}, "worst_ratio": float(worst),
                     "meets": bool(worst <= 1.0)}
                cands.append(c)
                say(f"{mode:8s} T1={t1:5g} T2={t2:5g}: heading {row['heading_deg']:.4f} "
                    f"pitch {row['pitch_deg']:.4f} roll {row['roll_deg']:.4f} deg -> "
                    f"{'ok' if c['meets'] else 'no'}")

    def order(c):
        return (-c["t2_s"], c["flight_time_s"], c["worst_ratio"])

    ok = [c for c in cands if c["meets"]]
    per_mode = []
    for mode in modes:
        m_ok = sorted((c for c in ok if c["mode"] == mode), key=order)
        per_mode.append({"mode": mode, "label": LABEL.get(mode, mode), "plan": m_ok[0] if m_ok else None})
    rec = min(ok, key=order) if ok else None
    closest = min(cands, key=lambda c: c["worst_ratio"]) if cands else None
    shown = rec or closest
    mc = None
    if rec is not None and mc_runs > 0:
        mc = _confirm(rec, gkey, baseline_km, nstate, legs, int(mc_runs), int(base_seed), req)
        say(f"Monte Carlo ({mc_runs} runs): RMS heading {mc['rms']['heading_deg']:.4f} pitch "
            f"{mc['rms']['pitch_deg']:.4f} roll {mc['rms']['roll_deg']:.4f} deg")
    if rec is not None:
        msg = (f"recommended: {rec['label']} maneuver, T1 = {rec['t1_s']:g} s, T2 = {rec['t2_s']:g} s "
               f"(predicted worst ratio {rec['worst_ratio']:.2f} of the requirement)")
        if rec["t2_s"] >= t2s[-1]:
            msg += "; T2 is the longest candidate: longer legs may meet it too (extend --t2)"
    else:
        msg = ("no plan meets the requirement among the candidates"
               + (f"; closest: {closest['label']}, T1 = {closest['t1_s']:g} s, T2 = {closest['t2_s']:g} s at "
                  f"{closest['worst_ratio']:.2f} x the requirement" if closest else ""))
    summary = {
        "grade": gkey if gkey.endswith("_arw") else f"seed004_{gkey}", "imu": imu_spec(gkey).name,
        "requirement": req, "legs": list(legs), "baseline_km": float(baseline_km), "nstate": int(nstate),
        "t1_values_s": t1s, "t2_values_s": t2s, "feasible": rec is not None, "recommended": rec,
        "t2_at_candidate_limit": bool(rec is not None and rec["t2_s"] >= t2s[-1]),
        "closest": closest, "per_mode": per_mode, "candidates": cands, "monte_carlo": mc, "message": msg,
        "method": ("covariance analysis of the transfer-alignment filter along each candidate trajectory "
                   "(mean over the legs of the RMS of the predicted 1-sigma), T2 searched in increasing "
                   "order per (mode, T1); Monte Carlo confirmation of the recommended plan"),
    }
    ana = None
    if shown is not None:  # recomputed: keeping every candidate's covariance history would take ~1 GB
        scn = variant(load_mode(shown["mode"]), shown["t1_s"], shown["t2_s"])
        _, ana = predict_accuracy(generate_truth(scn), fcfg, legs=legs)
    return TrajectoryDesign(summary=summary, analysis=ana)


def _confirm(plan: dict, gkey: str, baseline_km: float, nstate: int, legs, runs: int, base_seed: int,
             req: dict) -> dict:
    """Monte Carlo of the recommended plan: RMS over runs of the per-run leg RMS and mean per-run leg STD."""
    # lazy: pulls in pydantic, yaml
    from aidnav.experiments.transfer_cases import Case, load_mode, sim_config, variant
    from aidnav.sim.trajectory import generate_truth  # lazy: pulls in pydantic, yaml

    cfg = sim_config(Case(mode=plan["mode"], t1=plan["t1_s"], t2=plan["t2_s"], grade=gkey,
                          baseline_km=baseline_km))
    fcfg = TransferConfig.from_sim(cfg, nstate=nstate)
    bundle = generate_truth(variant(load_mode(plan["mode"]), plan["t1_s"], plan["t2_s"]))
    geo = sub_geometry(bundle[0], bundle[1], cfg.lever_arm)
    rms, std = [], []
    for ss in np.random.SeedSequence(base_seed).spawn(runs):
        run = simulate_distributed_pos(bundle, cfg, ss, geo)
        e = transfer_errors(run_transfer(run, fcfg), run)
        err = np.degrees(e.rph[:, [2, 1, 0]])  # heading, pitch, roll
        rms.append(segment_statistic(e.time, err, run.segments, legs, stat="rms"))
        std.append(segment_statistic(e.time, err, run.segments, legs, stat="std"))
    r = np.sqrt(np.mean(np.square(rms), axis=0))
    s = np.mean(std, axis=0)
    rd = dict(zip(_AXES, map(float, r), strict=True))
    sd = dict(zip(_AXES, map(float, s), strict=True))
    return {"runs": runs, "base_seed": base_seed, "rms": rd, "std": sd,
            "meets": bool(all(rd[k] <= req[k] for k in _AXES)),
            "ratio_to_predicted": {k: rd[k] / plan["predicted"][k] for k in _AXES}}


def write_design(design: TrajectoryDesign, out_dir) -> list[Path]:
    """Write ``design.json`` (the summary) and ``design.png`` (predicted σ of the recommended or closest
    plan against the requirement; longest feasible T2 per mode) into ``out_dir``. Returns the paths."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # lazy: matplotlib is heavy to import
    from matplotlib.figure import Figure  # lazy: matplotlib is heavy to import

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    s = design.summary
    pj = out / "design.json"
    pj.write_text(json.dumps(s, indent=2))
    fig = Figure(figsize=(13, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 2, 1)
    plan = s["recommended"] or s["closest"]
    a = design.analysis
    if a is not None and plan is not None:
        for r in a.segments:
            if r["name"] in s["legs"]:
                ax.axvspan(r["start_s"], r["end_s"], color="0.9", zorder=0)
        for k, i, c in (("heading_deg", 2, "tab:blue"), ("pitch_deg", 1, "tab:orange"),
                        ("roll_deg", 0, "tab:green")):
            ax.semilogy(a.time, np.degrees(a.rph_sigma[:, i]), color=c, lw=1, label=f"{k[:-4]} 1σ")
            ax.axhline(s["requirement"][k], color=c, ls="--", lw=0.8)
        kind = "recommended" if s["recommended"] else "closest (requirement not met)"
        ax.set_title(f"{kind}: {plan['label']}, T1 = {plan['t1_s']:g} s, T2 = {plan['t2_s']:g} s")
        ax.legend(fontsize=8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("predicted 1σ [deg] (dashed: required)")
    ax.grid(alpha=0.3, which="both")
    ax = fig.add_subplot(1, 2, 2)
    labels = [m["label"] for m in s["per_mode"]]
    t2 = [m["plan"]["t2_s"] if m["plan"] else 0.0 for m in s["per_mode"]]
    ax.bar(range(len(labels)), t2, color=["tab:green" if v > 0 else "0.7" for v in t2])
    ax.set_xticks(range(len(labels)), labels)
    ax.set_ylabel("longest T2 meeting the requirement [s]")
    ax.set_title(f"per maneuver (grade {s['grade']}; 0 = none meets)")
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    pp = out / "design.png"
    fig.savefig(pp, dpi=110)
    return [pj, pp]


def print_design(design: TrajectoryDesign, console) -> None:
    """Print the per-mode plans, the recommendation and the Monte Carlo check as rich tables."""
    from rich.table import Table  # lazy: rich is heavy to import

    s = design.summary
    rq = s["requirement"]
    t = Table(title=f"trajectory design: grade {s['grade']}, required heading/pitch/roll "
                    f"{rq['heading_deg']:g}/{rq['pitch_deg']:g}/{rq['roll_deg']:g} deg (1σ)")
    for c in ("maneuver", "T1 [s]", "longest T2 [s]", "flight [s]", "heading [deg]", "pitch [deg]",
              "roll [deg]", "worst ratio"):
        t.add_column(c, justify="right")
    rec = s["recommended"]
    for m in s["per_mode"]:
        p = m["plan"]
        if p is None:
            t.add_row(m["label"], "-", "none meets", "-", "-", "-", "-", "-")
            continue
        star = " *" if rec is not None and p is rec else ""
        t.add_row(m["label"] + star, f"{p['t1_s']:g}", f"{p['t2_s']:g}", f"{p['flight_time_s']:g}",
                  *(f"{p['predicted'][k]:.4f}" for k in _AXES), f"{p['worst_ratio']:.2f}")
    console.print(t)
    from rich.text import Text  # lazy: rich is heavy to import

    console.print(Text(s["message"], style="bold green" if s["feasible"] else "bold red"))
    mc = s["monte_carlo"]
    if mc:
        t = Table(title=f"Monte Carlo confirmation ({mc['runs']} runs)")
        for c in ("", "heading [deg]", "pitch [deg]", "roll [deg]"):
            t.add_column(c, justify="right")
        t.add_row("predicted 1σ", *(f"{rec['predicted'][k]:.4f}" for k in _AXES))
        t.add_row("MC RMS", *(f"{mc['rms'][k]:.4f}" for k in _AXES))
        t.add_row("MC STD", *(f"{mc['std'][k]:.4f}" for k in _AXES))
        t.add_row("required", *(f"{rq[k]:g}" for k in _AXES))
        console.print(t)
        console.print(f"Monte Carlo RMS {'meets' if mc['meets'] else 'does NOT meet'} the requirement")
